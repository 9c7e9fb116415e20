"""``fabric-fenicsx impact SCENE --out DIR [--set section.key=value ...]``: one ballistic impact
(thesis chapter 4). Run in parallel with ``mpirun -n N fabric-fenicsx impact ...``.

Nothing heavy is imported at module level. Every input the run reads is checked before DOLFINx
is loaded and the mesh is built: the scene and the fabric file it names
(:func:`~fabric_fenicsx.impact.scene.load_scene`), the output folder
(:func:`~fabric_fenicsx.impact.scene.check_output_dir`), the run's size (a scene estimated beyond
``run.max_cells`` or the free memory is refused with the finest setting that fits,
:mod:`fabric_fenicsx.impact.sizing`; every run prints its estimate), the output folder's lock
(one writer per folder, :mod:`fabric_fenicsx.impact.lock`: a second run into a folder in use
stops, naming the first) and the surrogate cache (a cache that
cannot be written is not an error: new tiles stay in memory, said once). Under MPI every rank
checks and the ranks agree before going on, so a bad input stops all of them with one message
(exit code 2), printed by rank 0.

An error while the run goes (exit code 1): if every rank meets it (a check on reduced values)
rank 0 prints it and all ranks end normally; if only some ranks do, each of those prints its
message with its rank and ends all ranks with ``MPI_Abort``, since the others wait in a
collective call that would never return.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
import traceback

PROG = "fabric-fenicsx impact"
AGREE_SECONDS = 5.0
"""How long a failing rank waits for the other ranks to fail too before it aborts them all."""


def _rank() -> int:
    """MPI rank from the launcher's environment, without importing MPI."""
    return _launcher_int(("OMPI_COMM_WORLD_RANK", "PMI_RANK", "PMIX_RANK", "MV2_COMM_WORLD_RANK"), 0)


