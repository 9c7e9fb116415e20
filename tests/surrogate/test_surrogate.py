"""The unit-cell surrogate: cache, damage scaling, damage update, range handling.

Most tests use the session's coarse table (``coarse_surrogate`` in tests/conftest.py: h = 0.004,
6 r-nodes), solved once for the whole suite.
"""

import os

import numpy as np
import pytest

from fabric_fenicsx.material.fibril import BundleDamage, ExponentialDamage
from fabric_fenicsx.material.fabric import zylon_as
from fabric_fenicsx.surrogate.table import Surrogate
from fabric_fenicsx.material.unitcell import UnitCell
from conftest import COARSE

FABRIC = zylon_as("max")
P_PEAK = 148e3  # N/m, peak of the uniaxial-strain response (scenario 1)


@pytest.fixture(scope="module")
def cache(surrogate_cache):
    """The folder the shared coarse table is cached in (tests/conftest.py)."""
    return surrogate_cache


@pytest.fixture(scope="module")
def sur(coarse_surrogate):
    assert coarse_surrogate.key == Surrogate(FABRIC, cache_dir=False, **COARSE).key
    return coarse_surrogate


def test_cache_key_changes_with_every_fabric_parameter():
    keys = {Surrogate(FABRIC, cache_dir=False, **COARSE).key}
    variants = []
    for yarn in ("warp", "fill"):
        y = getattr(FABRIC, yarn)
        for field in ("L", "Phi_L", "A0", "B0", "mu_crit"):
            variants.append(FABRIC.with_yarn(yarn, **{field: getattr(y, field) * 1.001}))
    variants += [FABRIC.replace(area=FABRIC.area * 1.001), FABRIC.replace(density=1561.0),
                 FABRIC.replace(damage=type(FABRIC.damage)(beta=125.0))]
    for fab in variants:
        keys.add(Surrogate(fab, cache_dir=False, **COARSE).key)
    keys.add(Surrogate(FABRIC, cache_dir=False, **{**COARSE, "resolution": 0.005}).key)
    keys.add(Surrogate(FABRIC, cache_dir=False, n_elements=16, **COARSE).key)
    assert len(keys) == len(variants) + 3


def test_intact_values_match_direct_solves(sur):
    rng = np.random.default_rng(1)
    E1 = rng.uniform(0.0, 0.045, 40)
    E2 = rng.uniform(-0.01, 0.04, 40)
    damaged_before = sur.built["damaged"].copy()   # the shared table: other tests may have solved some
    P1, P2, mu1, mu2 = sur.evaluate(E1, E2, 1.0, 1.0, tension_only=False)
    cell = UnitCell(FABRIC)
    ref = np.array([[r.P1, r.P2, r.mu1_max] for r in (cell.solve(a, b) for a, b in zip(E1, E2))])
    assert np.max(np.abs(P1 - ref[:, 0])) < 0.01 * P_PEAK
    assert np.max(np.abs(P2 - ref[:, 1])) < 0.01 * P_PEAK
    assert np.max(np.abs(mu1 - ref[:, 2])) < 2e-4
    # frozen intact lookups never solve a tile of the damaged layer
    assert np.array_equal(sur.built["damaged"], damaged_before)


def test_scaling_identity_against_direct_solves(sur):
    """response(E, a1, a2) = a_max response(E, r, weaker yarn), checked on damaged states."""
    rng = np.random.default_rng(2)
    n = 30
    E1 = rng.uniform(0.0, 0.04, n)
    E2 = rng.uniform(0.0, 0.03, n)
    a = rng.uniform(0.3, 1.0, (n, 2))
    P1, P2, _, _ = sur.evaluate(E1, E2, a[:, 0], a[:, 1], tension_only=False)
    cell = UnitCell(FABRIC)
    ref = np.array([[r.P1, r.P2] for r in (cell.solve(E1[k], E2[k], tuple(a[k])) for k in range(n))])
    assert np.max(np.abs(np.c_[P1, P2] - ref)) < 0.01 * P_PEAK


def test_second_instance_loads_from_cache(sur, cache):
    sur.evaluate(0.01, 0.01, 1.0, 1.0)
    again = Surrogate(FABRIC, cache_dir=cache, **COARSE)
    P = again.evaluate(0.01, 0.01, 1.0, 1.0)
    assert again.solves == 0
    np.testing.assert_array_equal(P, sur.evaluate(0.01, 0.01, 1.0, 1.0))


