"""Tests for the rigid projectile and its penalty contact (thesis Chapter 4, Section 4.1)."""

import math

import numpy as np
import pytest

from fabric_fenicsx.fem.projectile import (
    PenaltyContact,
    Projectile,
    ProjectileState,
    advance,
    contact_work,
    critical_omega_dt,
    stable_penalty,
)

FILLETS = (0.0, 0.8e-3, 2.0e-3)  # thesis Sec. 4.4.3


def _fd_gradient(proj, x, z_face, eps=1e-8):
    grad = np.zeros_like(x)
    for j in range(3):  # three coordinate directions, vectorised over points
        e = np.zeros(3)
        e[j] = eps
        gp, _ = proj.gap_and_normal(x + e, z_face)
        gm, _ = proj.gap_and_normal(x - e, z_face)
        grad[:, j] = (gp - gm) / (2 * eps)
    return grad


def _probe_points(proj, zf):
    """Points with known signed distance and normal: face, fillet and side, inside and out."""
    R, L, rf = proj.radius, proj.length, proj.fillet
    xc, yc = proj.axis_xy
    d = 5e-5
    phi = 0.7  # azimuth of the probes, away from the axes
    er = np.array([math.cos(phi), math.sin(phi), 0.0])
    ez = np.array([0.0, 0.0, 1.0])
    base = np.array([xc, yc, zf])
    pts, gaps, normals = [], [], []
    for s in (+1, -1):  # s=+1: inside (penetrating), s=-1: outside
        # face, radius 0.3 R, depth d above / below the face
        pts.append(base + 0.3 * R * er + s * d * ez)
        gaps.append(-s * d)
        normals.append(-ez)
        # side, mid-height, radius R -/+ d
        pts.append(base + (R - s * d) * er + 0.5 * L * ez)
        gaps.append(-s * d)
        normals.append(er)
        # fillet: at 40 degrees between the face normal and the radial direction
        th = math.radians(40.0)
        n_fil = math.sin(th) * er - math.cos(th) * ez
        centre = base + (R - rf) * er + rf * ez
        rho = rf - s * d
        pts.append(centre + rho * n_fil)
        gaps.append(rho - rf)
        normals.append(n_fil)
    return np.array(pts), np.array(gaps), np.array(normals)


@pytest.mark.parametrize("fillet", FILLETS)
def test_gap_and_normal_face_fillet_side(fillet):
    proj = Projectile(fillet=fillet, axis_xy=(0.01, -0.02))
    zf = -3e-3
    x, g_exact, n_exact = _probe_points(proj, zf)
    g, n = proj.gap_and_normal(x, zf)
    if fillet == 0.0:  # the "fillet" probes sit exactly at the sharp corner: skip them
        keep = np.ones(len(x), bool)
        keep[[2, 5]] = False
        x, g_exact, n_exact, g, n = x[keep], g_exact[keep], n_exact[keep], g[keep], n[keep]
    np.testing.assert_allclose(g, g_exact, atol=1e-12)
    np.testing.assert_allclose(n, n_exact, atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-12)
    np.testing.assert_allclose(n, _fd_gradient(proj, x, zf), atol=1e-5)
    # the normal points out of the solid: stepping along it increases the gap
    g_out, _ = proj.gap_and_normal(x + 1e-6 * n, zf)
    assert np.all(g_out > g)


@pytest.mark.parametrize("fillet", FILLETS)
def test_penetrating_node_is_pushed_out_along_the_normal(fillet):
    proj = Projectile(fillet=fillet, z0=0.0, friction=0.5)
    contact = PenaltyContact(proj, damping_ratio=0.0)
    state = ProjectileState(z=0.0, vz=0.0, mass=proj.mass)
    x, _, n_exact = _probe_points(proj, 0.0)
    inside = np.array([0, 1] + ([2] if fillet > 0 else []))
    x = x[inside]
    m, dt = 1e-7, 1e-7
    f, _, info = contact.forces(x, np.zeros_like(x), m, dt, state)
    assert info["n_active"] == len(x)
    fmag = np.linalg.norm(f, axis=1)
    assert np.all(fmag > 0)
    np.testing.assert_allclose(f / fmag[:, None], n_exact[inside], atol=1e-9)
    # undamped, at rest: the force is the penalty k p
    k = stable_penalty(m, dt, contact.penalty_fraction, 0.0)
    np.testing.assert_allclose(fmag, k * 5e-5, rtol=1e-9)


