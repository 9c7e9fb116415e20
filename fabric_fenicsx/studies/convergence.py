"""``fabric-fenicsx convergence``: error against run time for each discretisation knob
(docs/convergence/discretisation.md).

Knobs and the quantities a user reads:

* unit-cell elements per half-yarn: P1, P2, V at fixed strain states, against a much finer cell;
* surrogate resolution: the table of ``docs/surrogate/surrogate_report.csv`` (made by
  ``fabric-fenicsx surrogate report``), included as it is;
* membrane mesh size at the impact point (``mesh.h_centre``) and
* time-step safety factor (``run.dt_safety``): residual velocity, absorbed energy and maximum
  deflection of the Y90 impact at 57.3 m/s (damage on) and at 34.5 m/s with damage off
  (elastic rebound), against the finest level and a Richardson extrapolation.

The command writes the run folders, CSV tables and log-log plots under ``--out`` and the
report ``--doc`` (default ``docs/convergence/discretisation.md``). Each impact run has its own folder; a run
whose ``summary.json`` (or recorded ``error.json``) exists with the same scene settings is not
run again, so an interrupted study resumes where it stopped.

The pure helpers (observed order, Richardson extrapolation, the "cheapest within 2 %" rule)
come first and import nothing heavy; DOLFINx is imported only when an impact run starts. This
module runs and analyses; the report (tables, plots, ``docs/convergence/discretisation.md``) is written by
:mod:`fabric_fenicsx.studies.convergence_report`, which imports this module's names, and the
command (options, resuming, the order of the steps) is :mod:`fabric_fenicsx.cli.convergence`,
which imports both.
"""

from __future__ import annotations

import csv
import datetime
import json
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np


# ============================================================================ pure helpers
ORDER_RANGE = (0.5, 4.0)
"""Observed orders outside this interval are not trusted for a Richardson extrapolation
(a ladder still in its pre-asymptotic range, or errors at the level of noise)."""


def observed_order(h, f, p_max: float = 20.0) -> float:
    """Observed order of convergence p from three levels, ``f(h) = f0 + C h^p``.

    ``h`` are the three level parameters (any order; positive, distinct), ``f`` the values.
    For a constant ratio r = h_c/h_m = h_m/h_f this is ``ln((f_c - f_m)/(f_m - f_f)) / ln r``;
    otherwise the equation ``(f_c - f_m)/(f_m - f_f) = (h_c^p - h_m^p)/(h_m^p - h_f^p)`` is
    solved for p in (0, p_max]. Returns ``nan`` when the differences change sign
    (oscillating, no asymptotic order), one of them is zero, or no p in range fits.
    """
    h = np.asarray(h, dtype=float)
    f = np.asarray(f, dtype=float)
    if h.shape != (3,) or f.shape != (3,):
        raise ValueError(f"observed_order needs three levels, got h {h.shape} and f {f.shape}")
    if not (np.all(np.isfinite(h)) and np.all(h > 0)):
        raise ValueError(f"level parameters must be positive and finite, got {h.tolist()}")
    order = np.argsort(h)[::-1]          # coarse, medium, fine
    h, f = h[order], f[order]
    if not (h[0] > h[1] > h[2]):
        raise ValueError(f"level parameters must be distinct, got {h.tolist()}")
    if not np.all(np.isfinite(f)):
        return math.nan
    d1, d2 = f[0] - f[1], f[1] - f[2]
    if d1 == 0.0 or d2 == 0.0 or (d1 > 0) != (d2 > 0):
        return math.nan
    ratio = d1 / d2
    r1, r2 = h[0] / h[1], h[1] / h[2]
    if math.isclose(r1, r2, rel_tol=1e-9):
        return math.log(ratio) / math.log(r1)

    def g(p: float) -> float:
        return (h[0] ** p - h[1] ** p) / (h[1] ** p - h[2] ** p) - ratio

    lo, hi = 1e-6, p_max
    if g(lo) > 0 or g(hi) < 0:          # g increases with p
        return math.nan
    from scipy.optimize import brentq
    return float(brentq(g, lo, hi, xtol=1e-12))


