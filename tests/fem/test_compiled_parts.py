"""The compiled parts of an explicit step against the expressions they replace: the yarn
strains against DOLFINx's evaluation of the UFL expression, the gathered coefficients against
DOLFINx's packing, the contact force law, the node pass of the end tests and the
central-difference update against their numpy formulas."""
import numpy as np
import pytest
from dolfinx import fem, mesh
from dolfinx.cpp.fem import pack_coefficients
from dolfinx.fem import petsc as fem_petsc
from mpi4py import MPI
from petsc4py import PETSc

from fabric_fenicsx.impact.removal import _node_extremes as node_extremes
from fabric_fenicsx.fem import explicit
from fabric_fenicsx.fem.explicit import CentralDifference, LinearYarnMaterial
from fabric_fenicsx.fem.membrane import Membrane
from fabric_fenicsx.fem.packing import CoefficientPacker, _pack_columns
from fabric_fenicsx.fem.projectile import PenaltyContact, Projectile, ProjectileState
from fabric_fenicsx.fem.terms import HourglassControl, IsotropicShear

A = 0.05


def membrane(cell, angle, degree, distort=0.2, seed=1):
    kind = {"quadrilateral": mesh.CellType.quadrilateral, "triangle": mesh.CellType.triangle}[cell]
    msh = mesh.create_rectangle(MPI.COMM_WORLD, [[-A, -A], [A, A]], [6, 5], kind)
    x = msh.geometry.x
    inner = (np.abs(x[:, 0]) < A - 1e-12) & (np.abs(x[:, 1]) < A - 1e-12)
    x[inner, :2] += distort * (2 * A / 6) * np.random.default_rng(seed).uniform(-1, 1, (inner.sum(), 2))
    m = Membrane(msh, angle=angle, quadrature_degree=degree)
    rng = np.random.default_rng(seed)
    m.set_displacement(0.002 * rng.standard_normal(m.n_owned_dofs))
    return m


@pytest.mark.parametrize("cell, degree", [("quadrilateral", 1), ("quadrilateral", 2), ("triangle", 2)])
@pytest.mark.parametrize("angle", [0.0, 0.7])
def test_point_strains_equal_the_ufl_expression(cell, degree, angle):
    m = membrane(cell, angle, degree)
    E1, E2 = m.yarn_strains()
    R1, R2 = m.yarn_strains_expression()
    assert E1.shape == (m.n_points,) and np.ptp(E1) > 1e-3   # a real, non-uniform strain field
    # Round-off of a sum in another order: relative to the field's scale, since a strain near
    # zero is a difference of terms of that scale (3e-16 apart at 2e-4 on one CPU).
    for E, R in ((E1, R1), (E2, R2)):
        np.testing.assert_allclose(E, R, rtol=1e-13, atol=1e-13 * np.abs(R).max())


@pytest.mark.parametrize("cell, degree", [("quadrilateral", 1), ("triangle", 2)])
def test_gathered_coefficients_and_force_equal_dolfinx_packing(cell, degree):
    m = membrane(cell, 0.3, degree)
    if cell == "quadrilateral":
        m.add_term(HourglassControl(0.05, 1e5))
    m.add_term(IsotropicShear(2e3))
    rng = np.random.default_rng(2)
    m.set_stress(rng.uniform(0, 1e4, m.n_points), rng.uniform(0, 1e4, m.n_points))
    f = m.internal_force()
    assert all(p.gathers for p in m._packers)
    for form, packer in zip(m._form, m._packers):
        mine, ref = packer.pack(), pack_coefficients(form)
        assert mine.keys() == ref.keys()
        for key in ref:
            assert np.array_equal(mine[key], ref[key])
    # the force with DOLFINx packing its coefficients itself is the same, bit for bit
    b = m._b.duplicate()
    with b.localForm() as bl:
        bl.set(0.0)
    for form in m._form:
        fem_petsc.assemble_vector(b, form)
    with b.localForm() as bl:
        for term in m._per_cell_terms:
            term.add_cell_forces(m, bl.array_w.reshape(-1, 3))
    b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    assert np.abs(f).max() > 0 and np.array_equal(f, b.array_r)
    # after a change of the displacement the gather follows it
    m.set_displacement(m.u.x.array[:m.n_owned_dofs] * 1.5)
    for form, packer in zip(m._form, m._packers):
        ref = pack_coefficients(form)
        assert all(np.array_equal(packer.pack()[k], ref[k]) for k in ref)


