"""Tension-field relaxation (fabric_fenicsx.fem.tension_field): the strains a wrinkled yarn
takes, and the invariant it restores: the membrane's yarn stresses do no work around a closed
strain cycle (they are the gradient of an energy)."""
import numpy as np
import pytest

from fabric_fenicsx.fem.tension_field import (CURVE_TOL, ForceFreeCurves, RelaxStats, force_free_strain,
                                              relaxed_strains)
from fabric_fenicsx.fem.yarn_stress import YarnStress
from fabric_fenicsx.surrogate.kernels.interp import ROOT_FOUND, ROOT_NONE, ROOT_TENSION

A, B, D = 6.0e6, 1.5e6, 2.0e6   # P1 = A E1 + B E2, P2 = B E1 + D E2: W = A/2 E1^2 + B E1 E2 + D/2 E2^2


class Quadratic:
    """Stand-in for the surrogate: the signed forces of a quadratic energy with crimp-interchange
    coupling B (its ``lookup`` signature), and their force-free strains in closed form."""
    E_table = (-0.06, 0.1)

    @staticmethod
    def lookup(E1, E2, a1, a2, quantities, derivative=False):
        values = {"P1": A * E1 + B * E2, "P2": B * E1 + D * E2}
        assert not derivative
        return np.stack([values[q] for q in quantities], axis=1)

    @staticmethod
    def zero_force_strain(yarn, E_other, lo, hi, a1, a2, guess=None):
        own = A if yarn == 1 else D
        x = -B * E_other / own
        status = np.where(own * lo + B * E_other >= 0, ROOT_TENSION,
                          np.where((x >= lo) & (x <= hi), ROOT_FOUND, ROOT_NONE))
        return np.where(status == ROOT_FOUND, x, lo), status


def loop_work(forces, c1, c2, h, m=64, stretch=True):
    """Work of forces(E1, E2) -> (P1, P2) around the square [c1, c1 + h] x [c2, c2 + h],
    counter-clockwise (midpoint rule on each side): sum_i P_i dlambda_i, dlambda = dE / lambda,
    as the membrane does it, or sum_i P_i dE_i (``stretch`` False)."""
    s = (np.arange(m) + 0.5) / m
    corners = [(0, 0), (1, 0), (1, 1), (0, 1), (0, 0)]
    work = 0.0
    for (x0, y0), (x1, y1) in zip(corners[:-1], corners[1:]):
        e1, e2 = c1 + h * (x0 + s * (x1 - x0)), c2 + h * (y0 + s * (y1 - y0))
        P1, P2 = forces(e1, e2)
        l1, l2 = (np.sqrt(1 + 2 * e1), np.sqrt(1 + 2 * e2)) if stretch else (1.0, 1.0)
        work += np.sum(P1 * h * (x1 - x0) / m / l1 + P2 * h * (y1 - y0) / m / l2)
    return work


def test_relaxed_strain_is_the_force_free_strain_of_the_wrinkled_yarn():
    E1 = np.array([0.02, 0.02, 0.02, -0.01, -0.01, 0.01])
    E2 = np.array([-0.03, -0.005, 0.01, 0.03, -0.02, 0.0])
    one = np.ones(E1.size)
    stats = RelaxStats()
    r1, r2 = relaxed_strains(Quadratic, E1, E2, one, one, stats)
    # fill relaxed where B E1 + D E2 < 0 with E1 > 0: E2* = -B E1 / D = -0.015
    np.testing.assert_allclose(r2, [-0.015, -0.005, 0.01, 0.03, -0.02, 0.0], atol=1e-12)
    # warp relaxed where A E1 + B E2 < 0 with E2 > 0: E1* = -B E2 / A = -0.0075
    np.testing.assert_allclose(r1, [0.02, 0.02, 0.02, -0.0075, -0.01, 0.01], atol=1e-12)
    assert stats.relaxed == 2 and stats.no_root == 0
    P = Quadratic.lookup(r1, r2, one, one, ("P1", "P2"))
    assert abs(P[0, 1]) < 1e-3 and abs(P[3, 0]) < 1e-3
    assert P[0, 0] == pytest.approx((A - B * B / D) * 0.02)   # the Schur complement's stiffness


