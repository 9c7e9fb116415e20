"""Benchmark of the strength scatter's cost in the constitutive update (prints numbers; not a test).

Runs Y90 at 57.3 m/s on its own mesh with ``material.scatter = weibull`` up to ``--t-end``
(default 1.2 ms: through damage onset and the first broken yarns), keeping the yarn strains of
every ``--every``-th step. Then it replays those strain states, in order, through two fresh
quadrature materials on the same points: the scene's default (no scatter: the fabric's law, the
table without a damage range) and the Weibull field (each point's own law, the table grown to the
field's damage range), alternating the two ``--repeats`` times, and prints the time per update
of each and their ratio (scatter on / off), measured in this one process.

    .venv/bin/python benchmarks/bench_scatter.py [--scene demos/scenes/y90.toml] [--set KEY=VALUE ...]
"""

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from fabric_fenicsx.fem.yarn_stress import YarnStress
from fabric_fenicsx.impact.scene import load_scene
from fabric_fenicsx.impact.simulation import ImpactSimulation
from fabric_fenicsx.surrogate.table import Surrogate

ROOT = Path(__file__).resolve().parents[1]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default=str(ROOT / "demos" / "scenes" / "y90.toml"))
    parser.add_argument("--set", dest="overrides", action="append", default=[])
    parser.add_argument("--t-end", type=float, default=1.2e-3)
    parser.add_argument("--every", type=int, default=5)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    scene = load_scene(args.scene, ["projectile.velocity=57.3", "output.png=false", "output.xdmf_interval=0",
                                    "output.progress_interval=0", "material.scatter=weibull",
                                    f"run.t_end={args.t_end}", *args.overrides])
    with tempfile.TemporaryDirectory() as out:
        sim = ImpactSimulation(scene, out, verbose=False)
        states, update = [], sim.material.update

        def recording(E1, E2, dt=0.0):
            if sim.cd.n_steps % args.every == 0:
                states.append((E1.copy(), E2.copy(), dt))
            return update(E1, E2, dt)

        sim.material.update = recording
        try:
            summary = sim.run()
        finally:
            sim.output.close()
    m = sim.membrane
    plain = Surrogate(sim.fabric, progress=False)
    materials = {"off": lambda: YarnStress(plain, m.quadrature_weights_detJ, True, sim.beta,
                                           straight_modulus=sim.k_straight),
                 "on": lambda: YarnStress(sim.surrogate, m.quadrature_weights_detJ, True, sim.beta,
                                          straight_modulus=sim.k_straight, laws=sim.laws)}
    for make in materials.values():       # warm up: tiles, compiled kernels
        mat = make()
        for E1, E2, dt in states:
            mat.update(E1, E2, dt)
    seconds = {k: [] for k in materials}
    damaged = {}
    for _ in range(args.repeats):
        for name, make in materials.items():
            mat = make()
            t0 = time.perf_counter()
            for E1, E2, dt in states:
                mat.update(E1, E2, dt)
            seconds[name].append((time.perf_counter() - t0) / len(states))
            damaged[name] = int(np.count_nonzero(np.minimum(mat.alpha1, mat.alpha2) < 1.0))
    best = {k: min(v) for k, v in seconds.items()}
    print(f"Y90 at 57.3 m/s, {summary['n_cells']} cells, {len(states)} strain states "
          f"(every {args.every}th step to t = {args.t_end * 1e3:g} ms), best of {args.repeats}:")
    for name in materials:
        print(f"  scatter {name:3s}: {best[name] * 1e3:.3f} ms per constitutive update "
              f"({damaged[name]} points damaged at the end)")
    print(f"ratio scatter on / off: {best['on'] / best['off']:.3f}")


if __name__ == "__main__":
    main()