def _copy_and_take(packer):
    """The packing by a copy of the arrays into one source and numpy's take (the general path)."""
    source = np.concatenate(packer._arrays)
    return {key: np.take(source, index) for key, index in packer._index.items()}


def _special_values(rng, n):
    """n random values with zeros of both signs, NaN, infinities and subnormals among them."""
    x = rng.standard_normal(n) * 10.0 ** rng.integers(-300, 300, n)
    pick = rng.integers(0, 7, n)
    for k, v in enumerate((0.0, -0.0, np.nan, np.inf, -np.inf, 5e-324)):
        x[pick == k] = v
    return x


def test_packing_from_the_arrays_equals_copy_and_take():
    """The membrane's forms pack from the Functions' arrays in one pass (no source copy): the
    bits of the copy-and-take packing, for values with both zeros, NaN and infinities."""
    m = membrane("quadrilateral", 0.3, 1)
    m.add_term(HourglassControl(0.05, 1e5))
    m.internal_force()
    assert all(p.gathers and p._columns for p in m._packers)
    rng = np.random.default_rng(7)
    for _ in range(20):
        for packer in m._packers:
            for a in packer._arrays:
                a[:] = _special_values(rng, a.size)
            mine, ref = packer.pack(), _copy_and_take(packer)
            assert mine.keys() == ref.keys()
            for key in ref:
                assert np.array_equal(mine[key].view(np.int64), ref[key].view(np.int64))


def test_pack_columns_kernel_equals_numpy_take():
    rng = np.random.default_rng(8)
    for n_cells, width, n_copied in ((1, 1, 1), (7, 12, 3), (50, 6, 2)):
        a = _special_values(rng, 40)
        copied = tuple(_special_values(rng, n_cells) for _ in range(n_copied))
        index = rng.integers(0, a.size, (n_cells, width)).astype(np.uint32)
        first = int(rng.integers(0, n_copied + 1))     # the gathered block between the columns
        columns = np.array([c if c < first else c + width for c in range(n_copied)], np.int64)
        out = np.full((n_cells, width + n_copied), 1.5)
        _pack_columns(a, index, first, copied, columns, out)
        ref = np.empty_like(out)
        ref[:, first:first + width] = np.take(a, index.astype(np.int64))
        for b, c in zip(copied, columns):
            ref[:, c] = b
        assert np.array_equal(out.view(np.int64), ref.view(np.int64))


def test_bounded_values_equal_numpy_and_their_sum_is_finite():
    """The step's finiteness test: the compiled bound test against numpy's, and where it holds
    the numpy sums the step made before are finite; where it fails the step sums as before."""
    rng = np.random.default_rng(9)
    for trial in range(300):
        n = [int(k) for k in rng.integers(0, 40, 4)]
        arrays = [rng.standard_normal(k) * 10.0 ** rng.uniform(-5, 308, k) for k in n]
        bound = explicit._SUM_BOUND / (sum(n) + 1)
        for x in arrays:   # values at the bound, zeros of both signs, NaN, infinities
            if x.size:
                x[rng.integers(0, x.size)] = rng.choice([bound, -bound, np.nextafter(bound, np.inf),
                                                         0.0, -0.0, np.nan, np.inf, -np.inf, 1.0])
        want = bool(np.all(np.abs(np.concatenate(arrays)) <= bound))
        assert explicit._small(*arrays) == want
        if want:
            assert np.isfinite(explicit._point_sums(*arrays))
    big = [np.full(10, 1.7e307), np.full(10, 1.7e307), np.zeros(1), np.zeros(1)]
    with np.errstate(over="ignore"):
        assert not explicit._small(*big) and not np.isfinite(explicit._point_sums(*big))
    assert not explicit._small(np.zeros(2, np.float32), np.zeros(2), np.zeros(2), np.zeros(2))


