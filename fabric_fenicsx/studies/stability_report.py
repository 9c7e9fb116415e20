"""The report of the stability study (:mod:`fabric_fenicsx.studies.stability`): reading a
case's history.csv and stop message, the CSV of the outcomes, the plots, and the markdown report
with its hand-written prose (:data:`PROSE_FILE`). Matplotlib is imported when the plots are drawn.
"""

from __future__ import annotations

import csv
import datetime
import math
import platform
import re
from pathlib import Path

import numpy as np

from fabric_fenicsx.studies.stability_cases import (BASE_OVERRIDES, BASE_SCENE, CANONICAL_COMMAND, CASES,
                                                    ENERGY_LIMIT, Case)


def read_history(path: Path) -> dict[str, np.ndarray]:
    """Columns of a history.csv as float arrays (empty dict if missing or empty)."""
    if not path.is_file():
        return {}
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    if len(rows) < 2:
        return {}
    head, body = rows[0], rows[1:]
    data = np.array([[float(x) for x in r] for r in body if len(r) == len(head)], dtype=float)
    if data.size == 0:
        return {}
    return {name: data[:, k] for k, name in enumerate(head)}


_MESSAGE = re.compile(r"impact run stopped at step (?P<step>\d+), t = (?P<t>\S+) s: (?P<what>.+?); "
                      r"(?P<place>.*reference \(x, y\) = .*?m on rank \d+|no owned nodes)", re.S)


def parse_stop_message(message: str) -> dict | None:
    """Step, time, cause and place of an ImpactError message (``_trouble`` format), or None
    if the message does not name them."""
    m = _MESSAGE.search(message)
    if not m:
        return None
    return {"step": int(m["step"]), "time": float(m["t"]), "cause": m["what"].strip(),
            "place": m["place"].strip()}



CSV_COLUMNS = ("name", "case", "status", "verdict", "end_reason", "residual_velocity_m_s",
               "energy_error", "steps", "end_time_s", "wall_time_s", "cpu_time_s", "deleted_cells",
               "eroded_cells", "points_beyond_table", "n_cells", "dt_initial_s", "dt_final_s",
               "history_finite", "history_max_energy_error", "max_kinetic_over_KE0",
               "error_type", "message")


def csv_row(rec: dict) -> dict:
    """One CSV row of a record (missing numbers empty)."""
    s = rec.get("summary") or {}
    h = rec.get("history") or {}
    return {"name": rec["name"], "case": rec["title"], "status": rec["status"],
            "verdict": rec["assessment"]["verdict"], "end_reason": s.get("end_reason", ""),
            "residual_velocity_m_s": s.get("residual_velocity", ""),
            "energy_error": s.get("energy_error", ""), "steps": s.get("n_steps", ""),
            "end_time_s": s.get("end_time", h.get("t_last", "")),
            "wall_time_s": round(rec["wall_time_s"], 2), "cpu_time_s": round(rec["cpu_time_s"], 2),
            "deleted_cells": s.get("deleted_cells", ""), "eroded_cells": s.get("eroded_cells", ""),
            "points_beyond_table": s.get("points_beyond_table", ""), "n_cells": s.get("n_cells", ""),
            "dt_initial_s": s.get("dt_initial", ""), "dt_final_s": s.get("dt", ""),
            "history_finite": h.get("finite", ""), "history_max_energy_error": h.get("max_energy_error", ""),
            "max_kinetic_over_KE0": h.get("max_kinetic_over_KE0", ""),
            "error_type": rec.get("error_type") or "", "message": rec.get("message") or ""}


def write_csv(path: Path, records: list[dict]) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=CSV_COLUMNS)
        w.writeheader()
        for rec in records:
            w.writerow(csv_row(rec))


