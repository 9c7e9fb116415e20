"""Studies that share folders and disks: one writer per output folder (``study``, ``ensemble``,
``divergence`` hold their ``--out``'s lock), a study on a disk that fills up (it ends with one
line and exit 1; resumed with room, it reruns every incomplete run and its pictures have every
panel), what counts as a stored run, and records written whole or not at all.

The runs are stand-ins (``runpool._command`` monkeypatched): each writes what a finished impact
run writes that the study reads (summary.json with the run's settings and model version,
history.csv, damage.npz), in that order, so a study of three runs takes seconds.
"""
import errno
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from fabric_fenicsx.cli import main
from fabric_fenicsx.impact.lock import LOCK_NAME, FolderLock
from fabric_fenicsx.provenance import model_version
from fabric_fenicsx.studies import chapter4, runpool
from fabric_fenicsx.studies.runpool import Run, incomplete, run_all

ROOT = Path(__file__).resolve().parents[2]
FILLET = ["Y90-v57.3", "Y90-v57.3-fillet0.8mm", "Y90-v57.3-fillet2mm"]

STAND_IN = r"""
import json, sys
from pathlib import Path
import numpy as np
folder = Path(sys.argv[1])
job = json.loads((folder / "stand-in.json").read_text())
if job.get("fail"):
    print(job["fail"]); sys.exit(1)
(folder / "summary.json").write_text(json.dumps(job["summary"]))
(folder / "history.csv").write_text("time,projectile_velocity\n0,57.3\n1e-4,40.0\n")
n = 4
quads = np.array([[[0, 0], [1, 0], [1, 1], [0, 1]]], float).repeat(n, 0) * 0.01 + np.arange(n)[:, None, None] * 0.01
np.savez(folder / "damage.npz", quads=quads, live=np.ones(n, bool), SDV1=np.ones(n), SDV2=np.linspace(0, 1, n),
         SDV3=np.ones(n), padding=np.random.default_rng(0).random(job.get("padding", 0)))
"""


def stand_ins(monkeypatch, fail=(), padding=0, started=None):
    """Make every run a stand-in: runs named in ``fail`` fail in the model (exit 1); the others
    write a complete run (damage.npz ``padding`` x 8 bytes larger). ``started``: a list the
    started runs' keys are appended to."""
    def command(run, folder):
        settings = runpool._settings(run)
        v = settings["projectile"]["velocity"]
        summary = {"v0": v, "residual_velocity": v / 2, "absorbed_energy": 1.0, "perforated": True,
                   "end_reason": "perforated", "settings": settings, "model_version": model_version()}
        job = {"summary": summary, "padding": padding,
               "fail": f"impact run stopped at step 7: stand-in blow-up of {run.key}" if run.key in fail else ""}
        (folder / "stand-in.json").write_text(json.dumps(job))
        if started is not None:
            started.append(run.key)
        return [sys.executable, "-c", STAND_IN, str(folder)]
    monkeypatch.setattr(runpool, "_command", command)


def _no_traceback(err: str) -> None:
    assert "Traceback" not in err and "Error:" not in err.split(": stopped: ")[0], err


# ----------------------------------------------------------------------------- one writer per folder
def _holder(folder: Path, what: str) -> subprocess.Popen:
    """Another process holding ``folder``'s lock as ``what`` until it is ended."""
    code = ("import sys, time; from fabric_fenicsx.impact.lock import FolderLock; "
            f"FolderLock(sys.argv[1], {what!r}, run_id='first').acquire(); print('held', flush=True); time.sleep(120)")
    proc = subprocess.Popen([sys.executable, "-c", code, str(folder)], cwd=ROOT, stdout=subprocess.PIPE, text=True,
                            env=dict(os.environ, PYTHONPATH=str(ROOT)))
    assert proc.stdout.readline().strip() == "held"
    return proc


@pytest.mark.parametrize("command, what", [
    (["study", "fillet"], "study"),
    (["ensemble", str(chapter4.SCENE_DIR / "y90.toml"), "-n", "2"], "ensemble"),
    (["divergence", str(chapter4.SCENE_DIR / "y90.toml")], "divergence"),
])
def test_a_second_writer_into_the_folder_stops_before_any_work_naming_the_first(command, what, tmp_path, capsys,
                                                                               monkeypatch):
    out = tmp_path / "out"
    started = []
    stand_ins(monkeypatch, started=started)
    first = _holder(out, what)
    try:
        t0 = time.monotonic()
        assert main([*command, "--out", str(out)]) == 2
        took = time.monotonic() - t0
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1, err
        assert f"is in use by {what} first (process {first.pid} on host" in err[0], err
        assert err[0].startswith(f"fabric-fenicsx {command[0]}: output folder ") and "give another --out" in err[0]
        assert started == [] and sorted(p.name for p in out.iterdir()) == [LOCK_NAME] and took < 5.0
    finally:
        first.kill()
        first.wait()
    assert json.loads((out / LOCK_NAME).read_text())["pid"] == first.pid   # the first's lock was left alone


