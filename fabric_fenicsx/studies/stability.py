"""``python -m fabric_fenicsx.studies.stability``: the impact driver on stiff and extreme cases
(docs/stability.md).

Each case is the Y90 scene (``demos/scenes/y90.toml``) on a coarse mesh with a short time
limit (:data:`BASE_OVERRIDES`), changed in one respect: the fabric's bending or stretch
stiffness, its crimp, the projectile's velocity, friction or edge, the material angle, the
impact point, the mesh, the damage switch or the projectile's size (:data:`CASES`). A case
whose fabric differs writes that fabric as TOML into its run folder and passes it with
``fabric.file``. The cases run one after the other, serially, on one rank, as
:func:`fabric_fenicsx.impact.simulation.run_impact` does (:func:`run_simulation`), keeping the
simulation so that its live cells can be split into connected pieces at the end
(:func:`free_fragments`: a piece holding no clamped node is a fragment cut loose).

Outcome of a case:

* ``completed``: the run ended by itself (time limit, perforation, rebound); its end reason,
  residual velocity, energy-balance error, steps, removed cells and the strain evaluations
  beyond the surrogate's table are recorded, and its ``history.csv`` is checked for NaN, a
  kinetic energy above the impact energy and an energy error above 5 %;
* ``stopped``: an :class:`fabric_fenicsx.impact.simulation.ImpactError`; its message is recorded and
  checked for the step, time and place the guards promise;
* ``failed``: any other exception (scene, unit cell, surrogate, ...), before or during the
  run: its type and message are recorded; whether that message is clear is a finding.

A case whose ``result.json`` exists with the same settings is not run again (``--rerun``
forces it), so an interrupted study resumes where it stopped. The study writes
``OUT/stability.csv`` (copied next to the plots), the plots in ``docs/stability/`` and the
report ``--doc`` (default ``docs/stability.md``), whose hand-written prose (the reading of each
case and the notes on the findings) is read from ``docs/stability/discussion.md``
(:data:`PROSE_FILE`).

Nothing heavy is imported at module level: DOLFINx is loaded when the first case runs.

The code is split by concern; every name stays importable from this module:

* :mod:`.stability_cases`: the base scene, the cases and their fabrics;
* this module: the runner (one case, the study, the outcome's verdict) and the command line;
* :mod:`.stability_report`: the CSV, the plots and the markdown report.
"""

from __future__ import annotations

import argparse
import datetime
import json
import math
import resource
import shutil
import sys
import time
import traceback
from pathlib import Path

import numpy as np

from fabric_fenicsx.provenance import code_fingerprint, load_if_same
from fabric_fenicsx.studies.stability_cases import (  # noqa: F401 - re-exported
    BASE_OVERRIDES, BASE_SCENE, BLOW_UP_RATIO, CANONICAL_COMMAND, CASES, EDGE_DISTANCE, EDGE_Y,
    ENERGY_LIMIT, SIDE, Case, _yarn_with_crimp, case_settings, make_fabric, scaled_stiffness,
    with_crimp)
from fabric_fenicsx.studies.stability_report import (  # noqa: F401 - re-exported
    _MESSAGE, CSV_COLUMNS, FINDINGS, PROSE_FILE, VERDICT_NOTES, _code_text, _f, _facts,
    _markdown_sections, _md_table, _outcome_text, _settings_text, _short, csv_row,
    parse_stop_message, plot_histories, read_history, read_prose, table_rows, write_csv,
    write_report)

__all__ = ["Case", "CASES", "BASE_SCENE", "BASE_OVERRIDES", "ENERGY_LIMIT", "scaled_stiffness",
           "with_crimp", "make_fabric", "case_settings", "run_case", "assess", "run_study",
           "write_csv", "plot_histories", "read_prose", "write_report", "main", "run_simulation",
           "free_fragments", "parse_stop_message"]


def _cpu_seconds() -> float:
    """CPU time of this process and its finished children (surrogate tile workers), s."""
    own = resource.getrusage(resource.RUSAGE_SELF)
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime



def run_case(case: Case, folder: Path, base_scene: str = BASE_SCENE,
             base_overrides: tuple[str, ...] = BASE_OVERRIDES) -> dict:
    """Run one case in ``folder`` and return its outcome record (also ``folder/result.json``).
    Every exception except KeyboardInterrupt is an outcome, not an error of the study."""
    from fabric_fenicsx.impact.simulation import ImpactError
    from fabric_fenicsx.impact.scene import load_scene

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    for stale in ("summary.json", "history.csv", "result.json"):
        (folder / stale).unlink(missing_ok=True)
    settings = case_settings(case, base_scene, base_overrides)
    overrides = list(settings["overrides"])
    record = {"name": case.name, "title": case.title, "settings": settings,
              "date": datetime.datetime.now().isoformat(timespec="seconds"),
              "status": None, "error_type": None, "message": None, "summary": None,
              **code_fingerprint()}
    wall0, cpu0 = time.perf_counter(), _cpu_seconds()
    scene = None
    keep: dict = {}
    try:
        if case.fabric:
            fab = make_fabric(case.fabric)
            fab.save(folder / "fabric.toml")
            overrides.append(f'fabric.file="{(folder / "fabric.toml").resolve()}"')
        scene = load_scene(base_scene, overrides)
        summary = run_simulation(scene, folder, keep)
        record["status"] = "completed"
        record["summary"] = _summary_digest(summary)
    except ImpactError as err:
        record.update(status="stopped", error_type=type(err).__name__, message=str(err),
                      stop=parse_stop_message(str(err)))
    except Exception as err:  # noqa: BLE001 - any failure is the case's outcome
        record.update(status="failed", error_type=type(err).__name__, message=str(err),
                      traceback=traceback.format_exc(limit=6))
    record["wall_time_s"] = time.perf_counter() - wall0
    record["cpu_time_s"] = _cpu_seconds() - cpu0
    if scene is not None:
        record["KE0"] = 0.5 * scene.projectile.mass * scene.projectile.velocity ** 2
    record["history"] = _history_digest(folder / "history.csv", record.get("KE0"))
    if "sim" in keep:
        try:
            record["fragments"] = free_fragments(keep["sim"])
        except Exception as err:  # noqa: BLE001 - a diagnosis must not lose the outcome
            record["fragments"] = {"error": f"{type(err).__name__}: {err}"}
    record["assessment"] = assess(record)
    (folder / "result.json").write_text(json.dumps(record, indent=1, default=_json_default))
    return record


def run_simulation(scene, folder: Path, keep: dict) -> dict:
    """:func:`fabric_fenicsx.impact.simulation.run_impact` on one rank, verbose off, with the simulation
    left in ``keep["sim"]`` (also when it raises) for :func:`free_fragments`."""
    from mpi4py import MPI

    from fabric_fenicsx.impact.simulation import ImpactSimulation

    sim = ImpactSimulation(scene, folder, MPI.COMM_SELF, verbose=False)
    keep["sim"] = sim
    try:
        return sim.run()
    finally:
        sim.output.close()