def test_nodes_outside_get_no_force():
    proj = Projectile(fillet=0.8e-3, z0=0.0)
    contact = PenaltyContact(proj)
    state = ProjectileState(z=0.0, vz=-50.0, mass=proj.mass)
    R, L = proj.radius, proj.length
    x = np.array([
        [0.0, 0.0, -1e-6],  # just below the face centre
        [0.0, 0.0, 0.0],  # exactly on the face: g = 0, no penetration
        [R + 1e-6, 0.0, 0.5 * L],  # beside the side
        [0.0, 0.0, L + 1e-6],  # above the back face
        [R - 1e-5, 0.0, 1e-5],  # in the corner cut away by the fillet
        [0.1, 0.1, 0.001],  # far away
    ])
    v = np.full_like(x, 3.0)
    f, fp, info = contact.forces(x, v, 1e-7, 1e-7, state)
    assert np.all(f == 0.0) and np.all(fp == 0.0)
    assert info["n_active"] == 0 and info["penalty_energy"] == 0.0
    g, _ = proj.gap_and_normal(x, 0.0)
    assert np.all(g >= 0.0)


def _face_node(v_node, pen=2e-6, vz=0.0):
    proj = Projectile(z0=0.0, friction=0.5)
    state = ProjectileState(z=0.0, vz=vz, mass=proj.mass)
    x = np.array([[0.002, 0.001, pen]])
    return proj, state, x, np.array([v_node], float)


def test_friction_opposes_sliding_and_is_capped_by_coulomb():
    m, dt = 1e-7, 1e-7
    _, state, x, v = _face_node([30.0, -40.0, 0.0])
    contact = PenaltyContact(Projectile(z0=0.0, friction=0.5), damping_ratio=0.0)
    f, _, info = contact.forces(x, v, m, dt, state)
    f_n = f[0, 2]  # face normal is -z: the normal force is f_n = -f_z
    f_t = f[0, :2]
    assert f_n < 0.0
    # fast sliding: friction at the Coulomb limit, opposite to the sliding direction
    np.testing.assert_allclose(np.linalg.norm(f_t), 0.5 * abs(f_n), rtol=1e-12)
    np.testing.assert_allclose(f_t / np.linalg.norm(f_t), -v[0, :2] / 50.0, atol=1e-12)
    assert info["n_sliding"] == 1
    np.testing.assert_allclose(info["friction_work"], dt * f_t @ v[0, :2], rtol=1e-12)
    assert info["friction_work"] < 0.0


def test_slow_sliding_friction_does_not_reverse_the_slip():
    m, dt = 1e-7, 1e-7
    _, state, x, v = _face_node([1e-3, 0.0, 0.0])
    contact = PenaltyContact(Projectile(z0=0.0, friction=0.5), damping_ratio=0.0)
    f, _, info = contact.forces(x, v, m, dt, state)
    f_t = f[0, 0]
    assert f_t < 0.0
    assert abs(f_t) < 0.5 * abs(f[0, 2])  # below the Coulomb limit: stick regime
    v_next = v[0, 0] + dt * f_t / m
    assert v_next >= -1e-15  # brought to rest, not reversed
    assert info["n_sliding"] == 0


def test_friction_drags_a_side_node_along_the_moving_projectile():
    proj = Projectile(z0=0.0, friction=2.0)  # thesis Sec. 4.4.1 high friction
    contact = PenaltyContact(proj, damping_ratio=0.0)
    state = ProjectileState(z=0.0, vz=-57.3, mass=proj.mass)
    x = np.array([[proj.radius - 2e-6, 0.0, 0.5 * proj.length]])
    f, fp, _ = contact.forces(x, np.zeros((1, 3)), 1e-7, 1e-7, state)
    assert f[0, 0] > 0.0  # side normal is +x here: pushed radially out
    assert f[0, 2] < 0.0  # dragged along the projectile's motion (-z)
    np.testing.assert_allclose(-f[0, 2], 2.0 * f[0, 0], rtol=1e-12)
    assert fp[2] > 0.0  # and the fabric holds the projectile back


