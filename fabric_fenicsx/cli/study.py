"""``fabric-fenicsx study NAME --out DIR [--jobs N] [--scheduler ADDRESS] [--set section.key=value ...]``:
the thesis's chapter 4 as studies (:mod:`fabric_fenicsx.studies.chapter4`).

NAME: table4, table5, table6, friction, fillet, v50 or chapter4 (all of them, and the validation
report), or strip (the strength scatter's strip test, :mod:`fabric_fenicsx.cli.strip`). The runs are independent ``fabric-fenicsx impact`` processes, ``--jobs`` at a time
(the four scenes' ballistic limits are bisected side by side, sharing them), each into
OUT/runs/<run>; a run stored with the same settings and model version is reused, so
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

    parser.add_argument("name", metavar="NAME", help=f"the study: {', '.join(STUDIES)}, strip")
    parser.add_argument("--out", default=None, help="output folder (default out/study-NAME)")
    parser.add_argument("--jobs", type=int, default=None,
                        help="runs at the same time (default: the cores; with --scheduler, the cluster's worker threads)")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="SECTION.KEY=VALUE",
                        help="override a scene key of every run (repeatable)")
    parser.add_argument("--members", type=int, default=None,
                        help="v50: runs per velocity, the impact velocity changed by k x 1e-12 (default: --jobs, "
                             "at least 2)")
    parser.add_argument("--tol", type=float, default=0.5, help="v50: width of the final bracket (m/s, default 0.5)")
    parser.add_argument("--doc", default="docs/validation.md", help="chapter4: the report to write")
    parser.add_argument("--quiet", action="store_true", help="no line per run and no progress lines")
    parser.add_argument("--seeds", type=int, default=100, help="strip: seeds of the scatter per mesh (default 100)")
    parser.add_argument("--scatter", default="weibull", help="strip: the scatter model (weibull or fibrils)")
    parser.add_argument("--sizes", default="0.002,0.001", help="strip: cell sizes in m (default 0.002,0.001)")
    parser.add_argument("--families", default="aligned,free", help="strip: mesh families (default aligned,free)")
    parser.add_argument("--cell-rule", default="weakest",
                        help="strip: how a cell reads the segments it covers, weakest, patch or yarn (default weakest)")
    parser.add_argument("--crack-band", action="store_true",
                        help="strip: shorten each cell's softening to one segment's (scale l / h)")
    parser.add_argument("--shear-modulus", type=float, default=0.0,
                        help="strip: isotropic in-plane shear stiffness G (N/m, default 0: the thesis's membrane)")
    from fabric_fenicsx.cli._guarded import add_scheduler_argument

    add_scheduler_argument(parser, "runs")


def _check(args) -> str | None:
    from fabric_fenicsx.impact.scene import InputError, check_output_dir, load_scene
    from fabric_fenicsx.studies import chapter4
    from fabric_fenicsx.studies.executor import scheduler_problem

    if args.name not in chapter4.STUDIES:
        return f"unknown study {args.name!r}; the studies are {', '.join(chapter4.STUDIES)}"
    if args.jobs is not None and args.jobs < 1:
        return f"--jobs must be at least 1, got {args.jobs}"
    if args.members is not None and args.members < 1:
        return f"--members must be at least 1, got {args.members}"
    if not args.tol > 0:
        return f"--tol must be positive, got {args.tol}"
    if scheduler_problem(args.scheduler):
        return scheduler_problem(args.scheduler)
    try:
        for scene in chapter4.SCENES.values():
            load_scene(str(chapter4.SCENE_DIR / scene), [*RUN_OUTPUT, *args.overrides])
        check_output_dir(args.out)
    except InputError as err:
        return str(err)
    return None


def run(args: argparse.Namespace) -> int:
    from fabric_fenicsx.cli.impact import _size

    if _size() > 1:
        print(f"{PROG}: the runs are processes of their own (--jobs); run it without mpirun", file=sys.stderr)
        return 2
    args.out = args.out or str(Path("out") / f"study-{args.name}")
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

    out = Path(args.out)
    jobs = args.jobs or executor.slots
    overrides = (*RUN_OUTPUT, *args.overrides)
    runs = chapter4.plan(args.name, overrides)
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
        limits = _ballistic_limits(overrides, results, out / "runs", jobs, args.members or max(2, jobs), args.tol,
                                   progress, executor, counter)
    wall = time.perf_counter() - t0
    report = {"study": args.name, "overrides": list(args.overrides), "wall_time_s": wall,
              "runs": results, "v50": limits, "waves": waves}
    write_atomic(out / f"{args.name}.json", json.dumps(report, indent=1, default=str))
    text = _report(args.name, results, limits, waves, overrides, wall, out)
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
    print(f"{PROG} {args.name}: {len(results) - len(failed)} of {len(results)} runs, wall time "
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


def _ballistic_limits(overrides, results: dict, runs_dir: Path, jobs: int, members: int, tol: float,
                      progress, executor=None, counter=None) -> dict:
    """The ballistic limit of each scene: :func:`~fabric_fenicsx.studies.limit.bisect_limit` from
    :func:`~fabric_fenicsx.studies.chapter4.v50_start` (on the table runs in ``results``),
    ``members`` runs per velocity (V0 changed by k x 1e-12); the four scenes side by side in
    threads whose runs share ``jobs`` processes of ``executor``; ``counter`` (a
    :class:`~fabric_fenicsx.studies.runpool.Progress`) is told of each velocity's runs."""
    import threading

    from fabric_fenicsx.studies import chapter4
    from fabric_fenicsx.studies.ensemble import offsets
    from fabric_fenicsx.studies.limit import bisect_limit
    from fabric_fenicsx.studies.runpool import run_all

    slots = threading.BoundedSemaphore(jobs)
    stop = threading.Event()        # one scene's pool stopped (a full disk): the others stop too
    limits, crashed = {}, {}

    def guarded(scene):
        try:
            bisect(scene)
        except BaseException as err:        # a bug, not a failed run: raised again below
            crashed[scene] = err

    def bisect(scene):
        summaries: list[dict] = []

        def evaluate(v):
            runs = [chapter4.v50_run(scene, v, k, overrides) for k in offsets(members)]
            if counter is not None:
                counter.expect(len(runs))
            done = run_all(runs, runs_dir, jobs=jobs, on_done=progress, slots=slots, stop=stop, executor=executor)
            bad = [k for k, s in done.items() if "error" in s]
            if bad:
                raise RuntimeError(f"v50 of {scene}: run {bad[0]} failed ({done[bad[0]]['error']}); "
                                   f"see {runs_dir / bad[0] / 'run.log'}")
            summaries.extend(s for k, s in done.items() if k not in results)   # not the table's runs again
            return [bool(s["perforated"]) for s in done.values()]

        start = chapter4.v50_start(scene, results)
        _say(f"{PROG} v50: {scene}, bisection from {start} m/s to {tol} m/s, {members} runs a velocity")
        try:
            r = bisect_limit(evaluate, *start, tol=tol)
        except RuntimeError as err:         # a failed run: report it; the other scenes go on
            _say(f"{PROG} v50: {err}", sys.stderr)
            limits[scene] = {"error": str(err), "start": start, "members": members}
            return
        limits[scene] = {**r, "start": start, "members": members, "summaries": summaries}
        _say(f"{PROG} v50: {scene}: limit {r['limit']} m/s, band {r['band']}")

    threads = [threading.Thread(target=guarded, args=(scene,), name=f"v50-{scene}", daemon=True)
               for scene in chapter4.SCENES]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    stopped = [err for err in crashed.values() if isinstance(err, PoolStopped)]
    if stopped:         # the first cause, not the pools that stopped with it
        raise next((e for e in stopped if not str(e).startswith("stopped with")), stopped[0])
    for scene, err in crashed.items():
        raise RuntimeError(f"{PROG} v50: the bisection of {scene} stopped") from err
    return {scene: limits[scene] for scene in chapter4.SCENES}


