"""Reliability of the statistics commands (v50, ladder, study v50 / chapter4 / strip), as
docs/reliability.md states it for ``impact``: bad input stops before any work with one line
(exit 2, no traceback, no folder left); a rung that never perforates is reported, not a crash;
the files of an estimate describe the same runs, also after a stopped rerun. The runs are
stand-ins: a process that writes the summary a rule gives."""
import json
import math
import sys
from pathlib import Path

import pytest

from fabric_fenicsx.studies import runpool

ROOT = Path(__file__).resolve().parents[2]
SCENE = str(ROOT / "demos" / "scenes" / "y90.toml")


def _summary_process(folder: Path, summary: dict) -> list[str]:
    return [sys.executable, "-c", f"open({str(folder / 'summary.json')!r}, 'w').write({json.dumps(summary)!r})"]


def _never_through(run, folder):
    """A scene no run perforates: the V50 runs alternate held and undecided (still moving
    forward at the time limit), the members are held."""
    i = int(folder.name.split("_")[1]) if folder.name.startswith("run_") else 0
    undecided = "stop_when_held" in " ".join(run.overrides) and i % 2 == 1
    summary = {"perforated": False, "end_reason": "time_limit" if undecided else "held",
               "residual_velocity": 2.0 if undecided else -0.5, "absorbed_energy": 1.0, "wall_time_s": 1.0}
    return _summary_process(folder, summary)


def _stored(run, folder):
    path = folder / "summary.json"
    return json.loads(path.read_text()) if path.exists() else None


def _refused(capsys, argv, *needles, folder=None):
    """``argv`` ends with exit 2 and one line on stderr naming ``needles``, before any run and
    without leaving ``folder``."""
    from fabric_fenicsx.cli import main

    assert main(argv) == 2
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and all(n in lines[0] for n in needles), err
    if folder is not None:
        assert not Path(folder).exists(), f"{folder} was left"
    return lines[0]


@pytest.fixture
def no_runs(monkeypatch):
    """A run started by a refused command fails the test."""
    def started(run, folder):
        raise AssertionError(f"run {run.key} started")
    monkeypatch.setattr(runpool, "_command", started)


# ----------------------------------------------------------------------------- ladder
def test_a_ladder_whose_rung_never_perforates_reports_no_limit_in_its_range(tmp_path, monkeypatch, capsys):
    from fabric_fenicsx.cli import main

    monkeypatch.setattr(runpool, "_command", _never_through)
    monkeypatch.setattr(runpool, "_stored", _stored)
    out = tmp_path / "L"
    argv = ["ladder", SCENE, "--sizes", "0.008", "--families", "graded", "--members", "2", "--max-runs", "3",
            "--jobs", "1", "--quiet", "--out", str(out)]
    for _ in range(2):                                   # and again, on its stored runs
        assert main(argv) == 0
        rep = json.loads((out / "ladder.json").read_text())
        row = rep["rows"][0]
        assert row["v50"] is None and row["v50_kind"] == "none in range" and row["v50_hi"] is None
        assert "no limit in its range: every counted run held" in (out / "ladder.md").read_text()
    assert "Traceback" not in capsys.readouterr().err


def test_a_bracket_reached_at_max_runs_is_not_called_sharp():
    from fabric_fenicsx.cli.ladder import _est
    from fabric_fenicsx.studies import ladder

    rows = [{"velocity": v, "outcome": "perforated" if v > 50 else "held", "residual_velocity": 1.0,
             "wall_time_s": 1.0} for v in (20.0, 40.0, 60.0)]
    members = [{"residual_velocity": 1.0, "wall_time_s": 1.0}] * 2
    capped = ladder.measure(ladder.Rung("graded", 0.004), rows, "3 runs (--max-runs) reached", members)
    assert capped["v50_kind"] == "bracket" and "sharp" not in _est(capped, "v50").split(":")[0].replace("not narrowed "
                                                                                                           "to a sharp", "")
    assert _est(capped, "v50").startswith("bracket, not narrowed")
    sharp = ladder.measure(ladder.Rung("graded", 0.004), rows, "a sharp limit: no overlap", members)
    assert _est(sharp, "v50").startswith("sharp: held at 40.00")


ESTIMATE_CASES = [
    (["--bracket", "20,inf"], "--bracket must be LO,HI"),
    (["--bracket", "0.5,10"], "the design never goes below 1 m/s"),
    (["--bracket", "nan,10"], "--bracket must be LO,HI"),
    (["--out", ""], "--out is empty"),
    (["--jobs", "0"], "--jobs must be at least 1"),
    (["--ci", "0"], "--ci must be a width > 0"),
    (["--max-runs", "1"], "--max-runs must be at least 2"),
    (["--scheduler", "nowhere"], "--scheduler must be the address"),
]
"""Bad arguments that ``v50`` and ``ladder`` share."""

