"""Accuracy of the surrogate against direct unit-cell solves, against its build and lookup time.

For several table settings (grid spacing h of E1, E2; nodes in sqrt r; interpolation order)
the report measures, at random states (damaged ones included), the maximum and RMS error
of P1, P2 against direct solves, the build time of the tiles those states need, and the
evaluation rate of the frozen-damage lookup and of the damage update on many random points.
"""

from __future__ import annotations

import csv
import json
import time
from pathlib import Path

import numpy as np

from fabric_fenicsx.material.fabric import Fabric
from fabric_fenicsx.surrogate.table import Surrogate
from fabric_fenicsx.material.unitcell import UnitCell

# (resolution, r_nodes, order): a ladder in h at cubic order, the default, and linear order.
DEFAULT_LADDER = ((0.004, 6, 3), (0.002, 11, 3), (0.001, 21, 3), (0.002, 11, 1), (0.001, 11, 1))
STATE_RANGES = {"E1": (0.0, 0.045), "E2": (-0.01, 0.04), "alpha": (0.25, 1.0)}
P_PEAK_UNIAXIAL = 148e3  # N/m: peak P1 of scenario 1, the error scale of the criterion


def random_states(n: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    E1 = rng.uniform(*STATE_RANGES["E1"], n)
    E2 = rng.uniform(*STATE_RANGES["E2"], n)
    alpha = rng.uniform(*STATE_RANGES["alpha"], (n, 2))
    return E1, E2, alpha


def direct_solves(fabric: Fabric, E1, E2, alpha):
    """By direct unit-cell solves: P1, P2 with damage frozen at alpha, the median solve time,
    and (alpha1, alpha2, P1, P2) of the damage update from the history alpha (respond)."""
    cell = UnitCell(fabric)
    out = np.empty((E1.size, 2))
    upd = np.empty((E1.size, 4))
    times = np.empty(E1.size)
    for k in range(E1.size):
        t0 = time.perf_counter()
        r = cell.solve(float(E1[k]), float(E2[k]), tuple(alpha[k]))
        times[k] = time.perf_counter() - t0
        out[k] = r.P1, r.P2
        r = cell.respond(float(E1[k]), float(E2[k]), tuple(alpha[k]))
        upd[k] = r.alpha1, r.alpha2, r.P1, r.P2
    return out, float(np.median(times)), upd


def evaluation_rates(sur: Surrogate, n: int, seed: int = 1) -> dict:
    """Points per second of evaluate (intact) and update (mixed damage) on n random points."""
    rng = np.random.default_rng(seed)
    E1 = rng.uniform(*STATE_RANGES["E1"], n)
    E2 = rng.uniform(*STATE_RANGES["E2"], n)
    ones = np.ones(n)
    sur.evaluate(E1[:100], E2[:100], ones[:100], ones[:100])  # builds what is needed
    t0 = time.perf_counter()
    sur.evaluate(E1, E2, ones, ones)
    t_intact = time.perf_counter() - t0
    a = rng.uniform(*STATE_RANGES["alpha"], (n, 2))
    sur.update(E1[:100], E2[:100], a[:100, 0], a[:100, 1])
    t0 = time.perf_counter()
    sur.update(E1, E2, a[:, 0], a[:, 1])
    t_damaged = time.perf_counter() - t0
    return {"evaluate_intact_per_s": n / t_intact, "update_damaged_per_s": n / t_damaged}


def run_report(fabric: Fabric, out_dir: str | Path, ladder=DEFAULT_LADDER, n_states: int = 300,
               n_rate: int = 200_000, seed: int = 0, workers: int | None = None,
               progress: bool = True) -> list[dict]:
    """Write ``surrogate_report.{csv,md,json}`` and ``surrogate_error_vs_time.png`` in out_dir."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    E1, E2, alpha = random_states(n_states, seed)
    ref, t_direct, ref_update = direct_solves(fabric, E1, E2, alpha)
    rows = []
    for h, nr, order in ladder:
        sur = Surrogate(fabric, resolution=h, r_nodes=nr, order=order, cache_dir=False,
                        workers=workers, progress=progress)
        t0 = time.perf_counter()
        P1, P2, _, _ = sur.evaluate(E1, E2, alpha[:, 0], alpha[:, 1], tension_only=False)
        build = time.perf_counter() - t0
        err = np.abs(np.c_[P1, P2] - ref)
        U1, U2, a1, a2 = sur.update(E1, E2, alpha[:, 0], alpha[:, 1], tension_only=False)
        err_alpha = np.abs(np.c_[a1, a2] - ref_update[:, :2])
        err_update = np.abs(np.c_[U1, U2] - ref_update[:, 2:])
        rates = evaluation_rates(sur, n_rate)
        row = {"resolution": h, "r_nodes": nr, "order": order, "solves": sur.solves,
               "build_s": build, "max_err_N_per_m": float(err.max()),
               "rms_err_N_per_m": float(np.sqrt(np.mean(err ** 2))),
               "max_err_pct_of_peak": float(100 * err.max() / P_PEAK_UNIAXIAL),
               "update_alpha_err_max": float(err_alpha.max()),
               "update_alpha_err_p95": float(np.percentile(err_alpha, 95)),
               "update_P_err_max_N_per_m": float(err_update.max()),
               "update_P_err_p95_N_per_m": float(np.percentile(err_update, 95)),
               **rates, "direct_solve_s": t_direct,
               "speedup_update": rates["update_damaged_per_s"] * t_direct}
        rows.append(row)
        if progress:
            print(f"h={h:g} r_nodes={nr} order={order}: max err {row['max_err_N_per_m']:.0f} N/m "
                  f"({row['max_err_pct_of_peak']:.3f} % of peak), rms {row['rms_err_N_per_m']:.0f} N/m, "
                  f"build {build:.1f} s ({sur.solves} solves), update {rates['update_damaged_per_s']:.3g} pts/s",
                  flush=True)
    _write(out, rows, n_states, seed)
    return rows


def _write(out: Path, rows: list[dict], n_states: int, seed: int) -> None:
    with open(out / "surrogate_report.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    (out / "surrogate_report.json").write_text(json.dumps(rows, indent=2))
    lines = ["# Surrogate accuracy against direct unit-cell solves",
             "",
             f"{n_states} random states (seed {seed}): E1 in {STATE_RANGES['E1']}, E2 in {STATE_RANGES['E2']}, "
             f"alpha1, alpha2 in {STATE_RANGES['alpha']}. Errors of P1 and P2 (N/m); the issue's criterion is "
             f"0.5 % of the peak uniaxial-strain stress ({P_PEAK_UNIAXIAL:.0f} N/m). Build time is that of the "
             f"tiles these states need, from an empty cache. Rates on random points: `evaluate` at alpha = 1, "
             f"`update` with random damage histories.",
             "",
             "| h | r nodes | order | solves | build (s) | max err (N/m) | max err (% peak) | rms err (N/m) "
             "| update: alpha err max / 95 % | update: P err max / 95 % (N/m) "
             "| evaluate (pts/s) | update (pts/s) | speed-up over a direct solve |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['resolution']:g} | {r['r_nodes']} | {r['order']} | {r['solves']} | {r['build_s']:.1f} "
                     f"| {r['max_err_N_per_m']:.0f} | {r['max_err_pct_of_peak']:.3f} | {r['rms_err_N_per_m']:.0f} "
                     f"| {r['update_alpha_err_max']:.3g} / {r['update_alpha_err_p95']:.2g} "
                     f"| {r['update_P_err_max_N_per_m']:.0f} / {r['update_P_err_p95_N_per_m']:.0f} "
                     f"| {r['evaluate_intact_per_s']:.3g} | {r['update_damaged_per_s']:.3g} "
                     f"| {r['speedup_update']:.0f} |")
    lines += ["", f"Median direct unit-cell solve: {rows[0]['direct_solve_s'] * 1e3:.2f} ms.",
              "",
              "The update columns compare the damage update from the random history alpha with the unit "
              "cell's own damage iteration (respond) at the same state. Its largest errors sit at states "
              "near a snap, where target'(alpha) is close to 1: there a table error of 1e-5 in the "
              "stretch mu moves the root of alpha = target(alpha) by several hundredths."]
    (out / "surrogate_report.md").write_text("\n".join(lines) + "\n")

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    for order, marker in ((3, "o"), (1, "s")):
        sel = [r for r in rows if r["order"] == order]
        if not sel:
            continue
        label = "cubic" if order == 3 else "linear"
        axes[0].loglog([r["build_s"] for r in sel], [r["max_err_N_per_m"] for r in sel], marker + "-",
                       label=f"{label}, max")
        axes[0].loglog([r["build_s"] for r in sel], [r["rms_err_N_per_m"] for r in sel], marker + "--",
                       label=f"{label}, rms")
        axes[1].loglog([1.0 / r["update_damaged_per_s"] for r in sel], [r["max_err_N_per_m"] for r in sel],
                       marker + "-", label=f"{label}, max")
        for r in sel:
            axes[0].annotate(f"h={r['resolution']:g}", (r["build_s"], r["max_err_N_per_m"]), fontsize=7)
    for ax in axes:
        ax.axhline(0.005 * P_PEAK_UNIAXIAL, color="k", lw=0.8, ls=":", label="0.5 % of peak")
        ax.set_ylabel("error of P (N/m)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    axes[0].set_xlabel("build time of the tiles needed (s)")
    axes[1].set_xlabel("update time per point (s)")
    fig.suptitle("Surrogate error against run time")
    fig.tight_layout()
    fig.savefig(out / "surrogate_error_vs_time.png", dpi=120)
    plt.close(fig)
