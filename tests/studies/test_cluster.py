"""Studies whose runs go to a dask.distributed cluster (``--scheduler``,
:mod:`fabric_fenicsx.studies.executor`): a two-run study on local processes and on a local
cluster gives the same table to the last bit; a study's runs on the cluster reuse what is stored;
a worker that cannot see the output folder is refused in one line, naming it; without dask,
``--scheduler`` says what to install; and the progress line of a study.

The tests that start a cluster skip where distributed is not installed (the Makefile installs
the ``cluster`` extra, so CI runs them).
"""
import csv
import json
import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

from fabric_fenicsx.cli import main
from fabric_fenicsx.provenance import model_version
from fabric_fenicsx.studies import chapter4, executor, runpool
from fabric_fenicsx.studies.runpool import Progress, duration

INSTALL_LINE = "--scheduler needs dask.distributed, which is not installed: pip install 'fabric_fenicsx[cluster]'"
RUNNING_HOW = {"scene", "wall_time_s", "build_time_s", "time_per_step_s", "time_total_s", "model_version", "run_id"}
"""Summary keys that say how, where and with which file name a run ran, not what it computed."""

STAND_IN = r"""
import json, os, sys
from pathlib import Path
folder = Path(sys.argv[1])
summary = json.loads((folder / "stand-in.json").read_text())
summary["pid"], summary["parent"] = os.getpid(), os.getppid()
(folder / "summary.json").write_text(json.dumps(summary))
(folder / "history.csv").write_text("time,projectile_velocity\n0,57.3\n")
"""


def stand_ins(monkeypatch, started=None):
    """Every run a stand-in that writes a complete run of the study (no pictures: the study runs
    with ``--set output.png=false``) with the settings and model version of the run."""
    def command(run, folder):
        settings = runpool._settings(run)
        v = settings["projectile"]["velocity"]
        summary = {"v0": v, "residual_velocity": v / 2, "absorbed_energy": 1.0, "perforated": True,
                   "end_reason": "perforated", "settings": settings, "model_version": model_version()}
        (folder / "stand-in.json").write_text(json.dumps(summary))
        if started is not None:
            started.append(run.key)
        return [sys.executable, "-c", STAND_IN, str(folder)]
    monkeypatch.setattr(runpool, "_command", command)


def _one_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, lines
    return lines[0]


# ----------------------------------------------------------------------------- the progress line
def test_the_progress_line_counts_the_runs_and_estimates_the_time_left():
    now = [100.0]
    lines = []
    p = Progress("study", "runs", say=lines.append, clock=lambda: now[0])
    p.expect(8)
    assert p.finished({"residual_velocity": 1.0}, reused=True) == \
        "study: 1/8 runs done (1 reused), 0 s elapsed, time left not known yet"
    now[0] = 190.0
    p.finished({"residual_velocity": 1.0}, reused=False)
    now[0] = 230.0
    assert p.finished({"error": "exit code 1: x"}, reused=False) == \
        "study: 3/8 runs done (1 reused, 1 failed), 2 min 10 s elapsed, about 5 min 25 s left"   # 130 s / 2 runs x 5
    p.expect(1)                                  # the ballistic limit plans more runs as it goes
    for _ in range(6):
        p.finished({}, reused=False)
    assert lines[-1] == "study: 9/9 runs done (1 reused, 1 failed), 2 min 10 s elapsed" and len(lines) == 9
    assert [duration(s) for s in (0.4, 59.6, 61, 3725)] == ["0 s", "1 min 0 s", "1 min 1 s", "1 h 02 min"]