def test_non_finite_stress_raises_with_the_sums():
    m = membrane("quadrilateral", 0.2, 1)

    class NaNYarns(LinearYarnMaterial):
        def update(self, E1, E2, dt=0.0):
            P1, P2 = super().update(E1, E2, dt)
            P1[3] = np.nan
            return P1, P2

    cd = CentralDifference(m, NaNYarns(1e5, 8e4), 0.2, np.array([0, 1, 2]))
    with pytest.raises(FloatingPointError, match=r"strain/stress sums = \[.*nan\]"):
        cd.step(1e-6)


def test_non_finite_work_reports_the_strain_and_stress_sum():
    """Where the strains and stresses are small their sum is not made during the step, but the
    message of a non-finite step still shows it."""
    m = membrane("quadrilateral", 0.2, 1)
    cd = CentralDifference(m, LinearYarnMaterial(1e5, 8e4), 0.2, np.array([0, 1, 2]))
    cd.step(1e-6)
    f_ext = np.zeros(m.n_owned_dofs)
    f_ext[5] = np.inf
    with pytest.raises(FloatingPointError) as error:
        cd.step(1e-6, f_ext)
    fields = cd.material.point_fields()
    total = explicit._point_sums(fields["E1"], fields["E2"], fields["P1"], fields["P2"])
    shown = str(error.value).split("sums = [")[1].split("]")[0].split()
    assert total != 0.0 and float(shown[-1]) == pytest.approx(total, rel=1e-7)


def test_packer_falls_back_where_the_values_are_transformed():
    msh = mesh.create_unit_square(MPI.COMM_WORLD, 2, 2)
    V = fem.FunctionSpace(msh, ("N1curl", 1))   # edge dofs carry signs: not a plain gather
    g = fem.Function(V)
    import ufl
    form = fem.form(ufl.inner(g, g) * ufl.TestFunction(fem.FunctionSpace(msh, ("DG", 0))) * ufl.dx)
    packer = CoefficientPacker(form)
    g.x.array[:] = np.random.default_rng(0).standard_normal(g.x.array.size)
    ref = pack_coefficients(form)
    assert all(np.array_equal(packer.pack()[k], ref[k]) for k in ref)


def _numpy_contact(contact, x, v, m, dt, state):
    """The force law of PenaltyContact.forces as numpy expressions (the formulas before it was
    compiled)."""
    proj = contact.projectile
    idx = np.flatnonzero(proj.candidates(x, state.z))
    gap, nrm = proj.gap_and_normal(x[idx], state.z)
    inside = gap < 0
    idx, pen, nrm = idx[inside], -gap[inside], nrm[inside]
    mm = m[idx]
    k = contact._stiffness(mm, dt, idx, x.shape[0])
    c = 2.0 * contact.damping_ratio * np.sqrt(k * mm)
    v_rel = v[idx].copy()
    v_rel[:, 2] -= state.vz
    vn = np.einsum("ij,ij->i", v_rel, nrm)
    elastic = k * pen
    fn = np.maximum(elastic - c * vn, 0.0)
    v_t = v_rel - vn[:, None] * nrm
    speed = np.linalg.norm(v_t, axis=1)
    coulomb = contact.friction * fn
    stick = mm * speed / dt
    ft = np.minimum(coulomb, stick)
    f_t = -ft[:, None] * (v_t / np.where(speed > 0, speed, 1.0)[:, None])
    f = np.zeros_like(x)
    f[idx] = fn[:, None] * nrm + f_t
    info = dict(penalty_energy=0.5 * np.sum(k * pen * pen), friction_work=dt * np.einsum("ij,ij->", f_t, v_rel),
                damping_work=dt * np.sum((fn - elastic) * vn), n_active=idx.size,
                n_released=np.count_nonzero(elastic - c * vn < 0), n_sliding=np.count_nonzero((coulomb <= stick) & (ft > 0)),
                max_penetration=pen.max(), normal_force=fn.sum(), friction_force=ft.sum())
    return f, -f.sum(axis=0), info


