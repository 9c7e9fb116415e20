"""Benchmark of the impact driver (prints numbers; not a test).

Runs demos/scenes/y90.toml at 57.3 m/s on its own 1.41 mm graded mesh (``make demo`` uses 4 mm:
``--set mesh.h_centre=0.004``) and
prints the time per step split into strain evaluation, constitutive update (the surrogate),
assembly of the internal force, contact, output and the rest, and the total wall time. Table
tiles the surrogate had to solve (a cold cache) are shown apart: they are a one-off cost.

    .venv/bin/python benchmarks/bench_impact.py [--scene demos/scenes/y90.toml] [--set KEY=VALUE ...]
        [--reference KEY=VALUE ...]

Then it times, in the same process and on the same mesh, the floor (benchmarks/floor_step.py):
a minimal compiled explicit step of a membrane with the same cells and quadrature points, linear
yarns, and prints the ratio product step / floor step, the figure the speed work moves.

With ``--reference`` the same scene also runs with those keys changed (for example the settings
before the reduced element, docs/mesh_independence.md: ``--reference mesh.element=full --reference mesh.kind=graded --reference
mesh.h_centre=1.41e-3``), and the ratio of the two runs' wall times (without surrogate tile
solves) is printed, both measured in this one process.
"""

import argparse
import tempfile
import time
from pathlib import Path

from mpi4py import MPI

from floor_step import floor_seconds_per_step

from fabric_fenicsx.impact.simulation import ImpactSimulation
from fabric_fenicsx.impact.scene import load_scene

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "demos" / "scenes" / "y90.toml"
SETTINGS = ["projectile.velocity=57.3", "output.png=false", "output.progress_interval=0"]
"""The benchmarked scene and the keys every benchmark run sets."""


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default=str(SCENE))
    parser.add_argument("--set", dest="overrides", action="append", default=[])
    parser.add_argument("--reference", action="append", default=[],
                        help="also run with these keys changed and print the wall-time ratio")
    args = parser.parse_args()
    s = bench(load_scene(args.scene, [*SETTINGS, *args.overrides]))
    if args.reference:
        r = bench(load_scene(args.scene, [*SETTINGS, *args.overrides, *args.reference]))
        if MPI.COMM_WORLD.rank == 0:
            run, ref = (x["wall_time_s"] - x["time_total_s"]["surrogate_tiles"] for x in (s, r))
            print(f"ratio of run times (without tile solves): {run:.1f} s / {ref:.1f} s = "
                  f"{run / ref:.2f} x the reference {args.reference}")


def bench(scene):
    """Run ``scene`` in a temporary folder and print its timings; return its summary."""
    with tempfile.TemporaryDirectory() as out:
        t0 = time.perf_counter()
        sim = ImpactSimulation(scene, out, verbose=False)
        try:
            s = sim.run()
        finally:
            sim.output.close()
        total = time.perf_counter() - t0
        floor = (floor_seconds_per_step(sim.membrane, sim.cd.mass, sim.k_straight, s["dt"])
                 if MPI.COMM_WORLD.size == 1 else None)
    if MPI.COMM_WORLD.rank:
        return s
    per = s["time_per_step_s"]
    tiles = s["time_total_s"]["surrogate_tiles"]
    print(f"impact benchmark: {scene.source} at {s['v0']:g} m/s, {s['n_cells']} cells, "
          f"{s['n_ranks']} rank(s), {s['n_steps']} steps, end: {s['end_reason']} at "
          f"{s['end_time'] * 1e6:.1f} us")
    print("  time per step (ms):")
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
    print(f"    {1e3 * step_sum:8.3f}  total per step ({1 / step_sum:.0f} steps/s, "
          f"{1e6 * step_sum / s['n_cells']:.2f} us per cell)")
    if floor is not None:
        print(f"  floor: a minimal compiled step of the same mesh ({s['n_cells']} cells, linear yarns, "
              f"benchmarks/floor_step.py) {1e3 * floor:.4f} ms; product / floor = {step_sum / floor:.0f}")
    ours, dolfinx = per["constitutive"] + per["contact"], per["strain"] + per["assembly"]
    print(f"  target: constitutive + contact {1e3 * ours:.3f} ms against strain + assembly "
          f"(DOLFINx) {1e3 * dolfinx:.3f} ms: ratio {ours / dolfinx:.2f} (target <= 1)")
    print(f"  surrogate tiles solved during the run: {tiles:.1f} s ({s['surrogate']['solves_this_run']} solves)")
    print(f"  run {s['wall_time_s']:.1f} s, set-up {s['build_time_s']:.1f} s, total {total:.1f} s")
    print(f"  result: residual velocity {s['residual_velocity']:.2f} m/s, absorbed {s['absorbed_energy']:.2f} J, "
          f"energy error {s['energy_error']:.2e}")
    return s


if __name__ == "__main__":
    main()
