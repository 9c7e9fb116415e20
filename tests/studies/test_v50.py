"""``fabric-fenicsx v50``: the outcome of a run, the estimate on stand-in runs (interrupted and
resumed, it gives the table of an uninterrupted estimate), and the command on tiny impact runs
with two jobs, continued where it stopped."""
import json
import math
import sys
from pathlib import Path


from fabric_fenicsx.studies import runpool
from fabric_fenicsx.studies.v50 import member_run, outcome

ROOT = Path(__file__).resolve().parents[2]
SCENE = str(ROOT / "demos" / "scenes" / "y90.toml")
TINY = ("mesh.kind=uniform", "mesh.n=12", "mesh.side=0.08", "run.t_end=1.5e-3", "projectile.diameter=0.02",
        "projectile.mass=0.005", "output.xdmf_interval=0", "output.progress_interval=0")
"""A 12 x 12 fabric of 80 mm hit by a 5 g projectile: held at 50 m/s, through at 95 m/s, 2-5 s a run."""


def test_outcomes_count_a_projectile_moving_back_as_held_and_a_forward_one_at_the_time_limit_as_undecided():
    assert outcome({"perforated": True, "end_reason": "perforated", "residual_velocity": 12.0}) == "perforated"
    assert outcome({"perforated": False, "end_reason": "held", "residual_velocity": 0.1}) == "held"
    assert outcome({"perforated": False, "end_reason": "rebound", "residual_velocity": -3.0}) == "held"
    assert outcome({"perforated": False, "end_reason": "time_limit", "residual_velocity": -0.2}) == "held"
    assert outcome({"perforated": False, "end_reason": "time_limit", "residual_velocity": 4.0}) == "undecided"
    assert outcome({"error": "exit code 3: blow-up"}) == "failed"


def test_members_are_seeds_with_a_scatter_and_round_off_twins_without():
    twin = member_run("s.toml", ["a.b=1"], 3, 40.0, None)
    assert twin.key == "run_003" and twin.overrides[0] == "a.b=1" and "run.stop_when_held=true" in twin.overrides
    assert f"projectile.velocity={40.0 * (1 + 3e-12)!r}" in twin.overrides
    fabric = member_run("s.toml", [], 3, 40.0, 10)
    assert "material.seed=13" in fabric.overrides and "projectile.velocity=40.0" in fabric.overrides


def _stand_in(monkeypatch, executed: list):
    """Runs replaced by a process that writes a summary drawn from the probit curve V50 = 40 m/s,
    sigma = 3 m/s (a uniform number from the run's index); a stored summary is reused."""
    def command(run, folder):
        executed.append(run.key)
        v = float(next(o for o in run.overrides if o.startswith("projectile.velocity=")).split("=")[1])
        i = int(run.key.split("_")[1])
        u = (i * 0.6180339887498949) % 1.0
        through = u < 0.5 * (1.0 + math.erf((v - 40.0) / (3.0 * math.sqrt(2.0))))
        summary = {"perforated": through, "end_reason": "perforated" if through else "held",
                   "residual_velocity": 0.9 * math.sqrt(max(v * v - 37.0 ** 2, 0.0)) if through else -1.0,
                   "absorbed_energy": 1.0, "wall_time_s": 1.0}
        return [sys.executable, "-c", f"open({str(folder / 'summary.json')!r}, 'w').write({json.dumps(summary)!r})"]

    def stored(run, folder):
        path = folder / "summary.json"
        return json.loads(path.read_text()) if path.exists() else None
    monkeypatch.setattr(runpool, "_command", command)
    monkeypatch.setattr(runpool, "_stored", stored)


def test_an_interrupted_estimate_resumes_to_the_table_of_an_uninterrupted_one(tmp_path, monkeypatch, capsys):
    from fabric_fenicsx.cli import main

    executed = []
    _stand_in(monkeypatch, executed)
    args = ["v50", SCENE, "--jobs", "2", "--max-runs", "16", "--ci", "0.5", "--quiet"]
    assert main([*args, "--out", str(tmp_path / "straight")]) == 0
    straight = (tmp_path / "straight" / "v50.csv").read_text()
    assert len(executed) == 16 and len(straight.splitlines()) == 17

    real_run_all, batches = runpool.run_all, []

    def interrupted(*a, **k):
        out = real_run_all(*a, **k)
        batches.append(1)
        if len(batches) == 3:
            raise KeyboardInterrupt
        return out
    monkeypatch.setattr(runpool, "run_all", interrupted)
    executed.clear()
    assert main([*args, "--out", str(tmp_path / "resumed")]) == 130
    assert len(executed) == 6 and len((tmp_path / "resumed" / "v50.csv").read_text().splitlines()) == 1 + 6
    monkeypatch.setattr(runpool, "run_all", real_run_all)
    executed.clear()
    assert main([*args, "--out", str(tmp_path / "resumed")]) == 0
    assert len(executed) == 10                           # the 6 stored runs are reused
    assert (tmp_path / "resumed" / "v50.csv").read_text() == straight
    rep = json.loads((tmp_path / "resumed" / "v50.json").read_text())
    assert rep["runs"] == 16 and rep["stop"].startswith("16 runs") and rep["counts"]["undecided"] == 0
    if rep["probit"] is not None:
        lo, hi = rep["probit"]["v50_ci"]
        assert rep["answer"] in ("v50", "per-velocity") and (lo is None or lo < rep["probit"]["v50"])
    assert (tmp_path / "resumed" / "v50.png").stat().st_size > 0


def test_bad_options_are_refused_with_one_line(tmp_path, capsys):
    from fabric_fenicsx.cli import main

    assert main(["v50", SCENE, "--ci", "0", "--bracket", "60,20", "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err
    assert "--ci must be a width > 0" in err and "--bracket must be LO,HI" in err
    assert main(["v50", SCENE, "--max-runs", "1", "--out", str(tmp_path / "y")]) == 2


def test_the_command_on_tiny_impact_runs_with_two_jobs_goes_on_where_it_stopped(tmp_path, capsys):
    from fabric_fenicsx.cli import main

    out = tmp_path / "v50"
    base = ["v50", SCENE, "--jobs", "2", "--bracket", "20,200", "--out", str(out), "--quiet",
            *[a for o in TINY for a in ("--set", o)]]
    assert main([*base, "--max-runs", "4"]) == 0
    first = (out / "v50.csv").read_text().splitlines()
    stamp = (out / "run_000" / "summary.json").stat().st_mtime_ns
    assert main([*base, "--max-runs", "6"]) == 0
    again = (out / "v50.csv").read_text().splitlines()
    assert again[:5] == first and len(again) == 7
    assert (out / "run_000" / "summary.json").stat().st_mtime_ns == stamp
    rep = json.loads((out / "v50.json").read_text())
    assert rep["runs"] == 6 and rep["counts"]["held"] >= 1 and rep["counts"]["perforated"] >= 1
    assert "V50" in capsys.readouterr().out or rep["bracket"] is not None
    assert (out / "v50.png").stat().st_size > 0
    # resumed with one job, the design would start elsewhere: the stored runs are taken as they are
    stamps = [(out / f"run_{i:03d}" / "summary.json").stat().st_mtime_ns for i in range(6)]
    base[base.index("--jobs") + 1] = "1"
    assert main([*base, "--max-runs", "7"]) == 0
    resumed = (out / "v50.csv").read_text().splitlines()
    assert resumed[:7] == again and len(resumed) == 8
    assert [(out / f"run_{i:03d}" / "summary.json").stat().st_mtime_ns for i in range(6)] == stamps
