"""``fabric-fenicsx study NAME --out DIR [--jobs N] [--scheduler ADDRESS] [--set section.key=value ...]``:
the thesis's chapter 4 as studies (:mod:`fabric_fenicsx.studies.chapter4`).

NAME: table4, table5, table6, friction, fillet, v50 or chapter4 (all of them, and the validation
report), strip (the strength scatter's strip test, :mod:`fabric_fenicsx.cli.strip`) or tear (the tear
test of a slit panel on several mesh families, :mod:`fabric_fenicsx.cli.tear`). The runs are independent ``fabric-fenicsx impact`` processes, ``--jobs`` at a time
(the four scenes' ballistic limits are estimated side by side, sharing them), each into
OUT/runs/<run> (the ballistic limits' runs into OUT/v50/SCENE/run_<i>, with each scene's
v50.csv, v50.json and v50.png: :mod:`fabric_fenicsx.studies.v50`, ``--ci`` and ``--max-runs``
as in ``fabric-fenicsx v50``); a run stored with the same settings and model version is reused, so
an interrupted study resumes. ``--set`` applies to every run. Writes OUT/NAME.md and
OUT/NAME.json; ``chapter4`` also writes the report ``--doc`` (default docs/validation.md).
Unless ``--quiet``, a line per run as it ends and a progress line (runs done of those planned,
time elapsed, about how long is left).

``--scheduler tcp://HOST:8786`` runs the processes on the workers of a dask cluster instead
(``local:N``: a cluster of N workers on this machine; :mod:`fabric_fenicsx.studies.executor`),
``--jobs`` at a time (default: the cluster's worker threads); OUT and the scene files must be on
a file system every worker sees at the same path, which is checked before the first run.

One study at a time in a folder: the study holds OUT's lock (:mod:`fabric_fenicsx.impact.lock`)
from before its first run to its end (also on an error or Ctrl-C); a second study, ensemble or
run into OUT stops at once (exit 2) with a line naming the first. Each run's folder is locked
by its own ``impact`` process. A run's outcome that cannot be recorded, or a disk that fills
up, ends the study with one line (exit 1, no traceback): run it again when there is room, and
it reruns every incomplete run (:mod:`fabric_fenicsx.studies.runpool`). A damage picture is
drawn only when every run it shows is complete; else the report says which runs it lacks.
"""
from __future__ import annotations

import argparse
import json
import shutil
import sys
import time
from pathlib import Path

from fabric_fenicsx.studies.runpool import PoolStopped

PROG = "fabric-fenicsx study"
RUN_OUTPUT = ("output.xdmf_interval=0", "output.progress_interval=0")

"""Every study run writes its history, summary and pictures, but no XDMF (unless --set asks)."""


