"""The ballistic limit and the residual velocity of a scene as statistics
(``fabric-fenicsx v50``; docs/ballistic_limit.md).

Shots are impact runs chosen by Neyer's sequential design (:mod:`~fabric_fenicsx.studies.neyer`)
``jobs`` at a time, each run a new member of the scene's ensemble: with a strength scatter
(``material.scatter``) member i is the fabric of seed ``first_seed + i``; without one it is the
impact velocity changed by i x 1e-12 of itself (a twin, :mod:`~fabric_fenicsx.studies.ensemble`),
so that two shots at one velocity are two draws. Each run stops as soon as the fabric holds the
projectile (``run.stop_when_held``): only its outcome and, when it perforates, its residual
velocity count.

A run's outcome (:func:`outcome`): *perforated* (the summary's ``perforated``); *held* (it ended
held or rebounding, or at the time limit with the projectile moving back: the fabric has stopped
it); *undecided* (at the time limit with the projectile still moving forward: a longer run
would tell; reported, not counted, as are failed runs).

After each batch the counted outcomes are fitted (:func:`~fabric_fenicsx.studies.probit.fit_probit`);
the estimate stops when V50's 95 % interval is no wider than ``ci`` m/s, at ``max_runs``
runs, when the design ends (a sharp limit, or no bracket between the floor and the ceiling), or
when more than half of four or more runs counted no outcome (undecided or failed: the scene's
``run.t_end`` is too short for it, or it fails). The design is a pure function of the shots so far and batches
run to their end before the next is chosen, so a resumed estimate chooses the same runs and
reuses the stored ones (:func:`~fabric_fenicsx.studies.runpool.run_all`). Resumed with another
``jobs``, the design would choose other velocities for the stored runs' folders and run them
again over them: a complete run stored in a batch's folder is taken at its own velocity instead
(:func:`stored_velocities`), and the design goes on from it.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from fabric_fenicsx.studies.neyer import NeyerDesign, Shot

__all__ = ["COLUMNS", "TWIN_STEP", "outcome", "member_run", "stored_velocities", "estimate", "report", "format_report", "format_interval",
           "table_cells", "write_table", "write_report", "write_stopped", "thesis_points", "plot", "figure"]

COLUMNS = ("run", "seed", "velocity", "outcome", "residual_velocity", "absorbed_energy", "viscous_dissipation",
           "removed_cells", "damage_onset_radius", "damage_extent_radius", "end_reason", "phase", "wall_time_s",
           "error")
"""Columns of v50.csv, one row per run (SI units: m/s, J, m); the viscous damping's share of the
absorbed energy is booked with it. How the fabric failed, beside the
outcome: the cells removed, the distance from the impact point of the first damaged cell and of
the farthest one (a hole at the projectile's face keeps the damage within a few cells of its
edge; a tear runs along the yarns towards the clamps)."""

MODE_QUANTITIES = ("removed_cells", "damage_onset_radius", "damage_extent_radius", "absorbed_energy")
"""Per-run quantities whose mean :func:`report` gives for the held and the perforating runs."""

TWIN_STEP = 1e-12
"""Relative change of the impact velocity between members without a strength scatter."""


def outcome(summary: dict) -> str:
    """``perforated``, ``held``, ``undecided`` or ``failed`` (see the module's docstring)."""
    if "error" in summary:
        return "failed"
    if summary.get("perforated"):
        return "perforated"
    if summary.get("end_reason") in ("held", "rebound") or (summary.get("residual_velocity") or 0.0) < 0.0:
        return "held"
    return "undecided"


def member_run(scene: str, overrides, i: int, v: float, first_seed: int | None):
    """Run ``i`` of the estimate at ``v`` m/s: a :class:`~fabric_fenicsx.studies.runpool.Run`
    into folder ``run_<i>``."""
    from fabric_fenicsx.studies.runpool import Run

    extra = ["run.stop_when_held=true"]
    if first_seed is None:
        extra.append(f"projectile.velocity={v * (1.0 + i * TWIN_STEP)!r}")
    else:
        extra += [f"projectile.velocity={v!r}", f"material.seed={first_seed + i}"]
    return Run(f"run_{i:03d}", str(scene), (*overrides, *extra))


def stored_velocities(scene: str, overrides, out_dir, start: int, stop: int, first_seed: int | None) -> list[float]:
    """The velocities (m/s, as the design chose them) of the complete runs stored in run_<start>,
    run_<start + 1>, ... (up to run_<stop - 1>) for this estimate, until the first folder without
    one: a run is taken when :func:`member_run` at its stored velocity has exactly its settings
    and model version (:func:`~fabric_fenicsx.studies.runpool.stored_summary`)."""
    from fabric_fenicsx.studies.runpool import stored_summary

    found = []
    for i in range(start, stop):
        folder = Path(out_dir) / f"run_{i:03d}"
        try:
            ran = float(json.loads((folder / "summary.json").read_text())["settings"]["projectile"]["velocity"])
        except (OSError, ValueError, KeyError, TypeError):
            break
        nominal = ran if first_seed is not None else ran / (1.0 + i * TWIN_STEP)
        # the design's velocity, to the digits it was rounded to
        match = next((v for v in (round(nominal, d) for d in range(2, 13))
                      if stored_summary(member_run(scene, overrides, i, v, first_seed), out_dir) is not None), None)
        if match is None:
            break
        found.append(match)
    return found


def _row(i: int, v: float, seed, phase: str, summary: dict) -> dict:
    """Run i's row: an ensemble member's row (:func:`~fabric_fenicsx.studies.ensemble.member_row`)
    with the outcome, the design's phase and the damage's extent."""
    from fabric_fenicsx.studies.ensemble import member_row

    row = {"run": i, "seed": seed, "velocity": v, "outcome": outcome(summary), "phase": phase}
    if "error" in summary:
        return {**row, "error": summary["error"]}
    member = member_row(i, v, summary)
    del member["k"]
    return {**member, **row, "damage_extent_radius": summary.get("damage_extent_radius")}


def _shots(rows) -> list[Shot]:
    return [Shot(r["velocity"], {"perforated": True, "held": False}.get(r["outcome"])) for r in rows]


def estimate(scene: str, overrides, out_dir, design: NeyerDesign, ci: float = 2.0, max_runs: int = 40,
             jobs: int = 1, first_seed: int | None = None, executor=None, on_run=None, on_batch=None,
             on_start=None, on_done=None, slots=None, stop=None) -> dict:
    """Run the estimate into ``out_dir`` (run_<i> folders). ``on_start(n)`` precedes a batch of
    ``n`` runs, ``on_run(row)`` follows each run's end (after ``on_done(run, summary, reused)``,
    the pool's own callback), ``on_batch(rows, fit)`` each batch. ``slots`` and ``stop`` are
    shared with estimates running beside this one (:func:`~fabric_fenicsx.studies.runpool.run_all`).
    Returns ``{"rows": [...], "stop": why it stopped}``."""
    from fabric_fenicsx.studies.probit import fit_probit
    from fabric_fenicsx.studies.runpool import run_all

    if ci <= 0 or max_runs < 1 or jobs < 1:
        raise ValueError(f"need ci > 0, max_runs >= 1 and jobs >= 1, got {ci!r}, {max_runs!r}, {jobs!r}")
    rows: list[dict] = []
    while True:
        if len(rows) >= max_runs:
            return {"rows": rows, "stop": f"{max_runs} runs (--max-runs) reached"}
        shots = _shots(rows)
        phase = design.phase(shots)
        velocities = design.next(shots, min(jobs, max_runs - len(rows)))
        stored = stored_velocities(scene, overrides, out_dir, len(rows), len(rows) + len(velocities), first_seed)
        velocities = stored + velocities[len(stored):]
        if not velocities:
            why = {"sharp": f"a sharp limit: no overlap of the outcomes in a gap of {design.resolution:g} m/s",
                   "unbracketed": "no bracket: perforated at the floor or held at the ceiling"}[phase]
            return {"rows": rows, "stop": why}
        batch = {}
        for j, v in enumerate(velocities):
            i = len(rows) + j
            batch[f"run_{i:03d}"] = (i, v, None if first_seed is None else first_seed + i)
        runs = [member_run(scene, overrides, i, v, first_seed) for i, v, _ in batch.values()]
        new = {}

        def done(run, summary, reused):
            i, v, seed = batch[run.key]
            new[i] = _row(i, v, seed, phase, summary)
            if on_done is not None:
                on_done(run, summary, reused)
            if on_run is not None:
                on_run(new[i])

        if on_start is not None:
            on_start(len(runs))
        run_all(runs, out_dir, jobs=len(runs), on_done=done, executor=executor, slots=slots, stop=stop)
        rows += [new[i] for i in sorted(new)]
        counted = [r for r in rows if r["outcome"] in ("perforated", "held")]
        fit = fit_probit([r["velocity"] for r in counted], [r["outcome"] == "perforated" for r in counted],
                         intervals="v50") if counted else None
        if on_batch is not None:
            on_batch(rows, fit)
        lost = len(rows) - len(counted)
        if len(rows) >= 4 and 2 * lost > len(rows):
            return {"rows": rows, "stop": f"{lost} of {len(rows)} runs counted no outcome (undecided or failed): "
                                          "see their end_reason and error; an undecided run needs a longer run.t_end"}
        if fit is not None and fit.width <= ci and not _violations(counted):
            return {"rows": rows, "stop": f"V50's 95 % interval ({fit.width:.2f} m/s) is within --ci {ci:g} m/s"}


def _bins(counted) -> list[dict]:
    from fabric_fenicsx.studies.probit import binned

    v = np.array([r["velocity"] for r in counted], float)
    y = np.array([r["outcome"] == "perforated" for r in counted])
    if v.size == 0:
        return []
    n_bins = max(1, min(8, int(round(math.sqrt(v.size)))))
    edges = np.linspace(v.min(), v.max(), n_bins + 1) if v.max() > v.min() else np.array([v.min(), v.min() + 1e-9])
    return binned(v, y, edges)


def _violations(counted) -> list:
    from fabric_fenicsx.studies.probit import monotone_violations

    return monotone_violations(_bins(counted))


def report(rows: list[dict], stop: str, scene_name: str = "") -> dict:
    """v50.json: the probit fit with every interval, the binned fractions, whether the outcomes
    rise with velocity, the Lambert-Jonas fit of the perforating runs, counts and cost."""
    from fabric_fenicsx.studies.lambert_jonas import fit_lambert_jonas
    from fabric_fenicsx.studies.probit import LEVEL, fit_probit, monotone_violations, separation

    counted = [r for r in rows if r["outcome"] in ("perforated", "held")]
    v = [r["velocity"] for r in counted]
    y = [r["outcome"] == "perforated" for r in counted]
    fit = fit_probit(v, y) if counted else None
    bins = _bins(counted)
    violations = monotone_violations(bins)
    monotone = not violations and (fit is not None or (counted and separation(v, y) is not None))
    through = [r for r in rows if r["outcome"] == "perforated" and r.get("residual_velocity") is not None]
    lj, lj_error = None, None
    try:
        lj = fit_lambert_jonas([r["velocity"] for r in through], [r["residual_velocity"] for r in through]).to_dict()
    except ValueError as err:
        lj_error = str(err)
    wall = [r.get("wall_time_s") or 0.0 for r in rows]
    modes = {}
    for kind in ("held", "perforated"):
        mine = [r for r in rows if r["outcome"] == kind]
        modes[kind] = {"n": len(mine), "velocity": _range([r["velocity"] for r in mine]),
                       **{q: _mean([r.get(q) for r in mine]) for q in MODE_QUANTITIES}}
    return {
        "scene": scene_name, "level": LEVEL, "stop": stop,
        "answer": "v50" if fit is not None and monotone else "per-velocity",
        "probit": fit.to_dict() if fit is not None else None,
        "bracket": None if fit is not None or not counted else separation(v, y),
        "monotone": bool(monotone),
        "violations": [{"slower": a, "faster": b} for a, b in violations],
        "bins": bins,
        "lambert_jonas": lj, "lambert_jonas_error": lj_error,
        "counts": {k: sum(r["outcome"] == k for r in rows) for k in ("perforated", "held", "undecided", "failed")},
        "modes": modes, "runs": len(rows), "core_seconds": float(sum(wall)),
    }


def _mean(values):
    x = [v for v in values if v is not None and math.isfinite(v)]
    return float(np.mean(x)) if x else None


def _range(values):
    return [float(min(values)), float(max(values))] if values else None


def format_interval(ci) -> str:
    """``[lo, hi]`` of an interval to two decimals, an end that is None as ``open``."""
    lo, hi = ci
    return f"[{'open' if lo is None else f'{lo:.2f}'}, {'open' if hi is None else f'{hi:.2f}'}]"


def _fmt(x, scale: float, unit: str) -> str:
    return "-" if x is None else f"{x * scale:.1f}{unit}"


def format_report(rep: dict) -> str:
    """The report in a few lines."""
    c = rep["counts"]
    lines = [f"{rep['runs']} runs: {c['perforated']} perforated, {c['held']} held, {c['undecided']} undecided, "
             f"{c['failed']} failed; {rep['core_seconds'] / 3600:.3g} core-hours of solving (the runs' wall_time_s, "
             f"process start-up not counted); stopped: {rep['stop']}"]
    p = rep["probit"]
    if p is not None:
        lines += [f"V50   {p['v50']:8.2f} m/s  95 % {format_interval(p['v50_ci'])}",
                  f"V10   {p['v10']:8.2f} m/s  95 % {format_interval(p['v10_ci'])}",
                  f"V90   {p['v90']:8.2f} m/s  95 % {format_interval(p['v90_ci'])}",
                  f"sigma {p['sigma']:8.2f} m/s  95 % {format_interval(p['sigma_ci'])}  (probit, profile-likelihood intervals)"]
    elif rep["bracket"] is not None:
        lines.append(f"no probit fit: every held run is slower than every perforating one, bracket "
                     f"{format_interval(rep['bracket'])} m/s")
    if not rep["monotone"]:
        lines.append("the outcomes do not rise with velocity within their intervals: read the probability of "
                     "perforation per velocity, not one V50:")
    lines += [f"  {b['lo']:7.2f}-{b['hi']:7.2f} m/s: {b['perforated']}/{b['n']} perforated "
              f"({100 * b['fraction']:.0f} %, 95 % {100 * b['ci'][0]:.0f}-{100 * b['ci'][1]:.0f} %)" for b in rep["bins"]]
    for kind, m in rep["modes"].items():
        if m["n"] and m["removed_cells"] is not None:
            lines.append(f"{kind:>10}: {m['n']} runs at {m['velocity'][0]:.2f}-{m['velocity'][1]:.2f} m/s, mean "
                         f"{_fmt(m['removed_cells'], 1, '')} cells removed, first damage "
                         f"{_fmt(m['damage_onset_radius'], 1e3, ' mm')} and farthest {_fmt(m['damage_extent_radius'], 1e3, ' mm')} "
                         f"from the impact point, absorbed {_fmt(m['absorbed_energy'], 1, ' J')}")
    lj = rep["lambert_jonas"]
    if lj is not None:
        lines.append(f"Lambert-Jonas: a {lj['a']:.3f} {format_interval(lj['a_ci'])}, p {lj['p']:.2f} {format_interval(lj['p_ci'])}, "
                     f"Vbl {lj['vbl']:.2f} m/s {format_interval(lj['vbl_ci'])} (bootstrap), rms {lj['rms']:.2f} m/s, "
                     f"{lj['n']} runs" + (f"; at a bound of its range, not determined by these runs: "
                                          f"{', '.join(lj['at_bound'])}" if lj["at_bound"] else ""))
    else:
        lines.append(f"Lambert-Jonas: not fitted ({rep['lambert_jonas_error']})")
    return "\n".join(lines)


def table_cells(row: dict) -> list:
    """One row of v50.csv: ``row``'s values in :data:`COLUMNS` order, None as an empty cell."""
    return ["" if row.get(c) is None else row[c] for c in COLUMNS]


def write_table(path, rows) -> None:
    """v50.csv with ``rows`` in run order, written atomically (the rows appended as each run ended
    are replaced by the same rows sorted)."""
    import csv
    import io

    from fabric_fenicsx.studies.runpool import write_atomic

    text = io.StringIO()
    writer = csv.writer(text, lineterminator="\n")
    writer.writerow(COLUMNS)
    for r in sorted(rows, key=lambda r: r["run"]):
        writer.writerow(table_cells(r))
    write_atomic(path, text.getvalue())


def write_report(out, rows: list[dict], stop: str, scene_name: str, extra: dict, with_rows: bool = False,
                 reference: dict | None = None) -> dict:
    """v50.csv, v50.json (:func:`report` updated with ``extra``; with ``with_rows`` also the rows)
    and v50.png of the same ``rows`` into the folder ``out``, so that the three always describe
    the same runs (also when an estimate stops early); returns the report."""
    from fabric_fenicsx.studies.runpool import write_atomic

    out = Path(out)
    write_table(out / "v50.csv", rows)
    rep = {**report(rows, stop, scene_name), **extra}
    write_atomic(out / "v50.json", json.dumps({**rep, "rows": rows} if with_rows else rep, indent=1, default=str))
    plot(rep, rows, out / "v50.png", title=f"{scene_name}: {len(rows)} runs", reference=reference)
    return rep


def write_stopped(write, seen: dict, err: BaseException) -> None:
    """After ``err`` (an interruption, a stopped pool) ended an estimate early: ``write(rows,
    stop)`` (:func:`write_report` with the estimate's settings) of the runs ``seen`` ({index:
    row}), so that v50.csv, v50.json and v50.png describe the runs that ended. A write that fails
    (a full disk) is left: ``err`` is what gets reported."""
    rows = [seen[i] for i in sorted(seen)]
    why = "interrupted" if isinstance(err, KeyboardInterrupt) else f"stopped ({err})"
    try:
        write(rows, f"{why} after {len(rows)} runs: run it again to go on (its complete runs are reused)")
    except OSError:
        pass


def thesis_points(scene_name: str) -> dict:
    """The residual velocities of Tables 4-6 for scene ``scene_name`` (Y90 also the
    experiment's) as ``{label: (velocities, residuals)}``, the runs that bounced back left out:
    the ``reference`` of :func:`plot`."""
    from fabric_fenicsx.studies.chapter4 import THESIS, VELOCITIES

    thesis = THESIS.get(scene_name.upper(), {})
    points = {}
    for key, label in (("residual", "thesis (Table 4-6)"), ("residual_experiment", "experiment (Table 4)")):
        pts = [(v, r) for v, r in zip(VELOCITIES, thesis.get(key, ())) if r is not None]
        if pts:
            points[label] = tuple(zip(*pts))
    return points


def plot(rep: dict, rows: list[dict], path, title: str = "", reference: dict | None = None) -> None:
    """v50.png: left, each counted run's outcome against velocity, the probit curve with V50's
    interval, and the binned fractions with their intervals; right, the residual velocity of the
    perforating runs with the Lambert-Jonas curve and ``reference`` points ({label: (v, vr)}). The
    legends sit below the plots, where they hide no run."""
    import matplotlib.pyplot as plt

    fig = figure(rep, rows, title, reference)
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)


