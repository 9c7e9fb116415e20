"""Reliability of impact and static runs (docs/reliability.md): bad input stops before any work, on every rank, with one message
saying what is valid; an unwritable surrogate cache does not stop a run; a table tile copied over
another is rebuilt; errors in a step name the component that failed; a static step that would
take days is refused.

The command-line cases run in a fresh process under the probe of
:mod:`tests.tools.fault_harness` (which tells whether DOLFINx, i.e. the mesh stage, was reached)
on the tiny scene, each with its own surrogate cache.
"""

import contextlib
import errno
import shutil

import numpy as np
import pytest

from fabric_fenicsx.impact.scene import SceneError, load_scene
from fabric_fenicsx.material.fabric import zylon_as
from fabric_fenicsx.surrogate import tiles as tiles_module
from fabric_fenicsx.surrogate.table import Surrogate
from conftest import COARSE
from tests.tools import faults

FABRIC = zylon_as("max")


@pytest.fixture
def ws(tmp_path):
    return faults.Workspace(tmp_path)


def _one_message(run, *needles):
    """The run printed exactly one line naming all ``needles`` and no traceback."""
    lines = [ln for ln in run.messages if all(n in ln for n in needles)]
    assert len(lines) == 1, run.stderr
    assert "Traceback" not in run.stderr, run.stderr


# ----------------------------------------------------------------------------- checked before any work
@pytest.mark.parametrize("label", sorted(faults.BAD_FABRICS))
def test_a_bad_fabric_file_fails_check_with_what_is_valid(ws, label):
    (ws.base / "bad.fabric.toml").write_text(faults.BAD_FABRICS[label])
    scene = ws.scene_with("bad.toml", '[fabric]\nfile = "bad.fabric.toml"\n')
    with pytest.raises(SceneError, match="fabric.file"):
        load_scene(scene)
    run = faults.run_cli(["impact", scene, "--check"], env=faults.cli_env(ws.cache))
    assert run.returncode == 2, run.stderr
    _one_message(run, "fabric.file")
    expected = {"negative A0": "A0", "missing key (area)": "area", "unknown damage law": "exponential"}[label]
    assert expected in run.first_line
    assert run.dolfinx is False


def test_a_missing_fabric_file_is_caught_without_a_scene_file(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SceneError, match="fabric.file.*no such file"):
        load_scene(None, ["fabric.file=no-such-fabric.toml"])
    # relative to the working folder when there is no scene file
    (tmp_path / "good.toml").write_text(faults.GOOD_FABRIC)
    assert load_scene(None, ["fabric.file=good.toml"]).fabric.file == str(tmp_path / "good.toml")


@contextlib.contextmanager
def _a_file(path):
    path.write_text("a file, not a folder\n")
    yield "a file"


@pytest.mark.parametrize("kind", ["existing file", "read-only folder"])
def test_an_unusable_out_stops_before_the_mesh(ws, kind):
    target = ws.path("target")
    with faults.read_only_dir(target) if kind == "read-only folder" else _a_file(target) as how:
        if how is None:
            pytest.skip("no read-only folder can be made here (mount refused)")
        run = faults.run_cli(["impact", ws.scene, "--out", target], env=faults.cli_env(ws.cache))
    assert run.returncode == 2, run.stderr
    _one_message(run, "--out", str(target))
    assert run.dolfinx is False and run.tiles is False


def test_a_scene_path_that_is_a_folder_or_not_utf8_is_a_scene_error(ws):
    with pytest.raises(SceneError, match="folder"):
        load_scene(ws.base)
    latin1 = ws.path("latin1.toml")
    latin1.write_bytes("description = \"sc\xe8ne\"\n".encode("latin-1"))
    with pytest.raises(SceneError, match="UTF-8"):
        load_scene(latin1)
    for path in (ws.base, latin1):
        run = faults.run_cli(["impact", path, "--check"], env=faults.cli_env(ws.cache))
        assert run.returncode == 2, run.stderr
        _one_message(run, str(path))


# ----------------------------------------------------------------------------- MPI
def test_a_bad_out_on_two_ranks_ends_both_with_one_message(ws):
    target = ws.path("existing-file")
    target.write_text("a file\n")
    run = faults.run_cli(["impact", ws.scene, "--out", target], env=faults.cli_env(ws.cache), ranks=2,
                         timeout=300)
    assert run.returncode == 2, f"exit {run.returncode} after {run.seconds:.0f} s: {run.stderr[-2000:]}"
    _one_message(run, "--out")
    assert run.dolfinx is False


def test_an_error_on_one_rank_mid_run_ends_every_rank(ws):
    run = faults.run_cli(["impact", ws.scene, "--out", ws.path("out"), "--quiet"],
                         env=faults.cli_env(ws.cache), ranks=2, timeout=300, inject=faults.INJECT_RANK1)
    assert run.returncode is not None, f"hang: {run.stderr[-2000:]}"
    assert run.returncode != 0
    _one_message(run, "injected by the reliability study", "membrane", "rank 1")


