"""The report of ``fabric-fenicsx convergence``: CSV tables, log-log plots of error against
run time and ``docs/convergence/discretisation.md``, written from the runs and analyses of
:mod:`fabric_fenicsx.studies.convergence` (imported here; it does not import this module). The
command, :mod:`fabric_fenicsx.cli.convergence`, calls :func:`write_report`."""

from __future__ import annotations

import csv
import datetime
import json
import math
import os
import platform
from pathlib import Path

import numpy as np

from fabric_fenicsx.studies.convergence import (CASES, DEFAULT_SAFETY, DT_MESH_MM, ORDER_RANGE, QUANTITIES, SCENE,
                                        RunRecord, ensemble_recommendation, recommend, scatter_spread)
from fabric_fenicsx.provenance import git_head


def _fmt(x, spec: str = ".4g") -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "-"
    return format(x, spec)


def _pct(x) -> str:
    return "-" if x is None or not math.isfinite(x) else f"{100 * x:.2f} %"


def write_csv(path: Path, rows: list[dict]) -> None:
    keys = list(dict.fromkeys(k for r in rows for k in r))
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=keys)
        w.writeheader()
        w.writerows(rows)


def ladder_rows(analysis: dict) -> list[dict]:
    rows = []
    for i, r in enumerate(analysis["records"]):
        row = {"case": r.case, "h_centre_m": r.h_centre, "dt_safety": r.dt_safety, "error": r.error,
               **{k: v for k, v in r.values.items()}}
        for q in QUANTITIES:
            row[f"err_{q}_vs_finest"] = analysis[q]["err_finest"][i]
            row[f"err_{q}_vs_richardson"] = analysis[q]["err_richardson"][i]
        rows.append(row)
    return rows


