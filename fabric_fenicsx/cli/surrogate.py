"""``fabric-fenicsx surrogate build | report | ship``: tabulate the unit cell, measure its error,
or rewrite the table tiles shipped with the package (:mod:`fabric_fenicsx.surrogate.ship`)."""

from __future__ import annotations

import argparse
import time


def _positive_float(text: str) -> float:
    value = float(text)
    if not value > 0:
        raise argparse.ArgumentTypeError(f"must be positive, got {text}")
    return value


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("action", choices=("build", "report", "ship"),
                        help="build: solve and cache the tables; report: error against direct solves and time; "
                             "ship: solve the tiles shipped with the package again (the tables and tiles its "
                             "shipped/tables.json lists; --fabric, --resolution, ... do not apply)")
    parser.add_argument("--fabric", help="fabric TOML file (default: Zylon AS of the thesis, Table 1)")
    parser.add_argument("--bending", choices=("max", "min"), default="max",
                        help="bending stiffness bound of the Zylon preset (default max)")
    parser.add_argument("--resolution", type=_positive_float, default=0.002,
                        help="grid spacing of E1 and E2 (default 0.002)")
    parser.add_argument("--r-nodes", type=int, default=11, help="nodes in sqrt(alpha_min/alpha_max) (default 11)")
    parser.add_argument("--order", type=int, choices=(1, 3), default=3, help="interpolation order in E (default 3)")
    parser.add_argument("--layers", default="intact,damaged",
                        help="for build: comma-separated layers, intact and/or damaged (default both)")
    parser.add_argument("--E-range", type=float, nargs=2, metavar=("LO", "HI"),
                        help="for build: strain range of both axes (default: the whole table)")
    parser.add_argument("--workers", type=int, help="processes for solving (default: all cores)")
    parser.add_argument("--cache", help="cache folder (default $FABRIC_FENICSX_CACHE or ~/.cache/fabric_fenicsx)")
    parser.add_argument("--out", help="for report: output folder")
    parser.add_argument("--states", type=int, default=300, help="for report: random states (default 300)")
    parser.add_argument("--seed", type=int, default=0, help="for report: random seed (default 0)")
    parser.add_argument("--add-from", action="append", default=[], metavar="CACHE",
                        help="for ship: also ship the tiles this cache folder holds for a shipped "
                             "table (the cache of scene runs started from an empty one); repeatable")
    parser.add_argument("--shipped", metavar="DIR",
                        help="for ship: the folder of shipped tiles (default: the package's)")


def _fabric(args):
    from fabric_fenicsx.material.fabric import Fabric, zylon_as
    return Fabric.load(args.fabric) if args.fabric else zylon_as(args.bending)


def run(args) -> int:
    if args.action == "ship":
        from fabric_fenicsx.surrogate.ship import ship
        t0 = time.perf_counter()
        try:
            rows = ship(args.shipped, args.add_from, workers=args.workers)
        except ValueError as err:
            raise SystemExit(f"surrogate ship: {err}") from None
        total = sum(r["bytes"] for r in rows)
        print(f"shipped {len(rows)} table(s), {total / 1e6:.2f} MB, in {time.perf_counter() - t0:.1f} s")
        return 0
    fabric = _fabric(args)
    if args.action == "build":
        from fabric_fenicsx.surrogate.table import Surrogate
        layers = tuple(x.strip() for x in args.layers.split(",") if x.strip())
        bad = set(layers) - {"intact", "damaged"}
        if bad:
            raise SystemExit(f"unknown layer(s) {sorted(bad)}; valid: intact, damaged")
        sur = Surrogate(fabric, resolution=args.resolution, r_nodes=args.r_nodes, order=args.order,
                        cache_dir=args.cache, workers=args.workers)
        t0 = time.perf_counter()
        rng = tuple(args.E_range) if args.E_range else None
        sur.build(layers, rng, rng)
        print(f"{sur.describe()}\n{sur.solves} unit-cell solves in {time.perf_counter() - t0:.1f} s")
        return 0
    if not args.out:
        raise SystemExit("surrogate report needs --out DIR")
    from fabric_fenicsx.studies.surrogate_report import run_report
    rows = run_report(fabric, args.out, n_states=args.states, seed=args.seed, workers=args.workers)
    print(f"report written to {args.out}/surrogate_report.md ({len(rows)} table settings)")
    return 0
