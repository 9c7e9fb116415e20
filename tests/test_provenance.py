"""Reuse of stored study runs: only with the same settings and the same model code."""

import json
import shutil

from fabric_fenicsx import provenance


def test_a_stored_run_is_reused_only_with_the_same_settings_and_model_version(tmp_path):
    settings = {"projectile": {"velocity": 57.3}, "mesh": {"h_centre": 0.002}}
    path = tmp_path / "summary.json"
    path.write_text(json.dumps({"settings": settings, **provenance.code_fingerprint(), "v": 1.0}))
    assert provenance.load_if_same(path, settings)["v"] == 1.0
    assert provenance.load_if_same(path, {**settings, "mesh": {"h_centre": 0.001}}) is None
    path.write_text(json.dumps({"settings": settings, "model_version": "0123456789ab"}))
    assert provenance.load_if_same(path, settings) is None         # made by other code
    path.write_text("{not json")
    assert provenance.load_if_same(path, settings) is None
    assert provenance.load_if_same(tmp_path / "absent.json", settings) is None


def test_the_model_version_follows_the_physics_modules_only(tmp_path, monkeypatch):
    copy = tmp_path / "pkg"
    shutil.copytree(provenance.PACKAGE, copy, ignore=shutil.ignore_patterns("__pycache__"))
    monkeypatch.setattr(provenance, "PACKAGE", copy)

    def version():
        provenance.model_version.cache_clear()
        return provenance.model_version()

    try:
        base = version()
        (copy / "studies" / "convergence.py").write_text("# a report writer edited\n")
        assert version() == base
        source = (copy / "impact" / "simulation.py").read_text()
        (copy / "impact" / "simulation.py").write_text(source.replace('"""', '"""Prose edited. ', 1) + "\n# a comment\n")
        assert version() == base                            # docstrings and comments are prose
        with open(copy / "fem" / "membrane.py", "a") as f:
            f.write("\n_A_PHYSICS_MODULE_EDITED = 1\n")
        assert version() != base
    finally:
        provenance.model_version.cache_clear()
