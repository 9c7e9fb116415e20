"""The guard around a study-like command (study, ensemble, divergence): its output folder's lock
(:mod:`fabric_fenicsx.impact.lock`) held from before the first run to the end, and a full disk,
a stopped pool or a cluster that cannot run the study reported in one line. Exit codes: 2 for a
folder in use or a cluster that cannot be used (:class:`~fabric_fenicsx.studies.executor.ClusterError`),
1 for a lock that cannot be written, a full disk or a stopped pool, else the body's. Also the
``--scheduler`` option of the commands whose runs can go to a dask cluster (study, ensemble)."""
from __future__ import annotations

import argparse
import sys


def add_scheduler_argument(parser: argparse.ArgumentParser, runs: str) -> None:
    """``--scheduler``: where the command's ``runs`` run (:mod:`fabric_fenicsx.studies.executor`)."""
    parser.add_argument("--scheduler", default=None, metavar="ADDRESS",
                        help=f"run the {runs} on a dask cluster: the address of its scheduler (tcp://HOST:8786), "
                             "or local:N for N workers on this machine; the output folder must be on a file "
                             "system every worker shares (needs pip install 'fabric_fenicsx[cluster]')")


def guarded(prog: str, out, what: str, run_id: str, body, reused: str = "its complete runs are reused") -> int:
    """Run ``body()`` holding the lock of ``out`` as ``what``; messages are prefixed with ``prog``."""
    from pathlib import Path

    from fabric_fenicsx.cli._checks import first_missing, remove_new
    from fabric_fenicsx.impact.lock import FolderLock, FolderLocked
    from fabric_fenicsx.studies.executor import ClusterError
    from fabric_fenicsx.studies.runpool import DISK_ERRNOS, PoolStopped

    def say(text: str) -> None:
        print(f"{prog}: {text}", file=sys.stderr, flush=True)

    lock = FolderLock(out, what, run_id=run_id, warn=lambda m: say(f"warning: {m}"))
    new = first_missing(Path(out))
    try:
        lock.acquire()
    except FolderLocked as err:
        say(str(err))
        return 2
    except OSError as err:
        say(f"cannot lock the output folder {out}: {err.strerror or err}")
        return 1
    try:
        return body()
    except OSError as err:
        if err.errno not in DISK_ERRNOS:
            raise
        where = f" ({err.filename})" if err.filename else ""
        say(f"stopped: a file could not be written{where}: {err.strerror or err}; free space and run it "
            f"again: {reused}")
        return 1
    except PoolStopped as err:
        say(f"stopped: {err}")
        return 1
    except ClusterError as err:
        say(str(err))
        lock.release()
        remove_new(Path(out), new)          # nothing ran: a folder made for the lock goes again
        return 2
    finally:
        lock.release()