LADDER_CASES = [
    (["--velocity", "nan"], "--velocity must be a finite number > 0"),
    (["--velocity", "-3"], "--velocity must be a finite number > 0"),
    (["--velocity", "0"], "--velocity must be a finite number > 0"),
    (["--variant-size", "0"], "--variant-size must be a finite number > 0"),
    (["--families", "graded,graded"], "--families names graded more than once"),
    (["--variant", "run.damping=0.05", "--variant", "run.damping=0.05", "--variant-size", "0.004"],
     "--variant names run.damping=0.05 more than once"),
    (["--sizes", "0.004,0.0040000001"], "rungs would share a folder (graded-4mm)"),
    (["--members", "1"], "--members must be at least 2"),
]

V50_CASES = [(["--resolution", "0"], "--resolution must lie in (0, 1]"), (["--seeds=-1"], "--seeds must be a seed >= 0")]


@pytest.mark.parametrize("command, extra, needle", [("ladder", *c) for c in ESTIMATE_CASES + LADDER_CASES]
                         + [("v50", *c) for c in ESTIMATE_CASES + V50_CASES])
def test_bad_arguments_stop_before_any_run_and_leave_no_folder(tmp_path, capsys, no_runs, command, extra, needle):
    out = tmp_path / "deep" / "L"
    rungs = ["--sizes", "0.004", "--families", "graded"] if command == "ladder" else []
    _refused(capsys, [command, SCENE, *rungs, "--out", str(out), *extra], needle, folder=tmp_path / "deep")


def test_an_empty_scene_name_is_named_as_such(tmp_path, capsys, no_runs):
    _refused(capsys, ["v50", "", "--out", str(tmp_path / "V")], "SCENE is empty", folder=tmp_path / "V")
    _refused(capsys, ["ladder", "", "--out", str(tmp_path / "L")], "SCENE is empty", folder=tmp_path / "L")


@pytest.mark.parametrize("where", ["file", "proc"])
def test_an_unusable_out_is_refused_in_one_line(tmp_path, capsys, no_runs, where):
    target = tmp_path / "a-file" if where == "file" else Path("/proc/x")
    if where == "file":
        target.write_text("not a folder\n")
    for command in ("v50", "ladder"):
        _refused(capsys, [command, SCENE, "--out", str(target)], str(target))


# ----------------------------------------------------------------------------- study
@pytest.mark.parametrize("extra, needle", [
    (["--jobs", "0"], "--jobs must be at least 1"),
    (["--jobs=-1"], "--jobs must be at least 1"),
    (["--scheduler", "local:2"], "--scheduler is not available for strip"),
    (["--sizes", "0.002,0.002"], "strip-aligned-2mm.csv more than once"),
    (["--sizes", "0.002,0.0020000001"], "strip-aligned-2mm.csv more than once"),
    (["--out", ""], "--out is empty"),
])
def test_bad_strip_arguments_stop_before_any_pull_and_leave_no_folder(tmp_path, capsys, extra, needle):
    out = tmp_path / "deep" / "S"
    argv = ["study", "strip", "--families", "aligned", "--sizes", "0.005", "--seeds", "3", "--out", str(out), *extra]
    _refused(capsys, argv, needle, folder=tmp_path / "deep")


@pytest.mark.parametrize("where", ["file", "proc"])
def test_strip_refuses_an_unusable_out_in_one_line(tmp_path, capsys, where):
    target = tmp_path / "a-file" if where == "file" else Path("/proc/x")
    if where == "file":
        target.write_text("not a folder\n")
    _refused(capsys, ["study", "strip", "--seeds", "3", "--out", str(target)], str(target))


def test_a_strip_study_into_a_folder_in_use_stops_at_once(tmp_path, capsys):
    from fabric_fenicsx.impact.lock import FolderLock

    out = tmp_path / "S"
    with FolderLock(out, "study", run_id="strip"):
        _refused(capsys, ["study", "strip", "--families", "aligned", "--sizes", "0.005", "--seeds", "3",
                          "--out", str(out)], "is in use by study strip")
    assert [p.name for p in out.iterdir()] == []          # no table begun


