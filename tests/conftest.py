"""Fixtures shared by the whole test suite.

* Every test session gets its own, empty cache folders (:func:`pytest_configure`): the
  surrogate's (``FABRIC_FENICSX_CACHE``, read first by
  ``fabric_fenicsx.surrogate.tiles.default_cache_dir``), DOLFINx's JIT forms and matplotlib's
  (``XDG_CACHE_HOME``, ``MPLCONFIGDIR``), so the tests never read or write ``~/.cache`` and
  their times and results do not depend on what an earlier run cached. Subprocesses (the
  demos, ``mpirun`` runs, the command line) inherit the variables; the folder is removed at
  the end. To reuse a cache between
  sessions while developing, set ``FABRIC_FENICSX_TEST_CACHE=/some/folder``.
* ``coarse_surrogate``: one coarse table of the built-in Zylon AS (h = 0.004, 6 r-nodes, tiles
  of 8 nodes) for the whole session, in that cache; the surrogate and impact tests share it
  instead of each solving it again.
"""

import os
import shutil
import tempfile
from pathlib import Path

import pytest

COARSE = dict(resolution=0.004, r_nodes=6, tile=8, progress=False)
"""Settings of the shared coarse table (``coarse_surrogate``)."""


def pytest_configure(config):
    """Before any test module imports DOLFINx (whose JIT cache folder is fixed at import): the
    session's cache folders. ``XDG_CACHE_HOME`` (DOLFINx/FFCx JIT forms, matplotlib, anything
    honouring XDG) and ``MPLCONFIGDIR`` go to one temporary folder shared by this process and
    every subprocess, so each form is compiled once per session and nothing under ``~/.cache``
    is read or written; ``FABRIC_FENICSX_CACHE`` to ``FABRIC_FENICSX_TEST_CACHE`` if set, else
    to an empty folder in it."""
    base = Path(tempfile.mkdtemp(prefix="fabric_fenicsx_tests_"))
    config._fabric_fenicsx_base = base
    os.environ["XDG_CACHE_HOME"] = str(base / "xdg")
    os.environ["MPLCONFIGDIR"] = str(base / "matplotlib")
    chosen = os.environ.get("FABRIC_FENICSX_TEST_CACHE")
    surrogate = Path(chosen) if chosen else base / "surrogate"
    surrogate.mkdir(parents=True, exist_ok=True)
    os.environ["FABRIC_FENICSX_CACHE"] = str(surrogate)


def pytest_unconfigure(config):
    base = getattr(config, "_fabric_fenicsx_base", None)
    if base is not None:
        shutil.rmtree(base, ignore_errors=True)


@pytest.fixture(scope="session")
def surrogate_cache():
    """The session's surrogate cache folder (``FABRIC_FENICSX_CACHE``, see pytest_configure)."""
    return Path(os.environ["FABRIC_FENICSX_CACHE"])


@pytest.fixture(scope="session")
def coarse_surrogate(surrogate_cache):
    """The coarse Zylon AS table (``COARSE``), shared by every test that asks for it. Tests
    may read its counters (``solves``, ``stats``) but must not change its settings."""
    from fabric_fenicsx.material.fabric import zylon_as
    from fabric_fenicsx.surrogate.table import Surrogate

    return Surrogate(zylon_as("max"), cache_dir=surrogate_cache, **COARSE)