def test_action_equals_reaction_and_energy_bookkeeping():
    rng = np.random.default_rng(7)
    proj = Projectile(fillet=0.8e-3, z0=0.0, axis_xy=(0.001, 0.002))
    contact = PenaltyContact(proj, damping_ratio=0.3)
    state = ProjectileState(z=0.0, vz=-40.0, mass=proj.mass)
    n = 4000
    x = np.column_stack((
        rng.uniform(-0.016, 0.016, n), rng.uniform(-0.016, 0.016, n), rng.uniform(-2e-5, 2e-5, n)
    ))
    x[:200, 0] = proj.axis_xy[0] + proj.radius - rng.uniform(0, 2e-5, 200)  # on the side
    x[:200, 1] = proj.axis_xy[1]
    x[:200, 2] = rng.uniform(0, proj.length, 200)
    v = rng.normal(0.0, 20.0, (n, 3))
    m = rng.uniform(0.5e-7, 2e-7, n)
    dt = 1e-7
    f, fp, info = contact.forces(x, v, m, dt, state)
    assert 100 < info["n_active"] < n
    assert np.array_equal(fp, -f.sum(axis=0))
    # independent recomputation of the stored penalty energy and the normal/tangent split
    g, nrm = proj.gap_and_normal(x, 0.0)
    act = g < 0
    k = stable_penalty(m[act], dt, contact.penalty_fraction, 0.3)
    np.testing.assert_allclose(info["penalty_energy"], 0.5 * np.sum(k * g[act] ** 2), rtol=1e-12)
    fn = np.einsum("ij,ij->i", f[act], nrm[act])
    ft = np.linalg.norm(f[act] - fn[:, None] * nrm[act], axis=1)
    assert np.all(fn >= 0.0)  # never pulls
    assert np.all(ft <= 0.5 * fn * (1 + 1e-12))  # Coulomb cone
    assert np.all(f[~act] == 0.0)
    assert info["friction_work"] <= 0.0 and info["damping_work"] <= 0.0
    assert info["n_released"] > 0  # some separating nodes would have been pulled back


def _drop(zeta, fraction, offset, u=57.3, m=1e-7, dt=1e-7):
    """A free node of mass m moving at u towards a fixed face, central difference."""
    proj = Projectile(z0=0.0, velocity=0.0, friction=0.0)
    contact = PenaltyContact(proj, damping_ratio=zeta, penalty_fraction=fraction)
    state = ProjectileState.initial(proj)
    x = np.array([[0.003, 0.0, -offset * u * dt]])
    v = np.array([[0.0, 0.0, u]])
    e0 = 0.5 * m * u * u
    energies, damping_work, f_z = [], 0.0, []
    for _ in range(500):
        f, _, info = contact.forces(x, v, m, dt, state)
        v_new = v + dt * f / m
        if info["n_active"]:
            # the energy central difference conserves for a linear spring
            energies.append(0.5 * m * float(v[0] @ v_new[0]) + info["penalty_energy"])
            f_z.append(f[0, 2])
        damping_work += info["damping_work"]
        v = v_new
        x = x + dt * v
        if x[0, 2] < -2 * u * dt:
            break
    assert v[0, 2] < 0.0, "the node did not come back off the face"
    return e0, 0.5 * m * float(v[0] @ v[0]), np.array(energies), damping_work, np.array(f_z)


@pytest.mark.parametrize("offset", [0.0, 0.37, 0.81])
def test_undamped_bounce_conserves_energy(offset):
    # omega dt = 0.2: energy kept to about (omega dt)^2 / 4 = 1 %
    e0, e_after, energies, damping_work, f_z = _drop(0.0, 0.1, offset)
    assert len(energies) >= 10  # the contact event is resolved in time
    assert np.max(np.abs(energies - e0)) < 0.015 * e0
    assert abs(e_after - e0) < 0.01 * e0
    assert damping_work == 0.0
    assert np.all(f_z <= 0.0)


