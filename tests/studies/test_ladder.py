"""``fabric-fenicsx ladder``: the analysis of a ladder of rungs (each size's error against the
finest, the families, the variants, the recommended size, the cost of an interval) on made-up
rows, and the command on stand-in runs whose statistics are known."""
import json
import math
import random
import sys
from pathlib import Path

import pytest

from fabric_fenicsx.studies import ladder, runpool

ROOT = Path(__file__).resolve().parents[2]
SCENE = str(ROOT / "demos" / "scenes" / "y90.toml")


def _row(family, size, v50, half, variant="", residual=30.0, residual_half=1.0):
    return {"rung": ladder.Rung(family, size, variant).key, "family": family, "size": size, "variant": variant,
            "v50": v50, "v50_lo": v50 - half, "v50_hi": v50 + half, "v50_sigma": 3.0, "v50_runs": 20,
            "v50_counted": 20, "v50_core_s": 2000.0 / size * 1e-3, "v50_stop": "x",
            "residual_velocity": residual, "residual_velocity_lo": residual - residual_half,
            "residual_velocity_hi": residual + residual_half, "residual_velocity_sd": 2.0,
            "residual_velocity_runs": 12, "residual_velocity_core_s": 1200.0 / size * 1e-3}


def test_rungs_sizes_and_variants():
    rungs = ladder.rungs(["graded", "aligned"], [0.002, 0.004, 0.002], ["run.damping=0.05"], 0.002)
    assert [r.key for r in rungs] == ["graded-4mm", "graded-2mm", "aligned-4mm", "aligned-2mm",
                                      "graded-2mm-run.damping=0.05", "aligned-2mm-run.damping=0.05"]
    assert rungs[-1].overrides() == ("mesh.kind=aligned", "mesh.h_centre=0.002", "run.damping=0.05")
    with pytest.raises(ValueError, match="must be one of the sizes"):
        ladder.rungs(["graded"], [0.004], ["run.damping=0.05"], 0.003)


def test_the_analysis_finds_each_sizes_error_and_the_coarsest_size_that_agrees():
    rows = [_row("graded", 0.004, 45.0, 1.0), _row("graded", 0.002, 40.5, 1.0), _row("graded", 0.001, 40.0, 1.0),
            _row("aligned", 0.004, 41.0, 1.0), _row("aligned", 0.002, 40.2, 1.0), _row("aligned", 0.001, 41.0, 1.0),
            _row("graded", 0.002, 43.0, 1.0, variant="run.damping=0.05"),
            _row("aligned", 0.002, 40.4, 1.0, variant="run.damping=0.05")]
    a = ladder.analyse(rows)
    err = {(e["family"], e["size"], e["statistic"]): e for e in a["errors"]}
    assert err[("graded", 0.004, "v50")]["difference"] == pytest.approx(5.0)
    assert err[("graded", 0.004, "v50")]["half_width"] == pytest.approx(math.sqrt(2.0))
    assert err[("graded", 0.004, "v50")]["agree"] is False and err[("graded", 0.002, "v50")]["agree"] is True
    assert err[("aligned", 0.004, "v50")]["agree"] is True
    assert ladder.recommend(a) == 0.002                     # 4 mm: graded's V50 is 5 m/s off
    fam = {(f["size"], f["statistic"]): f for f in a["families"]}
    assert fam[(0.004, "v50")]["difference"] == pytest.approx(4.0) and fam[(0.004, "v50")]["agree"] is False
    var = {(v["family"], v["statistic"]): v for v in a["variants"]}
    assert var[("graded", "v50")]["difference"] == pytest.approx(2.5) and var[("graded", "v50")]["within_interval"] is False
    assert var[("aligned", "v50")]["within_interval"] is True
    rows[2] = _row("graded", 0.001, 40.0, 1.0, residual=35.0)
    assert ladder.recommend(ladder.analyse(rows)) == 0.001  # the mean residual velocities differ at every coarser size
    cost = {(c["rung"], c["statistic"]): c for c in ladder.runs_for(1.0, rows)}
    assert cost[("graded-1mm", "v50")]["runs"] == 80        # a 2 m/s wide interval from 20 runs: 4 x as many for 1 m/s
    assert cost[("graded-1mm", "v50")]["core_hours"] == pytest.approx(80 * 100.0 / 3600)


def _stand_in(run, folder):
    """A run of the stand-in scene: V50 = 40 + 1000 (h - 1 mm) m/s (aligned 1 m/s higher), sigma
    4 m/s; the residual velocity 30 + 2000 (h - 1 mm) m/s with sd 0.5 m/s; a number drawn from
    the run's folder decides."""
    settings = dict(o.split("=", 1) for o in run.overrides)
    v, h = float(settings["projectile.velocity"]), float(settings["mesh.h_centre"])
    shift = 1.0 if settings["mesh.kind"] == "aligned" else 0.0
    z = random.Random(str(folder.relative_to(folder.parents[2]))).gauss(0.0, 1.0)
    if "stop_when_held" in " ".join(run.overrides):
        through = v > 40.0 + 1000.0 * (h - 0.001) + shift + 4.0 * z
        residual = max(v - 38.0, 1.0) if through else -0.5
    else:
        through, residual = True, 30.0 + 2000.0 * (h - 0.001) + 0.5 * z
    summary = {"perforated": through, "end_reason": "perforated" if through else "held",
               "residual_velocity": residual, "absorbed_energy": 1.0, "wall_time_s": 1000.0 * h}
    return [sys.executable, "-c", f"open({str(folder / 'summary.json')!r}, 'w').write({json.dumps(summary)!r})"]


