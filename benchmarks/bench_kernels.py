"""Benchmark: how much of an impact step is spent inside compiled kernels (prints numbers; not a test).

Runs the scene of benchmarks/bench_impact.py (demos/scenes/y90.toml at 57.3 m/s on its own 1.41 mm
graded mesh) with every compiled kernel of the step timed: the numba kernels of the surrogate,
the yarn stresses, strains, hourglass forces and stiffness, contact, cell removal and the central
difference, DOLFINx's ``assemble_vector`` and the pass (or ``numpy.take``) that packs its
coefficients. It prints each kernel's time per step and their sum against the whole step. The
sum is the step's floor for any change that keeps these kernels (the same answers to round-off,
DOLFINx's assembly of the weak form): Python around them can be removed, the kernels' own work cannot.

    .venv/bin/python benchmarks/bench_kernels.py [--scene demos/scenes/y90.toml] [--set KEY=VALUE ...]

The kernels are timed by replacing them, by name, in the modules that call them; each timed call
costs about a microsecond more (about 0.02 ms per step here), so the step is a little slower than
in bench_impact.py.
"""

import argparse
import collections
import tempfile
import time

import numpy as np

import fabric_fenicsx.fem.explicit as explicit
import fabric_fenicsx.fem.membrane as membrane
import fabric_fenicsx.fem.packing as packing
import fabric_fenicsx.fem.point_strains as point_strains
import fabric_fenicsx.fem.projectile as projectile
import fabric_fenicsx.fem.terms as terms
import fabric_fenicsx.impact.removal as removal
import fabric_fenicsx.impact.simulation as simulation
import fabric_fenicsx.surrogate.kernels.damage as damage_kernel
import fabric_fenicsx.surrogate.kernels.interp as interp_kernel
import fabric_fenicsx.surrogate.kernels.tension_field as curve_kernel
import fabric_fenicsx.surrogate.kernels.yarn_stress as yarn_stress_kernel
from bench_impact import SCENE, SETTINGS
from fabric_fenicsx.impact.scene import load_scene

KERNELS = [
    (interp_kernel, "zero_force_strain", "tension field: force-free strain searches"),
    (curve_kernel, "relax_on_curve", "tension field: force-free strains from the curves"),
    (interp_kernel, "lookup", "surrogate look-up"),
    (interp_kernel, "lookup_derivatives", "surrogate look-up with slopes (dt checks)"),
    (interp_kernel, "prepare_inputs", "surrogate input checks"),
    (interp_kernel, "record_inputs", "surrogate range statistics"),
    (damage_kernel, "update", "damage update (look-up, Eq. 2-25 iteration)"),
    (yarn_stress_kernel, "stresses", "yarn stresses, slack rule, viscous stress"),
    (yarn_stress_kernel, "new_damage", "damage history"),
    (yarn_stress_kernel, "tension", "yarn tensions (hourglass term)"),
    (yarn_stress_kernel, "slack", "slack masks (dt checks)"),
    (yarn_stress_kernel, "live_inputs", "live points' inputs and peak strains"),
    (yarn_stress_kernel, "put_live", "tension field's strains kept for the next step"),
    (yarn_stress_kernel, "clip", "strains clipped to the table"),
    (yarn_stress_kernel, "keep_given", "strains as given where not relaxed"),
    (curve_kernel, "candidates", "tension field: candidates gathered"),
    (curve_kernel, "place_roots", "tension field: roots put back"),
    (point_strains, "_yarn_strains", "yarn strains at the points"),
    (membrane.fem, "assemble_vector", "DOLFINx assemble_vector (internal force)"),
    (np, "take", "numpy.take (packed coefficients)"),
    (packing, "_pack_columns", "packed coefficients from the Functions' arrays"),
    (terms, "_add_hourglass_forces", "hourglass forces (and energy in history rows)"),
    (terms, "_hourglass_stiffness", "hourglass stiffness per cell"),
    (explicit, "_forces_and_works", "central difference: forces and works"),
    (explicit, "_leapfrog", "central difference: update"),
    (explicit, "_bounded", "central difference: finiteness bound test"),
    (simulation, "near_nodes", "contact: nodes near the projectile"),
    (projectile, "penalty_forces", "contact: penalty and friction"),
    (projectile, "_inside", "contact: nodes inside the solid (cylinder, gap, normal)"),
    (projectile, "_all_finite", "contact: finite positions and velocities"),
    (projectile, "_all_finite_positive", "contact: finite positive masses"),
    (simulation, "count_touching", "contact: touching attached nodes"),
    (removal, "_node_extremes", "end tests: node pass"),
    (simulation, "least", "smallest integrities (reductions)"),
    (removal, "_select", "removal: cells to delete or erode"),
    (removal, "_attach", "removal: fabric still attached to a clamp"),
]


def timed(seconds, calls, owner, name):
    """Replace ``owner.name`` by a wrapper that adds its wall time to ``seconds[name]``."""
    kernel = getattr(owner, name)

    def wrapper(*args, **kwargs):
        t0 = time.perf_counter()
        try:
            return kernel(*args, **kwargs)
        finally:
            seconds[name] += time.perf_counter() - t0
            calls[name] += 1

    setattr(owner, name, wrapper)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default=str(SCENE))
    parser.add_argument("--set", dest="overrides", action="append", default=[])
    args = parser.parse_args()
    scene = load_scene(args.scene, [*SETTINGS, *args.overrides])
    seconds, calls = collections.defaultdict(float), collections.Counter()
    for owner, name, _ in KERNELS:
        timed(seconds, calls, owner, name)
    with tempfile.TemporaryDirectory() as out:
        s = simulation.run_impact(scene, out, verbose=False)
    n = s["n_steps"]
    loop = s["wall_time_s"] - s["time_total_s"]["surrogate_tiles"]
    print(f"kernel benchmark: {scene.source} at {s['v0']:g} m/s, {s['n_cells']} cells, {n} steps, "
          f"end: {s['end_reason']}; the step: {loop / n * 1e3:.3f} ms (run without tile solves / steps)")
    print("  time per step inside compiled kernels (ms, calls per step):")
    for owner, name, label in sorted(KERNELS, key=lambda k: -seconds[k[1]]):
        print(f"    {seconds[name] / n * 1e3:7.4f}  ({calls[name] / n:4.2f})  {label}")
    inside = sum(seconds.values())
    print(f"    {inside / n * 1e3:7.4f}  sum: {inside / loop:.0%} of the step; the rest "
          f"({(loop - inside) / n * 1e3:.3f} ms) is Python and numpy around them")


if __name__ == "__main__":
    main()
