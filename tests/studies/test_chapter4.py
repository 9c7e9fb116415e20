"""The chapter-4 studies (docs/validation.md): the ballistic-limit bisection on stand-in functions, which
runs each study makes, the thesis's findings from the numbers, parallel runs that equal serial
ones, and the ``study`` command on tiny runs."""
import json
import sys

import pytest

from fabric_fenicsx.studies import chapter4
from fabric_fenicsx.studies.limit import bisect_limit
from fabric_fenicsx.studies.runpool import Run, run_all

TINY = ("mesh.kind=uniform", "mesh.n=12", "mesh.side=0.08", "run.t_end=2e-4", "projectile.diameter=0.02",
        "projectile.mass=0.005", "output.xdmf_interval=0", "output.progress_interval=0")
"""A 12 x 12 fabric of 80 mm hit by a 5 g projectile for 0.2 ms: a run of about a second."""


def test_bisection_brackets_a_sharp_limit_to_the_tolerance():
    r = bisect_limit(lambda v: [v > 37.2], 20.0, 60.0, tol=0.5)
    lo, hi = r["band"]
    assert r["found"] and lo <= 37.2 < hi and hi - lo <= 0.5 and r["lower"] == r["upper"] == (lo, hi)
    assert r["limit"] == pytest.approx(37.2, abs=0.25)


def test_bisection_keeps_scattered_outcomes_as_a_band():
    """Two runs a velocity whose limits are 36.6 and 37.8 m/s: the band runs from the last
    velocity where both held to the first where both perforated, each edge to the tolerance."""
    r = bisect_limit(lambda v: [v > 36.6, v > 37.8], 20.0, 60.0, tol=0.5)
    lo, hi = r["band"]
    assert r["found"] and 36.1 <= lo <= 36.6 and 37.8 <= hi <= 38.3
    assert r["lower"][0] <= 36.6 < r["lower"][1] and r["upper"][0] <= 37.8 < r["upper"][1]
    velocities = [v for v, _ in r["tries"]]
    assert len(velocities) == len(set(velocities))           # no velocity run twice


def test_bisection_widens_the_bracket_and_says_when_it_finds_no_limit():
    low = bisect_limit(lambda v: [v > 7.2], 20.0, 60.0)
    assert low["found"] and low["band"][0] <= 7.2 < low["band"][1]
    high = bisect_limit(lambda v: [v > 700.0], 20.0, 60.0, expand=3)
    assert not high["found"] and high["limit"] is None
    assert high["band"] == (480.0, None) and [v for v, _ in high["tries"]] == [20.0, 60.0, 120.0, 240.0, 480.0]
    with pytest.raises(ValueError):
        bisect_limit(lambda v: [True], 60.0, 20.0)


def test_every_study_runs_what_the_thesis_ran_and_shares_runs():
    counts = {name: len(chapter4.plan(name)) for name in ("table4", "table5", "table6", "friction", "fillet")}
    assert counts == {"table4": 5, "table5": 10, "table6": 15, "friction": 6, "fillet": 3}
    keys = [r.key for r in chapter4.plan("chapter4", ("run.t_end=1e-3",))]
    assert len(keys) == len(set(keys)) == 20 + 4 + 2       # four scenes x five V0, friction, fillet
    assert "Y90-v57.3" in keys and "XY0-v57.3-mu2" in keys and "Y90-v57.3-fillet0.8mm" in keys
    run = {r.key: r for r in chapter4.plan("chapter4", ("run.t_end=1e-3",))}["XY0-v57.3-mu0.1"]
    assert run.overrides[0] == "run.t_end=1e-3" and "projectile.friction=0.1" in run.overrides
    v50 = [r.key for r in chapter4.plan("v50")]
    assert v50 == [f"{s}-v{v}" for s in chapter4.SCENES for v in (34.5, 39.78)]
    assert set(v50) <= set(keys)          # chapter4 makes them once, for the tables
    with pytest.raises(ValueError, match="unknown study"):
        chapter4.plan("table7")


