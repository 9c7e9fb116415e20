"""The harness of the bad-input and fault tables (:mod:`tests.tools.faults`): the command line
run in a fresh process under a probe, the tiny scene and fabric files the cases use, read-only
folders and small disks, and a workspace with its own surrogate cache.

How "work started" is seen: the command runs under :data:`PROBE`, a few lines that install an
audit hook (:func:`sys.addaudithook`) before ``fabric_fenicsx.cli.main`` and print, at exit, whether
DOLFINx was imported (the impact command imports it only to build the mesh, after every input
check) and whether a table tile file was opened (read from or written to the cache). A process
ended by a signal or ``MPI_Abort`` prints nothing; its row says so.

Read-only folders: root ignores permission bits, so as root a read-only folder is a tmpfs
mount remounted read-only (``mount -o remount,ro``); as another user it is ``chmod 555``. A full
disk is a tmpfs of 20 or 200 kB. Where mounting is refused the row says "not available"; nothing
is faked.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PROBE_TAG = "fabric-fenicsx-probe:"
ESTIMATE = ": estimate: about "
"""What the line of a run's size estimate holds (left out of the messages)."""

PROBE = r"""
import json, os, sys
seen = {"dolfinx": False, "tiles": False}
def hook(event, args):
    if event == "import" and args and args[0] == "dolfinx":
        seen["dolfinx"] = True
    elif event == "open" and args:
        try:
            path = os.fspath(args[0])
        except TypeError:
            return
        if isinstance(path, str) and path.endswith(".npz") and "surrogate-" in path:
            seen["tiles"] = True
sys.addaudithook(hook)
import atexit
atexit.register(lambda: sys.stderr.write("%s " + json.dumps(seen) + "\n"))
pid_dir = os.environ.get("FAULTS_PID_DIR")
if pid_dir:
    rank = os.environ.get("OMPI_COMM_WORLD_RANK", "0")
    with open(os.path.join(pid_dir, "rank%%s.pid" %% rank), "w") as f:
        f.write(str(os.getpid()))
%s
from fabric_fenicsx.cli import main
sys.argv[0] = "fabric-fenicsx"
sys.exit(main(sys.argv[1:]))
"""
"""The instrumented command line (``%s``: the tag, then Python run before ``main``: a fault
injected by the harness, empty otherwise)."""

TINY_SCENE = """\
description = "tiny scene of the reliability study"
[material]
angle = 90.0
damage = false
[mesh]
kind = "uniform"
side = 0.08
n = 16
[projectile]
diameter = 0.02
velocity = 20.0
mass = 0.005
[boundary]
clamped = ["bottom", "top"]
[run]
t_end = 3e-4
[output]
xdmf_interval = 0.0
png = false
progress_interval = 0.0
"""
"""The tiny scene (as ``TINY`` of tests/impact/test_impact.py): four intact table tiles, about
700 steps."""

GOOD_FABRIC = """\
name = "zylon-like"
area = 3.61e-8
density = 1560.0
[warp]
L = 0.3741e-3
Phi_L = 0.3481
A0 = 4338.0
B0 = 0.2657e-6
mu_crit = 1.025
[fill]
L = 0.3650e-3
Phi_L = 0.1546
A0 = 4724.0
B0 = 0.2935e-6
mu_crit = 1.0297
[damage]
law = "exponential"
beta = 124.0
width = 0.03
"""
"""A valid fabric file (Zylon AS of Table 1); the bad ones below change one thing in it."""

BAD_FABRICS = {
    "negative A0": GOOD_FABRIC.replace("A0 = 4338.0", "A0 = -4338.0"),
    "missing key (area)": GOOD_FABRIC.replace("area = 3.61e-8\n", ""),
    "unknown damage law": GOOD_FABRIC.replace('law = "exponential"', 'law = "weibull"'),
}

MPI_ENV = {"OMPI_ALLOW_RUN_AS_ROOT": "1", "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM": "1",
           "OMPI_MCA_rmaps_base_oversubscribe": "1", "OMPI_MCA_mpi_yield_when_idle": "1"}
"""OpenMPI as root, more ranks than cores, and waiting ranks yielding the core (the study runs
on a shared machine)."""


