"""Bad input and faults, each run through the command line in a fresh process: the two tables
of the reliability study's report (docs/reliability.md, written by :mod:`tests.tools.reliability`).

* :func:`bad_input_rows`: every bad input the study covers (a bad scene key or value, bad fabric
  files, a missing ``fabric.file``, an unusable ``--out``, a scene path that is a folder or not
  UTF-8, an unwritable surrogate cache, ``static --step 1e-9``, a corrupted or a swapped table
  tile), one row each: the input, the exit code, the first line of the message, the seconds until
  the process stopped, and whether mesh or surrogate work had started.
* :func:`fault_rows`: faults while a run goes (SIGINT, SIGKILL, a read-only or full surrogate
  cache, a full output disk, one failing MPI rank), one row each: what happened and what of the
  output is kept.
* :func:`sharing_rows`: runs that share folders, machines and disks: a second impact run into
  a running run's ``--out``, an ensemble into a folder a study holds, a runaway mesh
  (``--set mesh.h_centre=1e-6``, refused within 5 s), and a study on a disk that fills up and
  its resumption on the same disk made larger; one row each: exit code, seconds, the message
  and what is left.

Each row's keys are its table's columns. Every case runs the tiny scene :data:`TINY_SCENE` (a
16 x 16 uniform mesh, 0.3 ms of simulated time, about a second of solving), in its own
temporary folder with its own surrogate cache, so the study neither reads nor changes the
user's cache. The harness (running the command line under a probe, read-only folders, full
disks, the workspace) is :mod:`tests.tools.fault_harness`; its names are importable from here
too. Messages are recorded with ``$TMP`` for the case's temporary folder and ``$REPO`` for the
checkout (:func:`~tests.tools.fault_harness.scrub`). ``python -m tests.tools.faults`` (from the
checkout's root) prints the tables as JSON lines, ``--markdown`` as markdown tables.
"""

from __future__ import annotations

import contextlib
import csv
import dataclasses
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from tests.tools.fault_harness import (  # noqa: F401 - re-exported for the tests
    BAD_FABRICS, GOOD_FABRIC, INJECT_RANK1, MPI_ENV, PROBE, PROBE_TAG, ROOT, TINY_SCENE, Run,
    Workspace, _end_group, _mount, _probe, cli_command, cli_env, is_root, read_only_dir, run_cli,
    scrub, small_disk)


@dataclasses.dataclass
class Case:
    """One bad input ready to run: arguments, environment, MPI ranks, and a note on how the
    input was made; ``args`` None when it could not be made (the note says why)."""

    args: list | None
    env: dict | None = None
    ranks: int = 1
    note: str = ""
    out: Path | None = None


def _row(what: str, case: Case, run: Run | None) -> dict:
    """One table row of a bad input."""
    if run is None:
        return {"input": what, "exit code": "-", "message (first line)": "not available: " + case.note,
                "seconds": "-", "work started": "-", "outcome": "-"}
    code = "timed out" if run.returncode is None else run.returncode
    how = f" ({case.note})" if case.note else ""
    return {"input": what + how, "exit code": code, "message (first line)": run.first_line,
            "seconds": round(run.seconds, 2), "work started": run.work_started,
            "outcome": _outcome(run, case.out)}


def _outcome(run: Run, out: Path | None) -> str:
    """How the run ended, in words; for a finished impact, the unit-cell solves it made."""
    if run.returncode is None:
        return f"still going after {run.seconds:.0f} s: ended by the harness"
    if run.returncode == 0:
        summary = out / "summary.json" if out is not None else None
        if summary is not None and summary.exists():
            solves = json.loads(summary.read_text()).get("surrogate", {}).get("solves_this_run")
            return f"ran to the end (summary.json); {solves} unit-cell solves for table tiles"
        return "ran to the end"
    if run.work_started == "none":
        return "stopped before any work"
    return f"failed after work started (exit {run.returncode})"


def _finished(rows: list[dict], tmp) -> list[dict]:
    """The rows as recorded: this machine's paths replaced (``$TMP``, ``$REPO``), then each
    message cut to its first 220 characters (in that order, so no path is cut in half)."""
    rows = scrub(rows, tmp)
    for row in rows:
        if isinstance(row.get("message (first line)"), str):
            row["message (first line)"] = _short(row["message (first line)"])
    return rows


