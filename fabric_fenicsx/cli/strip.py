"""``fabric-fenicsx study strip``: the strip test of the strength scatter
(:mod:`fabric_fenicsx.studies.strip`).

A 50 x 10 mm strip pulled along the warp to failure, once without scatter and once per seed
(``--seeds N``, default 100) of ``material.scatter`` (``--scatter``, default weibull), on each
mesh family (``--families``, default aligned,free) and cell size (``--sizes`` in m, default
0.002,0.001), with ``--shear-modulus`` G (N/m) an isotropic in-plane shear stiffness following
the weave's integrity (``membrane.shear_modulus``; default 0, the thesis's membrane), with
``--cell-rule patch`` or ``yarn`` the measured alternatives to how a cell reads the field
(:func:`~fabric_fenicsx.material.scatter.cell_laws`; default weakest),
with ``--crack-band`` each cell's softening shortened to that of one segment (scale l / h), with
``--failure`` the failure rule (thesis, the default, or a crack-tracking rule of
:data:`~fabric_fenicsx.fem.crack_rules.CRACK_RULES`, the scenes' ``material.failure``). The
meshes run side by side in ``--jobs`` processes; each writes
OUT/strip-<family>-<size>.csv a row per pull as it ends, and a study run again resumes from
them; ``--against DIR`` compares every mesh with another strip study's in DIR (another rule, say),
fabric by fabric (:func:`~fabric_fenicsx.studies.strip.against`). OUT/strip-setup.json keeps the options that decide a pull, and a study into an OUT of
other options is refused. Writes OUT/strip.json, OUT/strip.png and prints the distributions and their comparison.
Every option and OUT are checked before any pull (one line, exit 2, no folder left); the study
holds OUT's lock (:mod:`fabric_fenicsx.impact.lock`) while it writes there, so a second one into
OUT stops at once. Its pulls run on this machine only: ``--scheduler`` is refused.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

PROG = "fabric-fenicsx study strip"


SETUP_FILE = "strip-setup.json"


def strip_setup(args):
    """The :class:`~fabric_fenicsx.studies.strip.StripSetup` of the options."""
    from fabric_fenicsx.studies.strip import StripSetup

    return StripSetup(shear_modulus=args.shear_modulus, cell_rule=args.cell_rule, crack_band=bool(args.crack_band),
                      failure=args.failure)


def pull_options(args) -> dict:
    """What decides a pull (kept in OUT/strip-setup.json): the scatter and the whole setup."""
    from dataclasses import asdict

    return {"scatter": args.scatter, **asdict(strip_setup(args))}


def _problems(args, sizes: list[float], families: list[str]) -> list[str]:
    """What is wrong with the strip's options (each a line's part)."""
    from fabric_fenicsx.cli._checks import out_problem
    from fabric_fenicsx.fem.crack_rules import CRACK_RULES
    from fabric_fenicsx.material.scatter import CELL_RULES, SCATTER_MODELS

    problems = []
    if args.failure != "thesis" and args.failure not in CRACK_RULES:
        problems.append(f"--failure must be thesis or one of {list(CRACK_RULES)} for strip, got {args.failure!r}")
    kept = Path(args.out) / SETUP_FILE
    if kept.is_file() and not problems:
        try:
            before = json.loads(kept.read_text())
        except (OSError, ValueError) as err:
            before = {"unreadable": str(err)}
        if before != pull_options(args):
            changed = ", ".join(f"{k} {before.get(k)!r} -> {v!r}" for k, v in pull_options(args).items()
                                if before.get(k) != v)
            problems.append(f"{args.out} holds pulls of other options ({changed}): give another --out")
    if args.scatter not in SCATTER_MODELS[1:]:
        problems.append(f"--scatter must be one of {list(SCATTER_MODELS[1:])}, got {args.scatter!r}")
    if not all(0 < h <= 0.005 for h in sizes):
        problems.append(f"--sizes must lie in (0, 0.005] m (the strip is 10 mm wide), got {sizes}")
    if any(f not in ("aligned", "free") for f in families):
        problems.append(f"--families must name aligned and/or free, got {families}")
    names = [table_name(f, h) for f in families for h in sizes]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        problems.append(f"--families and --sizes give {', '.join(twice)} more than once (sizes must differ in their "
                        "first three digits, in mm)")
    if args.cell_rule not in CELL_RULES:
        problems.append(f"--cell-rule must be one of {list(CELL_RULES)}, got {args.cell_rule!r}")
    if not 0 <= args.shear_modulus < float("inf"):
        problems.append(f"--shear-modulus must be a finite number >= 0 N/m, got {args.shear_modulus}")
    if args.seeds < 3:
        problems.append(f"--seeds must be at least 3 (a distribution), got {args.seeds}")
    if args.jobs is not None and args.jobs < 1:
        problems.append(f"--jobs must be at least 1, got {args.jobs}")
    if args.scheduler is not None:
        problems.append("--scheduler is not available for strip: its pulls run in processes on this machine "
                        "(--jobs)")
    if args.against is not None:
        there = [table_name(f, h) for f in families for h in sizes
                 if (Path(args.against) / table_name(f, h)).is_file()]
        if not there:
            problems.append(f"--against {args.against} holds no strip table of these meshes "
                            f"({', '.join(names)})")
        elif Path(args.against).resolve() == Path(args.out).resolve():
            problems.append("--against must be another study's folder than --out")
    problems += [p for p in (out_problem(args.out),) if p]
    return problems


def table_name(family: str, h: float) -> str:
    """The CSV of one mesh: ``strip-aligned-2mm.csv``."""
    return f"strip-{family}-{h * 1e3:g}mm.csv"


def run(args: argparse.Namespace) -> int:
    """Check the options and the output folder, then pull the strips holding the folder's lock."""
    try:
        sizes = [float(s) for s in (args.sizes or "0.002,0.001").split(",")]
        families = [f.strip() for f in (args.families or "aligned,free").split(",")]
    except ValueError:
        print(f"{PROG}: --sizes must be cell sizes in m separated by commas, got {args.sizes!r}",
              file=sys.stderr)
        return 2
    problems = _problems(args, sizes, families)
    if problems:
        print(f"{PROG}: " + "; ".join(problems), file=sys.stderr)
        return 2
    from fabric_fenicsx.cli._guarded import guarded

    return guarded(PROG, args.out, "study", "strip", lambda: _pull(args, sizes, families),
                   "the pulls in its tables are kept, the others run")