def test_the_bisection_starts_from_the_tightest_bracket_the_table_runs_give():
    def runs(*outcomes, scene="XY0"):
        return {chapter4.run_key(scene, v): o if isinstance(o, dict) else {"perforated": o}
                for v, o in zip(chapter4.VELOCITIES, outcomes)}

    assert chapter4.v50_start("XY0", runs(False, True, True)) == (34.5, 39.78)
    assert chapter4.v50_start("XY0", runs(False, False, True)) == (39.78, 57.3)
    assert chapter4.v50_start("XY0", runs(False, False, False, False, False)) == chapter4.V50_BRACKET
    assert chapter4.v50_start("XY0", runs(True, False, True)) == chapter4.V50_BRACKET   # no hold below
    assert chapter4.v50_start("XY0", runs(False)) == chapter4.V50_BRACKET               # 39.78 not run
    assert chapter4.v50_start("XY0", runs(False, {"error": "x"}, True)) == chapter4.V50_BRACKET
    assert chapter4.v50_start("Y90", runs(False, True)) == chapter4.V50_BRACKET          # another scene's
    assert chapter4.v50_start("XY0", {}, default=(1.0, 2.0)) == (1.0, 2.0)
    first = chapter4.v50_run("XY0", 34.5, 0, ("run.t_end=1e-3",))
    table = {r.key: r for r in chapter4.plan("table5", ("run.t_end=1e-3",))}["XY0-v34.5"]
    assert first == table
    other = chapter4.v50_run("XY0", 34.5, 1, ("run.t_end=1e-3",))
    assert other.key == "XY0-v50-v34.5000-k1" and other.overrides[-1] == f"projectile.velocity={34.5 * (1 + 1e-12)!r}"
    assert "run.stop_when_held=true" in other.overrides and "run.stop_when_held=true" not in first.overrides
    assert chapter4.v50_run("XY0", 37.14, 0).key == "XY0-v50-v37.1400-k0"


def test_concurrent_studies_share_the_processes_they_are_given(tmp_path, monkeypatch):
    """Two threads, each running three stand-in runs two at a time, with two slots between them:
    never more than two processes at once (without the slots, up to four), every slot given back."""
    import threading

    from fabric_fenicsx.studies import runpool

    monkeypatch.setattr(runpool, "_command", lambda run, out: [sys.executable, "-c", (
        "import json, time; t0 = time.time(); time.sleep(0.6); "
        f"open({str(out / 'summary.json')!r}, 'w').write(json.dumps(dict(start=t0, end=time.time())))")])
    monkeypatch.setattr(runpool, "_stored", lambda run, folder: None)
    scene = str(chapter4.SCENE_DIR / "y90.toml")
    slots = threading.BoundedSemaphore(2)
    done = {}

    def study(name):
        done.update(run_all([Run(f"{name}{i}", scene, TINY) for i in range(3)], tmp_path, jobs=2, slots=slots))

    threads = [threading.Thread(target=study, args=(name,)) for name in "ab"]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert sorted(done) == ["a0", "a1", "a2", "b0", "b1", "b2"]
    events = sorted([(s["start"], 1) for s in done.values()] + [(s["end"], -1) for s in done.values()])
    running = [sum(e for _, e in events[:i + 1]) for i in range(len(events))]
    assert max(running) <= 2
    assert slots.acquire(blocking=False) and slots.acquire(blocking=False)   # every slot given back


def _summary(absorbed, peak=0.03, reach=0.02):
    return {"residual_velocity": 10.0, "absorbed_energy": absorbed, "max_deflection": peak,
            "damage_extent_radius": reach}


