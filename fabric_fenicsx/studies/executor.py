"""Where a study's runs execute: a ``concurrent.futures``-style executor whose every task is one
run, that is one ``fabric-fenicsx impact`` process (:func:`run_process`).

* :class:`LocalProcesses`, the default: each run a child process of this one, started at once
  (:func:`fabric_fenicsx.studies.runpool.run_all` submits ``jobs`` at a time).
* :class:`DaskCluster` (``--scheduler``): each run a task of a ``dask.distributed`` cluster; the
  worker that takes it starts the run's process on its machine and waits for it. ``tcp://HOST:8786``
  joins a running scheduler (``dask scheduler``, its workers ``dask worker tcp://HOST:8786
  --nthreads 1``); ``local:N`` starts a ``LocalCluster`` of N worker processes of one thread each
  on this machine. The runs' folders must be on a file system every worker sees at the same path:
  :meth:`DaskCluster.check_shared` checks it before the first run.

Both offer ``submit(fn, *args)`` (a future with ``done()`` and ``result()``), ``signal(tokens,
signum)`` (to the runs of those tokens, wherever they run), ``end(futures)``, ``check_shared``,
``slots`` (runs the executor can run at once), ``remote`` (whether paths must be absolute) and
``close()``. What to run, what to reuse and what a failure means stays with the caller
(:mod:`fabric_fenicsx.studies.runpool`). dask and distributed are optional (:data:`INSTALL`):
this module imports them only when a cluster is asked for.
"""
from __future__ import annotations

import contextlib
import hashlib
import os
import secrets
import signal
import subprocess
import sys
import threading
import time
from concurrent.futures import Future
from pathlib import Path

__all__ = ["INSTALL", "PYTHON", "ClusterError", "LocalProcesses", "DaskCluster", "make_executor",
           "scheduler_problem", "shared_problem", "run_process", "signal_processes", "worker_view"]

INSTALL = "pip install 'fabric_fenicsx[cluster]'"
"""What installs the optional dependencies of ``--scheduler`` (dask and distributed)."""

PYTHON = "{python}"
"""As the first item of a submitted command: the Python of the process that starts it (on a
worker, the worker's own), not the submitter's path to its Python."""

MARKER = ".fabric_fenicsx-shared-"
"""Prefix of the marker file :meth:`DaskCluster.check_shared` writes into the output folder."""

GRACE = 10.0
"""Seconds a run has to end after SIGTERM before it is killed (SIGKILL)."""

_LOCK = threading.Lock()
_RUNNING: dict[str, subprocess.Popen] = {}
_ENDED: set[str] = set()


class ClusterError(RuntimeError):
    """The cluster cannot run the study (not installed, not reachable, no workers, a folder or a
    file the workers cannot see); the message is one line saying what to do."""


def run_process(token: str, command: list, folder: str, env: dict | None = None) -> int | None:
    """Run ``command`` (a list; :data:`PYTHON` as its first item stands for this process's
    Python) with its output in ``folder``/run.log and this process's environment updated with
    ``env``, and wait for it. Registered under ``token`` while it runs, so that
    :func:`signal_processes` can end it. Returns its exit code (negative: the signal that ended
    it), or None when ``token`` was ended before the process started."""
    command = [sys.executable if i == 0 and a == PYTHON else str(a) for i, a in enumerate(command)]
    Path(folder).mkdir(parents=True, exist_ok=True)     # made by the submitter; a worker may not see it yet
    with open(Path(folder) / "run.log", "w") as log:
        with _LOCK:
            if token in _ENDED:
                _ENDED.discard(token)
                return None
            proc = subprocess.Popen(command, stdout=log, stderr=subprocess.STDOUT,
                                    env=dict(os.environ, **(env or {})))
            _RUNNING[token] = proc
        try:
            return proc.wait()
        finally:
            with _LOCK:
                _RUNNING.pop(token, None)


def signal_processes(tokens, signum: int) -> int:
    """Send ``signum`` to the processes of ``tokens`` that run in this process (a worker's, or
    this one's threads); a token whose process has not started yet is marked so that it never
    starts. Returns how many processes were signalled."""
    sent = 0
    with _LOCK:
        for token in tokens:
            proc = _RUNNING.get(token)
            if proc is None:
                _ENDED.add(token)
            elif proc.poll() is None:
                proc.send_signal(signum)
                sent += 1
    return sent


def _digest(path: str) -> str | None:
    """SHA-256 of a file's bytes, or None if it cannot be read."""
    try:
        return hashlib.sha256(Path(path).read_bytes()).hexdigest()
    except OSError:
        return None


def _fresh_model_version() -> str:
    """The model version of the package's files as they are on disk now (not the value cached
    when this process first asked)."""
    from fabric_fenicsx.provenance import model_version

    return model_version.__wrapped__()


def worker_view(marker: str, files: list[str]) -> dict:
    """What this process (a worker) sees of a study's shared files: the text of ``marker`` (None
    if it cannot be read), the SHA-256 of each of ``files`` (None if unreadable) and the model
    version of the code it would run."""
    try:
        text = Path(marker).read_text()
    except (OSError, UnicodeDecodeError):
        text = None
    return {"marker": text, "files": {f: _digest(f) for f in files}, "model_version": _fresh_model_version()}


