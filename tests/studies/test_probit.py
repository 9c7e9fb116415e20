"""The ballistic limit's statistics on stand-ins (outcomes drawn from a known probit curve, no
impact runs): the probit fit and its profile-likelihood intervals (coverage), separation and
monotonicity, Neyer's sequential design against a fixed grid, and the Lambert-Jonas fit."""
import numpy as np
import pytest
from scipy.stats import norm

from fabric_fenicsx.studies.lambert_jonas import fit_lambert_jonas, residual_velocity
from fabric_fenicsx.studies.neyer import NeyerDesign, Shot
from fabric_fenicsx.studies.probit import (Z90, binned, fit_probit, monotone_violations, probit_information,
                                           separation)

V50, SIGMA = 40.0, 3.0


def shots(rng, v):
    return rng.random(len(v)) < norm.cdf((np.asarray(v) - V50) / SIGMA)


def covers(ci, x):
    lo, hi = ci
    return (lo is None or lo <= x) and (hi is None or x <= hi)


def test_the_fit_recovers_a_known_curve_from_many_shots():
    rng = np.random.default_rng(1)
    v = np.repeat(np.linspace(30.0, 50.0, 21), 40)
    fit = fit_probit(v, shots(rng, v))
    assert fit.v50 == pytest.approx(V50, abs=0.4) and fit.sigma == pytest.approx(SIGMA, rel=0.12)
    assert fit.v90 - fit.v50 == pytest.approx(Z90 * fit.sigma) and fit.v50 - fit.v10 == pytest.approx(Z90 * fit.sigma)
    for name, true in (("v50", V50), ("v10", V50 - Z90 * SIGMA), ("v90", V50 + Z90 * SIGMA), ("sigma", SIGMA)):
        lo, hi = getattr(fit, f"{name}_ci")
        assert lo < getattr(fit, name) < hi and covers((lo, hi), true), name
    assert fit.width < 1.0


def test_the_v50_interval_covers_the_true_v50_in_95_percent_of_1000_repetitions():
    """30 shots on a fixed grid (10 velocities over +-2 sigma, 3 each), 1000 times: the profile
    likelihood-ratio interval covers V50 in 95 +- 2 % of the repetitions where a fit exists."""
    rng = np.random.default_rng(7)
    v = np.repeat(np.linspace(V50 - 2 * SIGMA, V50 + 2 * SIGMA, 10), 3)
    hits = []
    for _ in range(1000):
        fit = fit_probit(v, shots(rng, v), intervals="v50")
        if fit is not None:
            hits.append(covers(fit.v50_ci, V50))
    assert len(hits) > 950
    assert np.mean(hits) == pytest.approx(0.95, abs=0.02)


def test_on_the_sequential_design_the_interval_covers_v50_at_least_90_percent():
    """The interval on Neyer's design, 40 shots, 300 times: the design chooses its velocities
    from the outcomes, which a large-sample interval does not know; measured 93 % (60 shots)
    and 91.5 % (30 shots) in 300-400 repetitions (docs/ballistic_limit.md): the statement is 'at
    least 90 %', not 95."""
    rng = np.random.default_rng(11)
    hits = []
    for _ in range(300):
        design, done = NeyerDesign(20.0, 60.0), []
        while len(done) < 40:
            v = design.next(done, 2)
            if not v:
                break
            done += [Shot(x, bool(o)) for x, o in zip(v, shots(rng, v))]
        fit = fit_probit([s.velocity for s in done], [s.perforated for s in done], intervals="v50")
        if fit is not None:
            hits.append(covers(fit.v50_ci, V50))
    assert len(hits) > 280 and np.mean(hits) >= 0.90


def test_the_sequential_design_reaches_a_width_in_fewer_runs_than_a_fixed_grid():
    """Runs until V50's interval is within 2 sigma, median of 25 stand-ins each: Neyer's design
    from the bracket 20-60 m/s against a grid over the same bracket (9 velocities, cycled)."""
    rng = np.random.default_rng(5)
    grid = np.linspace(20.0, 60.0, 9)

    def runs_to_width(choose):
        done = []
        while len(done) < 120:
            v = choose(done)
            done += [Shot(x, bool(o)) for x, o in zip(v, shots(rng, v))]
            if len(done) % 4 == 0:
                fit = fit_probit([s.velocity for s in done], [s.perforated for s in done], intervals="v50")
                if fit is not None and fit.width <= 2 * SIGMA:
                    return len(done)
        return len(done)

    design = NeyerDesign(20.0, 60.0)
    neyer = [runs_to_width(lambda d: design.next(d, 2)) for _ in range(25)]
    fixed = [runs_to_width(lambda d: [grid[len(d) % 9], grid[(len(d) + 1) % 9]]) for _ in range(25)]
    assert np.median(neyer) < np.median(fixed)
    assert np.median(neyer) <= 0.75 * np.median(fixed)


