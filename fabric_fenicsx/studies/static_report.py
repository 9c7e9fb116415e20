"""Key points, printed summary, JSON and figure of a static scene
(:mod:`fabric_fenicsx.studies.static`). Nothing here imports DOLFINx (the figure imports
matplotlib when it is drawn).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from fabric_fenicsx.material.unitcell import ALPHA_BROKEN
from fabric_fenicsx.studies.static_scenarios import _TITLES, E1_CAP

if TYPE_CHECKING:
    from fabric_fenicsx.studies.static import ScenarioResult


# ----------------------------------------------------------------------------- key points
def _first(E1, mask):
    idx = np.flatnonzero(mask)
    return float(E1[idx[0]]) if idx.size else None


def _peaks(E1, P, min_prominence=0.05):
    """Local maxima of P (interior or at the end of the path) with prominence >= fraction of max."""
    from scipy.signal import find_peaks

    if P.size == 0 or np.max(P) <= 0.0:
        return []
    padded = np.concatenate(([-np.inf], P, [-np.inf]))
    idx, _ = find_peaks(padded, prominence=min_prominence * float(np.max(P)))
    return [{"E1": float(E1[i - 1]), "P": float(P[i - 1])} for i in idx]


def path_key_points(data: dict[str, np.ndarray]) -> dict:
    """Peak of P1 (and every prominent local peak of P1 and P2), damage onset (first E1 with
    alpha_i < 1) and complete failure (first E1 with alpha_i <= ALPHA_BROKEN) for each yarn."""
    E1, P1, P2 = data["E1"], data["P1"], data["P2"]
    i = int(np.argmax(P1))
    kp = {
        "peak_P1": {"E1": float(E1[i]), "P1": float(P1[i])},
        "peaks_P1": [{"E1": p["E1"], "P1": p["P"]} for p in _peaks(E1, P1)],
        "peaks_P2": [{"E1": p["E1"], "P2": p["P"]} for p in _peaks(E1, P2)],
        "damage_onset": {}, "complete_failure": {}, "E1_max": float(E1[-1]),
    }
    if np.max(P2) > 0.0:
        j = int(np.argmax(P2))
        kp["peak_P2"] = {"E1": float(E1[j]), "P2": float(P2[j])}
    for k, yarn in ((1, "warp"), (2, "fill")):
        a = data[f"alpha{k}"]
        kp["damage_onset"][yarn] = _first(E1, a < 1.0 - 1e-12)
        kp["complete_failure"][yarn] = _first(E1, a <= ALPHA_BROKEN)
    return kp


def _free_fill_key_points(data) -> dict:
    """Scenario 4: the largest transverse contraction (where E2 turns back, Fig. 3-5)."""
    alive = data["alpha1"] > ALPHA_BROKEN
    E2 = np.where(alive, data["E2"], np.inf)
    j = int(np.argmin(E2))
    return {"E2_min": {"E1": float(data["E1"][j]), "E2": float(data["E2"][j])}}


def _interp_P1(data, E1):
    E, P = data["E1"], data["P1"]
    return float(np.interp(E1, E, P)) if E[0] <= E1 <= E[-1] else None


# ----------------------------------------------------------------------------- report
def _fmt(E):
    return "-" if E is None else f"{E:.4f}"


def _path_lines(kp, indent="  ") -> list[str]:
    lines = [f"{indent}peak of P1: E1 = {kp['peak_P1']['E1']:.4f}, P1 = {kp['peak_P1']['P1'] / 1e3:.2f} kN/m"]
    if len(kp["peaks_P1"]) > 1:
        lines.append(indent + "peaks of P1: " + "; ".join(
            f"E1 = {p['E1']:.4f}, P1 = {p['P1'] / 1e3:.2f} kN/m" for p in kp["peaks_P1"]))
    if "peak_P2" in kp:
        pk = kp["peak_P2"]
        lines.append(f"{indent}peak of P2: E1 = {pk['E1']:.4f}, P2 = {pk['P2'] / 1e3:.2f} kN/m")
    for yarn in ("warp", "fill"):
        on, off = kp["damage_onset"][yarn], kp["complete_failure"][yarn]
        if on is None:
            lines.append(f"{indent}{yarn}: no damage up to E1 = {kp['E1_max']:.4f}")
        else:
            lines.append(f"{indent}{yarn}: damage onset at E1 = {_fmt(on)}, complete failure at "
                         f"E1 = {_fmt(off) if off is not None else '- (not reached)'}")
    if "E2_min" in kp:
        m = kp["E2_min"]
        lines.append(f"{indent}largest contraction: E2 = {m['E2']:.4f} at E1 = {m['E1']:.4f}")
    if kp.get("cap_reached"):
        lines.append(f"{indent}stopped at the cap E1 = {E1_CAP} before complete failure")
    return lines


def format_key_points(result: ScenarioResult) -> str:
    """The key points of a scene as printed by the command line."""
    kp = result.key_points
    head = f"{result.name} ({result.fabric.name}, {result.backend}, step {result.step:g}, {len(result)} rows)"
    lines = [head]
    if result.name == "bending":
        for bound in ("upper", "lower"):
            k = kp[f"B2_{bound}"]
            lines.append(f" B2 = {k['B2'] * 1e6:.4f} N mm^2 ({bound} bound):")
            lines += _path_lines(k)
        for label, c in kp["P1_lower_over_upper"].items():
            lines.append(f" P1(lower B2) / P1(upper B2) at E1 = {c['E1']:.4f}: {c['ratio']:.3f}")
        return "\n".join(lines)
    lines += _path_lines(kp)
    if result.name == "load-unload":
        u = kp["unload_at"]
        lines.append(f"  unloaded at E1 = {u['E1']:.4f} (P1 = {u['P1'] / 1e3:.2f} kN/m, "
                     f"alpha1 = {u['alpha1']:.4f})")
        lines.append(f"  residual P1 at zero strain: {kp['residual_P1_at_zero_strain']:.3g} N/m")
        dev = kp["reload_max_deviation_P1"]
        lines.append(f"  reload vs first loading beyond the unload point: max |dP1| = "
                     f"{'-' if dev is None else f'{dev:.3g}'} N/m")
    return "\n".join(lines)


def write_key_points(result: ScenarioResult, path) -> None:
    Path(path).write_text(json.dumps(result.key_points, indent=2) + "\n")


# ----------------------------------------------------------------------------- plot
def _alpha_axis(ax, data, style="--", lw=1.2, label_suffix=""):
    ax2 = ax.twinx()
    ax2.plot(data["E1"], data["alpha1"], "C0" + style, lw=lw, label="alpha1 (warp)" + label_suffix)
    ax2.plot(data["E1"], data["alpha2"], "C1" + style, lw=lw, label="alpha2 (fill)" + label_suffix)
    ax2.set_ylim(-0.05, 1.1)
    ax2.set_ylabel("damage parameter alpha (-)")
    return ax2


def plot_scenario(result: ScenarioResult, path) -> None:
    """PNG in the style of the thesis's Figs. 3-1 to 3-6: P1, P2 (kN/m) against E1 with alpha
    on a right axis; E2 against E1 as a second panel for scenario 4."""
    from matplotlib.figure import Figure

    name, d = result.name, result.data
    two_panels = name in ("uniaxial-stress", "bending")
    fig = Figure(figsize=(11, 4.5) if two_panels else (6.5, 4.5), layout="constrained")
    axes = fig.subplots(1, 2) if two_panels else [fig.subplots()]
    ax = axes[0]
    if name == "load-unload":
        ref = result.reference
        ax.plot(ref["E1"], ref["P1"] / 1e3, color="0.6", lw=0.8, ls=":", label="monotone loading")
        for leg, lw in (("load", 2.8), ("unload", 1.0), ("reload", 1.0)):
            s = result.select("leg", leg)
            ls = "-" if leg != "unload" else "--"
            ax.plot(s["E1"], s["P1"] / 1e3, "C0", lw=lw, ls=ls, label=f"P1, {leg}")
            ax.plot(s["E1"], s["P2"] / 1e3, "C1", lw=lw, ls=ls, label=f"P2, {leg}")
        ax2 = _alpha_axis(ax, d, style=":")
    elif name == "bending":
        kp = result.key_points
        for bound, ls in (("upper", "-"), ("lower", "--")):
            B2 = kp[f"B2_{bound}"]["B2"]
            s = result.select("B2", B2)
            tag = f"B2 = {B2 * 1e6:.4f} N mm^2 ({bound})"
            ax.plot(s["E1"], s["P1"] / 1e3, "C0", ls=ls, lw=1.8, label=f"P1, {tag}")
            axes[1].plot(s["E1"], s["E2"], "C2", ls=ls, lw=1.8, label=tag)
        ax2 = _alpha_axis(ax, result.select("B2", kp["B2_upper"]["B2"]), style=":",
                          label_suffix=", upper B2")
    else:
        ax.plot(d["E1"], d["P1"] / 1e3, "C0", lw=1.8, label="P1 (warp)")
        if name != "uniaxial-stress":
            ax.plot(d["E1"], d["P2"] / 1e3, "C1", lw=1.8, label="P2 (fill)")
        ax2 = _alpha_axis(ax, d)
        if name == "uniaxial-stress":
            axes[1].plot(d["E1"], d["E2"], "C2", lw=1.8, label="E2 (P2 = 0)")
    ax.set_xlabel("membrane strain E1 (-)")
    ax.set_ylabel("membrane stress P (kN/m)")
    ax.set_ylim(bottom=min(0.0, ax.get_ylim()[0]))
    ax.set_title(_TITLES[name], fontsize=10)
    h1, l1 = ax.get_legend_handles_labels()
    h2, l2 = ax2.get_legend_handles_labels()
    ax.legend(h1 + h2, l1 + l2, fontsize=7, loc="upper left")
    if two_panels:
        axes[1].axhline(0.0, color="0.7", lw=0.6)
        axes[1].set_xlabel("membrane strain E1 (-)")
        axes[1].set_ylabel("membrane strain E2 (-)")
        axes[1].set_title("transverse strain with P2 = 0 (Fig. 3-5)", fontsize=10)
        axes[1].legend(fontsize=7)
    fig.suptitle(f"{result.fabric.name}, {result.backend}, step {result.step:g}", fontsize=8)
    fig.savefig(path, dpi=120)