def richardson(h, f, p: float) -> float:
    """Richardson extrapolation to h -> 0 from the two finest of the given levels with order p:
    ``f_f + (f_f - f_m) / ((h_m/h_f)^p - 1)``."""
    h = np.asarray(h, dtype=float)
    f = np.asarray(f, dtype=float)
    if h.size < 2 or h.shape != f.shape:
        raise ValueError("richardson needs at least two levels with one value each")
    if not (math.isfinite(p) and p > 0):
        raise ValueError(f"order p must be positive and finite, got {p}")
    i = np.argsort(h)
    hf, hm, ff, fm = h[i[0]], h[i[1]], f[i[0]], f[i[1]]
    if not hm > hf > 0:
        raise ValueError(f"level parameters must be positive and distinct, got {h.tolist()}")
    return float(ff + (ff - fm) / ((hm / hf) ** p - 1.0))


def order_is_sensible(p: float, lo: float = ORDER_RANGE[0], hi: float = ORDER_RANGE[1]) -> bool:
    """Whether an observed order supports a Richardson extrapolation."""
    return bool(math.isfinite(p) and lo <= p <= hi)


def relative_error(values, reference: float) -> np.ndarray:
    """``|values - reference| / |reference|`` (``nan`` where a value is missing)."""
    v = np.asarray(values, dtype=float)
    if not (math.isfinite(reference) and reference != 0.0):
        raise ValueError(f"reference must be finite and nonzero, got {reference}")
    return np.abs(v - reference) / abs(reference)


def cheapest_within(costs, values, reference: float, tol: float = 0.02) -> int | None:
    """Index of the cheapest setting within ``tol`` (relative) of ``reference`` such that every
    costlier setting is also within ``tol`` (so a lucky crossing of a coarse, oscillating ladder
    is not chosen). ``None`` if no setting qualifies; missing values (nan) never qualify."""
    c = np.asarray(costs, dtype=float)
    v = np.asarray(values, dtype=float)
    if c.shape != v.shape or c.ndim != 1 or c.size == 0:
        raise ValueError("costs and values must be 1-d arrays of the same, nonzero length")
    if not tol > 0:
        raise ValueError(f"tol must be positive, got {tol}")
    ok = np.zeros(c.size, dtype=bool)
    finite = np.isfinite(v)
    ok[finite] = relative_error(v[finite], reference) <= tol
    by_cost = np.argsort(c, kind="stable")
    ok_sorted = ok[by_cost]
    # suffix "all ok" over the costlier settings
    tail_ok = np.logical_and.accumulate(ok_sorted[::-1])[::-1]
    hits = np.flatnonzero(tail_ok)
    return int(by_cost[hits[0]]) if hits.size else None


def ladder_analysis(h, values) -> dict:
    """Errors of one quantity along a ladder (``h`` finest = smallest): observed order of the
    three finest levels, Richardson value if that order is sensible, relative errors against
    the finest level and against the Richardson value."""
    h = np.asarray(h, dtype=float)
    v = np.asarray(values, dtype=float)
    # the finest level with a value (a failed finest run leaves the next one as reference)
    fine = int(np.argmin(np.where(np.isfinite(v), h, np.inf)))
    out = {"order": math.nan, "richardson": math.nan, "richardson_valid": False,
           "finest": float(v[fine]), "err_finest": np.full(v.size, math.nan),
           "err_richardson": np.full(v.size, math.nan)}
    if math.isfinite(v[fine]) and v[fine] != 0.0:
        out["err_finest"] = relative_error(v, v[fine])
    good = np.flatnonzero(np.isfinite(v))
    if good.size >= 3:
        three = good[np.argsort(h[good])[:3]]
        p = observed_order(h[three], v[three])
        out["order"] = p
        if order_is_sensible(p):
            f_inf = richardson(h[three], v[three], p)
            out["richardson"], out["richardson_valid"] = f_inf, True
            if f_inf != 0.0:
                out["err_richardson"] = relative_error(v, f_inf)
    return out


