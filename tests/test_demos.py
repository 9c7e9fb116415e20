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
