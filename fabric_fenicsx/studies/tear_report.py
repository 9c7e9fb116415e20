"""The tear test's report: a row per pull (tear.csv), the families compared at each size
(tear.json, printed: the panels without scatter, and the means over the strength-scatter
members), and the tear paths side by side (tear.png)."""
from __future__ import annotations

import math

import numpy as np

__all__ = ["COLUMNS", "MEMBER_MEASURES", "compare_families", "compare_members", "format_members", "format_report", "plot_paths"]

COLUMNS = ("family", "h", "seed", "n_cells", "notch", "tear_load", "peak_force", "work_per_length",
           "tear_length", "path_angle", "path_deviation", "path_spread", "n_tear_cells", "deleted",
           "eroded", "damage_dissipation", "erosion_energy", "viscous_dissipation", "end", "steps", "seconds",
           "tip_concentration", "tear_strain", "cut_strain")
"""tear.csv's columns (SI units: N, J/m, m, J, s; angles in degrees from the warp, x; seed -1:
no strength scatter; ``tip_concentration`` a ratio of strains,
:func:`~fabric_fenicsx.studies.tear.tip_concentration`; ``tear_strain`` the uncut section's mean
warp Green strain at the tear load; ``cut_strain`` the slit's cut yarns' mean warp strain away
from it over the section's then, :func:`~fabric_fenicsx.studies.tear.cut_yarn_cells`; a table
written before it had a column reads it as NaN)."""

AGREEMENT = 0.10
"""The families agree on a measure when its spread (max - min) is within this fraction of its mean."""


def _spread(values) -> float:
    x = np.asarray([v for v in values if math.isfinite(v)], float)
    return float((x.max() - x.min()) / abs(x.mean())) if x.size > 1 and x.mean() != 0 else math.nan


def compare_families(rows: list[dict]) -> dict:
    """Per cell size, over the deterministic rows (seed -1) of every family: the relative spread
    (max - min) / mean of the tear load, the peak force, the work per length and the tear strain, whether each is
    within :data:`AGREEMENT`, and the largest deviation of a path from the yarns (degrees)."""
    out = {}
    for h in sorted({r["h"] for r in rows}):
        at = [r for r in rows if r["h"] == h and int(r["seed"]) < 0]
        entry = {"families": [r["family"] for r in at]}
        for key in ("tear_load", "peak_force", "work_per_length", "tear_strain"):
            s = _spread([r.get(key, math.nan) for r in at])
            entry[f"{key}_spread"] = s
            entry[f"{key}_agrees"] = bool(s <= AGREEMENT) if math.isfinite(s) else None
        dev = [r["path_deviation"] for r in at if math.isfinite(r["path_deviation"])]
        entry["largest_path_deviation"] = max(dev) if dev else math.nan
        entry["paths_along_yarns"] = bool(dev) and max(dev) <= 10.0
        out[f"{h * 1e3:g} mm"] = entry
    return out


MEMBER_MEASURES = ("tear_load", "peak_force", "work_per_length", "path_deviation", "tip_concentration", "tear_strain")
"""The measures :func:`compare_members` averages over a family's members."""


def compare_members(rows: list[dict], twins: bool = False) -> dict:
    """Per cell size, over the strength-scatter members (seed >= 0) of every family, or with
    ``twins`` over its round-off twins (every seed, -1 the twin 0: members without scatter):
    each family's mean of each of :data:`MEMBER_MEASURES` with its 95 % interval
    (:func:`~fabric_fenicsx.studies.means.mean_of`) and its share of panels torn through; the
    relative spread (max - min) / mean of the families' means and whether it is within
    :data:`AGREEMENT`; and, since a seed is the same fabric on every mesh (the scatter is a field
    of the material, read by each mesh's cells), the paired differences of the tear load and the
    work per length between each two families with their 95 % intervals (not for twins, which
    pair nothing). Empty where no size has members. With the scatter a panel may break away
    from the slit first: the work per length then counts that crack's energy too (over the
    tear's length), and the tear load is the one to compare (docs/tear_test.md)."""
    from fabric_fenicsx.studies.means import mean_of

    out = {}
    for h in sorted({r["h"] for r in rows}):
        at = [r for r in rows if r["h"] == h and (twins or int(r["seed"]) >= 0)]
        families = list(dict.fromkeys(r["family"] for r in at))
        if not families or (twins and all(int(r["seed"]) < 0 for r in at)):
            continue
        entry = {"members": "round-off twins" if twins else "strength scatter", "families": {}, "paired": {}}
        for f in families:
            mine = [r for r in at if r["family"] == f]
            stats = {"n": len(mine), "torn_through": sum(r["end"].startswith("torn through") for r in mine) / len(mine)}
            for key in MEMBER_MEASURES:
                m = mean_of(r[key] for r in mine if math.isfinite(r.get(key, math.nan)))
                stats[key] = None if m is None else {"mean": m.mean, "ci95": m.half_width, "n": m.n}
            entry["families"][f] = stats
        for key in ("tear_load", "peak_force", "work_per_length", "tear_strain"):
            means = [s[key]["mean"] for s in entry["families"].values() if s[key] is not None]
            spread = _spread(means)
            entry[f"{key}_spread"] = spread
            entry[f"{key}_agrees"] = bool(spread <= AGREEMENT) if math.isfinite(spread) else None
        dev = [s["path_deviation"]["mean"] for s in entry["families"].values() if s["path_deviation"] is not None]
        entry["largest_mean_path_deviation"] = max(dev) if dev else math.nan
        by_seed = {(r["family"], int(r["seed"])): r for r in at}
        for i, a in enumerate([] if twins else families):
            for b in families[i + 1:]:
                seeds = sorted(s for f, s in by_seed if f == a and (b, s) in by_seed)
                pair = {}
                for key in ("tear_load", "work_per_length"):
                    d = mean_of(by_seed[(a, s)][key] - by_seed[(b, s)][key] for s in seeds
                                if math.isfinite(by_seed[(a, s)][key] - by_seed[(b, s)][key]))
                    pair[key] = None if d is None else {"mean": d.mean, "ci95": d.half_width, "n": d.n}
                entry["paired"][f"{a} - {b}"] = pair
        out[f"{h * 1e3:g} mm"] = entry
    return out