def plot_histories(records: list[dict], out: Path, plot_dir: Path) -> list[Path]:
    """energy_error.png (energy-balance error against time) and velocity.png (projectile
    velocity against time) of every case with a history; a stopped case ends with an x."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    plot_dir.mkdir(parents=True, exist_ok=True)
    cmap = plt.get_cmap("tab20")
    styles = ("-", "--", ":", "-.")
    paths = []
    for column, fname, ylabel, log in (
            ("energy_error", "energy_error.png", "energy-balance error |balance - KE_0| / KE_0", True),
            ("projectile_velocity", "velocity.png", "projectile velocity / initial velocity v0", False)):
        fig, ax = plt.subplots(figsize=(9, 5.5))
        for k, rec in enumerate(records):
            h = read_history(Path(out) / rec["name"] / "history.csv")
            if not h:
                continue
            t, y = h["time"] * 1e3, h[column]
            if column == "projectile_velocity":
                y = y / y[0]
            if log:
                y = np.maximum(y, 1e-8)
            line, = ax.plot(t, y, styles[k % len(styles)], color=cmap(k % 20), lw=1.2,
                            label=f"{rec['name']} ({rec['status']})")
            if rec["status"] != "completed":
                ax.plot(t[-1], y[-1], "x", color=line.get_color(), ms=9, mew=2)
        if log:
            ax.set_yscale("log")
            ax.axhline(ENERGY_LIMIT, color="k", lw=0.8, ls="--")
            ax.text(0.0, ENERGY_LIMIT * 1.15, "5 % (run.energy_tolerance)", fontsize=8)
        ax.set_xlabel("time (ms)")
        ax.set_ylabel(ylabel)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7, ncol=2, loc="best")
        ax.set_title("Stability cases (Y90, coarse mesh): " + ylabel.split(" |")[0])
        fig.tight_layout()
        path = plot_dir / fname
        fig.savefig(path, dpi=110)
        plt.close(fig)
        paths.append(path)
    return paths


# ============================================================================ report
def _f(x, spec: str) -> str:
    if x is None or x == "" or (isinstance(x, float) and not math.isfinite(x)):
        return "-"
    return format(x, spec)


def _outcome_text(rec: dict) -> str:
    s = rec.get("summary")
    if rec["status"] == "completed":
        return (f"completed ({s['end_reason']} at {s['end_time'] * 1e3:.3f} ms), energy error "
                f"{s['energy_error']:.3%}")
    return f"{rec['status']}: {rec['error_type']}: {_short(rec['message'])}"


def _short(message: str, n: int = 160) -> str:
    message = " ".join(str(message).split())
    return message if len(message) <= n else message[:n - 3] + "..."


def _settings_text(case: Case, rec: dict) -> str:
    parts = [f"`{o}`" for o in case.overrides]
    if case.fabric:
        fab = rec["settings"]["fabric"]
        w, f = fab["warp"], fab["fill"]
        parts.append(f"fabric `{case.fabric[0]}` = {case.fabric[1]:g}: warp L = {w['L'] * 1e3:.4f} mm, "
                     f"Phi_L = {w['Phi_L']:.4f}, A0 = {w['A0']:.4g} N, B0 = {w['B0']:.4g} N m^2; "
                     f"fill L = {f['L'] * 1e3:.4f} mm, Phi_L = {f['Phi_L']:.4f}, A0 = {f['A0']:.4g} N, "
                     f"B0 = {f['B0']:.4g} N m^2 (written to `{rec['name']}/fabric.toml`)")
    return "; ".join(parts) or "none"


def table_rows(records: list[dict]) -> list[list[str]]:
    rows = []
    for rec in records:
        s = rec.get("summary") or {}
        h = rec.get("history") or {}
        if rec["status"] == "completed":
            outcome = f"completed: {s['end_reason']}"
            err = _f(s["energy_error"], ".3%")
        elif rec["status"] == "stopped":
            stop = rec.get("stop") or parse_stop_message(rec["message"]) or {}
            outcome = (f"**stopped** at step {stop.get('step', '?')}, t = "
                       f"{_f(stop.get('time'), '.4g')} s: {_short(stop.get('cause', rec['message']), 90)}")
            err = _f(h.get("last_energy_error"), ".3%") + " (last row)"
        else:
            outcome = f"**failed**: `{rec['error_type']}`: {_short(rec['message'], 90)}"
            err = "-"
        removed = (f"{s['deleted_cells']} + {s['eroded_cells']}" if s else "-")
        rows.append([rec["name"], rec["title"], outcome,
                     _f(s.get("residual_velocity"), ".3f"), err, _f(s.get("n_steps"), "d"),
                     _f(s.get("end_time", h.get("t_last")) * 1e3 if (s.get("end_time") or h.get("t_last"))
                        else None, ".3f"),
                     _f(rec["wall_time_s"], ".1f"), _f(rec["cpu_time_s"], ".1f"), removed,
                     _f(s.get("points_beyond_table"), "d"),
                     ("ok" if rec["assessment"]["verdict"] == "ok" else "**finding**")
                     + (f" ({VERDICT_NOTES[rec['name']]})" if rec["name"] in VERDICT_NOTES else "")])
    return rows


def _md_table(header: list[str], rows: list[list[str]]) -> list[str]:
    out = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    out += ["| " + " | ".join(str(c).replace("|", "/") for c in r) + " |" for r in rows]
    return out


def _facts(rec: dict) -> str:
    """Measured facts of one case for its paragraph (generated, so they follow the numbers)."""
    s, h = rec.get("summary") or {}, rec.get("history") or {}
    bits = []
    if rec["status"] == "completed":
        bits.append(f"Completed ({s['end_reason']}) at t = {s['end_time'] * 1e3:.3f} ms after "
                    f"{s['n_steps']} steps on {s['n_cells']} cells; residual velocity "
                    f"{s['residual_velocity']:.3f} m/s (v0 = {s['v0']:g} m/s), largest energy-balance "
                    f"error {s['energy_error']:.3%}")
        bits.append(f"the time step is {s['dt_initial']:.4g} s at the start, {s['dt']:.4g} s at the end "
                    f"(dt lowered {s['n_dt_changes']} time(s))")
        if s.get("damage_onset_time") is not None:
            bits.append(f"damage starts at {s['damage_onset_time'] * 1e3:.3f} ms (central deflection "
                        f"{s['damage_onset_deflection'] * 1e3:.2f} mm)")
        elif "material.damage=false" in rec["settings"]["overrides"]:
            bits.append("damage off")
        else:
            bits.append("no yarn damaged")
        bits.append(f"removed cells {s['deleted_cells']} deleted + {s['eroded_cells']} eroded; "
                    f"absorbed energy {s['absorbed_energy']:.2f} J")
        bits.append(f"strain evaluations beyond the table (damage off) {s['points_beyond_table']}, "
                    f"compressed below it {s['points_below_table']}")
        if s.get("surrogate_range"):
            bits.append(s["surrogate_range"].splitlines()[0].replace("surrogate range: ", "surrogate: "))
        if s.get("surrogate_solves"):
            bits.append(f"the surrogate solved {s['surrogate_solves']} unit cells for new table tiles "
                        f"({s['surrogate_tile_seconds']:.1f} s)")
    elif rec["status"] == "stopped":
        bits.append(f"Stopped by `ImpactError` after {rec['wall_time_s']:.1f} s; message: "
                    f"\"{_short(rec['message'], 700)}\"")
    else:
        bits.append(f"Failed with `{rec['error_type']}` after {rec['wall_time_s']:.1f} s; message: "
                    f"\"{_short(rec['message'], 700)}\"")
    frag = rec.get("fragments") or {}
    if not frag and s and s.get("deleted_cells") == 0 and s.get("eroded_cells") == 0:
        bits.append("no cell removed, so the fabric is one piece")
    if frag.get("pieces"):
        free = [p for p in frag["pieces"] if not p["anchored"]]
        text = (f"live cells at the end: {len(frag['pieces'])} connected piece(s), "
                f"{frag['free_fragments']} of them cut loose from the clamped edges")
        if free:
            text += " (" + ", ".join(f"{p['cells']} cell(s) moving at {-p['mean_velocity_z']:.1f} m/s"
                                     for p in free) + ")"
        bits.append(text)
    if h.get("rows"):
        bits.append(f"its history.csv has {h['rows']} rows, {'all finite' if h['finite'] else 'NON-FINITE values'}, "
                    f"largest central deflection {h['max_central_deflection'] * 1e3:.2f} mm, largest "
                    f"kinetic energy {h.get('max_kinetic_over_KE0', float('nan')):.3f} KE_0")
    problems = rec["assessment"]["problems"]
    bits.append("Verdict: " + ("ok" if not problems else "FINDING: " + "; ".join(problems)))
    return ". ".join(b[0].upper() + b[1:] for b in bits) + "."


def _code_text(records: list[dict]) -> str:
    """Which source the cases ran with (the package changes while studies run)."""
    codes = {}
    for r in records:
        codes.setdefault((r.get("git_head", "?"), r.get("model_version", "?")), []).append(r["name"])
    if len(codes) == 1:
        (head, version), = codes
        return (f"All cases ran with the same code: git commit `{head}` ('+' = with uncommitted edits), "
                f"model version `{version}` (`provenance.model_version`, a hash of the modules that "
                "compute an impact).")
    parts = [f"`{head}`/`{v}`: {', '.join(names)}" for (head, v), names in codes.items()]
    return "The cases ran with different code (git commit / model version): " + "; ".join(parts) + "."


VERDICT_NOTES = {"v1000": "finding 1, fixed", "friction-0": "an earlier run: finding 2, fixed",
                 "beyond-table": "finding 3, fixed"}
"""Hand-written pointers from the table's verdict column to the findings below it."""