# ----------------------------------------------------------------------------- running the CLI
@dataclasses.dataclass
class Run:
    """One command-line run: exit code (None: killed on the time-out), output, wall seconds and
    what the probe saw (None: the process printed no probe line, e.g. it was killed)."""

    returncode: int | None
    stdout: str
    stderr: str
    seconds: float
    dolfinx: bool | None
    tiles: bool | None

    @property
    def messages(self) -> list[str]:
        """stderr lines without the probe's and without the size estimate every run prints
        before it starts (``fabric-fenicsx impact: estimate: ...``: information, not a message)."""
        return [ln for ln in self.stderr.splitlines() if not ln.startswith(PROBE_TAG) and ESTIMATE not in ln]

    @property
    def first_line(self) -> str:
        """The first line of the message: stderr's first non-empty line, else stdout's last."""
        for line in self.messages:
            if line.strip():
                return line.strip()
        lines = [ln for ln in self.stdout.splitlines() if ln.strip()]
        return lines[-1].strip() if lines else ""

    @property
    def work_started(self) -> str:
        """'none', 'mesh' (DOLFINx loaded), 'mesh + tile files' (and table tile files read or
        written), or 'unknown' (no probe line: the process was killed)."""
        if self.dolfinx is None:
            return "unknown"
        parts = [name for name, on in (("mesh", self.dolfinx), ("tile files", self.tiles)) if on]
        return " + ".join(parts) or "none"


def cli_env(cache: Path | None = None, **extra: str) -> dict[str, str]:
    """The environment of a study run: this checkout first on the path, MPI allowed as root,
    the surrogate cache in ``cache``."""
    env = dict(os.environ, **MPI_ENV)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))
    if cache is not None:
        env["FABRIC_FENICSX_CACHE"] = str(cache)
    env.update(extra)
    return env


def cli_command(args: list[str], ranks: int = 1, inject: str = "") -> list[str]:
    """``fabric-fenicsx ARGS`` under the probe (and ``mpirun -n RANKS`` when ranks > 1)."""
    cmd = [sys.executable, "-c", PROBE % (PROBE_TAG, inject), *map(str, args)]
    return (["mpirun", "-n", str(ranks)] + cmd) if ranks > 1 else cmd


def run_cli(args: list[str], env: dict | None = None, cwd: Path | None = None, timeout: float = 180.0,
            ranks: int = 1, inject: str = "", on_start=None) -> Run:
    """Run the command line once; a run still going after ``timeout`` s is ended (SIGTERM, then
    SIGKILL, to its whole process group) and has ``returncode`` None. ``on_start(proc)`` is
    called right after the start (to send signals)."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(cli_command(args, ranks, inject), env=env or cli_env(), cwd=cwd or ROOT,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    if on_start is not None:
        on_start(proc)
    try:
        out, err = proc.communicate(timeout=timeout)
        code = proc.returncode
    except subprocess.TimeoutExpired:
        out, err = _end_group(proc)
        code = None
    seconds = time.perf_counter() - t0
    probe = _probe(err)
    return Run(code, out, err, seconds, probe.get("dolfinx"), probe.get("tiles"))


def _end_group(proc: subprocess.Popen) -> tuple[str, str]:
    """End a process and its children (its own session): SIGTERM, then SIGKILL after 5 s."""
    for sig, wait in ((signal.SIGTERM, 5.0), (signal.SIGKILL, 10.0)):
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, sig)
        try:
            return proc.communicate(timeout=wait)
        except subprocess.TimeoutExpired:
            continue
    return "", ""


def _probe(stderr: str) -> dict:
    """What the probe saw, merged over the ranks (any rank counts)."""
    seen: dict = {}
    for line in stderr.splitlines():
        if line.startswith(PROBE_TAG):
            for key, value in json.loads(line[len(PROBE_TAG):]).items():
                seen[key] = seen.get(key, False) or value
    return seen


# ----------------------------------------------------------------------------- no machine paths
def scrub(value, tmp: str | os.PathLike | None = None):
    """``value`` (a string, or a row / list of them) with the paths of this machine replaced:
    the temporary folder ``tmp`` of the run by ``$TMP`` and the checkout's root by ``$REPO``
    (both as given and resolved), so that what the harness writes names no machine's paths."""
    if isinstance(value, dict):
        return {k: scrub(v, tmp) for k, v in value.items()}
    if isinstance(value, list):
        return [scrub(v, tmp) for v in value]
    if not isinstance(value, str):
        return value
    pairs = []
    for path, name in ((tmp, "$TMP"), (ROOT, "$REPO")):
        if path is not None:
            pairs += [(str(path), name), (str(Path(path).resolve()), name)]
    for path, name in sorted(set(pairs), key=lambda p: -len(p[0])):     # the longest first
        value = value.replace(path, name)
    return value


# ----------------------------------------------------------------------------- folders
def is_root() -> bool:
    return hasattr(os, "geteuid") and os.geteuid() == 0