def _say(line: str, stream=None) -> None:
    """One line at once (the ballistic limits' threads print side by side), flushed."""
    stream = stream or sys.stdout
    stream.write(line + "\n")
    stream.flush()


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from fabric_fenicsx.studies.chapter4 import STUDIES

    parser.add_argument("name", metavar="NAME", help=f"the study: {', '.join(STUDIES)}, strip, tear")
    parser.add_argument("--out", default=None, help="output folder (default out/study-NAME)")
    parser.add_argument("--jobs", type=int, default=None,
                        help="runs at the same time (default: the cores; with --scheduler, the cluster's worker threads)")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="SECTION.KEY=VALUE",
                        help="override a scene key of every run (repeatable)")
    parser.add_argument("--members", type=int, default=1,
                        help="tables, friction, fillet: runs per case, each a new member (a seed of the strength "
                             "scatter, or the velocity changed by k x 1e-12), reported as means with 95 %% intervals "
                             "(default 1); tear: the pull without scatter and N - 1 members of --scatter")
    parser.add_argument("--ci", type=float, default=2.0,
                        help="v50: stop a scene's estimate when V50's 95 %% interval is no wider (m/s, default 2)")
    parser.add_argument("--max-runs", type=int, default=40,
                        help="v50: stop a scene's estimate after this many runs (default 40)")
    parser.add_argument("--doc", default="docs/validation.md", help="chapter4: the report to write")
    parser.add_argument("--quiet", action="store_true", help="no line per run and no progress lines")
    parser.add_argument("--seeds", type=int, default=100, help="strip: seeds of the scatter per mesh (default 100)")
    parser.add_argument("--scatter", default="weibull", help="strip: the scatter model (weibull or fibrils); tear: "
                        "the members' (weibull, fibrils, or none: round-off twins)")
    parser.add_argument("--sizes", default=None, help="strip, tear: cell sizes in m (default 0.002,0.001)")
    parser.add_argument("--families", default=None,
                        help="strip: mesh families (default aligned,free); tear: aligned, graded, structured<deg>, "
                             "file (default aligned,structured30,structured45,graded)")
    parser.add_argument("--notch", default="edge", help="tear: a slit from the bottom edge (edge) or centred (centre)")
    parser.add_argument("--mesh-file", default=None, help="tear: the gmsh .msh file of the family 'file'")
    parser.add_argument("--grips", default="clamped",
                        help="tear: the pulled edges clamped (every component held) or rollers (free along y)")
    parser.add_argument("--failure", default="thesis",
                        help="tear, strip: the failure rule (strip: all but yarn_average): thesis, yarn_crack (a broken yarn tears along the other "
                             "family with one segment's energy), yarn_tip (the yarn crack whose tip runs on "
                             "when its yarn, read along it, reaches its strength), yarn_strain (the same for "
                             "a crack's start too), shear_lag (its tip breaks when its yarn's stretch, raised "
                             "by the load the broken yarns shed (Hedgepeth's factor), reaches its strength), "
                             "del_zone (shear_lag whose crossings slip: the factor at most 2), del_zone_budget "
                             "(del_zone whose cells break with one segment's work per yarn) or yarn_average "
                             "(damage driven by the strain averaged "
                             "along each yarn over --failure-length)")
    parser.add_argument("--failure-length", type=float, default=0.0, help="tear: the yarn average's length (m)")
    parser.add_argument("--slit-cut", default="cells",
                        help="tear: the slit's cells removed (cells) or only their warp yarns cut (warp)")
    parser.add_argument("--hourglass", type=float, default=0.05,
                        help="tear: the reduced element's hourglass control as a fraction of the yarn modulus "
                             "(membrane.hourglass, default 0.05); after a crack it is the main in-plane load "
                             "path between neighbouring yarns (docs/tear_test.md)")
    parser.add_argument("--cell-rule", default="weakest",
                        help="strip: how a cell reads the segments it covers, weakest, patch or yarn (default weakest)")
    parser.add_argument("--crack-band", action="store_true",
                        help="strip: shorten each cell's softening to one segment's (scale l / h)")
    parser.add_argument("--against", default=None, metavar="DIR",
                        help="strip: compare every mesh, fabric by fabric, with the strip study in DIR")
    parser.add_argument("--shear-modulus", type=float, default=0.0,
                        help="strip: isotropic in-plane shear stiffness G (N/m, default 0: the thesis's membrane)")
    from fabric_fenicsx.cli._guarded import add_scheduler_argument

    add_scheduler_argument(parser, "runs")


def _check(args) -> str | None:
    from fabric_fenicsx.cli._checks import doc_problem, out_problem
    from fabric_fenicsx.impact.scene import InputError, load_scene
    from fabric_fenicsx.studies import chapter4
    from fabric_fenicsx.studies.executor import scheduler_problem

    if args.name not in chapter4.STUDIES:
        return f"unknown study {args.name!r}; the studies are {', '.join(chapter4.STUDIES)}, strip, tear"
    if args.jobs is not None and args.jobs < 1:
        return f"--jobs must be at least 1, got {args.jobs}"
    if args.members < 1:
        return f"--members must be at least 1, got {args.members}"
    if not args.ci > 0:
        return f"--ci must be a width > 0 m/s, got {args.ci}"
    if args.max_runs < 2:
        return f"--max-runs must be at least 2 (a held and a perforating run), got {args.max_runs}"
    if scheduler_problem(args.scheduler):
        return scheduler_problem(args.scheduler)
    try:
        for scene in chapter4.SCENES.values():
            load_scene(str(chapter4.SCENE_DIR / scene), [*RUN_OUTPUT, *args.overrides])
    except InputError as err:
        return str(err)
    return out_problem(args.out) or (doc_problem(args.doc) if args.name == "chapter4" else None)