def _short(text: str, limit: int = 220) -> str:
    return text if len(text) <= limit else text[:limit - 3] + "..."


# ----------------------------------------------------------------------------- bad input
def bad_input_rows(timeout: float = 180.0) -> list[dict]:
    """Each bad input of the study through the command line: input, exit code, first line of the
    message, seconds until the process stopped, work started (see the module's docstring)."""
    with tempfile.TemporaryDirectory(prefix="fabric-faults-") as tmp:
        ws = Workspace(Path(tmp))
        rows = []
        for what, make in _bad_inputs(ws):
            with make() as case:
                run = None if case.args is None else run_cli(case.args, env=case.env, timeout=timeout,
                                                             ranks=case.ranks)
                rows.append(_row(what, case, run))
        return _finished(rows, tmp)


def _fixed(args, env, ranks: int = 1, out: Path | None = None):
    """A case whose input needs no setting up."""
    @contextlib.contextmanager
    def make():
        yield Case(args, env, ranks, out=out)
    return make


def _bad_inputs(ws: Workspace):
    """(description, context manager yielding a :class:`Case`) of every bad input."""
    env = cli_env(ws.cache)
    out = ws.path("out")
    run = ["impact", ws.scene, "--out", out]
    cases = [
        ("scene: unknown key (--set projectile.speed=50)", _fixed(run + ["--set", "projectile.speed=50"], env)),
        ("scene: bad value (--set projectile.velocity=-3)",
         _fixed(run + ["--set", "projectile.velocity=-3"], env)),
    ]
    for k, (label, text) in enumerate(BAD_FABRICS.items()):
        (ws.base / f"bad-fabric-{k}.fabric.toml").write_text(text)
        scene = ws.scene_with(f"bad-fabric-{k}.toml", f'[fabric]\nfile = "bad-fabric-{k}.fabric.toml"\n')
        cases.append((f"fabric file: {label}, --check", _fixed(["impact", scene, "--check"], env)))
        cases.append((f"fabric file: {label}, run", _fixed(["impact", scene, "--out", out], env)))
    missing = ws.scene_with("missing-fabric.toml", '[fabric]\nfile = "no-such-fabric.toml"\n')
    existing = ws.path("existing-file")
    existing.write_text("a file, not a folder\n")
    latin1 = ws.path("latin1.toml")
    latin1.write_bytes(TINY_SCENE.replace("tiny scene", "sc\xe8ne").encode("latin-1"))
    cache_file = ws.path("cache-file")
    cache_file.write_text("a file, not a folder\n")
    cases += [
        ("fabric.file missing, with a scene file", _fixed(["impact", missing, "--out", out], env)),
        ("fabric.file missing, no scene file (--set fabric.file=no-such-fabric.toml)",
         _fixed(["impact", "--out", out, "--set", "fabric.file=no-such-fabric.toml"], env)),
        ("--out is an existing file", _fixed(["impact", ws.scene, "--out", existing], env)),
        ("--out is an existing file, 2 MPI ranks", _fixed(["impact", ws.scene, "--out", existing], env, 2)),
        ("--out is a read-only folder", _read_only_folder(ws, "out")),
        ("scene path is a folder", _fixed(["impact", ws.base, "--out", out], env)),
        ("scene path is not UTF-8 (Latin-1)", _fixed(["impact", latin1, "--out", out], env)),
        ("surrogate cache: FABRIC_FENICSX_CACHE names a file",
         _fixed(["impact", ws.scene, "--out", ws.path("out-cache-file"), "--quiet"], cli_env(cache_file),
                out=ws.path("out-cache-file"))),
        ("surrogate cache: an empty read-only folder", _read_only_folder(ws, "cache")),
        ("static --step 1e-9", _fixed(["static", "--scenario", "uniaxial-strain", "--step", "1e-9",
                                       "--out", ws.path("static")], env)),
        ("table tile: a corrupted (truncated) file", _tile_fault(ws, "corrupt")),
        ("table tile: one tile's file copied over another's", _tile_fault(ws, "swap")),
    ]
    return cases


def _read_only_folder(ws: Workspace, which: str):
    """A case run with a read-only folder as the output folder (``which = "out"``) or as the
    surrogate cache (``"cache"``, output elsewhere); no case where the mount is refused."""
    @contextlib.contextmanager
    def make():
        folder = ws.path(f"ro-{which}")
        out = folder if which == "out" else ws.path("out-ro-cache")
        with read_only_dir(folder) as how:
            args = ["impact", ws.scene, "--out", out] + (["--quiet"] if which == "cache" else [])
            yield Case(None if how is None else args, cli_env(folder if which == "cache" else ws.cache),
                       note=how or "mount refused", out=None if which == "out" else out)
    return make


