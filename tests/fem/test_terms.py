"""Tests of the membrane's weak-form terms (fabric_fenicsx.fem.terms) as the rest of the model
sees them: the shear term's share of the explicit stable step, measured against the true highest
frequency of the discrete membrane; the live-cell mask switching every term off in a removed cell;
the energy balance of an impact run with a shear term; and the refusal of bad terms.
"""
import math

import numpy as np
import pytest
from dolfinx import fem
from dolfinx.fem import petsc as fem_petsc
from mpi4py import MPI
from petsc4py import PETSc

from fabric_fenicsx.fem.explicit import CentralDifference, LinearYarnMaterial
from fabric_fenicsx.fem.membrane import Membrane
from fabric_fenicsx.fem.mesh import uniform_square
from fabric_fenicsx.fem.terms import IsotropicShear, MembraneTerm, YarnTerm
from fabric_fenicsx.impact.scene import build_scene
from fabric_fenicsx.impact.simulation import ImpactSimulation

serial_only = pytest.mark.skipif(MPI.COMM_WORLD.size > 1, reason="dense serial matrices")

SIDE = 0.06      # side of the square test patch (m)
K_YARN = 1.0e5   # yarn stiffness dP/dlambda (N/m)
RHO_A = 0.158    # areal density (kg/m^2)
G_SHEAR = 5.0e4  # shear modulus of the isotropic shear term (N/m)
STRETCH = 0.01   # uniform equibiaxial prestretch: both yarns in tension

# The tiny impact scene of tests/test_impact.py (copied, not imported): an 8 cm Y90-like square of
# 16 x 16 cells hit by a light 20 mm projectile, damage off.
TINY = {
    "description": "tiny test scene",
    "material": {"angle": 90.0, "damage": False},
    "mesh": {"kind": "uniform", "side": 0.08, "n": 16},
    "projectile": {"diameter": 0.02, "velocity": 20.0, "mass": 0.005},
    "boundary": {"clamped": ["bottom", "top"]},
    "run": {"t_end": 3e-4},
    "output": {"xdmf_interval": 0.0, "png": False, "progress_interval": 0.0},
}


def tiny(overrides=()):
    return build_scene(TINY, list(overrides), "tiny.toml")


def patch(n, G=0.0, clamp=False, angle=0.0):
    """A uniform n x n patch, uniformly prestretched by STRETCH, with linear yarns (K_YARN, K_YARN)
    and, for G > 0, an isotropic shear term; its CentralDifference (no damping) and material."""
    msh, _, _ = uniform_square(n, SIDE, MPI.COMM_WORLD)
    m = Membrane(msh, angle=angle)
    if G > 0:
        m.add_term(IsotropicShear(G))
    a = SIDE / 2
    clamped = (m.boundary_dofs(lambda x: np.isclose(np.abs(x[0]), a) | np.isclose(np.abs(x[1]), a))
               if clamp else np.zeros(0, dtype=np.int32))
    material = LinearYarnMaterial(K_YARN, K_YARN)
    cd = CentralDifference(m, material, RHO_A, clamped, damping=0.0)
    m.set_displacement(m.interpolate_owned(
        lambda x: np.vstack([STRETCH * x[0], STRETCH * x[1], 0 * x[0]])))
    return cd, material


def internal_force(m, material):
    """u -> yarn strains -> material -> stresses -> f_int (every term)."""
    E1, E2 = m.yarn_strains()
    P1, P2 = material.update(E1, E2)
    m.set_stress(P1, P2)
    return m.internal_force()


def tangent_stiffness(cd, material):
    """K = d f_int / d u on the free dofs by central differences of the full
    strain -> material -> force chain (the yarn stresses follow u, as in a step)."""
    m = cd.membrane
    u0 = cd.u.copy()
    free = np.flatnonzero(cd.free)
    eps = 1e-7 * m.min_edge_length()
    K = np.zeros((free.size, free.size))
    for j, d in enumerate(free):
        up, um = u0.copy(), u0.copy()
        up[d] += eps
        um[d] -= eps
        m.set_displacement(up)
        f_plus = internal_force(m, material)
        m.set_displacement(um)
        f_minus = internal_force(m, material)
        K[:, j] = (f_plus - f_minus)[free] / (2 * eps)
    m.set_displacement(u0)
    return K, free