def run(args: argparse.Namespace) -> int:
    from fabric_fenicsx.cli.impact import _size

    if _size() > 1:
        print(f"{PROG}: the runs are processes of their own (--jobs); run it without mpirun", file=sys.stderr)
        return 2
    args.out = str(Path("out") / f"study-{args.name}") if args.out is None else args.out
    if args.name == "tear":
        from fabric_fenicsx.cli import tear

        return tear.run(args)
    if args.name == "strip":
        from fabric_fenicsx.cli import strip

        return strip.run(args)
    problem = _check(args)
    if problem:
        print(f"{PROG}: {problem}", file=sys.stderr)
        return 2
    from fabric_fenicsx.cli._guarded import guarded

    return guarded(PROG, args.out, "study", args.name, lambda: _study(args),
                   "its complete runs are reused, the others run again")


def _study(args) -> int:
    """Open the executor (:func:`~fabric_fenicsx.studies.executor.make_executor`), check that its
    workers see OUT and the scene files, and run the study on it."""
    from fabric_fenicsx.studies import chapter4
    from fabric_fenicsx.studies.executor import make_executor

    t0 = time.perf_counter()
    with make_executor(args.scheduler) as executor:
        scenes = {str(chapter4.SCENE_DIR / s) for s in chapter4.SCENES.values()}
        executor.check_shared(args.out, sorted(scenes))
        return _run_study(args, executor, t0)


def _run_study(args, executor, t0: float) -> int:
    from fabric_fenicsx.studies import chapter4
    from fabric_fenicsx.studies.runpool import Progress, run_all, write_atomic

    from fabric_fenicsx.cli._checks import memory_jobs
    from fabric_fenicsx.impact.scene import load_scene

    out = Path(args.out)
    overrides = (*RUN_OUTPUT, *args.overrides)
    scenes = [load_scene(str(chapter4.SCENE_DIR / s), list(overrides)) for s in chapter4.SCENES.values()]
    jobs = memory_jobs(args.jobs or executor.slots, scenes, lambda line: _say(f"{PROG}: {line}"), args.scheduler)
    runs = chapter4.plan(args.name, overrides, members=args.members)
    where = f", on {executor.description}" if executor.remote else ""
    print(f"{PROG} {args.name}: {len(runs)} runs, {jobs} at a time, into {out / 'runs'}{where}", flush=True)
    counter = Progress("study", "runs", say=None if args.quiet else _say)

    def progress(run, summary, reused):
        if not args.quiet:
            _say(_run_line(run, summary, reused))
        counter.finished(summary, reused)

    wave_run = _wave_run(overrides) if args.name == "chapter4" else None
    counter.expect(len(runs) + (wave_run is not None))
    results = run_all(runs + [wave_run] * (wave_run is not None), out / "runs", jobs=jobs, on_done=progress,
                      executor=executor)
    waves = _wave_speeds(wave_run, results.pop(wave_run.key), out / "runs") if wave_run else {}
    limits = {}
    if args.name in ("v50", "chapter4"):
        limits = _ballistic_limits(overrides, results, out / "v50", jobs, args.ci, args.max_runs, args.quiet,
                                   executor, counter)
    wall = time.perf_counter() - t0
    report = {"study": args.name, "overrides": list(args.overrides), "wall_time_s": wall,
              "runs": results, "v50": limits, "waves": waves}
    write_atomic(out / f"{args.name}.json", json.dumps(report, indent=1, default=str))
    text = _report(args.name, results, limits, waves, overrides, wall, out, args.members)
    write_atomic(out / f"{args.name}.md", text)
    if args.name == "chapter4":
        doc = Path(args.doc)
        doc.parent.mkdir(parents=True, exist_ok=True)
        pictures = doc.parent / doc.stem
        pictures.mkdir(exist_ok=True)
        for png in (out / "pictures").glob("*.png"):
            shutil.copy(png, pictures / png.name)
        write_atomic(doc, text.replace("](pictures/", f"]({pictures.name}/"))
        print(f"{PROG}: wrote {doc}")
    failed = [k for k, s in results.items() if "error" in s]
    failed += [f"{scene}/run_{r['run']:03d}" for scene, rep in limits.items() for r in rep["rows"]
               if r["outcome"] == "failed"]
    n_runs = len(results) + sum(rep["runs"] for rep in limits.values())
    print(f"{PROG} {args.name}: {n_runs - len(failed)} of {n_runs} runs complete, wall time "
          f"{wall / 60:.1f} min; report {out / (args.name + '.md')}")
    return 1 if failed else 0