def plot_ladders(path: Path, analyses: dict, title: str, label_fmt) -> None:
    """Log-log relative error against CPU time, one panel per case: solid lines against the
    finest level, dashed against the Richardson value where the observed order is sensible."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, len(analyses), figsize=(6 * len(analyses), 4.6), squeeze=False)
    for ax, (case, a) in zip(axes[0], analyses.items()):
        recs = a["records"]
        t = np.array([r.get("cpu_s") for r in recs])
        for q, mk, colour in zip(QUANTITIES, "osd", ("C0", "C1", "C2")):
            e = a[q]["err_finest"]
            keep = np.isfinite(e) & (e > 0) & np.isfinite(t)
            if keep.any():
                ax.loglog(t[keep], e[keep], marker=mk, color=colour, label=q.replace("_", " "))
                if q == "residual_velocity":
                    for ti, ei, r in zip(t[keep], e[keep], np.array(recs, dtype=object)[keep]):
                        ax.annotate(label_fmt(r), (ti, ei), textcoords="offset points", xytext=(4, 4), fontsize=7)
            er = a[q]["err_richardson"]
            keep = np.isfinite(er) & (er > 0) & np.isfinite(t)
            if a[q]["richardson_valid"] and keep.any():
                ax.loglog(t[keep], er[keep], marker=mk, color=colour, ls="--", mfc="none",
                          label=f"{q.replace('_', ' ')} vs Richardson")
        ax.axhline(0.02, color="grey", ls=":", lw=1, label="2 %")
        ax.set_xlabel("CPU time of the run (s, process time of run_impact)")
        ax.set_ylabel("relative error (solid: vs finest level; dashed: vs Richardson)")
        ax.set_title(f"{title}: {CASES[case]['label']}", fontsize=9)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_unitcell(path: Path, uc: dict) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    s = [x for x in uc["summary"] if x["n"] != uc["reference"]]
    t = np.array([x["cpu_s"] for x in s])
    fig, ax = plt.subplots(figsize=(6, 4.6))
    for q, mk in (("P1", "o"), ("P2", "s"), ("V_rel", "d")):
        e = np.array([x[f"max_err_{q}"] for x in s])
        keep = np.isfinite(e) & (e > 0)
        ax.loglog(t[keep], e[keep], marker=mk, label=f"max rel. error {q.replace('_rel', ' (in contact)')}")
    for ti, x in zip(t, s):
        ax.annotate(f"n={x['n']}", (ti, x["max_err_P1"]), textcoords="offset points", xytext=(4, 4), fontsize=7)
    ax.set_xlabel("CPU time per cold unit-cell solve (s)")
    ax.set_ylabel(f"relative error against n = {uc['reference']}")
    ax.set_title("Unit cell: elements per half-yarn", fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


# ============================================================================ report
def _md_table(header: list[str], rows: list[list[str]]) -> list[str]:
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return lines


def _rel(path: Path, doc: Path) -> str:
    return os.path.relpath(path, doc.parent)


def unitcell_section(uc: dict, out: Path, doc: Path) -> list[str]:
    ref = uc["reference"]
    L = ["## 1. Unit cell: linear elements per half-yarn", "",
         f"`UnitCell(zylon_as(), n_elements=n).solve(E1, E2, alpha)` (damage frozen at alpha) at "
         f"{len(uc['states'])} fixed states, against n = {ref}. Each solve is cold (a new cell, no warm "
         "start). Errors are relative to the reference value; V of a separated reference cell "
         "(V = 0) is compared as an absolute value in N. The default is n = 24 "
         "(`fabric_fenicsx.material.unitcell.N_ELEMENTS_DEFAULT`).", ""]
    rows = []
    for x in uc["rows"]:
        if x["n"] == ref:
            continue
        rows.append([str(x["n"]), f"({x['E1']:g}, {x['E2']:g})", f"({x['alpha1']:g}, {x['alpha2']:g})",
                     "yes" if x["ref_in_contact"] else "no", _fmt(x["P1"], ".6g"), _fmt(x["err_P1"], ".2e"),
                     _fmt(x["P2"], ".6g"), _fmt(x["err_P2"], ".2e"), _fmt(x["V"], ".5g"),
                     _fmt(x["err_V"], ".2e") + ("" if x["err_V_kind"] == "relative" else " N"),
                     _fmt(x["cpu_s"] * 1e3, ".3g")])
    refs = [[f"({x['E1']:g}, {x['E2']:g})", f"({x['alpha1']:g}, {x['alpha2']:g})",
             "yes" if x["in_contact"] else "no", _fmt(x["P1"], ".8g"), _fmt(x["P2"], ".8g"), _fmt(x["V"], ".6g"),
             _fmt(x["cpu_s"], ".3g")] for x in uc["rows"] if x["n"] == ref]
    L += [f"Reference values (n = {ref}):", ""]
    L += _md_table(["E = (E1, E2)", "alpha", "in contact", "P1 (N/m)", "P2 (N/m)", "V (N)", "CPU s"], refs)
    L += ["", "Summary per n (mean CPU and wall time per cold solve; largest error over the states):", ""]
    L += _md_table(["n", "CPU ms/solve", "wall ms/solve", "max rel. err P1", "max rel. err P2",
                    "max rel. err V (in contact)"],
                   [[str(s["n"]), _fmt(s["cpu_s"] * 1e3, ".3g"), _fmt(s["wall_s"] * 1e3, ".3g"),
                     _fmt(s["max_err_P1"], ".2e"), _fmt(s["max_err_P2"], ".2e"), _fmt(s["max_err_V_rel"], ".2e")]
                    for s in uc["summary"] if s["n"] != ref])
    o = uc["orders"]
    L += ["", f"Observed order of the largest error in 1/n (mean of log(e_n/e_2n)/log 2 over n = "
          f"{', '.join(map(str, uc['orders_from']))}): P1 {_fmt(o['P1'], '.2f')}, P2 {_fmt(o['P2'], '.2f')}, "
          f"V {_fmt(o['V_rel'], '.2f')}.", "", "All states:", ""]
    L += _md_table(["n", "E", "alpha", "ref. in contact", "P1 (N/m)", "err P1", "P2 (N/m)", "err P2",
                    "V (N)", "err V", "CPU ms"], rows)
    L += ["", f"![unit cell error against time]({_rel(out / 'unitcell_error_vs_time.png', doc)})", ""]
    return L


def surrogate_section(doc: Path, folder: Path) -> list[str]:
    """The surrogate study's table and plot from its report folder ``folder`` (docs/surrogate)."""
    csv_path = folder / "surrogate_report.csv"
    png = folder / "surrogate_error_vs_time.png"
    L = ["## 2. Surrogate resolution", "",
         "From the surrogate study (`fabric-fenicsx surrogate report --out docs/surrogate`, its own "
         "report `docs/surrogate/surrogate_report.md`); included here as it is, not recomputed by this command.", ""]
    if not csv_path.is_file():
        return L + [f"`{_rel(csv_path, doc)}` did not exist when this report was written: re-run this "
                    "command (`--only surrogate` suffices) once the surrogate report is done.", ""]
    with open(csv_path, newline="") as f:
        rows = list(csv.reader(f))
    def cell(text: str) -> str:
        try:
            return f"{float(text):.4g}"
        except ValueError:
            return text

    if rows:
        L += _md_table(rows[0], [[cell(c) for c in r] for r in rows[1:]])
        L += ["", "Columns as in the CSV (numbers rounded to 4 digits here): `resolution` = grid spacing "
              "of E1, E2; `r_nodes`, `order` = nodes in sqrt(alpha) and interpolation order; `solves`, "
              "`build_s` = unit-cell solves and build time (s) of the tiles; `max_err_N_per_m`, "
              "`rms_err_N_per_m`, `max_err_pct_of_peak` = error of P1, P2 against direct unit-cell "
              "solves; `update_*` = error of the damage update; `*_per_s` = lookup rates; "
              "`direct_solve_s` = median direct solve (s). Error against build time is plotted below."]
    L += ["", f"Source: `{_rel(csv_path, doc)}`."]
    if png.is_file():
        L += ["", f"![surrogate error against time]({_rel(png, doc)})"]
    return L + [""]