# ============================================================================ impact runs
CASES = {
    "damaged": {"label": "Y90, 57.3 m/s, damage on", "velocity": 57.3,
                "overrides": ["material.damage=true"]},
    "elastic": {"label": "Y90, 34.5 m/s, damage off (elastic rebound)", "velocity": 34.5,
                "overrides": ["material.damage=false"]},
}
SCATTER_PERTURBATIONS = tuple(k * 1e-12 for k in range(1, 9))
"""Relative changes of the damaged case's impact velocity for the run-to-run scatter: far below
any physical uncertainty, they show how much the tearing phase amplifies round-off."""
SCATTER_LEVELS_MM = (4.0, 2.83, 2.0, 1.41)
"""Mesh levels (h_centre, mm; dt_safety 0.8) at which the damaged case runs as an ensemble (the
unperturbed run of the mesh ladder and one run per perturbation): the ensemble means are what the
damaged mesh ladder can compare, to within their standard errors."""
SCENE = "demos/scenes/y90.toml"
STUDY_OVERRIDES = ["output.xdmf_interval=0", "output.png=false"]
QUANTITIES = ("residual_velocity", "absorbed_energy", "max_deflection")


def run_name(case: str, h_centre: float, dt_safety: float, perturbation: float = 0.0) -> str:
    """Folder name of one impact run, e.g. ``damaged-h2mm-s0.8`` (``-p1e-12``: V0 x (1 + 1e-12))."""
    return f"{case}-h{h_centre * 1e3:.4g}mm-s{dt_safety:.4g}" + (f"-p{perturbation:g}" if perturbation else "")


def scene_for(case: str, h_centre: float, dt_safety: float, scene_path: str = SCENE,
              perturbation: float = 0.0):
    from fabric_fenicsx.impact.scene import load_scene
    if case not in CASES:
        raise ValueError(f"unknown case {case!r}; valid: {list(CASES)}")
    v0 = CASES[case]["velocity"] * (1.0 + perturbation)
    return load_scene(scene_path, CASES[case]["overrides"] + STUDY_OVERRIDES
                      + [f"projectile.velocity={v0!r}", f"mesh.h_centre={h_centre!r}",
                         f"run.dt_safety={dt_safety!r}"])


def _history_max_deflection(folder: Path) -> float:
    with open(folder / "history.csv", newline="") as f:
        rows = csv.DictReader(f)
        values = [float(r["central_deflection"]) for r in rows]
    return max(values) if values else math.nan


def _load_done(folder: Path, settings: dict) -> dict | None:
    """The recorded outcome of a finished run with the same settings and model version, else None."""
    from fabric_fenicsx.provenance import load_if_same
    timing = folder / "timing.json"
    for name in ("summary.json", "error.json"):
        data = load_if_same(folder / name, settings)
        if data is not None and timing.is_file():
            with open(timing) as f:
                return {"outcome": data, "timing": json.load(f), "error": name == "error.json"}
    return None


@dataclass
class RunRecord:
    """What the study keeps of one impact run."""

    case: str
    h_centre: float
    dt_safety: float
    folder: str
    perturbation: float = 0.0
    error: str = ""
    values: dict = field(default_factory=dict)
    new: bool = False

    def get(self, key: str) -> float:
        v = self.values.get(key)
        return math.nan if v is None else float(v)


def is_stored(case: str, h_centre: float, dt_safety: float, runs_dir: Path, perturbation: float = 0.0) -> bool:
    """Whether this run is stored with the current settings and model version (reusable)."""
    settings = scene_for(case, h_centre, dt_safety, perturbation=perturbation).to_dict()
    return _load_done(runs_dir / run_name(case, h_centre, dt_safety, perturbation), settings) is not None