@pytest.mark.parametrize("offset", [0.0, 0.37, 0.81])
def test_critically_damped_bounce_loses_energy_into_the_booked_damping(offset):
    e0, e_after, energies, damping_work, f_z = _drop(1.0, 0.5, offset)
    assert e_after < 0.05 * e0
    assert np.all(f_z <= 0.0)  # the dashpot never pulls the node back
    assert damping_work < -0.5 * (e0 - e_after)  # the loss is booked as dashpot work


def test_projectile_and_node_conserve_momentum():
    proj = Projectile(z0=1e-6, velocity=100.0, mass=1e-5)  # light, so it visibly slows
    contact = PenaltyContact(proj, damping_ratio=0.5)
    state = ProjectileState.initial(proj)
    m, dt = 1e-6, 1e-8
    x = np.zeros((1, 3))
    v = np.zeros((1, 3))
    p0 = state.mass * state.vz
    e0 = state.kinetic_energy
    work = 0.0
    penalty_energy = 0.0
    for _ in range(300):
        f, fp, info = contact.forces(x, v, m, dt, state)
        v_new = v + dt * f / m
        x = x + dt * v_new
        new = advance(state, fp[2], dt)
        work += contact_work(f, v, v_new, fp, state.vz, new.vz, dt)
        v, state, penalty_energy = v_new, new, info["penalty_energy"]
    assert state.vz > -100.0  # slowed by the node
    assert v[0, 2] < 0.0  # node pushed along
    np.testing.assert_allclose(state.mass * state.vz + m * v[0, 2], p0, rtol=1e-12)
    # the discrete energy balance closes with the exact contact work ...
    e1 = state.kinetic_energy + 0.5 * m * float(v[0] @ v[0])
    np.testing.assert_allclose(e1 - e0, work, rtol=1e-9)
    # ... and the contact, being damped, has dissipated energy beyond what it stores
    assert -work - penalty_energy > 0.0


def test_advance_is_central_difference_under_constant_force():
    state = ProjectileState(z=0.01, vz=-50.0, mass=0.0371)
    f, dt, n = -3.0, 1e-6, 40
    s = state
    for _ in range(n):
        s = advance(s, f, dt)
    a = f / state.mass
    np.testing.assert_allclose(s.vz, state.vz + n * dt * a, rtol=1e-12)
    np.testing.assert_allclose(s.z, state.z + n * dt * state.vz + a * dt**2 * n * (n + 1) / 2,
                               rtol=1e-12)


@pytest.mark.parametrize("zeta", [0.0, 0.5, 1.0, 2.0])
def test_critical_omega_dt_is_the_stability_limit(zeta):
    def spectral_radius(wdt):
        a, b = wdt**2, 2 * zeta * wdt
        return max(abs(np.linalg.eigvals(np.array([[1 - a, 1 - b], [-a, 1 - b]]))))

    w = critical_omega_dt(zeta)
    assert spectral_radius(0.99 * w) <= 1.0 + 1e-12
    assert spectral_radius(1.01 * w) > 1.0 + 1e-6
    k = stable_penalty(2e-7, 1e-7, 1.0, zeta)
    np.testing.assert_allclose(math.sqrt(k / 2e-7) * 1e-7, w, rtol=1e-12)


