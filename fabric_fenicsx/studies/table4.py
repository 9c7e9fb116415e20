"""The thesis's Table 4 study: scene Y90 at the five impact velocities, against the thesis's
simulation and the experiment (Boeing report), as quoted in the thesis.

    .venv/bin/python -m fabric_fenicsx.studies.table4 --out docs/impact [--runs out/table4] [--set section.key=value ...]

Each velocity runs into its own folder under ``--runs`` (``v<V0>/summary.json``, ``history.csv``); a velocity
whose summary already exists with the same settings and model version (``provenance``) is not run
again, so an interrupted study resumes. Writes ``table4.csv``, ``table4.md`` (every setting behind the numbers) and
``table4.png`` into ``--out``. Serial; nothing is tuned: the scene's values are used as they are.
"""

from __future__ import annotations

import argparse
import csv
import sys
import time
from pathlib import Path

from fabric_fenicsx.studies.chapter4 import THESIS as _CHAPTER4, VELOCITIES, fmt

THESIS = {  # Table 4 of the thesis (chapter4.THESIS["Y90"]) under this module's names; None = "bounced back"
    f"{name}_{kind}": _CHAPTER4["Y90"][key] for name, kind, key in (
        ("residual", "simulation", "residual"), ("residual", "experiment", "residual_experiment"),
        ("absorbed", "simulation", "absorbed"), ("absorbed", "experiment", "absorbed_experiment"),
        ("deflection", "simulation_mm", "deflection_mm"))}

COLUMNS = ("v0", "residual_velocity", "perforated", "absorbed_energy", "max_deflection_mm",
           "energy_error", "end_reason", "n_cells", "n_steps", "wall_time_s",
           "thesis_residual", "experiment_residual", "thesis_absorbed", "experiment_absorbed",
           "thesis_deflection_mm")


def run_study(scene_path: str, runs: Path, overrides: list[str], verbose: bool = True) -> list[dict]:
    """Run (or reuse) the five velocities; return one row per velocity."""
    from fabric_fenicsx.impact.simulation import ImpactError, run_impact
    from fabric_fenicsx.provenance import load_if_same
    from fabric_fenicsx.impact.scene import load_scene

    rows = []
    for k, v0 in enumerate(VELOCITIES):
        scene = load_scene(scene_path, list(overrides) + [f"projectile.velocity={v0}"])
        folder = runs / f"v{v0:g}"
        summary = load_if_same(folder / "summary.json", scene.to_dict())
        if summary is None:
            if verbose:
                print(f"table4: running V0 = {v0:g} m/s into {folder}", flush=True)
            t0 = time.perf_counter()
            try:
                summary = run_impact(scene, folder, verbose=False)
            except ImpactError as err:
                print(f"table4: V0 = {v0:g} m/s stopped: {err}", file=sys.stderr)
                summary = {"v0": v0, "end_reason": f"stopped: {err}"}
            if verbose:
                print(f"table4: V0 = {v0:g} m/s done in {time.perf_counter() - t0:.0f} s: residual "
                      f"{summary.get('residual_velocity')} m/s", flush=True)
        defl = summary.get("max_deflection")
        rows.append({"v0": v0, "residual_velocity": summary.get("residual_velocity"),
                     "perforated": summary.get("perforated"),
                     "absorbed_energy": summary.get("absorbed_energy"),
                     "max_deflection_mm": None if defl is None else 1e3 * defl,
                     "energy_error": summary.get("energy_error"), "end_reason": summary.get("end_reason"),
                     "n_cells": summary.get("n_cells"), "n_steps": summary.get("n_steps"),
                     "wall_time_s": summary.get("wall_time_s"),
                     "thesis_residual": THESIS["residual_simulation"][k],
                     "experiment_residual": THESIS["residual_experiment"][k],
                     "thesis_absorbed": THESIS["absorbed_simulation"][k],
                     "experiment_absorbed": THESIS["absorbed_experiment"][k],
                     "thesis_deflection_mm": THESIS["deflection_simulation_mm"][k]})
    return rows


def _fmt(x, digits: int = 2) -> str:
    return fmt(x, digits, none="bounced back")


def write_outputs(rows: list[dict], out: Path, scene_path: str, overrides: list[str]) -> None:
    with open(out / "table4.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=COLUMNS)
        w.writeheader()
        w.writerows(rows)
    lines = [f"Scene `{scene_path}`" + (f" with `{' '.join('--set ' + o for o in overrides)}`" if overrides else ""),
             "", "| V0 (m/s) | residual (m/s) | thesis sim. | experiment | absorbed (J) | thesis sim. | "
             "experiment | deflection at damage onset (mm) | thesis sim. | perforated | energy error | "
             "cells | steps | wall (s) |", "|" + "---|" * 14]
    for r in rows:
        lines.append("| " + " | ".join(_fmt(r[c]) if c != "energy_error" else f"{r[c]:.2e}" if r[c] is not None else "-"
                                       for c in ("v0", "residual_velocity", "thesis_residual",
                                                 "experiment_residual", "absorbed_energy", "thesis_absorbed",
                                                 "experiment_absorbed", "max_deflection_mm",
                                                 "thesis_deflection_mm", "perforated", "energy_error",
                                                 "n_cells", "n_steps", "wall_time_s")) + " |")
    (out / "table4.md").write_text("\n".join(lines) + "\n")

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4.2))
    v0 = [r["v0"] for r in rows]
    ax.plot(v0, v0, ":", color="0.6", label="no fabric")
    for key, label, style in (("residual_velocity", "this model", "o-"),
                              ("thesis_residual", "thesis simulation", "s--"),
                              ("experiment_residual", "experiment", "^-.")):
        pts = [(r["v0"], r[key]) for r in rows if r[key] is not None]
        ax.plot(*zip(*pts), style, label=label)
    ax.set_xlabel("impact velocity V0 (m/s)")
    ax.set_ylabel("residual velocity (m/s)")
    ax.set_title("Y90, Table 4 (negative: rebound)")
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(out / "table4.png", dpi=120)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default=str(Path(__file__).resolve().parents[2] / "demos/scenes/y90.toml"))
    parser.add_argument("--out", default="docs/impact")
    parser.add_argument("--runs", default="out/table4", help="folder of the individual runs")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="SECTION.KEY=VALUE")
    args = parser.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    overrides = ["output.xdmf_interval=0", "output.png=false", "output.progress_interval=0"] + args.overrides
    rows = run_study(args.scene, Path(args.runs), overrides)
    write_outputs(rows, out, Path(args.scene).name, overrides)
    print(f"table4: wrote {out / 'table4.md'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
