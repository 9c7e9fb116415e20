"""The scene's failure rule (``material.failure``, fabric_fenicsx.impact.setup.FAILURE_RULES):
a bad name is refused; the yarn crack runs an impact whose removed cells lie on lines along the
fill, says what its cracks did in summary.json and cracks.csv, and refuses more than one rank in one line;
the crack that reads its yarn (yarn_strain) holds back its starts and tips in an impact, and the
shear-lag tip (shear_lag) joins its cracks by the concentration of the broken yarns beside it, and
capped where the crossings slip (del_zone) its cracks stay shorter."""

import csv
import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import mpi_env

from fabric_fenicsx.impact.scene import SceneError, load_scene

REPO = Path(__file__).resolve().parents[2]
Y90 = str(REPO / "demos" / "scenes" / "y90.toml")
BASE = [sys.executable, "-m", "fabric_fenicsx.cli", "impact", Y90, "--quiet", "--set", "output.xdmf_interval=0",
        "--set", "output.png=false", "--set", "material.failure=yarn_crack"]


def test_every_failure_rule_the_run_builds_is_a_scene_choice():
    """The scene's key lists the rules by name (the scene loader imports no rule); each name that
    fabric_fenicsx.impact.setup.FAILURE_RULES builds loads."""
    from fabric_fenicsx.impact.setup import FAILURE_RULES

    for name in FAILURE_RULES:
        assert load_scene(Y90, [f"material.failure={name}"]).material.failure == name


def test_an_unknown_failure_rule_is_refused_with_the_known_ones():
    with pytest.raises(SceneError, match="material.failure.*thesis.*yarn_crack"):
        load_scene(Y90, ["material.failure=nosuch"])
    assert load_scene(Y90, []).material.failure == "thesis"


def test_a_yarn_crack_impact_tears_along_the_fill(tmp_path):
    """Y90 (warp along y) at 57.3 m/s on the demo's 4 mm mesh: every removed cell has a yarn
    broken, and the cells removed with a broken warp lie in bands across the warp (narrow along y,
    long along x), no more bands than warp cracks the rule started."""
    run = subprocess.run([*BASE, "--set", "projectile.velocity=57.3", "--set", "mesh.h_centre=0.004",
                          "--out", str(tmp_path / "run")], capture_output=True, text=True, timeout=900)
    assert run.returncode == 0, run.stderr[-3000:]
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    cracks = summary["failure"]["cracks"]
    assert summary["failure"]["rule"] == "yarn_crack" and summary["perforated"]
    assert cracks["warp"]["roots"] >= 1 and cracks["warp"]["tips"] > cracks["warp"]["roots"]
    with open(tmp_path / "run" / "removed_cells.csv") as f:
        rows = list(csv.DictReader(f))
    assert rows and all(min(float(r["alpha1_warp"]), float(r["alpha2_fill"])) < 0.5 for r in rows)
    warp = [r for r in rows if float(r["alpha1_warp"]) < 0.5]
    y = np.sort([float(r["y_m"]) for r in warp])
    x = np.array([float(r["x_m"]) for r in warp])
    bands = np.split(y, np.flatnonzero(np.diff(y) > 0.008) + 1)    # two cells apart: another band
    assert len(warp) > 10 and len(bands) <= cracks["warp"]["roots"]
    assert max(b.ptp() for b in bands) < 0.25 * x.ptp()
    with open(tmp_path / "run" / "cracks.csv") as f:
        joined = list(csv.DictReader(f))
    for family in ("warp", "fill"):
        for kind in ("root", "tip"):
            assert sum(r["family"] == family and r["kind"] == kind for r in joined) == cracks[family][kind + "s"]
    times = [float(r["time_s"]) for r in joined]
    assert times == sorted(times) and 0.0 < times[0] <= float(rows[0]["time_s"])   # a crack before removal
    # each warp tip lies on the line of a warp root's crack (x . d_warp = y here: warp along y)
    roots = {float(r["line_m"]) for r in joined if r["family"] == "warp" and r["kind"] == "root"}
    assert all(float(r["line_m"]) in roots for r in joined if r["family"] == "warp" and r["kind"] == "tip")


