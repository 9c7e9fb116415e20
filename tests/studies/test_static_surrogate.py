"""The static scenes through the surrogate still meet the thesis's numbers (issue: surrogate)."""

import pytest

from fabric_fenicsx.studies.static import run_scenario


@pytest.fixture(scope="module")
def scenario_1():
    return run_scenario("uniaxial-strain", backend="surrogate", progress=False)


@pytest.fixture(scope="module")
def scenario_3():
    return run_scenario("equibiaxial", backend="surrogate", progress=False)


def test_uniaxial_strain_through_the_surrogate(scenario_1):
    kp = scenario_1.key_points
    assert kp["peak_P1"]["E1"] == pytest.approx(0.049, abs=0.002)
    assert kp["complete_failure"]["warp"] == pytest.approx(0.066, abs=0.003)
    assert kp["damage_onset"]["fill"] is None
    assert kp["peak_P1"]["P1"] == pytest.approx(148e3, rel=0.005)


def test_equibiaxial_through_the_surrogate(scenario_3):
    kp = scenario_3.key_points
    assert kp["damage_onset"]["fill"] == pytest.approx(0.029, abs=0.002)
    assert kp["complete_failure"]["fill"] == pytest.approx(0.0325, abs=0.002)
    assert kp["complete_failure"]["warp"] == pytest.approx(0.091, abs=0.003)


def test_cli_via_surrogate_follows_the_same_path(tmp_path, scenario_1, capsys):
    """``fabric-fenicsx static --via surrogate``: the command runs the scene through the
    surrogate (its key points say so) and gives, at the coarser step, the surrogate's stresses
    of the same path (damage depends on the largest stretch only) and the thesis's peak."""
    import csv
    import json

    import numpy as np

    from fabric_fenicsx.cli import main
    from fabric_fenicsx.studies.static import run_scenario

    out = tmp_path / "out"
    assert main(["static", "--scenario", "uniaxial-strain", "--via", "surrogate", "--step", "0.002",
                 "--out", str(out), "--quiet"]) == 0
    kp = json.loads((out / "uniaxial-strain.json").read_text())
    assert kp["backend"] == scenario_1.backend
    assert kp["backend"] != run_scenario("uniaxial-strain", step=0.02, progress=False).backend
    assert kp["peak_P1"]["E1"] == pytest.approx(0.049, abs=0.003)
    with open(out / "uniaxial-strain.csv") as f:
        rows = [{k: float(v) for k, v in r.items() if k != "leg"} for r in csv.DictReader(f)]
    fine = scenario_1.data
    rows = [r for r in rows if r["E1"] <= fine["E1"][-1] + 1e-12]      # both paths run past failure
    assert len(rows) > 30
    E1 = np.array([r["E1"] for r in rows])
    idx = np.searchsorted(fine["E1"], E1 - 1e-12)
    assert np.allclose(fine["E1"][idx], E1, atol=1e-12)
    np.testing.assert_allclose([r["P1"] for r in rows], fine["P1"][idx], rtol=0, atol=1e-3 * 148e3)
    np.testing.assert_allclose([r["alpha1"] for r in rows], fine["alpha1"][idx], rtol=0, atol=1e-6)
    assert "peak of P1" in capsys.readouterr().out