def run_one(case: str, h_centre: float, dt_safety: float, runs_dir: Path, rerun: bool = False,
            log=print, perturbation: float = 0.0) -> RunRecord:
    """One impact run into its own folder, or its recorded outcome if it was run before with
    the same settings. Wall and CPU (process) time of the whole call are kept in timing.json."""
    from fabric_fenicsx.impact.simulation import ImpactError, run_impact
    from fabric_fenicsx.provenance import code_fingerprint

    scene = scene_for(case, h_centre, dt_safety, perturbation=perturbation)
    settings = scene.to_dict()
    folder = runs_dir / run_name(case, h_centre, dt_safety, perturbation)
    done = None if rerun else _load_done(folder, settings)
    new = done is None
    if new:
        folder.mkdir(parents=True, exist_ok=True)
        for stale in ("summary.json", "error.json", "timing.json"):
            (folder / stale).unlink(missing_ok=True)
        log(f"  run {folder.name}: started {datetime.datetime.now():%H:%M:%S}")
        w0, c0 = time.perf_counter(), time.process_time()
        error = None
        try:
            run_impact(scene, folder, verbose=False)
        except (ImpactError, RuntimeError, ValueError, ArithmeticError) as err:
            # ImpactError and the library's solver errors (e.g. SurrogateError from the damage
            # iteration) are an outcome of the setting: recorded, and the study goes on.
            error = f"{type(err).__name__}: {err}"
        timing = {"wall_s": time.perf_counter() - w0, "cpu_s": time.process_time() - c0}
        if error is not None:
            with open(folder / "error.json", "w") as f:
                json.dump({"error": error, "settings": settings, **code_fingerprint()}, f, indent=1)
        with open(folder / "timing.json", "w") as f:
            json.dump(timing, f, indent=1)
        done = _load_done(folder, settings)
        status = f"FAILED ({error[:200]})" if error else "done"
        log(f"  run {folder.name}: {status} in {timing['wall_s']:.1f} s wall, {timing['cpu_s']:.1f} s CPU")
    else:
        log(f"  run {folder.name}: reused (same settings and model version), "
            f"{done['timing']['cpu_s']:.1f} s CPU")
    rec = RunRecord(case, h_centre, dt_safety, str(folder), perturbation, new=new)
    t = done["timing"]
    rec.values.update(wall_s=t["wall_s"], cpu_s=t["cpu_s"], model_version=done["outcome"].get("model_version"),
                      git_head=done["outcome"].get("git_head"))
    if done["error"]:
        rec.error = done["outcome"]["error"]
        return rec
    s = done["outcome"]
    defl = s.get("damage_onset_deflection")
    rec.values.update(
        residual_velocity=s["residual_velocity"], absorbed_energy=s["absorbed_energy"],
        eroded_cells=s.get("eroded_cells"),
        max_deflection=defl if defl is not None else _history_max_deflection(folder),
        deflection_kind="at damage onset" if defl is not None else "history maximum",
        n_cells=s["n_cells"], n_steps=s["n_steps"], dt=s["dt"], loop_wall_s=s["wall_time_s"],
        energy_error=s["energy_error"], end_reason=s["end_reason"], perforated=s["perforated"],
        end_time=s["end_time"], L_min=s["mesh"]["L_min"], xi=s["damping"]["xi"],
        surrogate_tiles_s=s["time_total_s"]["surrogate_tiles"], build_s=s["build_time_s"],
        finished=datetime.datetime.fromtimestamp((folder / "summary.json").stat().st_mtime,
                                                 datetime.timezone.utc).strftime("%Y-%m-%d %H:%M:%S"))
    return rec


# ============================================================================ unit cell
UNITCELL_STATES = [(E1, E2, alpha) for alpha in ((1.0, 1.0), (0.6, 1.0))
                   for E1, E2 in ((0.01, 0.0), (0.03, 0.01), (0.04, 0.04), (0.01, -0.03))]
