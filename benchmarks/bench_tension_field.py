"""Benchmark of the tension field (prints numbers; not a test).

What the wrinkling relaxation (fabric_fenicsx.fem.tension_field) costs per explicit step, next to
the surrogate's own constitutive update of the same points: N points with the warp stretched and
the fill compressed (every one a candidate, about half of them wrinkled), the force-free strain
searched from scratch (cold) and from the roots of a step before (warm: strains changed by
1e-5, as in one explicit step of an impact).

    .venv/bin/python benchmarks/bench_tension_field.py [--points 100000]
"""

import argparse
import time

import numpy as np

from fabric_fenicsx.fem.tension_field import RelaxStats, relaxed_strains
from fabric_fenicsx.material.fabric import zylon_as
from fabric_fenicsx.surrogate.table import Surrogate


def best_of(f, repeat=5):
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        f()
        times.append(time.perf_counter() - t0)
    return min(times)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=100_000)
    args = parser.parse_args()
    sur = Surrogate(zylon_as(), progress=False)
    rng = np.random.default_rng(0)
    n = args.points
    E1, E2 = rng.uniform(0.0, 0.04, n), rng.uniform(-0.05, 0.0, n)
    ones = np.ones(n)
    stats = RelaxStats()
    R = relaxed_strains(sur, E1, E2, ones, ones, stats)     # builds the tiles it needs
    print(f"{n} points, warp stretched, fill compressed: {stats.relaxed} wrinkled, "
          f"{stats.no_root} without a force-free strain")
    step1, step2 = E1 + 1e-5, E2 - 1e-5
    t_cold = best_of(lambda: relaxed_strains(sur, step1, step2, ones, ones))
    t_warm = best_of(lambda: relaxed_strains(sur, step1, step2, ones, ones, guess=R))
    t_update = best_of(lambda: sur.update(step1, step2, ones, ones))
    t_lookup = best_of(lambda: sur.lookup(step1, step2, ones, ones, ("P1", "P2")))
    for label, t in (("relaxation, cold start", t_cold), ("relaxation, warm start", t_warm),
                     ("surrogate update (Eq. 2-25 and P)", t_update),
                     ("surrogate look-up of P1, P2", t_lookup)):
        print(f"  {label:36s} {t * 1e3:8.2f} ms  {t / n * 1e9:7.1f} ns/point")
    print(f"  warm relaxation / update: {t_warm / t_update:.2f}; cold / warm: {t_cold / t_warm:.2f}")


if __name__ == "__main__":
    main()
