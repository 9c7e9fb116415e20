"""Pictures of the deformed fabric (fabric_fenicsx.impact.pictures): snapshots.png and impact.gif
are written, are not blank and show the fabric changing, serially and on 2 ranks."""
import shutil
import subprocess
import sys

import numpy as np
import pytest
from PIL import Image

from fabric_fenicsx.impact.pictures import _scale_bar_length
from conftest import ROOT, mpi_env

SETTINGS = ("mesh.kind=uniform", "mesh.n=16", "mesh.side=0.08", "projectile.diameter=0.02",
            "projectile.mass=0.005", "projectile.velocity=200", 'boundary.clamped=["left","right","bottom","top"]',
            "run.t_end=3e-4", "output.xdmf_interval=0", "output.progress_interval=0", "output.animation=true",
            "output.animation_interval=2e-5")
"""The tiny fabric clamped all round, perforated at 200 m/s in about 80 us (damage, a hole)."""


def _command(out):
    return [sys.executable, "-m", "fabric_fenicsx.cli", "impact", "demos/scenes/y90.toml", "--out", str(out),
            "--quiet", *[a for o in SETTINGS for a in ("--set", o)]]


def _not_blank(path, panels=1):
    img = np.asarray(Image.open(path).convert("RGB"), float)
    coloured = np.abs(img - 255).sum(axis=2) > 30
    assert coloured.mean() > 0.08 * panels / 3, path         # the fabric covers part of the picture
    assert len(np.unique(img.reshape(-1, 3).round(), axis=0)) > 200, path   # shaded, not flat
    return img


@pytest.mark.parametrize("ranks", [1, 2])
def test_snapshots_and_animation_are_written_and_show_the_fabric(tmp_path, ranks):
    if ranks == 2 and shutil.which("mpirun") is None:
        pytest.skip("needs mpirun")
    prefix = ["mpirun", "-n", "2", "--oversubscribe"] if ranks == 2 else []
    proc = subprocess.run(prefix + _command(tmp_path / "run"), cwd=ROOT, env=mpi_env(), capture_output=True,
                          text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    _not_blank(tmp_path / "run" / "snapshots.png", panels=3)
    gif = Image.open(tmp_path / "run" / "impact.gif")
    assert gif.n_frames >= 3                                  # 0, 20, 40, 60 us before the perforation
    frames = []
    for i in (0, gif.n_frames - 1):
        gif.seek(i)
        frames.append(np.asarray(gif.convert("RGB"), float))
    assert np.abs(frames[0] - frames[1]).mean() > 1.0         # the fabric moved and tore


def test_the_scale_bar_is_a_round_length_near_a_fifth_of_the_width():
    assert _scale_bar_length(0.1) == 0.02
    assert _scale_bar_length(0.27) == 0.05
    assert _scale_bar_length(0.004) == pytest.approx(0.001)