def test_the_study_takes_over_a_dead_holders_lock_and_releases_its_own_also_on_an_error(tmp_path, capsys,
                                                                                       monkeypatch):
    out = tmp_path / "study"
    dead = _holder(out, "study")
    dead.kill()
    dead.wait()
    stand_ins(monkeypatch)
    assert main(["study", "fillet", "--out", str(out), "--jobs", "2"]) == 0
    err = capsys.readouterr().err
    assert "took over the stale lock of study first" in err and not (out / LOCK_NAME).exists()
    # an error inside the study (a bug) still releases the lock
    monkeypatch.setattr("fabric_fenicsx.cli.study._report", lambda *a: 1 / 0)
    with pytest.raises(ZeroDivisionError):
        main(["study", "fillet", "--out", str(out)])
    assert not (out / LOCK_NAME).exists()
    # held by this process's own lock object: the study is refused, the lock is not touched
    mine = FolderLock(out, "study", run_id="mine").acquire()
    try:
        assert main(["study", "fillet", "--out", str(out)]) == 2
        assert f"in use by study mine (process {os.getpid()}" in capsys.readouterr().err
    finally:
        mine.release()


# ----------------------------------------------------------------------------- what counts as stored
def _fillet_runs():
    return chapter4.plan("fillet", ("output.xdmf_interval=0", "output.progress_interval=0"))


