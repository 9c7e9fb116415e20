"""Pure helpers of the convergence study (observed order, Richardson, selection rule) and a
tiny unit-cell ladder. Fast: no impact run, no timing assertions."""

import math

import numpy as np
import pytest

from fabric_fenicsx.cli import convergence as cli
from fabric_fenicsx.studies import convergence as cv


def manufactured(h, f0=3.0, C=2.0, p=1.5):
    return f0 + C * np.asarray(h, dtype=float) ** p


@pytest.mark.parametrize("h", [(0.4, 0.2, 0.1), (0.9, 0.6, 0.2), (0.1, 0.4, 0.2)])
def test_observed_order_recovers_known_order(h):
    # constant ratio (closed form), non-constant ratio (root finding), and unsorted levels
    assert cv.observed_order(h, manufactured(h)) == pytest.approx(1.5, rel=1e-8)


def test_observed_order_decreasing_quantity():
    h = (4.0, 2.0, 1.0)
    f = 51.0 - 0.7 * np.asarray(h) ** 2
    assert cv.observed_order(h, f) == pytest.approx(2.0, rel=1e-10)


def test_observed_order_oscillating_or_flat_is_nan():
    assert math.isnan(cv.observed_order((4, 2, 1), (1.0, 2.0, 1.5)))
    assert math.isnan(cv.observed_order((4, 2, 1), (1.0, 1.0, 1.5)))


def test_observed_order_bad_input():
    with pytest.raises(ValueError):
        cv.observed_order((1, 2), (1, 2))
    with pytest.raises(ValueError):
        cv.observed_order((1, 1, 2), (1, 2, 3))
    with pytest.raises(ValueError):
        cv.observed_order((0, 1, 2), (1, 2, 3))


@pytest.mark.parametrize("h", [(0.4, 0.2, 0.1), (0.9, 0.6, 0.2)])
def test_richardson_recovers_limit(h):
    f = manufactured(h)
    p = cv.observed_order(h, f)
    assert cv.richardson(h, f, p) == pytest.approx(3.0, rel=1e-9)
    # with a wrong order the extrapolation misses the limit
    assert abs(cv.richardson(h, f, 1.0) - 3.0) > 1e-3


def test_richardson_bad_order():
    with pytest.raises(ValueError):
        cv.richardson((2, 1), (1.0, 1.1), 0.0)


def test_ladder_analysis_errors_and_validity():
    h = np.array([0.8, 0.4, 0.2, 0.1])
    a = cv.ladder_analysis(h, manufactured(h))
    assert a["richardson_valid"]
    assert a["order"] == pytest.approx(1.5, rel=1e-8)
    assert a["richardson"] == pytest.approx(3.0, rel=1e-9)
    expected = 2.0 * h ** 1.5 / 3.0
    np.testing.assert_allclose(a["err_richardson"], expected, rtol=1e-7)
    assert a["err_finest"][-1] == 0.0
    # order 8 from an irregular sequence: outside the sensible range, no extrapolation
    b = cv.ladder_analysis(h[:3], [1.0, 1.0 + 1e-3 * 2 ** -8, 1.0])
    assert not b["richardson_valid"] and np.all(np.isnan(b["err_richardson"]))


def test_ladder_analysis_skips_failed_level():
    h = np.array([0.8, 0.4, 0.2, 0.1])
    v = manufactured(h)
    v[1] = np.nan
    a = cv.ladder_analysis(h, v)
    # uses 0.8, 0.2, 0.1 (non-constant ratio) and still finds the order
    assert a["order"] == pytest.approx(1.5, rel=1e-8)


def test_cheapest_within_rule():
    costs = [1.0, 2.0, 4.0, 8.0]
    assert cv.cheapest_within(costs, [0.9, 1.01, 0.985, 1.0], 1.0) == 1
    # a coarse level that crosses the reference by luck is not chosen
    assert cv.cheapest_within(costs, [1.01, 0.9, 0.99, 1.0], 1.0) == 2
    # order of the input does not matter, only cost
    assert cv.cheapest_within(costs[::-1], [1.0, 0.985, 1.01, 0.9], 1.0) == 2
    assert cv.cheapest_within(costs, [0.5, 0.6, 0.7, 0.9], 1.0) is None
    assert cv.cheapest_within(costs, [0.99, np.nan, 0.995, 1.0], 1.0) == 2


def test_cheapest_within_bad_input():
    with pytest.raises(ValueError):
        cv.cheapest_within([1, 2], [1.0], 1.0)
    with pytest.raises(ValueError):
        cv.cheapest_within([1, 2], [1.0, 1.0], 0.0)


def test_run_names_distinguish_settings():
    names = {cv.run_name(c, h, s) for c in cv.CASES for h in (2e-3, 1.41e-3) for s in (0.8, 0.4)}
    assert len(names) == 8
    assert cv.run_name("damaged", 2e-3, 0.8) == "damaged-h2mm-s0.8"


def test_unitcell_ladder_smoke():
    uc = cv.unitcell_study(ladder=(4, 8), reference=32, states=[(0.03, 0.01, (1.0, 1.0))], log=lambda s: None)
    err = {x["n"]: x["err_P1"] for x in uc["rows"]}
    assert err[32] == 0.0
    assert 0.0 < err[8] < err[4]
    assert all(x["ref_in_contact"] for x in uc["rows"])