def test_study_names_every_study_and_checks_the_report_file_first(tmp_path, capsys, no_runs):
    assert "strip" in _refused(capsys, ["study", "nosuch", "--out", str(tmp_path / "n")], "unknown study",
                               folder=tmp_path / "n")
    (tmp_path / "docs").mkdir()
    _refused(capsys, ["study", "chapter4", "--doc", str(tmp_path / "docs"), "--out", str(tmp_path / "c")],
             "is a folder", folder=tmp_path / "c")
    _refused(capsys, ["study", "chapter4", "--doc", "/proc/x/validation.md", "--out", str(tmp_path / "c")],
             "--doc's folder", folder=tmp_path / "c")
    _refused(capsys, ["study", "v50", "--out", ""], "--out is empty")


# ----------------------------------------------------------------------------- v50's files
def _probit_runs(run, folder):
    """Runs on the probit curve V50 = 40 m/s, sigma = 3 m/s (a number from the run's index)."""
    v = float(next(o for o in run.overrides if o.startswith("projectile.velocity=")).split("=")[1])
    u = (int(folder.name.split("_")[1]) * 0.6180339887498949) % 1.0
    through = u < 0.5 * (1.0 + math.erf((v - 40.0) / (3.0 * math.sqrt(2.0))))
    return _summary_process(folder, {"perforated": through, "end_reason": "perforated" if through else "held",
                                     "residual_velocity": 5.0 if through else -1.0, "absorbed_energy": 1.0,
                                     "wall_time_s": 1.0})


def test_a_stopped_rerun_leaves_csv_json_and_png_describing_the_same_runs(tmp_path, monkeypatch, capsys):
    from fabric_fenicsx.cli import main
    from fabric_fenicsx.studies import v50

    monkeypatch.setattr(runpool, "_command", _probit_runs)
    monkeypatch.setattr(runpool, "_stored", _stored)
    plotted = []
    real_plot = v50.plot
    monkeypatch.setattr(v50, "plot", lambda rep, rows, *a, **k: (plotted.append(len(rows)), real_plot(rep, rows, *a, **k)))
    out = tmp_path / "V"
    argv = ["v50", SCENE, "--jobs", "2", "--ci", "0.1", "--out", str(out)]
    assert main([*argv, "--max-runs", "6", "--quiet"]) == 0
    assert json.loads((out / "v50.json").read_text())["runs"] == 6 and plotted[-1] == 6

    real_run_all = runpool.run_all

    def stopped(*a, **k):                          # the rerun stops after its first batch (reused runs)
        real_run_all(*a, **k)
        raise KeyboardInterrupt
    monkeypatch.setattr(runpool, "run_all", stopped)
    assert main([*argv, "--max-runs", "16"]) == 130
    captured = capsys.readouterr()
    csv_rows = len((out / "v50.csv").read_text().splitlines()) - 1
    rep = json.loads((out / "v50.json").read_text())
    assert csv_rows == rep["runs"] == plotted[-1] == 2 and rep["stop"].startswith("interrupted after 2 runs")
    assert "(held, stored, reused)" in captured.out or "(perforated, stored, reused)" in captured.out


def test_the_v50_picture_counts_the_runs_and_its_legends_hide_none():
    import matplotlib.pyplot as plt

    from fabric_fenicsx.studies import v50

    rows = [{"run": i, "velocity": v, "outcome": o, "residual_velocity": 5.0 if o == "perforated" else -1.0,
             "wall_time_s": 1.0} for i, (v, o) in enumerate([(30, "held"), (35, "held"), (38, "perforated"),
                                                              (36, "perforated"), (34, "held"), (45, "perforated")])]
    rep = v50.report(rows, "test")
    fig = v50.figure(rep, rows, "t")
    try:
        fig.canvas.draw()
        renderer = fig.canvas.get_renderer()
        for ax in fig.axes:
            legend = ax.get_legend()
            assert not legend.get_window_extent(renderer).overlaps(ax.get_window_extent(renderer))
        labels = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
        assert "runs: 3 perforated (at 1), 3 held (at 0)" in labels
    finally:
        plt.close(fig)
    assert "process start-up not counted" in v50.format_report(rep)


# ----------------------------------------------------------------------------- study v50 interrupted
DRIVER = """
import os, sys
sys.path.insert(0, @ROOT@)
from fabric_fenicsx.studies import runpool
from tests.tools.limits import stand_in_limits

def command(run, folder):
    if os.environ.get("SLOW_V50") and "run.stop_when_held=true" in run.overrides:
        pid = str(folder / "pid")
        return [sys.executable, "-c", f"import os, time; open({pid!r}, 'w').write(str(os.getpid())); time.sleep(300)"]
    return stand_in_limits(run, folder)

if __name__ == "__main__":          # not in the processes of a local dask cluster
    runpool._command = command
    runpool._stored = lambda run, folder: None
    from fabric_fenicsx.cli import main
    code = main(sys.argv[1:])
    import threading
    print("threads left:", [t.name for t in threading.enumerate() if t is not threading.main_thread()],
          file=sys.stderr)
    sys.exit(code)
"""