def test_only_complete_records_count_as_stored(tmp_path, monkeypatch):
    runs = _fillet_runs()
    stand_ins(monkeypatch, fail={FILLET[2]})
    done = run_all(runs, tmp_path, jobs=2)
    assert "error" in done[FILLET[2]] and json.loads((tmp_path / FILLET[2] / "failed.json").read_text())["cause"] == "model"
    assert all(incomplete(tmp_path / k, done[k]) == [] for k in FILLET[:2])
    started = []
    stand_ins(monkeypatch, fail={FILLET[2]}, started=started)
    run_all(runs, tmp_path, jobs=2)
    assert started == []                          # complete runs and the model's failure are stored
    (tmp_path / FILLET[0] / "damage.npz").unlink()                       # stopped before its pictures
    (tmp_path / FILLET[1] / "summary.json").write_text("")                # an empty record
    failed = tmp_path / FILLET[2] / "failed.json"
    record = json.loads(failed.read_text())
    failed.write_text(json.dumps({k: v for k, v in record.items() if k != "cause"}))   # a record of the old code
    assert incomplete(tmp_path / FILLET[0], done[FILLET[0]]) == ["damage.npz"]
    started.clear()
    stand_ins(monkeypatch, started=started)
    again = run_all(runs, tmp_path, jobs=2)
    assert sorted(started) == sorted(FILLET) and not any("error" in s for s in again.values())
    data = (tmp_path / FILLET[0] / "damage.npz").read_bytes()
    (tmp_path / FILLET[0] / "damage.npz").write_bytes(data[: len(data) // 2])         # cut short
    (tmp_path / FILLET[1] / "history.csv").write_text("")
    started.clear()
    run_all(runs, tmp_path, jobs=2)
    assert sorted(started) == FILLET[:2]


def test_a_failure_of_the_surroundings_is_not_stored(tmp_path, monkeypatch):
    scene = str(chapter4.SCENE_DIR / "y90.toml")
    lines = {"locked": "fabric-fenicsx impact: output folder 'x' is in use by impact run (process 1 on host h)",
             "memory": "MemoryError", "model": "impact run stopped at step 9: non-finite membrane force"}
    monkeypatch.setattr(runpool, "_command", lambda run, out: [
        sys.executable, "-c", f"import sys; print({lines[run.key]!r}); sys.exit(1)"])
    run_all([Run(k, scene) for k in lines], tmp_path, jobs=3)
    assert [k for k in lines if (tmp_path / k / "failed.json").exists()] == ["model"]


def test_a_record_is_written_whole_or_not_at_all(tmp_path, monkeypatch):
    path = tmp_path / "failed.json"
    runpool.write_atomic(path, "old")

    def full(*args):
        raise OSError(errno.ENOSPC, "No space left on device")
    monkeypatch.setattr(runpool.os, "fsync", full)
    with pytest.raises(OSError):
        runpool.write_atomic(path, "new")
    assert path.read_text() == "old" and sorted(p.name for p in tmp_path.iterdir()) == ["failed.json"]


# ----------------------------------------------------------------------------- a full disk
def test_a_failure_that_cannot_be_recorded_stops_the_study_in_one_line_and_resuming_reruns_it(
        tmp_path, capsys, monkeypatch):
    """A simulated full disk: the failed run's record cannot be written (ENOSPC at os.replace)."""
    out = tmp_path / "study"
    stand_ins(monkeypatch, fail={FILLET[1]})
    real_replace = os.replace

    def replace(src, dst):
        if str(dst).endswith("failed.json"):
            raise OSError(errno.ENOSPC, "No space left on device")
        return real_replace(src, dst)
    monkeypatch.setattr(runpool.os, "replace", replace)
    assert main(["study", "fillet", "--out", str(out), "--jobs", "1"]) == 1
    err = capsys.readouterr().err
    _no_traceback(err)
    lines = err.strip().splitlines()
    assert len(lines) == 1, lines
    assert lines[0].startswith(f"fabric-fenicsx study: stopped: the failure of run {FILLET[1]} cannot be recorded in ")
    assert "No space left on device" in lines[0] and "run it again" in lines[0]
    folder = out / "runs" / FILLET[1]
    assert sorted(p.name for p in folder.iterdir()) == ["run.log", "stand-in.json"]   # no record, not even an empty one
    assert not (out / LOCK_NAME).exists() and not (out / "fillet.md").exists()
    assert not (out / "runs" / FILLET[2]).exists()                 # the study stopped there
    # resumed on a disk with room, the run no longer failing: every incomplete run runs, every panel is drawn
    monkeypatch.undo()
    started, panels = [], []
    stand_ins(monkeypatch, started=started)
    plot = chapter4.plot_damage
    monkeypatch.setattr(chapter4, "plot_damage", lambda cases, path: (panels.append(len(cases)), plot(cases, path)))
    assert main(["study", "fillet", "--out", str(out), "--jobs", "2"]) == 0
    assert sorted(started) == FILLET[1:] and panels == [3]
    assert "![damage, fillet](pictures/damage_fillet.png)" in (out / "fillet.md").read_text()


def test_pictures_refuse_incomplete_runs_and_say_which(tmp_path, capsys, monkeypatch):
    from fabric_fenicsx.cli.study import _damage_pictures

    stand_ins(monkeypatch, fail={FILLET[2]})
    results = run_all(_fillet_runs(), tmp_path / "runs", jobs=2)
    (tmp_path / "runs" / FILLET[0] / "damage.npz").unlink()
    cases = [(k, k) for k in FILLET]
    picture = tmp_path / "damage.png"
    picture.write_bytes(b"an older picture")
    lines = _damage_pictures(results, cases, tmp_path, picture, "fillet")
    assert not picture.exists() and len(lines) == 2
    assert lines[0].startswith("The fillet damage picture is not drawn: it would lack ")
    assert f"{FILLET[0]} (incomplete: no damage.npz)" in lines[0]
    assert f"{FILLET[2]} (failed: exit code 1: impact run stopped at step 7" in lines[0]
    assert FILLET[1] not in lines[0] and lines[0] in capsys.readouterr().err


def test_a_study_on_a_disk_that_fills_up(tmp_path, capsys, monkeypatch):
    """A real full disk where this process may mount a tmpfs (root), else skipped (the test
    above simulates it): three runs of about 100 kB each on a 256 kB disk; the study ends with
    one line and exit 1; on the same disk made larger it reruns every incomplete run."""
    from tests.tools.fault_harness import small_disk

    disk = tmp_path / "disk"
    with small_disk(disk, "256k") as mounted:
        if not mounted:
            pytest.skip("cannot mount a tmpfs here (not root, or mount refused)")
        out = disk / "study"
        stand_ins(monkeypatch, padding=12_000)
        code = main(["study", "fillet", "--out", str(out), "--jobs", "1"])
        err = capsys.readouterr().err
        _no_traceback(err)
        lines = err.strip().splitlines()
        assert code == 1 and len(lines) == 1 and lines[0].startswith("fabric-fenicsx study: stopped: "), lines
        assert "No space left on device" in lines[0] or "full disk" in lines[0], lines
        assert not any(p.stat().st_size == 0 for p in out.rglob("*.json")), list(out.rglob("*.json"))
        assert not (out / LOCK_NAME).exists()
        done = [k for k in FILLET if (out / "runs" / k / "summary.json").exists()
                and not incomplete(out / "runs" / k, json.loads((out / "runs" / k / "summary.json").read_text()))]
        assert len(done) < 3
        subprocess.run(["mount", "-o", "remount,size=8m", str(disk)], check=True)
        started, panels = [], []
        stand_ins(monkeypatch, padding=12_000, started=started)
        plot = chapter4.plot_damage
        monkeypatch.setattr(chapter4, "plot_damage",
                            lambda cases, path: (panels.append(len(cases)), plot(cases, path)))
        assert main(["study", "fillet", "--out", str(out), "--jobs", "1"]) == 0, capsys.readouterr().err
        assert sorted(started) == sorted(set(FILLET) - set(done)) and panels == [3]