def test_the_checklist_answers_from_the_numbers():
    results = {}
    for v in chapter4.VELOCITIES:
        results[chapter4.run_key("Y90", v)] = _summary(40.0, reach=0.05)
        results[chapter4.run_key("XY0", v)] = _summary(30.0, peak=0.03, reach=0.02)
        results[chapter4.run_key("XY45", v)] = _summary(35.0, peak=0.035)
    results[chapter4.run_key("Y90", 57.3, friction=0.1)] = _summary(40.0, reach=0.09)
    results[chapter4.run_key("Y90", 57.3, friction=2.0)] = _summary(40.0, reach=0.03)
    results[chapter4.run_key("Y90", 57.3, fillet=0.8e-3)] = _summary(40.0, reach=0.08)
    results[chapter4.run_key("Y90", 57.3, fillet=2e-3)] = _summary(20.0)
    holds = [h for _, h, _ in chapter4.checklist(results)]
    assert holds == [True, True, True, True, None]          # the wave speeds are not measured
    results[chapter4.run_key("XY0", 83.06)] = _summary(45.0)  # one velocity where XY0 absorbs more
    results[chapter4.run_key("Y90", 57.3, fillet=2e-3)] = _summary(35.0)
    holds = [h for _, h, _ in chapter4.checklist(results)]
    assert holds[0] is False and holds[3] is False
    del results[chapter4.run_key("XY45", 34.5)]
    assert chapter4.checklist(results)[1][1] is None


def test_runs_in_parallel_equal_the_serial_ones_and_are_reused(tmp_path):
    scene = str(chapter4.SCENE_DIR / "y90.toml")
    runs = [Run("a", scene, (*TINY, "projectile.velocity=20.0")), Run("b", scene, (*TINY, "projectile.velocity=60.0"))]
    serial = run_all(runs, tmp_path / "serial", jobs=1)
    seen = []
    parallel = run_all(runs, tmp_path / "parallel", jobs=2, on_done=lambda r, s, reused: seen.append(reused))
    assert seen == [False, False]
    for key in ("a", "b"):
        assert "error" not in serial[key], serial[key]
        for q in ("residual_velocity", "absorbed_energy", "n_steps", "energy_error"):
            assert parallel[key][q] == serial[key][q], (key, q)
    assert serial["a"]["residual_velocity"] != serial["b"]["residual_velocity"]
    again = []
    run_all(runs, tmp_path / "parallel", jobs=2, on_done=lambda r, s, reused: again.append(reused))
    assert again == [True, True]
    with pytest.raises(ValueError, match="must differ"):
        run_all([runs[0], runs[0]], tmp_path / "x")


def test_the_study_command_on_tiny_runs_and_its_input_errors(tmp_path, capsys):
    from fabric_fenicsx.cli import main

    tiny = [a for o in TINY for a in ("--set", o)]
    out = tmp_path / "fillet"
    assert main(["study", "fillet", "--out", str(out), "--jobs", "2", *tiny]) == 0
    md = (out / "fillet.md").read_text()
    assert md.count("| Y90, fillet ") == 3 and "damage_fillet.png" in md
    assert (out / "pictures" / "damage_fillet.png").stat().st_size > 10000
    report = json.loads((out / "fillet.json").read_text())
    assert set(report["runs"]) == {"Y90-v57.3", "Y90-v57.3-fillet0.8mm", "Y90-v57.3-fillet2mm"}
    capsys.readouterr()
    assert main(["study", "fillet", "--out", str(out), "--jobs", "2", *tiny]) == 0
    assert capsys.readouterr().out.count(": stored,") == 3
    assert main(["study", "table7", "--out", str(tmp_path / "x")]) == 2
    assert "unknown study 'table7'" in capsys.readouterr().err
    assert main(["study", "table4", "--jobs", "0", "--out", str(tmp_path / "y")]) == 2
    assert "--jobs must be at least 1" in capsys.readouterr().err
    assert main(["study", "table4", "--set", "run.damping=7", "--out", str(tmp_path / "z")]) == 2