def test_sharp_corner_has_no_nan_and_picks_the_shallower_surface():
    proj = Projectile(fillet=0.0, z0=0.0)
    R = proj.radius
    x = np.array([
        [R, 0.0, 0.0],  # the corner itself
        [R - 1e-6, 0.0, 1e-6],  # inside on the diagonal: tie, face wins
        [R - 2e-6, 0.0, 1e-6],  # nearer the face
        [R - 1e-6, 0.0, 2e-6],  # nearer the side
        [R + 1e-6, 0.0, -1e-6],  # outside on the diagonal
        [0.0, 0.0, 1e-6],  # on the axis
        [0.0, 0.0, 0.5 * proj.length],  # on the axis at mid-height
    ])
    g, n = proj.gap_and_normal(x, 0.0)
    assert np.all(np.isfinite(g)) and np.all(np.isfinite(n))
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-12)
    np.testing.assert_allclose(n[[1, 2, 5]], [[0, 0, -1]] * 3, atol=1e-12)
    np.testing.assert_allclose(n[3], [1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(n[4], [math.sqrt(0.5), 0, -math.sqrt(0.5)], atol=1e-9)
    np.testing.assert_allclose(g[:5], [0.0, -1e-6, -1e-6, -1e-6, math.sqrt(2) * 1e-6],
                               atol=1e-15)
    contact = PenaltyContact(proj)
    f, fp, _ = contact.forces(x[:6], np.zeros((6, 3)), 1e-7, 1e-7,
                              ProjectileState(z=0.0, vz=-50.0, mass=proj.mass))
    assert np.all(np.isfinite(f)) and np.all(np.isfinite(fp))


def test_may_touch():
    proj = Projectile(z0=2e-3)
    assert not proj.may_touch(0.0)
    assert proj.may_touch(0.0, z_face=-1e-3)  # perforated: still rubbing on the side
    assert proj.may_touch(0.0, margin=2.5e-3)
    assert proj.may_touch(2e-3)


def test_too_deep_penetration_raises():
    proj = Projectile(z0=0.0)
    x = np.array([[0.0, 0.0, 2e-3]])  # 2 mm inside the face
    with pytest.raises(RuntimeError, match="penetrates"):
        PenaltyContact(proj).forces(x, np.zeros((1, 3)), 1e-7, 1e-7,
                                    ProjectileState.initial(proj))


@pytest.mark.parametrize(
    "field, value",
    [
        ("diameter", 0.0), ("diameter", -0.01), ("diameter", float("nan")),
        ("length", 0.0), ("mass", -1.0), ("velocity", float("inf")),
        ("fillet", -1e-4), ("fillet", 5e-3),  # > length / 2
        ("friction", -0.1), ("axis_xy", (0.0,)), ("axis_xy", (0.0, float("nan"))),
        ("z0", float("nan")),
    ],
)
def test_bad_projectile_parameters_raise(field, value):
    with pytest.raises(ValueError, match=field):
        Projectile(**{field: value})


def test_bad_contact_parameters_raise():
    proj = Projectile(z0=0.0)
    with pytest.raises(ValueError, match="damping_ratio"):
        PenaltyContact(proj, damping_ratio=-0.1)
    with pytest.raises(ValueError, match="penalty_fraction"):
        PenaltyContact(proj, penalty_fraction=0.6)
    with pytest.raises(ValueError, match="friction"):
        PenaltyContact(proj, friction=-1.0)
    with pytest.raises(ValueError, match="dt"):
        stable_penalty(1e-7, 0.0)
    with pytest.raises(ValueError, match="nodal_mass"):
        stable_penalty(np.array([1e-7, 0.0]), 1e-7)
    state = ProjectileState.initial(proj)
    x = np.array([[0.0, 0.0, 1e-6]])
    contact = PenaltyContact(proj)
    with pytest.raises(ValueError, match="x must have shape"):
        contact.forces(x[0], np.zeros(3), 1e-7, 1e-7, state)
    with pytest.raises(ValueError, match="nodal_mass"):
        contact.forces(x, np.zeros((1, 3)), -1e-7, 1e-7, state)
    with pytest.raises(ValueError, match="x has non-finite"):
        contact.forces(x * np.nan, np.zeros((1, 3)), 1e-7, 1e-7, state)
    stiff = PenaltyContact(proj, penalty=1e9)  # far beyond m (1/dt)^2 = 1e7 N/m
    with pytest.raises(ValueError, match="penalty .* exceeds"):
        stiff.forces(x, np.zeros((1, 3)), 1e-7, 1e-7, state)
    with pytest.raises(ValueError, match="mass"):
        ProjectileState(z=0.0, vz=0.0, mass=0.0)