def _report(name: str, results: dict, limits: dict, waves: dict, overrides, wall: float, out: Path) -> str:
    from fabric_fenicsx.studies import chapter4
    from fabric_fenicsx.provenance import code_fingerprint

    fp = code_fingerprint()
    names = [s for s in chapter4.STUDIES if s != "chapter4"] if name == "chapter4" else [name]
    every = list(results.values()) + [s for r in limits.values() for s in r.get("summaries", [])]
    run_wall = sum(s.get("wall_time_s") or 0.0 for s in every) + (waves.get("wall_time_s") or 0.0)
    lines = [f"# The thesis's chapter 4: `fabric-fenicsx study {name}`", "",
             f"Made by `fabric-fenicsx study {name}` in {wall / 60:.1f} min of wall time (stored runs are "
             f"reused: the {len(every)} impact runs' own solving times add up to {run_wall / 60:.1f} min on one "
             f"core each), model version {fp['model_version']}, "
             f"git {fp['git_head']}. Every run: the scene file of demos/scenes as it is, with "
             f"`{' '.join('--set ' + o for o in overrides)}`. Deflections are the central deflection at damage "
             "onset, when the first cell is removed and the largest of the run; the damage reach is the "
             "largest distance from the impact point of a cell with a damaged yarn at the end. Y90's residual "
             "velocity after damage is one draw of a wide distribution (docs/mesh_independence.md, section 9): "
             "read it with the ensembles there.", ""]
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
        lines += ["## Ballistic limit (v50)", "",
                  "Bisection between a velocity the fabric holds and one it lets through, several runs a "
                  "velocity (the impact velocity changed by k x 1e-12 of itself): the band runs from the "
                  "highest velocity at which every run held to the lowest at which every run perforated, "
                  "each edge bisected to the tolerance; the limit is its midpoint. A scene's bisection starts "
                  "from the tightest bracket its table runs give (the highest table velocity up to which every "
                  "table run held, and the next; the table's run is the first member there), else from "
                  f"{chapter4.V50_BRACKET[0]:g}-{chapter4.V50_BRACKET[1]:g} m/s. The thesis and the "
                  "experiment put Y90's limit between 34.5 and 39.78 m/s.", "",
                  "| scene | limit (m/s) | band (m/s) | width (m/s) | start (m/s) | velocities tried: perforated runs |",
                  "|---|---|---|---|---|---|"]
        for scene, r in limits.items():
            if "error" in r:
                lines.append(f"| {scene} | not found: a run failed ({_short(r['error'])}) | | | | |")
                continue
            lo, hi = r["band"]
            width = f"{hi - lo:.2f}" if lo is not None and hi is not None else "-"
            tries = ", ".join(f"{v:.2f}: {sum(o)}/{len(o)}" for v, o in r["tries"])
            lim = f"{r['limit']:.2f}" if r["limit"] is not None else "not found"
            start = " - ".join(f"{v:g}" for v in r["start"])
            band = " - ".join("-" if x is None else f"{x:.6g}" for x in (lo, hi))
            lines.append(f"| {scene} | {lim} | {band} | {width} | {start} | {tries} |")
        lines += ["", "Every run of a scene at the velocities of its table and of the bisection together "
                  "(the velocities where at least one run perforated and where at least one held):", ""]
        for scene in limits:
            lines.append(f"- {scene}: {_outcomes(scene, results, limits[scene])}")
        lines.append("")
    if name == "chapter4":
        chapter4.plot_residual(results, pictures / "residual.png")
        lines += ["## Residual against impact velocity", "", "![residual velocity](pictures/residual.png)", "",
                  "## The thesis's findings", "", "| finding | holds | the numbers |", "|---|---|---|"]
        for finding, holds, numbers in chapter4.checklist(results, waves):
            lines.append(f"| {finding} | {'-' if holds is None else ('yes' if holds else 'no')} | {numbers} |")
        lines += ["", "Where these numbers differ from the thesis's, and what is known of why: "
                  "[validation_differences.md](validation_differences.md).", ""]
    return "\n".join(lines)


def _short(error: str) -> str:
    """The first clause of a run's error message."""
    return error.split("; largest")[0].split(". Likely")[0][:240]


def _outcomes(scene: str, results: dict, limit: dict) -> str:
    """Lowest velocity at which a run of ``scene`` perforated and highest at which one held,
    over the table's runs and the bisection's."""
    from fabric_fenicsx.studies import chapter4

    runs = [(v, bool(results.get(chapter4.run_key(scene, v), {}).get("perforated")))
            for v in chapter4.VELOCITIES if "perforated" in results.get(chapter4.run_key(scene, v), {})]
    runs += [(v, o) for v, outs in limit.get("tries", []) for o in outs]
    through = [v for v, o in runs if o]
    held = [v for v, o in runs if not o]
    if not runs:
        return "no runs"
    if not held:
        return f"every run perforated ({min(through):g} to {max(through):g} m/s)"
    if not through:
        return f"every run held ({min(held):g} to {max(held):g} m/s)"
    lo, hi = min(through), max(held)
    if lo > hi:
        return f"every run held up to {hi:g} m/s and perforated from {lo:g} m/s"
    return f"runs perforated from {lo:g} m/s and held up to {hi:g} m/s: outcomes overlap over {hi - lo:.2f} m/s"


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
