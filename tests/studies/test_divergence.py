"""Twin runs (fabric_fenicsx.studies.divergence, ``fabric-fenicsx divergence``): the growth
rate and crossing times on differences of known form, and the command on a small elastic
impact whose twins stay together."""
import json
import math

import numpy as np
import pytest

from fabric_fenicsx.studies.divergence import crossing_times, growth_rate, relative_difference, report

RATE = 1.0 / 20e-6   # 1/s: an e-folding time of 20 us, as the Y90 scene's 4 mm mesh before damage


def _growing(t, d0=1e-14, cap=1e-2):
    """An oscillating difference whose envelope grows as d0 exp(RATE t), capped (saturation)."""
    return np.minimum(d0 * np.exp(RATE * t) * np.abs(np.cos(2 * np.pi * t / 7e-6)), cap)


def test_growth_rate_recovers_the_envelope_of_an_oscillating_exponential():
    t = np.linspace(0.0, 800e-6, 16001)
    assert growth_rate(t, _growing(t)) == pytest.approx(RATE, rel=0.02)
    assert growth_rate(t, _growing(t, d0=1e-24)) is None      # never reaches 1e-4 by the end


def test_crossing_times_are_the_first_steps_above_each_threshold():
    t = np.arange(6) * 1e-6
    d = np.array([0.0, 3e-11, 2e-9, 5e-12, 1e-7, 2e-3])        # dips do not matter: first crossing
    assert crossing_times(t, d, (1e-10, 1e-8, 1e-6, 1e-4, 1e-2)) == pytest.approx([2e-6, 4e-6, 5e-6, 5e-6, None])


def test_report_of_twins_and_unequal_histories():
    t = np.linspace(0.0, 800e-6, 16001)
    a = {"x": 1.0 + 0.1 * t / t[-1]}
    b = {"x": a["x"] * (1.0 + _growing(t))}
    r = report(t, a, b, columns=("x",))["columns"]["x"]
    assert r["e_folding_time_s"] == pytest.approx(20e-6, rel=0.03)
    assert 0.0 < r["final_relative_difference"] <= 2e-2
    with pytest.raises(ValueError, match="differ in length"):
        relative_difference(np.ones(3), np.ones(4))


def test_the_command_on_a_small_elastic_impact_whose_twins_stay_together(tmp_path, capsys):
    """5 mm cells, damage off, 0.3 ms: the twins' histories differ by round-off only (measured:
    1.6e-10 of the fabric's kinetic energy at the end), unlike the Y90 scene's 4 mm mesh, whose
    difference grows by 1e-2 over 0.8 ms (docs/mesh_independence.md)."""
    from fabric_fenicsx.cli import main
    from tests.tools.faults import TINY_SCENE

    scene = tmp_path / "tiny.toml"
    scene.write_text(TINY_SCENE)
    assert main(["divergence", str(scene), "--out", str(tmp_path / "tw"), "--quiet"]) == 0
    rep = json.loads((tmp_path / "tw" / "divergence.json").read_text())
    assert rep["perturbation"] == pytest.approx(1e-12, rel=1e-3)
    for column, r in rep["columns"].items():
        assert r["final_relative_difference"] < 1e-8, column
        assert r["crossing_times_s"][1:] == [None] * 4, column       # never 1e-8 apart
    v = rep["residual_velocity"]
    assert math.isclose(v[0], v[1], rel_tol=1e-9) and 0.0 < v[0] < 20.0
    assert (tmp_path / "tw" / "a" / "summary.json").exists() and (tmp_path / "tw" / "b" / "history.csv").exists()
    assert "e-folding" in capsys.readouterr().out
    assert main(["divergence", str(scene), "--out", str(tmp_path / "x"), "--perturbation", "0"]) == 2
    assert "small relative change" in capsys.readouterr().err
