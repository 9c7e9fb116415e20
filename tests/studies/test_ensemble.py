"""Ensembles (fabric_fenicsx.studies.ensemble, ``fabric-fenicsx ensemble``): the members'
velocities, the statistics against hand values and the coverage of their interval, a failed
member, and the command on a small elastic impact whose members agree."""
import csv
import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from fabric_fenicsx.studies import ensemble
from fabric_fenicsx.studies.ensemble import member_row, member_velocity, offsets, statistics

ROOT = Path(__file__).resolve().parents[2]


def test_offsets_alternate_around_the_unperturbed_member():
    assert offsets(1) == [0]
    assert offsets(6) == [0, 1, -1, 2, -2, 3]
    assert member_velocity(57.3, -2, 1e-12) == 57.3 * (1 - 2e-12)
    with pytest.raises(ValueError, match="at least one member"):
        offsets(0)


def test_statistics_against_hand_values():
    s = statistics([1.0, 2.0, None, 3.0, float("nan"), 4.0])     # None and NaN are left out
    assert s["n"] == 4 and s["mean"] == 2.5 and (s["min"], s["max"]) == (1.0, 4.0)
    assert s["sd"] == pytest.approx(math.sqrt(5.0 / 3.0), rel=1e-12)
    assert s["ci95"] == pytest.approx(3.182446305284263 * math.sqrt(5.0 / 3.0) / 2.0, rel=1e-9)  # t(0.975, 3)
    assert s["relative_range"] == pytest.approx(3.0 / 2.5)
    one = statistics([7.0])
    assert one["mean"] == 7.0 and one["sd"] is None and one["ci95"] is None
    assert statistics([])["n"] == 0


def test_the_interval_covers_the_true_mean_95_percent_of_the_time_for_small_ensembles():
    """5 members from a normal distribution, 4000 times: the Student interval covers the mean in
    95 % of the draws (a normal-quantile interval, 1.96 sd / sqrt(n), would cover only 88 %)."""
    rng = np.random.default_rng(13)
    draws = rng.normal(30.0, 8.0, size=(4000, 5))
    covered = [abs(statistics(d)["mean"] - 30.0) <= statistics(d)["ci95"] for d in draws]
    assert np.mean(covered) == pytest.approx(0.95, abs=0.012)


def test_member_row_books_the_viscous_share_and_the_removed_cells():
    summary = {"residual_velocity": 30.0, "absorbed_energy": 40.0, "energies": {"viscous_dissipation": 2.0},
               "damage_onset_deflection": 0.043, "deleted_cells": 2, "eroded_cells": 48,
               "end_reason": "perforated", "wall_time_s": 9.0}
    row = member_row(-1, 57.3, summary)
    assert row["viscous_share"] == pytest.approx(0.05) and row["removed_cells"] == 50 and row["k"] == -1


def test_a_failed_member_is_reported_with_its_exit_code_and_the_others_are_kept(tmp_path, monkeypatch):
    from fabric_fenicsx.studies import runpool

    def command(run, out):
        velocity = float(run.overrides[-1].split("=")[1])
        if velocity < 57.3:
            return [sys.executable, "-c", "import sys; print('numerical trouble'); sys.exit(3)"]
        return [sys.executable, "-c", f"import json; open({str(out / 'summary.json')!r}, 'w').write(json.dumps("
                f"dict(residual_velocity={velocity - 20.0!r}, absorbed_energy=1.0)))"]
    monkeypatch.setattr(runpool, "_command", command)
    monkeypatch.setattr(runpool, "_stored", lambda run, folder: None)
    seen = []
    rows = ensemble.run_members("scene.toml", [], 57.3, 3, tmp_path, jobs=2, perturbation=1e-3,
                                on_member=seen.append)
    assert [r["k"] for r in rows] == [0, 1, -1] and len(seen) == 3
    assert rows[2]["error"] == "exit code 3: numerical trouble"
    assert rows[1]["residual_velocity"] == pytest.approx(57.3 * 1.001 - 20.0)


def test_the_command_on_a_small_elastic_impact_whose_members_agree(tmp_path, capsys):
    from fabric_fenicsx.cli import main
    from tests.tools.faults import TINY_SCENE

    scene = tmp_path / "tiny.toml"
    scene.write_text(TINY_SCENE)
    out = tmp_path / "ens"
    assert main(["ensemble", str(scene), "-n", "3", "--jobs", "2", "--out", str(out), "--quiet"]) == 0
    rep = json.loads((out / "ensemble.json").read_text())
    v = rep["statistics"]["residual_velocity"]
    assert v["n"] == 3 and 0.0 < v["mean"] < 20.0 and v["relative_range"] < 1e-9
    with open(out / "ensemble.csv") as f:
        rows = list(csv.DictReader(f))
    assert sorted(int(r["k"]) for r in rows) == [-1, 0, 1]
    assert (out / "ensemble.png").stat().st_size > 0 and (out / "member_-1" / "history.csv").exists()
    assert "+- 95 %" in capsys.readouterr().out
    assert main(["ensemble", str(scene), "-n", "1", "--out", str(tmp_path / "x")]) == 2
    assert "--members must be at least 2" in capsys.readouterr().err
    assert main(["ensemble", str(scene), "--set", "run.damping=7", "--out", str(tmp_path / "y")]) == 2


