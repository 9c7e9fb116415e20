"""The tear test's report: a row per mesh (tear.csv), the families compared at each size
(tear.json, printed), and the tear paths side by side (tear.png)."""
from __future__ import annotations

import math

import numpy as np

__all__ = ["COLUMNS", "compare_families", "format_report", "plot_paths"]

COLUMNS = ("family", "h", "seed", "n_cells", "notch", "tear_load", "peak_force", "work_per_length",
           "tear_length", "path_angle", "path_deviation", "path_spread", "n_tear_cells", "deleted",
           "eroded", "damage_dissipation", "erosion_energy", "viscous_dissipation", "end", "steps", "seconds")
"""tear.csv's columns (SI units: N, J/m, m, J, s; angles in degrees from the warp, x; seed -1:
no strength scatter)."""

AGREEMENT = 0.10
"""The families agree on a measure when its spread (max - min) is within this fraction of its mean."""


def _spread(values) -> float:
    x = np.asarray([v for v in values if math.isfinite(v)], float)
    return float((x.max() - x.min()) / abs(x.mean())) if x.size > 1 and x.mean() != 0 else math.nan


def compare_families(rows: list[dict]) -> dict:
    """Per cell size, over the deterministic rows (seed -1) of every family: the relative spread
    (max - min) / mean of the tear load, the peak force and the work per length, whether each is
    within :data:`AGREEMENT`, and the largest deviation of a path from the yarns (degrees)."""
    out = {}
    for h in sorted({r["h"] for r in rows}):
        at = [r for r in rows if r["h"] == h and int(r["seed"]) < 0]
        entry = {"families": [r["family"] for r in at]}
        for key in ("tear_load", "peak_force", "work_per_length"):
            s = _spread([r[key] for r in at])
            entry[f"{key}_spread"] = s
            entry[f"{key}_agrees"] = bool(s <= AGREEMENT) if math.isfinite(s) else None
        dev = [r["path_deviation"] for r in at if math.isfinite(r["path_deviation"])]
        entry["largest_path_deviation"] = max(dev) if dev else math.nan
        entry["paths_along_yarns"] = bool(dev) and max(dev) <= 10.0
        out[f"{h * 1e3:g} mm"] = entry
    return out


def format_report(rows: list[dict], comparison: dict) -> str:
    """A line per mesh, then the families' agreement per size."""
    lines = [f"{'mesh':<22}{'seed':>5}{'cells':>7}{'tear load (N)':>15}{'peak (N)':>10}{'work (J/m)':>12}"
             f"{'path (deg)':>11}{'off yarn':>9}{'removed':>9}{'s':>7}  end"]
    for r in rows:
        lines.append(f"{r['family'] + ' ' + format(r['h'] * 1e3, 'g') + ' mm':<22}{int(r['seed']):>5}"
                     f"{int(r['n_cells']):>7}{r['tear_load']:>15.1f}{r['peak_force']:>10.1f}"
                     f"{r['work_per_length']:>12.2f}{r['path_angle']:>11.1f}{r['path_deviation']:>9.1f}"
                     f"{int(r['deleted']) + int(r['eroded']):>9}{r['seconds']:>7.1f}  {r['end']}")
    for size, c in comparison.items():
        lines.append(f"{size}: spread over {', '.join(c['families'])}: tear load {c['tear_load_spread']:.1%}, "
                     f"peak {c['peak_force_spread']:.1%}, work per length {c['work_per_length_spread']:.1%} "
                     f"(agree within {AGREEMENT:.0%}: {c['tear_load_agrees']}, {c['peak_force_agrees']}, "
                     f"{c['work_per_length_agrees']}); largest path deviation from the yarns "
                     f"{c['largest_path_deviation']:.1f} deg")
    return "\n".join(lines)


def plot_paths(cells: dict, path, title: str = "") -> None:
    """The panels side by side, a row per cell size and a column per family: each cell coloured
    by its warp alpha, removed cells white with a grey edge, the slit's cells black.
    ``cells``: {(family, h): {"corners", "alpha1", "removed", "slit"}}."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import PolyCollection

    families = list(dict.fromkeys(f for f, _ in cells))
    sizes = sorted({h for _, h in cells}, reverse=True)
    fig, axes = plt.subplots(len(sizes), len(families), figsize=(3.2 * len(families), 3.3 * len(sizes)),
                             squeeze=False)
    for i, h in enumerate(sizes):
        for j, f in enumerate(families):
            ax = axes[i][j]
            ax.set_axis_off()
            c = cells.get((f, h))
            if c is None:
                continue
            colours = plt.cm.viridis(np.clip(c["alpha1"], 0.0, 1.0))
            colours[c["removed"]] = (1.0, 1.0, 1.0, 1.0)
            colours[c["slit"]] = (0.0, 0.0, 0.0, 1.0)
            edges = (0.6, 0.6, 0.6) if len(colours) < 2500 else "face"   # fine meshes: cells alone
            ax.add_collection(PolyCollection(c["corners"] * 1e3, facecolors=colours, edgecolors=edges,
                                             linewidths=0.1))
            ax.autoscale_view()
            ax.set_aspect("equal")
            ax.set_title(f"{f} {h * 1e3:g} mm", fontsize=9)
    sm = plt.cm.ScalarMappable(cmap="viridis", norm=plt.Normalize(0, 1))
    fig.colorbar(sm, ax=axes, shrink=0.6, label="warp alpha (white: removed; black: the slit)")
    fig.suptitle(title or "tear paths (warp along x, pulled along x)", fontsize=10)
    fig.savefig(path, dpi=90)
    plt.close(fig)