def _settings_text(rec: RunRecord, levels: str, safeties: str) -> str:
    """Every scene setting of a ladder (read back from a run's summary.json), with the ladder's
    own parameter given as ``levels`` / ``safeties``."""
    with open(Path(rec.folder) / ("summary.json" if not rec.error else "error.json")) as f:
        st = json.load(f)["settings"]
    m, p, r = st["mesh"], st["projectile"], st["run"]
    return (f"scene `{SCENE}`; projectile velocity {p['velocity']} m/s; material damage "
            f"{str(st['material']['damage']).lower()}; projectile diameter {p['diameter']} m, length {p['length']} m, mass "
            f"{p['mass']} kg, fillet {p['fillet']} m, friction {p['friction']}, standoff {p['standoff']} m, "
            f"contact_damping {p['contact_damping']}, penalty_fraction {p['penalty_fraction']}; mesh kind "
            f"{m['kind']}, side {m['side']} m, h_centre {levels}, h_edge {m['h_edge']} m, refine_radius {m['refine_radius']} m, "
            f"grading {m['grading']}, element {m.get('element', 'full')}, quadrature_degree "
            f"{m['quadrature_degree']}; material angle "
            f"{st['material']['angle']} deg, erosion_strain {st['material']['erosion_strain']}; boundary clamped "
            f"{st['boundary']['clamped']}; run t_end {r['t_end']} s, damping {r['damping']} (fraction of "
            f"critical at the unit cell's highest frequency), dt_safety {safeties}, dt_check_interval {r['dt_check_interval']}, "
            f"release_time {r['release_time']} s; output xdmf_interval {st['output']['xdmf_interval']}, "
            f"png {st['output']['png']}, history_interval {st['output']['history_interval']} s")