def critical_step(cd, material):
    """The true stability limit 2 / omega_max of the central-difference scheme: omega_max^2 the
    largest eigenvalue of M^-1 K with the lumped mass M; also the tangent's asymmetry."""
    K, free = tangent_stiffness(cd, material)
    asym = np.abs(K - K.T).max() / np.abs(K).max()
    s = 1.0 / np.sqrt(cd.mass[free])
    A = s[:, None] * K * s[None, :]
    omega2 = np.linalg.eigvalsh(0.5 * (A + A.T))
    return 2.0 / math.sqrt(omega2.max()), asym


# ------------------------------------------------------------------ 1. the stable time step
@serial_only
def test_shear_term_raises_the_wave_modulus_and_shortens_the_stable_step():
    # The formula: the term's modulus adds to the material's, dt ~ h / sqrt(modulus / rho_A).
    cd, _ = patch(8, clamp=True)
    m = cd.membrane
    h = SIDE / 8
    assert m.terms_wave_modulus() == 0.0                     # the yarn term adds nothing itself
    dt_yarns = cd.stable_dt(1.0)
    assert dt_yarns == pytest.approx(h / math.sqrt(K_YARN / RHO_A), rel=1e-12)
    m.add_term(IsotropicShear(G_SHEAR))
    assert m.terms_wave_modulus() == pytest.approx(G_SHEAR, rel=1e-15)
    dt_shear = cd.stable_dt(1.0)
    assert dt_shear == pytest.approx(h / math.sqrt((K_YARN + G_SHEAR) / RHO_A), rel=1e-12)
    assert dt_shear / dt_yarns == pytest.approx(math.sqrt(K_YARN / (K_YARN + G_SHEAR)), rel=1e-12)
    m.add_term(IsotropicShear(0.5 * G_SHEAR))                # moduli of several terms add up
    assert m.terms_wave_modulus() == pytest.approx(1.5 * G_SHEAR, rel=1e-15)

    # The physics, independently of that formula: the highest frequency of the discrete membrane
    # (tangent of the whole strain -> material -> force chain, lumped mass) on a free 6 x 6 patch
    # in 1 % equibiaxial tension. Free edges make the yarn-direction zigzag mode an exact
    # eigenmode, so without shear the Courant estimate with h_min is exact.
    cd0, mat0 = patch(6)
    crit0, asym0 = critical_step(cd0, mat0)
    cdG, matG = patch(6, G=G_SHEAR)
    critG, asymG = critical_step(cdG, matG)
    assert asym0 < 1e-8 and asymG < 1e-8                      # hyperelastic: symmetric tangent
    assert crit0 == pytest.approx(cd0.stable_dt(1.0), rel=1e-6)   # measured: 1 + 3e-10
    assert critG < crit0                                      # the shear term stiffens the membrane
    # Measured: critG / crit0 = 0.809 against sqrt(k / (k + G)) = 0.8165 from the wave moduli,
    # i.e. critG = 0.991 stable_dt(1): at G = k/2 the estimate G for the shear term is 0.9 %
    # short of the discrete stiffness (the Q1 / lumped mass shear modes are stiffer than the
    # wave speed says), well inside the default safety factor 0.9.
    ratio = critG / cdG.stable_dt(1.0)
    assert 0.98 <= ratio <= 1.5, ratio
    assert cdG.stable_dt() < critG                            # the default step (safety 0.9) is stable
    assert critG / crit0 == pytest.approx(math.sqrt(K_YARN / (K_YARN + G_SHEAR)), rel=0.02)


# ------------------------------------------------------------------ 2. removed cells
def cell_force(m, indicator_cells, terms=None):
    """Assembly of the membrane's terms (or `terms`) over the cells `indicator_cells` only, with
    a DG0 indicator built here (not the membrane's live mask), at the current u, P1, P2."""
    chi = fem.Function(m.live.function_space)
    W = chi.function_space
    chi.x.array[W.dofmap.list.array[np.asarray(indicator_cells, dtype=np.int64)]] = 1.0
    chi.x.scatter_forward()
    form = fem.form(sum(chi * t.integrand(m) * m.dx for t in (terms or m.terms)))
    b = fem_petsc.assemble_vector(form)
    b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    out = b.array_r.copy()
    b.destroy()
    return out


