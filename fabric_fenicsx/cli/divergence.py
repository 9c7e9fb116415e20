"""``fabric-fenicsx divergence``: is a scene's answer a property of the model, or of round-off?

Runs the scene twice (serially, one after the other), the second time with the impact velocity
changed by ``--perturbation`` of itself (default 1e-12), and prints when the two histories
first differ by 1e-10 ... 1e-2 of each quantity and the exponential rate at which the difference
grew (:mod:`fabric_fenicsx.studies.divergence`); writes divergence.json and each twin's output
(OUT/a, OUT/b). It holds OUT's lock (:mod:`fabric_fenicsx.impact.lock`) from before the first
twin to its end: a second writer into OUT stops at once (exit 2) with a line naming the first.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from fabric_fenicsx.cli import _perturbed

PROG = "fabric-fenicsx divergence"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    _perturbed.add_arguments(parser, "divergence", "both twins")


def run(args: argparse.Namespace) -> int:
    from fabric_fenicsx.impact.scene import InputError, check_output_dir, load_scene
    from fabric_fenicsx.studies import divergence

    from mpi4py import MPI

    if MPI.COMM_WORLD.size > 1:
        if MPI.COMM_WORLD.rank == 0:
            print(f"{PROG}: the twins run serially (their histories are compared step by step); "
                  "run it without mpirun", file=sys.stderr)
        return 2
    p = divergence.PERTURBATION if args.perturbation is None else args.perturbation
    problem = _perturbed.perturbation_problem(p)
    if problem:
        print(f"{PROG}: {problem}", file=sys.stderr)
        return 2
    try:
        scene = load_scene(args.scene, args.overrides)
        v_twin = scene.projectile.velocity * (1.0 + p)
        twin = load_scene(args.scene, [*args.overrides, f"projectile.velocity={v_twin!r}"])
        out = Path(args.out or Path("out") / f"divergence-{scene.name}")
        check_output_dir(str(out))
    except InputError as err:
        print(f"{PROG}: {err}", file=sys.stderr)
        return 2
    from fabric_fenicsx.cli._guarded import guarded

    return guarded(PROG, out, "divergence", scene.name, lambda: _twins(args, scene, twin, out))


def _twins(args: argparse.Namespace, scene, twin, out: Path) -> int:
    from fabric_fenicsx.studies import divergence

    rep, summaries = divergence.run_twins(scene, twin, out, verbose=not args.quiet)
    rep["residual_velocity"] = [s["residual_velocity"] for s in summaries]
    rep["absorbed_energy"] = [s["absorbed_energy"] for s in summaries]
    rep["end_reason"] = [s["end_reason"] for s in summaries]
    (out / "divergence.json").write_text(json.dumps(rep, indent=1))
    print(divergence.format_report(rep))
    print(f"residual velocity {rep['residual_velocity'][0]:.4f} / {rep['residual_velocity'][1]:.4f} m/s, "
          f"absorbed {rep['absorbed_energy'][0]:.3f} / {rep['absorbed_energy'][1]:.3f} J "
          f"({rep['end_reason'][0]} / {rep['end_reason'][1]}); report in {out / 'divergence.json'}")
    return 0
