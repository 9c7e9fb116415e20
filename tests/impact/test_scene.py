"""Impact scene files (fabric_fenicsx.impact.scene): the Table 3 scenes, overrides, and clear failures
on bad input before any work is done."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

from fabric_fenicsx.impact.scene import (EDGES, FIELDS, SCHEMA, SceneError, build_scene, load_scene,
                                  parse_override)

ROOT = Path(__file__).resolve().parents[2]
SCENES = ROOT / "demos" / "scenes"

# Table 3 (and Sec. 4.4.2 for XY0): clamped edges and material angle of each named scene.
TABLE3 = {
    "y0": ({"bottom", "top"}, 0.0),
    "y90": ({"bottom", "top"}, 90.0),
    "xy0": (set(EDGES), 0.0),
    "xy45": (set(EDGES), 45.0),
}


@pytest.mark.parametrize("name", sorted(TABLE3))
def test_named_scenes_follow_table3(name):
    scene = load_scene(SCENES / f"{name}.toml")
    clamped, angle = TABLE3[name]
    assert set(scene.boundary.clamped) == clamped
    assert scene.material.angle == angle
    assert scene.material.damage is True
    # the thesis's projectile (Sec. 4.1) and friction
    assert scene.projectile.mass == pytest.approx(0.0371)
    assert scene.projectile.length == pytest.approx(0.0093)
    assert scene.projectile.friction == pytest.approx(0.5)
    assert scene.mesh.side == pytest.approx(10.75 * 0.0254)


def test_defaults_fill_every_key():
    scene = build_scene({})
    d = scene.to_dict()
    assert set(d) == set(SCHEMA)
    for section, keys in SCHEMA.items():
        assert set(d[section]) == set(keys)
    assert scene.output.fields == list(FIELDS)


def test_overrides_are_typed_and_win_over_the_file():
    scene = load_scene(SCENES / "y90.toml", ["projectile.velocity=123.69", "material.damage=false",
                                             "projectile.fillet=0.8e-3", "boundary.clamped=[\"left\", \"right\"]",
                                             "mesh.kind=uniform", "projectile.friction=2"])
    assert scene.projectile.velocity == 123.69
    assert scene.material.damage is False
    assert scene.projectile.fillet == pytest.approx(0.8e-3)
    assert scene.boundary.clamped == ["left", "right"]
    assert scene.mesh.kind == "uniform"
    assert isinstance(scene.projectile.friction, float) and scene.projectile.friction == 2.0


def test_parse_override():
    assert parse_override("run.t_end=1e-3") == ("run", "t_end", 1e-3)
    assert parse_override("mesh.kind = graded") == ("mesh", "kind", "graded")
    assert parse_override("material.damage=true") == ("material", "damage", True)
    with pytest.raises(SceneError, match="section.key=value"):
        parse_override("projectile.velocity")
    with pytest.raises(SceneError, match="section.key"):
        parse_override("velocity=3")


@pytest.mark.parametrize("override, message", [
    ("projectile.speed=50", "unknown key projectile.speed.*velocity"),
    ("projectil.velocity=50", r"unknown section \[projectil\].*projectile"),
    ("projectile.velocity=-3", r"projectile.velocity = -3.*\(0, inf\)"),
    ("projectile.velocity=fast", "projectile.velocity = 'fast'.*number"),
    ("material.damage=maybe", "material.damage = 'maybe'.*true or false"),
    ("material.damage=1", "material.damage = 1.*true or false"),
    ("mesh.kind=hex", r"mesh.kind = 'hex'.*\['graded', 'uniform', 'aligned', 'structured', 'file'\]"),
    ("mesh.n=2.5", "mesh.n = 2.5.*integer"),
    ("boundary.clamped=[\"north\"]", "unknown \\['north'\\].*left"),
    ("boundary.clamped=[]", "at least one"),
    ("output.fields=[\"stress\"]", "unknown \\['stress'\\]"),
    ("projectile.fillet=0.01", "projectile.fillet.*min\\(diameter, length\\) / 2"),
    ("run.dt_safety=1.5", r"run.dt_safety = 1.5.*\(0, 1\]"),
    ("mesh.h_centre=0.01", "mesh.h_centre.*must not exceed mesh.h_edge"),
    ("projectile.x=0.13", r"projectile.x = 0.13.*inside the fabric.*mesh.side / 2 - diameter / 2"),
])
def test_bad_values_name_the_field_and_what_is_valid(override, message):
    with pytest.raises(SceneError, match="(?s)" + message):
        load_scene(SCENES / "y90.toml", [override])


def test_bad_files(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[projectile]\nvelocity = 57.3\nvelocity_typo = 1\n")
    with pytest.raises(SceneError, match="unknown key projectile.velocity_typo"):
        load_scene(bad)
    bad.write_text("[projectile\nvelocity = 57.3\n")
    with pytest.raises(SceneError, match="not valid TOML"):
        load_scene(bad)
    bad.write_text("projectile = 3\n")
    with pytest.raises(SceneError, match="must be a table"):
        load_scene(bad)
    with pytest.raises(SceneError, match="not found"):
        load_scene(tmp_path / "missing.toml")
    bad.write_text("[fabric]\nfile = \"no_such_fabric.toml\"\n")
    with pytest.raises(SceneError, match="fabric.file.*no such file"):
        load_scene(bad)


def _cli(*args, cwd=ROOT):
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])))
    return subprocess.run([sys.executable, "-m", "fabric_fenicsx.cli", "impact", *args], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=120)


def test_cli_stops_before_any_work_on_a_bad_key(tmp_path):
    out = tmp_path / "out"
    proc = _cli(str(SCENES / "y90.toml"), "--out", str(out), "--set", "projectile.speed=50")
    assert proc.returncode == 2
    assert "unknown key projectile.speed" in proc.stderr and "velocity" in proc.stderr
    assert not out.exists()


def test_cli_check_prints_the_resolved_scene():
    proc = _cli(str(SCENES / "xy45.toml"), "--check", "--set", "projectile.velocity=83.06")
    assert proc.returncode == 0, proc.stderr
    assert '"velocity": 83.06' in proc.stdout and '"angle": 45.0' in proc.stdout


def test_cli_module_does_not_import_dolfinx():
    code = "import sys, fabric_fenicsx.cli.impact, fabric_fenicsx.impact.scene; print('dolfinx' in sys.modules)"
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT)
    assert proc.stdout.strip() == "False", proc.stderr


@pytest.mark.parametrize("overrides, warned", [
    ([], True),                                                       # unstructured graded mesh
    (["mesh.kind=aligned"], False), (["mesh.kind=uniform"], False),   # Y90: warp along y
    (["mesh.kind=aligned", "material.angle=45"], True),               # XY45 on a mesh along x, y
    (["mesh.kind=aligned", "material.angle=-270"], False),
    (["mesh.element=reduced"], False), (["mesh.element=reduced", "material.angle=30"], False),
])
def test_locking_warning_names_the_fix_where_yarns_cross_the_cell_edges(overrides, warned):
    """The impact command warns for the fully integrated element whenever the mesh's edges do not
    follow both yarn families (tests/fem/test_hourglass.py: it locks there), and only then."""
    from fabric_fenicsx.impact.scene import locking_warning
    scene = load_scene(SCENES / "y90.toml", ["mesh.element=full", *overrides])
    text = locking_warning(scene)
    assert bool(text) is warned, text
    if warned:
        assert "mesh.element = 'reduced'" in text and "locks" in text


def test_cli_warns_for_a_locking_prone_scene_before_any_work():
    proc = _cli(str(SCENES / "y90.toml"), "--check", "--set", "mesh.element=full", "--set", "mesh.kind=graded")
    assert proc.returncode == 0, proc.stderr
    assert "warning: mesh.element = 'full' on the unstructured graded mesh" in proc.stderr
    quiet = _cli(str(SCENES / "y90.toml"), "--check", "--set", "mesh.element=reduced")
    assert "warning" not in quiet.stderr, quiet.stderr


def test_aligned_meshes_are_checked_like_graded_ones():
    with pytest.raises(SceneError, match=r"mesh.h_centre = 0.01: must not exceed mesh.h_edge = 0.008"):
        build_scene({"mesh": {"kind": "aligned", "h_centre": 0.01}})
    with pytest.raises(SceneError, match=r"mesh.element = 'M3D4R': must be one of \['full', 'reduced'\]"):
        build_scene({"mesh": {"element": "M3D4R"}})
    with pytest.raises(SceneError, match=r"mesh.quadrature_degree applies to mesh.element = 'full' only"):
        build_scene({"mesh": {"quadrature_degree": 4}})
    assert build_scene({"mesh": {"element": "full", "quadrature_degree": 4}}).mesh.quadrature_degree == 4