def _run_line(run, summary: dict, reused: bool) -> str:
    """The line of one run that ended: its residual velocity and absorbed energy, or its error."""
    if "error" in summary:
        return f"  {run.key}: failed ({summary['error']})"
    return (f"  {run.key}: {'stored' if reused else 'done'}, residual {summary['residual_velocity']:.2f} m/s, "
            f"absorbed {summary['absorbed_energy']:.2f} J ({summary['end_reason']})")


def _wave_run(overrides):
    """One short XY0 run whose first stress wave :mod:`fabric_fenicsx.studies.waves` measures."""
    from fabric_fenicsx.studies import chapter4, waves
    from fabric_fenicsx.studies.runpool import Run

    return Run("XY0-waves", str(chapter4.SCENE_DIR / chapter4.SCENES["XY0"]), (*overrides, *waves.RUN_SETTINGS))


def _wave_speeds(run, done: dict, runs_dir: Path) -> dict:
    """The first stress wave's speed along warp and fill (:mod:`fabric_fenicsx.studies.waves`):
    measured on the wave run ``done``, and expected from the unit cell."""
    from fabric_fenicsx.impact.scene import load_scene
    from fabric_fenicsx.impact.setup import build_fabric
    from fabric_fenicsx.studies import waves
    from fabric_fenicsx.surrogate.table import material_point

    if "error" in done:
        return {"error": done["error"]}
    fabric = build_fabric(load_scene(run.scene, list(run.overrides)))
    return {"measured": waves.wave_speeds(runs_dir / run.key), "expected": waves.expected_speeds(material_point(fabric)),
            "wall_time_s": done.get("wall_time_s")}