def ladder_section(title: str, knob: str, analyses: dict, out: Path, doc: Path) -> list[str]:
    param = "h_centre" if knob == "mesh" else "dt_safety"
    L = [title, ""]
    for case, a in analyses.items():
        recs = a["records"]
        L += [f"### {CASES[case]['label']}", ""]
        ok = [r for r in recs if not r.error]
        if ok:
            if param == "h_centre":
                lv, sf = "as in the table", f"{ok[0].dt_safety:g}"
            else:
                lv, sf = f"{ok[0].h_centre:g} m", "as in the table"
            L += ["Settings: " + _settings_text(ok[0], lv, sf) + ".", ""]
        rows = []
        for i, r in enumerate(recs):
            lvl = f"{r.h_centre * 1e3:.4g} mm" if param == "h_centre" else f"{r.dt_safety:g}"
            if r.error:
                rows.append([lvl, "-", "-", "-", _fmt(r.get("wall_s"), ".1f"), _fmt(r.get("cpu_s"), ".1f"),
                             f"FAILED: {r.error[:400].replace('|', '/')}"] + [""] * 12)
                continue
            e = {q: (a[q]["err_finest"][i], a[q]["err_richardson"][i]) for q in QUANTITIES}
            rows.append([lvl, str(r.values["n_cells"]), str(r.values["n_steps"]),
                         _fmt(r.get("dt"), ".3e"), _fmt(r.get("wall_s"), ".1f"), _fmt(r.get("cpu_s"), ".1f"),
                         f"{r.values['end_reason']} at {r.get('end_time') * 1e3:.3f} ms",
                         _fmt(r.get("residual_velocity"), ".3f"), _pct(e["residual_velocity"][0]),
                         _pct(e["residual_velocity"][1]),
                         _fmt(r.get("absorbed_energy"), ".3f"), _pct(e["absorbed_energy"][0]),
                         _pct(e["absorbed_energy"][1]),
                         _fmt(r.get("max_deflection") * 1e3, ".3f"), _pct(e["max_deflection"][0]),
                         _pct(e["max_deflection"][1]), _fmt(r.get("energy_error"), ".2e"),
                         r.values.get("finished", "")[11:]])
        head = ["h_centre" if param == "h_centre" else "dt_safety", "cells", "steps", "dt (s)", "wall s",
                "CPU s", "end", "v_res (m/s)", "err v_res vs finest", "err v_res vs Richardson",
                "E_abs (J)", "err E_abs vs finest", "err E_abs vs Richardson", "w_max (mm)",
                "err w_max vs finest", "err w_max vs Richardson", "energy error", "finished (UTC)"]
        L += _md_table(head, rows)
        kind = next((r.values.get("deflection_kind") for r in ok), "")
        L += ["", f"w_max: central deflection {kind}" + (" (summary `damage_onset_deflection`)" if kind == "at damage onset"
                                                        else " of the `central_deflection` column of history.csv"
                                                        if kind else "") + ".", ""]
        orows = []
        units = {"residual_velocity": ("v_res (m/s)", 1.0), "absorbed_energy": ("E_abs (J)", 1.0),
                 "max_deflection": ("w_max (mm)", 1e3)}
        for q in QUANTITIES:
            x = a[q]
            name, scale = units[q]
            orows.append([name, _fmt(x["order"], ".2f"),
                          (_fmt(x["richardson"] * scale, ".6g") if x["richardson_valid"] else
                           f"not used (order outside [{ORDER_RANGE[0]}, {ORDER_RANGE[1]}] or undefined)"),
                          _fmt(x["finest"] * scale, ".6g")])
        L += ["Observed order from the three finest successful levels and Richardson extrapolation "
              "(errors against it in the table only where the order is sensible):", ""]
        L += _md_table(["quantity", "observed order", "Richardson value", "finest level"], orows)
        rec = recommend(a)
        L += [""]
        if rec["index"] is None:
            L += [f"**No level of this ladder other than the reference itself is within 2 % of the converged "
                  f"residual velocity ({_fmt(rec['reference'], '.4g')} m/s, {rec['reference_kind']}) together "
                  f"with all costlier levels: the ladder has not converged within what could be afforded.**", ""]
        else:
            r = rec["record"]
            lvl = f"h_centre = {r.h_centre * 1e3:.4g} mm" if param == "h_centre" else f"dt_safety = {r.dt_safety:g}"
            L += [f"Cheapest within 2 % of the converged residual velocity ({rec['reference']:.4g} m/s, "
                  f"{rec['reference_kind']}), with every costlier level within 2 % too: **{lvl}** "
                  f"({r.get('residual_velocity'):.3f} m/s, {r.get('cpu_s'):.1f} s CPU).", ""]
    L += [f"![{knob} error against time]({_rel(out / f'{knob}_error_vs_time.png', doc)})", ""]
    return L


