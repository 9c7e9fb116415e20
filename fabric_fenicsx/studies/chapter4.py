"""The thesis's chapter 4 as studies (docs/validation.md): which runs each study makes, the thesis's
numbers beside them, and the tables, plot and checklist of docs/validation.md.

Studies (``fabric-fenicsx study NAME``): ``table4`` (Y90 at the five velocities of Table 4),
``table5`` (XY0 next to Y90), ``table6`` (XY45 next to XY0, and Y0), ``friction`` (Y90 and XY0
at 57.3 m/s, projectile friction 0.1, 0.5, 2.0; Sec. 4.4.1), ``fillet`` (Y90 at 57.3 m/s, fillet
0, 0.8, 2 mm; Sec. 4.4.3), ``v50`` (the ballistic limit of each scene as a statistic,
:mod:`~fabric_fenicsx.studies.v50`) and ``chapter4`` (all of them). A run is named by its settings
(``Y90-v57.3``, ``XY0-v57.3-mu2``, ``Y90-v57.3-fillet0.8mm``), so studies that need the same run
share it; a ballistic limit's design starts from the tightest bracket the table's runs give
(:func:`v50_start`).

Nothing here is tuned: the scenes are run as they are (``demos/scenes``), with the user's
``--set`` overrides applied to every run.
"""
from __future__ import annotations

from pathlib import Path

from fabric_fenicsx.studies.runpool import Run

__all__ = ["SCENES", "VELOCITIES", "THESIS", "STUDIES", "FRICTIONS", "FILLETS", "V50_BRACKET", "run_key", "plan",
           "member_key", "value", "v50_start", "row", "fmt", "table_md", "variant_md", "checklist", "plot_residual",
           "plot_damage", "incomplete_cases"]

SCENE_DIR = Path(__file__).resolve().parents[2] / "demos" / "scenes"
SCENES = {"Y90": "y90.toml", "XY0": "xy0.toml", "XY45": "xy45.toml", "Y0": "y0.toml"}
"""The four scenes of Table 3 (files in demos/scenes)."""

VELOCITIES = (34.5, 39.78, 57.3, 83.06, 123.69)
"""Impact velocities of Tables 4-6 (m/s)."""

FRICTIONS = (0.1, 0.5, 2.0)
"""Projectile-fabric friction of Sec. 4.4.1."""

FILLETS = (0.0, 0.8e-3, 2e-3)
"""Fillet radii of the impacting edge of Sec. 4.4.3 (m)."""

THESIS = {  # Tables 4-6 (thesis simulations; Y90 also the experiment); None = bounced back
    "Y90": {"residual": (None, 10.0, 32.6, 66.83, 110.0), "absorbed": (21.69, 27.5, 41.18, 45.13, 59.3),
            "deflection_mm": (50.91, 51.85, 51.75, 51.13, 51.25),
            "residual_experiment": (None, 5.67, 29.99, 61.54, 97.99),
            "absorbed_experiment": (21.69, 28.75, 44.22, 57.88, 105.66)},
    "XY0": {"residual": (13.89, 21.82, 43.1, 71.18, 114.9), "absorbed": (18.5, 20.52, 26.45, 33.99, 38.9),
            "deflection_mm": (26.5, 26.86, 27.66, 28.26, 25.28)},
    "XY45": {"residual": (11.13, 19.27, 38.5, 69.97, 113.9), "absorbed": (19.78, 22.5, 33.4, 37.16, 43.15),
             "deflection_mm": (28.5, 28.69, 31.63, 29.9, 26.27)},
    "Y0": {},
}

V50_BRACKET = (20.0, 60.0)
"""Where the ballistic-limit design of a scene starts when its table runs give no bracket
(m/s); it widens the bracket if it must."""

STUDIES = ("table4", "table5", "table6", "friction", "fillet", "v50", "chapter4")

TABLE_SCENES = {"table4": ("Y90",), "table5": ("XY0", "Y90"), "table6": ("XY45", "XY0", "Y0")}


def run_key(scene: str, v0: float, friction: float = 0.5, fillet: float = 0.0) -> str:
    """The folder name of a run: the scene, V0 and what differs from the scene file."""
    key = f"{scene}-v{v0:g}"
    if friction != 0.5:
        key += f"-mu{friction:g}"
    if fillet:
        key += f"-fillet{fillet * 1e3:g}mm"
    return key


def _run(scene: str, v0: float, overrides, friction: float = 0.5, fillet: float = 0.0) -> Run:
    extra = [f"projectile.velocity={v0!r}"]
    if friction != 0.5:
        extra.append(f"projectile.friction={friction!r}")
    if fillet:
        extra.append(f"projectile.fillet={fillet!r}")
    return Run(run_key(scene, v0, friction, fillet), str(SCENE_DIR / SCENES[scene]),
               (*overrides, *extra))