def _ballistic_limits(overrides, results: dict, v50_dir: Path, jobs: int, ci: float, max_runs: int, quiet: bool,
                      executor=None, counter=None) -> dict:
    """The ballistic limit of each scene as a statistic (:func:`~fabric_fenicsx.studies.v50.estimate`:
    Neyer's design from the bracket :func:`~fabric_fenicsx.studies.chapter4.v50_start` finds in the
    table runs of ``results``, a probit fit, until V50's 95 % interval is within ``ci`` m/s or
    ``max_runs`` runs), each scene into ``v50_dir``/SCENE (run_<i>, v50.csv, v50.json, v50.png),
    the four side by side in threads whose runs share ``jobs`` processes of ``executor``;
    ``counter`` (a :class:`~fabric_fenicsx.studies.runpool.Progress`) is told of each run.
    Returns {scene: :func:`~fabric_fenicsx.studies.v50.report` with ``start``, ``rows`` and
    ``first_seed``}."""
    import csv
    import threading

    from fabric_fenicsx.impact.scene import load_scene
    from fabric_fenicsx.studies import chapter4, v50
    from fabric_fenicsx.studies.neyer import NeyerDesign

    slots = threading.BoundedSemaphore(jobs)
    stop = threading.Event()        # one scene's pool stopped (a full disk): the others stop too
    limits, crashed = {}, {}
    ended = {scene: threading.Event() for scene in chapter4.SCENES}

    def guarded(scene):
        try:
            limits[scene] = estimate(scene)
        except BaseException as err:        # a bug or a stopped pool, not a failed run: raised again below
            crashed[scene] = err
        finally:
            ended[scene].set()

    def estimate(scene):
        path = str(chapter4.SCENE_DIR / chapter4.SCENES[scene])
        first_seed = None if load_scene(path, list(overrides)).material.scatter == "none" else 1
        start = chapter4.v50_start(scene, results)
        out = v50_dir / scene
        out.mkdir(parents=True, exist_ok=True)
        table = out / "v50.csv"
        v50.write_table(table, [])
        seen, reused = {}, set()    # every run that ended, by index; the keys of the reused ones

        def on_run(row):
            seen[row["run"]] = row
            with open(table, "a", newline="") as f:
                csv.writer(f, lineterminator="\n").writerow(v50.table_cells(row))
            if not quiet:
                how = " (stored, reused)" if f"run_{row['run']:03d}" in reused else ""
                _say(f"  {scene} v50 run {row['run']} at {row['velocity']:.2f} m/s: {row['outcome']}"
                     + (f" ({row['error']})" if "error" in row else how))

        def on_done(run, summary, was_reused):
            if was_reused:
                reused.add(run.key)
            if counter is not None:
                counter.finished(summary, was_reused)

        _say(f"{PROG} v50: {scene}, Neyer's design from {start[0]:g}-{start[1]:g} m/s until V50's 95 % interval "
             f"is within {ci:g} m/s or {max_runs} runs, into {out}")
        extra = dict(start=list(start), first_seed=first_seed, ci_target=ci, max_runs=max_runs)

        def write(rows, stop):
            return v50.write_report(out, rows, stop, scene, extra, with_rows=True, reference=v50.thesis_points(scene))
        try:
            result = v50.estimate(path, overrides, out, NeyerDesign(*start), ci=ci, max_runs=max_runs, jobs=jobs,
                                  first_seed=first_seed, executor=executor,
                                  on_run=on_run,
                                  on_batch=lambda rows, fit: v50.write_table(table, rows),
                                  on_start=None if counter is None else counter.expect,
                                  on_done=on_done,
                                  slots=slots, stop=stop)
        except BaseException as err:    # the three files describe the runs that ended, then the error goes on
            v50.write_stopped(write, seen, err)
            raise
        rows = result["rows"]
        rep = write(rows, result["stop"])
        p = rep["probit"]
        _say(f"{PROG} v50: {scene}: " + (f"V50 {p['v50']:.2f} m/s {v50.format_interval(p['v50_ci'])}"
                                         if p else "no probit fit") + f" after {len(rows)} runs ({result['stop']})")
        return {**rep, "rows": rows}

    threads = [threading.Thread(target=guarded, args=(scene,), name=f"v50-{scene}", daemon=True)
               for scene in chapter4.SCENES]
    for t in threads:
        t.start()
    _join(threads, list(ended.values()), stop)
    stopped = [err for err in crashed.values() if isinstance(err, PoolStopped)]
    if stopped:         # the first cause, not the pools that stopped with it
        raise next((e for e in stopped if not str(e).startswith("stopped with")), stopped[0])
    for scene, err in crashed.items():
        raise RuntimeError(f"{PROG} v50: the estimate of {scene} stopped") from err
    return {scene: limits[scene] for scene in chapter4.SCENES}


def _join(threads, ended, stop, grace: float = 30.0) -> None:
    """Wait for the ballistic limits' threads, each of which sets its event of ``ended`` as it
    ends. An interruption (Ctrl-C, SIGTERM) reaches only this thread: it sets ``stop``, so that
    each thread's pool ends its runs (SIGTERM, then SIGKILL) and writes what it has, waits up to
    ``grace`` s for them, then goes on. The events are waited for, not the threads: a
    ``Thread.join`` that an exception interrupts leaves the thread taken for ended."""
    try:
        for event in ended:
            while not event.wait(0.5):
                pass
    except BaseException:
        stop.set()
        deadline = time.monotonic() + grace
        for event in ended:
            event.wait(max(0.0, deadline - time.monotonic()))
        raise
    for t in threads:
        t.join()