def test_the_ballistic_limit_study_bisects_each_scene_on_its_runs(tmp_path, monkeypatch, capsys):
    """``study v50`` with stand-in runs (a run perforates above 37 m/s, Y0's members disagree
    between 41 and 42 m/s, XY45's runs fail): each scene's limit and band, the failure reported
    and the other scenes done."""
    from fabric_fenicsx.cli import main
    from fabric_fenicsx.studies import runpool

    def command(run, out):
        v = float([o for o in run.overrides if o.startswith("projectile.velocity=")][-1].split("=")[1])
        scene = run.key.split("-")[0]
        if scene == "XY45":
            return [sys.executable, "-c", "import sys; print('stand-in failure'); sys.exit(1)"]
        limit = 41.0 if scene == "Y0" and run.key.endswith("k0") else 42.0 if scene == "Y0" else 37.0
        summary = dict(residual_velocity=v - limit, absorbed_energy=1.0, end_reason="x", perforated=v > limit)
        return [sys.executable, "-c", f"import json; open({str(out / 'summary.json')!r}, 'w').write({json.dumps(summary)!r})"]
    monkeypatch.setattr(runpool, "_command", command)
    monkeypatch.setattr(runpool, "_stored", lambda run, folder: None)
    assert main(["study", "v50", "--out", str(tmp_path), "--jobs", "2", "--tol", "0.5"]) == 1   # XY45's runs failed
    limits = json.loads((tmp_path / "v50.json").read_text())["v50"]
    for scene in ("Y90", "XY0"):
        lo, hi = limits[scene]["band"]
        assert lo <= 37.0 < hi and hi - lo <= 0.5
        assert limits[scene]["start"] == [34.5, 39.78]        # the table runs at 34.5 and 39.78 bracket it
        tried = [v for v, _ in limits[scene]["tries"]]
        assert min(tried) == 34.5 and max(tried) == 39.78 and len(tried) == 6   # 5.28 m/s halved 4 times
        assert not (tmp_path / "runs" / f"{scene}-v50-v34.5000-k0").exists()   # member 0 is the table's run
        assert (tmp_path / "runs" / f"{scene}-v50-v34.5000-k1" / "summary.json").exists()
    assert limits["Y0"]["start"] == limits["XY45"]["start"] == list(chapter4.V50_BRACKET)  # held at both; failed
    lo, hi = limits["Y0"]["band"]
    assert 40.5 <= lo <= 41.0 and 42.0 <= hi <= 42.5
    assert "stand-in failure" in limits["XY45"]["error"]
    md = (tmp_path / "v50.md").read_text()
    xy45 = [line for line in md.splitlines() if line.startswith("| XY45 |")]
    assert len(xy45) == 1 and "not found: a run failed" in xy45[0] and "stand-in failure" in xy45[0]
    y90 = [line for line in md.splitlines() if line.startswith("| Y90 |")]
    assert len(y90) == 1 and y90[0].startswith(f"| Y90 | {limits['Y90']['limit']:.2f} |") and "| 34.5 - 39.78 |" in y90[0]
    assert "- Y0: runs perforated from 41" in md
    # the failure is stored with its settings and model version and reported again, not rerun
    failed = tmp_path / "runs" / "XY45-v50-v20.0000-k0" / "failed.json"
    assert json.loads(failed.read_text())["error"] == "exit code 1: stand-in failure"
    monkeypatch.undo()
    monkeypatch.setattr(runpool, "_command", lambda run, out: (_ for _ in ()).throw(AssertionError(run.key))
                        if run.key.startswith("XY45") else command(run, out))
    assert main(["study", "v50", "--out", str(tmp_path), "--jobs", "2", "--tol", "0.5"]) == 1


def test_a_failure_is_stored_but_a_killed_or_interrupted_run_is_not(tmp_path, monkeypatch):
    from fabric_fenicsx.studies import runpool

    codes = {"fails": "sys.exit(1)", "killed": "os.kill(os.getpid(), signal.SIGKILL)", "interrupted": "sys.exit(130)"}
    monkeypatch.setattr(runpool, "_command", lambda run, out: [
        sys.executable, "-c", f"import os, signal, sys; print('stop'); {codes[run.key]}"])
    scene = str(chapter4.SCENE_DIR / "y90.toml")
    done = run_all([Run(k, scene, TINY) for k in codes], tmp_path, jobs=3)
    assert all("error" in s for s in done.values())
    assert [k for k in codes if (tmp_path / k / "failed.json").exists()] == ["fails"]
    again = run_all([Run("fails", scene, TINY)], tmp_path, jobs=1,
                    on_done=lambda r, s, reused: pytest.fail("a stored failure is not run") if not reused else None)
    assert again["fails"]["error"] == "exit code 1: stop"