class _Executor:
    """What both executors share: ending runs by their tokens (:meth:`end`) and the context
    manager that closes the executor."""

    remote = False
    slots = 1
    description = ""

    def signal(self, tokens, signum: int) -> None:  # pragma: no cover - each executor has its own
        raise NotImplementedError

    def cancel(self, futures) -> None:
        """Drop futures whose runs have not started (nothing to do for local processes)."""

    def check_shared(self, folder, files=()) -> None:
        """Refuse (:class:`ClusterError`) when a worker cannot see ``folder`` or ``files``;
        local processes see what this process sees."""

    def lost(self, err: BaseException) -> str | None:
        """Why a run's future failed with ``err`` if its worker was lost (the run is not
        recorded, it runs again when resumed), else None: local processes are not lost."""
        return None

    def end(self, futures: dict, grace: float = GRACE) -> None:
        """End the runs of ``futures`` (``{token: future}``): SIGTERM, then SIGKILL to those still
        running after ``grace`` seconds; runs not started yet never start."""
        if not futures:
            return
        self.signal(list(futures), signal.SIGTERM)
        t0 = time.monotonic()
        while any(not f.done() for f in futures.values()) and time.monotonic() - t0 < grace:
            time.sleep(0.05)
        left = [t for t, f in futures.items() if not f.done()]
        if left:
            self.signal(left, signal.SIGKILL)
            t1 = time.monotonic()
            while any(not futures[t].done() for t in left) and time.monotonic() - t1 < 5.0:
                time.sleep(0.05)
        self.cancel(list(futures.values()))

    def close(self) -> None:
        """Let go of the executor's resources."""

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class LocalProcesses(_Executor):
    """Runs as child processes of this one: ``submit(fn, *args)`` calls ``fn(*args)`` in a thread
    of its own at once (the caller decides how many at a time) and returns a
    ``concurrent.futures.Future``. ``slots``: the cores this process may use."""

    def __init__(self, slots: int | None = None):
        self.slots = slots or len(os.sched_getaffinity(0))
        self.description = "local processes"

    def submit(self, fn, *args) -> Future:
        future: Future = Future()
        future.set_running_or_notify_cancel()

        def work():
            try:
                future.set_result(fn(*args))
            except BaseException as err:
                future.set_exception(err)
        threading.Thread(target=work, name=f"run-{args[0] if args else ''}", daemon=True).start()
        return future

    def signal(self, tokens, signum: int) -> None:
        signal_processes(tokens, signum)


class DaskCluster(_Executor):
    """Runs as tasks of a ``dask.distributed`` cluster: ``scheduler`` is the address of a running
    scheduler (``tcp://HOST:8786``) or ``local:N`` (a ``LocalCluster`` of N worker processes, one
    thread each, closed with the executor). Waits up to ``connect`` seconds for the scheduler and
    ``workers`` seconds for its first worker. ``slots``: the worker threads of the cluster when it
    was joined. Raises :class:`ClusterError` when dask is not installed, the scheduler cannot be
    reached or has no workers."""

    remote = True

    def __init__(self, scheduler: str, connect: float = 10.0, workers: float = 30.0, client=None):
        self.scheduler = scheduler
        self._cluster = None
        if client is not None:          # a client made elsewhere (tests): used as it is, not closed
            self.client, self._own = client, False
        else:
            self.client, self._own = self._connect(scheduler, connect, workers), True
        nthreads = self.client.nthreads()
        self.slots = max(1, sum(nthreads.values()))
        self.description = (f"the dask cluster at {self.client.scheduler.address} "
                            f"({len(nthreads)} workers, {self.slots} threads)")

    def _connect(self, scheduler: str, connect: float, workers: float):
        problem = scheduler_problem(scheduler)
        if problem:
            raise ClusterError(problem)
        import distributed

        address = scheduler
        if scheduler.startswith("local:"):
            try:
                with _deaf_to_ctrl_c():
                    self._cluster = distributed.LocalCluster(n_workers=int(scheduler[6:]), threads_per_worker=1,
                                                             processes=True, dashboard_address=None)
            except Exception as err:
                raise ClusterError(f"cannot start a local dask cluster ({scheduler}): {_first_line(err)}") from None
            address = self._cluster
        try:
            client = distributed.Client(address, timeout=connect, set_as_default=False)
        except Exception as err:
            self._close_cluster()
            raise ClusterError(f"cannot reach the dask scheduler at {scheduler}: {_first_line(err)}; start it "
                               "with `dask scheduler` and give its address (tcp://HOST:8786)") from None
        try:
            client.wait_for_workers(1, timeout=workers)
        except Exception:
            client.close()
            self._close_cluster()
            raise ClusterError(f"the dask scheduler at {scheduler} has no workers after {workers:g} s; start them "
                               f"with `dask worker {scheduler} --nworkers N --nthreads 1`") from None
        return client

    def submit(self, fn, *args):
        return self.client.submit(fn, *args, pure=False)

    def signal(self, tokens, signum: int) -> None:
        """Signal the runs of ``tokens`` on every worker; a cluster that cannot be reached any more
        has nothing to signal (its runs are ended with their workers)."""
        try:
            self.client.run(signal_processes, list(tokens), int(signum))
        except Exception:
            pass

    def cancel(self, futures) -> None:
        try:
            self.client.cancel(list(futures))
        except Exception:
            pass

    def lost(self, err: BaseException) -> str | None:
        from concurrent.futures import CancelledError as FuturesCancelled
        from asyncio import CancelledError as TaskCancelled

        from distributed.scheduler import KilledWorker

        if isinstance(err, KilledWorker):
            return f"its workers died while running it ({_first_line(err)})"
        if isinstance(err, (FuturesCancelled, TaskCancelled)):
            return f"the cluster dropped it ({_first_line(err) or 'cancelled'})"
        return None

    def check_shared(self, folder, files=()) -> None:
        """Refuse (:class:`ClusterError`, one line) unless every worker reads back a marker file
        with a random token that this process writes into ``folder`` (removed afterwards),
        reads each of ``files`` (the runs' scene and fabric files) with the same bytes as here,
        and would run the same model version
        (:func:`fabric_fenicsx.provenance.model_version`) as this process's files."""
        folder = Path(os.path.abspath(folder))
        files = [os.path.abspath(f) for f in files]
        token = secrets.token_hex(16)
        marker = folder / f"{MARKER}{token}"
        marker.write_text(token)
        try:
            views = self.client.run(worker_view, str(marker), files)
        finally:
            marker.unlink(missing_ok=True)
        problem = shared_problem(views, token, folder, {f: _digest(f) for f in files}, _fresh_model_version())
        if problem:
            raise ClusterError(problem)

    def _close_cluster(self) -> None:
        if self._cluster is not None:
            self._cluster.close()
            self._cluster = None

    def close(self) -> None:
        if self._own:
            self.client.close()
        self._close_cluster()


