"""``fabric-fenicsx impact SCENE --out DIR [--set section.key=value ...]``: one ballistic impact
(thesis chapter 4). Run in parallel with ``mpirun -n N fabric-fenicsx impact ...``.

Nothing heavy is imported at module level: the scene is validated (and any error reported)
before DOLFINx is loaded.
"""

from __future__ import annotations

import argparse
import json
import os
import sys


def _rank() -> int:
    """MPI rank from the launcher's environment, without importing MPI."""
    for var in ("OMPI_COMM_WORLD_RANK", "PMI_RANK", "PMIX_RANK", "MV2_COMM_WORLD_RANK"):
        if var in os.environ:
            try:
                return int(os.environ[var])
            except ValueError:
                pass
    return 0


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
                        help="validate the scene, print it with every default filled in, and stop")
    parser.add_argument("--quiet", action="store_true", help="no progress lines")


def run(args: argparse.Namespace) -> int:
    from fabric_fenicsx.impact.scene import SceneError, load_scene

    try:
        scene = load_scene(args.scene, args.overrides)
    except SceneError as err:
        if _rank() == 0:
            print(f"fabric-fenicsx impact: {err}", file=sys.stderr)
        return 2
    if args.check:
        if _rank() == 0:
            print(json.dumps({"source": scene.source, **scene.to_dict()}, indent=1))
        return 0
    out = args.out or os.path.join("out", f"impact-{scene.name}")

    from fabric_fenicsx.impact.simulation import ImpactError, run_impact

    try:
        summary = run_impact(scene, out, verbose=not args.quiet)
    except ImpactError as err:
        print(f"fabric-fenicsx impact: {err}", file=sys.stderr)
        return 1
    if _rank() == 0:
        keys = ("v0", "residual_velocity", "perforated", "absorbed_energy", "max_deflection",
                "energy_error", "end_reason", "n_steps", "wall_time_s")
        print(json.dumps({k: summary[k] for k in keys}, indent=1))
        print(f"fabric-fenicsx impact: output in {os.path.abspath(out)}")
    return 0
