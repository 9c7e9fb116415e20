"""Benchmark: the damage update kernel of a git revision against today's, in one run (prints numbers; not a test).

Runs the scene of benchmarks/bench_impact.py (demos/scenes/y90.toml at 57.3 m/s) with
``fabric_fenicsx.surrogate.kernels.damage.update`` replaced by a wrapper that calls, at every
call of the run, both the kernel of ``--before REV`` (default HEAD: the committed damage and
look-up kernels, compiled from that revision's source) and the working tree's on the same inputs, in alternating order (A B, B A,
...), times each, and checks that both give the same bits (forces, integrities, status and
counts); the run goes on with today's answers. It prints both kernels' time per step and their
ratio, and the number of calls whose answers differed (0 for a change that keeps the answers).
The first calls (WARM_UP) are not timed: they compile both kernels.

    .venv/bin/python benchmarks/bench_damage_update.py [--before REV] [--set KEY=VALUE ...]

``make demo``'s mesh: ``--set mesh.h_centre=0.004``.
"""

import argparse
import collections
import importlib.util
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import fabric_fenicsx.impact.simulation as simulation
import fabric_fenicsx.surrogate.kernels.damage as damage_kernel
from bench_impact import ROOT, SCENE, SETTINGS
from fabric_fenicsx.impact.scene import load_scene

BEFORE = "HEAD"
"""The revision whose kernel is the "before" of the comparison."""
WARM_UP = 10
"""Calls not timed (the first compiles both kernels)."""


def kernel_of(rev: str, folder: Path):
    """``update`` of the damage kernel at git revision ``rev``, with that revision's look-up
    kernel, compiled from their sources written to ``folder``."""
    modules = {}
    for name in ("interp", "damage"):
        source = subprocess.run(["git", "show", f"{rev}:fabric_fenicsx/surrogate/kernels/{name}.py"],
                                cwd=ROOT, check=True, capture_output=True, text=True).stdout
        source = source.replace("from fabric_fenicsx.surrogate.kernels import interp as interp_kernel",
                                "import before_interp as interp_kernel")
        path = folder / f"before_{name}.py"
        path.write_text(source)
        spec = importlib.util.spec_from_file_location(f"before_{name}", path)
        modules[name] = importlib.util.module_from_spec(spec)
        sys.modules[f"before_{name}"] = modules[name]
        spec.loader.exec_module(modules[name])
    return modules["damage"].update


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default=str(SCENE))
    parser.add_argument("--before", default=BEFORE)
    parser.add_argument("--set", dest="overrides", action="append", default=[])
    args = parser.parse_args()
    scene = load_scene(args.scene, [*SETTINGS, *args.overrides])
    seconds, calls, differ = collections.defaultdict(float), collections.Counter(), [0]
    today = damage_kernel.update
    with tempfile.TemporaryDirectory() as folder:
        before = kernel_of(args.before, Path(folder))

        def both(E1, E2, a1, a2, table, spec_P, spec_mu, law, mu_crit, band, floor, tol, P, alpha,
                 residual, status, mu_top=None, margin=0.0):
            outs = {}
            order = (("before", before), ("today", today))
            if calls["calls"] % 2:
                order = order[::-1]
            for label, kernel in order:
                o = (np.empty_like(P), np.empty_like(alpha), np.empty_like(residual),
                     np.empty_like(status))
                t0 = time.perf_counter()
                counts = kernel(E1, E2, a1, a2, table, spec_P, spec_mu, law, mu_crit, band, floor,
                                tol, *o, mu_top, margin)
                if calls["calls"] >= WARM_UP:
                    seconds[label] += time.perf_counter() - t0
                outs[label] = (counts, o)
            calls["calls"] += 1
            (cb, ob), (ct, ot) = outs["before"], outs["today"]
            done = (ot[3] != damage_kernel.NEEDS_TILES) & (ot[3] != damage_kernel.NEEDS_DAMAGED_TILES)
            same = (cb == ct and np.array_equal(ob[3], ot[3])
                    and np.array_equal(ob[0][done].view(np.int64), ot[0][done].view(np.int64))
                    and np.array_equal(ob[1].view(np.int64), ot[1].view(np.int64)))
            differ[0] += not same
            for whole, part in zip((P, alpha, residual, status), ot):
                whole[...] = part
            return ct

        damage_kernel.update = both
        with tempfile.TemporaryDirectory() as out:
            s = simulation.run_impact(scene, out, verbose=False)
    n = s["n_steps"] * (calls["calls"] - WARM_UP) / calls["calls"]  # the steps timed, about
    b, t = seconds["before"] / n * 1e3, seconds["today"] / n * 1e3
    print(f"damage update benchmark: {scene.source} at {s['v0']:g} m/s, {s['n_cells']} cells, "
          f"{s['n_steps']} steps, {calls['calls']} calls, end: {s['end_reason']}")
    print(f"  ms per step: before ({args.before[:12]}) {b:.4f}, today {t:.4f}: today / before "
          f"= {t / b:.3f}; calls whose answers differ: {differ[0]}")


if __name__ == "__main__":
    main()
