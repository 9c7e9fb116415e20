"""Twin runs: how fast an impact run amplifies a round-off perturbation (the
mesh-independence study, docs/mesh_independence.md).

Two runs of one scene differ only in the impact velocity, by a relative ``perturbation``
(1e-12: a round-off difference, like another MPI partition or summation order). Their
histories agree at first; where the discretised dynamics is unstable the difference grows
exponentially, d(t) ~ d0 exp(rate t), until it saturates at the size of the quantity itself. A
single run's result is an answer of the model only where the difference stays small up to the
end; :func:`report` says when it crossed each decade and at what rate it grew.

Pure numpy; :func:`run_twins` imports the impact simulation (DOLFINx) only when called.
The command line is ``fabric-fenicsx divergence SCENE``.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["PERTURBATION", "THRESHOLDS", "COLUMNS", "relative_difference", "crossing_times",
           "growth_rate", "report", "format_report", "run_twins"]

PERTURBATION = 1e-12
"""Relative change of the impact velocity of the second twin."""

THRESHOLDS = (1e-10, 1e-8, 1e-6, 1e-4, 1e-2)
"""Relative differences whose first crossing :func:`crossing_times` reports."""

COLUMNS = ("fabric_kinetic", "projectile_velocity", "central_deflection")
"""History columns compared (history.csv's names)."""


def relative_difference(a, b) -> np.ndarray:
    """|a - b| / max |a| over the run (a, b: one history column of each twin, same steps)."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    if a.shape != b.shape:
        raise ValueError(f"the twins' histories differ in length: {a.shape} against {b.shape}")
    scale = np.max(np.abs(a)) if a.size else 0.0
    return np.abs(a - b) / scale if scale > 0 else np.zeros_like(a)


def crossing_times(t, d, thresholds=THRESHOLDS) -> list[float | None]:
    """First time (s) at which the relative difference ``d`` exceeds each threshold (None:
    never)."""
    t, d = np.asarray(t, float), np.asarray(d, float)
    out = []
    for thr in thresholds:
        above = np.flatnonzero(d > thr)
        out.append(float(t[above[0]]) if above.size else None)
    return out


def growth_rate(t, d, lo: float = 1e-9, hi: float = 1e-4) -> float | None:
    """Exponential growth rate (1/s) of the difference while its running maximum climbs from
    ``lo`` to ``hi``: the least-squares slope of log(running max of d) against t over that
    stretch (the running maximum rides over the zero crossings of an oscillating difference).
    None if the difference never reaches ``hi`` or the stretch has fewer than 3 samples."""
    t, d = np.asarray(t, float), np.asarray(d, float)
    env = np.maximum.accumulate(d) if d.size else d
    if not d.size or env[-1] < hi:
        return None
    inside = (env >= lo) & (env <= hi)
    if np.count_nonzero(inside) < 3:
        return None
    slope, _ = np.polyfit(t[inside], np.log(env[inside]), 1)
    return float(slope)


def report(t, twin_a: dict, twin_b: dict, columns=COLUMNS, perturbation: float = PERTURBATION) -> dict:
    """Per history column: crossing times of :data:`THRESHOLDS`, the growth rate and its
    e-folding time, and the relative difference at the end. ``twin_a``, ``twin_b``: column ->
    values at the times ``t`` (the shorter run's steps)."""
    out = {"perturbation": perturbation, "thresholds": list(THRESHOLDS), "columns": {}}
    for c in columns:
        d = relative_difference(twin_a[c], twin_b[c])
        rate = growth_rate(t, d)
        out["columns"][c] = {"crossing_times_s": crossing_times(t, d), "growth_rate_per_s": rate,
                             "e_folding_time_s": 1.0 / rate if rate and rate > 0 else None,
                             "final_relative_difference": float(d[-1]) if d.size else 0.0}
    return out


def format_report(rep: dict) -> str:
    """The report as a table: one row per column, crossing times in microseconds."""
    head = " ".join(f"{thr:>8.0e}" for thr in rep["thresholds"])
    lines = [f"twin runs, impact velocity changed by {rep['perturbation']:g} of itself: first time "
             "(us) the relative difference passes",
             f"{'column':<22}{head}  {'e-folding (us)':>14}  {'at the end':>10}"]
    for c, r in rep["columns"].items():
        times = " ".join(f"{t * 1e6:8.1f}" if t is not None else f"{'-':>8}" for t in r["crossing_times_s"])
        ef = r["e_folding_time_s"]
        lines.append(f"{c:<22}{times}  {(f'{ef * 1e6:.1f}' if ef else '-'):>14}  "
                     f"{r['final_relative_difference']:>10.1e}")
    return "\n".join(lines)


def run_twins(scene, twin, out_dir: str | Path, verbose: bool = False):
    """Run ``scene`` and its ``twin`` (two :class:`~fabric_fenicsx.impact.scene.Scene`, the same
    but for the impact velocity) one after the other in this process, into ``out_dir``/a and
    ``out_dir``/b; returns (:func:`report`, the two summaries). Serial: the histories are
    those of rank 0."""
    from fabric_fenicsx.impact.simulation import ImpactSimulation

    v, v_twin = scene.projectile.velocity, twin.projectile.velocity
    perturbation = v_twin / v - 1.0
    if not (0 < abs(perturbation) < 1e-3):
        raise ValueError(f"the twin's impact velocity {v_twin!r} must differ from {v!r} by a small "
                         f"relative change (0 < |p| < 1e-3), got p = {perturbation:g}")
    out_dir = Path(out_dir)
    histories, summaries = [], []
    for name, sc in (("a", scene), ("b", twin)):
        sim = ImpactSimulation(sc, out_dir / name, verbose=verbose)
        try:
            summaries.append(sim.run())
        finally:
            sim.output.close()
        histories.append((list(sim.output.columns), np.array(sim.output.history_rows)))
    (cols, ha), (_, hb) = histories
    n = min(len(ha), len(hb))
    col = {c: i for i, c in enumerate(cols)}
    t = ha[:n, col["time"]]
    a, b = ({c: h[:n, col[c]] for c in COLUMNS} for h in (ha, hb))
    return report(t, a, b, perturbation=perturbation), summaries
