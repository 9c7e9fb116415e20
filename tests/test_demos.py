"""Every ``demos/demo_*.py`` runs to completion as a script, serially, from any directory.

Each demo gets an output directory under pytest's tmp_path as argv[1] and must write
something there. A demo that is meant for ``mpirun`` must still run serially; none is skipped.
"""

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DEMOS = sorted((ROOT / "demos").glob("demo_*.py"))


def test_there_are_demos():
    assert DEMOS, f"no demos/demo_*.py under {ROOT}"


@pytest.mark.parametrize("demo", DEMOS, ids=[d.stem for d in DEMOS])
def test_demo_runs(demo, tmp_path):
    out = tmp_path / "out"
    env = dict(os.environ, MPLBACKEND="Agg", PYVISTA_OFF_SCREEN="true",
               PYTHONPATH=os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])))
    # cwd = tmp_path: a demo must not depend on being started from its own folder.
    proc = subprocess.run([sys.executable, str(demo), str(out)], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, (
        f"{demo.name} exited with {proc.returncode}\n--- stdout\n{proc.stdout[-3000:]}"
        f"\n--- stderr\n{proc.stderr[-3000:]}")
    written = [p for p in out.rglob("*") if p.is_file()] if out.exists() else []
    assert written, f"{demo.name} wrote nothing into its output directory {out}"
    if demo.stem in CHECKS:
        CHECKS[demo.stem](out)


def _csv(path):
    import csv
    with open(path) as f:
        return list(csv.DictReader(f))


def check_weak_form(out):
    """Both shear terms store energy, shorten the time step and keep the balance within 1 %."""
    rows = {r["term"]: r for r in _csv(out / "weak_form_demo.csv")}
    assert set(rows) == {"none", "IsotropicShear", "TrellisShear"}
    assert float(rows["none"]["term_energy_J"]) == 0.0
    for name in ("IsotropicShear", "TrellisShear"):
        assert float(rows[name]["term_energy_J"]) > 0.0
        assert float(rows[name]["dt"]) < float(rows["none"]["dt"])
        assert float(rows[name]["velocity_at_end"]) < float(rows["none"]["velocity_at_end"])
    assert all(float(r["energy_error"]) < 0.01 for r in rows.values())


def check_explicit_loop(out):
    """The hand-written loop slows the projectile and keeps the energy balance within 1 %."""
    rows = _csv(out / "explicit_loop.csv")
    assert max(float(r["energy_error"]) for r in rows) < 0.01
    assert 0.0 < float(rows[-1]["projectile_velocity"]) < 0.9 * 20.0


CHECKS = {"demo_weak_form": check_weak_form, "demo_explicit_loop": check_explicit_loop}