def figure(rep: dict, rows: list[dict], title: str = "", reference: dict | None = None):
    """The figure of :func:`plot` (the caller closes it)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from scipy.stats import norm

    from fabric_fenicsx.studies.lambert_jonas import residual_velocity

    fig, (ax, bx) = plt.subplots(1, 2, figsize=(10, 3.8))
    counted = [r for r in rows if r["outcome"] in ("perforated", "held")]
    v = np.array([r["velocity"] for r in rows], float)
    lo, hi = (v.min(), v.max()) if v.size else (0.0, 1.0)
    grid = np.linspace(lo - 0.1 * (hi - lo + 1), hi + 0.1 * (hi - lo + 1), 200)
    n_through = sum(r["outcome"] == "perforated" for r in counted)
    ax.plot([r["velocity"] for r in counted], [float(r["outcome"] == "perforated") for r in counted], "k|",
            ms=14, label=f"runs: {n_through} perforated (at 1), {len(counted) - n_through} held (at 0)")
    other = [r for r in rows if r["outcome"] not in ("perforated", "held")]
    if other:
        ax.plot([r["velocity"] for r in other], [0.5] * len(other), "rx", label="undecided or failed")
    for b in rep["bins"]:
        ax.errorbar(b["v_mean"], b["fraction"], yerr=[[b["fraction"] - b["ci"][0]], [b["ci"][1] - b["fraction"]]],
                    fmt="s", color="tab:orange", capsize=3, label="fraction per bin (95 %)" if b is rep["bins"][0] else None)
    p = rep["probit"]
    if p is not None:
        ax.plot(grid, norm.cdf((grid - p["v50"]) / p["sigma"]), "b-", label=f"probit: V50 {p['v50']:.1f} m/s")
        l, h = p["v50_ci"]
        ax.axvspan(l if l is not None else grid[0], h if h is not None else grid[-1], color="b", alpha=0.12,
                   label="V50 95 %")
    ax.set_xlabel("impact velocity (m/s)")
    ax.set_ylabel("probability of perforation")
    ax.set_ylim(-0.08, 1.08)
    ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.18), ncol=2)
    through = [r for r in rows if r["outcome"] == "perforated" and r.get("residual_velocity") is not None]
    bx.plot([r["velocity"] for r in through], [r["residual_velocity"] for r in through], "ko", ms=4, label="runs")
    lj = rep["lambert_jonas"]
    if lj is not None:
        top = max(r["velocity"] for r in through)
        g = np.linspace(min(lj["vbl"], grid[0]), top, 200)
        bx.plot(g, residual_velocity(g, lj["a"], lj["p"], lj["vbl"]), "b-",
                label=f"Lambert-Jonas: Vbl {lj['vbl']:.1f} m/s, a {lj['a']:.2f}, p {lj['p']:.2f}")
        if reference:                                  # beyond the runs: an extrapolation, dashed
            g = np.linspace(top, 130.0, 100)
            bx.plot(g, residual_velocity(g, lj["a"], lj["p"], lj["vbl"]), "b--", lw=0.8)
    for (label, (rv, rr)), marker in zip((reference or {}).items(), ("^", "v", "D")):
        bx.plot(rv, rr, marker, mfc="none", label=label)
    bx.set_xlabel("impact velocity (m/s)")
    bx.set_ylabel("residual velocity (m/s)")
    bx.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.18), ncol=1)
    fig.suptitle(title or "ballistic limit")
    fig.tight_layout()
    return fig