def _pull(args, sizes: list[float], families: list[str]) -> int:
    """Pull every mesh's strips (:func:`~fabric_fenicsx.studies.strip.run_configuration`), then
    write the report."""
    import multiprocessing

    from fabric_fenicsx.cli._checks import cpu_count
    from fabric_fenicsx.studies import strip

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    configs = [(f, h) for f in families for h in sizes]
    paths = {c: out / table_name(*c) for c in configs}
    (out / SETUP_FILE).write_text(json.dumps(pull_options(args), indent=1))
    seeds = list(range(args.seeds))
    t0 = time.perf_counter()
    jobs = max(1, min(len(configs), args.jobs or cpu_count()))
    if not args.quiet:
        print(f"{PROG}: {len(configs)} meshes x ({args.seeds} seeds of {args.scatter} + no scatter), "
              f"{jobs} at a time, into {out}", flush=True)
    with multiprocessing.get_context("spawn").Pool(jobs) as pool:
        setup = strip_setup(args)
        pending = [pool.apply_async(strip.run_configuration, (f, h, args.scatter, seeds, str(paths[(f, h)]), setup))
                   for f, h in configs]
        for (f, h), job in zip(configs, pending):
            job.get()
            if not args.quiet:
                print(f"strip: {f} {h * 1e3:g} mm done ({time.perf_counter() - t0:.0f} s elapsed)", flush=True)
    tables = {c: strip.read_table(paths[c]) for c in configs}
    report = strip.summarise(tables)
    report.update(scatter=args.scatter, seeds=args.seeds,
                  setup=setup.__dict__,
                  wall_time_s=time.perf_counter() - t0)
    if args.against is not None:
        other = Path(args.against)
        others = {c: strip.read_table(other / table_name(*c)) for c in configs if (other / table_name(*c)).is_file()}
        kept = other / SETUP_FILE
        label = (f"failure {json.loads(kept.read_text()).get('failure', 'thesis')}" if kept.is_file()
                 else str(other))
        report["against"] = {"folder": str(other), "label": label, "meshes": strip.against(tables, others)}
    (out / "strip.json").write_text(json.dumps(report, indent=1))
    strip.plot(tables, report, out / "strip.png")
    print(strip.format_report(report))
    if args.against is not None:
        print(strip.format_against(report["against"]["meshes"], report["against"]["label"]))
    print(f"report in {out / 'strip.json'}, picture {out / 'strip.png'}")
    return 0