# ----------------------------------------------------------------------------- unwritable cache
def test_a_cache_that_is_a_file_does_not_stop_the_run(ws):
    cache_file = ws.path("cache-file")
    cache_file.write_text("a file\n")
    out = ws.path("out")
    run = faults.run_cli(["impact", ws.scene, "--out", out, "--quiet"], env=faults.cli_env(cache_file))
    assert run.returncode == 0, run.stderr
    assert (out / "summary.json").exists()
    _one_message(run, "surrogate cache", "memory")


def test_a_filled_read_only_cache_that_lacks_a_tile_goes_on_in_memory(ws):
    src = ws.cache_copy("src")
    ws.tiles(src)[-1].unlink()
    ro, out = ws.path("ro"), ws.path("out")
    with faults.read_only_dir(ro, fill=src) as how:
        if how is None:
            pytest.skip("no read-only folder can be made here (mount refused)")
        run = faults.run_cli(["impact", ws.scene, "--out", out, "--quiet"], env=faults.cli_env(ro))
    assert run.returncode == 0, run.stderr
    assert (out / "summary.json").exists()
    _one_message(run, "surrogate cache", "memory")


def test_a_tile_that_cannot_be_saved_is_kept_in_memory_and_said_once(tmp_path, monkeypatch):
    def full_disk(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(tiles_module.np, "savez", full_disk)
    # the warning, not the reporter an in-process `fabric-fenicsx impact` run earlier in the
    # session (tests/studies/test_waves.py) left set with report_cache_problems
    monkeypatch.setattr(tiles_module, "_REPORT", None)
    sur = Surrogate(FABRIC, cache_dir=tmp_path, **COARSE)
    with pytest.warns(UserWarning, match="memory") as record:
        P = sur.evaluate(np.array([0.0, 0.03]), np.array([0.0, 0.03]), 1.0, 1.0)[0]
    assert len([w for w in record if "memory" in str(w.message)]) == 1
    assert np.all(np.isfinite(P)) and sur.built["intact"].sum() >= 2
    assert not list(tmp_path.rglob("*.npz"))


# ----------------------------------------------------------------------------- swapped tile
def test_a_tile_copied_over_another_is_rebuilt(tmp_path):
    first = Surrogate(FABRIC, cache_dir=tmp_path, **COARSE)
    E = np.array([0.0, 0.03])
    P_ref = first.evaluate(E, E, 1.0, 1.0)[0]
    files = sorted(first.cache_dir.glob("intact_*.npz"))
    assert len(files) >= 2
    shutil.copyfile(files[0], files[-1])
    second = Surrogate(FABRIC, cache_dir=tmp_path, **COARSE)
    np.testing.assert_array_equal(second.evaluate(E, E, 1.0, 1.0)[0], P_ref)
    assert second.solves > 0


# ----------------------------------------------------------------------------- errors name the component
@pytest.mark.parametrize("error, component, fixes", [
    ("SurrogateError", "table tile", False),
    ("UnitCellError", "unit cell", False),
    ("FloatingPointError", "membrane", True),
])
def test_a_step_error_names_the_component_and_only_fixes_that_help(tmp_path, monkeypatch, error, component,
                                                                    fixes):
    from fabric_fenicsx.impact.scene import build_scene
    from fabric_fenicsx.impact.simulation import ImpactError, ImpactSimulation
    from fabric_fenicsx.material.unitcell import UnitCellError
    from fabric_fenicsx.surrogate.table import SurrogateError
    import tomllib

    monkeypatch.setenv("FABRIC_FENICSX_CACHE", str(tmp_path / "cache"))
    cls = {"SurrogateError": SurrogateError, "UnitCellError": UnitCellError,
           "FloatingPointError": FloatingPointError}[error]
    sim = ImpactSimulation(build_scene(tomllib.loads(faults.TINY_SCENE)), tmp_path / "out", verbose=False)

    def failing_step(dt, f_ext):
        raise cls("made to fail by the test")

    sim.cd.step = failing_step
    with pytest.raises(ImpactError) as info:
        sim.run()
    sim.output.close()
    message = str(info.value)
    assert component in message
    assert ("run.dt_safety" in message) is fixes


# ----------------------------------------------------------------------------- static step
def test_static_refuses_a_step_that_would_take_days(tmp_path):
    run = faults.run_cli(["static", "--scenario", "uniaxial-strain", "--step", "1e-9", "--out", tmp_path],
                         timeout=60)
    assert run.returncode == 2, f"exit {run.returncode} after {run.seconds:.0f} s"
    _one_message(run, "--step")
    assert "steps" in run.first_line and "--max-steps" in run.first_line


def test_static_estimate_bounds_the_steps_and_progress_shows_it(capsys, monkeypatch):
    from fabric_fenicsx.studies import static

    estimate = static.estimate_steps("uniaxial-strain", None, 0.001)
    monkeypatch.setattr(static, "PROGRESS_INTERVAL", 0.0)
    result = static.run_scenario("uniaxial-strain", step=0.001, progress=True)
    assert len(result) <= estimate <= 1.6 * len(result)
    assert f"of at most {estimate}" in capsys.readouterr().err
    with pytest.raises(ValueError, match="--step|step"):
        static.run_scenario("uniaxial-strain", step=1e-9)
