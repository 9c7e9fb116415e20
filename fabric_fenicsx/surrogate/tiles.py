"""Solving and caching the surrogate's table tiles (blocks of unit-cell solves).

A tile is a block of T x T grid nodes in (E1, E2) for one layer: the intact layer
(alpha = (1, 1)) or the damaged layer (the weaker yarn's relative integrity r < 1, for both
"warp weaker" and "fill weaker"). Each block is solved by warm-started sweeps along grid
lines, serpentine so that consecutive solves are neighbours, on a pool of processes; each
block's first node is solved from the unit cell's reference state, so a tile is the same
whichever blocks a worker solved before it.
Tiles are cached on disk as ``.npz`` files under a key derived from the fabric, the
solver settings and the grid; each file stores that key, the tile's name (layer and place in
the table) and a checksum covering both and the data, and is rebuilt when any does not match
(a tile's file copied over another's is rebuilt). A cache that cannot be written (a read-only
folder, a path naming a file, a full disk) does not stop a run: new tiles are kept in memory
and a :class:`CacheWarning` says so once (:func:`cache_problem`, :func:`warn_unwritable`,
:func:`report_cache_problems`).

One cache folder may be shared by many processes at once (the workers of a cluster, on one
machine or several, each with threads). No lock is taken: two processes that miss the same tile
both solve it, and that race only costs time. A tile's values depend on nothing but its key and
its name (each block starts from the reference state), so both writers write the same values;
each writes a complete file under a temporary name of its own in the same folder (host, process,
thread and a random part: :func:`save_tile`) and renames it over the tile's name with
:func:`os.replace`, which is atomic within a folder (also on NFS). A reader opens the tile's
name only, so it sees no file, the old one or a whole new one, never a half-written one; and a
file that fails its checksum anyway (a crash of the disk) is solved again.
"""

from __future__ import annotations

import hashlib
import json
import multiprocessing
import os
import sys
import tempfile
import time
import warnings
import zlib
from pathlib import Path

import numpy as np

from fabric_fenicsx.atomic import temporary_name, write_atomic  # noqa: F401 (temporary_name: tests)

QUANTITIES = ("P1", "P2", "mu1", "mu2", "V", "Psi")
"""Tabulated per node: P_i (N/m, Eq. 2-31), maximum stretches mu_i, contact force V (N) and
stored energy Psi (J/m^2) of the unit cell, at the node's (E1, E2, alpha)."""

FORMAT_VERSION = 3
"""3: the checksum covers the tile's name (layer, a, b) and the cache key, so a tile's file
copied over another's fails it (2 covered the values only). 2: each block starts from the unit
cell's reference state (1 warm-started its first node from the block the worker had solved
before: tiles depended on build order)."""


class CacheWarning(UserWarning):
    """The tile cache cannot be written: tiles are solved and kept in memory for this run."""


def default_cache_dir() -> Path:
    """``$FABRIC_FENICSX_CACHE``, else ``$XDG_CACHE_HOME/fabric_fenicsx``, else ``~/.cache/fabric_fenicsx``."""
    env = os.environ.get("FABRIC_FENICSX_CACHE")
    if env:
        return Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "fabric_fenicsx"


def cache_key(fabric_dict: dict, settings: dict) -> str:
    """A short hash of everything a tile's values depend on."""
    blob = json.dumps({"fabric": fabric_dict, "settings": settings, "format": FORMAT_VERSION},
                      sort_keys=True, default=float)
    return hashlib.sha256(blob.encode()).hexdigest()[:20]


def _checksum(values: np.ndarray, key: str, tile: str) -> int:
    """CRC-32 of the cache key, the tile's name and shape, and its values: a file holds one
    tile of one table, and says which."""
    head = f"{key}/{tile}/{values.shape}".encode()
    return zlib.crc32(np.ascontiguousarray(values).tobytes(), zlib.crc32(head))


def load_tile(path: Path, key: str, shape: tuple, tile: str) -> np.ndarray | None:
    """The values of tile ``tile`` (its name, e.g. ``intact_2_3``), or None if the file is
    missing, unreadable, corrupt, of another key or another tile's."""
    try:
        if not path.exists():
            return None
        with np.load(path, allow_pickle=False) as f:
            values = f["values"]
            ok = (str(f["key"]) == key and str(f["tile"]) == tile and values.shape == shape
                  and int(f["checksum"]) == _checksum(values, key, tile) and np.all(np.isfinite(values)))
    except Exception:  # truncated, garbled, unreadable or of an older format: rebuild it
        ok = False
    return values if ok else None


