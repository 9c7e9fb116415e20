"""Interfaces no other test runs: ``fabric-fenicsx surrogate build | report``, ``fabric-fenicsx
convergence`` (help, refused ladders, and its quick unit-cell knob), the Table 4 study
(``python -m fabric_fenicsx.studies.table4``: help and a tiny run with overrides) and a fabric
loaded from a file (scene ``fabric.file``, ``surrogate --fabric``).

Each runs on settings small enough for the suite (a 0.01 strain grid, 2 r-nodes, a few unit-cell
states, an 8 x 8 impact mesh for a few steps) and checks what the command promises to write.
"""

import csv
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from fabric_fenicsx.cli import main
from fabric_fenicsx.material.fabric import zylon_as
from fabric_fenicsx.material.fibril import BundleDamage
from fabric_fenicsx.surrogate.table import Surrogate

ROOT = Path(__file__).resolve().parents[1]
TINY_TABLE = ["--resolution", "0.01", "--r-nodes", "2", "--order", "1", "--workers", "1"]
"""The coarsest table the surrogate accepts: 19 nodes per axis."""


def _env():
    return dict(os.environ, MPLBACKEND="Agg",
                PYTHONPATH=os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])))


def a_fabric():
    """A fabric unlike the built-in one in every part a file holds: yarns, density, damage law."""
    fab = zylon_as("min").with_yarn("warp", A0=1.3 * zylon_as().warp.A0).with_yarn("fill", mu_crit=1.028)
    return fab.replace(density=1500.0, damage=BundleDamage.for_width(0.03, 1.025, n=300, seed=4))


# ============================================================================ fabric files
def test_a_fabric_file_round_trips_every_field(tmp_path):
    fab = a_fabric()
    fab.save(tmp_path / "f.toml")
    from fabric_fenicsx.material.fabric import Fabric
    assert Fabric.load(tmp_path / "f.toml").to_dict() == fab.to_dict()


def test_a_scene_loads_its_fabric_from_a_file_next_to_it(tmp_path):
    """``fabric.file`` is read relative to the scene file and replaces the built-in fabric in
    what an impact run builds (`impact.setup.build_fabric`, which ImpactSimulation calls)."""
    from fabric_fenicsx.impact.scene import load_scene
    from fabric_fenicsx.impact.setup import build_fabric
    fab = a_fabric()
    (tmp_path / "fabrics").mkdir()
    fab.save(tmp_path / "fabrics" / "stiff.toml")
    scene_file = tmp_path / "scenes" / "s.toml"
    scene_file.parent.mkdir()
    scene_file.write_text('[fabric]\nfile = "../fabrics/stiff.toml"\n')
    scene = load_scene(scene_file)
    assert Path(scene.fabric.file).resolve() == (tmp_path / "fabrics" / "stiff.toml").resolve()
    built = build_fabric(scene)
    assert built.to_dict() == fab.to_dict() and built.to_dict() != zylon_as().to_dict()
    assert build_fabric(load_scene(None)).to_dict() == zylon_as("max").to_dict()


# ============================================================================ surrogate command
def test_surrogate_build_solves_caches_and_reuses_the_tiles(tmp_path, capsys):
    cache = tmp_path / "cache"
    args = ["surrogate", "build", *TINY_TABLE, "--layers", "intact", "--E-range", "0", "0.02",
            "--cache", str(cache)]
    assert main(args) == 0
    first = capsys.readouterr().out
    sur = Surrogate(zylon_as("max"), resolution=0.01, r_nodes=2, order=1, cache_dir=cache, progress=False)
    files = sorted((cache / f"surrogate-{sur.key}").glob("intact_*.npz"))
    assert files and not list((cache / f"surrogate-{sur.key}").glob("damaged_*.npz"))
    solves = int(first.strip().splitlines()[-1].split()[0])
    assert solves > 0 and f"surrogate {sur.key}" in first
    assert main(args) == 0                                     # the second build loads them all
    assert capsys.readouterr().out.strip().splitlines()[-1].startswith("0 unit-cell solves")
    # what was cached is what the unit cell gives
    from fabric_fenicsx.material.unitcell import UnitCell
    P1, P2, _, _ = sur.evaluate(0.01, 0.01, 1.0, 1.0, tension_only=False)
    assert sur.solves == 0
    ref = UnitCell(zylon_as("max")).solve(0.01, 0.01)
    assert float(P1) == pytest.approx(ref.P1, rel=1e-6) and float(P2) == pytest.approx(ref.P2, rel=1e-6)