def member_key(key: str, i: int) -> str:
    """The folder of member ``i`` of run ``key`` (member 0 is the run itself)."""
    return key if i == 0 else f"{key}-m{i}"


def _members(run: Run, n: int) -> list[Run]:
    """Run ``run`` as ``n`` members: with a strength scatter, member i is the fabric of the
    scene's seed + i; without one, its impact velocity changed by k x 1e-12 of itself
    (k = 0, 1, -1, 2, ...: :func:`~fabric_fenicsx.studies.ensemble.offsets`)."""
    from fabric_fenicsx.impact.scene import load_scene
    from fabric_fenicsx.studies.ensemble import member_velocity, offsets

    if n == 1:
        return [run]
    material = load_scene(run.scene, list(run.overrides)).material
    velocity = [o for o in run.overrides if o.startswith("projectile.velocity=")][-1]
    v = float(velocity.split("=", 1)[1])
    members = [run]
    for i, k in enumerate(offsets(n)[1:], start=1):
        extra = (f"material.seed={material.seed + i}" if material.scatter != "none"
                 else f"projectile.velocity={member_velocity(v, k)!r}")
        members.append(Run(member_key(run.key, i), run.scene, (*run.overrides, extra)))
    return members


def plan(name: str, overrides=(), members: int = 1) -> list[Run]:
    """The impact runs of study ``name`` known before any has run, every run once, each as
    ``members`` members (:func:`_members`; the tables, friction and fillet cases are then read
    as means over them, :func:`value`): for ``v50`` each scene at the thesis's bracket, 34.5
    and 39.78 m/s (where its design may start; the design's own runs depend on their outcomes)."""
    if members < 1:
        raise ValueError(f"a run needs at least one member, got {members}")
    if name not in STUDIES:
        raise ValueError(f"unknown study {name!r}; the studies are {', '.join(STUDIES)}")
    names = [s for s in STUDIES if s != "chapter4"] if name == "chapter4" else [name]
    runs: dict[str, Run] = {}
    for n in names:
        if n in TABLE_SCENES:
            new = [_run(s, v, overrides) for s in TABLE_SCENES[n] for v in VELOCITIES]
        elif n == "friction":
            new = [_run(s, 57.3, overrides, friction=mu) for s in ("Y90", "XY0") for mu in FRICTIONS]
        elif n == "fillet":
            new = [_run("Y90", 57.3, overrides, fillet=f) for f in FILLETS]
        else:
            new = [_run(s, v, overrides) for s in SCENES for v in VELOCITIES[:2]]
        runs.update({m.key: m for r in new for m in _members(r, members)})
    return list(runs.values())


def v50_start(scene: str, results: dict, default: tuple = V50_BRACKET) -> tuple[float, float]:
    """Where the design of ``scene``'s ballistic limit starts (m/s): the highest of the table's
    velocities up to which every table run held, and the next one, whose run perforated; else
    ``default`` (the lowest table run perforated, or a run is missing or failed before the first
    perforation). ``results``: run key -> summary."""
    held = None
    for v in VELOCITIES:
        s = results.get(run_key(scene, v), {})
        if "error" in s or "perforated" not in s:
            return default
        if s["perforated"]:
            return default if held is None else (held, v)
        held = v
    return default


def row(summary: dict) -> dict:
    """The numbers of one run that the tables show (SI units; deflections in mm)."""
    mm = (lambda x: None if x is None else 1e3 * x)
    e = summary.get("energies", {})
    return {"residual_velocity": summary.get("residual_velocity"), "absorbed_energy": summary.get("absorbed_energy"),
            "perforated": summary.get("perforated"), "end_reason": summary.get("end_reason"),
            "onset_mm": mm(summary.get("damage_onset_deflection")),
            "first_removal_mm": mm(summary.get("first_removal_deflection")),
            "peak_mm": mm(summary.get("max_deflection")),
            "onset_radius_mm": mm(summary.get("damage_onset_radius")),
            "damage_extent_mm": mm(summary.get("damage_extent_radius")),
            "damaged_cells": summary.get("damaged_cells"),
            "removed_cells": (summary.get("deleted_cells") or 0) + (summary.get("eroded_cells") or 0),
            "viscous": e.get("viscous_dissipation"), "energy_error": summary.get("energy_error"),
            "wall_time_s": summary.get("wall_time_s"), "error": summary.get("error")}


