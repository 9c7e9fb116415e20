"""Fixtures shared by the whole test suite.

* Every test session gets its own, empty surrogate cache: ``FABRIC_FENICSX_CACHE`` points at a
  folder under pytest's temporary directory (``fabric_fenicsx.surrogate.tiles.default_cache_dir``
  reads it first), so the tests never read or write the user's ``~/.cache/fabric_fenicsx``,
  and their times and results do not depend on what an earlier run cached. ``XDG_CACHE_HOME``
  and ``MPLCONFIGDIR`` point to another temporary folder, so nothing under ``~/.cache`` is read
  or written. Subprocesses (the demos, ``mpirun`` runs, the command line) inherit the variables. To reuse a cache between
  sessions while developing, set ``FABRIC_FENICSX_TEST_CACHE=/some/folder``.
* ``coarse_surrogate``: one coarse table of the built-in Zylon AS (h = 0.004, 6 r-nodes, tiles
  of 8 nodes) for the whole session, in that cache; the surrogate and impact tests share it
  instead of each solving it again.
"""

import os
from pathlib import Path

import pytest

COARSE = dict(resolution=0.004, r_nodes=6, tile=8, progress=False)
"""Settings of the shared coarse table (``coarse_surrogate``)."""


@pytest.fixture(scope="session", autouse=True)
def surrogate_cache(tmp_path_factory):
    """The session's surrogate cache folder, exported as ``FABRIC_FENICSX_CACHE``."""
    chosen = os.environ.get("FABRIC_FENICSX_TEST_CACHE")
    path = Path(chosen) if chosen else tmp_path_factory.mktemp("fabric_fenicsx_cache")
    path.mkdir(parents=True, exist_ok=True)
    patch = pytest.MonkeyPatch()
    patch.setenv("FABRIC_FENICSX_CACHE", str(path))
    # nothing else under ~/.cache either (matplotlib's font cache, anything honouring XDG)
    home_cache = tmp_path_factory.mktemp("xdg_cache")
    patch.setenv("XDG_CACHE_HOME", str(home_cache))
    patch.setenv("MPLCONFIGDIR", str(home_cache / "matplotlib"))
    yield path
    patch.undo()


@pytest.fixture(scope="session")
def coarse_surrogate(surrogate_cache):
    """The coarse Zylon AS table (``COARSE``), shared by every test that asks for it. Tests
    may read its counters (``solves``, ``stats``) but must not change its settings."""
    from fabric_fenicsx.material.fabric import zylon_as
    from fabric_fenicsx.surrogate.table import Surrogate

    return Surrogate(zylon_as("max"), cache_dir=surrogate_cache, **COARSE)
