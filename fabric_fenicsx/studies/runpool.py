"""Independent impact runs of a study, ``jobs`` at a time, each a ``fabric-fenicsx impact``
process of its own; a run whose complete record is stored with the same settings and model
version (:mod:`fabric_fenicsx.provenance`) is reused, not run again, so an interrupted study
resumes where it stopped; so is a run that failed in the model (failed.json: its error,
settings and model version), which would fail the same way again.

A run is a :class:`Run` (a folder name, a scene file, ``--set`` overrides); :func:`run_all`
returns each run's summary, or a row with ``error`` (the exit code and the last line of its
log) for a run that failed. Each process runs serially (one rank, one thread).

What counts as stored (:func:`incomplete`): a run's folder is taken as done only if

* its summary.json is a non-empty JSON object with the same settings and model version, and
  the folder holds, each non-empty, every file a finished run writes that a study reads
  afterwards (:func:`expected_files`): history.csv always; damage.npz (and it opens as an
  archive) when the run draws its pictures (``output.png``, the damage pictures of several
  runs read it); impact.xdmf and impact.bin when it writes XDMF frames (``output.xdmf_interval``
  > 0 with ``output.fields``, the wave speeds read them). summary.json is written before the
  pictures, so a run stopped in between (killed, a full disk) has a summary but is not done;
* or its failed.json is a non-empty JSON object with ``error``, the same settings and model
  version, and ``"cause": "model"``: a failure the model reported (a blow-up, a bad input), not
  one of its surroundings. A run killed (a signal) or interrupted (exit 130, 143), ended by its
  surroundings (:func:`surroundings`: a full disk, a read-only or vanished folder, memory, its
  output folder held by another writer), or failing after it wrote its summary (while writing
  its pictures) is not recorded and runs again.

Anything else (a missing or empty file, a record cut short, a record older than this rule) is
incomplete: the run runs again. Records are written atomically
(:func:`fabric_fenicsx.atomic.write_atomic`: a temporary file in the same folder, then
``os.replace``), so none is ever left empty or cut.

A run's outcome that cannot be recorded, and a run that failed because its disk is full, stop
the pool: the running processes are ended (SIGTERM; they run again when the study is resumed)
and :class:`PoolStopped` is raised with one line that says why and what to do.

Where the processes run is the executor's business (:mod:`fabric_fenicsx.studies.executor`):
child processes of this one by default, or the workers of a dask cluster; what to reuse, what a
failure means and what is recorded is decided here, on the submitting side, the same for both.
A run whose cluster worker was lost is not recorded either (it runs again). :class:`Progress`
counts a study's runs as they end, for its progress line.
"""
from __future__ import annotations

import errno
import json
import os
import sys
import threading
import time
import uuid
import zipfile
from dataclasses import dataclass, field, replace
from pathlib import Path

from fabric_fenicsx.atomic import write_atomic

__all__ = ["Run", "run_all", "stored_summary", "PoolStopped", "Progress", "duration", "incomplete", "expected_files", "surroundings",
           "write_atomic", "DISK_ERRNOS"]

DISK_ERRNOS = (errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EROFS, errno.EIO)
"""Errors of a disk rather than of the model: full, over quota, file too large, read-only, I/O."""

SURROUNDINGS = ("No space left on device", "Disk quota exceeded", "File too large", "Read-only file system",
                "Input/output error", "Cannot allocate memory", "MemoryError", "Killed", "is in use by",
                "too large to run here", "output: a file could not be written")
"""Words in the last line of a failed run's log that name its surroundings, not the model:
such a failure is not recorded (the run runs again when the study is resumed)."""

FULL = ("No space left on device", "Disk quota exceeded")
"""Words of a failed run's log that mean its disk is full: the pool stops."""

LOW_SPACE = 64 << 10
"""A failed run whose file system has less free space than this (bytes) failed on a full disk."""


class PoolStopped(RuntimeError):
    """The pool stopped before its runs were done; the message is one line saying why."""


@dataclass(frozen=True)
class Run:
    """One impact run of a study: into ``out_dir``/``key``, the scene file with ``overrides``."""

    key: str
    scene: str
    overrides: tuple = field(default_factory=tuple)


