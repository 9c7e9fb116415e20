"""``fabric-fenicsx v50 SCENE``: the ballistic limit as ballistic testing estimates it
(:mod:`fabric_fenicsx.studies.v50`).

Runs the scene at velocities chosen by Neyer's sequential D-optimal design, ``--jobs`` runs at a
time (each a new member: a seed of the strength scatter from ``--seeds``, or without a scatter
the velocity changed by i x 1e-12), fits the probability of perforation with a probit model and
stops when V50's 95 % interval is no wider than ``--ci`` m/s or after ``--max-runs`` runs. Prints
V50, V10, V90 and sigma with their profile-likelihood intervals, the observed fraction per
velocity bin, and the Lambert-Jonas fit of the perforating runs' residual velocities. Writes
OUT/v50.csv (a row as each run ends, in run order after each batch), OUT/v50.json, OUT/v50.png
and each run's output (OUT/run_<i>). Run again into the same OUT, it reuses the stored runs and
goes on where it stopped (a larger --max-runs or a smaller --ci goes further). Interrupted or
stopped, it writes v50.csv, v50.json and v50.png from the runs that ended. Every argument and OUT
are checked before any run (one line, exit 2, no folder left); ``--jobs`` is capped to the runs
that fit in the free memory (:func:`fabric_fenicsx.cli._checks.memory_jobs`).
"""
from __future__ import annotations

import argparse
import csv
import json
import sys
import time
from pathlib import Path

PROG = "fabric-fenicsx v50"


def add_estimate_arguments(parser: argparse.ArgumentParser, name: str) -> None:
    """The arguments a command that estimates V50 shares with this one: SCENE, --out (default
    out/``name``-<scene name>), --set, --ci, --max-runs, --jobs, --bracket."""
    parser.add_argument("scene", help="scene TOML file (e.g. demos/scenes/y90.toml)")
    parser.add_argument("--out", default=None, help=f"output folder (default out/{name}-<scene name>)")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="SECTION.KEY=VALUE",
                        help="override a scene key of every run (repeatable)")
    parser.add_argument("--ci", type=float, default=2.0,
                        help="stop when V50's 95 %% interval is no wider than this (m/s, default 2)")
    parser.add_argument("--max-runs", type=int, default=40, help="stop after this many runs (default 40)")
    parser.add_argument("--jobs", type=int, default=None,
                        help="runs at the same time, chosen together (default: the cores, or the cluster's "
                             "worker threads)")
    parser.add_argument("--bracket", default="20,60", metavar="LO,HI",
                        help="where the design starts (m/s, default 20,60); it widens if it must")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_estimate_arguments(parser, "v50")
    parser.add_argument("--resolution", type=float, default=0.01,
                        help="velocities are rounded to this (m/s, default 0.01)")
    parser.add_argument("--seeds", type=int, default=1, metavar="FIRST",
                        help="with a strength scatter, run i is the fabric of seed FIRST + i (default 1)")
    parser.add_argument("--quiet", action="store_true", help="no progress lines")
    from fabric_fenicsx.cli._guarded import add_scheduler_argument

    add_scheduler_argument(parser, "runs")


def estimate_problems(args) -> list[str]:
    """What is wrong with the arguments of :func:`add_estimate_arguments` (and --scheduler)."""
    from fabric_fenicsx.cli._checks import parse_bracket, scene_problem
    from fabric_fenicsx.studies.executor import scheduler_problem

    problems = [p for p in (scene_problem(args.scene),) if p]
    try:
        parse_bracket(args.bracket)
    except ValueError as err:
        problems.append(str(err))
    if not args.ci > 0:
        problems.append(f"--ci must be a width > 0 m/s, got {args.ci}")
    if args.max_runs < 2:
        problems.append(f"--max-runs must be at least 2 (a held and a perforating run), got {args.max_runs}")
    if args.jobs is not None and args.jobs < 1:
        problems.append(f"--jobs must be at least 1, got {args.jobs}")
    if scheduler_problem(args.scheduler):
        problems.append(scheduler_problem(args.scheduler))
    return problems


def _problems(args) -> list[str]:
    problems = estimate_problems(args)
    if not 0 < args.resolution <= 1.0:
        problems.append(f"--resolution must lie in (0, 1] m/s, got {args.resolution}")
    if args.seeds < 0:
        problems.append(f"--seeds must be a seed >= 0, got {args.seeds}")
    return problems