def test_ladder_analysis_failed_finest_level_uses_next():
    h = np.array([0.4, 0.2, 0.1])
    v = np.array([1.2, 1.1, np.nan])
    a = cv.ladder_analysis(h, v)
    assert a["finest"] == 1.1
    assert a["err_finest"][1] == 0.0 and a["err_finest"][0] == pytest.approx(0.1 / 1.1)
    assert math.isnan(a["order"])


def test_scatter_runs_change_only_the_impact_velocity_and_have_their_own_folders():
    base = cv.scene_for("damaged", 2e-3, 0.8).to_dict()
    moved = cv.scene_for("damaged", 2e-3, 0.8, perturbation=1e-12).to_dict()
    assert moved["projectile"].pop("velocity") == pytest.approx(57.3 * (1 + 1e-12), rel=1e-15)
    assert base["projectile"].pop("velocity") == 57.3
    assert moved == base
    names = {cv.run_name("damaged", 2e-3, 0.8, p) for p in (0.0, *cv.SCATTER_PERTURBATIONS)}
    assert len(names) == 1 + len(cv.SCATTER_PERTURBATIONS)


def ensemble(h, values, cpu=10.0):
    recs = [cv.RunRecord("damaged", h, 0.8, f"r{k}", values={"residual_velocity": v, "cpu_s": cpu})
            for k, v in enumerate(values)]
    return recs + [cv.RunRecord("damaged", h, 0.8, "bad", error="ImpactError: stopped")]


def test_scatter_spread():
    s = cv.scatter_spread(ensemble(2e-3, (48.0, 50.0, 49.0, 49.0)))
    assert s["n"] == 4 and s["mean"] == pytest.approx(49.0) and s["cpu_s"] == 10.0
    std = np.std([48.0, 50.0, 49.0, 49.0], ddof=1)
    assert s["std_rel"] == pytest.approx(std / 49.0) and s["sem_rel"] == pytest.approx(std / 2 / 49.0)
    assert s["max_rel"] == pytest.approx(1.0 / 49.0)
    assert cv.scatter_spread(ensemble(2e-3, (48.0,))) == {}


def test_ensemble_recommendation_takes_the_coarsest_level_with_every_finer_mean_within_tol():
    ens = {h: cv.scatter_spread(ensemble(h, v)) for h, v in
           ((4e-3, (47.0, 47.4)), (2.83e-3, (45.0, 45.4)), (2e-3, (47.9, 48.3)), (1.41e-3, (48.0, 48.4)))}
    rec = cv.ensemble_recommendation(ens)
    assert rec["reference"] == pytest.approx(48.2)
    assert rec["h"] == 2e-3          # 4 mm is within 2 % but 2.83 mm, finer, is not
    assert rec["distance"][2.83e-3] == pytest.approx(3.0 / 48.2)
    # each mean of two runs 0.4 apart has a standard error of 0.2 m/s
    assert rec["se"][2e-3] == pytest.approx(math.hypot(0.2 / 48.2, 0.2 / 48.2))
    assert rec["verdict"] == {4e-3: "undecided", 2.83e-3: "beyond", 2e-3: "within"}
    assert cv.ensemble_recommendation({2e-3: ens[2e-3]})["h"] is None
    assert cv.scatter_spread(ensemble(2e-3, (1.0, -1.0))) == {}      # zero mean: no relative spread


def test_dt_ladder_mesh_per_case():
    import argparse
    parser = argparse.ArgumentParser()
    cli.add_arguments(parser)
    assert parser.parse_args(["--dt-mesh", "damaged=1.41", "--dt-mesh", "3"]).dt_mesh == [("damaged", 1.41), (None, 3.0)]
    with pytest.raises(SystemExit):
        parser.parse_args(["--dt-mesh", "plastic=2"])
    runs = cv.plan(["dt"], {}, [0.9, 0.8, 0.6], {"damaged": 1.41, "elastic": 2.0})
    assert {(c, h) for _, c, h, _ in runs} == {("damaged", 1.41e-3), ("elastic", 2e-3)}
    assert len(runs) == 6


def test_cases_select_the_ladders_that_run():
    """``--cases`` (default elastic: after damage a single run is a draw) keeps only the chosen
    cases' mesh and dt ladders; an unknown case is refused."""
    import argparse
    parser = argparse.ArgumentParser()
    cli.add_arguments(parser)
    assert parser.parse_args([]).cases == ["elastic"]
    with pytest.raises(SystemExit):
        parser.parse_args(["--cases", "elastic,plastic"])
    for given, expected in ((["--cases", "elastic"], {"elastic"}), (["--cases", "damaged,elastic"], {"damaged", "elastic"})):
        args = parser.parse_args(given)
        levels, safeties, dt_mesh = cli._ladders(args)
        runs = cv.plan(["mesh", "dt"], levels, safeties, dt_mesh)
        assert {c for _, c, _, _ in runs} == expected
        assert len(runs) == len(expected) * (len(cv.MESH_LEVELS_MM["elastic"]) + len(cv.DT_SAFETIES))
