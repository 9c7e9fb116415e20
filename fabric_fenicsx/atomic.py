"""Files written whole or not at all, by several writers at once if need be.

:func:`write_atomic` writes the whole file under a :func:`temporary_name` in the target's folder,
flushes it to the disk and renames it over the target with :func:`os.replace`, which is atomic
within a folder (also on NFS): a reader sees no file, the old one or the whole new one, never a
part. Writers of the same target at the same time (the threads of one process, the processes
of several hosts sharing a folder) each write a file of their own; the last rename wins. Used
for the surrogate's tiles, the records of a study's runs and the reports written beside them.
"""
from __future__ import annotations

import os
import socket
import threading
import uuid
from pathlib import Path
from typing import BinaryIO, Callable

__all__ = ["temporary_name", "write_atomic"]


def temporary_name(path: str | Path) -> Path:
    """A name for writing ``path`` that no other writer uses: in the same folder (so that
    :func:`os.replace` is a rename), hidden, ending in ``.tmp``, and unique across hosts,
    processes and threads sharing the folder."""
    path = Path(path)
    host = "".join(c for c in socket.gethostname() if c.isalnum() or c in "-_")[:32] or "host"
    tag = f"{host}-{os.getpid()}-{threading.get_ident()}-{uuid.uuid4().hex[:12]}"
    return path.with_name(f".{path.name}.{tag}.tmp")


def write_atomic(path: str | Path, data: str | bytes | Callable[[BinaryIO], None]) -> None:
    """Write ``data`` to ``path`` whole or not at all: text (UTF-8), bytes, or a function that
    writes into the open binary file. On an error (a full disk) the temporary file is removed,
    ``path`` keeps what it held, and the error is raised."""
    path = Path(path)
    tmp = temporary_name(path)
    try:
        with open(tmp, "xb") as f:
            if callable(data):
                data(f)
            else:
                f.write(data.encode("utf-8") if isinstance(data, str) else data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