def _driven(tmp_path, argv, slow: bool, **popen):
    """The command line ``argv`` in a process whose runs are stand-ins (:data:`DRIVER`); with
    ``slow`` its V50 runs sleep until they are ended."""
    import os
    import subprocess

    driver = tmp_path / "driver.py"
    driver.write_text(DRIVER.replace("@ROOT@", repr(str(ROOT))))
    env = {k: v for k, v in os.environ.items() if k != "SLOW_V50"}
    if slow:
        env["SLOW_V50"] = "1"
    return subprocess.Popen([sys.executable, str(driver), *argv], env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, **popen)


def _study_v50(tmp_path, out, slow: bool):
    return _driven(tmp_path, ["study", "v50", "--out", str(out), "--jobs", "2", "--max-runs", "6", "--ci", "1",
                              "--quiet"], slow)


def _wait_for_runs(out: Path, proc, limit: float = 120.0) -> list[int]:
    """The process ids of the sleeping V50 runs under ``out``, once one has started."""
    import time

    deadline = time.monotonic() + limit
    while not list(out.glob("**/run_*/pid")) and time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.2)
    time.sleep(0.5)
    return [int(p.read_text()) for p in out.glob("**/run_*/pid") if p.read_text()]


def _alive(pid: int) -> bool:
    import os

    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"


@pytest.mark.parametrize("sig", ["SIGINT", "SIGTERM"])
def test_an_interrupted_study_v50_ends_its_runs_and_releases_its_lock(tmp_path, sig):
    import signal

    from fabric_fenicsx.impact.lock import LOCK_NAME

    out = tmp_path / "study"
    proc = _study_v50(tmp_path, out, slow=True)
    try:
        assert _wait_for_runs(out, proc), "the V50 phase was not reached"
        proc.send_signal(getattr(signal, sig))
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == {"SIGINT": 130, "SIGTERM": 143}[sig], err
    assert "Traceback" not in err and "threads left: []" in err, err
    pids = [int(p.read_text()) for p in out.glob("v50/*/run_*/pid") if p.read_text()]
    assert not [pid for pid in pids if _alive(pid)], "impact runs left running"
    assert not list(out.rglob(LOCK_NAME))
    for scene in ("Y90", "XY0", "XY45", "Y0"):       # each scene's three files: the runs that ended
        rep = json.loads((out / "v50" / scene / "v50.json").read_text())
        csv_rows = len((out / "v50" / scene / "v50.csv").read_text().splitlines()) - 1
        assert rep["runs"] == len(rep["rows"]) == csv_rows and rep["stop"].startswith(("interrupted", "stopped"))
    rerun = _study_v50(tmp_path, out, slow=False)
    rerun.communicate(timeout=300)
    straight = _study_v50(tmp_path, tmp_path / "straight", slow=False)
    straight.communicate(timeout=300)
    assert rerun.returncode == straight.returncode == 1             # XY45's stand-in runs fail
    for scene in ("Y90", "XY0", "XY45", "Y0"):
        assert (out / "v50" / scene / "v50.csv").read_text() == \
            (tmp_path / "straight" / "v50" / scene / "v50.csv").read_text()


# ----------------------------------------------------------------------------- memory, folders, locks
def test_runs_at_a_time_are_capped_by_the_free_memory(tmp_path, monkeypatch, capsys):
    from fabric_fenicsx.cli import main
    from fabric_fenicsx.impact import sizing

    monkeypatch.setattr(runpool, "_command", _probit_runs)
    monkeypatch.setattr(runpool, "_stored", _stored)
    monkeypatch.setattr(sizing, "free_memory", lambda: 1.2e9)      # room for two runs of ~0.45 GB
    started = []
    real_start = runpool._start
    monkeypatch.setattr(runpool, "_start", lambda run, *a: (started.append(run.key), real_start(run, *a))[1])
    assert main(["v50", SCENE, "--jobs", "6", "--max-runs", "6", "--ci", "0.1", "--out", str(tmp_path / "V")]) == 0
    out = capsys.readouterr().out
    assert "2 runs at a time instead of 6: each needs about" in out and "MB are free" in out
    assert "2 runs at a time, until" in out and len(started) == 6


