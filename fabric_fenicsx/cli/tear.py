"""``fabric-fenicsx study tear``: the tear test (:mod:`fabric_fenicsx.studies.tear`).

A 60 mm panel with a 10 mm slit across the warp (``--notch edge``, from the bottom edge, or
``centre``), pulled along the warp at 5 m/s until the tear runs through, on each mesh family
(``--families``, default aligned,structured30,structured45,graded; ``file`` with
``--mesh-file``) and cell size (``--sizes`` in m, default 0.002,0.001): without scatter, and
with ``--members N`` also N - 1 seeds of ``--scatter``, or with ``--scatter none`` N - 1
round-off twins (the pull speed changed by k x 1e-12 of itself: after damage a pull is a draw).
Writes OUT/tear.csv (a row per pull as it ends; a study run again with the same setup skips the pulls it holds, one with another setup
is refused: OUT/tear-setup.json), OUT/tear-<family>-<size>.npz (each
mesh's final cells, for the picture), OUT/tear.json and OUT/tear.png, and prints the families
compared at each size: the panels without scatter, and with members each family's means over
its members with 95 % intervals and the paired differences (a seed is the same fabric on every
mesh). ``--hourglass`` sets the reduced element's hourglass control (``membrane.hourglass`` of
the scenes): after a crack it carries the load past the slit's tip, so the tear load on a grid
along the yarns moves with it (docs/tear_test.md).
"""
from __future__ import annotations

import argparse
import csv
import json
import math
import sys
import time
from pathlib import Path

PROG = "fabric-fenicsx study tear"
DEFAULT_FAMILIES = "aligned,structured30,structured45,graded"
DEFAULT_SIZES = "0.002,0.001"


def _plan(args: argparse.Namespace) -> tuple[list[tuple[str, float]], list[str]]:
    """The meshes (family, size) to pull and the problems with the arguments (none: [])."""
    from fabric_fenicsx.studies.tear import parse_family

    problems = []
    try:
        sizes = [float(s) for s in (args.sizes or DEFAULT_SIZES).split(",")]
    except ValueError:
        return [], [f"--sizes must be cell sizes in m separated by commas, got {args.sizes!r}"]
    if not all(math.isfinite(h) and 0.0002 <= h <= 0.005 for h in sizes):
        problems.append(f"--sizes must lie in [0.0002, 0.005] m, got {sizes}")
    families = [f.strip() for f in (args.families or DEFAULT_FAMILIES).split(",")]
    for f in families:
        try:
            parse_family(f)
        except ValueError as err:
            problems.append(str(err))
    if len(set(families)) != len(families) or len(set(sizes)) != len(sizes):
        problems.append("--families and --sizes must not repeat a value")
    mesh_file = getattr(args, "mesh_file", None)
    if "file" in families and not (mesh_file and Path(mesh_file).is_file()):
        problems.append(f"family 'file' needs --mesh-file naming a gmsh .msh file, got {mesh_file!r}")
    if args.members < 1:
        problems.append(f"--members must be >= 1, got {args.members}")
    return [(f, h) for h in sizes for f in families], problems


def _done(path: Path) -> list[dict]:
    """The rows of tear.csv already written (numbers as floats)."""
    if not path.exists():
        return []
    with open(path) as f:
        rows = list(csv.DictReader(f))
    text = ("family", "notch", "end")
    return [{k: (v if k in text else float(v)) for k, v in r.items()} for r in rows]


def _csv_row(r: dict, columns) -> list[str]:
    """A tear.csv row: text as it is, numbers to ten digits, a column the row lacks as nan."""
    return [r[c] if isinstance(r.get(c), str) else f"{r.get(c, math.nan):.10g}" for c in columns]


