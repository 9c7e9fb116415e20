"""Error against run time of an impact *statistic* (``fabric-fenicsx ladder``; docs/convergence.md):
after damage one run is one draw, so what converges with the mesh is a statistic with its
interval, not a run.

A *rung* is the scene on one mesh (``mesh.kind`` = a family, ``mesh.h_centre`` = a size) and,
optionally, one variant of a numerical knob (``run.damping=0.05``, ``material.erosion_strain=2``).
On every rung two statistics are estimated: the ballistic limit V50 with its 95 % interval
(:func:`~fabric_fenicsx.studies.v50.estimate`) and the mean residual velocity at one impact
velocity over an ensemble's members with its 95 % interval
(:func:`~fabric_fenicsx.studies.ensemble.run_members`). :func:`analyse` then gives, per family
and statistic, each size's error against the family's finest size (with the combined interval:
the estimates are independent), the cost in core-seconds, the family-to-family differences at
each size, each variant's change against its rung without the variant, and the size
:func:`recommend` picks: the coarsest whose estimates agree with the finest's within their
combined half-widths, for both statistics and every family.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["STATISTICS", "Rung", "rungs", "measure", "analyse", "recommend", "runs_for", "plot"]

STATISTICS = ("v50", "residual_velocity")
"""The statistics of a rung: V50 (m/s) and the mean residual velocity at the ensemble's impact velocity (m/s)."""


@dataclass(frozen=True)
class Rung:
    """The scene on one mesh (family ``family`` = ``mesh.kind``, size ``size`` = ``mesh.h_centre``
    in m), with ``variant`` (``SECTION.KEY=VALUE``, or "" for none)."""

    family: str
    size: float
    variant: str = ""

    @property
    def key(self) -> str:
        """The rung's folder: ``graded-1.41mm``, ``aligned-2mm-run.damping=0.05``."""
        return f"{self.family}-{self.size * 1e3:g}mm" + (f"-{self.variant}" if self.variant else "")

    def overrides(self) -> tuple[str, ...]:
        return (f"mesh.kind={self.family}", f"mesh.h_centre={self.size!r}", *([self.variant] if self.variant else []))


def rungs(families, sizes, variants=(), variant_size: float | None = None) -> list[Rung]:
    """Every family at every size (coarsest first), then every variant in every family at
    ``variant_size`` (one of ``sizes``)."""
    sizes = sorted(set(float(s) for s in sizes), reverse=True)
    if not families or not sizes:
        raise ValueError("a ladder needs at least one family and one size")
    if variants and variant_size not in sizes:
        raise ValueError(f"the variants' size {variant_size!r} must be one of the sizes {sizes}")
    ladder = ([Rung(f, s) for f in families for s in sizes]
              + [Rung(f, variant_size, v) for v in variants for f in families])
    keys = [r.key for r in ladder]
    same = sorted({k for k in keys if keys.count(k) > 1})
    if same:
        raise ValueError(f"rungs would share a folder ({', '.join(same)}): give each family, size and variant once, "
                         "sizes that differ in their first three digits (mm)")
    return ladder


def measure(rung: Rung, v50_rows: list[dict], v50_stop: str, members: list[dict]) -> dict:
    """A rung's row: each statistic's estimate with its 95 % interval (lo, hi; None for an open
    end or no estimate), the runs it took and their core-seconds. Where every run below a
    velocity held and every run above it went through (a scene that repeats run for run), the
    probit has no fit and V50 is a sharp limit: ``v50_kind`` "bracket", V50 the bracket's
    midpoint and lo, hi its ends (the limit lies inside for sure; else "probit", or None)."""
    from fabric_fenicsx.studies.ensemble import statistics
    from fabric_fenicsx.studies.v50 import report

    rep = report(v50_rows, v50_stop, rung.key)
    p = rep["probit"]
    if p is not None:
        v50, lo, hi, kind = p["v50"], p["v50_ci"][0], p["v50_ci"][1], "probit"
    elif rep["bracket"] is not None:       # report() gives a bracket only where the probit has no fit
        lo, hi = rep["bracket"]
        one_sided = lo is None or hi is None
        v50, kind = (None, "none in range") if one_sided else (0.5 * (lo + hi), "bracket")
    else:
        v50, lo, hi, kind = None, None, None, None
    ok = [m for m in members if "error" not in m]
    s = statistics([m["residual_velocity"] for m in ok])
    half = s["ci95"]
    return {
        "rung": rung.key, "family": rung.family, "size": rung.size, "variant": rung.variant,
        "v50": v50, "v50_lo": lo, "v50_hi": hi,
        "v50_sigma": None if p is None else p["sigma"], "v50_runs": rep["runs"],
        "v50_counted": rep["counts"]["perforated"] + rep["counts"]["held"], "v50_core_s": rep["core_seconds"],
        "v50_stop": v50_stop,
        "residual_velocity": s["mean"],
        "residual_velocity_lo": None if half is None else s["mean"] - half,
        "residual_velocity_hi": None if half is None else s["mean"] + half,
        "residual_velocity_sd": s["sd"], "residual_velocity_runs": len(members),
        "residual_velocity_core_s": float(sum(m.get("wall_time_s") or 0.0 for m in ok)),
        "v50_kind": kind,
    }


def _half(row: dict, stat: str) -> float | None:
    lo, hi = row.get(f"{stat}_lo"), row.get(f"{stat}_hi")
    return None if lo is None or hi is None else 0.5 * (hi - lo)