def write_report(doc: Path, out: Path, command: str, uc: dict | None, ladders: dict, study_time: dict,
                 quick: bool, scatter: dict | None = None, dt_mesh: dict | None = None) -> None:
    doc.parent.mkdir(parents=True, exist_ok=True)
    L = ["# Convergence of the discretisation: error against run time", "",
         f"Produced by `{command}` on {datetime.date.today().isoformat()} "
         f"(code at commit {git_head() or 'unknown'}, '+' = with uncommitted edits), {os.cpu_count()} cores, "
         f"{platform.processor() or platform.machine()}, Python {platform.python_version()}, one MPI rank. "
         "The machine was shared with other work while the study ran: wall times carry that load; "
         "the plots use the CPU (process) time of each run, which does not.", "",
         "The impact ladders here are of single runs, so they measure the discretisation only where a "
         "run repeats (the elastic case: damage off). After damage a run is one draw of a distribution; "
         "its statistics (V50, the mean residual velocity) converge, and `fabric-fenicsx ladder` measures "
         "them: [convergence.md](" + _rel(out.parent / "convergence.md", doc) + ").", ""]
    if quick:
        L += ["**Quick smoke version (`--quick`): tiny ladders, not a convergence study.**", ""]
    L += ["Re-running the command reuses every impact run whose folder under "
          f"`{_rel(out / 'runs', doc)}` holds a `summary.json` (or a recorded `error.json`) with the same "
          "scene settings and model version (`fabric_fenicsx.provenance`), and the stored unit-cell ladder (`unitcell.json`) if its element counts and "
          "states are the same; `--rerun` computes everything again. Tables as CSV: "
          f"`{_rel(out, doc)}/*.csv`.", ""]
    sections = []
    if uc is not None:
        sections += unitcell_section(uc, out, doc)
    sections += surrogate_section(doc, out.parent / "surrogate")
    titles = {"mesh": "## 3. Membrane mesh size at the impact point (`mesh.h_centre`, dt_safety 0.8)",
              "dt": "## 4. Time-step safety factor (`run.dt_safety`; h_centre per case: "
                    + ", ".join(f"{c} {h:g} mm" for c, h in (dt_mesh or DT_MESH_MM).items()) + ")"}
    for knob in ("mesh", "dt"):
        if knob in ladders:
            sections += ladder_section(titles[knob], knob, ladders[knob], out, doc)
    L += sections
    ensembles = {h: scatter_spread(recs) for h, recs in (scatter or {}).items()}
    if scatter:
        L += scatter_section(scatter, ensembles)
    L += recommendation_section(ladders, ensembles)
    L += ["## Cost of this study", "",
          f"Impact runs: {study_time['n_runs']} ({study_time['n_new']} run by this invocation), "
          f"{study_time['cpu_s'] / 60:.1f} min CPU and {study_time['wall_s'] / 60:.1f} min wall in total "
          "(sum over the runs as recorded in their timing.json, whenever they were run). Surrogate tiles "
          "missing from the cache are solved during a run in worker processes: their wall time is in the "
          "run's wall time, their CPU is not in its CPU time.", "",
          "## Notes", "",
          "* `run.damping` is a fraction of critical damping at the highest frequency of a membrane of "
          "unit cells (since the reduced element, docs/mesh_independence.md; before, at the highest frequency of the mesh, so that the damping "
          "coefficient followed the smallest cell): the same coefficient on every level.",
          "* Errors are relative: |q - q_ref| / |q_ref|. The observed order uses the three finest "
          "successful levels; it is trusted for Richardson extrapolation only inside "
          f"[{ORDER_RANGE[0]}, {ORDER_RANGE[1]}].",
          "* The study sets h_centre and dt_safety explicitly on every run, so the scenes' defaults "
          "(`demos/scenes/*.toml`) do not change its runs."]
    L += _data_notes(ladders)
    doc.write_text("\n".join(L))