@serial_only
def test_a_removed_cell_carries_no_force_from_any_term():
    n = 6
    msh, _, _ = uniform_square(n, SIDE, MPI.COMM_WORLD)
    m = Membrane(msh, angle=math.radians(30.0))
    shear = m.add_term(IsotropicShear(G_SHEAR))
    material = LinearYarnMaterial(K_YARN, K_YARN)
    h = SIDE / n
    rng = np.random.default_rng(7)
    u = m.interpolate_owned(lambda x: np.vstack([STRETCH * x[0], STRETCH * x[1], 0 * x[0]]))
    u += 2e-3 * h * rng.uniform(-1, 1, u.size)     # non-uniform: every cell sheared
    m.set_displacement(u)

    cells = m.V.dofmap.list.array.reshape(-1, 4)[:m.n_cells]
    xy = m.V.tabulate_dof_coordinates()[:, :2]
    interior = np.all(np.abs(xy[cells]) < SIDE / 2 - 1e-9, axis=(1, 2))
    c = int(np.flatnonzero(interior)[0])           # a cell with no node on the boundary
    npc = m.n_points_per_cell
    points = np.arange(c * npc, (c + 1) * npc)
    others = np.setdiff1d(np.arange(m.n_cells), [c])

    f_before = internal_force(m, material)
    E1, E2 = m.yarn_strains()
    P1, P2 = material.update(E1, E2)
    assert np.all(P1 > 0) and np.all(P2 > 0)       # both yarns in tension everywhere
    f_cell = cell_force(m, [c])
    f_cell_shear = cell_force(m, [c], [shear])
    f_others = cell_force(m, others)
    scale = np.abs(f_before).max()
    # the cell alone: a free body (its nodal forces sum to zero), loaded at all four nodes,
    # by the yarns and by the shear term
    by_node = f_cell.reshape(-1, 3)
    assert np.all(np.abs(by_node[cells[c]]).sum(axis=1) > 1e-3 * scale)
    assert np.abs(by_node.sum(axis=0)).max() < 1e-12 * scale
    assert np.abs(f_cell_shear).max() > 1e-2 * np.abs(f_cell).max()
    assert np.abs(f_cell - f_cell_shear).max() > 1e-2 * np.abs(f_cell).max()
    assert np.allclose(f_cell + f_others, f_before, rtol=0, atol=1e-12 * scale)

    # The live mask alone (the material not told yet, its stresses there still on) switches
    # every term off in the cell.
    m.remove_cells([c])
    f_masked = internal_force(m, material)
    assert np.allclose(f_masked, f_others, rtol=0, atol=1e-12 * scale)
    assert np.allclose(f_before - f_masked, f_cell, rtol=0, atol=1e-12 * scale)
    changed = np.abs(f_before - f_masked).reshape(-1, 3).sum(axis=1) > 1e-9 * scale
    assert set(np.flatnonzero(changed)) == set(cells[c])   # only the cell's own nodes, all four

    # Taking the cell's points out of the material as well changes nothing more.
    material.remove(points)
    f_after = internal_force(m, material)
    assert np.all(m.P1.x.array[points] == 0) and np.all(m.P2.x.array[points] == 0)
    assert np.allclose(f_after, f_masked, rtol=0, atol=1e-12 * scale)

    # The shear term alone (no yarn stress anywhere): removing the cell removes its shear force,
    # so the mask is not applied to the yarn term only.
    m2 = Membrane(msh, angle=math.radians(30.0))
    m2.add_term(IsotropicShear(G_SHEAR))
    m2.set_displacement(u)
    zero = np.zeros(m2.n_points)
    m2.set_stress(zero, zero)
    g_before = m2.internal_force()
    g_cell = cell_force(m2, [c])
    assert np.abs(g_cell).max() > 1e-3 * np.abs(g_before).max()
    m2.remove_cells([c])
    g_after = m2.internal_force()
    gscale = np.abs(g_before).max()
    assert np.allclose(g_before - g_after, g_cell, rtol=0, atol=1e-12 * gscale)
    assert np.allclose(g_after, cell_force(m2, others), rtol=0, atol=1e-12 * gscale)