def free_fragments(sim) -> dict:
    """The live cells of a (serial) simulation split into pieces connected through shared
    nodes. A piece holding no clamped node is a *free fragment* (e.g. a plug punched out by
    the projectile). Returns the pieces (largest first: cells, nodes, anchored, largest |u|
    and mean normal velocity of its nodes) and whether the live node with the largest
    displacement (what the blow-up guard looks at) lies in a free fragment."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    m = sim.membrane
    cells = m.V.dofmap.list.array.reshape(m.n_cells, -1)   # node (block) indices per cell
    n_nodes = sim.n_nodes
    live = np.flatnonzero(sim.live_cells)
    rows = np.repeat(live, cells.shape[1])
    cols = m.n_cells + cells[live].ravel()
    size = m.n_cells + int(cells.max()) + 1
    graph = coo_matrix((np.ones(rows.size), (rows, cols)), shape=(size, size))
    _, label = connected_components(graph, directed=False)
    anchored = set(label[m.n_cells + np.unique(sim.cd.clamped // 3)].tolist())
    u = sim.cd.u.reshape(-1, 3)
    vz = sim.cd.v.reshape(-1, 3)[:, 2]
    pieces = []
    for lab in np.unique(label[live]):
        nodes = np.unique(cells[live[label[live] == lab]])
        nodes = nodes[nodes < n_nodes]
        pieces.append({"cells": int(np.count_nonzero(label[live] == lab)), "nodes": int(nodes.size),
                       "anchored": bool(lab in anchored),
                       "max_displacement": float(np.abs(u[nodes]).max(initial=0.0)),
                       "mean_velocity_z": float(vz[nodes].mean()) if nodes.size else 0.0})
    pieces.sort(key=lambda p: -p["cells"])
    out = {"pieces": pieces, "free_fragments": sum(not p["anchored"] for p in pieces),
           "free_cells": sum(p["cells"] for p in pieces if not p["anchored"]),
           "largest_displacement_in_free_fragment": False}
    live_nodes = np.flatnonzero(sim.live_nodes)
    if live_nodes.size:
        k = live_nodes[np.argmax(np.abs(u[live_nodes]).max(axis=1))]
        piece_labels = {label[m.n_cells + k]} if k < n_nodes else set()
        out["largest_displacement"] = float(np.abs(u[k]).max())
        out["largest_displacement_in_free_fragment"] = not (piece_labels & anchored)
    return out


def _json_default(x):
    if isinstance(x, np.integer):
        return int(x)
    if isinstance(x, np.floating):
        return float(x)
    if isinstance(x, np.ndarray):
        return x.tolist()
    raise TypeError(f"not JSON serialisable: {type(x).__name__}")


def _summary_digest(s: dict) -> dict:
    """The summary's numbers the study reports."""
    keys = ("v0", "residual_velocity", "perforated", "absorbed_energy", "max_deflection",
            "damage_onset_time", "damage_onset_deflection", "energy_error", "end_reason", "end_time", "wall_time_s",
            "build_time_s", "n_cells", "n_steps", "dt", "dt_initial", "deleted_cells", "eroded_cells")
    out = {k: s.get(k) for k in keys}
    sur = s.get("surrogate", {})
    out["points_beyond_table"] = sur.get("points_beyond_table_damage_off")
    out["points_below_table"] = sur.get("points_compressed_below_table")
    out["surrogate_solves"] = sur.get("solves_this_run")
    out["surrogate_tile_seconds"] = s.get("time_total_s", {}).get("surrogate_tiles")
    out["surrogate_range"] = sur.get("range")
    out["n_dt_changes"] = len(s.get("dt_changes", []))
    return out


def _history_digest(path: Path, KE0: float | None) -> dict:
    """NaN check and extremes of a run's history.csv."""
    h = read_history(path)
    if not h:
        return {"rows": 0}
    values = np.column_stack(list(h.values()))
    out = {"rows": int(values.shape[0]), "finite": bool(np.all(np.isfinite(values))),
           "t_last": float(h["time"][-1]),
           "max_energy_error": float(np.nanmax(h["energy_error"])),
           "last_energy_error": float(h["energy_error"][-1]),
           "max_central_deflection": float(np.nanmax(h["central_deflection"])),
           "min_velocity": float(np.nanmin(h["projectile_velocity"])),
           "last_velocity": float(h["projectile_velocity"][-1])}
    if KE0:
        kinetic = h["fabric_kinetic"] + h["projectile_kinetic"]
        out["max_kinetic_over_KE0"] = float(np.nanmax(kinetic) / KE0)
    return out


def assess(record: dict) -> dict:
    """Verdict of one outcome: ``ok`` (completed within the limits, or stopped with a message
    naming step, time, place and cause) or ``finding`` with the reasons."""
    problems = []
    hist = record.get("history", {})
    status = record["status"]
    if hist.get("rows") and not hist.get("finite", True):
        problems.append("non-finite values (NaN/inf) in history.csv")
    if status == "completed":
        s = record["summary"]
        nums = [s[k] for k in ("residual_velocity", "energy_error", "end_time")]
        if not all(isinstance(x, (int, float)) and math.isfinite(x) for x in nums):
            problems.append(f"non-finite summary values {nums}")
        if s["energy_error"] > ENERGY_LIMIT:
            problems.append(f"energy error {s['energy_error']:.3%} > {ENERGY_LIMIT:.0%} and the run "
                            "did not stop")
        if hist.get("max_kinetic_over_KE0", 0.0) > BLOW_UP_RATIO:
            problems.append(f"kinetic energy reached {hist['max_kinetic_over_KE0']:.3g} KE_0 without a stop")
        kind = "completed"
    elif status == "stopped":
        stop = parse_stop_message(record["message"])
        if stop is None:
            problems.append("ImpactError message does not name step, time and place")
        frag = record.get("fragments") or {}
        if (stop is not None and stop["cause"].startswith("blow-up")
                and frag.get("largest_displacement_in_free_fragment")):
            problems.append(
                f"the blow-up guard tripped on a free fragment ({frag['free_cells']} live cells in "
                f"{frag['free_fragments']} piece(s) cut loose from the clamped fabric, largest "
                f"displacement {frag['largest_displacement']:.4g} m), not on numerical trouble: the "
                "message calls it a blow-up and proposes dt/damping/penalty/mesh fixes that do not apply")
        kind = "stopped with a message naming step, time, place and cause"
    else:
        problems.append(f"{record['error_type']} raised outside the impact guards")
        kind = "failed"
    return {"verdict": "finding" if problems else "ok", "kind": kind, "problems": problems}