def test_the_study_prints_a_progress_line_per_run_unless_quiet(tmp_path, capsys, monkeypatch):
    stand_ins(monkeypatch)
    out = tmp_path / "study"
    assert main(["study", "fillet", "--out", str(out), "--jobs", "2", "--set", "output.png=false"]) == 0
    lines = [line for line in capsys.readouterr().out.splitlines() if line.startswith("study: ")]
    assert [line.split(" runs done")[0] for line in lines] == ["study: 1/3", "study: 2/3", "study: 3/3"], lines
    pattern = r"study: [123]/3 runs done, \d+ s elapsed(, about \d+ s left)?"
    assert all(re.fullmatch(pattern, line) for line in lines), lines
    assert "left" in lines[0] and "left" not in lines[-1]
    assert main(["study", "fillet", "--out", str(out), "--set", "output.png=false"]) == 0     # every run stored
    lines = [line for line in capsys.readouterr().out.splitlines() if line.startswith("study: ")]
    assert len(lines) == 3 and lines[-1].startswith("study: 3/3 runs done (3 reused), "), lines
    assert main(["study", "fillet", "--out", str(out), "--quiet", "--set", "output.png=false"]) == 0
    assert not [line for line in capsys.readouterr().out.splitlines() if line.startswith(("study: ", "  Y90"))]


# ----------------------------------------------------------------------------- without dask, bad addresses
@pytest.mark.parametrize("command", [["study", "fillet"],
                                     ["ensemble", str(chapter4.SCENE_DIR / "y90.toml"), "-n", "2"]])
def test_without_dask_the_scheduler_option_says_what_to_install(command, tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)        # import distributed fails
    started = []
    stand_ins(monkeypatch, started)
    out = tmp_path / "out"
    assert main([*command, "--out", str(out), "--scheduler", "local:2"]) == 2
    assert _one_line(capsys.readouterr().err) == f"fabric-fenicsx {command[0]}: {INSTALL_LINE}"
    assert started == [] and not out.exists()


def test_without_dask_a_study_runs_on_local_processes(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)
    started = []
    stand_ins(monkeypatch, started)
    assert main(["study", "fillet", "--out", str(tmp_path / "s"), "--jobs", "2", "--set", "output.png=false"]) == 0
    assert len(started) == 3 and "on the dask cluster" not in capsys.readouterr().out


@pytest.mark.parametrize("address, message", [
    ("local:0", "--scheduler local:N needs a number of workers N of at least 1, got 'local:0'"),
    ("somehost:8786", "--scheduler must be the address of a dask scheduler (tcp://HOST:8786) or local:N, "
                      "got 'somehost:8786'"),
])
def test_a_scheduler_address_of_the_wrong_form_is_refused_before_any_work(address, message, tmp_path, capsys):
    assert main(["study", "fillet", "--out", str(tmp_path / "s"), "--scheduler", address]) == 2
    assert _one_line(capsys.readouterr().err) == f"fabric-fenicsx study: {message}"


# ----------------------------------------------------------------------------- what workers must see
class _Client:
    """A stand-in dask client of two workers: tcp://seeing runs the check here, tcp://blind
    answers as a worker on another machine that sees no such folder."""

    class scheduler:
        address = "tcp://stand-in:8786"

    def nthreads(self):
        return {"tcp://seeing:1": 1, "tcp://blind:2": 1}

    def run(self, fn, *args):
        assert fn is executor.worker_view
        marker, files = args
        return {"tcp://seeing:1": fn(*args),
                "tcp://blind:2": {"marker": None, "files": {f: None for f in files}, "model_version": model_version()}}


def test_workers_that_cannot_see_the_output_folder_are_named_in_one_line(tmp_path):
    cluster = executor.DaskCluster("tcp://stand-in:8786", client=_Client())
    assert cluster.slots == 2 and cluster.remote
    with pytest.raises(executor.ClusterError) as err:
        cluster.check_shared(tmp_path, [])
    assert str(err.value) == (f"the dask workers tcp://blind:2 cannot see the output folder {tmp_path}; put it on "
                              "a file system every worker shares, at the same path, and give that path as --out")
    assert list(tmp_path.iterdir()) == []                       # the marker is removed


