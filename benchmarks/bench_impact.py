"""Benchmark of the impact driver (prints numbers; not a test).

Runs demos/scenes/y90.toml at 57.3 m/s on its own 1.41 mm graded mesh (``make demo`` uses 4 mm:
``--set mesh.h_centre=0.004``) and
prints the time per step split into strain evaluation, constitutive update (the surrogate),
assembly of the internal force, contact, output and the rest, and the total wall time. Table
tiles the surrogate had to solve (a cold cache) are shown apart: they are a one-off cost.

    .venv/bin/python benchmarks/bench_impact.py [--scene demos/scenes/y90.toml] [--set KEY=VALUE ...]
"""

import argparse
import tempfile
import time
from pathlib import Path

from mpi4py import MPI

from fabric_fenicsx.impact.simulation import run_impact
from fabric_fenicsx.impact.scene import load_scene

ROOT = Path(__file__).resolve().parents[1]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default=str(ROOT / "demos" / "scenes" / "y90.toml"))
    parser.add_argument("--set", dest="overrides", action="append", default=[])
    args = parser.parse_args()
    overrides = ["projectile.velocity=57.3", "output.png=false", "output.progress_interval=0",
                 *args.overrides]
    scene = load_scene(args.scene, overrides)
    with tempfile.TemporaryDirectory() as out:
        t0 = time.perf_counter()
        s = run_impact(scene, out, verbose=False)
        total = time.perf_counter() - t0
    if MPI.COMM_WORLD.rank:
        return
    per = s["time_per_step_s"]
    tiles = s["time_total_s"]["surrogate_tiles"]
    print(f"impact benchmark: {scene.source} at {s['v0']:g} m/s, {s['n_cells']} cells, "
          f"{s['n_ranks']} rank(s), {s['n_steps']} steps, end: {s['end_reason']} at "
          f"{s['end_time'] * 1e6:.1f} us")
    print(f"  time per step (ms):")
    labels = {"strain": "strain evaluation (E1, E2 at the Gauss points)",
              "constitutive": "constitutive update (surrogate, damage, damping)",
              "assembly": "assembly of the internal force",
              "contact": "contact (search, penalty, friction)",
              "output": "output (history, XDMF)",
              "integrator": "central-difference update and energy sums",
              "dt_check": "stable time step re-checks (surrogate tangent)",
              "bookkeeping": "deletion, erosion, reductions, projectile, end checks"}
    step_sum = 0.0
    for key, label in labels.items():
        step_sum += per[key]
        print(f"    {1e3 * per[key]:8.3f}  {label}")
    print(f"    {1e3 * step_sum:8.3f}  total per step ({1 / step_sum:.0f} steps/s)")
    ours, dolfinx = per["constitutive"] + per["contact"], per["strain"] + per["assembly"]
    print(f"  target (issue 5): constitutive + contact {1e3 * ours:.3f} ms against strain + assembly "
          f"(DOLFINx) {1e3 * dolfinx:.3f} ms: ratio {ours / dolfinx:.2f} (target <= 1)")
    print(f"  surrogate tiles solved during the run: {tiles:.1f} s ({s['surrogate']['solves_this_run']} solves)")
    print(f"  run {s['wall_time_s']:.1f} s, set-up {s['build_time_s']:.1f} s, total {total:.1f} s")
    print(f"  result: residual velocity {s['residual_velocity']:.2f} m/s, absorbed {s['absorbed_energy']:.2f} J, "
          f"energy error {s['energy_error']:.2e}")


if __name__ == "__main__":
    main()