PROSE_FILE = Path(__file__).resolve().parents[2] / "docs" / "stability" / "discussion.md"
"""The report's hand-written prose: a ``## <case name>`` section reading each case (numbers as
in the table) and a ``## Findings`` section (what code change would fix each finding)."""

FINDINGS = "Findings"
"""Heading of the prose's findings section."""


def _markdown_sections(path: Path) -> dict[str, str]:
    """The ``## `` sections of a markdown file: heading -> its text, line for line, without the
    blank lines around it. Text before the first section is left out; ``###`` headings belong
    to the text of their section."""
    sections: dict[str, list[str]] = {}
    body = None
    for line in Path(path).read_text().splitlines():
        if line.startswith("## "):
            heading = line[3:].strip()
            if heading in sections:
                raise ValueError(f"{path}: section '## {heading}' appears twice")
            body = sections[heading] = []
        elif body is not None:
            body.append(line)
    return {heading: "\n".join(lines).strip("\n") for heading, lines in sections.items()}


def read_prose(path: Path = PROSE_FILE) -> tuple[dict[str, str], str]:
    """The report's hand-written prose (:data:`PROSE_FILE`): the reading of each case, by case
    name, and the findings' notes. A section named neither after a case nor ``Findings`` is an
    error (a misspelt case name would silently lose its reading)."""
    sections = _markdown_sections(path)
    if FINDINGS not in sections:
        raise ValueError(f"{path}: no '## {FINDINGS}' section")
    findings = sections.pop(FINDINGS)
    unknown = sorted(set(sections) - {c.name for c in CASES})
    if unknown:
        raise ValueError(f"{path}: section(s) {unknown} name no case; valid: "
                         f"{', '.join(c.name for c in CASES)}, {FINDINGS}")
    return sections, findings


