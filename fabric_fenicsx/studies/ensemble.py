"""Ensembles: a scene's answer as a distribution over round-off-sized changes
(the mesh-independence study, docs/mesh_independence.md).

Where a run amplifies a round-off difference (``fabric-fenicsx divergence``), one run's residual
velocity is one draw: the Y90 scene's tearing is decided by which of many nearly equally
strained points of the principal yarns breaks first (docs/mesh_independence.md, section 9).
An ensemble runs the scene N times with the impact velocity changed by k x ``perturbation`` of
itself (k = 0, 1, -1, 2, -2, ...) and reports each member and the statistics of each quantity:
mean, standard deviation, the 95 % confidence interval of the mean (Student t) and the range.

The statistics are pure numpy/scipy; :func:`run_members` starts the members as separate
``fabric-fenicsx impact`` processes, ``jobs`` at a time (here or on a dask cluster), and reports
each as it finishes, so an interrupted ensemble keeps the members it has (and reuses them when it
is run again). The command line is ``fabric-fenicsx ensemble SCENE``.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

__all__ = ["PERTURBATION", "QUANTITIES", "offsets", "member_velocity", "statistics", "member_row",
           "summarise", "format_summary", "run_members", "plot"]

PERTURBATION = 1e-12
"""Relative step of the impact velocity between members (a round-off-sized change)."""

QUANTITIES = ("residual_velocity", "absorbed_energy", "viscous_dissipation", "viscous_share",
              "damage_onset_deflection", "damage_onset_radius", "removed_cells")
"""Per-member quantities the summary gives statistics of (SI units; removed = deleted + eroded;
the onset radius is the distance of the first damaged cell from the impact point)."""


def offsets(n: int) -> list[int]:
    """The members' multiples k of the perturbation: 0, 1, -1, 2, -2, ... (n of them)."""
    if n < 1:
        raise ValueError(f"an ensemble needs at least one member, got n = {n}")
    return [0] + [s * (i // 2 + 1) for i, s in zip(range(n - 1), (1, -1) * n)]


def member_velocity(v0: float, k: int, perturbation: float = PERTURBATION) -> float:
    """Impact velocity of member k: v0 (1 + k perturbation)."""
    return v0 * (1.0 + k * perturbation)


def statistics(values) -> dict:
    """n, mean, standard deviation (n - 1), the half-width of the 95 % confidence interval of the
    mean (Student t with n - 1 degrees of freedom), min, max and the range relative to |mean|, of
    the finite ``values``; sd and ci95 are None for fewer than two values."""
    from scipy.stats import t as student_t

    x = np.asarray([v for v in values if v is not None and math.isfinite(v)], float)
    out = {"n": int(x.size), "mean": None, "sd": None, "ci95": None, "min": None, "max": None,
           "relative_range": None}
    if not x.size:
        return out
    mean = float(x.mean())
    out.update(mean=mean, min=float(x.min()), max=float(x.max()))
    if mean != 0.0:
        out["relative_range"] = float((x.max() - x.min()) / abs(mean))
    if x.size > 1:
        sd = float(x.std(ddof=1))
        out.update(sd=sd, ci95=float(student_t.ppf(0.975, x.size - 1) * sd / math.sqrt(x.size)))
    return out


def member_row(k: int, velocity: float, summary: dict) -> dict:
    """One member's row from its run's summary.json."""
    energies = summary.get("energies", {})
    absorbed = summary["absorbed_energy"]
    viscous = energies.get("viscous_dissipation")
    return {"k": k, "velocity": velocity,
            "residual_velocity": summary["residual_velocity"],
            "absorbed_energy": absorbed,
            "viscous_dissipation": viscous,
            "viscous_share": viscous / absorbed if viscous is not None and absorbed > 0 else None,
            "damage_onset_deflection": summary.get("damage_onset_deflection"),
            "damage_onset_radius": summary.get("damage_onset_radius"),
            "removed_cells": (summary.get("deleted_cells") or 0) + (summary.get("eroded_cells") or 0),
            "end_reason": summary.get("end_reason"),
            "wall_time_s": summary.get("wall_time_s")}


def summarise(rows: list[dict], perturbation: float = PERTURBATION, first_seed: int | None = None) -> dict:
    """The ensemble's report: its members (rows) and :func:`statistics` of every quantity;
    ``first_seed``: the members are the fabrics of seeds first_seed, first_seed + 1, ... (a
    strength scatter) instead of velocities changed by k x ``perturbation``."""
    return {"perturbation": perturbation, "first_seed": first_seed, "members": rows,
            "statistics": {q: statistics([r.get(q) for r in rows]) for q in QUANTITIES},
            "end_reasons": {e: sum(str(r.get("end_reason")) == e for r in rows)
                            for e in sorted({str(r.get("end_reason")) for r in rows})}}


def format_summary(rep: dict) -> str:
    """The report as a table: one line per quantity (mean +- 95 % interval, sd, range)."""
    units = {"residual_velocity": ("m/s", 1.0), "absorbed_energy": ("J", 1.0),
             "viscous_dissipation": ("J", 1.0), "viscous_share": ("%", 100.0),
             "damage_onset_deflection": ("mm", 1e3),
             "damage_onset_radius": ("mm", 1e3), "removed_cells": ("", 1.0)}
    n = len(rep["members"])
    members = (f"impact velocity changed by k x {rep['perturbation']:g} of itself" if rep.get("first_seed") is None
               else f"the fabrics of scatter seeds from {rep['first_seed']}, at one impact velocity")
    lines = [f"ensemble of {n} members, {members}",
             f"{'quantity':<26}{'mean':>10}{'+- 95 %':>10}{'sd':>10}{'min':>10}{'max':>10}"]
    for q, s in rep["statistics"].items():
        unit, scale = units.get(q, ("", 1.0))
        cells = [s[c] for c in ("mean", "ci95", "sd", "min", "max")]
        text = "".join(f"{c * scale:>10.4g}" if c is not None else f"{'-':>10}" for c in cells)
        lines.append(f"{q + (f' ({unit})' if unit else ''):<26}{text}")
    lines.append("end: " + ", ".join(f"{e} {c}" for e, c in rep["end_reasons"].items()))
    return "\n".join(lines)


PAIRED = ("residual_velocity", "absorbed_energy", "viscous_share")
"""The quantities :func:`against` pairs."""


def read_members(path: str | Path) -> list[dict]:
    """The members of an ensemble's table (OUT/ensemble.csv) that ended without error, numbers as
    floats (empty cells: None) and ``seed`` as an int (None for round-off twins)."""
    import csv

    rows = []
    with open(path, newline="") as f:
        for r in csv.DictReader(f):
            if r.get("error"):
                continue
            row = {}
            for key, value in r.items():
                try:
                    row[key] = float(value) if value not in ("", None) else None
                except ValueError:
                    row[key] = value
            row["seed"] = int(row["seed"]) if row.get("seed") is not None else None
            rows.append(row)
    return rows


def against(rows: list[dict], others: list[dict]) -> dict:
    """Two ensembles of the same fabrics (on two meshes, or under two rules) paired by seed over
    the seeds both ran: per quantity of :data:`PAIRED`, :func:`~fabric_fenicsx.studies.means.paired`
    of this - other, with ``seeds`` the seeds paired."""
    from fabric_fenicsx.studies.means import paired

    mine = {r["seed"]: r for r in rows if r.get("seed") is not None}
    theirs = {r["seed"]: r for r in others if r.get("seed") is not None}
    seeds = sorted(set(mine) & set(theirs))
    out = {"seeds": seeds}
    for q in PAIRED:
        both = [s for s in seeds if mine[s].get(q) is not None and theirs[s].get(q) is not None]
        out[q] = paired([mine[s][q] for s in both], [theirs[s][q] for s in both]) if len(both) >= 3 else None
    return out


def format_against(pairs: dict, label: str) -> str:
    """:func:`against` as lines: this - ``label``, per quantity."""
    units = {"residual_velocity": ("m/s", 1.0), "absorbed_energy": ("J", 1.0), "viscous_share": ("%", 100.0)}
    lines = [f"paired by fabric with {label} ({len(pairs['seeds'])} seeds in common), this - that:"]
    for q in PAIRED:
        c = pairs.get(q)
        if c is None:
            lines.append(f"  {q}: fewer than 3 fabrics in common")
            continue
        unit, k = units[q]
        lines.append(f"  {q}: {c['mean_difference'] * k:+.2f} +- {c['difference_ci95'] * k:.2f} {unit} "
                     f"(sd {c['sd_difference'] * k:.2f}, correlation {c['correlation']:.2f}, n {c['n']})")
    return "\n".join(lines)


def run_members(scene: str, overrides: list[str], v0: float, n: int, out_dir: str | Path,
                jobs: int = 1, perturbation: float = PERTURBATION, on_member=None, executor=None,
                progress=None, first_seed: int | None = None) -> list[dict]:
    """Run the n members of an ensemble of the scene file ``scene`` (with ``overrides``, the
    impact velocity v0 (1 + k perturbation)) as ``fabric-fenicsx impact`` processes, ``jobs`` at
    a time (:func:`fabric_fenicsx.studies.runpool.run_all`, which reuses a member stored with the
    same settings), into ``out_dir``/member_<k>; ``on_member(row)`` is called as each one ends (a
    failed member's row has ``error``: the exit code and the last line of its log), then
    ``progress`` (a :class:`~fabric_fenicsx.studies.runpool.Progress`) counts it. ``executor``:
    where the processes run (:mod:`fabric_fenicsx.studies.executor`; default here). Returns the
    rows in the order of :func:`offsets`.

    ``first_seed``: None (members differ by their impact velocity, the twins of one fabric), or
    the members are different fabrics of the scene's strength scatter: member i (the i-th of
    :func:`offsets`) has ``material.seed`` = first_seed + i and the velocity v0 itself."""
    from fabric_fenicsx.studies.runpool import Run, run_all

    if first_seed is None:
        member = {f"member_{k}": (k, member_velocity(v0, k, perturbation), None) for k in offsets(n)}
    else:
        member = {f"seed_{first_seed + i}": (k, v0, first_seed + i) for i, k in enumerate(offsets(n))}
    runs = [Run(key, scene, (*overrides, f"projectile.velocity={v!r}",
                             *([] if seed is None else [f"material.seed={seed}"])))
            for key, (k, v, seed) in member.items()]
    rows = {}

    def done(run, summary, reused):
        k, v, seed = member[run.key]
        rows[k] = ({"k": k, "velocity": v, "error": summary["error"]} if "error" in summary
                   else member_row(k, v, summary))
        rows[k]["seed"] = seed if seed is not None else summary.get("scatter", {}).get("seed")
        if on_member is not None:
            on_member(rows[k])
        if progress is not None:
            progress.finished(summary, reused)

    if progress is not None:
        progress.expect(len(runs))
    run_all(runs, out_dir, jobs=jobs, on_done=done, executor=executor)
    return [rows[k] for k in offsets(n)]


def plot(rep: dict, path: str | Path, title: str = "") -> None:
    """Residual velocity and absorbed energy of each member against k, with the mean and its
    95 % interval (PNG)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ok = [r for r in rep["members"] if "error" not in r]
    fig, axes = plt.subplots(1, 2, figsize=(9, 3.4))
    for ax, q, label in zip(axes, ("residual_velocity", "absorbed_energy"),
                            ("residual velocity (m/s)", "absorbed energy (J)")):
        ax.plot([r["k"] for r in ok], [r[q] for r in ok], "o")
        s = rep["statistics"][q]
        if s["mean"] is not None:
            ax.axhline(s["mean"], color="k", lw=1)
            if s["ci95"] is not None:
                ax.axhspan(s["mean"] - s["ci95"], s["mean"] + s["ci95"], color="k", alpha=0.12)
        ax.set_xlabel(f"member k (impact velocity x (1 + k {rep['perturbation']:g}))")
        ax.set_ylabel(label)
        ax.ticklabel_format(axis="y", useOffset=False)
    fig.suptitle(title or "ensemble: mean and 95 % interval of the mean")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