def test_surrogate_build_of_a_fabric_file_keys_the_table_by_that_fabric(tmp_path, capsys):
    fab = a_fabric()
    fab.save(tmp_path / "f.toml")
    cache = tmp_path / "cache"
    assert main(["surrogate", "build", *TINY_TABLE, "--layers", "intact", "--E-range", "0", "0.005",
                 "--cache", str(cache), "--fabric", str(tmp_path / "f.toml")]) == 0
    key = Surrogate(fab, resolution=0.01, r_nodes=2, order=1, cache_dir=False).key
    assert key != Surrogate(zylon_as(), resolution=0.01, r_nodes=2, order=1, cache_dir=False).key
    assert [p.name for p in cache.iterdir()] == [f"surrogate-{key}"]
    assert f"surrogate {key}" in capsys.readouterr().out


@pytest.mark.parametrize("args, message", [
    (["build", "--layers", "intact,plastic"], "unknown layer(s) ['plastic']; valid: intact, damaged"),
    (["report"], "surrogate report needs --out DIR"),
])
def test_surrogate_command_refuses_bad_options(args, message, tmp_path):
    with pytest.raises(SystemExit, match=message.replace("(", r"\(").replace(")", r"\)")
                       .replace("[", r"\[").replace("]", r"\]")):
        main(["surrogate", *args, "--cache", str(tmp_path)])


def test_surrogate_report_writes_its_tables(tmp_path, capsys, monkeypatch):
    """The report command's wiring (fabric, --states, --seed, --workers, --out) on a one-entry
    ladder of the coarsest table (the default ladder solves tables down to h = 0.001: minutes)."""
    from fabric_fenicsx.studies import surrogate_report
    seen = {}
    real = surrogate_report.run_report

    def small(fabric, out_dir, **kwargs):
        seen.update(kwargs, fabric=fabric)
        return real(fabric, out_dir, ladder=((0.01, 2, 1),), n_rate=500, progress=False, **kwargs)

    monkeypatch.setattr(surrogate_report, "run_report", small)
    out = tmp_path / "report"
    assert main(["surrogate", "report", "--out", str(out), "--states", "4", "--seed", "3",
                 "--workers", "1"]) == 0
    assert seen["n_states"] == 4 and seen["seed"] == 3 and seen["workers"] == 1
    assert seen["fabric"].to_dict() == zylon_as("max").to_dict()
    with open(out / "surrogate_report.csv") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 1 and float(rows[0]["resolution"]) == 0.01
    err = float(rows[0]["max_err_N_per_m"])
    assert 0 < err < 0.2 * 148e3 and int(rows[0]["solves"]) > 0      # a coarse, linear table
    for name in ("surrogate_report.md", "surrogate_report.json", "surrogate_error_vs_time.png"):
        assert (out / name).stat().st_size > 0
    assert f"report written to {out}/surrogate_report.md (1 table settings)" in capsys.readouterr().out


# ============================================================================ convergence command
def test_convergence_help_lists_every_knob(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["convergence", "--help"])
    assert exc.value.code == 0
    text = capsys.readouterr().out
    for word in ("--only", "--levels", "--safeties", "--dt-mesh", "--quick", "--rerun",
                 "unitcell,surrogate,mesh,dt,scatter"):
        assert word in text, word


@pytest.mark.parametrize("args, message", [
    (["--levels", "4,2"], "the mesh ladder of .* needs at least three levels"),
    (["--levels", "12,8,4"], "h_centre above h_edge = 8 mm"),
    (["--safeties", "0.8,0.8,0.6"], "the dt ladder needs at least three distinct levels"),
    (["--safeties", "1.2,0.8,0.6"], r"dt_safety must lie in \(0, 1\]"),
])
def test_convergence_refuses_bad_ladders_before_any_run(args, message, tmp_path):
    with pytest.raises(SystemExit, match=message):
        main(["convergence", "--out", str(tmp_path / "c"), *args])
    assert not (tmp_path / "c").exists()


def test_convergence_quick_unit_cell_knob_writes_its_report(tmp_path):
    """``--quick --only unitcell``: the unit-cell ladder (4, 8, 16 elements against 64) at the
    study's states, its tables, plot and report; no impact run is asked for or made. Its errors
    fall at second order, as the element promises (tests/material/test_unitcell.py)."""
    out = tmp_path / "conv"
    assert main(["convergence", "--quick", "--only", "unitcell", "--out", str(out)]) == 0
    uc = json.loads((out / "unitcell.json").read_text())
    assert sorted(s["n"] for s in uc["summary"]) == [4, 8, 16, 64] and uc["reference"] == 64
    err = {s["n"]: s for s in uc["summary"]}
    order = np.log2(err[8]["max_err_P1"] / err[16]["max_err_P1"])
    assert 1.8 < order < 2.2, order
    for name in ("unitcell.csv", "unitcell_summary.csv", "unitcell_error_vs_time.png", "plan.json"):
        assert (out / name).stat().st_size > 0
    report = (out / "convergence.md").read_text()
    assert "Quick smoke version" in report and "## 1. Unit cell" in report
    assert not (out / "runs").exists() or not any((out / "runs").iterdir())


