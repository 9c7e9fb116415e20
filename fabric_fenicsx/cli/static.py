"""``fabric-fenicsx static --scenario NAME [--out DIR] ...``: one static material-point scene of
the thesis, chapter 3 (:mod:`fabric_fenicsx.studies.static`), written as NAME.csv, NAME.json and
NAME.png, its key points printed.

The scene module is imported at module level for its names (scenes, backends, default step);
it imports the unit cell and never DOLFINx.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from fabric_fenicsx.material.fabric import Fabric, zylon_as
from fabric_fenicsx.studies.static import (BACKENDS, DEFAULT_STEP, MAX_STEPS, SCENARIOS, bending_bounds,
                                           check_budget, check_step, format_key_points, plot_scenario,
                                           run_scenario, write_key_points)

PROG = "fabric-fenicsx static"


def _positive_step(text: str) -> float:
    """``--step`` as a float (argparse type), or an error (argparse names the option before it)."""
    try:
        return check_step(text)
    except ValueError as err:
        raise argparse.ArgumentTypeError(str(err)) from None


def _positive_int(text: str) -> int:
    """``--max-steps`` as an integer >= 1 (argparse type)."""
    try:
        n = int(text)
    except ValueError:
        n = 0
    if n < 1:
        raise argparse.ArgumentTypeError(f"must be an integer >= 1, got {text!r}")
    return n


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The options of ``fabric-fenicsx static``."""
    parser.add_argument("--scenario", required=True, choices=SCENARIOS, metavar="NAME",
                        help="one of: " + ", ".join(SCENARIOS))
    parser.add_argument("--out", default="out/static", metavar="DIR",
                        help="output directory, created if missing (default: out/static); "
                             "writes NAME.csv, NAME.png, NAME.json")
    parser.add_argument("--step", type=_positive_step, default=DEFAULT_STEP,
                        help=f"E1 increment (default {DEFAULT_STEP})")
    parser.add_argument("--max-steps", type=_positive_int, default=MAX_STEPS, metavar="N",
                        help=f"refuse a --step whose scene would take more than N steps (material-point "
                             f"solves, about 18 ms each; default {MAX_STEPS:,}, about an hour)")
    parser.add_argument("--fabric", metavar="FILE.toml", help="fabric description (SI units); "
                        "default: Zylon AS of Table 1")
    parser.add_argument("--bending", choices=("max", "min"), default=None,
                        help="bending-stiffness bound of the built-in Zylon AS (default max)")
    parser.add_argument("--via", choices=tuple(BACKENDS), default="unitcell",
                        help="material point: the unit cell (default) or its surrogate")
    parser.add_argument("--quiet", action="store_true", help="no progress on stderr")


def _fabric(args: argparse.Namespace) -> Fabric:
    """The fabric of ``--fabric`` or the built-in Zylon AS at ``--bending`` (not both)."""
    if args.fabric is not None and args.bending is not None:
        raise SystemExit(f"{PROG}: give either --fabric or --bending, not both")
    try:
        return Fabric.load(args.fabric) if args.fabric else zylon_as(args.bending or "max")
    except (OSError, ValueError) as err:
        raise SystemExit(f"{PROG}: cannot read the fabric {args.fabric!r}: {err}") from None


def run(args: argparse.Namespace) -> int:
    """Run the scene, write its CSV, key points (JSON) and plot, and print the key points.
    A step that would take more than ``--max-steps`` steps stops before any work (exit 2)."""
    fabric = _fabric(args)
    try:
        check_budget(args.scenario, fabric, args.step, args.max_steps)
    except ValueError as err:
        print(f"{PROG}: {err}", file=sys.stderr)
        return 2
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    csv_path = out / f"{args.scenario}.csv"
    # The built-in Zylon AS (either --bending preset) takes the Table 1 bounds of B2.
    bounds = bending_bounds(None if args.fabric is None else fabric)
    result = run_scenario(args.scenario, fabric=fabric, step=args.step, backend=args.via,
                          progress=not args.quiet, csv_path=csv_path, fill_B0_bounds=bounds,
                          max_steps=args.max_steps)
    write_key_points(result, out / f"{args.scenario}.json")
    plot_scenario(result, out / f"{args.scenario}.png")
    print(format_key_points(result))
    print(f"wrote {csv_path}, {out / (args.scenario + '.json')}, {out / (args.scenario + '.png')}")
    return 0
