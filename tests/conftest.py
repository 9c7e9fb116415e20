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
  instead of each solving it again. ``coarse_tables_in_runs`` makes the impact runs of a test
  module use that table's settings (and so its tiles) instead of the default table's.
* The demos whose tests are selected start in the background, at a lower priority, as soon as
  the session knows its tests (:class:`BackgroundDemos`); ``test_demo_runs`` waits for them.
* The checkout's root is put on ``sys.path`` (first, unless it is there already), so the test tools import as ``tests.tools``
  (:mod:`tests.tools.faults`, ...) however pytest is started.
* Ctrl-C reaches the commands the tests start even when pytest itself was started with SIGINT
  ignored (a shell's background job without job control): an ignored SIGINT is inherited by
  every child, whose Python then never raises KeyboardInterrupt, and the interrupt tests would
  measure the runner instead of the commands.
"""

import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest

if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)

if str(Path(__file__).resolve().parents[1]) not in sys.path:
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

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
    demos = getattr(config, "_fabric_fenicsx_demos", None)
    if demos is not None:
        demos.stop()
    base = getattr(config, "_fabric_fenicsx_base", None)
    if base is not None:
        shutil.rmtree(base, ignore_errors=True)


DEMO_TIMEOUT = 900
"""Seconds a demo may take, counted from its start."""


class BackgroundDemos:
    """The selected ``demos/demo_*.py`` scripts, started as soon as the session knows its tests
    (:func:`pytest_collection_finish`), at a lower CPU priority (nice 10), each in its own
    folder: they are separate processes, and most of the suite keeps one of the two cores busy,
    so they run on the other one while the rest of the suite runs. ``result(demo)`` waits for
    one and returns (return code, stdout, stderr, its output folder)."""

    def __init__(self, folder: Path):
        self.folder = folder
        self.running: dict[str, tuple] = {}

    def start(self, demo: Path) -> None:
        run = self.folder / demo.stem
        out = run / "out"
        run.mkdir(parents=True)
        env = dict(mpi_env(), MPLBACKEND="Agg", PYVISTA_OFF_SCREEN="true")
        stdout, stderr = open(run / "stdout.txt", "w"), open(run / "stderr.txt", "w")
        # cwd = its own folder: a demo must not depend on being started from the demos folder
        proc = subprocess.Popen([sys.executable, str(demo), str(out)], cwd=run, env=env,
                                stdout=stdout, stderr=stderr, preexec_fn=lambda: os.nice(10))
        self.running[demo.stem] = (proc, out, stdout, stderr, time.monotonic())

    def result(self, demo: Path):
        if demo.stem not in self.running:
            self.start(demo)
        proc, out, stdout, stderr, started = self.running[demo.stem]
        try:
            proc.wait(timeout=max(1.0, DEMO_TIMEOUT - (time.monotonic() - started)))
        except subprocess.TimeoutExpired:
            proc.kill()
            pytest.fail(f"{demo.name} did not end within {DEMO_TIMEOUT} s")
        finally:
            stdout.close()
            stderr.close()
        return (proc.returncode, Path(stdout.name).read_text(), Path(stderr.name).read_text(), out)

    def stop(self) -> None:
        for proc, *_ in self.running.values():
            if proc.poll() is None:
                proc.kill()
                proc.wait()


def pytest_collection_finish(session):
    """Start every demo whose test was selected (see :class:`BackgroundDemos`)."""
    config = session.config
    demos = BackgroundDemos(config._fabric_fenicsx_base / "demos")
    config._fabric_fenicsx_demos = demos
    for item in session.items:
        if getattr(item, "originalname", None) == "test_demo_runs":
            demos.start(item.callspec.params["demo"])


@pytest.fixture(scope="session")
def background_demos(request):
    """The session's :class:`BackgroundDemos`."""
    return request.config._fabric_fenicsx_demos


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


@pytest.fixture(scope="module")
def coarse_tables_in_runs(coarse_surrogate):
    """For a module whose impact runs test something other than the table's accuracy: every
    ``Surrogate`` made in this process while the module runs (the simulation's among them) takes
    the coarse table's settings, so the runs read the session's coarse tiles instead of solving
    the default table's (minutes from an empty cache). Yields those settings."""
    import functools

    import fabric_fenicsx.surrogate.table as table

    settings = dict(resolution=coarse_surrogate.h, r_nodes=coarse_surrogate.r_nodes,
                    tile=coarse_surrogate.tile)
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(table, "Surrogate", functools.partial(table.Surrogate, **settings))
        yield settings


ROOT = Path(__file__).resolve().parents[1]

TINY_TOML = ('description = "tiny"\n[material]\nangle = 90.0\ndamage = false\n'
             '[mesh]\nkind = "uniform"\nside = 0.08\nn = 16\n'
             '[projectile]\ndiameter = 0.02\nvelocity = 20.0\nmass = 0.005\n'
             '[boundary]\nclamped = ["bottom", "top"]\n[run]\nmax_steps = {max_steps}\n'
             '[output]\nxdmf_interval = {xdmf_interval}\npng = false\nprogress_interval = 0.0\n')
"""The tiny impact scene (8 cm square, 16 x 16 cells, damage off) as a TOML file's text."""


def mpi_env() -> dict:
    """Environment for subprocesses run with or without ``mpirun``: OpenMPI allowed as root and
    on more ranks than cores, this checkout first on the Python path."""
    return dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
                OMPI_MCA_rmaps_base_oversubscribe="1",
                PYTHONPATH=os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])))


@pytest.fixture(scope="session")
def impact_on_one_and_two_ranks(tmp_path_factory):
    """The tiny scene (400 steps, XDMF every 20 us) through ``fabric-fenicsx impact`` on 1 and
    on 2 ranks, run once per session: the two output folders."""
    folder = tmp_path_factory.mktemp("tiny_ranks")
    scene = folder / "tiny.toml"
    scene.write_text(TINY_TOML.format(max_steps=400, xdmf_interval=2e-5))
    cmd = [sys.executable, "-m", "fabric_fenicsx.cli", "impact", str(scene), "--quiet"]
    outs = []
    for n, prefix in ((1, []), (2, ["mpirun", "-n", "2", "--oversubscribe"])):
        out = folder / f"np{n}"
        proc = subprocess.run(prefix + cmd + ["--out", str(out)], env=mpi_env(), cwd=folder,
                              capture_output=True, text=True, timeout=600)
        assert proc.returncode == 0, proc.stderr[-3000:]
        outs.append(out)
    return outs