def _command(run: Run, folder: Path) -> list[str]:
    return [sys.executable, "-m", "fabric_fenicsx.cli", "impact", str(run.scene), "--out", str(folder),
            "--quiet", *[a for o in run.overrides for a in ("--set", o)]]


def _settings(run: Run) -> dict:
    from fabric_fenicsx.impact.scene import load_scene

    return load_scene(run.scene, list(run.overrides)).to_dict()


def expected_files(settings: dict | None) -> list[str]:
    """The files a finished run with these settings (a summary's ``settings``) writes that a
    study reads afterwards; with no settings (a record not made by the impact command) only
    summary.json."""
    if not settings:
        return ["summary.json"]
    output = settings.get("output", {})
    names = ["summary.json", "history.csv"]
    if output.get("png", True):
        names.append("damage.npz")
    if (output.get("xdmf_interval") or 0) > 0 and output.get("fields", [None]):
        names += ["impact.xdmf", "impact.bin"]
    return names


def incomplete(folder: str | Path, summary: dict) -> list[str]:
    """The files of :func:`expected_files` (for the summary's settings) that ``folder`` lacks,
    holds empty, or (damage.npz) holds cut short; [] for a complete run."""
    folder = Path(folder)
    missing = []
    for name in expected_files(summary.get("settings")):
        path = folder / name
        try:
            ok = path.stat().st_size > 0
            if ok and name.endswith(".npz"):
                with zipfile.ZipFile(path) as z:
                    ok = bool(z.namelist())
        except (OSError, zipfile.BadZipFile):
            ok = False
        if not ok:
            missing.append(name)
    return missing


def _record(path: Path, settings: dict) -> dict | None:
    from fabric_fenicsx.provenance import load_if_same

    record = load_if_same(path, settings)
    return record if isinstance(record, dict) and record else None


def stored_summary(run: Run, out_dir) -> dict | None:
    """The complete stored result of ``run`` in ``out_dir`` (its summary, or its failure in the
    model), or None: what :func:`run_all` would reuse instead of running it."""
    return _stored(run, Path(out_dir) / run.key)


def _stored(run: Run, folder: Path) -> dict | None:
    """The run's complete stored summary, or its stored failure in the model, or None (see the
    module's docstring)."""
    settings = _settings(run)
    summary = _record(folder / "summary.json", settings)
    if summary is not None and "error" not in summary and not incomplete(folder, summary):
        return summary
    failed = _record(folder / "failed.json", settings)
    if failed is not None and failed.get("error") and failed.get("cause") == "model":
        return failed
    return None


def surroundings(error: str) -> bool:
    """Whether a failed run's error (the last line of its log) names its surroundings (a disk,
    memory, a signal, another writer) rather than the model."""
    return any(words in error for words in SURROUNDINGS)


def _disk_full(folder: Path, error: str) -> bool:
    if any(words in error for words in FULL):
        return True
    try:
        st = os.statvfs(folder)
    except OSError:
        return False
    return st.f_bavail * st.f_frsize < LOW_SPACE


def _last_line(folder: Path) -> str:
    try:
        lines = (folder / "run.log").read_text(errors="replace").strip().splitlines()
    except OSError:
        return "no output (its log cannot be read)"
    return lines[-1] if lines else "no output"


def _resume_hint(out_dir: Path) -> str:
    return (f"free space in {out_dir} (or give another --out) and run it again: its complete runs are "
            "reused, the others run again")


