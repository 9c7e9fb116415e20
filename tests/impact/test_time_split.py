"""The run's time split (summary.json ``time_total_s``): table tiles the surrogate solves during a
run are a one-off cost, reported apart and taken out of the phase they were spent in. A cold
cache whose tiles are solved in the time-step checks must not take the constitutive update's time
away (it once did: the update then read 0 and the checks carried it)."""
import time

import pytest
from conftest import TINY_TOML

from fabric_fenicsx.impact.scene import load_scene
from fabric_fenicsx.impact.simulation import ImpactSimulation

SOLVE_SECONDS = 0.03


def test_tiles_solved_in_the_dt_checks_are_taken_out_of_the_checks_only(coarse_surrogate, tmp_path,
                                                                       monkeypatch):
    scene_file = tmp_path / "tiny.toml"
    scene_file.write_text(TINY_TOML.format(max_steps=60, xdmf_interval=0.0))
    sim = ImpactSimulation(load_scene(scene_file), tmp_path / "out", verbose=False,
                           surrogate=coarse_surrogate)
    checks = []
    check = sim.material.max_wave_modulus

    def check_solving_a_tile(lookahead=0.0):
        """The check, and a stand-in for a tile solved inside it (its time spent and booked)."""
        time.sleep(SOLVE_SECONDS)
        monkeypatch.setattr(coarse_surrogate, "build_seconds",
                            coarse_surrogate.build_seconds + SOLVE_SECONDS)
        t0 = time.perf_counter()
        modulus = check(lookahead)
        checks.append(time.perf_counter() - t0)
        return modulus

    monkeypatch.setattr(sim.material, "max_wave_modulus", check_solving_a_tile)
    s = sim.run()
    sim.output.close()
    total = s["time_total_s"]
    assert len(checks) >= 3
    assert total["surrogate_tiles"] == pytest.approx(SOLVE_SECONDS * len(checks))
    assert total["constitutive"] == sim.cd.timings["material"] > 0.0
    # what is left of the checks is their own work (and how much longer the sleeps slept)
    assert sum(checks) <= total["dt_check"] < sum(checks) + 0.005 * len(checks)
    assert total["bookkeeping"] >= 0.0