def test_what_else_the_workers_must_share():
    seeing = {"marker": "t", "files": {"/s.toml": "abc"}, "model_version": "v1"}
    assert executor.shared_problem({"tcp://a:1": seeing}, "t", "/out", {"/s.toml": "abc"}, "v1") is None
    other_scene = {**seeing, "files": {"/s.toml": "abd"}}
    problem = executor.shared_problem({"tcp://a:1": seeing, "tcp://b:1": other_scene}, "t", "/out",
                                      {"/s.toml": "abc"}, "v1")
    assert problem.startswith("the dask workers tcp://b:1 cannot read the runs' input file /s.toml as it is here")
    other_code = {**seeing, "model_version": "v0"}
    problem = executor.shared_problem({"tcp://a:1": other_code}, "t", "/out", {"/s.toml": "abc"}, "v1")
    assert problem == ("the dask workers tcp://a:1 would run model version v0, not this one's v1; install the same "
                       "fabric_fenicsx on every worker")


# ----------------------------------------------------------------------------- on a cluster
def _table(out: Path) -> list[dict]:
    """The ensemble's table (a row as each member ended) in the members' order, without run times."""
    with open(out / "ensemble.csv") as f:
        rows = [{k: v for k, v in row.items() if k != "wall_time_s"} for row in csv.DictReader(f)]
    return sorted(rows, key=lambda row: int(row["k"]))


def _computed(summary_path: Path) -> dict:
    """A run's summary without what says how it ran (times, ids, the scene file's name, whether the
    surrogate's tiles were solved in this run or read from the cache)."""
    summary = {k: v for k, v in json.loads(summary_path.read_text()).items() if k not in RUNNING_HOW}
    summary["surrogate"].pop("solves_this_run")
    return summary


def test_a_two_run_study_gives_the_same_table_on_local_processes_and_on_a_local_cluster(tmp_path, capsys):
    """The tiny scene's two-member ensemble (a 16 x 16 mesh, 0.3 ms): once as processes of this
    machine, once on a LocalCluster of two workers; every member's summary and history are the
    same to the last bit (each run is one deterministic serial process). Run again on the
    cluster into the first folder, every member is reused."""
    pytest.importorskip("distributed")
    from tests.tools.faults import TINY_SCENE

    scene = tmp_path / "tiny.toml"
    scene.write_text(TINY_SCENE)
    pool, cluster = tmp_path / "pool", tmp_path / "cluster"
    assert main(["ensemble", str(scene), "-n", "2", "--jobs", "2", "--out", str(pool), "--quiet"]) == 0
    assert main(["ensemble", str(scene), "-n", "2", "--out", str(cluster), "--scheduler", "local:2"]) == 0
    out = capsys.readouterr().out
    assert "on the dask cluster at tcp://127.0.0.1:" in out and "(2 workers, 2 threads)" in out
    assert re.search(r"^ensemble: 2/2 members done, \d+ (min \d+ )?s elapsed$", out, re.MULTILINE), out
    table = _table(pool)
    assert len(table) == 2 and table == _table(cluster)
    for k in (0, 1):
        first, second = pool / f"member_{k}", cluster / f"member_{k}"
        assert _computed(first / "summary.json") == _computed(second / "summary.json")
        assert (first / "history.csv").read_bytes() == (second / "history.csv").read_bytes()
    assert json.loads((pool / "member_0" / "summary.json").read_text())["residual_velocity"] > 0
    assert not [p for p in cluster.iterdir() if p.name.startswith(executor.MARKER)]
    before = {k: (pool / f"member_{k}" / "summary.json").stat().st_mtime_ns for k in (0, 1)}
    assert main(["ensemble", str(scene), "-n", "2", "--out", str(pool), "--scheduler", "local:1"]) == 0
    assert "ensemble: 2/2 members done (2 reused)" in capsys.readouterr().out
    assert before == {k: (pool / f"member_{k}" / "summary.json").stat().st_mtime_ns for k in (0, 1)}