def run_all(runs: list[Run], out_dir: str | Path, jobs: int = 1, on_done=None, reuse: bool = True,
            slots=None, stop=None, executor=None) -> dict:
    """Run (or, with ``reuse``, take the stored result of) every run, ``jobs`` processes at a
    time; ``on_done(run, summary, reused)`` is called as each one ends. ``slots``: a
    ``threading.Semaphore`` shared by calls in other threads, of which every process holds one
    while it runs (so that concurrent calls together keep to the cores). ``stop``: a
    ``threading.Event`` shared with those calls: set when one of them stops, it stops the others.
    ``executor``: where the processes run (:mod:`fabric_fenicsx.studies.executor`; default
    child processes of this one); on a cluster the folders and scene files are given to the
    workers as absolute paths. Returns ``{key: summary}`` (a failed run: ``{"error": ...}``).
    Raises :class:`PoolStopped` when an outcome cannot be recorded or a run failed on a full disk
    (see the module's docstring)."""
    from fabric_fenicsx.studies.executor import LocalProcesses

    out_dir = Path(out_dir)
    keys = [r.key for r in runs]
    if len(set(keys)) != len(keys):
        raise ValueError(f"the runs' keys must differ (they name their folders), got {keys}")
    own = executor is None
    executor = LocalProcesses() if own else executor
    given = {r.key: r for r in runs}                # on_done gets the runs as given
    if executor.remote:
        out_dir = Path(os.path.abspath(out_dir))
        runs = [replace(r, scene=os.path.abspath(r.scene)) for r in runs]
    results: dict[str, dict] = {}
    pending = []
    for run in runs:
        stored = _stored(run, out_dir / run.key) if reuse else None
        if stored is not None:
            results[run.key] = stored
            if on_done is not None:
                on_done(given[run.key], stored, True)
        else:
            pending.append(run)
    running: dict = {}
    try:
        while pending or running:
            if stop is not None and stop.is_set():
                raise PoolStopped("stopped with the runs beside it")
            while pending and len(running) < max(1, jobs) and (slots is None or slots.acquire(blocking=False)):
                run = pending.pop(0)
                try:
                    running[run.key] = _start(run, out_dir / run.key, executor)
                except BaseException as err:
                    if slots is not None:
                        slots.release()
                    if isinstance(err, OSError):
                        raise _not_started(run, out_dir, err) from None
                    raise
            time.sleep(0.2)
            for key in [k for k, (future, *_) in running.items() if future.done()]:
                future, token, run, folder = running.pop(key)
                if slots is not None:
                    slots.release()
                results[key] = _outcome(future, run, folder, out_dir, executor)
                if on_done is not None:
                    on_done(given[key], results[key], False)
    except BaseException as err:
        _end(running, slots, executor)
        if isinstance(err, PoolStopped) and stop is not None:
            stop.set()
        raise
    finally:
        if own:
            executor.close()
    return {k: results[k] for k in keys}


def _not_started(run: Run, out_dir: Path, err: OSError) -> PoolStopped:
    """The stop of a pool whose run could not be started (its folder or log cannot be written;
    a file where its folder goes is not a matter of space)."""
    folder = out_dir / run.key
    if isinstance(err, (FileExistsError, NotADirectoryError)) or folder.exists() and not folder.is_dir():
        return PoolStopped(f"run {run.key} cannot be started: {folder} is a file, where the run's folder goes; move "
                           "it away and run it again: its complete runs are reused, the others run again")
    return PoolStopped(f"run {run.key} cannot be started in {folder}: {err.strerror or err}; "
                       f"{_resume_hint(out_dir)}")


def _start(run: Run, folder: Path, executor):
    """Submit the run's process to ``executor`` (:func:`fabric_fenicsx.studies.executor.run_process`)
    into a fresh ``folder``; (future, token, run, folder)."""
    from fabric_fenicsx.studies.executor import PYTHON, run_process

    folder.mkdir(parents=True, exist_ok=True)
    for name in ("summary.json", "failed.json"):
        (folder / name).unlink(missing_ok=True)     # never read an older run's
    command = _command(run, folder)
    if executor.remote:
        command = [PYTHON if i == 0 and a == sys.executable else a for i, a in enumerate(command)]
    token = f"{run.key}-{uuid.uuid4().hex}"
    return executor.submit(run_process, token, command, str(folder), {"OMP_NUM_THREADS": "1"}), token, run, folder


def _outcome(future, run: Run, folder: Path, out_dir: Path, executor) -> dict:
    """The outcome of a run whose future is done: :func:`_finished` on its exit code; a row with
    ``error`` (not recorded) if its worker was lost; :class:`PoolStopped` if it could not start."""
    try:
        code = future.result()
    except (KeyboardInterrupt, SystemExit):
        raise
    except BaseException as err:
        lost = executor.lost(err)
        if lost:
            return {"error": f"not run to its end: {lost}"}
        if isinstance(err, OSError):
            raise _not_started(run, out_dir, err) from None
        raise
    return _finished(run, folder, code, out_dir)