def _upgrade(table: Path, rows: list[dict]) -> None:
    """Rewrite ``table`` with today's columns if it was written with others (an older version's:
    the columns it lacks read as nan), so that new rows can be appended to it."""
    from fabric_fenicsx.studies.tear_report import COLUMNS

    with open(table) as f:
        header = next(csv.reader(f), None)
    if header is not None and tuple(header) == COLUMNS:
        return
    with open(table, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(COLUMNS)
        w.writerows(_csv_row(r, COLUMNS) for r in rows)


def run(args: argparse.Namespace) -> int:
    from fabric_fenicsx.cli._checks import out_problem
    from fabric_fenicsx.studies import tear

    plan, problems = _plan(args)
    try:
        setup = tear.TearSetup(notch=getattr(args, "notch", "edge"), grips=getattr(args, "grips", "clamped"),
                               failure=getattr(args, "failure", "thesis"),
                               failure_length=getattr(args, "failure_length", 0.0),
                               slit_cut=getattr(args, "slit_cut", "cells"),
                               hourglass=getattr(args, "hourglass", 0.05))
    except ValueError as err:
        problems.append(str(err))
    if args.members > 1 and args.scatter not in ("weibull", "fibrils", "none"):
        problems.append(f"--scatter must be weibull, fibrils or none (round-off twins), got {args.scatter!r}")
    out_wrong = out_problem(args.out if args.out is not None else "out/study-tear")
    if out_wrong:
        problems.append(out_wrong)
    if problems:
        print(f"{PROG}: " + "; ".join(problems), file=sys.stderr)
        return 2
    from fabric_fenicsx.cli._guarded import guarded

    out = Path(args.out if args.out is not None else "out/study-tear")
    return guarded(PROG, out, "study", "tear", lambda: _run(args, plan, setup, out),
                   "the pulls in tear.csv are kept, the others run")


def _run(args, plan, setup, out: Path) -> int:
    import numpy as np

    from fabric_fenicsx.impact.trouble import STEP_ERRORS
    from fabric_fenicsx.material.fabric import zylon_as
    from fabric_fenicsx.material.scatter import DamageRange, StrengthScatter
    from fabric_fenicsx.studies import tear, tear_report
    from fabric_fenicsx.surrogate.table import Surrogate

    notch = setup.notch
    table = out / "tear.csv"
    recorded = out / "tear-setup.json"
    mesh_file = getattr(args, "mesh_file", None)
    twins = args.scatter == "none"
    wanted = json.dumps({**tear.setup_dict(setup), "mesh_file": str(Path(mesh_file).resolve()) if mesh_file else None,
                         "members": "twins" if twins else args.scatter}, sort_keys=True)
    if table.exists() and recorded.exists() and recorded.read_text() != wanted:
        print(f"{PROG}: {out} holds pulls of another setup ({recorded.read_text()}); give another --out",
              file=sys.stderr)
        return 2
    out.mkdir(parents=True, exist_ok=True)
    recorded.write_text(wanted)
    every = _done(table)
    if table.exists():
        _upgrade(table, every)
    rows = [r for r in every if r["notch"] == notch]
    have = {(r["family"], r["h"], int(r["seed"])) for r in rows}
    if not table.exists():
        with open(table, "w", newline="") as f:
            csv.writer(f).writerow(tear_report.COLUMNS)
    fabric = zylon_as()
    seeds = [-1, *range(args.members - 1)]
    t0 = time.perf_counter()
    say = (lambda line: None) if args.quiet else (lambda line: print(line, flush=True))
    say(f"{PROG}: {len(plan)} meshes x {len(seeds)} pull(s), {notch} notch, {setup.failure} rule, "
        f"hourglass control {setup.hourglass:g}, into {out}")
    surrogate = None
    for family, h in plan:
        todo = [s for s in seeds if (family, h, s) not in have]
        if not todo:
            say(f"tear: {family} {h * 1e3:g} mm: reused from {table}")
            continue
        test = tear.TearTest(fabric, family, h, setup, mesh_file=mesh_file)
        laws = {s: None if s < 0 or twins else test.laws(StrengthScatter(args.scatter, seed=s)) for s in todo}
        rng = DamageRange.union(*(test.damage_range(law) for law in laws.values()))
        if surrogate is None or rng is not None:
            surrogate = Surrogate(fabric, progress=False, workers=1, damage_range=rng)
        for seed in todo:
            try:
                r = test.pull(surrogate, laws[seed], progress=lambda line: say(f"  {family} {h * 1e3:g} mm: {line}"),
                              twin=seed + 1 if twins else 0)
            except STEP_ERRORS as err:
                print(f"{PROG}: stopped: {family} {h * 1e3:g} mm, seed {seed}: {type(err).__name__}: {err}; the "
                      f"pulls in {table} are kept", file=sys.stderr)
                return 1
            r["seed"] = seed
            cells = r.pop("cells")
            r.pop("history")
            if seed < 0:
                np.savez_compressed(out / f"tear-{family}-{h * 1e3:g}mm.npz", **cells)
            with open(table, "a", newline="") as f:
                csv.writer(f).writerow(_csv_row(r, tear_report.COLUMNS))
            rows.append(r)
            say(f"tear: {family} {h * 1e3:g} mm seed {seed}: tear load {r['tear_load']:.1f} N, work "
                f"{r['work_per_length']:.2f} J/m, path {r['path_angle']:.1f} deg, {r['end']} "
                f"({r['seconds']:.1f} s; {time.perf_counter() - t0:.0f} s elapsed)")
    rows = [r for r in rows if (r["family"], r["h"]) in set(plan)]
    comparison = tear_report.compare_families(rows)
    members = tear_report.compare_members(rows, twins=twins)
    report = {"setup": tear.setup_dict(setup), "rows": rows, "families_compared": comparison,
              "members_compared": members, "wall_time_s": time.perf_counter() - t0}
    (out / "tear.json").write_text(json.dumps(report, indent=1, default=float))
    cells = {}
    for family, h in plan:
        f = out / f"tear-{family}-{h * 1e3:g}mm.npz"
        if f.exists():
            with np.load(f) as data:
                cells[(family, h)] = {k: data[k] for k in data.files}
    tear_report.plot_paths(cells, out / "tear.png", f"tear paths, {notch} notch (warp along x, pulled along x)")
    print(tear_report.format_report(rows, comparison))
    if members:
        print(tear_report.format_members(members))
    print(f"report in {out / 'tear.json'}, picture {out / 'tear.png'}")
    return 0