@pytest.mark.parametrize("friction, fillet", [(0.5, 0.0), (2.0, 2e-3), (0.0, 0.0)])
def test_contact_kernel_equals_the_numpy_force_law(friction, fillet):
    rng = np.random.default_rng(3)
    proj = Projectile(diameter=0.0254, fillet=fillet, friction=friction)
    contact = PenaltyContact(proj)
    state = ProjectileState(z=0.0, vz=-50.0, mass=proj.mass)
    n = 400
    x = np.column_stack((rng.uniform(-0.015, 0.015, (n, 2)), rng.uniform(-5e-6, 2e-5, n)))
    v = rng.normal(0, 30, (n, 3))
    v[:5] = [0.0, 0.0, state.vz]   # no sliding at all
    m = rng.uniform(1e-6, 3e-6, n)
    f, fp, info = contact.forces(x, v, m, 1e-7, state)
    rf, rfp, rinfo = _numpy_contact(contact, x, v, m, 1e-7, state)
    assert info["n_active"] > 50 and info["n_released"] > 0 and (friction == 0 or info["n_sliding"] > 0)
    np.testing.assert_allclose(f, rf, rtol=1e-13, atol=1e-9)
    np.testing.assert_allclose(fp, rfp, rtol=1e-12)
    for key, value in rinfo.items():
        assert info[key] == pytest.approx(value, rel=1e-12, abs=1e-15), key


def test_node_pass_equals_the_numpy_masks():
    rng = np.random.default_rng(4)
    n = 500
    X = np.column_stack((rng.uniform(-0.02, 0.02, (n, 2)), np.zeros(n)))
    u = rng.normal(0, 2e-3, 3 * n)
    live, free = rng.random(n) < 0.8, rng.random(n) < 0.2
    z_max, front, moved = node_extremes(X, u, live, free, 0.001, -0.002, 0.0127, 1e-3)
    x = X + u.reshape(-1, 3)
    attached = live & ~free
    r2 = (x[:, 0] - 0.001) ** 2 + (x[:, 1] + 0.002) ** 2
    assert z_max == x[live, 2].max()
    assert front == np.count_nonzero(attached & (r2 < 0.0127 ** 2) & (x[:, 2] < 1e-3)) > 0
    assert moved == np.abs(u.reshape(-1, 3)[attached]).max()
    assert node_extremes(X, u, np.zeros(n, bool), free, 0, 0, 0.01, 0.0)[0] == -np.inf


def test_central_difference_update_equals_the_numpy_formulas():
    """Two steps of a damped, loaded membrane: u, v and every energy against the scheme's
    formulas written with numpy (module docstring of fabric_fenicsx.fem.explicit)."""
    m = membrane("quadrilateral", 0.2, 2, distort=0.1)
    u0 = m.u.x.array[:m.n_owned_dofs].copy()
    cd = CentralDifference(m, LinearYarnMaterial(1e5, 8e4), 0.2, np.array([0, 1, 2]), damping=1e-6)
    rng = np.random.default_rng(5)
    f_ext = rng.normal(0, 1e-3, m.n_owned_dofs)
    dts = (2e-6, 1.5e-6, 1e-6)
    u, v, f_prev, works = u0.copy(), np.zeros_like(u0), np.zeros_like(u0), np.zeros(4)
    du, f_ext_prev, f_damp_prev, dt_prev = np.zeros_like(u0), np.zeros_like(u0), np.zeros_like(u0), 0.0
    inv = np.where(cd.free, 1.0 / cd.mass, 0.0)
    for dt in dts:
        m.set_displacement(u)
        E1, E2 = m.yarn_strains()
        P1, P2 = LinearYarnMaterial(1e5, 8e4).constitutive_update(E1, E2, None)[:2]
        m.set_stress(P1, P2)
        f_int = m.internal_force()
        f_damp = (1e-6 / dt_prev) * (f_int - f_prev) if dt_prev else np.zeros_like(u)
        acc = (f_ext - f_int - f_damp) * inv
        works += [0.5 * np.dot(f_int + f_prev, du), 0.5 * np.dot(f_ext + f_ext_prev, du),
                  0.5 * np.dot(f_damp + f_damp_prev, du), 0.0]
        v_full = v + 0.5 * dt_prev * acc
        kinetic = 0.5 * np.dot(cd.mass * v_full, v_full)
        v = v + 0.5 * (dt_prev + dt) * acc
        du = dt * v
        u = u + du
        f_prev, f_ext_prev, f_damp_prev, dt_prev = f_int, f_ext, f_damp, dt
        m.set_displacement(cd.u.copy())   # the integrator's own state
        record = cd.step(dt, f_ext)
        assert record.kinetic == pytest.approx(kinetic, rel=1e-12, abs=1e-30)
        assert record.internal == pytest.approx(works[0], rel=1e-12, abs=1e-30)
        assert record.external == pytest.approx(works[1], rel=1e-12, abs=1e-30)
        assert record.damping == pytest.approx(works[2], rel=1e-12, abs=1e-30)
        np.testing.assert_allclose(cd.u, u, rtol=1e-13, atol=1e-18)
        np.testing.assert_allclose(cd.v, v, rtol=1e-12, atol=1e-15)
    assert works[0] != 0 and works[2] != 0