def _report(name: str, results: dict, limits: dict, waves: dict, overrides, wall: float, out: Path,
            members: int = 1) -> str:
    from fabric_fenicsx.studies import chapter4
    from fabric_fenicsx.provenance import code_fingerprint

    fp = code_fingerprint()
    names = [s for s in chapter4.STUDIES if s != "chapter4"] if name == "chapter4" else [name]
    every = list(results.values()) + [r for rep in limits.values() for r in rep["rows"]]
    run_wall = sum(s.get("wall_time_s") or 0.0 for s in every) + (waves.get("wall_time_s") or 0.0)
    lines = [f"# The thesis's chapter 4: `fabric-fenicsx study {name}`", "",
             f"Made by `fabric-fenicsx study {name}` in {wall / 60:.1f} min of wall time (stored runs are "
             f"reused: the {len(every)} impact runs' own solving times add up to {run_wall / 60:.1f} min on one "
             f"core each), model version {fp['model_version']}, "
             f"git {fp['git_head']}. Every run: the scene file of demos/scenes as it is, with "
             f"`{' '.join('--set ' + o for o in overrides)}`. Deflections are the central deflection at damage "
             "onset, when the first cell is removed and the largest of the run; the damage reach is the "
             "largest distance from the impact point of a cell with a damaged yarn at the end. "
             + (f"Every case ran as {members} members (the fabrics of {members} seeds of the strength scatter, or "
                "without one the impact velocity changed by k x 1e-12): its numbers are the members' mean +- the 95 % "
                "interval of the mean (n: the members that completed), and a finding is answered from those means "
                "(Welch's test at 95 %: yes, no, or cannot be told apart at these members)." if members > 1 else
                "Each case is one run: after damage one draw of a distribution (docs/mesh_independence.md, sections "
                "9-10); `--members N` runs each N times and answers from means with their intervals."), ""]
    titles = {"table4": "Table 4: Y90 (two edges clamped, warp along Y)",
              "table5": "Table 5: XY0 (four edges clamped) next to Y90",
              "table6": "Table 6: XY45 (four edges clamped, yarns at 45 degrees) next to XY0, and Y0"}
    pictures = out / "pictures"
    pictures.mkdir(parents=True, exist_ok=True)
    for n in names:
        if n in chapter4.TABLE_SCENES:
            lines += [f"## {titles[n]}", ""]
            for scene in chapter4.TABLE_SCENES[n]:
                lines += [f"**{scene}** (`demos/scenes/{chapter4.SCENES[scene]}`)", "",
                          chapter4.table_md(scene, results), ""]
        elif n == "friction":
            cases = [(f"{s}, friction {mu:g}", chapter4.run_key(s, 57.3, friction=mu))
                     for s in ("Y90", "XY0") for mu in chapter4.FRICTIONS]
            lines += ["## Friction (Sec. 4.4.1), 57.3 m/s", "", chapter4.variant_md(results, cases), ""]
            lines += _damage_pictures(results, cases, out, pictures / "damage_friction.png", "friction")
        elif n == "fillet":
            cases = [(f"Y90, fillet {f * 1e3:g} mm", chapter4.run_key("Y90", 57.3, fillet=f))
                     for f in chapter4.FILLETS]
            lines += ["## Fillet of the impacting edge (Sec. 4.4.3), Y90 at 57.3 m/s", "",
                      chapter4.variant_md(results, cases), ""]
            lines += _damage_pictures(results, cases, out, pictures / "damage_fillet.png", "fillet")
    if limits:
        lines += _limits_md(limits, out, pictures)
    if name == "chapter4":
        chapter4.plot_residual(results, pictures / "residual.png")
        lines += ["## Residual against impact velocity", "", "![residual velocity](pictures/residual.png)", "",
                  "## The thesis's findings", "", "| finding | holds | the numbers |", "|---|---|---|"]
        for finding, holds, numbers in chapter4.checklist(results, waves):
            answer = {None: "-", True: "yes", False: "no"}.get(holds, "cannot be told apart at these members")
            lines.append(f"| {finding} | {answer} | {numbers} |")
        lines += ["", "Where these numbers differ from the thesis's, and what is known of why: "
                  "[validation_differences.md](validation_differences.md).", ""]
    return "\n".join(lines)


def _short(error: str) -> str:
    """The first clause of a run's error message."""
    return error.split("; largest")[0].split(". Likely")[0][:240]


