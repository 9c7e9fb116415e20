"""``fabric-fenicsx ensemble SCENE -n N``: a scene's answer as a distribution.

Runs the scene N times, the impact velocity changed by k x ``--perturbation`` of itself (k = 0,
1, -1, 2, ...), ``--jobs`` members at a time as separate processes, and prints the mean, the
95 % interval of the mean, the standard deviation and the range of the residual velocity, the
absorbed energy, the viscous dissipation and its share, the deflection at damage onset, how far
from the impact point the first yarn breaks, and the removed cells (:mod:`fabric_fenicsx.studies.ensemble`). Writes OUT/ensemble.csv (a row as each
member ends), OUT/ensemble.json, OUT/ensemble.png and each member's output (OUT/member_<k>).
Unless ``--quiet``, a line per member as it ends and a progress line (members done, time
elapsed, about how long is left). With ``--seeds``, ``--against DIR`` pairs the members with
another ensemble's of the same fabrics (DIR/ensemble.csv: another mesh, another rule) seed by
seed (:func:`~fabric_fenicsx.studies.ensemble.against`), into the report as ``against``.

``--scheduler tcp://HOST:8786`` runs the members on the workers of a dask cluster instead
(``local:N``: N workers on this machine; :mod:`fabric_fenicsx.studies.executor`), ``--jobs`` at a
time (default: the cluster's worker threads); OUT and the scene file must be on a file system
every worker sees at the same path, which is checked before the first member.

One ensemble at a time in a folder: it holds OUT's lock (:mod:`fabric_fenicsx.impact.lock`)
from before its first member to its end; a second writer into OUT stops at once (exit 2)
with a line naming the first. A member's outcome that cannot be recorded, or a disk that
fills up, ends it with one line (exit 1); run again, it reuses the complete members.
"""
from __future__ import annotations

import argparse
import csv
import json
import sys
from pathlib import Path

from fabric_fenicsx.cli import _perturbed

PROG = "fabric-fenicsx ensemble"
COLUMNS = ("k", "seed", "velocity", "residual_velocity", "absorbed_energy", "viscous_dissipation", "viscous_share",
           "damage_onset_deflection", "damage_onset_radius", "removed_cells", "end_reason", "wall_time_s", "error")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    _perturbed.add_arguments(parser, "ensemble", "every member")
    parser.add_argument("-n", "--members", type=int, default=8, help="number of members (default 8)")
    parser.add_argument("--seeds", type=int, default=None, metavar="FIRST",
                        help="members are fabrics of the scene's strength scatter (material.scatter): "
                             "seeds FIRST, FIRST+1, ... at the scene's velocity, instead of the velocity "
                             "changed by k x --perturbation")
    parser.add_argument("--against", default=None, metavar="DIR",
                        help="with --seeds: pair the members seed by seed with the ensemble in DIR "
                             "(the same fabrics on another mesh, or under another rule)")
    parser.add_argument("--jobs", type=int, default=None,
                        help="members run at the same time (default: the cores, or with --scheduler the "
                             "cluster's worker threads; at most the members)")
    from fabric_fenicsx.cli._guarded import add_scheduler_argument

    add_scheduler_argument(parser, "members")


def run(args: argparse.Namespace) -> int:
    from fabric_fenicsx.cli.impact import _size
    from fabric_fenicsx.impact.scene import InputError, check_output_dir, load_scene
    from fabric_fenicsx.studies import ensemble
    from fabric_fenicsx.studies.executor import scheduler_problem

    if _size() > 1:
        print(f"{PROG}: the members are processes of their own; run it without mpirun", file=sys.stderr)
        return 2
    p = ensemble.PERTURBATION if args.perturbation is None else args.perturbation
    problems = []
    if args.members < 2:
        problems.append(f"--members must be at least 2, got {args.members}")
    if _perturbed.perturbation_problem(p):
        problems.append(_perturbed.perturbation_problem(p))
    if args.seeds is not None and args.seeds < 0:
        problems.append(f"--seeds must be a seed >= 0, got {args.seeds}")
    if args.jobs is not None and args.jobs < 1:
        problems.append(f"--jobs must be at least 1, got {args.jobs}")
    if scheduler_problem(args.scheduler):
        problems.append(scheduler_problem(args.scheduler))
    if args.against is not None:
        if args.seeds is None:
            problems.append("--against pairs fabrics: it needs --seeds (round-off twins of one fabric do not pair)")
        elif not (Path(args.against) / "ensemble.csv").is_file():
            problems.append(f"--against {args.against} holds no ensemble.csv")
    if problems:
        print(f"{PROG}: " + "; ".join(problems), file=sys.stderr)
        return 2
    try:
        scene = load_scene(args.scene, args.overrides)
        if args.seeds is not None and scene.material.scatter == "none":
            raise InputError("--seeds needs a strength scatter (material.scatter = fibrils or weibull): "
                             "with scatter none every seed is the same fabric")
        out = Path(args.out or Path("out") / f"ensemble-{scene.name}")
        check_output_dir(str(out))
        if args.against is not None and Path(args.against).resolve() == out.resolve():
            raise InputError("--against must name another ensemble's folder than --out")
    except InputError as err:
        print(f"{PROG}: {err}", file=sys.stderr)
        return 2
    from fabric_fenicsx.cli._guarded import guarded

    return guarded(PROG, out, "ensemble", scene.name, lambda: _ensemble(args, scene, out, p),
                   "its complete members are reused")


