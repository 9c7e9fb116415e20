"""One writer per output folder: an advisory lock file that an impact run, a study or an ensemble
holds on its ``--out`` folder while it writes there.

The lock is the file ``.fabric-fenicsx.lock`` in the folder, created with ``O_CREAT | O_EXCL``
(atomic on a local file system and on NFS version 3 and later), holding JSON: what holds it
(``what``, e.g. "impact run"), its ``run_id``, ``host``, process id ``pid``, the process's start
``ticks`` (from /proc, so that a reused process id is not taken for the holder), and ``started``.
It is released (removed) when the holder ends, also on an exception or Ctrl-C.

A second writer finds the file and stops before any work with a message naming the holder. A
lock whose holder is gone (a process of this host that no longer runs, or runs as another
program with a reused id) is stale: it is taken over with a warning, by renaming it away (only
one of two racing takers can rename the same file) and creating a new one. A lock held on
another host cannot be checked from here: it is refused, and the message says which file to
delete if that run is known to be dead. On a file system without atomic exclusive create (some
old network file systems), two writers starting within the same instant could both succeed;
nothing else depends on it.
"""
from __future__ import annotations

import json
import os
import socket
import time
from pathlib import Path

from fabric_fenicsx.impact.scene import InputError

__all__ = ["LOCK_NAME", "FolderLock", "FolderLocked"]

LOCK_NAME = ".fabric-fenicsx.lock"


class FolderLocked(InputError):
    """The folder is held by another live writer; the message names it."""


def _start_ticks(pid: int) -> int | None:
    """The start time of process ``pid`` in clock ticks since boot (field 22 of /proc/PID/stat),
    None where /proc cannot tell."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    try:
        return int(stat.rsplit(")", 1)[1].split()[19])
    except (IndexError, ValueError):
        return None


def _alive(pid: int, ticks: int | None) -> bool:
    """Whether the process ``pid`` (started at ``ticks``) still runs on this host."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        pass                     # it exists, owned by someone else
    now = _start_ticks(pid)
    return ticks is None or now is None or now == ticks


class FolderLock:
    """The lock of ``folder`` for one writer (``what``: e.g. "impact run", "study", "ensemble").

    ``acquire()`` takes it or raises :class:`FolderLocked`; ``release()`` gives it back (only
    if it is still ours). Use as a context manager. ``warn``: called with a message when a
    stale lock is taken over."""

    def __init__(self, folder: str | os.PathLike, what: str, run_id: str = "", warn=None):
        self.folder = Path(folder)
        self.path = self.folder / LOCK_NAME
        self.what, self.run_id = what, run_id
        self.warn = warn or (lambda message: None)
        self._mine: dict | None = None

    def _record(self) -> dict:
        return {"what": self.what, "run_id": self.run_id, "host": socket.gethostname(),
                "pid": os.getpid(), "ticks": _start_ticks(os.getpid()),
                "started": time.strftime("%Y-%m-%dT%H:%M:%S%z")}

    def _create(self) -> bool:
        """Create the lock file with our record; False if it exists."""
        record = self._record()
        try:
            fd = os.open(self.path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
        except FileExistsError:
            return False
        try:
            with os.fdopen(fd, "w") as f:
                json.dump(record, f)
        except OSError:
            self.path.unlink(missing_ok=True)   # a full disk: leave no empty lock behind
            raise
        self._mine = record
        return True

    def holder(self) -> dict | None:
        """The record in the lock file (None if there is none; ``{}`` if it cannot be read)."""
        try:
            return json.loads(self.path.read_text())
        except FileNotFoundError:
            return None
        except (OSError, ValueError):
            return {}

    def describe(self, h: dict) -> str:
        if not h:
            return f"an unreadable lock {self.path}"
        return (f"{h.get('what', 'a run')} {h.get('run_id') or ''} (process {h.get('pid')} on host "
                f"{h.get('host')}, started {h.get('started')})").replace("  ", " ")

    def acquire(self) -> "FolderLock":
        self.folder.mkdir(parents=True, exist_ok=True)
        for _ in range(3):
            if self._create():
                return self
            h = self.holder()
            if h is None:
                continue                        # released meanwhile: try again
            stale = (h and h.get("host") == socket.gethostname() and isinstance(h.get("pid"), int)
                     and not _alive(h["pid"], h.get("ticks")))
            if not h:
                raise FolderLocked(f"output folder {str(self.folder)!r} holds an empty or unreadable lock "
                                   f"{self.path} (left by a writer stopped as it began, or written by hand): if "
                                   f"no run writes there, delete {self.path} and run it again; else give another "
                                   "--out")
            if not stale:
                where = ("" if h.get("host") == socket.gethostname() else
                         f"; if that run is known to be dead, delete {self.path}")
                raise FolderLocked(f"output folder {str(self.folder)!r} is in use by "
                                   f"{self.describe(h)}: give another --out, or wait until it ends{where}")
            aside = self.path.with_name(f"{LOCK_NAME}.stale-{os.getpid()}")
            try:
                os.rename(self.path, aside)
            except FileNotFoundError:
                continue                        # another taker was first
            aside.unlink(missing_ok=True)
            self.warn(f"output folder {str(self.folder)!r}: took over the stale lock of "
                      f"{self.describe(h)}, which no longer runs")
        raise FolderLocked(f"output folder {str(self.folder)!r}: its lock {self.path} keeps changing "
                           "hands; another run is starting there")

    def release(self) -> None:
        if self._mine is None:
            return
        h = self.holder()
        if h and h.get("pid") == self._mine["pid"] and h.get("ticks") == self._mine["ticks"] \
                and h.get("host") == self._mine["host"]:
            self.path.unlink(missing_ok=True)
        self._mine = None

    def __enter__(self) -> "FolderLock":
        return self.acquire()

    def __exit__(self, *exc) -> None:
        self.release()
