"""``fabric-fenicsx convergence``: error against run time of each discretisation knob
(docs/convergence/discretisation.md).

The command runs (or reuses) the impact ladders, the unit-cell ladder and the run-to-run
scatter of :mod:`fabric_fenicsx.studies.convergence`, analyses them and writes the tables,
plots and report of :mod:`fabric_fenicsx.studies.convergence_report`. It imports both; the
report imports the study and the study neither, so the three form no import cycle.

At module level only the study is imported (its ladders are the options' defaults; it imports
no DOLFINx); the report is imported when the command runs.
"""

from __future__ import annotations

import argparse
import datetime
import json
import math
import sys
from pathlib import Path

from fabric_fenicsx.studies import convergence as cv

PROG = "fabric-fenicsx convergence"

KNOBS = ("unitcell", "surrogate", "mesh", "dt", "scatter")
"""What ``--only`` selects."""


# ============================================================================ options
def _float_list(text: str) -> list[float]:
    """Comma-separated positive numbers (argparse type)."""
    try:
        vals = [float(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated numbers, got {text!r}") from None
    if len(vals) < 1 or not all(v > 0 and math.isfinite(v) for v in vals):
        raise argparse.ArgumentTypeError(f"expected positive numbers, got {text!r}")
    return vals


def _knobs(text: str) -> list[str]:
    """Comma-separated knobs of :data:`KNOBS` (argparse type)."""
    k = [x.strip() for x in text.split(",") if x.strip()]
    bad = sorted(set(k) - set(KNOBS))
    if bad or not k:
        raise argparse.ArgumentTypeError(f"unknown knob(s) {bad or text!r}; valid: {', '.join(KNOBS)}")
    return k


def _cases(text: str) -> list[str]:
    """Comma-separated cases of the impact ladders (argparse type)."""
    c = [x.strip() for x in text.split(",") if x.strip()]
    bad = sorted(set(c) - set(cv.CASES))
    if bad or not c:
        raise argparse.ArgumentTypeError(f"unknown case(s) {bad or text!r}; valid: {', '.join(cv.CASES)}")
    return c


def _dt_mesh(text: str) -> tuple[str | None, float]:
    """``H`` (every case) or ``CASE=H``: the h_centre (mm) of a dt ladder (argparse type)."""
    case, sep, rest = text.rpartition("=")
    if sep and case.strip() not in cv.CASES:
        raise argparse.ArgumentTypeError(f"expected H or CASE=H with CASE one of {list(cv.CASES)}, got {text!r}")
    try:
        return (case.strip() or None), float(rest)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a mesh size in mm, got {rest!r}") from None


def _case_levels(text: str) -> tuple[str, list[float]]:
    """``CASE=H,H,H``: the mesh ladder (mm) of one case (argparse type)."""
    case, sep, rest = text.partition("=")
    if not sep or case.strip() not in cv.CASES:
        raise argparse.ArgumentTypeError(f"expected CASE=H,H,H with CASE one of {list(cv.CASES)}, got {text!r}")
    return case.strip(), _float_list(rest)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The options of ``fabric-fenicsx convergence``."""
    parser.add_argument("--out", help="folder of run folders, CSVs and plots (default docs/convergence; "
                        "out/convergence-quick with --quick)")
    parser.add_argument("--doc", help="report file (default docs/convergence/discretisation.md; OUT/convergence.md "
                        "with --quick)")
    parser.add_argument("--cases", type=_cases, default=["elastic"],
                        help="impact ladders of these cases (default elastic: damage off, a run repeats; "
                             f"valid: {', '.join(cv.CASES)}). After damage a run is one draw of a distribution: "
                             "its statistics converge, which `fabric-fenicsx ladder` measures (docs/convergence.md)")
    parser.add_argument("--only", type=_knobs, default=list(KNOBS),
                        help=f"comma-separated knobs to compute (default all: {','.join(KNOBS)}); the report "
                             "includes every knob whose results are already stored")
    parser.add_argument("--levels", type=_float_list, help="mesh ladder of every case, h_centre in mm (default "
                        + "; ".join(f"{c}: " + ",".join(f"{h:g}" for h in v) for c, v in cv.MESH_LEVELS_MM.items())
                        + ")")
    parser.add_argument("--case-levels", type=_case_levels, action="append", default=[], metavar="CASE=H,H,H",
                        help=f"mesh ladder of one case (cases: {', '.join(cv.CASES)}), e.g. damaged=4,2,1; repeatable")
    parser.add_argument("--safeties", type=_float_list, help="dt ladder, run.dt_safety values (default "
                        + ",".join(f"{s:g}" for s in cv.DT_SAFETIES) + ")")
    parser.add_argument("--dt-mesh", type=_dt_mesh, action="append", default=[], metavar="[CASE=]H",
                        help="h_centre (mm) of the dt ladder, of every case (H) or of one (CASE=H); repeatable "
                        "(default " + ", ".join(f"{c}={h:g}" for c, h in cv.DT_MESH_MM.items()) + ")")
    parser.add_argument("--quick", action="store_true", help="tiny smoke version (coarse ladders), not a study")
    parser.add_argument("--rerun", action="store_true",
                        help="run every impact run and the unit-cell ladder again, even if stored")


# ============================================================================ ladders
def _ladders(args: argparse.Namespace) -> tuple[dict[str, list[float]], list[float], dict[str, float]]:
    """The ladders asked for: mesh levels of each case (mm), dt_safety levels, and the mesh
    (mm) of each case's dt ladder."""
    if args.levels:
        levels = {c: list(args.levels) for c in cv.CASES}
    elif args.quick:
        levels = {c: [8.0, 5.66, 4.0] for c in cv.CASES}
    else:
        levels = {c: list(v) for c, v in cv.MESH_LEVELS_MM.items()}
    levels.update(dict(args.case_levels))
    safeties = args.safeties or ([0.8, 0.6, 0.4] if args.quick else list(cv.DT_SAFETIES))
    dt_mesh = dict(cv.DT_MESH_MM) if not args.quick else {c: 8.0 for c in cv.CASES}
    for case, h in args.dt_mesh:
        dt_mesh.update({case: h} if case else {c: h for c in cv.CASES})
    cases = getattr(args, "cases", list(cv.CASES))
    return ({c: v for c, v in levels.items() if c in cases}, safeties,
            {c: h for c, h in dt_mesh.items() if c in cases})


def _check_ladders(levels: dict, safeties) -> None:
    """Stop unless every ladder has three distinct levels within the scene's limits."""
    for case, lv in levels.items():
        if len(set(lv)) < 3:
            raise SystemExit(f"{PROG}: the mesh ladder of {case} needs at least three levels")
    if len(set(safeties)) < 3:
        raise SystemExit(f"{PROG}: the dt ladder needs at least three distinct levels")
    if max(max(lv) for lv in levels.values()) > 8.0:
        raise SystemExit(f"{PROG}: h_centre above h_edge = 8 mm of the scene")
    if max(safeties) > 1.0:
        raise SystemExit(f"{PROG}: dt_safety must lie in (0, 1]")


def _update_plan(path: Path, only, levels: dict, safeties, dt_mesh: dict) -> dict:
    """The stored plan (``plan.json``) with the ladders of the knobs asked for replaced, written
    back: so ``--only`` keeps the other knob's ladder in the report."""
    plan = json.loads(path.read_text()) if path.is_file() else {}
    if "mesh" in only:
        plan["mesh"] = levels
    if "dt" in only:
        plan["dt"] = {"safeties": safeties, "mesh_mm": dt_mesh}
    path.write_text(json.dumps(plan, indent=1))
    return plan


def _planned_dt_mesh(plan: dict, dt_mesh: dict) -> dict:
    """The mesh (mm) of each case's dt ladder in the plan (``dt_mesh`` if it has no dt ladder);
    a plan.json of a study before per-case meshes holds one number for all cases."""
    mesh = plan.get("dt", {}).get("mesh_mm", dt_mesh)
    return mesh if isinstance(mesh, dict) else {c: float(mesh) for c in cv.CASES}


# ============================================================================ the study
def _log(text: str) -> None:
    """A progress line, with the time of day."""
    print(f"{datetime.datetime.now():%H:%M:%S} {text}", flush=True)


def _command() -> str:
    """The command line as typed, for the report."""
    if len(sys.argv) > 1 and sys.argv[1] == "convergence":
        return " ".join([PROG, *sys.argv[2:]])
    return PROG


def _impact_runs(runs, only, runs_dir: Path, rerun: bool) -> list[tuple[str, cv.RunRecord]]:
    """Run (or reuse) the planned runs of the knobs asked for; the runs of the other knobs are
    only read back (they must be stored with this model version, else they are left out)."""
    records = cv.run_ladders([r for r in runs if r[0] in only], runs_dir, rerun=rerun, log=_log)
    for knob, case, h, s in runs:
        if knob in only:
            continue
        if cv.is_stored(case, h, s, runs_dir):
            records.append((knob, cv.run_one(case, h, s, runs_dir, log=_log)))
        else:
            _log(f"  {cv.run_name(case, h, s)}: not stored with this model version; left out (run --only {knob})")
    return records


def _analyse_knob(knob: str, records, out: Path) -> dict:
    """Each case's ladder of one impact knob ("mesh" or "dt") analysed, with the knob's CSV
    table and plot."""
    from fabric_fenicsx.studies.convergence_report import ladder_rows, plot_ladders, write_csv

    param = "h_centre" if knob == "mesh" else "dt_safety"
    analyses = {}
    for case in cv.CASES:
        recs = [r for k, r in records if k == knob and r.case == case]
        if recs:
            analyses[case] = cv.analyse_ladder(recs, param)
    rows = [row for a in analyses.values() for row in ladder_rows(a)]
    if rows:
        write_csv(out / f"{knob}.csv", rows)
        label = ((lambda r: f"{r.h_centre * 1e3:.3g} mm") if knob == "mesh" else (lambda r: f"s={r.dt_safety:g}"))
        plot_ladders(out / f"{knob}_error_vs_time.png", analyses,
                     "mesh h_centre" if knob == "mesh" else "dt_safety", label)
    return analyses


def _load_unitcell(path: Path) -> dict | None:
    """The stored unit-cell study (``unitcell.json``), or None."""
    if not path.is_file():
        return None
    with open(path) as f:
        uc = json.load(f)
    uc["states"] = [(E1, E2, tuple(a)) for E1, E2, a in uc["states"]]
    return uc


def _same_unitcell(uc: dict | None, ladder, reference: int, states) -> bool:
    """Whether a stored unit-cell study has the same element counts, reference and states."""
    if uc is None:
        return False
    ns = sorted({int(n) for n in ladder} | {int(reference)})
    return (uc["reference"] == reference and sorted(s["n"] for s in uc["summary"]) == ns
            and [(float(a), float(b), tuple(map(float, c))) for a, b, c in uc["states"]]
            == [(float(a), float(b), tuple(map(float, c))) for a, b, c in states])


def _unitcell(args: argparse.Namespace, out: Path) -> dict | None:
    """The unit-cell ladder: if asked for, computed (or reused when stored with the same element
    counts and states) and written as CSV and plot; else the stored one, if any."""
    from fabric_fenicsx.studies.convergence_report import plot_unitcell, write_csv

    uc_path = out / "unitcell.json"
    uc = _load_unitcell(uc_path)
    if "unitcell" not in args.only:
        return uc
    ladder = (4, 8, 16) if args.quick else cv.UNITCELL_LADDER
    reference = 64 if args.quick else cv.UNITCELL_REFERENCE
    if args.rerun or not _same_unitcell(uc, ladder, reference, cv.UNITCELL_STATES):
        _log("unit cell ladder")
        uc = cv.unitcell_study(ladder, reference, log=_log)
        with open(uc_path, "w") as f:
            json.dump(uc, f, indent=1)
    else:
        _log(f"unit cell ladder: reused {uc_path} (same element counts and states)")
    write_csv(out / "unitcell.csv", uc["rows"])
    write_csv(out / "unitcell_summary.csv", uc["summary"])
    plot_unitcell(out / "unitcell_error_vs_time.png", uc)
    return uc


def _scatter(args: argparse.Namespace, runs_dir: Path, records) -> dict[float, list[cv.RunRecord]]:
    """Run-to-run scatter of the damaged case: at each of ``SCATTER_LEVELS_MM`` (none with
    ``--quick``) the unperturbed run of the mesh ladder and one run per perturbation, run (or
    reused) if asked for, else those stored."""
    scatter: dict[float, list[cv.RunRecord]] = {}
    asked = "scatter" in args.only and "damaged" in getattr(args, "cases", cv.CASES)
    if "scatter" in args.only and not asked and not args.quick:
        _log("scatter: not run (it is the damaged case's; add --cases damaged,elastic for it)")
    for h in (x * 1e-3 for x in ([] if args.quick else cv.SCATTER_LEVELS_MM)):
        base = [r for k, r in records if k == "mesh" and r.case == "damaged" and math.isclose(r.h_centre, h)
                and r.dt_safety == cv.DEFAULT_SAFETY]
        recs = [cv.run_one("damaged", h, cv.DEFAULT_SAFETY, runs_dir, rerun=args.rerun and asked, log=_log,
                           perturbation=p)
                for p in cv.SCATTER_PERTURBATIONS
                if asked or cv.is_stored("damaged", h, cv.DEFAULT_SAFETY, runs_dir, p)]
        if recs and not base:
            _log(f"  scatter at {h * 1e3:.4g} mm: the unperturbed run is not in the mesh ladder; "
                 "the ensemble has only the perturbed runs")
        if recs:
            scatter[h] = base[:1] + recs
    return scatter


def _study_time(records) -> dict:
    """Number of distinct runs (by folder; the last record of a folder counts), the new ones
    among them, and their total CPU and wall time."""
    unique = {r.folder: r for r in records}
    return {"n_runs": len(unique), "n_new": sum(r.new for r in unique.values()),
            "cpu_s": sum(r.get("cpu_s") for r in unique.values()),
            "wall_s": sum(r.get("wall_s") for r in unique.values())}


def run(args: argparse.Namespace) -> int:
    """Run (or reuse) the knobs asked for, analyse every stored ladder and write the report."""
    from fabric_fenicsx.studies.convergence_report import write_report

    out = Path(args.out or ("out/convergence-quick" if args.quick else "docs/convergence"))
    doc = Path(args.doc or (out / "convergence.md" if args.quick else out / "discretisation.md"))
    levels, safeties, dt_mesh = _ladders(args)
    _check_ladders(levels, safeties)
    out.mkdir(parents=True, exist_ok=True)
    plan = _update_plan(out / "plan.json", args.only, levels, safeties, dt_mesh)
    knobs = [k for k in ("mesh", "dt") if k in plan]
    plan_dt_mesh = _planned_dt_mesh(plan, dt_mesh)
    runs = cv.plan(knobs, plan.get("mesh", []), plan.get("dt", {}).get("safeties", []), plan_dt_mesh)
    records = _impact_runs(runs, args.only, out / "runs", args.rerun)
    ladders = {knob: _analyse_knob(knob, records, out) for knob in knobs}
    uc = _unitcell(args, out)      # after the impact runs: the n = 768 reference solves take minutes
    scatter = _scatter(args, out / "runs", records)
    perturbed = [r for recs in scatter.values() for r in recs if r.perturbation]
    study_time = _study_time([r for _, r in records] + perturbed)
    write_report(doc, out, _command(), uc, ladders, study_time, args.quick, scatter, plan_dt_mesh)
    _log(f"report written to {doc}")
    return 0