def _ensemble(args: argparse.Namespace, scene, out: Path, p: float) -> int:
    """Open the executor (:func:`~fabric_fenicsx.studies.executor.make_executor`), check that its
    workers see OUT, the scene file and the fabric file it names, and run the members on it."""
    from fabric_fenicsx.studies.executor import make_executor

    with make_executor(args.scheduler) as executor:
        executor.check_shared(out, [args.scene, *([scene.fabric.file] if scene.fabric.file else [])])
        return _members(args, scene, out, p, executor)


def _members(args: argparse.Namespace, scene, out: Path, p: float, executor) -> int:
    from fabric_fenicsx.studies import ensemble
    from fabric_fenicsx.studies.runpool import Progress, write_atomic

    jobs = min(args.members, args.jobs or executor.slots)
    out.mkdir(parents=True, exist_ok=True)
    table = out / "ensemble.csv"
    with open(table, "w", newline="") as f:
        csv.writer(f).writerow(COLUMNS)

    def on_member(row: dict) -> None:
        with open(table, "a", newline="") as f:
            csv.writer(f).writerow([row.get(c, "") for c in COLUMNS])
        if not args.quiet:
            if "error" in row:
                print(f"member k = {row['k']:+d}: failed ({row['error']})", flush=True)
            else:
                print(f"member k = {row['k']:+d}: residual {row['residual_velocity']:.4f} m/s, absorbed "
                      f"{row['absorbed_energy']:.3f} J, {row['removed_cells']} cells removed "
                      f"({row['end_reason']}, {row['wall_time_s']:.0f} s)", flush=True)

    if not args.quiet:
        where = f", on {executor.description}" if executor.remote else ""
        what = ("impact velocity x (1 + k perturbation)" if args.seeds is None
                else f"scatter seeds {args.seeds}..{args.seeds + args.members - 1}")
        print(f"{PROG}: {args.members} members of {scene.name} ({what}), {jobs} at a time, into "
              f"{out}{where}", flush=True)
    progress = None if args.quiet else Progress("ensemble", "members", say=lambda line: print(line, flush=True))
    rows = ensemble.run_members(args.scene, args.overrides, scene.projectile.velocity, args.members, out,
                                jobs=jobs, perturbation=p, on_member=on_member, executor=executor,
                                progress=progress, first_seed=args.seeds)
    ok = [r for r in rows if "error" not in r]
    rep = ensemble.summarise(ok, p, first_seed=args.seeds)
    rep.update(scene=str(args.scene), overrides=list(args.overrides), failed=[r for r in rows if "error" in r])
    if args.against is not None:
        rep["against"] = {"folder": str(args.against),
                          **ensemble.against(ok, ensemble.read_members(Path(args.against) / "ensemble.csv"))}
    write_atomic(out / "ensemble.json", json.dumps(rep, indent=1))
    if ok:
        ensemble.plot(rep, out / "ensemble.png", title=f"{scene.name}: {len(ok)} members")
    print(ensemble.format_summary(rep))
    if args.against is not None:
        print(ensemble.format_against(rep["against"], str(args.against)))
    print(f"report in {out / 'ensemble.json'}, members in {table}")
    if rep["failed"]:
        print(f"{PROG}: {len(rep['failed'])} of {len(rows)} members failed; their logs are in "
              f"{out}/member_<k>/run.log", file=sys.stderr)
        return 1
    return 0
