"""Benchmark of the internal-force assembly per element choice (prints numbers; not a test).

On the mesh of a scene (default: demos/scenes/y90.toml, its graded mesh; ``--set`` changes it)
it times ``Membrane.internal_force`` for

* full: the yarn term with 2 x 2 Gauss points (``mesh.element = "full"``);
* reduced: the yarn term with one point, without hourglass control (unstable alone);
* reduced + hourglass: one point and ``HourglassControl`` following a material (the default
  element), whose forces are assembled per cell in numpy;

with random displacements, integrities and tensions, and prints milliseconds per assembly
and the ratios, all measured in this one process (one rank).

    .venv/bin/python benchmarks/bench_hourglass.py [--scene demos/scenes/y90.toml] [--set KEY=VALUE ...]
        [--repeat 200]
"""

import argparse
import time
from pathlib import Path

import numpy as np
from mpi4py import MPI

from fabric_fenicsx.fem.membrane import Membrane
from fabric_fenicsx.fem.terms import HourglassControl
from fabric_fenicsx.fem.yarn_stress import straight_yarn_modulus
from fabric_fenicsx.impact.scene import load_scene
from fabric_fenicsx.impact.setup import build_fabric, build_mesh
from fabric_fenicsx.material.contract import DamageState

ROOT = Path(__file__).resolve().parents[1]


def time_assembly(m: Membrane, repeat: int) -> float:
    """Milliseconds per internal_force, the best of three batches of ``repeat``."""
    m.internal_force()                                  # forms compiled, buffers made
    best = np.inf
    for _ in range(3):
        t = time.perf_counter()
        for _ in range(repeat):
            m.internal_force()
        best = min(best, (time.perf_counter() - t) / repeat)
    return 1e3 * best


def membrane(msh, angle: float, q: int, rng, hourglass: float | None = None, modulus: float = 0.0) -> Membrane:
    m = Membrane(msh, angle=angle, quadrature_degree=q)
    if hourglass is not None:
        hg = m.add_term(HourglassControl(hourglass, modulus))
        n = m.n_points
        state = DamageState(rng.uniform(0, 1, n), rng.uniform(0, 1, n))
        tension = rng.uniform(0, 0.05 * modulus, (2, n))
        hg.follow(lambda: state, lambda: tension)
    m.set_displacement(rng.normal(scale=1e-4, size=m.n_owned_dofs))
    m.set_stress(rng.uniform(0, 1e4, m.n_points), rng.uniform(0, 1e4, m.n_points))
    return m


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default=str(ROOT / "demos" / "scenes" / "y90.toml"))
    parser.add_argument("--set", dest="overrides", action="append", default=[])
    parser.add_argument("--repeat", type=int, default=200)
    args = parser.parse_args()
    scene = load_scene(args.scene, args.overrides)
    msh, _ = build_mesh(scene, MPI.COMM_WORLD)
    angle = np.radians(scene.material.angle)
    modulus = straight_yarn_modulus(build_fabric(scene))
    rng = np.random.default_rng(0)
    cases = {"full (2 x 2 points)": membrane(msh, angle, 2, rng),
             "reduced, no control": membrane(msh, angle, 1, rng),
             "reduced + hourglass": membrane(msh, angle, 1, rng, scene.membrane.hourglass, modulus)}
    n_cells = cases["full (2 x 2 points)"].n_cells
    print(f"{args.scene} {' '.join(args.overrides)}: {n_cells} cells, {args.repeat} assemblies x 3")
    times = {name: time_assembly(m, args.repeat) for name, m in cases.items()}
    for name, ms in times.items():
        print(f"  {name:22s} {ms:7.3f} ms per internal_force")
    hg = times["reduced + hourglass"] - times["reduced, no control"]
    print(f"  hourglass control      {hg:7.3f} ms ({hg / times['reduced, no control']:.2f} x the one-point yarn term)")
    print(f"  reduced + hourglass / full: {times['reduced + hourglass'] / times['full (2 x 2 points)']:.2f}")


if __name__ == "__main__":
    main()