# ------------------------------------------------------------------ 3. an impact run
def test_energy_balance_with_damage_off_and_a_shear_term(tmp_path):
    G = G_SHEAR
    plain = ImpactSimulation(tiny(), tmp_path / "plain", verbose=False)
    sim = ImpactSimulation(tiny([f"membrane.shear_modulus={G!r}"]), tmp_path / "shear",
                           verbose=False)
    assert [t.name for t in sim.membrane.terms] == ["yarns", "hourglass", "isotropic_shear"]
    assert [t.name for t in plain.membrane.terms] == ["yarns", "hourglass"]   # the reduced element
    s = sim.run()
    e = s["energies"]
    assert s["end_reason"] == "time_limit"
    assert s["energy_error"] < 0.01                            # measured 1.3e-3
    shear_energy = e["membrane_terms"]["isotropic_shear"]
    # the shear term stores energy, and it is part of (not more than) the elastic work
    assert 0.0 < shear_energy < e["elastic_work"]

    # dt_initial ~ 1 / sqrt(modulus), with the stiffness-proportional damping of the run: invert
    # dt = safety 2/omega (sqrt(1 + xi^2) - xi), xi = beta omega / 2, for the material's initial
    # modulus (the run without shear), then predict the step for the material's modulus + G.
    beta, L, rho, safety = plain.material.beta, plain.L_min, plain.rho_A, plain.scene.run.dt_safety
    assert (beta, L, rho, safety) == (sim.material.beta, sim.L_min, sim.rho_A, sim.scene.run.dt_safety)
    a = plain.dt_initial / safety
    omega0 = (2.0 / a) / math.sqrt(1.0 + 2.0 * beta / a)
    k_material = rho * (omega0 * L / 2.0) ** 2

    def damped_step(modulus):
        omega = 2.0 * math.sqrt(modulus / rho) / L
        xi = 0.5 * beta * omega
        return safety * 2.0 / omega * (math.sqrt(1.0 + xi * xi) - xi)

    assert damped_step(k_material) == pytest.approx(plain.dt_initial, rel=1e-12)
    assert s["dt_initial"] < plain.dt_initial
    assert s["dt_initial"] / plain.dt_initial == pytest.approx(
        damped_step(k_material + G) / damped_step(k_material), rel=1e-9)


# ------------------------------------------------------------------ 4. bad terms
def test_bad_terms_are_refused():
    msh, _, _ = uniform_square(2, SIDE, MPI.COMM_WORLD)
    m = Membrane(msh)
    with pytest.raises(TypeError, match="MembraneTerm"):
        m.add_term("isotropic_shear")
    with pytest.raises(TypeError, match="MembraneTerm"):
        m.add_term(IsotropicShear)                  # the class, not a term
    assert len(m.terms) == 1 and isinstance(m.terms[0], YarnTerm)
    for bad in (-1.0, -1, float("nan"), float("inf"), "5e4", None):
        with pytest.raises(ValueError, match="shear_modulus"):
            IsotropicShear(bad)
    assert IsotropicShear(0).wave_modulus() == 0.0  # zero is allowed (the term switched off)
    assert isinstance(m.add_term(IsotropicShear(1.0)), MembraneTerm) and len(m.terms) == 2


def test_the_shear_term_follows_the_integrity_of_the_weaker_yarn():
    """psi = min(alpha1, alpha2) G dev(E) : dev(E) per cell once the term follows a material:
    checked by hand for a uniform simple shear u = (g y, 0, 0), dev(E) : dev(E) = g^2 / 2 +
    g^4 / 8, on cells with alpha (1, 1), (1, 0.25) and (0, 1)."""
    from fabric_fenicsx.material.contract import DamageState

    n, g = 4, 0.02
    msh, _, _ = uniform_square(n, SIDE, MPI.COMM_WORLD)
    m = Membrane(msh)
    shear = m.add_term(IsotropicShear(G_SHEAR))
    m.set_displacement(m.interpolate_owned(lambda x: np.vstack([g * x[1], 0 * x[0], 0 * x[0]])))
    npc, cells = m.n_points_per_cell, m.n_cells
    a1, a2 = np.ones(cells * npc), np.ones(cells * npc)
    k = np.arange(cells) % 3                          # cell kinds 0, 1, 2
    a2[np.repeat(k == 1, npc)] = 0.25
    a1[np.repeat(k == 2, npc)] = 0.0
    shear.follow(lambda: DamageState(a1, a2))
    m.internal_force()                                # builds the forms, then reads the state
    density = G_SHEAR * (g ** 2 / 2 + g ** 4 / 8)
    area = (SIDE / n) ** 2
    weight = MPI.COMM_WORLD.allreduce(float(np.where(k == 0, 1.0, np.where(k == 1, 0.25, 0.0)).sum()),
                                      op=MPI.SUM)
    energy = m.term_energies()["isotropic_shear"]
    assert energy == pytest.approx(weight * area * density, rel=1e-10)
    unscaled = Membrane(msh)
    unscaled.add_term(IsotropicShear(G_SHEAR))
    unscaled.set_displacement(m.u.x.array[:m.n_owned_dofs].copy())
    assert unscaled.term_energies()["isotropic_shear"] == pytest.approx(n * n * area * density, rel=1e-10)
