"""``fabric-fenicsx ladder SCENE``: error against run time of the impact statistics
(:mod:`fabric_fenicsx.studies.ladder`).

On every rung (a mesh family at a size, and each ``--variant`` of a numerical knob at
``--variant-size``) the command estimates V50 as ``fabric-fenicsx v50`` does (``--ci``,
``--max-runs``, ``--bracket``) and the mean residual velocity at ``--velocity`` over
``--members`` members as ``fabric-fenicsx ensemble`` does (seeds of the strength scatter, or
without one the velocity changed by k x 1e-12). Rungs run one after the other, each with
``--jobs`` runs at a time (``--scheduler``: on a dask cluster). Writes OUT/<rung>/v50 and
OUT/<rung>/members (every run's folder; stored runs are reused, so an interrupted ladder
resumes), and OUT/ladder.csv (a row per rung as it ends), OUT/ladder.json (rows, each size's
error against its family's finest, the families' differences, the variants' changes, the
recommended size, the runs and core-hours an interval of 2 and of 1 m/s would take),
OUT/ladder.md and OUT/ladder.png (error against core-hours).
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

PROG = "fabric-fenicsx ladder"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from fabric_fenicsx.cli.v50 import add_estimate_arguments

    add_estimate_arguments(parser, "ladder")
    parser.add_argument("--sizes", default="0.004,0.002,0.00141",
                        help="mesh sizes at the impact point, mesh.h_centre in m (default 0.004,0.002,0.00141)")
    parser.add_argument("--families", default="graded,aligned", help="mesh families, mesh.kind (default graded,aligned)")
    parser.add_argument("--variant", dest="variants", action="append", default=[], metavar="SECTION.KEY=VALUE",
                        help="a variant of a numerical knob, run in every family at --variant-size (repeatable; "
                             "e.g. run.damping=0.05)")
    parser.add_argument("--variant-size", type=float, default=None,
                        help="the size of the variants' rungs (m; default the scene's mesh.h_centre, which must be "
                             "one of --sizes)")
    parser.add_argument("--members", type=int, default=12,
                        help="members of the residual-velocity ensemble of each rung (default 12)")
    parser.add_argument("--velocity", type=float, default=None,
                        help="impact velocity of the ensembles (m/s; default the scene's)")
    parser.add_argument("--quiet", action="store_true", help="no line per rung")
    from fabric_fenicsx.cli._guarded import add_scheduler_argument

    add_scheduler_argument(parser, "runs")


def _parse(args) -> tuple[list, list, tuple, list[str]]:
    """(families, sizes, bracket, problems) from the arguments."""
    from fabric_fenicsx.cli._checks import parse_bracket, positive_problem
    from fabric_fenicsx.cli.v50 import estimate_problems

    problems = estimate_problems(args)
    families = [f.strip() for f in args.families.split(",") if f.strip()]
    try:
        given = [float(s) for s in args.sizes.split(",")]
        sizes = sorted(set(given), reverse=True)
        if not sizes or not all(0 < s < float("inf") for s in sizes):
            raise ValueError
    except ValueError:
        problems.append(f"--sizes must be positive sizes in m separated by commas, got {args.sizes!r}")
        given = sizes = []
    if not families:
        problems.append("--families names no family")
    for option, items in (("--families", families), ("--sizes", given), ("--variant", args.variants)):
        twice = sorted({str(x) for x in items if items.count(x) > 1})
        if twice:
            problems.append(f"{option} names {', '.join(twice)} more than once (each rung once)")
    if args.members < 2:
        problems.append(f"--members must be at least 2 (an interval needs two), got {args.members}")
    if any("=" not in v for v in args.variants):
        problems.append(f"--variant must be SECTION.KEY=VALUE, got {args.variants!r}")
    problems += [p for p in (positive_problem("--velocity", args.velocity, "m/s"),
                             positive_problem("--variant-size", args.variant_size, "m")) if p]
    bracket = (20.0, 60.0) if any(p.startswith("--bracket") for p in problems) else parse_bracket(args.bracket)
    return families, sizes, bracket, problems


def _given(value, default):
    """``value`` where the option was given (0 included: the checks refuse it), else ``default``."""
    return default if value is None else value


def run(args: argparse.Namespace) -> int:
    from fabric_fenicsx.cli._checks import out_problem
    from fabric_fenicsx.cli.impact import _size
    from fabric_fenicsx.impact.scene import InputError, load_scene
    from fabric_fenicsx.studies.ladder import rungs

    if _size() > 1:
        print(f"{PROG}: the runs are processes of their own; run it without mpirun", file=sys.stderr)
        return 2
    families, sizes, bracket, problems = _parse(args)
    try:
        if problems:
            raise ValueError("; ".join(problems))
        scene = load_scene(args.scene, args.overrides)
        velocity = [f"projectile.velocity={args.velocity!r}"] if args.velocity is not None else []
        ladder = rungs(families, sizes, args.variants, _given(args.variant_size, scene.mesh.h_centre))
        for r in ladder:          # every rung's settings are valid before the first run
            load_scene(args.scene, [*args.overrides, *r.overrides(), *velocity])
        out = Path(args.out or Path("out") / f"ladder-{scene.name}")
        problem = out_problem(args.out if args.out is not None else out)
        if problem:
            raise ValueError(problem)
    except (InputError, ValueError) as err:
        print(f"{PROG}: {err}", file=sys.stderr)
        return 2
    from fabric_fenicsx.cli._guarded import guarded

    return guarded(PROG, out, "ladder", scene.name, lambda: _open(args, scene, out, ladder, bracket),
                   "its complete runs are reused")


def _open(args, scene, out: Path, ladder, bracket) -> int:
    from fabric_fenicsx.studies.executor import make_executor

    with make_executor(args.scheduler) as executor:
        executor.check_shared(out, [args.scene, *([scene.fabric.file] if scene.fabric.file else [])])
        return _ladder(args, scene, out, ladder, bracket, executor)


def _ladder(args, scene, out: Path, ladder, bracket, executor) -> int:
    from fabric_fenicsx.cli._checks import memory_jobs
    from fabric_fenicsx.impact.scene import load_scene
    from fabric_fenicsx.studies import ensemble, v50
    from fabric_fenicsx.studies import ladder as study
    from fabric_fenicsx.studies.neyer import NeyerDesign
    from fabric_fenicsx.studies.runpool import write_atomic

    scenes = [load_scene(args.scene, [*args.overrides, *r.overrides()]) for r in ladder]
    jobs = memory_jobs(args.jobs or executor.slots, scenes, lambda line: print(f"{PROG}: {line}", flush=True),
                       args.scheduler)
    first_seed = None if scene.material.scatter == "none" else scene.material.seed
    velocity = _given(args.velocity, scene.projectile.velocity)
    say = (lambda line: None) if args.quiet else (lambda line: print(line, flush=True))
    say(f"{PROG}: {scene.name}, {len(ladder)} rungs ({', '.join(r.key for r in ladder)}), V50 to {args.ci:g} m/s or "
        f"{args.max_runs} runs and {args.members} members at {velocity:g} m/s each, {jobs} runs at a time, into {out}")
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.monotonic()
    rows = []
    for i, rung in enumerate(ladder):
        overrides = [*args.overrides, *rung.overrides()]
        folder = out / rung.key
        estimate = v50.estimate(args.scene, overrides, folder / "v50", NeyerDesign(*bracket), ci=args.ci,
                                max_runs=args.max_runs, jobs=jobs, first_seed=None if first_seed is None else 1,
                                executor=executor)
        folder.mkdir(parents=True, exist_ok=True)
        v50.write_table(folder / "v50" / "v50.csv", estimate["rows"])
        members = ensemble.run_members(args.scene, overrides, velocity, args.members, folder / "members", jobs=jobs,
                                       executor=executor, first_seed=first_seed)
        rows.append(study.measure(rung, estimate["rows"], estimate["stop"], members))
        _write_table(out / "ladder.csv", rows)
        r = rows[-1]
        say(f"rung {i + 1}/{len(ladder)} {rung.key}: V50 {_est(r, 'v50')} ({r['v50_runs']} runs), mean residual "
            f"{_est(r, 'residual_velocity')} ({r['residual_velocity_runs']} members); "
            f"{time.monotonic() - t0:.0f} s elapsed")
    analysis = study.analyse(rows)
    best = study.recommend(analysis)
    report = {"scene": str(args.scene), "overrides": list(args.overrides), "velocity": velocity,
              "members": args.members, "ci_target": args.ci, "max_runs": args.max_runs, "rows": rows, **analysis,
              "recommended_size": best, "cost": {f"{w:g}": study.runs_for(w, rows) for w in (2.0, 1.0)},
              "wall_time_s": time.monotonic() - t0}
    write_atomic(out / "ladder.json", json.dumps(report, indent=1))
    text = _markdown(report, scene.name)
    write_atomic(out / "ladder.md", text)
    study.plot(analysis, out / "ladder.png", title=f"{scene.name}: error against run time")
    print(text)
    print(f"report in {out / 'ladder.md'}, {out / 'ladder.json'}, plot {out / 'ladder.png'}")
    return 0


def _est(row: dict, stat: str) -> str:
    from fabric_fenicsx.studies.v50 import format_interval

    if stat == "v50" and row.get("v50_kind") == "none in range":
        return (f"no limit in its range: every counted run held, up to {row['v50_lo']:.2f} m/s" if row["v50_hi"] is None
                else f"no limit in its range: every counted run went through, from {row['v50_hi']:.2f} m/s")
    if row[stat] is None:
        return "no estimate"
    if stat == "v50" and row.get("v50_kind") == "bracket":
        sharp = str(row.get("v50_stop", "")).startswith("a sharp limit")
        return (f"{'sharp' if sharp else 'bracket, not narrowed to a sharp limit'}: held at {row['v50_lo']:.2f}, "
                f"through at {row['v50_hi']:.2f}")
    return f"{row[stat]:.2f} m/s {format_interval((row[f'{stat}_lo'], row[f'{stat}_hi']))}"


def _write_table(path: Path, rows: list[dict]) -> None:
    import csv
    import io

    from fabric_fenicsx.studies.runpool import write_atomic

    text = io.StringIO()
    writer = csv.DictWriter(text, fieldnames=list(rows[0]), lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    write_atomic(path, text.getvalue())


def _markdown(rep: dict, name: str) -> str:
    """ladder.md: the rungs, each size's error against the finest, the families, the variants,
    the recommended size and what an interval costs."""
    def num(x, digits=2):
        return "-" if x is None else f"{x:.{digits}f}"

    def diff(d):
        if d.get("size") is not None and d.get("size") == d.get("finest"):
            return "reference"
        if d.get("difference") is None:
            return "-"
        agree = {True: "agree", False: "differ", None: "-"}[d.get("agree")]
        return f"{d['difference']:+.2f} +- {num(d.get('half_width'))} ({agree})"

    lines = [f"# Error against run time: {name}", "",
             f"V50 (Neyer's design, probit, 95 % profile-likelihood interval, to {rep['ci_target']:g} m/s or "
             f"{rep['max_runs']} runs) and the mean residual velocity at {rep['velocity']:g} m/s over "
             f"{rep['members']} members (95 % Student-t interval) on every rung; core-h: the runs' solving "
             "(their wall_time_s), process start-up not counted.", "",
             "| rung | V50 (m/s), 95 % | sigma | V50 runs | core-h | mean residual (m/s), 95 % | members | core-h |",
             "|---|---|---|---|---|---|---|---|"]
    for r in rep["rows"]:
        lines.append(f"| {r['rung']} | {_est(r, 'v50')} | {num(r['v50_sigma'])} | {r['v50_runs']} | "
                     f"{r['v50_core_s'] / 3600:.3f} | {_est(r, 'residual_velocity')} | {r['residual_velocity_runs']} | "
                     f"{r['residual_velocity_core_s'] / 3600:.3f} |")
    lines += ["", "Each size against its family's finest (difference +- combined 95 % half-width; *agree*: "
              "within the sum of the two half-widths):", "", "| family | size (mm) | V50 | mean residual |",
              "|---|---|---|---|"]
    errors = rep["errors"]
    for family in dict.fromkeys(e["family"] for e in errors):
        for size in sorted({e["size"] for e in errors if e["family"] == family}, reverse=True):
            at = {e["statistic"]: e for e in errors if e["family"] == family and e["size"] == size}
            lines.append(f"| {family} | {size * 1e3:g} | {diff(at['v50'])} | {diff(at['residual_velocity'])} |")
    if rep["families"]:
        lines += ["", "The families at each size:", "", "| size (mm) | pair | V50 | mean residual |", "|---|---|---|---|"]
        for size in sorted({f["size"] for f in rep["families"]}, reverse=True):
            for pair in dict.fromkeys(f["pair"] for f in rep["families"] if f["size"] == size):
                at = {f["statistic"]: f for f in rep["families"] if f["size"] == size and f["pair"] == pair}
                lines.append(f"| {size * 1e3:g} | {pair} | {diff(at['v50'])} | {diff(at['residual_velocity'])} |")
    if rep["variants"]:
        lines += ["", "Each variant against its rung without it (*within*: the change is smaller than the "
                  "rung's own half-width):", "", "| variant | family | size (mm) | V50 | mean residual |",
                  "|---|---|---|---|---|"]
        for v in dict.fromkeys((x["variant"], x["family"], x["size"]) for x in rep["variants"]):
            at = {x["statistic"]: x for x in rep["variants"] if (x["variant"], x["family"], x["size"]) == v}
            cells = [diff(at[s]) + ("" if at[s].get("within_interval") is None else
                                    ", within" if at[s]["within_interval"] else ", beyond") for s in ("v50", "residual_velocity")]
            lines.append(f"| {v[0]} | {v[1]} | {v[2] * 1e3:g} | {cells[0]} | {cells[1]} |")
    best, finest = rep["recommended_size"], min(e["size"] for e in errors)
    if best is None:
        verdict = "none: the finest size has no interval in some family"
    elif best == finest:
        verdict = (f"none coarser than the finest ({finest * 1e3:g} mm) agrees with it, so this ladder does not show "
                   "convergence: add a finer size")
    else:
        verdict = f"{best * 1e3:g} mm (against the finest, {finest * 1e3:g} mm)"
    lines += ["", "Recommended size (the coarsest whose estimates agree with the finest's in every family, as do "
              "those between): " + verdict, "",
              "What an interval costs (runs scaled from the width each rung reached, as 1 / sqrt(runs)):", "",
              "| rung | statistic | 95 % width (m/s) | runs | core-hours |", "|---|---|---|---|---|"]
    for w, items in rep["cost"].items():
        for c in items:
            lines.append(f"| {c['rung']} | {c['statistic']} | {w} | {c['runs']} | {c['core_hours']:.2f} |")
    return "\n".join(lines) + "\n"
