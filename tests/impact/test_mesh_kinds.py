"""The scene's mesh kinds ``structured`` (a turned patch) and ``file`` (a user's gmsh file):
bad values are refused before any work with a line naming the key, and the kinds build."""

import subprocess
import sys
from pathlib import Path

import pytest

from fabric_fenicsx.fem import mesh as fm
from fabric_fenicsx.impact.scene import SceneError, ignored_keys_warning, load_scene

REPO = Path(__file__).resolve().parents[2]
Y90 = str(REPO / "demos" / "scenes" / "y90.toml")


@pytest.fixture(scope="module")
def fabric_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("mesh") / "fabric.msh"
    fm.build_msh(fm.MeshSpec(h_centre=8e-3, h_edge=16e-3, refine_radius=0.02, grading=0.3, rotation=30.0), path)
    return path


def test_a_file_mesh_needs_a_file_that_is_a_square_of_quadrilaterals(tmp_path, fabric_file):
    with pytest.raises(SceneError, match="needs mesh.file"):
        load_scene(Y90, ["mesh.kind=file"])
    with pytest.raises(SceneError, match="no such file"):
        load_scene(Y90, ["mesh.kind=file", f"mesh.file={tmp_path / 'none.msh'}"])
    with pytest.raises(SceneError, match="must cover the square"):
        load_scene(Y90, ["mesh.kind=file", f"mesh.file={fabric_file}", "mesh.side=0.2"])
    (tmp_path / "junk.msh").write_text("$MeshFormat\nnonsense\n")
    with pytest.raises(SceneError, match="mesh.file"):
        load_scene(Y90, ["mesh.kind=file", f"mesh.file={tmp_path / 'junk.msh'}"])
    scene = load_scene(Y90, ["mesh.kind=file", f"mesh.file={fabric_file}", "mesh.h_centre=0.003"])
    warning = ignored_keys_warning(scene)
    assert "mesh.h_centre" in warning and "ignored" in warning and "mesh.file" in warning


def test_a_structured_patch_that_does_not_fit_is_refused_before_any_work():
    with pytest.raises(SceneError, match="structured patch"):
        load_scene(Y90, ["mesh.kind=structured", "mesh.rotation=45", "mesh.refine_radius=0.1"])
    scene = load_scene(Y90, ["mesh.kind=graded", "mesh.rotation=45"])
    assert "mesh.rotation is ignored" in ignored_keys_warning(scene)


def test_an_impact_on_a_users_file_runs_and_says_so_for_a_bad_file(tmp_path, fabric_file):
    base = [sys.executable, "-m", "fabric_fenicsx.cli", "impact", Y90, "--quiet", "--set", "run.t_end=2e-5",
            "--set", "output.xdmf_interval=0", "--set", "output.png=false", "--set", "mesh.kind=file"]
    ok = subprocess.run([*base, "--set", f"mesh.file={fabric_file}", "--out", str(tmp_path / "run")],
                        capture_output=True, text=True, timeout=600)
    assert ok.returncode == 0, ok.stderr[-2000:]
    bad = subprocess.run([*base, "--set", "mesh.file=nowhere.msh", "--out", str(tmp_path / "bad")],
                         capture_output=True, text=True, timeout=600)
    assert bad.returncode == 2
    assert "mesh.file" in bad.stderr and "Traceback" not in bad.stderr
