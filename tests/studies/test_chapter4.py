"""The chapter-4 studies (docs/validation.md): which runs each study makes, the ballistic limits on
stand-in runs, the thesis's findings from the numbers, parallel runs that equal serial
ones, and the ``study`` command on tiny runs."""
import json
import sys

import pytest

from fabric_fenicsx.studies import chapter4
from fabric_fenicsx.studies.runpool import Run, run_all
from tests.tools.limits import check_stand_in_limits, stand_in_limits

TINY = ("mesh.kind=uniform", "mesh.n=12", "mesh.side=0.08", "run.t_end=2e-4", "projectile.diameter=0.02",
        "projectile.mass=0.005", "output.xdmf_interval=0", "output.progress_interval=0")
"""A 12 x 12 fabric of 80 mm hit by a 5 g projectile for 0.2 ms: a run of about a second."""


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


def test_the_ballistic_limit_starts_from_the_tightest_bracket_the_table_runs_give():
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


def test_members_of_a_run_are_round_off_twins_or_seeds_and_are_read_as_means():
    runs = {r.key: r for r in chapter4.plan("fillet", ("run.t_end=1e-3",), members=3)}
    assert len(runs) == 9 and {"Y90-v57.3", "Y90-v57.3-m1", "Y90-v57.3-m2", "Y90-v57.3-fillet2mm-m2"} <= set(runs)
    assert runs["Y90-v57.3-m1"].overrides[-1] == f"projectile.velocity={57.3 * (1 + 1e-12)!r}"
    assert runs["Y90-v57.3-m2"].overrides[-1] == f"projectile.velocity={57.3 * (1 - 1e-12)!r}"
    assert runs["Y90-v57.3"] == chapter4.plan("fillet", ("run.t_end=1e-3",))[0]      # member 0: the run itself
    seeds = {r.key: r for r in chapter4.plan("fillet", ("material.scatter=weibull", "material.seed=7"), members=3)}
    assert seeds["Y90-v57.3-m2"].overrides[-1] == "material.seed=9" and "projectile.velocity=57.3" in seeds[
        "Y90-v57.3-m2"].overrides
    with pytest.raises(ValueError, match="at least one member"):
        chapter4.plan("fillet", members=0)
    results = {"Y90-v57.3": _summary(40.0), "Y90-v57.3-m1": _summary(42.0), "Y90-v57.3-m2": _summary(44.0),
               "Y90-v57.3-m3": {"error": "exit code 1"}, "Y90-v57.3-mu2": _summary(1.0)}
    m = chapter4.value(results, "Y90-v57.3", "absorbed_energy")
    assert (m.mean, m.n) == (42.0, 3) and m.half_width == pytest.approx(4.303 * 2.0 / 3 ** 0.5, rel=1e-3)
    assert chapter4.fmt(m) == "42.00 +- 4.97 (n 3)" and chapter4.value(results, "XY0-v57.3", "absorbed_energy") is None
    assert chapter4.value(results, "Y90-v57.3-mu2", "absorbed_energy").text() == "1.00"


def test_a_finding_from_members_holds_fails_or_cannot_be_told():
    from fabric_fenicsx.studies.means import UNTOLD, larger, mean_of

    def members(key, absorbed):
        return {chapter4.member_key(key, i): _summary(a, reach=0.05 if key.startswith("Y90") else 0.02)
                for i, a in enumerate(absorbed)}

    def first_finding(y90, xy0):
        results = {}
        for v in chapter4.VELOCITIES:
            results |= members(chapter4.run_key("Y90", v), y90) | members(chapter4.run_key("XY0", v), xy0)
        return chapter4.checklist(results)[0]

    assert first_finding([40.0, 41.0, 39.0], [30.0, 31.0, 29.0])[1] is True
    assert first_finding([30.0, 31.0, 29.0], [40.0, 41.0, 39.0])[1] is False
    finding, holds, numbers = first_finding([40.0, 30.0, 35.0], [38.0, 29.0, 33.0])
    assert holds == UNTOLD and "5 not told apart" in numbers and "35.00 +- " in numbers
    assert larger(mean_of([2.0]), mean_of([1.0])) is True and larger(mean_of([1.0]), None) is None
    assert larger(mean_of([1.0, 1.0]), mean_of([1.0, 1.0])) == UNTOLD