def _load_done(folder: Path, settings: dict) -> dict | None:
    return load_if_same(folder / "result.json", settings)


# ============================================================================ the study
def run_study(cases, out: Path, rerun: bool = False, log=print) -> list[dict]:
    """Run (or load) the cases one after the other; returns their records in order."""
    records = []
    for case in cases:
        folder = Path(out) / case.name
        done = None if rerun else _load_done(folder, case_settings(case))
        if done is not None:
            log(f"stability: {case.name}: stored result ({done['status']}) reused")
            records.append(done)
            continue
        log(f"stability: {case.name}: {case.title} ...")
        rec = run_case(case, folder)
        log(f"stability: {case.name}: {_outcome_text(rec)} [{rec['wall_time_s']:.1f} s wall, "
            f"{rec['cpu_time_s']:.1f} s CPU]")
        records.append(rec)
    return records



# ============================================================================ command line
def _names(text: str) -> list[str]:
    names = [n.strip() for n in text.split(",") if n.strip()]
    valid = [c.name for c in CASES]
    bad = [n for n in names if n not in valid]
    if bad or not names:
        raise argparse.ArgumentTypeError(f"unknown case(s) {bad or text!r}; valid: {', '.join(valid)}")
    return names


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", default="out/stability",
                        help="folder of the case run folders and stability.csv (default out/stability)")
    parser.add_argument("--doc", default="docs/stability.md",
                        help="report file (default docs/stability.md); plots go to its folder "
                             "<doc without .md>/ (docs/stability/)")
    parser.add_argument("--only", type=_names, default=None, metavar="NAME,...",
                        help="run only these cases (the report still lists every case stored with "
                             "this model version)")
    parser.add_argument("--rerun", action="store_true", help="run the cases again even if stored")
    parser.add_argument("--no-doc", action="store_true", help="run the cases, write no report")


def run(args: argparse.Namespace) -> int:
    out = Path(args.out)
    todo = [c for c in CASES if args.only is None or c.name in args.only]
    t0, cpu0 = time.perf_counter(), _cpu_seconds()
    run_study(todo, out, rerun=args.rerun)
    print(f"stability: this invocation {time.perf_counter() - t0:.0f} s wall, "
          f"{_cpu_seconds() - cpu0:.0f} s CPU", flush=True)
    # the report covers every case with a stored result (run now or before)
    records = [r for r in (_load_done(out / c.name, case_settings(c)) for c in CASES) if r is not None]
    for rec in records:   # the checks of this version of the study
        rec["assessment"] = assess(rec)
    write_csv(out / "stability.csv", records)
    if args.no_doc:
        return 0
    doc = Path(args.doc)
    plot_dir = doc.with_suffix("")
    plots = plot_histories(records, out, plot_dir)
    csv_copy = plot_dir / "stability.csv"
    shutil.copyfile(out / "stability.csv", csv_copy)
    command = (f".venv/bin/python -m fabric_fenicsx.studies.stability --out {args.out} --doc {args.doc}"
               + (f" --only {','.join(args.only)}" if args.only else "") + (" --rerun" if args.rerun else ""))
    write_report(doc, out, records, CASES, command, plots, csv_copy)
    print(f"stability: {len(records)} case(s) in {doc} and {out / 'stability.csv'}", flush=True)
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m fabric_fenicsx.studies.stability",
                                     description="Impact runs on stiff and extreme cases.")
    add_arguments(parser)
    return run(parser.parse_args(argv))


if __name__ == "__main__":
    sys.exit(main())