def test_a_crack_that_reads_its_yarn_holds_back_its_tips_and_starts_in_an_impact(tmp_path):
    """``yarn_strain`` (fabric_fenicsx.fem.yarn_tip with its roots reading the yarn too), Y90 at
    57.3 m/s, 4 mm, to 1.2 ms: cracks start and run along the fill, and both a crack's start and
    its tips waited for their yarns at times (measured: 3 roots, 12 tips, 12566 tip cell-steps held)."""
    out = tmp_path / "run"
    run = subprocess.run([*BASE[:-1], "material.failure=yarn_strain", "--set", "projectile.velocity=57.3",
                          "--set", "mesh.h_centre=0.004", "--set", "run.t_end=0.0012", "--out", str(out)],
                         capture_output=True, text=True, timeout=900)
    assert run.returncode == 0, run.stderr[-3000:]
    summary = json.loads((out / "summary.json").read_text())
    warp = summary["failure"]["cracks"]["warp"]
    assert summary["failure"]["rule"] == "yarn_strain"
    assert warp["roots"] >= 1 and warp["tips"] >= 1 and warp["tips_held"] > 0 and warp["roots_held"] > 0
    assert warp["held"] >= warp["tips_held"] + warp["roots_held"]
    with open(out / "cracks.csv") as f:
        joined = [r for r in csv.DictReader(f) if r["family"] == "warp"]
    roots = {float(r["line_m"]) for r in joined if r["kind"] == "root"}
    assert all(float(r["line_m"]) in roots for r in joined if r["kind"] == "tip")


def _cracks_of(rule: str, out: Path) -> dict:
    """The warp's crack counts of Y90 at 57.3 m/s, 4 mm, to 1.2 ms, with the failure rule ``rule``."""
    run = subprocess.run([*BASE[:-1], f"material.failure={rule}", "--set", "projectile.velocity=57.3",
                          "--set", "mesh.h_centre=0.004", "--set", "run.t_end=0.0012", "--out", str(out)],
                         capture_output=True, text=True, timeout=900)
    assert run.returncode == 0, run.stderr[-3000:]
    return json.loads((out / "summary.json").read_text())["failure"]["cracks"]["warp"]


def test_the_shear_lag_tip_joins_its_cracks_by_the_concentration_in_an_impact(tmp_path):
    """``shear_lag`` (fabric_fenicsx.fem.shear_lag), Y90 at 57.3 m/s, 4 mm, to 1.2 ms: cracks start
    where a yarn reaches its strength and every tip joins by its yarn's stretch raised by the broken
    yarns beside it (measured: 3 roots, 95 tips, the largest count of broken yarns 367, a crack
    along a clamped edge). Capped at 2 (``del_zone``) the cracks stay short of the lightly loaded
    yarns (measured: 2 roots, 16 tips, at most 85 broken yarns beside a tip)."""
    out = tmp_path / "run"
    warp = _cracks_of("shear_lag", out)
    assert warp["roots"] >= 1 and warp["tips"] >= 1 and warp["concentration_joined"] == warp["tips"]
    assert warp["largest_broken_yarns"] > 1
    with open(out / "cracks.csv") as f:
        joined = [r for r in csv.DictReader(f) if r["family"] == "warp"]
    roots = {float(r["line_m"]) for r in joined if r["kind"] == "root"}
    assert all(float(r["line_m"]) in roots for r in joined if r["kind"] == "tip")
    slip = _cracks_of("del_zone", tmp_path / "del_zone")
    assert slip["roots"] >= 1 and slip["concentration_joined"] == slip["tips"]
    assert slip["tips"] < 0.5 * warp["tips"] and slip["largest_broken_yarns"] < warp["largest_broken_yarns"]


@pytest.mark.skipif(shutil.which("mpirun") is None, reason="needs mpirun")
def test_the_yarn_crack_on_two_ranks_stops_with_one_line(tmp_path):
    run = subprocess.run(["mpirun", "-n", "2", "--oversubscribe", *BASE, "--set", "run.t_end=2e-5",
                          "--out", str(tmp_path / "run")], env=mpi_env(), capture_output=True, text=True,
                         timeout=600)
    assert run.returncode != 0
    assert "runs on one rank" in run.stderr and "Traceback" not in run.stderr