def _limits_md(limits: dict, out: Path, pictures: Path) -> list[str]:
    """The report's ballistic-limit section: each scene's estimate (V50, sigma, V10 and V90 with
    their 95 % intervals, the runs' outcomes, the Lambert-Jonas Vbl), its picture, and the scenes
    whose outcomes do not rise with velocity, per velocity bin."""
    from fabric_fenicsx.studies import chapter4
    from fabric_fenicsx.studies.v50 import format_interval as ci

    lines = ["## Ballistic limit (v50)", "",
             "Each scene's ballistic limit as ballistic testing estimates it (`fabric-fenicsx v50`, "
             "docs/ballistic_limit.md): runs at velocities chosen by Neyer's D-optimal design, starting from the "
             "tightest bracket the scene's table runs give (the highest table velocity up to which every table run "
             f"held, and the next), else from {chapter4.V50_BRACKET[0]:g}-{chapter4.V50_BRACKET[1]:g} m/s; each run "
             "a new member (a seed of the strength scatter, or without one the velocity changed by i x 1e-12); a "
             "probit fit with profile-likelihood 95 % intervals. Runs at the time limit with the projectile still "
             "moving forward are undecided and not counted. The thesis and the experiment put Y90's limit between "
             "34.5 and 39.78 m/s.", "",
             "| scene | V50 (m/s), 95 % | sigma (m/s), 95 % | V10 / V90 (m/s) | runs: perforated / held / undecided / "
             "failed | Lambert-Jonas Vbl (m/s), 95 % | start (m/s) | stopped |",
             "|---|---|---|---|---|---|---|---|"]
    for scene, rep in limits.items():
        p, c, lj = rep["probit"], rep["counts"], rep["lambert_jonas"]
        if p is not None:
            v50 = f"{p['v50']:.2f} {ci(p['v50_ci'])}" + ("" if rep["monotone"] else " (not monotone)")
            sigma, tails = f"{p['sigma']:.2f} {ci(p['sigma_ci'])}", f"{p['v10']:.2f} / {p['v90']:.2f}"
        else:
            v50 = ("no fit: held below, perforated above " + ci(rep["bracket"]) if rep["bracket"] is not None
                   else "no estimate")
            sigma = tails = "-"
        vbl = "-" if lj is None else f"{lj['vbl']:.2f} {ci(lj['vbl_ci'])}"
        start = " - ".join(f"{v:g}" for v in rep["start"])
        errors = sorted({_short(r["error"]) for r in rep["rows"] if r.get("error")})
        stopped = rep["stop"] + (f"; failed: {errors[0]}" if errors else "")
        lines.append(f"| {scene} | {v50} | {sigma} | {tails} | {c['perforated']} / {c['held']} / {c['undecided']} / "
                     f"{c['failed']} | {vbl} | {start} | {stopped} |")
    lines.append("")
    for scene, rep in limits.items():
        if not rep["monotone"] and rep["bins"]:
            lines.append(f"{scene}: the outcomes do not rise with velocity within their intervals; the fraction "
                         "perforated per velocity: " + "; ".join(
                             f"{b['lo']:.2f}-{b['hi']:.2f} m/s {b['perforated']}/{b['n']}" for b in rep["bins"]))
            lines.append("")
        png = out / "v50" / scene / "v50.png"
        if png.exists():
            shutil.copy(png, pictures / f"v50-{scene}.png")
            lines += [f"![{scene}: ballistic limit](pictures/v50-{scene}.png)", ""]
    return lines


def _damage_pictures(results: dict, cases, out: Path, path: Path, what: str) -> list[str]:
    """The cases' damage at the end side by side (:func:`~fabric_fenicsx.studies.chapter4.plot_damage`),
    drawn only when every case's run is complete (:func:`~fabric_fenicsx.studies.chapter4.incomplete_cases`);
    else no picture (an older one is removed) and a line, in the report and on stderr, naming
    the runs it lacks."""
    from fabric_fenicsx.studies import chapter4

    lacking = chapter4.incomplete_cases(results, cases, out / "runs")
    if lacking:
        path.unlink(missing_ok=True)
        line = (f"The {what} damage picture is not drawn: it would lack "
                + "; ".join(f"{key} ({why})" for key, why in lacking) + ".")
        _say(f"{PROG}: {line}", sys.stderr)
        return [line, ""]
    chapter4.plot_damage([(label, out / "runs" / key / "damage.npz") for label, key in cases], path)
    return [f"![damage, {what}](pictures/{path.name})", ""]