"""Fixed membrane strain states (E1, E2) with frozen damage alpha: intact and damaged warp;
the first three in contact, (0.01, -0.03) separated (fill in compression, V = 0)."""
UNITCELL_LADDER = (6, 12, 24, 48, 96)
UNITCELL_REFERENCE = 768


def unitcell_study(ladder=UNITCELL_LADDER, reference: int = UNITCELL_REFERENCE,
                   states=UNITCELL_STATES, log=print) -> dict:
    """P1, P2, V of the unit cell at fixed states for each element count, against ``reference``.

    Every solve is cold (a new cell per state, so no warm start from another state); its wall
    and CPU time are recorded. Errors: |P_i - P_i,ref| / |P_i,ref| for P1, P2; for V relative
    to |V_ref| when the reference cell is in contact, else the absolute V (N) (the exact V of
    a separated cell is zero).
    """
    from fabric_fenicsx.material.fabric import zylon_as
    from fabric_fenicsx.material.unitcell import UnitCell
    fabric = zylon_as()
    ns = sorted(set(int(n) for n in ladder) | {int(reference)})
    if min(ns) < 2:
        raise ValueError(f"element counts must be >= 2, got {list(ladder)}")
    rows = []
    for n in ns:
        for E1, E2, alpha in states:
            cell = UnitCell(fabric, n_elements=n)
            w0, c0 = time.perf_counter(), time.process_time()
            r = cell.solve(E1, E2, alpha)
            if n >= 384:
                log(f"    n = {n}, E = ({E1:g}, {E2:g}), alpha = {alpha}: {time.process_time() - c0:.1f} s CPU")
            rows.append({"n": n, "E1": E1, "E2": E2, "alpha1": alpha[0], "alpha2": alpha[1],
                         "P1": r.P1, "P2": r.P2, "V": r.V, "in_contact": bool(r.in_contact),
                         "wall_s": time.perf_counter() - w0, "cpu_s": time.process_time() - c0})
        last = rows[-len(states):]
        log(f"  unit cell n = {n}: {sum(x['cpu_s'] for x in last):.2f} s CPU for {len(states)} states")
    ref = {(x["E1"], x["E2"], x["alpha1"], x["alpha2"]): x for x in rows if x["n"] == reference}
    for x in rows:
        rf = ref[(x["E1"], x["E2"], x["alpha1"], x["alpha2"])]
        for q in ("P1", "P2"):
            x[f"err_{q}"] = abs(x[q] - rf[q]) / abs(rf[q]) if rf[q] != 0 else abs(x[q])
        x["err_V"] = abs(x["V"] - rf["V"]) / abs(rf["V"]) if rf["in_contact"] and rf["V"] != 0 else abs(x["V"])
        x["err_V_kind"] = "relative" if rf["in_contact"] and rf["V"] != 0 else "absolute (N)"
        x["ref_in_contact"] = rf["in_contact"]
    summary = []
    for n in ns:
        sel = [x for x in rows if x["n"] == n]
        summary.append({"n": n, "wall_s": float(np.mean([x["wall_s"] for x in sel])),
                        "cpu_s": float(np.mean([x["cpu_s"] for x in sel])),
                        **{f"max_err_{q}": float(max(x[f"err_{q}"] for x in sel)) for q in ("P1", "P2")},
                        "max_err_V_rel": float(max([x["err_V"] for x in sel if x["err_V_kind"] == "relative"],
                                                   default=math.nan))})
    orders = {}
    fine = [n for n in ns if n != reference][-3:]
    for q in ("P1", "P2", "V_rel"):
        key = f"max_err_{q}"
        e = [next(s[key] for s in summary if s["n"] == n) for n in fine]
        # error ~ C h^p with h ~ 1/n: p = ln(e_c/e_m)/ln(n_m/n_c), averaged over the pairs
        ps = [math.log(e[i] / e[i + 1]) / math.log(fine[i + 1] / fine[i])
              for i in range(len(e) - 1) if e[i] > 0 and e[i + 1] > 0]
        orders[q] = float(np.mean(ps)) if ps else math.nan
    return {"rows": rows, "summary": summary, "orders": orders, "orders_from": fine,
            "reference": reference, "states": states}