def test_a_file_where_a_run_folder_goes_is_named_not_a_full_disk(tmp_path, monkeypatch, capsys):
    from fabric_fenicsx.cli import main

    monkeypatch.setattr(runpool, "_command", _probit_runs)
    out = tmp_path / "V"
    out.mkdir()
    (out / "run_000").write_text("in the way\n")
    assert main(["v50", SCENE, "--jobs", "1", "--max-runs", "4", "--quiet", "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert "run_000 is a file, where the run's folder goes; move it away" in err and "free space" not in err


def test_an_empty_lock_says_how_to_clear_it(tmp_path, capsys, no_runs):
    from fabric_fenicsx.impact.lock import LOCK_NAME

    out = tmp_path / "V"
    out.mkdir()
    (out / LOCK_NAME).write_text("")
    line = _refused(capsys, ["v50", SCENE, "--out", str(out)], "empty or unreadable lock")
    assert f"delete {out / LOCK_NAME}" in line and "wait until it ends" not in line


def test_an_unreachable_scheduler_leaves_no_folder(tmp_path, capsys, no_runs):
    pytest.importorskip("distributed")
    out = tmp_path / "deep" / "V"
    from fabric_fenicsx.cli import main

    assert main(["v50", SCENE, "--scheduler", "tcp://127.0.0.1:9", "--out", str(out)]) == 2
    assert "Traceback" not in capsys.readouterr().err
    assert not (tmp_path / "deep").exists()


# ----------------------------------------------------------------------------- Ctrl-C, then SIGTERM
SLOW_CLEAN_UP = """
import sys, time, types
sys.path.insert(0, @ROOT@)
from fabric_fenicsx import cli
from fabric_fenicsx.impact.lock import FolderLock

def add_arguments(parser):
    parser.add_argument("out")

def run(args):
    lock = FolderLock(args.out, "impact run").acquire()
    try:
        open(args.out + "/ready", "w").close()
        time.sleep(60)
    finally:
        time.sleep(1.0)                 # closing the output files
        lock.release()

module = types.ModuleType("slow_clean_up")
module.add_arguments, module.run = add_arguments, run
sys.modules["slow_clean_up"] = module
cli.SUBCOMMANDS["slow"] = ("slow_clean_up", "a run whose clean-up takes a second")
sys.exit(cli.main(["slow", sys.argv[1]]))
"""


def test_a_sigterm_during_the_clean_up_of_a_ctrl_c_does_not_leave_the_lock(tmp_path):
    """A run of a v50 given Ctrl-C (with its process group) and then SIGTERM by its pool, while
    it cleans up: its lock is still released."""
    import signal
    import subprocess
    import time

    from fabric_fenicsx.impact.lock import LOCK_NAME

    driver = tmp_path / "slow.py"
    driver.write_text(SLOW_CLEAN_UP.replace("@ROOT@", repr(str(ROOT))))
    out = tmp_path / "run"
    proc = subprocess.Popen([sys.executable, str(driver), str(out)], stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 60
        while not (out / "ready").exists() and time.monotonic() < deadline:
            time.sleep(0.05)
        proc.send_signal(signal.SIGINT)
        time.sleep(0.3)
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130 and "Traceback" not in err, err
    assert not (out / LOCK_NAME).exists()


def test_ctrl_c_of_a_v50_on_a_local_cluster_ends_at_once_in_one_line(tmp_path):
    """Ctrl-C (SIGINT to the whole process group) of ``v50 --scheduler local:2``: the cluster's
    workers do not get it, the v50 ends their runs and closes the cluster."""
    pytest.importorskip("distributed")
    import os
    import signal
    import time

    from fabric_fenicsx.impact.lock import LOCK_NAME

    out = tmp_path / "V"
    proc = _driven(tmp_path, ["v50", SCENE, "--scheduler", "local:2", "--max-runs", "4", "--out", str(out)], True,
                   start_new_session=True)
    try:
        assert _wait_for_runs(out, proc, 180), "no run started"
        t0 = time.monotonic()
        os.killpg(proc.pid, signal.SIGINT)
        _, err = proc.communicate(timeout=60)
        seconds = time.monotonic() - t0
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    lines = [ln for ln in err.splitlines() if not ln.startswith("threads left")]
    assert proc.returncode == 130 and lines == ["interrupted: output written so far is kept"], err
    assert seconds < 10, seconds
    pids = [int(p.read_text()) for p in out.glob("run_*/pid") if p.read_text()]
    assert pids and not [pid for pid in pids if _alive(pid)] and not list(out.rglob(LOCK_NAME))