def test_the_study_reports_a_case_with_members_as_their_mean(tmp_path, monkeypatch):
    """``study fillet --members 2`` with stand-in runs whose absorbed energy is the velocity's
    12th digit made visible (40 J at V0, 42 J at V0 (1 + 1e-12)): each case's row is the mean +-
    its interval over its two members."""
    from fabric_fenicsx.cli import main
    from fabric_fenicsx.studies import runpool

    def command(run, out):
        v = float([o for o in run.overrides if o.startswith("projectile.velocity=")][-1].split("=")[1])
        summary = dict(residual_velocity=30.0, absorbed_energy=40.0 if v == 57.3 else 42.0, end_reason="perforated",
                       perforated=True)
        return [sys.executable, "-c", f"import json; open({str(out / 'summary.json')!r}, 'w').write({json.dumps(summary)!r})"]
    monkeypatch.setattr(runpool, "_command", command)
    monkeypatch.setattr(runpool, "_stored", lambda run, folder: None)
    assert main(["study", "fillet", "--members", "2", "--out", str(tmp_path), "--jobs", "2", "--quiet"]) == 0
    md = (tmp_path / "fillet.md").read_text()
    rows = [line for line in md.splitlines() if line.startswith("| Y90, fillet ")]
    assert len(rows) == 3 and all("| 30.00 +- 0.00 (n 2) | 41.00 +- 12.71 (n 2) |" in line and "perforated 2" in line for line in rows)
    assert "Every case ran as 2 members" in md
    assert len(json.loads((tmp_path / "fillet.json").read_text())["runs"]) == 6
    assert main(["study", "fillet", "--members", "0", "--out", str(tmp_path / "x")]) == 2


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


def test_the_ballistic_limit_study_estimates_each_scene_from_its_runs(tmp_path, monkeypatch, capsys):
    """``study v50`` with stand-in runs (:func:`tests.tools.limits.stand_in_limits`): each scene's estimate, the
    failure reported and the other scenes done; run again, the stored runs (the failures
    included) are reused and the tables are the same."""
    from fabric_fenicsx.cli import main
    from fabric_fenicsx.studies import runpool

    monkeypatch.setattr(runpool, "_command", stand_in_limits)
    real_stored = runpool._stored
    monkeypatch.setattr(runpool, "_stored", lambda run, folder: None)
    args = ["study", "v50", "--out", str(tmp_path), "--jobs", "2", "--max-runs", "12", "--ci", "1", "--quiet"]
    assert main(args) == 1                  # XY45's runs failed
    limits = json.loads((tmp_path / "v50.json").read_text())["v50"]
    check_stand_in_limits(limits, tmp_path, 12)
    md = (tmp_path / "v50.md").read_text()
    xy45 = [line for line in md.splitlines() if line.startswith("| XY45 |")]
    assert len(xy45) == 1 and "no estimate" in xy45[0] and "stand-in failure" in xy45[0]
    y90 = [line for line in md.splitlines() if line.startswith("| Y90 |")]
    assert len(y90) == 1 and y90[0].startswith(f"| Y90 | {limits['Y90']['probit']['v50']:.2f} [")
    assert "no fit: held below, perforated above" in [line for line in md.splitlines() if line.startswith("| Y0 |")][0]
    assert (tmp_path / "pictures" / "v50-Y90.png").stat().st_size > 10000 and "pictures/v50-Y90.png" in md
    tables = {s: (tmp_path / "v50" / s / "v50.csv").read_text() for s in chapter4.SCENES}
    # the failures are stored with their settings and model version and reported again, not rerun
    failed = tmp_path / "v50" / "XY45" / "run_000" / "failed.json"
    assert json.loads(failed.read_text())["error"] == "exit code 1: stand-in failure"
    def stored(run, folder):       # a stand-in summary carries no settings: it is reused as it is
        path = folder / "summary.json"
        return json.loads(path.read_text()) if path.exists() else real_stored(run, folder)
    monkeypatch.setattr(runpool, "_stored", stored)
    monkeypatch.setattr(runpool, "_command", lambda run, out: pytest.fail(f"{run.key} of {run.scene} ran again"))
    assert main(args) == 1
    assert {s: (tmp_path / "v50" / s / "v50.csv").read_text() for s in chapter4.SCENES} == tables


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