# ============================================================================ impact ladders
MESH_LEVELS_MM = {"damaged": (4.0, 2.83, 2.0, 1.41, 1.0), "elastic": (4.0, 2.83, 2.0, 1.41, 1.0)}
"""h_centre ladders (mm), ratio sqrt(2), per case. 1 mm is the finest level the study's budget
(about 100 min CPU for the ladders and the ensembles on 2 shared cores) allows: measured cost
grows about 2 to 3 times per level of the damaged ladder."""
DT_SAFETIES = (0.9, 0.8, 0.6, 0.4, 0.2)
DT_MESH_MM = {"damaged": 1.41, "elastic": 2.0}
"""h_centre (mm) of each case's dt ladder: the damaged case on the recommended 1.41 mm mesh,
where single runs scatter by 0.13 % (on 2 mm by 1.6 %, which hides any dt effect below that);
the elastic case, which does not scatter, on 2 mm."""
DEFAULT_SAFETY = 0.8


def _cost_guess(case: str, h_mm: float, safety: float) -> float:
    """Rough relative cost of a run (steps ~ 1/(h s), cells grow slower than 1/h^2 on the
    graded mesh; damage-off runs go on to t_end): only used to order the runs."""
    return h_mm ** -1.6 / safety * (2.0 if case == "elastic" else 1.0)


def plan(knobs, mesh_levels_mm: dict, safeties, dt_mesh_mm: dict) -> list[tuple[str, str, float, float]]:
    """The impact runs of the study as (knob, case, h_centre in m, dt_safety), in the order that
    keeps an interrupted study most useful: first the three coarsest levels of every ladder
    (enough for an observed order), cheapest first; then the further mesh levels, level by level;
    then the further dt levels. ``mesh_levels_mm`` maps each case to its h_centre ladder in mm,
    ``dt_mesh_mm`` each case to the h_centre of its dt ladder; a case in neither is not run."""
    runs = []
    if "mesh" in knobs:
        for case in (c for c in CASES if c in mesh_levels_mm):
            for i, h in enumerate(sorted(mesh_levels_mm[case], reverse=True)):
                runs.append(((0 if i < 3 else 1, i, _cost_guess(case, h, DEFAULT_SAFETY)),
                             ("mesh", case, h * 1e-3, DEFAULT_SAFETY)))
    if "dt" in knobs:
        for case in (c for c in CASES if c in dt_mesh_mm):
            for i, s in enumerate(sorted(safeties, reverse=True)):
                runs.append(((0 if i < 3 else 2, i, _cost_guess(case, dt_mesh_mm[case], s)),
                             ("dt", case, dt_mesh_mm[case] * 1e-3, s)))
    runs.sort(key=lambda r: r[0] if r[0][0] else (0, 0, r[0][2]))
    return [r for _, r in runs]


def run_ladders(runs, runs_dir: Path, rerun: bool = False, log=print) -> list[tuple[str, RunRecord]]:
    """Run (or reuse) every planned impact run, strictly one after another."""
    out, cpu = [], 0.0
    seen: dict[tuple, RunRecord] = {}
    for i, (knob, case, h, s) in enumerate(runs, 1):
        log(f"[{i}/{len(runs)}] {knob}: {CASES[case]['label']}, h_centre = {h * 1e3:.4g} mm, dt_safety = {s:g}")
        key = (case, h, s)
        if key not in seen:
            seen[key] = run_one(case, h, s, runs_dir, rerun=rerun, log=log)
            cpu += seen[key].get("cpu_s")
        out.append((knob, seen[key]))
        log(f"  CPU time of the study's impact runs so far: {cpu / 60:.1f} min")
    return out


