"""The size of an impact run estimated from its scene alone, before gmsh or DOLFINx run: cells,
memory, time steps and wall time, and the refusal of a scene beyond ``run.max_cells`` or the
machine's free memory, with the largest setting that fits.

- **Cells**: ``uniform``: n^2. ``aligned``: the product of the node counts along x and y, each
  the integral of dx / h(x) of the graded spacing (h_centre within refine_radius of the impact
  point, growing by ``grading`` per unit distance up to h_edge). ``graded``: the integral of
  dA / h(r)^2 over the square (the gmsh size field), times :data:`GRADED_CELLS` (gmsh's
  recombined quadrilaterals are a little smaller than h).
- **Smallest cell** (``area_over_diagonal``, what the time step uses): h / sqrt(2) for the
  structured meshes, :data:`GRADED_L_MIN` x h_centre for the unstructured one.
- **Memory**: :data:`BASE_BYTES` + :data:`CELL_BYTES` per cell.
- **Steps**: run.t_end over the stable step (:func:`fabric_fenicsx.fem.timestep.stable_dt`) of
  the straight intact yarns (the stiffest state; crimped yarns allow longer steps early on);
  **wall time**: steps x cells x :data:`SECONDS_PER_CELL_STEP`.

The constants were measured here (DOLFINx 0.5.2, one core) on the Y90 scene; they make an
estimate, not a promise: the estimate is within a factor of about two of real runs.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from fabric_fenicsx.fem.polygons import polygon_areas
from fabric_fenicsx.impact.scene import Scene, SceneError

__all__ = ["Estimate", "estimate", "check_size", "free_memory", "BASE_BYTES", "CELL_BYTES",
           "SECONDS_PER_CELL_STEP", "GRADED_CELLS", "GRADED_L_MIN"]

BASE_BYTES = 450e6
"""Memory of a run before its mesh (interpreter, DOLFINx, numba, the surrogate's tiles):
measured peak 388-407 MB on 1588-10891 cells, rounded up."""
CELL_BYTES = 4e3
"""Memory per cell: measured 2.1 kB (peak resident memory from 1588 to 10891 cells), doubled
for gmsh's meshing and the output buffers of a long run."""
SECONDS_PER_CELL_STEP = 2.5e-6
"""Wall time per cell and step on one core: measured 1.2 us (3254 cells) to 2.1 us (1588 cells;
per-step costs that do not scale with the cells weigh more on small meshes), rounded up."""
GRADED_CELLS = 1.18
"""gmsh's quadrilaterals over the integral of dA / h^2: measured 1.18, 1.19 and 1.18 at
h_centre = 4, 1.41 and 0.5 mm (1588, 3254 and 10891 cells)."""
GRADED_L_MIN = 0.35
"""Smallest area-over-diagonal cell size of the graded gmsh mesh over h_centre: measured 0.46,
0.37 and 0.35 at h_centre = 4, 1.41 and 0.5 mm."""


@dataclass(frozen=True)
class Estimate:
    """A run's size from its scene: cells, smallest cell (m), stable step (s), steps, memory
    (bytes) and wall time on one core (s)."""
    cells: float
    L_min: float
    dt: float
    steps: float
    memory: float
    wall: float

    def describe(self) -> str:
        return (f"about {self.cells:,.0f} cells (smallest {self.L_min * 1e3:.3g} mm), "
                f"{self.memory / 1e6:,.0f} MB, {self.steps:,.0f} steps of {self.dt:.3g} s, "
                f"{_duration(self.wall)} on one core")


def _duration(seconds: float) -> str:
    if seconds < 120:
        return f"{seconds:.0f} s"
    if seconds < 7200:
        return f"{seconds / 60:.0f} min"
    if seconds < 2 * 86400:
        return f"{seconds / 3600:.1f} h"
    return f"{seconds / 86400:,.0f} days"


def _spacing(d: np.ndarray, h_centre: float, h_edge: float, radius: float, grading: float) -> np.ndarray:
    """The mesh size (m) at distance d from the impact point."""
    return np.minimum(h_centre + grading * np.maximum(d - radius, 0.0), h_edge)


def _nodes_1d(lo: float, hi: float, c: float, h_centre: float, h_edge: float, radius: float,
              grading: float) -> float:
    """Cells along [lo, hi] of the graded spacing around c: the integral of dx / h, exact."""
    def one_side(length: float) -> float:
        inner = min(length, radius)
        n = inner / h_centre
        rest = length - inner
        if rest > 0:
            ramp = min(rest, (h_edge - h_centre) / grading) if grading > 0 else 0.0
            n += math.log((h_centre + grading * ramp) / h_centre) / grading if ramp > 0 else 0.0
            n += (rest - ramp) / h_edge
        return n
    return one_side(c - lo) + one_side(hi - c)


def _graded_cells(side: float, c: tuple[float, float], h_centre: float, h_edge: float, radius: float,
                  grading: float) -> float:
    """The integral of dA / h(r)^2 over the square, in polar coordinates around the impact
    point: fine in r where h changes, the arc inside the square from 720 angles."""
    half = side / 2
    r_far = math.hypot(half + abs(c[0]), half + abs(c[1]))
    r = np.concatenate((np.linspace(0.0, radius, 200, endpoint=False),
                        radius + np.geomspace(1e-9, r_far - radius + 1e-9, 2000)))
    theta = np.linspace(0.0, 2 * math.pi, 720, endpoint=False)
    x = c[0] + r[:, None] * np.cos(theta)
    y = c[1] + r[:, None] * np.sin(theta)
    inside = ((np.abs(x) <= half) & (np.abs(y) <= half)).mean(axis=1)
    integrand = 2 * math.pi * r * inside / _spacing(r, h_centre, h_edge, radius, grading) ** 2
    return float(np.trapz(integrand, r))


def _file_cells(path: str) -> tuple[float, float]:
    """(cells, L_min) of a user's mesh file: its 2D cells and the smallest area / longest
    diagonal of its quadrilaterals (the stable step's length, ``cell_sizes``), read with gmsh."""
    import gmsh

    gmsh.initialize(readConfigFiles=False)
    gmsh.option.setNumber("General.Terminal", 0)
    try:
        gmsh.merge(str(path))
        tags, coords, _ = gmsh.model.mesh.getNodes()
        _, _, nodes = gmsh.model.mesh.getElements(2)
    except Exception:   # an unreadable file is refused with its reason when the mesh is read
        return 0.0, math.inf
    finally:
        gmsh.finalize()
    if len(nodes) != 1 or len(nodes[0]) % 4:
        return 0.0, math.inf
    x = np.zeros((int(np.max(tags)) + 1, 2))
    x[np.asarray(tags, dtype=np.int64)] = coords.reshape(-1, 3)[:, :2]
    p = x[np.asarray(nodes[0], dtype=np.int64).reshape(-1, 4)]
    area = polygon_areas(p)
    diagonal = np.maximum(np.linalg.norm(p[:, 2] - p[:, 0], axis=1), np.linalg.norm(p[:, 3] - p[:, 1], axis=1))
    return float(p.shape[0]), float(np.min(area / diagonal))


def _straight_modulus(scene: Scene):
    """(straight intact yarn modulus (N/m), fabric) of the scene, without DOLFINx."""
    from fabric_fenicsx.impact.scene import load_fabric
    from fabric_fenicsx.material.fabric import zylon_as

    fabric = load_fabric(scene) if scene.fabric.file else zylon_as(bending=scene.fabric.bending)
    w = (fabric.warp.w, fabric.fill.w)
    k = max(fabric.warp.A0 * w[0] / (fabric.warp.L * 2 * w[1]),
            fabric.fill.A0 * w[1] / (fabric.fill.L * 2 * w[0]))
    return k, fabric


def estimate(scene: Scene) -> Estimate:
    """The size of the run ``scene`` describes (see the module docstring)."""
    from fabric_fenicsx.fem.timestep import damping_coefficient, stable_dt, unit_cell_frequency

    m, p = scene.mesh, scene.projectile
    if m.kind == "uniform":
        cells, L_min = float(m.n) ** 2, m.side / m.n / math.sqrt(2)
    elif m.kind == "aligned":
        args = (m.h_centre, m.h_edge, m.refine_radius, m.grading)
        nx = _nodes_1d(-m.side / 2, m.side / 2, p.x, *args)
        ny = _nodes_1d(-m.side / 2, m.side / 2, p.y, *args)
        cells, L_min = nx * ny, m.h_centre / math.sqrt(2)
    elif m.kind == "file":
        cells, L_min = _file_cells(m.file)
    else:   # graded, and structured: its patch's squares are within the estimate's factor of two
        cells = GRADED_CELLS * _graded_cells(m.side, (p.x, p.y), m.h_centre, m.h_edge, m.refine_radius,
                                             m.grading)
        L_min = GRADED_L_MIN * m.h_centre
    k, fabric = _straight_modulus(scene)
    modulus = k * (1.0 + (scene.membrane.hourglass if m.element == "reduced" else 0.0)) \
        + scene.membrane.shear_modulus
    beta = damping_coefficient(scene.run.damping, unit_cell_frequency(fabric, k))
    dt = stable_dt(modulus, fabric.areal_density, L_min, beta, scene.run.dt_safety)
    steps = scene.run.t_end / dt
    if scene.run.max_steps:
        steps = min(steps, scene.run.max_steps)
    return Estimate(cells, L_min, dt, steps, BASE_BYTES + CELL_BYTES * cells,
                    steps * cells * SECONDS_PER_CELL_STEP)


def free_memory() -> float | None:
    """The memory available to a new process (bytes, MemAvailable of /proc/meminfo, or the
    cgroup's limit less its use where that is lower); None where neither can be read."""
    found = []
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    found.append(float(line.split()[1]) * 1024)
    except OSError:
        pass
    try:
        with open("/sys/fs/cgroup/memory.max") as f:
            limit = f.read().strip()
        with open("/sys/fs/cgroup/memory.current") as f:
            used = float(f.read().strip())
        if limit != "max":
            found.append(float(limit) - used)
    except (OSError, ValueError):
        pass
    return min(found) if found else None


def _fits(scene: Scene, max_cells: float, memory: float | None) -> bool:
    e = estimate(scene)
    return e.cells <= max_cells and (memory is None or e.memory <= memory)


def _largest_fitting(scene: Scene, max_cells: float, memory: float | None) -> str:
    """The finest mesh setting of the scene that fits, as a ``--set`` hint."""
    def with_value(key: str, value) -> Scene:
        data = scene.to_dict()
        data["mesh"][key] = value
        return Scene(data, scene.source, scene.description)

    if scene.mesh.kind == "file":
        return "coarsen the mesh of mesh.file, free memory or raise run.max_cells"
    if scene.mesh.kind == "uniform":
        lo, hi = 1, scene.mesh.n                  # lo fits, hi does not
        if not _fits(with_value("n", lo), max_cells, memory):
            return "no mesh fits: free memory or raise run.max_cells"
        while hi - lo > 1:
            mid = (lo + hi) // 2
            lo, hi = (mid, hi) if _fits(with_value("n", mid), max_cells, memory) else (lo, mid)
        return f"--set mesh.n={lo}"
    lo, hi = scene.mesh.h_centre, scene.mesh.h_edge    # hi fits unless nothing does, lo does not
    if not _fits(with_value("h_centre", hi), max_cells, memory):
        return "no h_centre fits at this mesh.h_edge: raise mesh.h_edge, free memory or raise run.max_cells"
    for _ in range(60):
        mid = math.sqrt(lo * hi)
        lo, hi = (lo, mid) if _fits(with_value("h_centre", mid), max_cells, memory) else (mid, hi)
        if hi / lo < 1.01:
            break
    return f"--set mesh.h_centre={float(f'{hi * 1.005:.3g}'):g}"


def check_size(scene: Scene, memory: float | None = -1.0) -> Estimate:
    """The scene's :class:`Estimate`, or a :class:`SceneError` if it has more cells than
    ``run.max_cells`` or needs more memory than ``memory`` (bytes; default: what the machine has
    free, :func:`free_memory`; None: no memory limit), naming the estimate and the finest
    setting that fits."""
    if memory is not None and memory < 0:
        memory = free_memory()
    e = estimate(scene)
    max_cells = scene.run.max_cells
    over = []
    if e.cells > max_cells:
        over.append(f"more cells than run.max_cells = {max_cells:,}")
    if memory is not None and e.memory > memory:
        over.append(f"more memory than the {memory / 1e6:,.0f} MB free")
    if over:
        raise SceneError(f"the scene is too large to run here: {e.describe()}: "
                         f"{' and '.join(over)}; the finest mesh that fits: "
                         f"{_largest_fitting(scene, max_cells, memory)}")
    return e