def test_no_force_free_strain_is_counted_and_left_alone():
    class Compressive(Quadratic):
        @staticmethod
        def zero_force_strain(yarn, E_other, lo, hi, a1, a2, guess=None):
            return lo.copy(), np.full(lo.size, ROOT_NONE)
    stats = RelaxStats()
    r1, r2 = relaxed_strains(Compressive, np.array([0.02]), np.array([-0.03]), np.ones(1),
                             np.ones(1), stats)
    assert stats.no_root == 1 and stats.relaxed == 0 and r2[0] == -0.03 and r1[0] == 0.02


def _cut_forces(relax):
    """Tension-only forces of the quadratic energy, with or without the tension field."""
    def forces(e1, e2):
        one = np.ones(e1.size)
        if relax:
            e1, e2 = relaxed_strains(Quadratic, e1, e2, one, one)
        P = Quadratic.lookup(e1, e2, one, one, ("P1", "P2"))
        return np.maximum(P[:, 0], 0.0), np.maximum(P[:, 1], 0.0)
    return forces


def test_tension_field_does_no_work_around_a_closed_cycle():
    """A square through the band where the fill would be compressed: cutting P2 alone leaves
    P1 depending on E2 and the cycle does work; the tension field's does none."""
    c1, c2, h = 0.015, -0.02, 0.01
    side = A * c1 * h   # the work scale of one side
    cut_only = loop_work(_cut_forces(False), c1, c2, h, stretch=False)   # W is a function of E
    relaxed = loop_work(_cut_forces(True), c1, c2, h, stretch=False)
    assert abs(cut_only) > 0.05 * side
    assert abs(relaxed) < 1e-3 * abs(cut_only)


@pytest.mark.parametrize("corner", [(0.024, -0.024), (0.028, -0.032), (0.012, -0.012)])
def test_unit_cell_stresses_do_little_work_around_the_contact_band(coarse_surrogate, corner):
    """The membrane's yarn stresses (surrogate, tension field, slack rules) around squares in
    strain space where the compressed fill separates from the stretched warp. Without the
    tension field these cycles gave out 15.9, 15.6, 7.0 J/m^2 on the default table (of a
    side's work of 46, 63, 9 J/m^2); the remaining work is the interpolant's (P1 and P2 are
    interpolated separately)."""
    stress = YarnStress(coarse_surrogate, np.ones(1), damage=False)
    forces = lambda e1, e2: stress._frozen_P(e1, e2, np.ones(e1.size), np.ones(e1.size))
    h = 0.004
    side = float(forces(np.array([corner[0] + h]), np.array([corner[1] + h]))[0][0]) * h
    work = loop_work(forces, corner[0], corner[1], h)
    assert abs(work) < 0.03 * side, (work, side)


@pytest.mark.parametrize("alpha", [(1.0, 1.0), (0.6, 0.9)])
def test_zero_force_strain_of_the_surrogate(coarse_surrogate, alpha):
    """The compiled root finder against bisection on the surrogate's own look-up: the fill's
    force-free strain with the warp stretched, intact and damaged, with and without a starting
    guess; a bracket without a sign change, and a fill in tension, are reported as such."""
    sur = coarse_surrogate
    E1 = np.array([0.01, 0.02, 0.026, 0.035])
    n = E1.size
    a1, a2 = np.full(n, alpha[0]), np.full(n, alpha[1])
    lo, hi = np.full(n, -0.05), np.zeros(n)
    assert np.all(sur.lookup(E1, lo, a1, a2, ("P2",))[:, 0] < 0)
    left, right = lo.copy(), hi.copy()
    for _ in range(60):
        mid = 0.5 * (left + right)
        neg = sur.lookup(E1, mid, a1, a2, ("P2",))[:, 0] < 0
        left, right = np.where(neg, mid, left), np.where(neg, right, mid)
    for guess in (None, np.full(n, -0.049), 0.5 * (left + right) + 1e-4):
        x, status = sur.zero_force_strain(2, E1, lo, hi, a1, a2, guess)
        assert np.all(status == ROOT_FOUND)
        np.testing.assert_allclose(x, 0.5 * (left + right), atol=1e-9)
        assert np.all(np.abs(sur.lookup(E1, x, a1, a2, ("P2",))[:, 0]) < 1e-2)
    x, status = sur.zero_force_strain(2, E1, lo, np.full(n, -0.045), a1, a2)
    assert np.all(status == ROOT_NONE) and np.array_equal(x, lo)
    x, status = sur.zero_force_strain(2, E1, np.full(n, 0.001), np.full(n, 0.01), a1, a2)
    assert np.all(status == ROOT_TENSION) and np.all(x == 0.001)