def _finished(run: Run, folder: Path, code: int, out_dir: Path) -> dict:
    """The outcome of a run that ended with exit code ``code``: its summary, or a row with
    ``error`` (recorded in failed.json if the model failed)."""
    summary = None
    try:
        summary = json.loads((folder / "summary.json").read_text())
        if not isinstance(summary, dict) or not summary:
            raise ValueError("an empty summary")
    except (OSError, ValueError):
        summary = None
    if summary is not None and code == 0:
        missing = incomplete(folder, summary)
        if not missing:
            return summary
        error = f"exit code 0 but its output lacks {', '.join(missing)}"
    else:
        error = f"exit code {code}: {_last_line(folder)}"
    if code != 0 and _disk_full(folder, error) or code == 0 and _disk_full(folder, ""):
        raise PoolStopped(f"run {run.key} failed on a full disk ({error}); {_resume_hint(out_dir)}")
    failure = {"error": error}
    if code > 0 and code not in (130, 143) and not surroundings(error) and summary is None:
        try:
            _record_failure(run, folder, failure)
        except OSError as err:
            raise PoolStopped(f"the failure of run {run.key} cannot be recorded in {folder / 'failed.json'}: "
                              f"{err.strerror or err}; {_resume_hint(out_dir)}") from None
    return failure


def _end(running: dict, slots, executor) -> None:
    """End the running processes (SIGTERM, then SIGKILL after 10 s): they run again later."""
    try:
        executor.end({token: future for future, token, *_ in running.values()})
    finally:
        if slots is not None:
            for _ in running:
                slots.release()
        running.clear()


def _record_failure(run: Run, folder: Path, summary: dict) -> None:
    """failed.json beside the run's log: its error, settings and model version, so that the
    study reports it again instead of repeating a run that fails the same way; written
    atomically (an OSError, e.g. a full disk, leaves no failed.json)."""
    from fabric_fenicsx.provenance import model_version

    try:
        settings = _settings(run)
    except Exception:        # the scene itself is bad: nothing to reuse
        return
    write_atomic(folder / "failed.json", json.dumps({**summary, "cause": "model", "settings": settings,
                                                     "model_version": model_version()}, indent=1))


def duration(seconds: float) -> str:
    """A span of time as a person says it: ``45 s``, ``2 min 10 s``, ``1 h 05 min``."""
    s = max(0, int(round(seconds)))
    if s < 60:
        return f"{s} s"
    if s < 3600:
        return f"{s // 60} min {s % 60} s"
    return f"{s // 3600} h {s % 3600 // 60:02d} min"


class Progress:
    """A study's runs counted as they end, for one progress line each (:meth:`finished`): runs
    done of the runs planned so far (:meth:`expect`), how many of them were reused or failed,
    the time since the study began and an estimate of the time left: the runs still to do times
    the time per run run so far (reused runs take none). Thread-safe (the ballistic limits'
    threads share one). ``say``: called with each line (None: lines are only returned)."""

    def __init__(self, label: str = "study", noun: str = "runs", say=None, clock=time.monotonic):
        self.label, self.noun, self.say, self.clock = label, noun, say, clock
        self.t0 = clock()
        self.total = self.done = self.reused = self.failed = 0
        self._lock = threading.Lock()

    def expect(self, n: int) -> None:
        """``n`` more runs are planned."""
        with self._lock:
            self.total += n

    def finished(self, summary: dict, reused: bool) -> str:
        """Count one run that ended (``summary``: its summary, or a row with ``error``); its line."""
        with self._lock:
            self.done += 1
            self.reused += bool(reused)
            self.failed += "error" in summary
            line = self.line()
        if self.say is not None:
            self.say(line)
        return line

    def line(self) -> str:
        """``study: 3/8 runs done (1 reused), 2 min 10 s elapsed, about 4 min 20 s left``."""
        elapsed = self.clock() - self.t0
        apart = [f"{n} {what}" for n, what in ((self.reused, "reused"), (self.failed, "failed")) if n]
        text = (f"{self.label}: {self.done}/{self.total} {self.noun} done"
                + (f" ({', '.join(apart)})" if apart else "") + f", {duration(elapsed)} elapsed")
        ran, left = self.done - self.reused, self.total - self.done
        if left > 0:
            text += f", about {duration(elapsed / ran * left)} left" if ran else ", time left not known yet"
        return text