def test_a_study_on_a_local_cluster_runs_each_run_in_a_process_of_a_worker(tmp_path, capsys, monkeypatch):
    """``study fillet`` with stand-in runs on a LocalCluster of two workers: each run is a
    process of its own, started by a worker process (not by this one), and the report is written."""
    pytest.importorskip("distributed")
    started = []
    stand_ins(monkeypatch, started)
    out = tmp_path / "study"
    assert main(["study", "fillet", "--out", str(out), "--scheduler", "local:2", "--set", "output.png=false"]) == 0
    assert "fabric-fenicsx study fillet: 3 runs, 2 at a time, into " in capsys.readouterr().out
    report = json.loads((out / "fillet.json").read_text())
    assert len(started) == 3 and len({s["pid"] for s in report["runs"].values()}) == 3
    assert os.getpid() not in {s["parent"] for s in report["runs"].values()}
    assert all((out / "runs" / k / "run.log").exists() for k in report["runs"])


def test_the_ballistic_limits_share_one_cluster_between_their_threads(tmp_path, monkeypatch):
    """``study v50`` on a LocalCluster with the stand-in runs of the process-pool test
    (:func:`tests.tools.limits.stand_in_limits`): the four scenes' estimates submit from four threads to one
    client; each scene's estimate is what it is on local processes and XY45's failure is
    reported (exit 1)."""
    pytest.importorskip("distributed")
    from tests.tools.limits import check_stand_in_limits, stand_in_limits

    monkeypatch.setattr(runpool, "_command", stand_in_limits)
    monkeypatch.setattr(runpool, "_stored", lambda run, folder: None)
    assert main(["study", "v50", "--out", str(tmp_path), "--max-runs", "8", "--quiet", "--scheduler", "local:2"]) == 1
    check_stand_in_limits(json.loads((tmp_path / "v50.json").read_text())["v50"], tmp_path, 8)


def test_a_worker_that_cannot_see_the_output_folder_is_refused(tmp_path, capsys):
    """A cluster of two workers, one of them started in a mount namespace of its own where the
    folder of --out is an empty tmpfs (as a worker on a machine without the shared disk): the
    study stops before its first run (exit 2) with one line naming that worker and the folder."""
    distributed = pytest.importorskip("distributed")
    if os.geteuid() != 0 or shutil.which("unshare") is None:
        pytest.skip("needs root and unshare to give a worker its own view of the folders")
    from tests.tools.faults import TINY_SCENE

    scene = tmp_path / "tiny.toml"
    scene.write_text(TINY_SCENE)
    shared = tmp_path / "shared"
    shared.mkdir()
    cluster = distributed.LocalCluster(n_workers=1, threads_per_worker=1, dashboard_address=None)
    client = distributed.Client(cluster, set_as_default=False)
    seeing = set(client.nthreads())
    worker = [sys.executable, "-m", "distributed.cli.dask_worker", cluster.scheduler_address, "--nthreads", "1",
              "--no-dashboard"]
    log = open(tmp_path / "worker.log", "wb")
    blind = subprocess.Popen(["unshare", "-m", "sh", "-c", 'mount -t tmpfs none "$0" && exec "$@"', str(shared),
                              *worker], stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
    try:
        t0 = time.monotonic()
        while len(client.nthreads()) < 2 and blind.poll() is None and time.monotonic() - t0 < 30:
            time.sleep(0.2)
        if len(client.nthreads()) < 2:
            pytest.skip("the worker in its own mount namespace did not start: "
                        + (tmp_path / "worker.log").read_text(errors="replace")[-300:])
        (other,) = set(client.nthreads()) - seeing
        out = shared / "ensemble"
        code = main(["ensemble", str(scene), "-n", "2", "--out", str(out), "--scheduler", cluster.scheduler_address])
        line = _one_line(capsys.readouterr().err)
        assert code == 2
        assert line == (f"fabric-fenicsx ensemble: the dask workers {other} cannot see the output folder {out}; put it "
                        "on a file system every worker shares, at the same path, and give that path as --out")
        assert not list(out.glob("member_*")) and not list(out.glob(executor.MARKER + "*"))
    finally:
        if blind.poll() is None:
            os.killpg(blind.pid, 15)
        blind.wait(timeout=30)
        log.close()
        client.close()
        cluster.close()