def save_tile(path: Path, key: str, values: np.ndarray, tile: str, compress: bool = False) -> None:
    """Write tile ``tile`` atomically (:func:`fabric_fenicsx.atomic.write_atomic`): the whole
    file under a name of its own, flushed to the disk, then renamed over ``path`` (another
    writer of the same tile at the same time writes its own file; the last rename wins, and
    each is complete). ``compress``: zip-deflated
    (smaller, slower to read). OSError if it cannot be written (no partial file is left)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    save = np.savez_compressed if compress else np.savez
    write_atomic(path, lambda f: save(f, values=values, key=np.array(key), tile=np.array(tile),
                                      checksum=np.array(_checksum(values, key, tile))))


def cache_problem(folder: Path) -> str | None:
    """Why tiles cannot be written into ``folder`` (created if missing), or None if they can;
    the reason names the folder."""
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        return f"{folder} is a file, not a folder"
    try:
        folder.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=folder, prefix=".write-test-"):
            pass
    except OSError as err:
        return f"{folder} is not writable ({err.strerror or err})"
    return None


_WARNED: set[str] = set()
_REPORT = None


def report_cache_problems(report) -> None:
    """Send cache problems to ``report(message)`` instead of :func:`warnings.warn` (the command
    line prints them on rank 0 and drops them on the others); None restores the warning."""
    global _REPORT
    _REPORT = report


def warn_unwritable(reason: str) -> None:
    """Say, once per process and reason, that new tiles stay in memory (a :class:`CacheWarning`
    or the reporter of :func:`report_cache_problems`; the command line's pre-flight check and
    the surrogate give the same reason for the same folder, so it is said once)."""
    if reason in _WARNED:
        return
    _WARNED.add(reason)
    message = (f"surrogate cache: {reason}: table tiles not in it are solved and kept in memory "
               "for this run only; set material.surrogate_cache or FABRIC_FENICSX_CACHE to a "
               "writable folder to keep them")
    if _REPORT is not None:
        _REPORT(message)
    else:
        warnings.warn(message, CacheWarning, stacklevel=1)


# ---------------------------------------------------------------------------- solving
_WORKER_CELL = None


def _worker_init(fabric_dict: dict, n_elements: int) -> None:
    global _WORKER_CELL
    from fabric_fenicsx.material.fabric import Fabric
    from fabric_fenicsx.material.unitcell import UnitCell
    _WORKER_CELL = UnitCell(Fabric.from_dict(fabric_dict), n_elements=n_elements)


def _solve_block(task):
    """Solve one block: nodes E1s x E2s at one alpha, as a serpentine warm-started sweep
    from the reference state, so that a block does not depend on the blocks solved before."""
    tag, alpha, E1s, E2s = task
    cell = _WORKER_CELL
    cell.forget()
    out = np.empty((len(E1s), len(E2s), len(QUANTITIES)))
    for j, E2 in enumerate(E2s):
        order = range(len(E1s)) if j % 2 == 0 else range(len(E1s) - 1, -1, -1)
        for i in order:
            r = cell.solve(float(E1s[i]), float(E2), alpha)
            out[i, j] = (r.P1, r.P2, r.mu1_max, r.mu2_max, r.V, r.Psi)
    return tag, out


class Progress:
    """A one-line progress bar on stderr."""

    def __init__(self, total: int, label: str, enabled: bool = True):
        self.total, self.label, self.done = total, label, 0
        self.enabled = enabled and total > 0
        self.t0 = self.shown = time.perf_counter()
        # On a terminal redraw twice a second; in a log file write a line every 10 s.
        self.tty = sys.stderr.isatty()
        self.interval = 0.5 if self.tty else 10.0

    def advance(self, n: int) -> None:
        self.done += n
        if not self.enabled:
            return
        now = time.perf_counter()
        if self.done < self.total and now - self.shown < self.interval:
            return
        self.shown = now
        frac = self.done / self.total
        bar = "#" * int(30 * frac)
        elapsed = time.perf_counter() - self.t0
        eta = elapsed / frac - elapsed if frac > 0 else 0.0
        start = "\r" if self.tty else ""
        sys.stderr.write(f"{start}{self.label} [{bar:<30}] {100 * frac:5.1f} % "
                         f"{self.done}/{self.total} solves, {elapsed:6.1f} s, eta {eta:5.1f} s")
        if self.done >= self.total or not self.tty:
            sys.stderr.write("\n")
        sys.stderr.flush()


def solve_blocks(tasks: list, fabric_dict: dict, n_elements: int, workers: int,
                 progress: Progress | None = None):
    """Yield (tag, values) for each task, solved on ``workers`` processes."""
    if workers <= 1 or len(tasks) <= 1:
        _worker_init(fabric_dict, n_elements)
        for task in tasks:
            tag, out = _solve_block(task)
            if progress:
                progress.advance(out.shape[0] * out.shape[1])
            yield tag, out
        return
    ctx = multiprocessing.get_context("fork")
    with ctx.Pool(workers, initializer=_worker_init, initargs=(fabric_dict, n_elements)) as pool:
        for tag, out in pool.imap_unordered(_solve_block, tasks):
            if progress:
                progress.advance(out.shape[0] * out.shape[1])
            yield tag, out