def test_corrupt_or_stale_cache_file_is_rebuilt(tmp_path):
    first = Surrogate(FABRIC, cache_dir=tmp_path, **COARSE)
    P_ref = first.evaluate(0.0, 0.0, 1.0, 1.0)[0]
    files = sorted(first.cache_dir.glob("intact_*.npz"))
    assert files
    files[0].write_bytes(files[0].read_bytes()[: len(files[0].read_bytes()) // 2])  # truncated
    second = Surrogate(FABRIC, cache_dir=tmp_path, **COARSE)
    np.testing.assert_array_equal(second.evaluate(0.0, 0.0, 1.0, 1.0)[0], P_ref)
    assert second.solves > 0
    # A file of another fabric moved into this folder (stale) is detected by its key.
    other = Surrogate(FABRIC.with_yarn("warp", A0=4000.0), cache_dir=tmp_path, **COARSE)
    other.evaluate(0.0, 0.0, 1.0, 1.0)
    for f in sorted(other.cache_dir.glob("intact_*.npz")):
        os.replace(f, first.cache_dir / f.name)
    third = Surrogate(FABRIC, cache_dir=tmp_path, **COARSE)
    np.testing.assert_array_equal(third.evaluate(0.0, 0.0, 1.0, 1.0)[0], P_ref)
    assert third.solves > 0


def test_update_follows_the_unit_cell_along_uniaxial_strain(sur):
    cell = UnitCell(FABRIC)
    a_cell = np.ones(2)
    a_sur = np.ones(2)
    for E1 in np.arange(0.0, 0.07, 0.002):
        r = cell.respond(E1, 0.0, a_cell)
        a_cell = np.array([r.alpha1, r.alpha2])
        P1, P2, a1, a2 = sur.update(E1, 0.0, a_sur[0], a_sur[1])
        assert a1 <= a_sur[0] and a2 <= a_sur[1]
        a_sur = np.array([float(a1), float(a2)])
        assert abs(a_sur[0] - a_cell[0]) < 0.05
        assert abs(float(P1) - max(r.P1, 0.0)) < 0.05 * P_PEAK  # steep softening, coarse table
    assert a_sur[0] == 0.0 and a_sur[1] == 1.0


def test_update_never_increases_damage_and_is_self_consistent(sur):
    rng = np.random.default_rng(3)
    n = 2000
    E1 = rng.uniform(-0.02, 0.09, n)
    E2 = rng.uniform(-0.02, 0.07, n)
    hist = rng.uniform(0.0, 1.0, (n, 2))
    hist[rng.random(n) < 0.3] = 1.0
    P1, P2, a1, a2, mu1, mu2 = sur.update(E1, E2, hist[:, 0], hist[:, 1], return_mu=True)
    assert np.all(a1 <= hist[:, 0]) and np.all(a2 <= hist[:, 1])
    assert np.all(P1 >= 0) and np.all(P2 >= 0)
    law = FABRIC.damage
    alive = a1 > 0
    expect = np.minimum(hist[alive, 0], law.alpha(mu1[alive], FABRIC.warp.mu_crit))
    np.testing.assert_allclose(a1[alive], expect, atol=1e-8)


def test_out_of_range_strains_are_counted(sur):
    before = sur.stats.beyond_failure.copy(), sur.stats.compression.copy()
    P1, P2, a1, a2 = sur.update([0.2, 0.01], [0.0, -0.1], [1.0, 1.0], [1.0, 1.0])
    assert P1[0] == 0.0 and a1[0] == 0.0  # beyond complete failure of a straight warp
    assert P2[1] == 0.0  # compressed fill: tension-only
    assert sur.stats.beyond_failure[0] - before[0][0] == 1
    assert sur.stats.compression[1] - before[1][1] == 1
    assert "beyond complete failure" in sur.report_range()


@pytest.mark.parametrize("E1, E2, alpha", [(0.02, 0.01, (1.0, 1.0)), (0.03, 0.002, (1.0, 1.0)),
                                          (0.01, 0.025, (0.7, 1.0)), (0.025, 0.015, (0.9, 0.5))])
def test_tangent_matches_finite_differences(sur, E1, E2, alpha):
    """All four dP_i/dlambda_j against central differences of evaluate() in lambda_1 and
    lambda_2: the off-diagonal terms (crimp interchange through the contact force) set the
    wave modulus and the time step as much as the diagonal ones."""
    t = np.array(sur.tangent(E1, E2, *alpha), dtype=float).reshape(2, 2)   # [[t11, t12], [t21, t22]]
    h = 1e-6
    lam = np.sqrt(1 + 2 * np.array([E1, E2]))
    fd = np.empty((2, 2))
    for j in range(2):
        Ep, Em = np.array([E1, E2]), np.array([E1, E2])
        Ep[j], Em[j] = 0.5 * ((lam[j] + h) ** 2 - 1), 0.5 * ((lam[j] - h) ** 2 - 1)
        Pp = np.array(sur.evaluate(*Ep, *alpha, tension_only=False)[:2], dtype=float)
        Pm = np.array(sur.evaluate(*Em, *alpha, tension_only=False)[:2], dtype=float)
        fd[:, j] = (Pp - Pm) / (2 * h)
    np.testing.assert_allclose(t, fd, rtol=1e-5, atol=1e-6 * np.abs(fd).max())
    assert t[0, 0] > 0 and t[1, 1] > 0
    # in contact the yarns push on each other: stretching one unloads the other's crimp
    assert abs(t[0, 1]) > 1e-3 * t[0, 0] and abs(t[1, 0]) > 1e-3 * t[1, 1]


@pytest.mark.parametrize("bad, message", [
    (dict(E1=np.nan), r"surrogate input E1 has 1 non-finite value\(s\), first at point 0: E1=nan"),
    (dict(alpha1=np.nan), r"surrogate input alpha1 has 1 non-finite value\(s\)"),
    (dict(alpha1=1.5), r"surrogate input alpha1 must lie in \[0, 1\]; point 0 has 1\.5"),
    (dict(E2=-0.7), r"strain at point 0 \(E1=0\.01, E2=-0\.7\) is not a Green-Lagrange strain"),
])
def test_bad_input_raises(sur, bad, message):
    args = dict(E1=0.01, E2=0.0, alpha1=1.0, alpha2=1.0)
    args.update(bad)
    with pytest.raises(ValueError, match=message):
        sur.evaluate(args["E1"], args["E2"], args["alpha1"], args["alpha2"])


def test_bad_construction_raises():
    with pytest.raises(ValueError, match="resolution"):
        Surrogate(FABRIC, resolution=0.0)
    with pytest.raises(ValueError, match="order"):
        Surrogate(FABRIC, order=2)


def test_skipping_the_stretch_lookup_below_damage_changes_nothing(sur):
    """update() skips mu where no table node is near mu_crit; the full path must agree."""
    rng = np.random.default_rng(4)
    n = 3000
    E1 = rng.uniform(-0.01, 0.07, n)
    E2 = rng.uniform(-0.01, 0.05, n)
    hist = np.where(rng.random((n, 2)) < 0.5, 1.0, rng.uniform(0.2, 1.0, (n, 2)))
    fast = sur.update(E1, E2, hist[:, 0], hist[:, 1])
    full = sur.update(E1, E2, hist[:, 0], hist[:, 1], return_mu=True)[:4]
    for a, b in zip(fast, full):
        np.testing.assert_array_equal(a, b)
    assert 0 < sur._values(E1, E2, hist[:, 0], hist[:, 1], ("P1",))[1].mean() < 1


@pytest.mark.parametrize("alpha", [(1.0, 1.0), (0.011, 1.0), (1.0, 1e-4)])
def test_a_tile_block_does_not_depend_on_the_block_solved_before(alpha):
    """Where the unit cell has several equilibria (both yarns compressed, E2 near the table's
    end) a warm start from another block used to pick another one: 4e5 N/m apart in P2."""
    from fabric_fenicsx.surrogate import tiles
    E1s = np.arange(-0.06, 0.1, 0.008)
    E2s = np.array([-0.06, -0.056])
    tiles._worker_init(FABRIC.to_dict(), 24)
    _, fresh = tiles._solve_block(("b", alpha, E1s, E2s))
    for before in [(0.05, 0.05), (-0.05, 0.02), (0.09, -0.06)]:
        tiles._worker_init(FABRIC.to_dict(), 24)
        tiles._solve_block(("a", alpha, np.array([before[0]]), np.array([before[1]])))
        _, after = tiles._solve_block(("b", alpha, E1s, E2s))
        np.testing.assert_array_equal(after, fresh)


def test_lookup_reproduces_the_table_nodes(sur):
    """At a grid node the interpolant is the node's value: intact, damaged (both cases, every
    r node), with the damage scaling (forces x alpha_max) and broken yarns (no force, the
    stretch of complete failure)."""
    E = sur.E_lo + sur.h * np.arange(sur.nE)
    # nodes from E = -0.02 up (the strains the other tests of the shared table reach: the
    # compressive tiles below are never solved for them)
    first = int(np.searchsorted(E, -0.02 - 1e-9))
    i, j = np.meshgrid(np.arange(first, sur.nE - 3, 3), np.arange(first + 1, sur.nE - 3, 4), indexing="ij")
    i, j = i.ravel(), j.ravel()
    E1, E2 = E[i], E[j]
    quantities = ("P1", "P2", "mu1", "mu2", "V", "Psi")
    force = np.array([not q.startswith("mu") for q in quantities])
    one = np.ones(i.size)
    vals, d1, d2 = sur.lookup(E1, E2, one, one, quantities, derivative=True)
    scale = np.abs(vals).max(axis=0)
    np.testing.assert_allclose(vals, sur.intact[i, j], rtol=0, atol=1e-12 * scale.max())
    assert np.all(np.isfinite(d1)) and np.all(np.isfinite(d2))
    for k, r in enumerate(sur.r_grid[1:-1], start=1):
        for case, (a1, a2) in enumerate(((0.8 * r, 0.8), (0.8, 0.8 * r))):
            vals = sur.lookup(E1, E2, a1 * one, a2 * one, quantities)
            node = sur.damaged[case, i, j, k] * np.where(force, 0.8, 1.0)
            np.testing.assert_allclose(vals, node, rtol=0, atol=1e-9 * scale.max())
    mu_complete = sur.fabric.damage.mu_complete(sur.mu_crit[0])
    vals = sur.lookup(E1, E2, 0.0 * one, 0.6 * one, quantities)
    assert np.all(vals[:, 0] == 0.0) and np.all(vals[:, 2] == mu_complete)
    np.testing.assert_allclose(vals[:, 1], 0.6 * sur.damaged[0, i, j, 0, 1], rtol=0,
                               atol=1e-4 * scale[1])  # r = 0 holds the limit r -> 0+ (R_LIMIT)
    vals = sur.lookup(E1, E2, 0.0 * one, 0.0 * one, quantities)
    assert np.all(vals[:, [0, 1, 4, 5]] == 0.0)


def test_compiled_damage_iteration_matches_the_solver_run_in_python(sur):
    """damage_kernel compiles damage_solver's code; run in Python (as the unit cell runs it)
    with the surrogate's target it gives the same integrities."""
    from fabric_fenicsx.material.damage_solver import solve_damage
    from fabric_fenicsx.material.unitcell import ALPHA_BROKEN
    rng = np.random.default_rng(11)
    n = 400
    E1 = rng.uniform(0.02, 0.08, n)
    E2 = rng.uniform(-0.01, 0.06, n)
    hist = np.where(rng.random((n, 2)) < 0.5, 1.0, rng.uniform(0.05, 1.0, (n, 2)))
    law = sur.fabric.damage

    def evaluate(rows, alpha):
        alpha = np.where(alpha < ALPHA_BROKEN, 0.0, alpha)
        mu = sur.lookup(E1[rows], E2[rows], alpha[:, 0], alpha[:, 1], ("mu1", "mu2"))
        return np.minimum(hist[rows], np.stack([law.alpha(mu[:, i], sur.mu_crit[i])
                                                for i in range(2)], axis=1))

    target = evaluate(np.arange(n), hist)
    grows = np.any(hist - target > 1e-10, axis=1)
    assert grows.sum() > 50
    compiled = np.stack(sur.update(E1[grows], E2[grows], hist[grows, 0], hist[grows, 1])[2:], axis=1)
    python = solve_damage(hist[grows], target[grows], lambda rows, a: evaluate(np.flatnonzero(grows)[rows], a),
                          floor=2 * ALPHA_BROKEN, tol=1e-10)
    python = np.where(python < ALPHA_BROKEN, 0.0, python)
    np.testing.assert_allclose(compiled, python, rtol=0, atol=1e-9)
    assert np.any((compiled > 0) & (compiled < hist[grows]))


def _damaging_states(n, seed):
    """Random states of growing damage: E1 past the warp's onset, random histories."""
    rng = np.random.default_rng(seed)
    E1 = rng.uniform(0.045, 0.07, n)
    E2 = rng.uniform(0.0, 0.03, n)
    hist = np.where(rng.random((n, 2)) < 0.5, 1.0, rng.uniform(0.3, 1.0, (n, 2)))
    return E1, E2, hist


def test_damage_update_is_a_fixed_point_checked_without_the_damage_kernel(sur):
    """Independent of the damage iteration (kernel and damage_solver): the integrities the
    update returns satisfy Eq. 2-25, alpha_i = min(alpha_i^hist, alpha(mu_i(E, alpha))), with
    the stretches mu_i looked up afresh at the returned alpha and the fibril law evaluated in
    Python, and the damage grew where the history's own stretch already breaks fibrils."""
    E1, E2, hist = _damaging_states(300, 12)
    law = sur.fabric.damage
    a1, a2 = sur.update(E1, E2, hist[:, 0], hist[:, 1])[2:]
    alpha = np.stack([a1, a2], axis=1)
    mu = sur.lookup(E1, E2, a1, a2, ("mu1", "mu2"))
    target = np.minimum(hist, np.stack([law.alpha(mu[:, i], sur.mu_crit[i]) for i in range(2)], axis=1))
    alive = alpha > 0
    np.testing.assert_allclose(alpha[alive], target[alive], rtol=0, atol=1e-8)
    assert np.all(target[~alive] < 1e-4)                 # a broken yarn: its law gives ~0 too
    first = np.stack([law.alpha(m, sur.mu_crit[i]) for i, m in
                      enumerate(sur.lookup(E1, E2, hist[:, 0], hist[:, 1], ("mu1", "mu2")).T)], axis=1)
    grows = np.any(first < hist - 1e-6, axis=1)
    assert grows.sum() > 100 and np.all(np.any(alpha[grows] < hist[grows], axis=1))
    # one step from the history (alpha = law(mu(hist))) is not the solution: the coupling matters
    assert np.abs(np.minimum(hist, first) - alpha)[grows].max() > 0.05


def test_damage_update_with_a_shortened_softening_branch_is_its_fixed_point(sur):
    """With crack-band scales s_i per point, the update solves alpha_i = min(alpha_i^hist,
    alpha(mu_crit + (mu_i - mu_crit) / s_i)) (fibril.crack_band_alpha in Python); s = 1 is the
    law itself; a scale outside (0, 1] is refused."""
    from fabric_fenicsx.material.fibril import crack_band_alpha
    E1, E2, hist = _damaging_states(300, 13)
    scale = np.random.default_rng(5).uniform(0.6, 1.0, (2, E1.size))
    law = sur.fabric.damage
    a1, a2 = sur.update(E1, E2, hist[:, 0], hist[:, 1], crack_band=tuple(scale))[2:]
    mu = sur.lookup(E1, E2, a1, a2, ("mu1", "mu2"))
    alpha = np.stack([a1, a2], axis=1)
    target = np.minimum(hist, np.stack([crack_band_alpha(law, mu[:, i], sur.mu_crit[i], scale[i])
                                        for i in range(2)], axis=1))
    alive = alpha > 0
    np.testing.assert_allclose(alpha[alive], target[alive], rtol=0, atol=1e-8)
    plain = np.stack(sur.update(E1, E2, hist[:, 0], hist[:, 1])[2:], axis=1)
    # more brittle: more broken yarns (a yarn's integrity alone need not drop: where the
    # crossing yarn breaks first, its own stretch falls)
    assert (alpha == 0).sum() > (plain == 0).sum() and np.abs(alpha - plain).max() > 0.1
    np.testing.assert_array_equal(np.stack(sur.update(E1, E2, hist[:, 0], hist[:, 1],
                                                      crack_band=(1.0, 1.0))[2:], axis=1), plain)
    with pytest.raises(ValueError, match=r"crack_band scales must lie in \(0, 1\]"):
        sur.update(E1, E2, hist[:, 0], hist[:, 1], crack_band=(1.5, 1.0))


def test_damage_update_against_the_unit_cell(sur):
    """The surrogate's damage update against the unit cell's own (UnitCell.respond: direct
    solves, no table) at damaging states: integrities within 0.05 and stresses within 3 % of the
    uniaxial peak on this coarse table (the default table's errors: docs/surrogate.md)."""
    E1, E2, hist = _damaging_states(12, 13)
    P1, P2, a1, a2 = sur.update(E1, E2, hist[:, 0], hist[:, 1])
    cell = UnitCell(FABRIC)
    ref = np.array([[r.alpha1, r.alpha2, max(r.P1, 0.0), max(r.P2, 0.0)]
                    for r in (cell.respond(E1[k], E2[k], tuple(hist[k])) for k in range(E1.size))])
    assert np.any(ref[:, :2] < hist - 0.05)               # the states do damage the yarns
    np.testing.assert_allclose(np.c_[a1, a2], ref[:, :2], rtol=0, atol=0.05)
    np.testing.assert_allclose(np.c_[P1, P2], ref[:, 2:], rtol=0, atol=0.03 * P_PEAK)


@pytest.mark.parametrize("law", [ExponentialDamage(), ExponentialDamage(beta=5.0, width=0.05),
                                 BundleDamage.for_width(0.03, 1.03, n=500, seed=2)])
def test_compiled_damage_laws_match_the_fibril_module(law):
    from fabric_fenicsx.surrogate.kernels.damage import law_alpha, law_arguments
    mu_crit = 1.03
    mu = np.concatenate([np.linspace(1.0, 1.07, 701), [mu_crit, law.mu_complete(mu_crit)]])
    compiled = np.array([law_alpha(m, mu_crit, law_arguments(law)) for m in mu])
    np.testing.assert_allclose(compiled, law.alpha(mu, mu_crit), rtol=0, atol=1e-14)
    from fabric_fenicsx.material.fibril import crack_band_alpha
    from fabric_fenicsx.surrogate.kernels.damage import band_alpha
    for s in (1.0, 0.7, 0.3):
        compiled = np.array([band_alpha(m, mu_crit, s, law_arguments(law)) for m in mu])
        np.testing.assert_allclose(compiled, crack_band_alpha(law, mu, mu_crit, s), rtol=0, atol=1e-14)


def test_only_points_that_iterated_have_a_status(sur):
    """Surrogate.update looks at the damage statuses (non-finite, fallbacks) only when a point
    iterated: the kernel gives every other point status 0 (converged). Over random states, intact
    and damaging, below and beyond the onset, the statuses that are not 0 are at most as many as
    the points that iterated, and all 0 where none did."""
    rng = np.random.default_rng(21)
    states = [_damaging_states(400, 22)]
    for n in (1, 50, 2000):
        E1, E2 = rng.uniform(-0.02, 0.07, n), rng.uniform(-0.02, 0.05, n)
        E1[rng.random(n) < 0.05], E2[rng.random(n) < 0.05] = 0.0, -0.0
        hist = np.where(rng.random((n, 2)) < 0.6, 1.0, rng.uniform(0.0, 1.0, (n, 2)))
        states.append((E1, E2, hist))
    iterated_somewhere = False
    for E1, E2, hist in states:
        n = E1.size
        band, mu_crit = np.ones((n, 2)), np.empty((n, 2))
        mu_crit[:] = sur.mu_crit
        assert np.array_equal(sur.mu_crit[None].repeat(n, axis=0), mu_crit)   # update's copy
        *_, status, iterated = sur._update_points(E1, E2, hist[:, 0].copy(), hist[:, 1].copy(),
                                                  1e-10, band, mu_crit)
        assert np.count_nonzero(status) <= iterated
        iterated_somewhere |= iterated > 0
    assert iterated_somewhere


def test_range_statistics_pass_equals_numpy():
    """interp_kernel.record_inputs (the range statistics of Surrogate._inputs, in place) against
    the numpy expressions it replaces, bit for bit: counts added, the range widened by
    numpy.minimum / numpy.maximum, with NaN, infinities and zeros of both signs."""
    from fabric_fenicsx.surrogate.kernels import interp as interp_kernel

    rng = np.random.default_rng(41)
    values = np.array([0.0, -0.0, np.nan, np.inf, -np.inf, 0.01, -0.02, 0.03])
    for _ in range(3000):
        E_min, E_max = rng.choice(values, 2), rng.choice(values, 2)
        ranges = rng.choice(values, (2, 2))
        counts = rng.integers(0, 50, 5)
        beyond, compression = rng.integers(0, 9, 2), rng.integers(0, 9, 2)
        expected = (beyond + counts[:2], compression + counts[2:4], np.minimum(E_min, ranges[0]),
                    np.maximum(E_max, ranges[1]))
        interp_kernel.record_inputs(counts, ranges, beyond, compression, E_min, E_max)
        for got, want in zip((beyond, compression, E_min, E_max), expected):
            assert got.dtype == want.dtype and got.tobytes() == want.tobytes()