def value(results: dict, key: str, quantity: str):
    """:func:`row`'s ``quantity`` of run ``key`` over its members in ``results`` (run key ->
    summary; ``key``, ``key``-m1, ``key``-m2, ...; failed members left out), as a
    :class:`~fabric_fenicsx.studies.means.Mean`, or None where no member has it."""
    from fabric_fenicsx.studies.means import mean_of

    found = [results[k] for k in _member_keys(results, key)]
    return mean_of(row(s).get(quantity) for s in found)


def _member_keys(results: dict, key: str) -> list[str]:
    prefix = f"{key}-m"
    return [k for k in results if k == key or (k.startswith(prefix) and k[len(prefix):].isdigit())]


def _ends(results: dict, key: str) -> str | None:
    """How the members of ``key`` ended: the one member's end reason or error, or the counts
    (``perforated 5, held 3``)."""
    found = [results[k] for k in _member_keys(results, key)]
    if len(found) <= 1:
        r = row(found[0] if found else {})
        return r["error"] or fmt(r["end_reason"])
    reasons = [("failed" if "error" in s else str(s.get("end_reason"))) for s in found]
    return ", ".join(f"{e} {reasons.count(e)}" for e in sorted(set(reasons)))


def fmt(x, digits: int = 2, none: str = "-") -> str:
    """A table cell: floats to ``digits`` decimals, a mean over members with its 95 % interval,
    booleans as yes / no, None as ``none``."""
    from fabric_fenicsx.studies.means import Mean

    if x is None:
        return none
    if isinstance(x, Mean):
        return x.text(digits)
    if isinstance(x, bool):
        return "yes" if x else "no"
    if isinstance(x, float):
        return f"{x:.{digits}f}"
    return str(x)