def _code_note(recs) -> list[str]:
    """Which code the runs were made with: a run is reused only with the same settings and
    model version (`fabric_fenicsx.provenance`), so a report normally shows one version."""
    versions: dict[str, list[str]] = {}
    for r in recs:
        versions.setdefault(r.values.get("model_version", "?"), []).append(Path(r.folder).name)
    if len(versions) == 1:
        (v,), heads = versions, sorted({r.values.get("git_head", "?") for r in recs})
        return [f"* Every run was made with model version `{v}` (`provenance.model_version`, a hash of the "
                f"modules that compute an impact), git commit(s) {', '.join(f'`{h}`' for h in heads)}."]
    return ["* The runs were made with different model versions: "
            + "; ".join(f"`{v}`: {', '.join(names)}" for v, names in versions.items()) + "."]


def _data_notes(ladders: dict) -> list[str]:
    """Notes that follow from the runs themselves: failures, runs ended by the time limit,
    and the extent of the mesh ladder."""
    L = []
    recs = {r.folder: r for k in ladders.values() for a in k.values() for r in a["records"]}.values()
    failed = [r for r in recs if r.error]
    if failed:
        L.append(f"* {len(failed)} run(s) stopped with an error; the message is the outcome in the tables, "
                 "and the orders, errors and recommendation of that ladder use its successful levels only: "
                 + "; ".join(f"`{Path(r.folder).name}`" for r in failed) + ".")
    timed = [r for r in recs if not r.error and r.values.get("end_reason") == "time_limit"]
    if timed:
        L.append(f"* {len(timed)} run(s) ended at the time limit t_end of the scene rather than on perforation "
                 "or rebound (e.g. the projectile still touching the fabric): for them v_res is the projectile "
                 "velocity at t_end, compared at the same t_end on every level: "
                 + ", ".join(f"`{Path(r.folder).name}`" for r in timed) + ".")
    L += _code_note(recs)
    mesh = ladders.get("mesh", {})
    if mesh:
        for case, a in mesh.items():
            ok = sorted((r for r in a["records"] if not r.error), key=lambda r: r.h_centre)
            if len(ok) >= 2:
                f, m = ok[0], ok[1]
                L.append(f"* {CASES[case]['label']}: the finest mesh level, h_centre = {f.h_centre * 1e3:.4g} mm, "
                         f"took {f.get('cpu_s') / 60:.1f} min CPU, {f.get('cpu_s') / m.get('cpu_s'):.1f} times the "
                         f"{m.h_centre * 1e3:.4g} mm level; the ladder stops there to keep the whole study "
                         "within the budget of one working session on a shared 2-core machine (its cost: above).")
    return L + [""]


def scatter_section(scatter: dict, ensembles: dict) -> list[str]:
    L = [f"## 5. Run-to-run scatter of the damaged case (dt_safety = {DEFAULT_SAFETY:g})", "",
         "The same run with the impact velocity changed in its 12th digit (V0 x (1 + p), p = 0 is the run of "
         "the mesh ladder): the tearing phase amplifies such round-off (as it amplifies the summation order "
         "of an MPI run), so a single run per level cannot resolve differences below this scatter; the "
         "ensemble means can, to within their standard errors.", ""]
    for h, recs in sorted(scatter.items(), reverse=True):
        L += [f"### h_centre = {h * 1e3:.4g} mm", ""]
        rows = [[f"{r.perturbation:g}", _fmt(r.get("residual_velocity"), ".5g"), _fmt(r.get("absorbed_energy"), ".4g"),
                 _fmt(1e3 * r.get("max_deflection"), ".5g"), _fmt(r.get("n_steps"), ".0f"),
                 _fmt(1e3 * r.get("end_time"), ".4g"), _fmt(r.get("eroded_cells"), ".0f"),
                 r.error[:80] or r.values.get("end_reason", "")] for r in recs]
        L += _md_table(["p", "v_res (m/s)", "E_abs (J)", "w_max (mm)", "steps", "end (ms)", "eroded cells",
                        "end reason"], rows) + [""]
    rows = [[f"{h * 1e3:.4g}", str(s["n"]), f"{s['mean']:.4g}", _pct(s["std_rel"]), _pct(s["sem_rel"]),
             _pct(s["max_rel"]), f"{s['cpu_s']:.0f}"] for h, s in sorted(ensembles.items(), reverse=True) if s]
    L += ["Ensembles (residual velocity):", ""]
    L += _md_table(["h_centre (mm)", "runs", "mean (m/s)", "std. deviation", "std. error of the mean",
                    "largest deviation", "CPU s per run"], rows)
    return L + [""]