def test_the_design_brackets_then_splits_the_gap_then_spreads_around_v50():
    design = NeyerDesign(20.0, 60.0)
    assert design.next([], 1) == [40.0] and design.next([], 3) == [30.0, 40.0, 50.0]
    assert design.phase([Shot(40.0, True)]) == "bracket"
    below = design.next([Shot(40.0, True)], 2)
    assert below == [30.0, 20.0]                         # down from the slowest perforation
    gap = [Shot(30.0, False), Shot(50.0, True)]
    assert design.phase(gap) == "overlap" and design.next(gap, 1) == [40.0]
    assert design.phase([Shot(39.0, False), Shot(39.005, True)]) == "sharp"
    assert design.next([Shot(39.0, False), Shot(39.005, True)]) == []
    both = [Shot(20.0, False), Shot(39.0, False), Shot(39.0, True), Shot(60.0, True)]
    assert design.phase(both) == "overlap"                # one velocity, both outcomes: not sharp
    assert all(abs(v - 39.0) > 1.0 for v in design.next(both, 2))
    assert design.phase([Shot(1.0, True)]) == "unbracketed"
    mixed = [Shot(v, o) for v, o in [(35, False), (38, True), (41, False), (44, True), (37, False), (42, True)]]
    assert design.phase(mixed) == "d-optimal"
    nxt = design.next(mixed, 2)
    fit = fit_probit([s.velocity for s in mixed], [s.perforated for s in mixed], intervals="none")
    z = sorted((np.array(nxt) - fit.v50) / fit.sigma)
    assert z[0] < -0.5 and z[1] > 0.5                    # D-optimal: either side of V50, not at it
    assert design.next(mixed, 2) == nxt                  # a pure function of the shots


def test_information_is_symmetric_and_largest_for_v50_at_the_middle():
    m = probit_information([37.0, 40.0, 44.0], V50, SIGMA)
    assert np.allclose(m, m.T) and np.all(np.linalg.eigvalsh(m) > 0)
    each = probit_information(np.linspace(30, 50, 201), V50, SIGMA, each=True)
    assert np.argmax(each[:, 0, 0]) == 100               # location information peaks at V50
    assert np.all(np.isfinite(probit_information([V50 + 60 * SIGMA], V50, SIGMA)))


def test_separated_outcomes_have_no_fit_only_a_bracket():
    assert separation([30, 35, 40, 45], [False, False, True, True]) == (35.0, 40.0)
    assert fit_probit([30, 35, 40, 45], [False, False, True, True]) is None
    assert fit_probit([30, 35, 35, 45], [False, False, True, True]) is None      # quasi-complete
    assert separation([30, 40, 35, 45], [False, False, True, True]) is None
    assert separation([30, 40], [False, False]) == (40.0, None)
    assert fit_probit([30, 40, 35, 45, 50, 28], [True, False, True, False, False, False]) is None  # slope < 0


def test_a_faster_bin_that_perforates_less_often_breaks_monotonicity():
    v = np.r_[np.full(12, 35.0), np.full(12, 45.0)]
    y = np.r_[np.ones(12, bool), np.zeros(12, bool)]
    bins = binned(v, y, [30.0, 40.0, 50.0])
    assert [b["perforated"] for b in bins] == [12, 0] and bins[0]["ci"][0] > 0.7
    assert len(monotone_violations(bins)) == 1
    rising = binned(v, ~y, [30.0, 40.0, 50.0])
    assert monotone_violations(rising) == []


def test_lambert_jonas_recovers_known_parameters_from_noisy_runs():
    """a = 0.9, p = 2.5, Vbl = 37 m/s, 16 perforating runs between 42 and 125 m/s with 1.5 m/s
    noise: every fitted parameter within its bootstrap interval's reach of the truth, and a and
    Vbl close to it."""
    rng = np.random.default_rng(3)
    v = np.sort(rng.uniform(42.0, 125.0, 16))
    vr = residual_velocity(v, 0.9, 2.5, 37.0) + rng.normal(0.0, 1.5, v.size)
    fit = fit_lambert_jonas(v, vr, resamples=200)
    assert covers(fit.a_ci, 0.9) and covers(fit.p_ci, 2.5) and covers(fit.vbl_ci, 37.0)
    assert fit.a == pytest.approx(0.9, abs=0.06) and fit.vbl == pytest.approx(37.0, abs=5.0)
    assert fit.rms == pytest.approx(1.5, rel=0.4) and fit.resamples > 150
    exact = fit_lambert_jonas(v, residual_velocity(v, 0.9, 2.5, 37.0), resamples=20)
    assert (exact.a, exact.p, exact.vbl) == pytest.approx((0.9, 2.5, 37.0), rel=1e-3)
    assert residual_velocity([30.0, 37.0], 0.9, 2.5, 37.0).tolist() == [0.0, 0.0]
    with pytest.raises(ValueError, match="at least 4 perforating runs"):
        fit_lambert_jonas([50.0, 60.0, 70.0], [20.0, 30.0, 40.0])


def test_the_lambert_jonas_jacobian_is_the_derivative_of_the_law():
    """The analytic d Vr / d (a, p, Vbl) the least squares use, against central differences,
    above the limit and at it (where the law is flat)."""
    from fabric_fenicsx.studies.lambert_jonas import _jacobian

    v = np.array([30.0, 38.0, 45.0, 60.0, 90.0, 125.0])
    for x in ((0.9, 2.2, 37.0), (0.7, 1.3, 20.0), (1.0, 6.0, 35.0)):
        numeric = np.column_stack([(residual_velocity(v, *(np.add(x, h))) - residual_velocity(v, *(np.subtract(x, h))))
                                   / 2e-6 for h in np.eye(3) * 1e-6])
        assert np.allclose(_jacobian(v, *x), numeric, rtol=1e-5, atol=1e-5)
    assert not _jacobian(v, 0.9, 2.2, 37.0)[0].any()           # below the limit: Vr = 0 whatever the parameters