def test_force_free_curves_give_the_searched_strains_within_their_tolerance(coarse_surrogate):
    """The tabulated force-free strains of the intact layer (r = 1, intact or equally damaged
    yarns) against the per-point search (Newton to 1e-15): within the curve's tolerance (checked
    at three points per interval, so allowed twice that in between), most of the curve in use,
    the same points relaxed; points with r < 1 are searched, so their strains are the search's
    bits."""
    sur = coarse_surrogate
    rng = np.random.default_rng(7)
    n = 4000
    E1, E2 = rng.uniform(-0.04, 0.05, n), rng.uniform(-0.04, 0.05, n)
    a1 = np.where(rng.random(n) < 0.5, 1.0, rng.uniform(0.3, 1.0, n))
    a2 = np.where(rng.random(n) < 0.6, a1, rng.uniform(0.3, 1.0, n))   # r = 1 and r < 1
    curves = ForceFreeCurves(sur)
    searched, stats = relaxed_strains(sur, E1, E2, a1, a2, RelaxStats()), RelaxStats()
    tabulated = relaxed_strains(sur, E1, E2, a1, a2, stats, curves=curves)
    r1 = a1 == a2
    for j in range(2):
        assert np.abs(tabulated[j] - searched[j])[r1].max() <= 2 * CURVE_TOL
        np.testing.assert_array_equal(tabulated[j][~r1], searched[j][~r1])
        assert np.count_nonzero(tabulated[j][r1] != (E1, E2)[j][r1]) > 200
        built = np.repeat(curves.built[j], curves.m)
        assert curves.ok[j][built].mean() > 0.8
    assert stats.relaxed == sum(np.count_nonzero(s != e) for s, e in zip(searched, (E1, E2)))
    # the stresses the membrane gets: within 2 CURVE_TOL x |dP_i/dE_j|
    P = [sur.lookup(*E, a1, a2, ("P1", "P2")) for E in (searched, tabulated)]
    assert np.abs(P[0] - P[1]).max() < 1e-8 * np.abs(P[0]).max()


class Recording(Quadratic):
    """The quadratic stand-in, recording the searches it is asked for, without a root where the
    crossing yarn is stretched beyond 0.03; its root depends on the start guess where one is
    given (so a guess gathered from the wrong point shows)."""
    calls = []

    @classmethod
    def zero_force_strain(cls, yarn, E_other, lo, hi, a1, a2, guess=None):
        cls.calls.append(tuple(np.array(x, dtype=float) for x in (E_other, lo, hi, a1, a2))
                         + (None if guess is None else np.array(guess),))
        x, status = Quadratic.zero_force_strain(yarn, E_other, lo, hi, a1, a2)
        far = E_other > 0.03   # no root up to the table's top
        x, status = np.where(far, lo, x), np.where(far, ROOT_NONE, status)
        if guess is not None:
            x = np.where(status == ROOT_FOUND, x + 1e-9 * np.nan_to_num(guess), x)
        return x, status


def _numpy_relaxed_strains(surrogate, E1, E2, a1, a2, stats, guess=None):
    """relaxed_strains without curves as it was: numpy selections and gathers around the searches."""
    E = [np.array(E1, dtype=float, copy=True), np.array(E2, dtype=float, copy=True)]
    for j in (0, 1):
        i = 1 - j
        k = np.flatnonzero((E[j] < 0.0) & (E[i] > 0.0))
        if k.size == 0:
            continue
        root, status = force_free_strain(surrogate, j, E[i][k], E[j][k], a1[k], a2[k],
                                         None if guess is None else guess[j][k])
        E[j][k] = root
        stats.relaxed += int(np.count_nonzero(status == ROOT_FOUND))
        stats.no_root += int(np.count_nonzero(status == ROOT_NONE))
    return E[0], E[1]