def _mean_text(m: dict | None, digits: int, of: int | None = None) -> str:
    """``mean +- half-width``, with ``(n k)`` where fewer than ``of`` members gave the measure."""
    if m is None:
        return "-"
    text = f"{m['mean']:.{digits}f}" + (f" +- {m['ci95']:.{digits}f}" if m["ci95"] is not None else "")
    return text + (f" (n {m['n']})" if of is not None and m["n"] != of else "")


def format_members(comparison: dict) -> str:
    """The members' means per size and family, then their spread and the paired differences."""
    lines = []
    for size, c in comparison.items():
        lines.append(f"{size}, {c.get('members', 'strength scatter')} members (means with 95 % intervals):")
        for f, s in c["families"].items():
            n = s["n"]
            lines.append(f"  {f:<16} n {n:>3}  tear load {_mean_text(s['tear_load'], 0, n)} N, peak "
                         f"{_mean_text(s['peak_force'], 0, n)} N, work {_mean_text(s['work_per_length'], 2, n)} J/m, "
                         f"off yarn {_mean_text(s['path_deviation'], 1, n)} deg, tip concentration "
                         f"{_mean_text(s.get('tip_concentration'), 3, n)}, tear strain {_mean_text(s.get('tear_strain'), 4, n)}, torn through {s['torn_through']:.0%}")
        lines.append(f"  spread of the means: tear load {c['tear_load_spread']:.1%}, peak {c['peak_force_spread']:.1%}, "
                     f"work per length {c['work_per_length_spread']:.1%}, tear strain {c['tear_strain_spread']:.1%} (agree within {AGREEMENT:.0%}: "
                     f"{c['tear_load_agrees']}, {c['peak_force_agrees']}, {c['work_per_length_agrees']})")
        for pair, d in c["paired"].items():
            lines.append(f"  paired {pair}: tear load {_mean_text(d['tear_load'], 0)} N, work "
                         f"{_mean_text(d['work_per_length'], 2)} J/m")
    return "\n".join(lines)


def format_report(rows: list[dict], comparison: dict) -> str:
    """A line per mesh, then the families' agreement per size."""
    lines = [f"{'mesh':<22}{'seed':>5}{'cells':>7}{'tear load (N)':>15}{'peak (N)':>10}{'work (J/m)':>12}"
             f"{'path (deg)':>11}{'off yarn':>9}{'tip conc.':>10}{'strain':>8}{'cut':>7}{'removed':>9}{'s':>7}  end"]
    for r in rows:
        lines.append(f"{r['family'] + ' ' + format(r['h'] * 1e3, 'g') + ' mm':<22}{int(r['seed']):>5}"
                     f"{int(r['n_cells']):>7}{r['tear_load']:>15.1f}{r['peak_force']:>10.1f}"
                     f"{r['work_per_length']:>12.2f}{r['path_angle']:>11.1f}{r['path_deviation']:>9.1f}"
                     f"{r.get('tip_concentration', math.nan):>10.3f}{r.get('tear_strain', math.nan):>8.4f}"
                     f"{r.get('cut_strain', math.nan):>7.2f}"
                     f"{int(r['deleted']) + int(r['eroded']):>9}{r['seconds']:>7.1f}  {r['end']}")
    for size, c in comparison.items():
        lines.append(f"{size}: spread over {', '.join(c['families'])}: tear load {c['tear_load_spread']:.1%}, "
                     f"peak {c['peak_force_spread']:.1%}, work per length {c['work_per_length_spread']:.1%} "
                     f"(tear strain {c['tear_strain_spread']:.1%}) (agree within {AGREEMENT:.0%}: {c['tear_load_agrees']}, {c['peak_force_agrees']}, "
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