def test_the_command_on_stand_in_runs(tmp_path, monkeypatch, capsys):
    from fabric_fenicsx.cli import main

    monkeypatch.setattr(runpool, "_command", _stand_in)
    monkeypatch.setattr(runpool, "_stored", lambda run, folder: None)
    out = tmp_path / "ladder"
    args = ["ladder", SCENE, "--sizes", "0.004,0.001", "--families", "graded,aligned", "--variant", "run.damping=0.05",
            "--variant-size", "0.001", "--members", "6", "--max-runs", "16", "--bracket", "30,50", "--jobs", "2", "--quiet", "--out", str(out)]
    assert main(args) == 0
    rep = json.loads((out / "ladder.json").read_text())
    rows = {r["rung"]: r for r in rep["rows"]}
    assert list(rows) == ["graded-4mm", "graded-1mm", "aligned-4mm", "aligned-1mm", "graded-1mm-run.damping=0.05",
                          "aligned-1mm-run.damping=0.05"]
    for key, mean in (("graded-4mm", 36.0), ("graded-1mm", 30.0), ("aligned-1mm", 30.0)):
        r = rows[key]
        assert r["residual_velocity_lo"] < mean < r["residual_velocity_hi"] and r["residual_velocity_runs"] == 6
        assert r["v50"] is not None and 2 <= r["v50_runs"] <= 16 and r["v50_core_s"] == pytest.approx(1000.0 * float(key.split("-")[1][:-2]) * 1e-3
                                                                             * r["v50_runs"])
    err = {(e["family"], e["size"], e["statistic"]): e for e in rep["errors"]}
    assert err[("graded", 0.004, "residual_velocity")]["agree"] is False      # 6 m/s off, intervals of ~0.5 m/s
    assert rep["recommended_size"] == 0.001
    md = (out / "ladder.md").read_text()
    assert "| graded-1mm-run.damping=0.05 |" in md and "| graded | 1 | reference | reference |" in md
    assert "none coarser than the finest (1 mm) agrees with it" in md
    assert (out / "ladder.png").stat().st_size > 10000
    assert len((out / "ladder.csv").read_text().splitlines()) == 7
    assert (out / "aligned-4mm" / "v50" / "v50.csv").exists() and (out / "aligned-4mm" / "members").is_dir()
    assert main(["ladder", SCENE, "--sizes", "0.004", "--variant", "run.damping=0.05", "--out", str(tmp_path / "x")]) == 2
    assert "must be one of the sizes" in capsys.readouterr().err


def test_a_sharp_limit_is_reported_as_its_bracket():
    """Outcomes separated in velocity (a scene that repeats run for run, like XY0): no probit, V50
    is the bracket's midpoint with the bracket as its interval, and its cost is not scaled as
    1 / sqrt(runs); a mixed zone gives the probit as before."""
    def rows(velocities, limit):
        return [{"velocity": v, "outcome": "perforated" if v > limit else "held",
                 "residual_velocity": v - limit if v > limit else -0.1, "wall_time_s": 10.0} for v in velocities]

    members = [{"residual_velocity": 30.0, "wall_time_s": 10.0}] * 4
    sharp = ladder.measure(ladder.Rung("graded", 0.002), rows([36.0, 38.0, 39.0, 39.5, 40.0, 42.0], 39.2),
                           "design ended", members)
    assert sharp["v50_kind"] == "bracket" and (sharp["v50_lo"], sharp["v50_hi"]) == (39.0, 39.5)
    assert sharp["v50"] == pytest.approx(39.25) and sharp["v50_sigma"] is None
    assert not [c for c in ladder.runs_for(2.0, [sharp]) if c["statistic"] == "v50"]
    other = dict(sharp, rung="graded-4mm", size=0.004, v50=39.6, v50_lo=39.3, v50_hi=39.9)
    err = {e["size"]: e for e in ladder.analyse([other, sharp])["errors"] if e["statistic"] == "v50"}
    assert err[0.004]["agree"] is True                      # the brackets overlap
    mixed = [{"velocity": v, "outcome": o, "residual_velocity": 1.0 if o == "perforated" else -0.1,
              "wall_time_s": 10.0}
             for v, o in [(34, "held"), (36, "held"), (37, "perforated"), (38, "held"), (39, "perforated"),
                          (40, "held"), (41, "perforated"), (43, "perforated"), (35, "held"), (42, "perforated")]]
    fitted = ladder.measure(ladder.Rung("graded", 0.002), mixed, "n runs", members)
    assert fitted["v50_kind"] == "probit" and fitted["v50_lo"] < fitted["v50"] < fitted["v50_hi"]