def write_report(doc: Path, out: Path, records: list[dict], cases, command: str, plots: list[Path],
                 csv_copy: Path, prose: Path = PROSE_FILE) -> None:
    """The markdown report: command, date, base settings, outcome table, per-case paragraphs,
    findings and plots; the hand-written parts come from ``prose`` (:func:`read_prose`)."""
    doc = Path(doc)
    discussion, notes = read_prose(prose)
    by_name = {c.name: c for c in cases}
    total_cpu = sum(r["cpu_time_s"] for r in records)
    total_wall = sum(r["wall_time_s"] for r in records)
    findings = [r for r in records if r["assessment"]["verdict"] != "ok"]
    rel = lambda p: Path(p).resolve().relative_to(doc.parent.resolve()).as_posix() \
        if Path(p).resolve().is_relative_to(doc.parent.resolve()) else str(p)
    lines = [
        "# Stability on stiff and extreme cases",
        "",
        "Each case below is the Y90 impact changed in one respect and run to its end; "
        "its outcome is either *completed* (with its energy-balance error) or *stopped* (with "
        "the message). No case may produce NaN, a silent blow-up or an energy error above 5 % "
        "without stopping and naming the cause.",
        "",
        "## How this was made",
        "",
        "Every number below is reproduced, from scratch, by",
        "",
        "```",
        CANONICAL_COMMAND,
        "```",
        "",
        "(without `--rerun` a case whose `result.json` holds the same settings is reused; "
        f"this file was last written by `{command}`).",
        "",
        f"Generated {datetime.datetime.now().isoformat(timespec='seconds')} on {platform.node() or 'this machine'} "
        f"(Python {platform.python_version()}); each case's own run date is in "
        f"`{out}/<case>/result.json`. Cases run one after the other on one MPI rank. "
        f"Run folders (history.csv, summary.json, result.json, fabric.toml) are in `{out}/`; "
        f"the table as CSV: [{rel(csv_copy)}]({rel(csv_copy)}).",
        "",
        _code_text(records) + " The runs are deterministic on one rank: an earlier version of "
        "this study ran the six cases with removed cells twice and got the same numbers to the "
        "last digit; only the times vary.",
        "",
        f"Base scene: `{BASE_SCENE}` (Y90: warp along global Y, edges y = +-side/2 clamped, "
        "Zylon AS with the upper bending bound, 37.1 g flat-ended projectile of 25.4 mm at "
        "57.3 m/s, friction 0.5, damage on, damping xi = 0.1, dt_safety 0.8, "
        "run.energy_tolerance 0.05) with",
        "",
        "```",
        *BASE_OVERRIDES,
        "```",
        "",
        "(a graded mesh of 4 mm at the impact point and 12 mm at the edges, 1039 cells for the "
        "centre impact; 0.6 ms of impact, in which the base case reaches damage onset; no XDMF, "
        "no pictures). Each case adds the overrides listed in its paragraph.",
        "",
        "## Outcomes",
        "",
        "Energy error: the largest relative energy-balance error of the run (summary "
        "`energy_error`; for a stopped run the error in the last row of history.csv). Removed "
        "cells: deleted + eroded. Beyond table: yarn-strain evaluations above the surrogate's "
        "table with damage off (`points_beyond_table_damage_off`). Wall and CPU times include "
        "building the scene and any new surrogate tiles.",
        "",
        *_md_table(["name", "case", "outcome", "v_res (m/s)", "energy error", "steps", "end (ms)",
                    "wall (s)", "CPU (s)", "removed cells", "beyond table", "verdict"],
                   table_rows(records)),
        "",
        f"Total over the {len(records)} cases: {total_wall:.0f} s wall, {total_cpu:.0f} s CPU "
        "(as recorded when each case ran, whatever else the machine ran then). They include "
        "the table tiles a case had to solve (the fabric variants: each case's paragraph gives "
        "the unit cells solved and their time); tiles already in the cache (~/.cache/fabric_fenicsx) "
        "are only read from disk (under a second in benchmarks/bench_impact.py).",
        "",
    ]
    for p in plots:
        lines += [f"![{p.stem}]({rel(p)})", ""]
    lines += ["Energy-balance error (log scale, dashed: the 5 % limit) and projectile velocity "
              "against time for every case with a history; x marks where a stopped run ended.", "",
              "## The cases", ""]
    for rec in records:
        case = by_name.get(rec["name"])
        lines += [f"### {rec['name']}: {rec['title']}", ""]
        if case is not None:
            lines += [f"*Probes*: {case.purpose}. *Overrides*: {_settings_text(case, rec)}.", ""]
        lines += [_facts(rec), ""]
        if rec["name"] in discussion:
            lines += [discussion[rec["name"]], ""]
    lines += ["## Findings", "",
              "Flagged by the study's own checks (NaN, energy error above 5 % without a stop, kinetic "
              "energy above 1.2 KE_0, a stop message without step/time/place, an exception outside "
              "the impact guards, a blow-up stop caused by a free fragment):", ""]
    if findings:
        for r in findings:
            lines.append(f"* **{r['name']}**: " + "; ".join(r["assessment"]["problems"]))
    else:
        lines.append("* none.")
    lines += ["", notes, ""]
    lines += ["## Tests", "",
              "`tests/studies/test_stability.py` runs the fast cases on the study's coarse graded mesh, "
              "cut short (t_end 0.1-0.15 ms, or run.max_steps), plus v1000 as it is, and asserts "
              "their outcome: completed with finite fields and an energy error below 5 %, or "
              "stopped with an `ImpactError` naming step, time and place; "
              "`test_1000_m_per_s_plug_ends_as_a_perforation` checks the fix of finding 1. The "
              "fabric variants (a minute of table tiles each) are checked through their geometry "
              "only.", ""]
    doc.parent.mkdir(parents=True, exist_ok=True)
    doc.write_text("\n".join(lines))