def _size() -> int:
    """Number of MPI ranks from the launcher's environment, without importing MPI."""
    return _launcher_int(("OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "MV2_COMM_WORLD_SIZE"), 1)


def _launcher_int(names: tuple[str, ...], default: int) -> int:
    for var in names:
        if var in os.environ:
            try:
                return int(os.environ[var])
            except ValueError:
                pass
    return default


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from fabric_fenicsx.impact.scene import describe_schema

    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.epilog = "scene keys (section.key = default  # meaning):\n" + describe_schema()
    parser.add_argument("scene", nargs="?", default=None,
                        help="scene TOML file (e.g. demos/scenes/y90.toml); omitted = all defaults")
    parser.add_argument("--out", default=None,
                        help="output folder (default out/impact-<scene name>)")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="SECTION.KEY=VALUE",
                        help="override a scene key, e.g. --set projectile.velocity=123.69 (repeatable)")
    parser.add_argument("--check", action="store_true",
                        help="validate the scene and its fabric file, print the scene with every default "
                             "filled in, and stop")
    parser.add_argument("--quiet", action="store_true", help="no progress lines")


def run(args: argparse.Namespace) -> int:
    """Check every input (all ranks agree), then run the impact."""
    scene, problem = _checked(lambda: _load(args))
    if _agreed_problem(problem):
        return 2
    from fabric_fenicsx.impact.scene import ignored_keys_warning, locking_warning
    from fabric_fenicsx.impact.sizing import check_size

    for warning in (locking_warning(scene), ignored_keys_warning(scene)):
        if warning and _rank() == 0:
            _warning(warning)
    size, problem = _checked(lambda: check_size(scene))
    if _agreed_problem(problem):
        return 2
    if _rank() == 0:
        _say(f"estimate: {size.describe()}")
    if args.check:
        if _rank() == 0:
            print(json.dumps({"source": scene.source, **scene.to_dict()}, indent=1))
        return 0
    out = args.out or os.path.join("out", f"impact-{scene.name}")
    _, problem = _checked(lambda: _check_run_inputs(scene, out))
    if _agreed_problem(problem):
        return 2
    lock, problem = _checked(lambda: _lock(out))
    if _agreed_problem(problem):
        if lock is not None:
            lock.release()
        return 2
    try:
        return _run(scene, out, args)
    finally:
        if lock is not None:
            lock.release()


def _lock(out: str):
    """Rank 0 takes the output folder's lock (the other ranks return None)."""
    if _rank() != 0:
        return None
    from fabric_fenicsx.impact.lock import FolderLock

    return FolderLock(out, "impact run", warn=_warning).acquire()


# ----------------------------------------------------------------------------- before any work
def _load(args: argparse.Namespace):
    from fabric_fenicsx.impact.scene import load_scene

    return load_scene(args.scene, args.overrides)


def _check_run_inputs(scene, out: str) -> None:
    """The output folder (an InputError if unusable) and the surrogate cache (a warning if it
    cannot be written)."""
    from pathlib import Path

    from fabric_fenicsx.impact.scene import check_output_dir

    check_output_dir(out)
    from fabric_fenicsx.surrogate.tiles import (cache_problem, default_cache_dir, report_cache_problems,
                                                warn_unwritable)

    report_cache_problems(_warning if _rank() == 0 else (lambda message: None))
    cache = scene.material.surrogate_cache
    problem = cache_problem(Path(cache) if cache else default_cache_dir())
    if problem:
        warn_unwritable(problem)


def _say(text: str) -> None:
    """``fabric-fenicsx impact: TEXT`` on stderr in one write (under mpirun the ranks' output
    is merged, and print's separate newline could land after another rank's line)."""
    sys.stderr.write(f"{PROG}: {text}\n")
    sys.stderr.flush()


def _warning(message: str) -> None:
    _say(f"warning: {message}")


def _checked(check):
    """(result of ``check()``, None) or (None, its InputError's message)."""
    from fabric_fenicsx.impact.scene import InputError

    try:
        return check(), None
    except InputError as err:
        return None, str(err)


def _agreed_problem(problem: str | None) -> bool:
    """Whether any rank found a problem; rank 0 prints the first one (lowest rank). Under MPI
    the ranks exchange what they found, so all stop or all go on."""
    if _size() > 1:
        from mpi4py import MPI

        found = MPI.COMM_WORLD.allgather(problem)
        rank, problem = next(((r, p) for r, p in enumerate(found) if p), (0, None))
        if problem and rank != 0:
            problem += f" (on rank {rank})"
    if problem and _rank() == 0:
        _say(problem)
    return problem is not None


# ----------------------------------------------------------------------------- the run
def _run(scene, out: str, args: argparse.Namespace) -> int:
    """Build and run the simulation; an error ends every rank (see the module docstring)."""
    from mpi4py import MPI

    from fabric_fenicsx.impact.simulation import ImpactSimulation

    comm = MPI.COMM_WORLD
    side = comm.Dup() if comm.size > 1 else None  # only failing ranks use it
    sim = None
    try:
        sim = ImpactSimulation(scene, out, comm, verbose=not args.quiet)
        summary = sim.run()
        sim.output.close()
    except Exception as err:  # noqa: BLE001 -- every error must end every rank
        return _stopped(err, sim, comm, side, out)
    if comm.rank == 0:
        keys = ("v0", "residual_velocity", "perforated", "absorbed_energy", "max_deflection",
                "energy_error", "end_reason", "n_steps", "wall_time_s")
        print(json.dumps({k: summary[k] for k in keys}, indent=1))
        print(f"{PROG}: output in {os.path.abspath(out)}")
    return 0


def _stopped(err: Exception, sim, comm, side, out: str) -> int:
    """Report ``err`` once and end: every rank together when all failed, else MPI_Abort."""
    message = _describe(err, out)
    if side is None:
        if message is None:
            raise err
        _close(sim)
        _say(message)
        return 1
    if message is None:
        traceback.print_exc()
        message = f"internal error (a bug): {type(err).__name__}: {err}"
    if _all_failed(side):
        from mpi4py import MPI

        if side.allreduce(sim is not None, op=MPI.LAND):
            _close(sim)
        if comm.rank == 0:
            _say(message)
        return 1
    _say(f"{message} (on rank {comm.rank} of {comm.size}; ending every rank)")
    sys.stdout.flush()
    comm.Abort(1)
    return 1  # not reached


def _describe(err: Exception, out: str) -> str | None:
    """The one-line message of an expected error; None for an unexpected one (a bug: its
    traceback is shown)."""
    from fabric_fenicsx.impact.scene import InputError
    from fabric_fenicsx.impact.simulation import ImpactError

    if isinstance(err, (ImpactError, InputError)):
        return str(err)
    if isinstance(err, OSError):
        where = f" ({err.filename})" if err.filename else ""
        return (f"output: a file could not be written or read{where}: {err.strerror or err}; what was "
                f"written to {out} so far is kept")
    return None


def _all_failed(side, seconds: float = AGREE_SECONDS) -> bool:
    """Whether every rank reaches this point within ``seconds`` (a barrier on ``side``, a
    communicator only failing ranks use, so it cannot mix with the run's collectives)."""
    request = side.Ibarrier()
    t0 = time.monotonic()
    while time.monotonic() - t0 < seconds:
        if request.Test():
            return True
        time.sleep(0.01)
    return False


def _close(sim) -> None:
    """Close the output files after an error (collective: only when every rank is here); an
    output that cannot be flushed (a full disk) is left as it is."""
    if sim is not None:
        try:
            sim.output.close()
        except OSError:
            pass
