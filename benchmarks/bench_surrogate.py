"""Benchmark of the unit-cell surrogate (prints numbers; not a test).

Measures, in one run: the default tables' build time on all cores from an empty cache and
their load time from the cache; the constitutive update rate on 1e6 random points (intact,
and with random damage histories); the median direct unit-cell solve; the speed-up.

    .venv/bin/python benchmarks/bench_surrogate.py [--points 1000000] [--workers 2]
"""

import argparse
import os
import tempfile
import time

import numpy as np

from fabric_fenicsx.material.fabric import zylon_as
from fabric_fenicsx.surrogate.table import Surrogate
from fabric_fenicsx.material.unitcell import UnitCell


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=1_000_000)
    parser.add_argument("--workers", type=int, default=len(os.sched_getaffinity(0)))
    args = parser.parse_args()
    fabric = zylon_as()
    with tempfile.TemporaryDirectory() as cache:
        t0 = time.perf_counter()
        sur = Surrogate(fabric, cache_dir=cache, workers=args.workers)
        sur.build()
        t_build = time.perf_counter() - t0
        print(f"default tables ({sur.describe()})")
        print(f"  build, both layers, {args.workers} worker(s): {t_build:.1f} s, {sur.solves} unit-cell solves")
        t0 = time.perf_counter()
        loaded = Surrogate(fabric, cache_dir=cache, progress=False)
        loaded.build()
        t_load = time.perf_counter() - t0
        print(f"  load from cache: {t_load:.3f} s ({loaded.solves} solves)")

        rng = np.random.default_rng(0)
        n = args.points
        E1 = rng.uniform(0.0, 0.045, n)
        E2 = rng.uniform(-0.01, 0.04, n)
        ones = np.ones(n)
        # States an explicit step meets: most points below damage onset, the others at the
        # damage their history left (alpha converged at these strains), a few loading further.
        _, _, a1c, a2c = loaded.update(E1, E2, ones, ones)
        below = (rng.uniform(0.0, 0.02, n), rng.uniform(-0.01, 0.02, n))
        cases = (("intact, strains below damage onset (E in [0, 0.02])", below + (ones, ones)),
                 ("random strains, alpha converged to their history", (E1, E2, a1c, a2c)),
                 ("random strains, intact history (first loading: every damaging point iterates)",
                  (E1, E2, ones, ones)),
                 ("random strains, random damage histories in [0.25, 1]",
                  (E1, E2, rng.uniform(0.25, 1.0, n), rng.uniform(0.25, 1.0, n))))
        timings = {}
        for label, state in cases:
            best = np.inf
            for _ in range(3):
                t0 = time.perf_counter()
                loaded.update(*state)
                best = min(best, time.perf_counter() - t0)
            timings[label] = best
            print(f"  update on {n} points, {label}: {best:.3f} s = {n / best:.3g} points/s (one core), "
                  f"{loaded.last_damaging} points iterated")

    cell = UnitCell(fabric)
    times = []
    for E in np.arange(0.0, 0.045, 0.00015):
        t0 = time.perf_counter()
        cell.solve(float(E), 0.01)
        times.append(time.perf_counter() - t0)
    t_direct = float(np.median(times))
    print(f"direct unit-cell solve (warm-started along a path): median {t_direct * 1e3:.3f} ms")
    for label, t in timings.items():
        print(f"speed-up of the update over a direct solve, {label}: {t_direct / (t / n):.0f} x")


if __name__ == "__main__":
    main()
