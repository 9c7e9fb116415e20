"""One writer per output folder (:mod:`fabric_fenicsx.impact.lock`) and work sized before it
starts (:mod:`fabric_fenicsx.impact.sizing`), in the library and through ``fabric-fenicsx impact``."""
import json
import os
import resource
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from fabric_fenicsx.impact.lock import LOCK_NAME, FolderLock, FolderLocked
from fabric_fenicsx.impact.scene import SceneError, load_scene
from fabric_fenicsx.impact.sizing import check_size, estimate

ROOT = Path(__file__).resolve().parents[2]
Y90 = ROOT / "demos" / "scenes" / "y90.toml"

TINY = """
[material]
damage = false
[mesh]
kind = "uniform"
side = 0.08
n = {n}
[projectile]
diameter = 0.02
velocity = 20.0
mass = 0.005
[run]
t_end = {t_end}
release_time = 1.0
[output]
xdmf_interval = 0.0
png = false
progress_interval = 0.0
"""


def cli(*args, **kw):
    return subprocess.Popen([sys.executable, "-m", "fabric_fenicsx.cli", *map(str, args)], cwd=ROOT,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, **kw)


# ------------------------------------------------------------------ the lock
def test_a_lock_is_held_released_and_refused_to_a_second_writer(tmp_path):
    with FolderLock(tmp_path, "study", "run-a") as lock:
        held = json.loads((tmp_path / LOCK_NAME).read_text())
        assert held["pid"] == os.getpid() and held["run_id"] == "run-a"
        with pytest.raises(FolderLocked, match=f"in use by study run-a \\(process {os.getpid()}"):
            FolderLock(tmp_path, "impact run").acquire()
        assert lock.holder() == held
    assert not (tmp_path / LOCK_NAME).exists()


def test_a_stale_lock_of_a_dead_process_is_taken_over_and_a_foreign_host_is_refused(tmp_path):
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True,
                          text=True).stdout.strip()
    (tmp_path / LOCK_NAME).write_text(json.dumps({"what": "impact run", "run_id": "old", "pid": int(dead),
                                                  "host": socket.gethostname(), "ticks": 1}))
    warnings = []
    with FolderLock(tmp_path, "impact run", "new", warn=warnings.append):
        assert json.loads((tmp_path / LOCK_NAME).read_text())["run_id"] == "new"
    assert len(warnings) == 1 and "stale lock of impact run old" in warnings[0]
    # A live process of this host whose id was reused by another program (other start ticks).
    (tmp_path / LOCK_NAME).write_text(json.dumps({"pid": os.getpid(), "host": socket.gethostname(),
                                                  "ticks": -5}))
    with FolderLock(tmp_path, "impact run", warn=warnings.append):
        pass
    assert len(warnings) == 2
    (tmp_path / LOCK_NAME).write_text(json.dumps({"what": "study", "pid": 1, "host": "elsewhere.example"}))
    with pytest.raises(FolderLocked, match=f"delete {tmp_path / LOCK_NAME}"):
        FolderLock(tmp_path, "impact run").acquire()


def test_two_impact_runs_into_one_folder(tmp_path):
    """The second run exits 2 naming the first before any work; the first's files are whole and
    of one run."""
    slow, quick = tmp_path / "slow.toml", tmp_path / "quick.toml"
    slow.write_text(TINY.format(t_end=2e-3, n=30))     # ends at t_end only (release_time): seconds
    quick.write_text(TINY.format(t_end=1e-5, n=12))
    out = tmp_path / "out"
    first = cli("impact", slow, "--out", out)
    t0 = time.monotonic()
    while not (out / LOCK_NAME).exists() or not (out / "run.json").exists():
        assert first.poll() is None, first.communicate()
        assert time.monotonic() - t0 < 120
        time.sleep(0.1)
    second = cli("impact", quick, "--out", out)
    _, err2 = second.communicate(timeout=120)
    assert first.poll() is None, "the first run ended before the second stopped: the test needs a longer one"
    assert second.returncode == 2, err2
    assert "is in use by impact run" in err2 and f"process {first.pid} " in err2
    _, err1 = first.communicate(timeout=600)
    assert first.returncode == 0, err1
    run = json.loads((out / "run.json").read_text())
    summary = json.loads((out / "summary.json").read_text())
    assert summary["run_id"] == run["run_id"] and run["settings"]["run"]["t_end"] == 2e-3
    assert run["end_reason"] == summary["end_reason"] == "time_limit"
    rows = (out / "history.csv").read_text().splitlines()
    assert float(rows[-1].split(",")[0]) > 1e-5          # the slow run's history, not the quick one's
    assert not (out / LOCK_NAME).exists()