def _difference(a: dict, b: dict, stat: str) -> dict | None:
    """a - b of ``stat`` with the combined half-width sqrt(ha^2 + hb^2) (independent estimates) and
    whether |a - b| is within the sum of the half-widths (the estimates' intervals overlap)."""
    if a.get(stat) is None or b.get(stat) is None:
        return None
    ha, hb = _half(a, stat), _half(b, stat)
    d = a[stat] - b[stat]
    if ha is None or hb is None:
        return {"difference": d, "half_width": None, "agree": None}
    return {"difference": d, "half_width": math.hypot(ha, hb), "agree": abs(d) <= ha + hb}


def analyse(rows: list[dict]) -> dict:
    """From the rungs' rows (:func:`measure`): per family and statistic the error of each size
    against the family's finest (``errors``), the families' differences at each size
    (``families``) and each variant's change against its rung without the variant (``variants``)."""
    base = [r for r in rows if not r["variant"]]
    out = {"errors": [], "families": [], "variants": []}
    for family in dict.fromkeys(r["family"] for r in base):
        ladder = sorted((r for r in base if r["family"] == family), key=lambda r: r["size"])
        finest = ladder[0]
        for r in ladder:
            for stat in STATISTICS:
                d = _difference(r, finest, stat)
                out["errors"].append({"family": family, "size": r["size"], "statistic": stat,
                                      "core_s": r[f"{stat}_core_s"], "finest": finest["size"],
                                      **(d or {"difference": None, "half_width": None, "agree": None})})
    families = list(dict.fromkeys(r["family"] for r in base))
    for size in sorted({r["size"] for r in base}):
        at = {r["family"]: r for r in base if r["size"] == size}
        for i, f in enumerate(families):
            for g in families[i + 1:]:
                if f in at and g in at:
                    for stat in STATISTICS:
                        out["families"].append({"size": size, "pair": f"{f} - {g}", "statistic": stat,
                                                **(_difference(at[f], at[g], stat) or {})})
    for r in rows:
        if r["variant"]:
            plain = next((b for b in base if b["family"] == r["family"] and b["size"] == r["size"]), None)
            for stat in STATISTICS:
                d = None if plain is None else _difference(r, plain, stat)
                moved_less = (None if d is None or d["difference"] is None or _half(plain, stat) is None
                              else abs(d["difference"]) <= _half(plain, stat))
                out["variants"].append({"variant": r["variant"], "family": r["family"], "size": r["size"],
                                        "statistic": stat, **(d or {}), "within_interval": moved_less})
    return out


def recommend(analysis: dict) -> float | None:
    """The coarsest size whose estimates agree with their family's finest within the combined
    half-widths, for every statistic in every family, as do those of every size between (the
    finest itself when no coarser one does; None when the finest has no interval)."""
    errors = analysis["errors"]
    best = None
    for size in sorted({e["size"] for e in errors}):
        if any(e["agree"] is not True for e in errors if e["size"] == size):
            break
        best = size
    return best


def runs_for(width: float, rows: list[dict]) -> list[dict]:
    """What an estimate to a 95 % interval of full width ``width`` m/s costs on each rung, scaled
    from the interval the rung reached (the width falls as 1 / sqrt(runs)): runs and core-hours,
    for V50 and for the mean residual velocity."""
    out = []
    for r in rows:
        for stat, runs in (("v50", r["v50_counted"]), ("residual_velocity", r["residual_velocity_runs"])):
            half = _half(r, stat)
            if half is None or not runs or (stat == "v50" and r.get("v50_kind") == "bracket"):
                continue            # a sharp limit's bracket halves with each run: no 1 / sqrt(runs)
            n = max(runs, math.ceil(runs * (2.0 * half / width) ** 2))
            per_run = r[f"{stat}_core_s"] / max(r[f"{stat}_runs"], 1)
            out.append({"rung": r["rung"], "statistic": stat, "width": width, "runs": n,
                        "core_hours": n * per_run / 3600.0})
    return out


def plot(analysis: dict, path, title: str = "") -> None:
    """ladder.png: for V50 and the mean residual velocity, the error against the family's finest
    size (with its combined 95 % interval) against the core-hours the estimate took, a line per
    family, each point labelled with its size."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 3.8))
    names = {"v50": "V50", "residual_velocity": "mean residual velocity"}
    for ax, stat in zip(axes, STATISTICS):
        for i, family in enumerate(dict.fromkeys(e["family"] for e in analysis["errors"])):
            pts = [e for e in analysis["errors"] if e["family"] == family and e["statistic"] == stat
                   and e["difference"] is not None and e["size"] != e["finest"]]
            if not pts:
                continue
            x = [e["core_s"] / 3600.0 for e in pts]
            y = [e["difference"] for e in pts]
            ax.errorbar(x, y, yerr=[e["half_width"] or 0.0 for e in pts], fmt="o-", color=f"C{i}", capsize=3,
                        label=family)
            for xi, yi, e in zip(x, y, pts):
                ax.annotate(f"{e['size'] * 1e3:g} mm", (xi, yi), textcoords="offset points", xytext=(4, 4), fontsize=7)
        ax.axhline(0.0, color="0.5", lw=0.8)
        ax.set_xlabel("core-hours of the estimate")
        ax.set_title(names[stat], fontsize=10)
        ax.set_ylabel("error against the finest size (m/s)")
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=7)
        else:
            ax.text(0.5, 0.5, "no coarser size with an estimate", ha="center", transform=ax.transAxes)
    fig.suptitle(title or "error against run time")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