def test_one_rank_skips_only_scatters_that_change_nothing():
    """On one rank there are no ghosts: the steps without the scatters, the ghost update and the
    energies' Allreduce (``Membrane.parallel`` False) give the bits of the steps with them."""
    if MPI.COMM_WORLD.size > 1:
        pytest.skip("the skip is for one rank")
    runs = []
    for parallel in (True, False):
        m = membrane("quadrilateral", 0.3, 1, distort=0.1)
        m.add_term(HourglassControl(0.05, 1e5))
        assert m.parallel is False and m.V.dofmap.index_map.num_ghosts == 0
        m.parallel = parallel
        cd = CentralDifference(m, LinearYarnMaterial(1e5, 8e4), 0.2, np.array([0, 1, 2]), damping=1e-6)
        f_ext = np.random.default_rng(6).normal(0, 1e-3, m.n_owned_dofs)
        records = [cd.step(dt, f_ext) for dt in (2e-6, 1.5e-6, 1e-6)]
        runs.append((cd.u.copy(), cd.v.copy(), m.internal_force(), records))
    (u, v, f, rec), (u2, v2, f2, rec2) = runs
    assert np.abs(f).max() > 0 and np.array_equal(u, u2) and np.array_equal(v, v2)
    assert np.array_equal(f, f2) and rec == rec2


def test_least_integrity_equals_numpy_min():
    """The step's smallest integrities (impact.ledger.least) against numpy's min with an initial
    value: the same value, NaN where one is; the yarn damage 1 - min the same bits (of two equal
    zeros either may be numpy's result, and 1 - 0 is 1 for both)."""
    from fabric_fenicsx.impact.ledger import least

    rng = np.random.default_rng(7)
    for n in (0, 1, 5, 64, 6000):
        for special in (None, 0.0, -0.0, np.nan, 1.0, 1.5, 1e-300):
            a = np.where(rng.random(n) < 0.7, 1.0, rng.uniform(0.0, 1.0, n))
            if special is not None and n:
                a[rng.random(n) < 0.05] = special
            for view in (a, a[::3]):
                got, want = least(view, 1.0), view.min(initial=1.0)
                assert (got == want) or (np.isnan(got) and np.isnan(want))
                x, y = 1.0 - float(got), 1.0 - float(want)
                assert np.float64(x).tobytes() == np.float64(y).tobytes() or (np.isnan(x) and np.isnan(y))


def test_one_rank_reduction_equals_the_allreduce():
    """reduce_named on one rank returns the values as MPI's sum and max over that rank would."""
    from fabric_fenicsx.impact.ledger import reduce_named

    comm = MPI.COMM_WORLD
    if comm.size > 1:
        pytest.skip("the shortcut is for one rank")
    values = {"a": 1.5, "b": -0.0, "c": 3, "d": np.float64(np.nan), "e": np.inf, "f": 1e-310}
    for op in (MPI.SUM, MPI.MAX):
        local = np.array(list(values.values()), dtype=float)
        total = np.empty_like(local)
        comm.Allreduce(local, total, op=op)
        got = reduce_named(comm, values, op=op)
        assert list(got) == list(values)
        assert all(type(x) is type(y) and np.float64(x).tobytes() == np.float64(y).tobytes()
                   for x, y in zip(got.values(), total))