@contextlib.contextmanager
def read_only_dir(path: Path, fill: Path | None = None, size: str = "2m"):
    """``path`` made a read-only folder (holding a copy of ``fill``'s contents, if given).
    Yields how ("read-only tmpfs mount" / "chmod 555") or None when it cannot be made."""
    path.mkdir(parents=True, exist_ok=True)
    if is_root():
        if _mount(["-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(path)]) is not None:
            yield None
            return
        try:
            if fill is not None:
                shutil.copytree(fill, path, dirs_exist_ok=True)
            if _mount(["-o", "remount,ro", str(path)]) is not None:
                yield None
                return
            yield "read-only tmpfs mount"
        finally:
            subprocess.run(["umount", str(path)], capture_output=True)
        return
    if fill is not None:
        shutil.copytree(fill, path, dirs_exist_ok=True)
    modes = [(p, p.stat().st_mode) for p in [path, *path.rglob("*")]]
    for p, _ in modes:
        p.chmod(0o555 if p.is_dir() else 0o444)
    try:
        yield "chmod 555"
    finally:
        for p, mode in modes:
            p.chmod(mode)


@contextlib.contextmanager
def small_disk(path: Path, size: str):
    """``path`` a tmpfs of ``size`` (a nearly full disk); yields False when mounting is refused."""
    path.mkdir(parents=True, exist_ok=True)
    if not is_root() or _mount(["-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(path)]) is not None:
        yield False
        return
    try:
        yield True
    finally:
        subprocess.run(["umount", str(path)], capture_output=True)


def _mount(args: list[str]) -> str | None:
    """Run ``mount ARGS``; None on success, else the reason it was refused."""
    try:
        proc = subprocess.run(["mount", *args], capture_output=True, text=True)
    except OSError as err:
        return str(err)
    return None if proc.returncode == 0 else (proc.stderr.strip() or f"exit {proc.returncode}")


# ----------------------------------------------------------------------------- a workspace
class Workspace:
    """A temporary folder with the tiny scene, fabric files and a filled surrogate cache."""

    def __init__(self, base: Path):
        self.base = base
        self.scene = base / "tiny.toml"
        self.scene.write_text(TINY_SCENE)
        self.cache = base / "cache"
        self._filled = False

    def path(self, name: str) -> Path:
        return self.base / name

    def scene_with(self, name: str, extra: str) -> Path:
        """The tiny scene with ``extra`` TOML tables after it (e.g. a [fabric] table)."""
        p = self.base / name
        p.write_text(TINY_SCENE + "\n" + extra)
        return p

    def filled_cache(self) -> Path:
        """The cache after one tiny run (its four intact tiles)."""
        if not self._filled:
            run = run_cli(["impact", self.scene, "--out", self.path("fill-out"), "--quiet"],
                          env=cli_env(self.cache))
            if run.returncode != 0:
                raise RuntimeError(f"filling the study's cache failed: {run.first_line}")
            self._filled = True
        return self.cache

    def tiles(self, cache: Path | None = None) -> list[Path]:
        return sorted((cache or self.cache).glob("surrogate-*/*.npz"))

    def cache_copy(self, name: str) -> Path:
        """A copy of the filled cache."""
        dst = self.base / name
        shutil.copytree(self.filled_cache(), dst)
        return dst



INJECT_RANK1 = """
if os.environ.get("OMPI_COMM_WORLD_RANK") == "1":
    import importlib.util

    def _fail_later(module):
        step = module.CentralDifference.step

        def failing_step(self, dt, f_ext):
            if self.time > 5e-5:
                raise FloatingPointError("non-finite value injected by the reliability study on rank 1")
            return step(self, dt, f_ext)
        module.CentralDifference.step = failing_step

    class _PatchOnImport:
        # patches the simulation module when the command imports it (importing DOLFINx here,
        # on one rank only, would start PETSc's collective set-up out of step with rank 0)
        def find_spec(self, name, path=None, target=None):
            if name != "fabric_fenicsx.impact.simulation":
                return None
            sys.meta_path.remove(self)
            spec = importlib.util.find_spec(name)
            run_module = spec.loader.exec_module

            def exec_module(module):
                run_module(module)
                _fail_later(module)
            spec.loader.exec_module = exec_module
            return spec

    sys.meta_path.insert(0, _PatchOnImport())
"""
"""A fault on rank 1 only, injected by the harness (the product has no such switch): once the
command has imported the simulation, rank 1's membrane step raises FloatingPointError when the
run passes 50 us, as a blow-up in the part of the mesh one rank owns would; the other rank
meanwhile waits in the step's reductions."""
