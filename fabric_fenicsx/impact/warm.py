"""Fill numba's on-disk cache with the compiled kernels of an impact run, ahead of the first run.

numba compiles each kernel on its first call and keeps the machine code in ``__pycache__``
beside the source (``cache=True``); a new clone has none, so its first impact run spends some
20 s compiling before its first steps. ``make setup`` runs this module in the background while
pip installs the packages the run does not need for compiling (it only needs numba, numpy and
DOLFINx): a short run of the demo's scene (demos/scenes/y90.toml, the demo's coarse mesh, a
few steps) calls every kernel of a step with the argument types of a real run, so numba
compiles exactly the signatures a run uses and writes them to its cache. The run's mesh, tiles
and output go to a temporary folder, removed at the end; only numba's (and FFCx's) caches stay.

    python -m fabric_fenicsx.impact.warm [--steps N] [--scene FILE]

Prints how long it took and how many functions numba compiled. Exit code 0 also when the run
fails (a warm-up is an optimisation: the run compiles what is missing), with the error printed.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
import traceback
from pathlib import Path

SCENE = Path(__file__).resolve().parents[2] / "demos" / "scenes" / "y90.toml"
SETTINGS = ("projectile.velocity=57.3", "mesh.h_centre=0.004", "output.png=false",
            "output.progress_interval=0")
STEPS = 20
"""Steps of the warm-up run: the tension field's force-free strain search is first called
near step 13 (the first compressed yarns); the other kernels at the first step."""


def warm(scene: Path | None = SCENE, steps: int = STEPS) -> int:
    """Run ``steps`` steps of ``scene`` (None or a missing file: the scene defaults) in a
    temporary folder; returns the number of functions numba compiled."""
    from numba.core import event

    compiled = []

    class Listener(event.Listener):
        def on_start(self, ev):
            pass

        def on_end(self, ev):
            compiled.append(ev.data["dispatcher"])

    with tempfile.TemporaryDirectory(prefix="fabric-fenicsx-warm-") as tmp:
        # the run's own caches (tiles, meshes) stay in the temporary folder
        os.environ["FABRIC_FENICSX_CACHE"] = str(Path(tmp) / "tiles")
        os.environ["FABRIC_FENICSX_MESH_DIR"] = str(Path(tmp) / "meshes")
        from fabric_fenicsx.impact.scene import load_scene
        from fabric_fenicsx.impact.simulation import run_impact

        path = scene if scene is not None and Path(scene).is_file() else None
        settings = [*SETTINGS, f"run.max_steps={steps}"]
        event.register("numba:compile", Listener())
        run_impact(load_scene(path, settings), Path(tmp) / "out", verbose=False)
        _warm_removal()
    return len(compiled)


def _warm_removal() -> None:
    """The kernel a short run does not reach: the attached fabric's closure after cells are
    removed, called with the argument types of a run (cell nodes int32, a boolean node mask)."""
    import numpy as np

    from fabric_fenicsx.impact.removal import _attach

    _attach(np.zeros((1, 4), np.int32), np.zeros(1, bool))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=STEPS)
    parser.add_argument("--scene", default=str(SCENE))
    args = parser.parse_args(argv)
    t0 = time.perf_counter()
    try:
        n = warm(Path(args.scene), args.steps)
    except Exception:  # noqa: BLE001 - an optimisation only: say why and go on
        traceback.print_exc()
        print(f"numba warm-up: failed after {time.perf_counter() - t0:.1f} s; the first run "
              f"compiles its kernels itself", file=sys.stderr)
        return 0
    print(f"numba warm-up: {n} functions compiled into numba's cache in "
          f"{time.perf_counter() - t0:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