def test_members_of_a_strength_scatter_are_seeds_at_the_scenes_velocity(tmp_path, monkeypatch):
    """With first_seed the members differ by material.seed (first_seed + i), not by velocity;
    the rows carry their seed."""
    from fabric_fenicsx.studies import runpool

    seen = []

    def command(run, out):
        seen.append(run.overrides)
        seed = int(run.overrides[-1].split("=")[1])
        return [sys.executable, "-c", f"import json; open({str(out / 'summary.json')!r}, 'w').write(json.dumps("
                f"dict(residual_velocity={10.0 + seed!r}, absorbed_energy=1.0)))"]
    monkeypatch.setattr(runpool, "_command", command)
    monkeypatch.setattr(runpool, "_stored", lambda run, folder: None)
    rows = ensemble.run_members("scene.toml", ["material.scatter=weibull"], 57.3, 3, tmp_path, jobs=1,
                                first_seed=5)
    assert [r["seed"] for r in rows] == [5, 6, 7] and [r["k"] for r in rows] == [0, 1, -1]
    assert all(r["velocity"] == 57.3 for r in rows)
    assert [r["residual_velocity"] for r in rows] == [15.0, 16.0, 17.0]
    assert all("projectile.velocity=57.3" in o and o[0] == "material.scatter=weibull" for o in seen)
    assert sorted(p.name for p in tmp_path.iterdir() if p.is_dir()) == ["seed_5", "seed_6", "seed_7"]
    assert "the fabrics of scatter seeds from 5" in ensemble.format_summary(ensemble.summarise(rows, first_seed=5))
    assert "velocity changed by k x 1e-12" in ensemble.format_summary(ensemble.summarise(rows))


def test_seeds_without_a_scatter_are_refused(tmp_path):
    import subprocess

    proc = subprocess.run([sys.executable, "-m", "fabric_fenicsx.cli", "ensemble", "demos/scenes/y90.toml",
                           "--seeds", "0", "--out", str(tmp_path / "e")], cwd=ROOT, capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 2 and "--seeds needs a strength scatter" in proc.stderr


def test_two_ensembles_of_the_same_fabrics_pair_seed_by_seed(tmp_path, monkeypatch, capsys):
    """``--against``: the members of two ensembles of seeds pair by seed over the seeds both ran
    without error; an offset common to every fabric is resolved where the fabrics' own scatter
    hides it from the means."""
    from fabric_fenicsx.cli import main
    from fabric_fenicsx.studies import runpool
    from tests.tools.faults import TINY_SCENE

    scene = tmp_path / "tiny.toml"
    scene.write_text(TINY_SCENE)
    fabric = {5: 3.0, 6: 41.0, 7: 17.0, 8: 29.0, 9: 8.0, 10: 22.0}     # each fabric's own residual velocity

    def command(offset):
        def make(run, out):
            seed = int(run.overrides[-1].split("=")[1])
            if offset and seed == 9:
                return [sys.executable, "-c", "import sys; sys.exit(3)"]
            v = fabric[seed] + offset + 0.01 * seed
            return [sys.executable, "-c", f"import json; open({str(out / 'summary.json')!r}, 'w').write(json.dumps("
                    f"dict(residual_velocity={v!r}, absorbed_energy={60.0 - v!r})))"]
        return make
    monkeypatch.setattr(runpool, "_stored", lambda run, folder: None)
    base = tmp_path / "graded"
    monkeypatch.setattr(runpool, "_command", command(0.0))
    args = ["ensemble", str(scene), "--set", "material.scatter=weibull", "--seeds", "5", "--quiet", "--jobs", "1"]
    assert main([*args, "-n", "5", "--out", str(base)]) == 0
    monkeypatch.setattr(runpool, "_command", command(2.0))
    assert main([*args, "-n", "6", "--out", str(tmp_path / "aligned"), "--against", str(base)]) == 1  # seed 9 fails
    pairs = json.loads((tmp_path / "aligned" / "ensemble.json").read_text())["against"]
    assert pairs["seeds"] == [5, 6, 7, 8] and pairs["folder"] == str(base)
    v = pairs["residual_velocity"]
    assert v["n"] == 4 and v["mean_difference"] == pytest.approx(2.0) and v["difference_ci95"] < 1e-9
    assert pairs["absorbed_energy"]["mean_difference"] == pytest.approx(-2.0)
    assert "paired by fabric with" in capsys.readouterr().out
    rows = ensemble.read_members(base / "ensemble.csv")
    assert [r["seed"] for r in rows] == [5, 6, 7, 8, 9] and isinstance(rows[0]["residual_velocity"], float)
    assert main(["ensemble", str(scene), "--out", str(tmp_path / "z"), "--against", str(base)]) == 2
    assert "it needs --seeds" in capsys.readouterr().err
    assert main([*args, "--out", str(tmp_path / "w"), "--against", str(tmp_path / "none")]) == 2
    assert "holds no ensemble.csv" in capsys.readouterr().err
    assert main([*args, "--out", str(base), "--against", str(base)]) == 2
    assert "another ensemble's folder" in capsys.readouterr().err