# ------------------------------------------------------------------ the size
def test_the_estimate_counts_the_cells_of_the_scenes_meshes():
    """Against the cell counts of meshes built here: 1588, 3254 and 10891 cells of the graded
    Y90 mesh at h_centre = 4, 1.41 and 0.5 mm; 4096 of the aligned 2 mm mesh; n^2."""
    for overrides, cells in ((["mesh.h_centre=0.004"], 1588), ([], 3254), (["mesh.h_centre=0.0005"], 10891),
                             (["mesh.kind=aligned", "mesh.h_centre=0.002"], 4096),
                             (["mesh.kind=uniform", "mesh.n=40"], 1600)):
        e = estimate(load_scene(Y90, overrides))
        assert e.cells == pytest.approx(cells, rel=0.1), overrides
        assert e.steps == pytest.approx(3e-3 / e.dt) and e.wall > 0


def test_a_scene_beyond_the_machine_is_refused_with_the_finest_setting_that_fits():
    scene = load_scene(Y90, ["mesh.h_centre=0.0005"])
    with pytest.raises(SceneError, match="more memory than the 470 MB free") as err:
        check_size(scene, memory=470e6)
    hint = str(err.value).split("--set ")[1]
    assert hint.startswith("mesh.h_centre=")
    fits = load_scene(Y90, [hint])
    assert check_size(fits, memory=470e6).memory <= 470e6
    finer = float(hint.split("=")[1]) * 0.97           # the hint is the finest: 3 % finer does not fit
    with pytest.raises(SceneError):
        check_size(load_scene(Y90, [f"mesh.h_centre={finer}"]), memory=470e6)
    with pytest.raises(SceneError, match="run.max_cells = 2,000"):
        check_size(load_scene(Y90, ["run.max_cells=2000"]), memory=None)
    with pytest.raises(SceneError, match="--set mesh.n="):
        check_size(load_scene(Y90, ["mesh.kind=uniform", "mesh.n=100000"]))


@pytest.mark.skipif(sys.platform != "linux", reason="peak memory from getrusage")
def test_the_command_refuses_a_runaway_mesh_fast_and_small(tmp_path):
    """Exit 2 within 5 s, under 500 MB: the peak memory of the command alone, measured by an
    intermediate process whose only child it is (this test process has had larger children)."""
    probe = tmp_path / "probe.json"
    code = ("import json, resource, subprocess, sys, time; t0 = time.monotonic(); "
            "p = subprocess.run(sys.argv[2:], capture_output=True, text=True); "
            "json.dump(dict(rc=p.returncode, err=p.stderr, took=time.monotonic() - t0, "
            "peak=resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss * 1024), open(sys.argv[1], 'w'))")
    subprocess.run([sys.executable, "-c", code, str(probe), sys.executable, "-m", "fabric_fenicsx.cli",
                    "impact", str(Y90), "--set", "mesh.h_centre=1e-6", "--out", str(tmp_path / "never")],
                   cwd=ROOT, timeout=60, check=True)
    r = json.loads(probe.read_text())
    assert r["rc"] == 2 and "too large to run here" in r["err"] and "--set mesh.h_centre=" in r["err"]
    assert r["took"] < 5.0 and r["peak"] < 500e6, (r["took"], r["peak"])
    assert not (tmp_path / "never").exists()
    check = cli("impact", Y90, "--set", "mesh.h_centre=1e-6", "--check")
    _, err = check.communicate(timeout=60)
    assert check.returncode == 2 and "too large to run here" in err
    ok = cli("impact", Y90, "--check")
    _, err = ok.communicate(timeout=60)
    assert ok.returncode == 0 and "estimate: about 3," in err


def test_a_lock_that_cannot_be_written_leaves_no_file(tmp_path, monkeypatch):
    import errno

    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(json, "dump", full)
    with pytest.raises(OSError, match="No space"):
        FolderLock(tmp_path, "study").acquire()
    assert not (tmp_path / LOCK_NAME).exists()