def _tile_fault(ws: Workspace, kind: str):
    @contextlib.contextmanager
    def make():
        cache = ws.cache_copy(f"cache-{kind}")
        tiles = ws.tiles(cache)
        if kind == "corrupt":
            data = tiles[0].read_bytes()
            tiles[0].write_bytes(data[: len(data) // 2])
        else:
            shutil.copyfile(tiles[0], tiles[-1])
        out = ws.path(f"out-{kind}")
        yield Case(["impact", ws.scene, "--out", out, "--quiet"], cli_env(cache), out=out)
    return make


# ----------------------------------------------------------------------------- faults
def fault_rows(timeout: float = 240.0) -> list[dict]:
    """Faults while a run goes: one row each with what happened and what output is kept."""
    with tempfile.TemporaryDirectory(prefix="fabric-faults-") as tmp:
        ws = Workspace(Path(tmp))
        rows = [
            _signal_row(ws, signal.SIGINT, timeout),
            _signal_row(ws, signal.SIGKILL, timeout),
            _read_only_cache_row(ws, timeout),
            _full_cache_row(ws, timeout),
            _full_out_row(ws, timeout, xdmf=False),
            _full_out_row(ws, timeout, xdmf=True),
            _mpi_read_only_out_row(ws, timeout),
            _mpi_exception_row(ws, timeout),
            _mpi_kill_row(ws, timeout),
        ]
        return _finished(rows, tmp)


def kept(out: Path) -> dict:
    """What an output folder holds: readable history.csv rows, whether its last line is
    complete, and whether summary.json is there and parses."""
    hist = out / "history.csv"
    rows, complete = 0, None
    if hist.exists():
        text = hist.read_text()
        complete = text.endswith("\n") or not text
        with open(hist, newline="") as f:
            table = list(csv.reader(f))
        header = table[0] if table else []
        rows = sum(1 for r in table[1:] if len(r) == len(header) and _floats(r))
    summary = out / "summary.json"
    ok = False
    if summary.exists():
        with contextlib.suppress(ValueError):
            json.loads(summary.read_text())
            ok = True
    return {"history rows readable": rows, "history ends on a whole line": complete,
            "summary.json": "present" if ok else ("unreadable" if summary.exists() else "absent")}


def _floats(row: list[str]) -> bool:
    try:
        [float(x) for x in row]
    except ValueError:
        return False
    return True


def _fault(fault: str, run: Run | None, out: Path | None, note: str = "") -> dict:
    """One table row of a fault (``out`` None: no output folder to look at, "-")."""
    nothing = {"history rows readable": "-", "history ends on a whole line": "-", "summary.json": "-"}
    if run is None:
        return {"fault": fault, "exit code": "-", "seconds": "-",
                "message (first line)": "not available: " + note, **nothing}
    code = "timed out" if run.returncode is None else run.returncode
    row = {"fault": fault, "exit code": code, "seconds": round(run.seconds, 2),
           "message (first line)": _fault_message(run, note)}
    row.update(kept(out) if out is not None else nothing)
    return row


def _fault_message(run: Run, note: str) -> str:
    """The line that tells what happened: the command's own (``fabric-fenicsx ...``,
    ``interrupted ...``), else mpirun's, else the first error line, else the first line."""
    lines = [ln.strip() for ln in run.messages if ln.strip()]
    picks = ([ln for ln in lines if ln.startswith(("fabric-fenicsx", "interrupted"))]
             + [ln for ln in lines if ln.startswith("mpirun noticed")]
             + [ln for ln in lines if "Error" in ln] + lines)
    text = picks[0] if picks else "(no message)"
    return f"{note}: {text}" if note else text


def _with_t_end(ws: Workspace, t_end: float) -> Path:
    p = ws.path(f"tiny-{t_end:g}.toml")
    p.write_text(TINY_SCENE.replace("t_end = 3e-4", f"t_end = {t_end!r}"))
    return p


def _wait_for_rows(path: Path, rows: int, proc: subprocess.Popen, limit: float = 120.0) -> bool:
    """Wait until ``path`` has ``rows`` lines (or the process ended); True if it has."""
    t0 = time.perf_counter()
    while time.perf_counter() - t0 < limit and proc.poll() is None:
        if path.exists() and path.read_text().count("\n") > rows:
            return True
        time.sleep(0.05)
    return False


def _signal_row(ws: Workspace, sig: signal.Signals, timeout: float) -> dict:
    out = ws.path(f"out-{sig.name}")
    scene = _with_t_end(ws, 3e-3)
    ws.filled_cache()

    def send(proc):
        if _wait_for_rows(out / "history.csv", 100, proc):
            os.kill(proc.pid, sig)

    run = run_cli(["impact", scene, "--out", out, "--quiet"], env=cli_env(ws.cache), timeout=timeout,
                  on_start=send)
    return _fault(f"{sig.name} after 100 history rows (serial)", run, out)


def _read_only_cache_row(ws: Workspace, timeout: float) -> dict:
    """A filled cache, one tile removed, made read-only: the run needs that one new tile."""
    src = ws.cache_copy("cache-ro-src")
    tiles = ws.tiles(src)
    tiles[-1].unlink()
    ro = ws.path("cache-ro")
    out = ws.path("out-ro-cache")
    with read_only_dir(ro, fill=src) as how:
        if how is None:
            return _fault("read-only cache, one tile missing", None, None, "no read-only folder")
        run = run_cli(["impact", ws.scene, "--out", out, "--quiet"], env=cli_env(ro), timeout=timeout)
    return _fault("filled read-only cache, one tile missing", run, out, how)


def _full_cache_row(ws: Workspace, timeout: float) -> dict:
    """The cache on a 20 kB tmpfs: one tile (13 kB) fits, the next fails with ENOSPC."""
    disk = ws.path("cache-full")
    out = ws.path("out-cache-full")
    with small_disk(disk, "20k") as ok:
        if not ok:
            return _fault("surrogate cache on a full disk", None, None, "mount refused")
        run = run_cli(["impact", ws.scene, "--out", out, "--quiet"], env=cli_env(disk), timeout=timeout)
    return _fault("surrogate cache on a full disk (20 kB tmpfs)", run, out)


def _full_out_row(ws: Workspace, timeout: float, xdmf: bool) -> dict:
    """The output folder on a 200 kB tmpfs that the run overfills: history.csv alone (3 ms of
    history every 1 us, about 0.8 MB) or the XDMF series (a frame every 10 us)."""
    disk = ws.path(f"out-full-{'xdmf' if xdmf else 'csv'}")
    ws.filled_cache()
    if xdmf:
        args = ["--set", "output.xdmf_interval=1e-5"]
        scene = ws.scene
        what = "output folder on a full disk (200 kB tmpfs): XDMF frames"
    else:
        args = []
        scene = _with_t_end(ws, 3e-3)
        what = "output folder on a full disk (200 kB tmpfs): history.csv"
    with small_disk(disk, "200k") as ok:
        if not ok:
            return _fault(what, None, None, "mount refused")
        run = run_cli(["impact", scene, "--out", disk, "--quiet", *args], env=cli_env(ws.cache),
                      timeout=timeout)
        row = _fault(what, run, disk)
    return row


def _mpi_read_only_out_row(ws: Workspace, timeout: float) -> dict:
    out = ws.path("ro-out-mpi")
    with read_only_dir(out) as how:
        if how is None:
            return _fault("2 MPI ranks, read-only --out", None, None, "no read-only folder")
        run = run_cli(["impact", ws.scene, "--out", out, "--quiet"], env=cli_env(ws.cache),
                      timeout=timeout, ranks=2)
    return _fault("2 MPI ranks, --out a read-only folder", run, None, how)



def _mpi_exception_row(ws: Workspace, timeout: float) -> dict:
    out = ws.path("out-mpi-exception")
    ws.filled_cache()
    run = run_cli(["impact", ws.scene, "--out", out, "--quiet"], env=cli_env(ws.cache), timeout=timeout,
                  ranks=2, inject=INJECT_RANK1)
    return _fault("2 MPI ranks, exception on rank 1 mid-run (injected by the harness)", run, out)


def _mpi_kill_row(ws: Workspace, timeout: float) -> dict:
    out = ws.path("out-mpi-kill")
    pids = ws.path("pids")
    pids.mkdir(exist_ok=True)
    scene = _with_t_end(ws, 3e-3)
    ws.filled_cache()

    def kill_rank1(proc):
        if _wait_for_rows(out / "history.csv", 100, proc):
            with contextlib.suppress(OSError, ValueError):
                os.kill(int((pids / "rank1.pid").read_text()), signal.SIGKILL)

    run = run_cli(["impact", scene, "--out", out, "--quiet"],
                  env=cli_env(ws.cache, FAULTS_PID_DIR=str(pids)), timeout=timeout, ranks=2,
                  on_start=kill_rank1)
    return _fault("2 MPI ranks, rank 1 killed (SIGKILL) after 100 history rows", run, out)


# ----------------------------------------------------------------------------- shared folders, sizes, disks
STUDY_TINY = ("material.damage=false", "mesh.kind=uniform", "mesh.side=0.08", "mesh.n=16", "projectile.diameter=0.02",
              "projectile.mass=0.005", "run.t_end=3e-4")
"""The study's scene made as small as the tiny scene (its table tiles, a second a run)."""

STUDY_DISK = "450k"
"""The full-disk study's tmpfs: two of the fillet study's three runs (about 190 kB each with
their pictures) fit, the third fills it."""


def sharing_rows(timeout: float = 240.0) -> list[dict]:
    """Runs that share folders, machines and disks: one row each (see the module's docstring)."""
    with tempfile.TemporaryDirectory(prefix="fabric-faults-") as tmp:
        ws = Workspace(Path(tmp))
        rows = [_two_impact_runs_row(ws, timeout), _held_by_study_row(ws, timeout), _runaway_mesh_row(ws),
                *_full_disk_study_rows(ws, timeout)]
        return _finished(rows, tmp)


def _share(check: str, run: Run | None, left: str, note: str = "") -> dict:
    if run is None:
        return {"check": check, "exit code": "-", "seconds": "-", "message (first line)": "not available: " + note,
                "what is left": "-"}
    code = "timed out" if run.returncode is None else run.returncode
    return {"check": check, "exit code": code, "seconds": round(run.seconds, 2),
            "message (first line)": _fault_message(run, note), "what is left": left}


def _two_impact_runs_row(ws: Workspace, timeout: float) -> dict:
    """A second ``impact`` into the folder of one that runs: refused at once, the first's
    output whole when it ends."""
    out = ws.path("out-shared")
    scene = _with_t_end(ws, 3e-3)
    ws.filled_cache()
    first = subprocess.Popen(cli_command(["impact", scene, "--out", out, "--quiet"]), env=cli_env(ws.cache),
                             cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    try:
        if not _wait_for_rows(out / "history.csv", 20, first):
            return _share("a second impact run into a running run's --out", None, "-", "the first run did not start")
        second = run_cli(["impact", ws.scene, "--out", out, "--quiet"], env=cli_env(ws.cache), timeout=timeout)
        first.wait(timeout=timeout)
    finally:
        if first.poll() is None:
            _end_group(first)
    k = kept(out)
    left = (f"the first run ended with exit {first.returncode}: {k['history rows readable']} history rows, "
            f"summary.json {k['summary.json']}")
    return _share("a second impact run into a running run's --out", second, left)


def _held_by_study_row(ws: Workspace, timeout: float) -> dict:
    """An ensemble into a folder a study (another process) holds."""
    out = ws.path("study-held")
    code = ("import sys, time; from fabric_fenicsx.impact.lock import FolderLock; "
            "FolderLock(sys.argv[1], 'study', run_id='fillet').acquire(); print('held', flush=True); time.sleep(600)")
    holder = subprocess.Popen([sys.executable, "-c", code, str(out)], env=cli_env(ws.cache), cwd=ROOT,
                              stdout=subprocess.PIPE, text=True, start_new_session=True)
    try:
        holder.stdout.readline()
        run = run_cli(["ensemble", ws.scene, "-n", "2", "--out", out, "--quiet"], env=cli_env(ws.cache),
                      timeout=timeout)
    finally:
        _end_group(holder)
    left = ", ".join(sorted(p.name for p in out.iterdir())) or "nothing"
    return _share("an ensemble into a folder a study holds (the study: another process)", run,
                  f"the folder holds {left}")


def _runaway_mesh_row(ws: Workspace) -> dict:
    """The Y90 scene with a 1 um centre cell: refused from the scene alone, within 5 s."""
    out = ws.path("out-runaway")
    run = run_cli(["impact", ROOT / "demos" / "scenes" / "y90.toml", "--set", "mesh.h_centre=1e-6", "--out", out],
                  env=cli_env(ws.cache), timeout=60)
    verdict = "within 5 s" if run.seconds < 5 else "SLOWER than 5 s"
    left = (f"refused {verdict}, work started: {run.work_started}; output folder "
            f"{'absent' if not out.exists() else 'holds ' + (', '.join(p.name for p in out.iterdir()) or 'nothing')}")
    return _share("a runaway mesh: impact y90.toml --set mesh.h_centre=1e-6", run, left)


def _full_disk_study_rows(ws: Workspace, timeout: float) -> list[dict]:
    """``study fillet`` (three tiny runs, one at a time) on a tmpfs that fills up, then again on
    the same disk made 20 MB."""
    disk = ws.path("study-disk")
    out = disk / "study"
    ws.filled_cache()
    args = ["study", "fillet", "--out", out, "--jobs", "1", *[a for o in STUDY_TINY for a in ("--set", o)]]
    first_check = f"study fillet on a full disk ({STUDY_DISK} tmpfs)"
    second_check = "the same study resumed on the disk made 20 MB"
    with small_disk(disk, STUDY_DISK) as ok:
        if not ok:
            return [_share(first_check, None, "-", "mount refused"), _share(second_check, None, "-", "mount refused")]
        full = run_cli(args, env=cli_env(ws.cache), timeout=timeout)
        left = _study_left(out)
        lines = [ln for ln in full.messages if ln.strip()]
        left += f"; {len(lines)} line(s) on stderr, {'a' if 'Traceback' in full.stderr else 'no'} traceback"
        rows = [_share(first_check, full, left)]
        _mount(["-o", "remount,size=20m", str(disk)])
        again = run_cli(args, env=cli_env(ws.cache), timeout=timeout)
        md = out / "fillet.md"
        text = md.read_text() if md.exists() else ""
        reran = again.stdout.count(": done,")
        picture = ("the fillet picture drawn" if "](pictures/damage_fillet.png)" in text
                   else "NO fillet picture" + (": " + next((ln for ln in text.splitlines() if "not drawn" in ln), "")))
        rows.append(_share(second_check, again, f"{reran} run(s) run again, {again.stdout.count(': stored,')} "
                                                f"stored; {picture}; {_study_left(out)}"))
        return rows


def _study_left(out: Path) -> str:
    """Which runs of a study folder are complete (:func:`fabric_fenicsx.studies.runpool.incomplete`),
    and whether any record is empty."""
    from fabric_fenicsx.studies.runpool import incomplete

    runs = sorted(p for p in (out / "runs").glob("*") if p.is_dir())
    done = []
    for r in runs:
        with contextlib.suppress(OSError, ValueError):
            if not incomplete(r, json.loads((r / "summary.json").read_text())):
                done.append(r.name)
    empty = [str(p.relative_to(out)) for p in out.rglob("*.json") if p.stat().st_size == 0]
    return (f"{len(done)} of {len(runs)} run folders complete, "
            f"{'empty records: ' + ', '.join(empty) if empty else 'no empty record'}, "
            f"lock {'LEFT' if (out / '.fabric-fenicsx.lock').exists() else 'released'}")


def main(argv: list[str] | None = None) -> None:
    """Print the tables as JSON lines, or with ``--markdown`` as markdown tables (the report's
    rendering is in :mod:`tests.tools.reliability`); ``--only NAME`` (bad_input, fault,
    sharing) for one of them."""
    import argparse

    parser = argparse.ArgumentParser(prog="python -m tests.tools.faults")
    parser.add_argument("--markdown", action="store_true")
    parser.add_argument("--only", choices=("bad_input", "fault", "sharing"), action="append")
    args = parser.parse_args(argv)
    for name in args.only or ("bad_input", "fault", "sharing"):
        t0 = time.perf_counter()
        rows = globals()[f"{name}_rows"]()
        if args.markdown:
            from tests.tools.reliability import markdown_table

            print(f"<!-- {name}_rows: {time.perf_counter() - t0:.0f} s -->\n{markdown_table(rows)}\n")
        else:
            for row in rows:
                print(json.dumps(row))


if __name__ == "__main__":
    main()
