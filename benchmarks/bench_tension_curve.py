"""Benchmark: the tension field from the force-free curves against the per-point searches (prints numbers; not a test).

Runs a scene twice, once with the wrinkled points' force-free strains searched (Newton to
1e-15 at every point, ``YarnStress.curves = None``, the default) and once read from the
tabulated curves (:class:`fabric_fenicsx.fem.tension_field.ForceFreeCurves`). In both runs every call
of the tension field also computes the other path on the same strains, in alternating order
(A B, B A, ...), and times both: the ratio of their times per step is measured in one process,
interleaved. Then it prints how far the two runs' histories lie apart: the largest difference
of the central deflection and of the contact force over the run, relative to each history's
peak (row by row, and with the curve run's histories interpolated to the search run's row
times: the two runs take different time steps, so their rows are not written at the same
times; over the whole run and up to ``--early``), and the deflections at damage onset (damage on). A third run, the search with the
impact velocity changed by 1e-12 of itself, gives the same differences for a change of
round-off size: the floor under which no change of the model can be told from round-off.

    .venv/bin/python benchmarks/bench_tension_curve.py [--scene demos/scenes/y90.toml] [--set KEY=VALUE ...]

Default: Y90 at 34.5 m/s, damage off, on the scene's mesh (``--set mesh.h_centre=0.004`` for
``make demo``'s).
"""

import argparse
import collections
import csv
import tempfile
import time
from pathlib import Path

import numpy as np

import fabric_fenicsx.fem.tension_field as tension_field
import fabric_fenicsx.fem.yarn_stress as yarn_stress
import fabric_fenicsx.impact.simulation as simulation
from bench_impact import SCENE
from fabric_fenicsx.impact.scene import load_scene

SETTINGS = ["projectile.velocity=34.5", "material.damage=false", "output.png=false",
            "output.progress_interval=0"]
WARM_UP = 10
"""Calls not timed (the first compiles the kernels)."""


def run(scene, path):
    """Run ``scene`` with the tension field's ``path`` ("search" or "curve"), timing both paths
    at every call; returns (summary, history rows, seconds per path, curve build seconds)."""
    seconds, calls, build = collections.defaultdict(float), collections.Counter(), [0.0]
    made = {}
    relaxed = yarn_stress.relaxed_strains
    builder = tension_field.ForceFreeCurves.build

    def timed_build(self, j, segments):
        t0 = time.perf_counter()
        try:
            return builder(self, j, segments)
        finally:
            build[0] += time.perf_counter() - t0

    def both(surrogate, E1, E2, a1, a2, stats=None, guess=None, curves=None):
        if "curves" not in made:
            made["curves"] = tension_field.ForceFreeCurves(surrogate)
        curves = made["curves"]
        order = ["search", "curve"] if calls["calls"] % 2 == 0 else ["curve", "search"]
        result = {}
        for label in order:
            b0 = build[0]
            t0 = time.perf_counter()
            out = relaxed(surrogate, E1, E2, a1, a2, stats if label == path else None, guess,
                          curves if label == "curve" else None)
            if calls["calls"] >= WARM_UP:
                seconds[label] += time.perf_counter() - t0 - (build[0] - b0)
            result[label] = out
        calls["calls"] += 1
        return result[path]

    yarn_stress.relaxed_strains, tension_field.ForceFreeCurves.build = both, timed_build
    try:
        with tempfile.TemporaryDirectory() as out:
            s = simulation.run_impact(scene, out, verbose=False)
            with open(Path(out) / "history.csv") as f:
                rows = list(csv.DictReader(f))
    finally:
        yarn_stress.relaxed_strains, tension_field.ForceFreeCurves.build = relaxed, builder
    return s, rows, seconds, build[0], made["curves"]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default=str(SCENE))
    parser.add_argument("--set", dest="overrides", action="append", default=[])
    parser.add_argument("--early", type=float, default=3e-4,
                        help="also the differences up to this time (s): before the contact's chatter "
                             "has spread round-off")
    args = parser.parse_args()
    scene = load_scene(args.scene, [*SETTINGS, *args.overrides])
    results = {path: run(scene, path) for path in ("search", "curve")}
    velocity = scene.projectile.velocity * (1.0 + 1e-12)
    results["round-off"] = run(load_scene(args.scene, [*SETTINGS, *args.overrides,
                                                       f"projectile.velocity={velocity!r}"]), "search")
    s = results["curve"][0]
    print(f"tension-field benchmark: {scene.source} at {s['v0']:g} m/s, {s['n_cells']} cells, "
          f"damage {'on' if scene.material.damage else 'off'}")
    for path, (s, rows, seconds, build, curves) in results.items():
        n = s["n_steps"]
        print(f"  run with the {path}: {n} steps, end {s['end_reason']}; tension field ms per step: "
              f"search {seconds['search'] / n * 1e3:.4f}, curve {seconds['curve'] / n * 1e3:.4f} "
              f"(curve / search = {seconds['curve'] / seconds['search']:.3f}); curve segments built "
              f"in {build:.2f} s, intervals in use {curves.ok.sum()} of {curves.checked.sum()} "
              f"checked, largest check error {curves.max_error.max():.2e}")
    a = results["search"][1]
    ta = np.array([float(r["time"]) for r in a])
    for other in ("curve", "round-off"):
        b = results[other][1]
        k = min(len(a), len(b))
        tb = np.array([float(r["time"]) for r in b])
        print(f"  search against {other}: rows {len(a)} and {len(b)}, largest difference of the "
              f"rows' times {np.abs(ta[:k] - tb[:k]).max():.3e} s")
        for column in ("central_deflection", "contact_force"):
            x = np.array([float(r[column]) for r in a])
            y = np.array([float(r[column]) for r in b])
            peak = np.abs(x).max()
            raw = np.abs(x[:k] - y[:k]).max() / peak
            inside = (ta >= tb[0]) & (ta <= tb[-1])
            apart = np.abs(x[inside] - np.interp(ta[inside], tb, y)) / peak
            early = apart[ta[inside] <= args.early].max()
            print(f"    {column} (peak {peak:.4g}): largest difference / peak {raw:.2e} row by row, "
                  f"{apart.max():.2e} at the same times, {early:.2e} up to {args.early * 1e3:g} ms")
    onset = [results[p][0].get("damage_onset_deflection") for p in results]
    if None not in onset:
        print("  damage onset deflection (mm): " + ", ".join(
            f"{p} {d * 1e3:.4f}" for p, d in zip(results, onset)))


if __name__ == "__main__":
    main()