@contextlib.contextmanager
def _deaf_to_ctrl_c():
    """SIGINT ignored while the processes of a local cluster start, so that they (and the runs
    they start) inherit it: Ctrl-C reaches only this process, which ends the runs (SIGTERM) and
    closes the cluster, instead of every worker printing its traceback as it dies."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


def shared_problem(views: dict, token: str, folder, digests: dict, version: str) -> str | None:
    """What the workers' ``views`` (``{address: worker_view(...)}``) say is wrong, in one line, or
    None: a worker that did not read ``token`` back cannot see ``folder``; one whose digest of an
    input file (a scene, a fabric file) differs from ``digests`` cannot read it (or reads another
    file there); one whose model version is not ``version`` runs other code."""
    blind = sorted(a for a, v in views.items() if v.get("marker") != token)
    if blind:
        return (f"the dask workers {', '.join(blind)} cannot see the output folder {folder}; put it on a "
                "file system every worker shares, at the same path, and give that path as --out")
    for path, digest in digests.items():
        other = sorted(a for a, v in views.items() if v.get("files", {}).get(path) != digest)
        if other:
            return (f"the dask workers {', '.join(other)} cannot read the runs' input file {path} as it is "
                    "here; put it on a file system every worker shares, at the same path")
    other = sorted(a for a, v in views.items() if v.get("model_version") != version)
    if other:
        theirs = ", ".join(sorted({str(views[a].get("model_version")) for a in other}))
        return (f"the dask workers {', '.join(other)} would run model version {theirs}, not this one's "
                f"{version}; install the same fabric_fenicsx on every worker")
    return None


def _first_line(err: BaseException) -> str:
    text = str(err).strip()
    return text.splitlines()[0] if text else type(err).__name__


def scheduler_problem(scheduler: str | None) -> str | None:
    """Why ``--scheduler`` cannot be used as given (its form, or dask not installed), in one
    line, or None; checked before any work."""
    if scheduler is None:
        return None
    if scheduler.startswith("local:"):
        n = scheduler[6:]
        if not n.isdigit() or int(n) < 1:
            return f"--scheduler local:N needs a number of workers N of at least 1, got {scheduler!r}"
    elif "://" not in scheduler:
        return (f"--scheduler must be the address of a dask scheduler (tcp://HOST:8786) or local:N, "
                f"got {scheduler!r}")
    try:
        import distributed  # noqa: F401
    except ImportError:
        return f"--scheduler needs dask.distributed, which is not installed: {INSTALL}"
    return None


def make_executor(scheduler: str | None = None, slots: int | None = None):
    """The executor of a study: :class:`LocalProcesses` (``slots`` at most, default the cores)
    without ``scheduler``, else a :class:`DaskCluster` at ``scheduler`` (``tcp://HOST:PORT`` or
    ``local:N``). Raises :class:`ClusterError`."""
    if scheduler is None:
        return LocalProcesses(slots)
    return DaskCluster(scheduler)