# ============================================================================ Table 4 study
def test_table4_help():
    proc = subprocess.run([sys.executable, "-m", "fabric_fenicsx.studies.table4", "--help"], env=_env(),
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    for word in ("--scene", "--out", "--runs", "--set"):
        assert word in proc.stdout


def test_table4_tiny_run_writes_the_table_and_reuses_its_runs(tmp_path, capsys):
    """The five velocities on an 8 x 8 mesh for 30 steps (damage off): one run folder each with
    the overrides applied, table4.csv/md/png with the thesis's columns; a second call reuses
    every stored run."""
    from fabric_fenicsx.studies import table4
    tiny = ["mesh.kind=uniform", "mesh.n=8", "mesh.side=0.08", "projectile.diameter=0.02",
            "projectile.mass=0.005", "material.damage=false", "run.max_steps=30"]
    argv = ["--out", str(tmp_path / "doc"), "--runs", str(tmp_path / "runs")]
    for o in tiny:
        argv += ["--set", o]
    assert table4.main(argv) == 0
    first = capsys.readouterr().out
    assert first.count("table4: running V0") == 5
    with open(tmp_path / "doc" / "table4.csv") as f:
        rows = list(csv.DictReader(f))
    assert [float(r["v0"]) for r in rows] == [34.5, 39.78, 57.3, 83.06, 123.69]
    for r in rows:
        assert r["end_reason"] == "max_steps" and int(r["n_steps"]) == 30 and int(r["n_cells"]) == 64
        summary = json.loads((tmp_path / "runs" / f"v{float(r['v0']):g}" / "summary.json").read_text())
        assert summary["settings"]["mesh"]["n"] == 8 and summary["v0"] == float(r["v0"])
        assert summary["settings"]["output"]["png"] is False          # the study's own overrides
    assert rows[-1]["thesis_residual"] == "110.0" and rows[-1]["experiment_residual"] == "97.99"
    assert rows[0]["thesis_residual"] == ""                             # "bounced back"
    md = (tmp_path / "doc" / "table4.md").read_text()
    assert "--set mesh.n=8" in md and md.count("\n| ") == 6
    assert (tmp_path / "doc" / "table4.png").read_bytes()[:4] == b"\x89PNG"
    assert table4.main(argv) == 0
    assert "table4: running" not in capsys.readouterr().out


# ----------------------------------------------------------------------------- negative numbers
def test_a_negative_number_after_an_option_is_its_value_in_every_subcommand():
    """argparse takes '-1e-12' for an option ("expected one argument"); the command line joins
    it onto the option before it, for every subcommand, and leaves everything else alone."""
    from fabric_fenicsx.cli import build_parser, join_negative_values

    parser = build_parser()
    assert join_negative_values(parser, ["ensemble", "s.toml", "--perturbation", "-1e-12", "-n", "-3"]) == \
        ["ensemble", "s.toml", "--perturbation=-1e-12", "-n=-3"]
    assert join_negative_values(parser, ["static", "--scenario", "equibiaxial", "--step", "-1e-3"])[-1] == "--step=-1e-3"
    assert join_negative_values(parser, ["divergence", "s.toml", "--pert", "-2e-12"])[-1] == "--pert=-2e-12"
    untouched = ["ensemble", "s.toml", "--quiet", "-1e-3", "--set", "a.b=-1", "--", "--out", "-1"]
    assert join_negative_values(parser, untouched) == untouched      # a flag takes no value; after '--'
    args = parser.parse_args(join_negative_values(parser, ["divergence", "s.toml", "--perturbation", "-1e-12"]))
    assert args.perturbation == -1e-12
    args = parser.parse_args(join_negative_values(parser, ["ensemble", "s.toml", "--perturbation", "-5e-13"]))
    assert args.perturbation == -5e-13


def test_a_negative_perturbation_is_accepted_and_a_negative_step_meets_our_own_message(tmp_path, capsys):
    """``--perturbation -1e-12`` (a twin or members below the velocity: allowed, 0 < |p| < 1e-3)
    gets past the parser to the command's checks; ``static --step -1e-3`` gets our message."""
    scene = str(ROOT / "demos" / "scenes" / "y90.toml")
    assert main(["ensemble", scene, "--perturbation", "-1e-12", "-n", "1", "--out", str(tmp_path / "e")]) == 2
    err = capsys.readouterr().err
    assert "expected one argument" not in err and err.strip() == \
        "fabric-fenicsx ensemble: --members must be at least 2, got 1"          # only the member count refused
    assert main(["divergence", scene, "--perturbation", "-1e-2", "--out", str(tmp_path / "d")]) == 2
    assert "--perturbation must be a small relative change, 0 < |p| < 1e-3, got -0.01" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exc:
        main(["static", "--scenario", "equibiaxial", "--step", "-1e-3", "--out", str(tmp_path / "s")])
    err = capsys.readouterr().err
    assert exc.value.code == 2 and "expected one argument" not in err
    assert "argument --step: step must be a finite number in (0, 0.15], got '-1e-3'" in err