def run(args: argparse.Namespace) -> int:
    from fabric_fenicsx.cli.impact import _size
    from fabric_fenicsx.cli._checks import out_problem
    from fabric_fenicsx.impact.scene import InputError, load_scene

    if _size() > 1:
        print(f"{PROG}: the runs are processes of their own; run it without mpirun", file=sys.stderr)
        return 2
    problems = _problems(args)
    if problems:
        print(f"{PROG}: " + "; ".join(problems), file=sys.stderr)
        return 2
    try:
        scene = load_scene(args.scene, args.overrides)
    except InputError as err:
        print(f"{PROG}: {err}", file=sys.stderr)
        return 2
    out = Path(args.out if args.out is not None else Path("out") / f"v50-{scene.name}")
    problem = out_problem(args.out if args.out is not None else out)
    if problem:
        print(f"{PROG}: {problem}", file=sys.stderr)
        return 2
    from fabric_fenicsx.cli._guarded import guarded

    return guarded(PROG, out, "v50", scene.name, lambda: _open(args, scene, out), "its complete runs are reused")


def _open(args, scene, out: Path) -> int:
    from fabric_fenicsx.studies.executor import make_executor

    with make_executor(args.scheduler) as executor:
        executor.check_shared(out, [args.scene, *([scene.fabric.file] if scene.fabric.file else [])])
        return _estimate(args, scene, out, executor)


def _estimate(args, scene, out: Path, executor) -> int:
    from fabric_fenicsx.cli._checks import memory_jobs
    from fabric_fenicsx.studies import v50
    from fabric_fenicsx.studies.neyer import NeyerDesign

    say = (lambda line: None) if args.quiet else (lambda line: print(line, flush=True))
    lo, hi = (float(x) for x in args.bracket.split(","))
    design = NeyerDesign(lo, hi, resolution=args.resolution)
    jobs = memory_jobs(args.jobs or executor.slots, [scene], lambda line: print(f"{PROG}: {line}", flush=True),
                       args.scheduler)
    first_seed = None if scene.material.scatter == "none" else args.seeds
    out.mkdir(parents=True, exist_ok=True)
    table = out / "v50.csv"
    members = ("round-off twins (velocity x (1 + i 1e-12))" if first_seed is None
               else f"fabrics of seeds {first_seed}, {first_seed + 1}, ... ({scene.material.scatter} scatter)")
    say(f"{PROG}: {scene.name}, Neyer's D-optimal design from {lo:g}-{hi:g} m/s, {jobs} runs at a time, "
        f"until V50's 95 % interval is within {args.ci:g} m/s or {args.max_runs} runs; members are {members}")
    t0 = time.monotonic()
    seen, reused = {}, set()            # every run that ended, by index; the keys of the reused ones

    def on_run(row):
        seen[row["run"]] = row
        with open(table, "a", newline="") as f:
            csv.writer(f, lineterminator="\n").writerow(v50.table_cells(row))
        extra = (f", residual {row['residual_velocity']:.2f} m/s" if row["outcome"] == "perforated" else "")
        how = "stored, reused" if f"run_{row['run']:03d}" in reused else f"{row.get('wall_time_s') or 0:.0f} s"
        say(f"run {row['run']} at {row['velocity']:.2f} m/s: {row['outcome']}{extra}"
            + (f" ({row['error']})" if "error" in row else f" ({row.get('end_reason')}, {how})"))

    def on_batch(rows, fit):
        v50.write_table(table, rows)
        c = {k: sum(r["outcome"] == k for r in rows) for k in ("held", "perforated")}
        state = ("no fit yet" if fit is None else
                 f"V50 {fit.v50:.2f} m/s, 95 % {v50.format_interval(fit.v50_ci)}, width {fit.width:.2f} m/s")
        say(f"v50: {len(rows)} runs ({c['held']} held, {c['perforated']} perforated): {state}; "
            f"{time.monotonic() - t0:.0f} s elapsed")

    def report(rows, stop):
        extra = dict(scene_file=str(args.scene), overrides=list(args.overrides), ci_target=args.ci,
                     max_runs=args.max_runs, jobs=jobs, start_bracket=[lo, hi], first_seed=first_seed,
                     wall_time_s=time.monotonic() - t0)
        return v50.write_report(out, rows, stop, scene.name, extra, reference=v50.thesis_points(scene.name))

    v50.write_table(table, [])
    try:
        result = v50.estimate(args.scene, args.overrides, out, design, ci=args.ci, max_runs=args.max_runs, jobs=jobs,
                              first_seed=first_seed, executor=executor, on_run=on_run, on_batch=on_batch,
                              on_done=lambda run, summary, was: reused.add(run.key) if was else None)
    except BaseException as err:        # the three files describe the runs that ended, then the error goes on
        v50.write_stopped(report, seen, err)
        raise
    rep = report(result["rows"], result["stop"])
    print(v50.format_report(rep))
    print(f"report in {out / 'v50.json'}, runs in {table}, plot {out / 'v50.png'}")
    return 0