def recommendation_section(ladders: dict, ensembles: dict | None = None) -> list[str]:
    L = ["## Recommendation", "",
         "Rule: the cheapest setting (CPU time) whose residual velocity is within 2 % of the converged "
         "value (the Richardson extrapolation if its observed order is sensible, else the finest level), "
         "with every costlier setting of the ladder within 2 % too.", ""]
    ens = ensemble_recommendation(ensembles or {})
    if ens["distance"]:
        finest = ens["finest"]
        s = ensembles[finest]
        dist = "; ".join(f"{h * 1e3:.4g} mm: {100 * d:.2f} % +- {100 * ens['se'][h]:.2f} % ({ens['verdict'][h]})"
                         for h, d in sorted(ens["distance"].items(), reverse=True))
        L += [f"With damage on, single runs scatter by a standard deviation of {_pct(s['std_rel'])} "
              f"(section 5, h_centre = {finest * 1e3:.4g} mm), so the damaged mesh ladder is judged by the "
              f"ensemble means, against the finest ensemble ({finest * 1e3:.4g} mm, mean {ens['reference']:.4g} m/s), "
              "not against a single finer run. Distance of each mean from it +- one standard error, and the "
              f"verdict at two standard errors: {dist}. Coarsest level whose mean is within 2 %, every finer "
              "one too: " + (f"h_centre = {ens['h'] * 1e3:.4g} mm." if ens["h"] is not None else
                             f"none but the finest ensemble, {finest * 1e3:.4g} mm.")]
        finer = [r for r in ladders.get("mesh", {}).get("damaged", {}).get("records", [])
                 if not r.error and r.h_centre < finest and not math.isclose(r.h_centre, finest)]
        for r in sorted(finer, key=lambda r: -r.h_centre):
            d = (r.get("residual_velocity") - ens["reference"]) / abs(ens["reference"])
            L[-1] += (f" The finer single run at {r.h_centre * 1e3:.4g} mm ({r.get('residual_velocity'):.4g} m/s) "
                      f"lies {100 * d:+.2f} % from that mean, {abs(d) / s['std_rel']:.1f} standard deviations "
                      "of a single run.")
        L += [""]
    dt_recs = [r for r in ladders.get("dt", {}).get("damaged", {}).get("records", []) if not r.error]
    at_dt_mesh = [h for h in (ensembles or {}) if ensembles[h] and dt_recs and math.isclose(h, dt_recs[0].h_centre)]
    if at_dt_mesh and dt_recs:
        e = ensembles[at_dt_mesh[0]]
        devs = ", ".join(f"{r.dt_safety:g}: {(r.get('residual_velocity') - e['mean']) / abs(e['mean']) / e['std_rel']:+.1f}"
                         for r in sorted(dt_recs, key=lambda r: -r.dt_safety))
        L += [f"The damaged dt ladder (single runs at {dt_recs[0].h_centre * 1e3:.4g} mm) against the ensemble at that mesh "
              f"(mean {e['mean']:.4g} m/s, standard deviation {_pct(e['std_rel'])}), in standard deviations of a "
              f"single run: {devs}. Levels within about two standard deviations of the mean cannot be ranked "
              "by single runs.", ""]
    rows = []
    for knob in ("mesh", "dt"):
        for case, a in ladders.get(knob, {}).items():
            rec = recommend(a)
            if rec["index"] is None:
                choice = "none within 2 % besides the reference level itself (ladder not converged)"
            else:
                r = rec["record"]
                choice = (f"h_centre = {r.h_centre * 1e3:.4g} mm" if knob == "mesh"
                          else f"dt_safety = {r.dt_safety:g}")
            if knob == "mesh" and case == "damaged" and ens["distance"]:
                choice += " (single runs, within the scatter: see the ensembles above)"
            rows.append([knob, CASES[case]["label"], _fmt(rec["reference"], ".4g") + f" ({rec['reference_kind']})",
                         choice])
    L += _md_table(["knob", "case", "converged v_res (m/s)", "cheapest within 2 %"], rows)
    return L + [""]