def analyse_ladder(records: list[RunRecord], param: str) -> dict:
    """Errors and observed orders of the three quantities along one ladder.
    ``param`` is "h_centre" or "dt_safety" (the level parameter, finest = smallest)."""
    recs = sorted(records, key=lambda r: -getattr(r, param))
    h = np.array([getattr(r, param) for r in recs])
    res = {"records": recs, "param": param, "h": h}
    for q in QUANTITIES:
        res[q] = ladder_analysis(h, [r.get(q) for r in recs])
    return res


def recommend(analysis: dict, tol: float = 0.02) -> dict:
    """Cheapest level (by CPU time) within tol of the converged residual velocity (Richardson
    value if its order is sensible, else the finest level), every costlier level within too."""
    a = analysis["residual_velocity"]
    recs = analysis["records"]
    ref, kind = (a["richardson"], "Richardson") if a["richardson_valid"] else (a["finest"], "finest level")
    if not math.isfinite(ref):
        return {"index": None, "reference": ref, "reference_kind": kind}
    costs = [r.get("cpu_s") for r in recs]
    values = [r.get("residual_velocity") for r in recs]
    idx = cheapest_within(costs, values, ref, tol)
    if idx is not None and not a["richardson_valid"] and values[idx] == ref:
        # only the reference level itself qualifies: that says nothing about convergence
        idx = None
    return {"index": idx, "reference": ref, "reference_kind": kind,
            "record": recs[idx] if idx is not None else None}


def scatter_spread(records) -> dict:
    """Mean, sample standard deviation, standard error of the mean and largest deviation from
    the mean of the residual velocity over an ensemble (relative to the mean), with the mean
    CPU time of a run; empty without two successful runs."""
    ok = [r for r in records if not r.error and math.isfinite(r.get("residual_velocity"))]
    v = np.array([r.get("residual_velocity") for r in ok], dtype=float)
    if v.size < 2 or v.mean() == 0.0:
        return {}
    mean = float(v.mean())
    std = float(v.std(ddof=1))
    return {"n": int(v.size), "mean": mean, "std_rel": std / abs(mean),
            "sem_rel": std / math.sqrt(v.size) / abs(mean),
            "max_rel": float(np.abs(v - mean).max() / abs(mean)),
            "cpu_s": float(np.mean([r.get("cpu_s") for r in ok]))}


def ensemble_recommendation(ensembles: dict, tol: float = 0.02, k: float = 2.0) -> dict:
    """The coarsest mesh level (h_centre in m -> :func:`scatter_spread`) whose ensemble mean is
    within ``tol`` of the finest ensemble's mean, every finer level within too (point estimates;
    None when only the finest qualifies). Per level: ``distance`` of its mean from the finest's
    (relative), its standard error ``se`` (both means' errors combined) and a ``verdict``:
    "within" if distance + k se <= tol, "beyond" if distance - k se > tol, else "undecided"."""
    levels = sorted((h for h, s in ensembles.items() if s), reverse=True)
    if len(levels) < 2:
        return {"h": None, "distance": {}, "se": {}, "verdict": {}}
    finest = ensembles[levels[-1]]
    ref = finest["mean"]
    dist = {h: abs(ensembles[h]["mean"] - ref) / abs(ref) for h in levels[:-1]}
    se = {h: math.hypot(ensembles[h]["sem_rel"] * ensembles[h]["mean"] / ref, finest["sem_rel"])
          for h in levels[:-1]}
    verdict = {h: "within" if dist[h] + k * se[h] <= tol else "beyond" if dist[h] - k * se[h] > tol
               else "undecided" for h in levels[:-1]}
    h_ok = None
    for h in reversed(levels[:-1]):          # from the second finest towards the coarsest
        if dist[h] > tol:
            break
        h_ok = h
    return {"h": h_ok, "distance": dist, "se": se, "verdict": verdict, "reference": ref,
            "finest": levels[-1]}