def _random_strains(rng, n, spread=0.04):
    """Strains of both signs with exact zeros of both signs among them, and integrities."""
    E = rng.uniform(-spread, spread, (2, n))
    E[:, rng.random(n) < 0.1] = 0.0
    E[:, rng.random(n) < 0.1] = -0.0
    return E[0], E[1], rng.uniform(0.2, 1.0, n), rng.uniform(0.2, 1.0, n)


@pytest.mark.parametrize("with_guess", [False, True])
def test_compiled_selections_give_the_bits_of_the_numpy_ones(with_guess):
    """relaxed_strains (candidates gathered and roots put back by compiled passes) against the
    numpy selections it replaces: the same searches asked (inputs bit for bit), the same strains
    and counts, over random strains with roots found, in tension and without a root."""
    rng = np.random.default_rng(7)
    for n in (0, 1, 5, 400):
        E1, E2, a1, a2 = _random_strains(rng, n)
        guess = rng.uniform(-0.03, 0.0, (2, n)) if with_guess else None
        results = []
        for relax in (relaxed_strains, _numpy_relaxed_strains):
            Recording.calls = []
            stats = RelaxStats()
            r = relax(Recording, E1, E2, a1, a2, stats, guess)
            results.append((r, stats, Recording.calls))
        (r, stats, calls), (r0, stats0, calls0) = results
        for x, x0 in zip(r, r0):
            assert x.dtype == x0.dtype and x.tobytes() == x0.tobytes()
        assert stats == stats0 and len(calls) == len(calls0)
        for call, call0 in zip(calls, calls0):
            for x, x0 in zip(call, call0):
                assert (x is None and x0 is None) or x.tobytes() == x0.tobytes()


def test_compiled_selections_on_the_surrogate(coarse_surrogate):
    """The same with the surrogate's compiled searches, intact and damaged points."""
    rng = np.random.default_rng(8)
    E1, E2, a1, a2 = _random_strains(rng, 300, 0.03)
    a1[::2] = a2[::2] = 1.0
    for guess in (None, rng.uniform(-0.03, 0.01, (2, 300))):
        stats, stats0 = RelaxStats(), RelaxStats()
        r = relaxed_strains(coarse_surrogate, E1, E2, a1, a2, stats, guess)
        r0 = _numpy_relaxed_strains(coarse_surrogate, E1, E2, a1, a2, stats0, guess)
        assert all(x.tobytes() == x0.tobytes() for x, x0 in zip(r, r0))
        assert stats == stats0 and stats.relaxed > 0


def test_search_counts_the_points_that_wait_for_tiles(coarse_surrogate):
    """The compiled force-free search returns how many points have the status ROOT_NEEDS_TILES
    (numpy's count of them): with a random third of the table's tiles taken as not built, over
    random strains with zeros of both signs and starting guesses with NaN, both yarns."""
    from fabric_fenicsx.surrogate.kernels import interp as interp_kernel

    sur = coarse_surrogate
    rng = np.random.default_rng(31)
    table = list(sur._table())
    for layer in (2, 3):   # the ready maps of the intact and the damaged layer
        table[layer] = table[layer] & (rng.random(table[layer].shape) < 0.67)
    table = tuple(table)
    for n in (0, 1, 17, 600):
        E_other = rng.uniform(-0.01, 0.04, n)
        E_other[rng.random(n) < 0.1] = 0.0
        E_other[rng.random(n) < 0.1] = -0.0
        lo, hi = np.full(n, -0.05), rng.uniform(-0.01, 0.01, n)
        hi[rng.random(n) < 0.1] = -0.0
        guess = rng.uniform(-0.05, 0.0, n)
        guess[rng.random(n) < 0.3] = np.nan
        a1, a2 = (np.where(rng.random(n) < 0.5, 1.0, rng.uniform(0.2, 1.0, n)) for _ in range(2))
        for yarn in (0, 1):
            x, status = np.empty(n), np.empty(n, np.int8)
            waiting = interp_kernel.zero_force_strain(yarn, E_other, lo, hi, guess, a1, a2, table,
                                                      sur._spec((f"P{yarn + 1}",)), 1e-15, 60, x,
                                                      status)
            assert waiting == np.count_nonzero(status == interp_kernel.ROOT_NEEDS_TILES)
            assert n < 600 or 0 < waiting < n