def table_md(scene: str, results: dict) -> str:
    """Markdown table of a scene at the five velocities: ours beside the thesis's (and the
    experiment's for Y90). ``results``: run key -> summary; a run with members shows their mean
    +- its 95 % interval (:func:`value`) and how they ended."""
    ref = THESIS[scene]
    head = ["V0 (m/s)", "residual (m/s)", "thesis", "absorbed (J)", "thesis"]
    if "residual_experiment" in ref:
        head[3:3] = ["experiment"]
        head.append("experiment")
    head += ["deflection: onset / first removal / max (mm)", "thesis max (mm)", "damage reach (mm)",
             "removed cells", "viscous (J)", "end"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for i, v in enumerate(VELOCITIES):
        key = run_key(scene, v)
        q = (lambda name, digits=2: fmt(value(results, key, name), digits))
        thesis = (lambda k: ref[k][i] if k in ref else None)
        cells = [f"{v:g}", q("residual_velocity"), fmt(thesis("residual")) if ref else "-"]
        if "residual_experiment" in ref:
            cells.append(fmt(thesis("residual_experiment")))
        cells += [q("absorbed_energy"), fmt(thesis("absorbed"))]
        if "absorbed_experiment" in ref:
            cells.append(fmt(thesis("absorbed_experiment")))
        cells += [" / ".join(q(k, 1) for k in ("onset_mm", "first_removal_mm", "peak_mm")),
                  fmt(thesis("deflection_mm")), q("damage_extent_mm", 1), q("removed_cells", 0),
                  q("viscous"), _ends(results, key)]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def variant_md(results: dict, runs: list[tuple[str, str]]) -> str:
    """Markdown table of named runs (label, run key), each a run or the mean over its members:
    the friction and fillet studies."""
    head = ["case", "residual (m/s)", "absorbed (J)", "onset / max deflection (mm)", "damage starts at r (mm)",
            "damage reach (mm)", "damaged cells", "removed cells", "end"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for label, key in runs:
        q = (lambda name, digits=2: fmt(value(results, key, name), digits))
        lines.append("| " + " | ".join([label, q("residual_velocity"), q("absorbed_energy"),
                                        f"{q('onset_mm', 1)} / {q('peak_mm', 1)}",
                                        q("onset_radius_mm", 1), q("damage_extent_mm", 1),
                                        q("damaged_cells", 0), q("removed_cells", 0), _ends(results, key)]) + " |")
    return "\n".join(lines)


def checklist(results: dict, waves: dict | None = None) -> list[tuple[str, object, str]]:
    """The thesis's qualitative findings (Sec. 4.3-4.5), each (finding, holds, the numbers).
    holds: True or False; :data:`~fabric_fenicsx.studies.means.UNTOLD` where the runs have
    members and their means cannot be told apart (Welch, 95 %); None where a run is missing.
    ``waves``: ``{"measured": ..., "expected": ...}`` with the warp and fill wave speeds
    (:mod:`fabric_fenicsx.studies.waves`)."""
    from fabric_fenicsx.studies.means import UNTOLD, all_of, larger

    def get(key, q):
        return value(results, key, q)

    out = []
    pairs = [(get(run_key("Y90", v), "absorbed_energy"), get(run_key("XY0", v), "absorbed_energy")) for v in VELOCITIES]
    answers = [larger(a, b) for a, b in pairs]
    out.append(("two-edge clamping (Y90) absorbs more than four-edge clamping (XY0)", all_of(answers),
                f"at {answers.count(True)} of {len(pairs)} velocities" + _untold(answers) + "; Y90 / XY0 absorbed (J): "
                + ", ".join(f"{fmt(a)} / {fmt(b)}" for a, b in pairs)))
    trip = [(get(run_key("XY45", v), "absorbed_energy"), get(run_key("XY0", v), "absorbed_energy"),
             get(run_key("XY45", v), "peak_mm"), get(run_key("XY0", v), "peak_mm")) for v in VELOCITIES]
    answers = [all_of([larger(a, b), larger(c, d)]) for a, b, c, d in trip]
    out.append(("45 degrees (XY45) absorbs more than 0 degrees (XY0) and deflects more", all_of(answers),
                f"both at {answers.count(True)} of {len(trip)} velocities" + _untold(answers)
                + "; XY45 / XY0 absorbed (J), largest deflection (mm): "
                + ", ".join(f"{fmt(a)} / {fmt(b)}, {fmt(c, 1)} / {fmt(d, 1)}" for a, b, c, d in trip)))
    r01, r05, r2, rf, rxy = (get(k, "damage_extent_mm") for k in (
        run_key("Y90", 57.3, friction=0.1), run_key("Y90", 57.3), run_key("Y90", 57.3, friction=2.0),
        run_key("Y90", 57.3, fillet=0.8e-3), run_key("XY0", 57.3)))
    parts = {"further with friction 0.1": larger(r01, r05), "with the fillet": larger(rf, r05),
             "closer with friction 2.0": larger(r05, r2), "clamped all round": larger(r05, rxy)}
    holds = all_of(parts.values())
    out.append(("low friction (0.1) and a 0.8 mm fillet spread damage further than friction 0.5 with a sharp edge; "
                "friction 2.0 and four-edge clamping keep it closer", holds,
                "damage reach at 57.3 m/s (mm): Y90 friction 0.1 / 0.5 / 2.0: "
                f"{fmt(r01, 1)} / {fmt(r05, 1)} / {fmt(r2, 1)}; 0.8 mm fillet {fmt(rf, 1)}; XY0 {fmt(rxy, 1)}"
                + ("" if holds is None else " (" + ", ".join(
                    f"{what}: {UNTOLD if a == UNTOLD else fmt(a)}" for what, a in parts.items()) + ")")))
    sharp, round2 = get(run_key("Y90", 57.3), "absorbed_energy"), get(run_key("Y90", 57.3, fillet=2e-3), "absorbed_energy")
    ratio, holds = _fillet_ratio(round2, sharp)
    out.append(("the 2 mm fillet lets the projectile through with about half the absorbed energy of the sharp "
                "edge (ratio 0.35-0.65)", holds,
                f"absorbed 2 mm fillet / sharp: {fmt(round2)} / {fmt(sharp)} J = {ratio}"))
    w = (waves or {}).get("measured") or {}
    e = (waves or {}).get("expected") or {}
    speeds = None if w.get("warp") is None or w.get("fill") is None else (w["warp"], w["fill"])
    out.append(("early in the impact the stress wave runs faster along the less crimped fill",
                None if speeds is None else speeds[1] > speeds[0],
                "not measured" if speeds is None else
                f"wave front speed along warp / fill {speeds[0]:.0f} / {speeds[1]:.0f} m/s (XY0, first 25 us; "
                f"sqrt(K / rho_A) of the unit cell at zero strain: {fmt(e.get('warp'), 0)} / {fmt(e.get('fill'), 0)} m/s)"))
    return out


def _untold(answers) -> str:
    from fabric_fenicsx.studies.means import UNTOLD

    n = sum(a == UNTOLD for a in answers)
    return f" ({n} not told apart by the members)" if n else ""


def _fillet_ratio(round2, sharp) -> tuple[str, object]:
    """The absorbed energy's ratio 2 mm fillet / sharp edge as text, and whether it lies in
    0.35-0.65: for means over members, whether its 95 % interval (the delta method on the two
    independent means) lies inside (True), outside (False) or across an end (untold)."""
    import math

    from fabric_fenicsx.studies.means import UNTOLD

    if round2 is None or sharp is None or not sharp.mean:
        return "-", None
    ratio = round2.mean / sharp.mean
    if round2.half_width is None or sharp.half_width is None:
        return f"{ratio:.2f}", 0.35 <= ratio <= 0.65
    half = abs(ratio) * math.hypot(round2.half_width / round2.mean, sharp.half_width / sharp.mean)
    lo, hi = ratio - half, ratio + half
    holds = True if 0.35 <= lo and hi <= 0.65 else False if hi < 0.35 or lo > 0.65 else UNTOLD
    return f"{ratio:.2f} +- {half:.2f}", holds


def plot_residual(results: dict, path: str | Path) -> None:
    """Residual against impact velocity for the four scenes (the mean over a run's members with
    its 95 % interval), with the thesis's (and the experiment's) points (PNG)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.6))
    ax.plot(VELOCITIES, VELOCITIES, ":", color="0.6", label="no fabric")
    for i, scene in enumerate(SCENES):
        c = f"C{i}"
        pts = [(v, value(results, run_key(scene, v), "residual_velocity")) for v in VELOCITIES]
        pts = [(v, m.mean, m.half_width or 0.0) for v, m in pts if m is not None]
        if pts:
            v, mean, half = zip(*pts)
            ax.errorbar(v, mean, yerr=half, fmt="o-", color=c, capsize=3, label=f"{scene}, this model")
        ref = THESIS[scene]
        for key, marker, what in (("residual", "s", "thesis"), ("residual_experiment", "^", "experiment")):
            if key in ref:
                tp = [(v, r) for v, r in zip(VELOCITIES, ref[key]) if r is not None]
                ax.plot(*zip(*tp), marker, mfc="none", color=c, ls="--" if what == "thesis" else "-.",
                        label=f"{scene}, {what}")
    ax.set_xlabel("impact velocity V0 (m/s)")
    ax.set_ylabel("residual velocity (m/s; negative: rebound)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def incomplete_cases(results: dict, cases, runs_dir: str | Path) -> list[tuple[str, str]]:
    """(run key, why) of each case (label, run key) whose run cannot be drawn: missing from
    ``results``, failed, or its folder in ``runs_dir`` incomplete
    (:func:`~fabric_fenicsx.studies.runpool.incomplete`: no damage.npz, ...)."""
    from fabric_fenicsx.studies.runpool import incomplete

    lacking = []
    for _, key in cases:
        summary = results.get(key)
        if summary is None:
            lacking.append((key, "not run"))
        elif "error" in summary:
            lacking.append((key, f"failed: {summary['error']}"))
        else:
            folder = Path(runs_dir) / key
            missing = incomplete(folder, summary) if summary.get("settings") else []
            drawn = incomplete(folder, {"settings": {"output": {"png": True}}})   # the picture's own file
            missing += [m for m in drawn if m == "damage.npz" and m not in missing]
            if missing:
                lacking.append((key, f"incomplete: no {', '.join(missing)}"))
    return lacking


def plot_damage(cases: list[tuple[str, Path]], path: str | Path, half_width: float = 0.07) -> None:
    """The warp's integrity at the end (SDV2 = alpha1, 1 intact, 0 broken; removed cells
    blank) of each run, three to a row, within ``half_width`` (m) of the centre of the
    reference fabric, with a colour bar. ``cases``: (label, the run's damage.npz)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np
    from matplotlib.collections import PolyCollection

    cols = min(3, len(cases))
    rows = -(-len(cases) // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(3.5 * cols + 1.0, 3.4 * rows), squeeze=False)
    for ax in axes.ravel()[len(cases):]:
        ax.axis("off")
    lim = half_width * 1e3
    for ax, (label, npz) in zip(axes.ravel(), cases):
        d = np.load(npz)
        live = d["live"]
        pc = PolyCollection(d["quads"][live] * 1e3, array=d["SDV2"][live], cmap="viridis", clim=(0.0, 1.0),
                            edgecolors="face", linewidths=0.2)
        ax.add_collection(pc)
        ax.set_xlim(-lim, lim)
        ax.set_ylim(-lim, lim)
        ax.set_aspect("equal")
        ax.set_title(label, fontsize=9)
        ax.set_xlabel("x (mm)", fontsize=8)
        ax.set_ylabel("y (mm)", fontsize=8)
        ax.tick_params(labelsize=7)
    fig.colorbar(pc, ax=list(axes.ravel()), label="warp integrity alpha1 (SDV2); blank: removed", shrink=0.8)
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)
