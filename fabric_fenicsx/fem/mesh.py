"""Membrane meshes of the square fabric target (thesis Sec. 4.1, Fig. 4-1).

The fabric is a square of side 10.75 in = 273.05 mm, centred at the origin of a flat
2D reference mesh (x = warp direction for material angle 0, see Table 3). It is
meshed with quadrilaterals, fine (``h_centre``) within ``refine_radius`` of the
impact point and graded linearly to ``h_edge`` (gmsh Distance + Threshold size
field). The four edges carry facet tags ``LEFT, RIGHT, BOTTOM, TOP`` so the
boundary conditions Y0 / XY45 / Y90 of Table 3 can clamp any pair of them.

Meshes are built on rank 0, cached as ``<cache_dir>/<spec.name>`` with a JSON
sidecar (spec, size, sha256) so a half-written or stale file is never used, and
distributed over the communicator with ``dolfinx.io.gmshio.model_to_mesh``.

Two DOLFINx 0.5.2 / Debian gmsh 4.8.4 facts shape this module:

* ``gmshio.read_from_msh`` of the Debian 0.5.2 package is broken (it returns an
  undefined name on rank 0 and passes an undefined ``partitioner`` elsewhere), so
  :func:`_read_msh` does the merge + ``model_to_mesh`` itself.
* gmsh's "Frontal-Delaunay for Quads" (Mesh.Algorithm 8) segfaults in this build,
  even on a unit square, and "Packing of parallelograms" (9) gives a different
  mesh on every run. Frontal-Delaunay (6) with blossom recombination is used: it
  is deterministic and its shortest edge is about 0.54 h_centre. The explicit
  time step must use :func:`min_cell_size`, not ``h_centre``.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import os
import time
from pathlib import Path
from typing import Iterable

import numpy as np
from mpi4py import MPI

import dolfinx.fem
import dolfinx.mesh

from fabric_fenicsx.fem.structured_patch import build_patch_geometry, largest_patch_radius, patch_half_side

SIDE_DEFAULT = 0.27305  # m, 10.75 in (thesis Sec. 4.1)

FABRIC = 1  # cell (surface) tag
LEFT, RIGHT, BOTTOM, TOP = 1, 2, 3, 4  # facet tags (the same in .structured_patch): x = -side/2, x = +side/2, y = -side/2, y = +side/2
EDGE_NAMES = {LEFT: "left", RIGHT: "right", BOTTOM: "bottom", TOP: "top"}

# Bump when build_msh changes what it writes: cached files of other versions are rebuilt.
MESHER_VERSION = 1

# (Mesh.Algorithm, Mesh.RecombinationAlgorithm) tried in order; see module docstring.
_ALGORITHMS = ((6, 1), (6, 3), (5, 1))
_MIN_SCALED_JACOBIAN = 0.3  # reject a recombined mesh with a corner angle below ~17 degrees

# DOLFINx quadrilateral vertices are in tensor-product order (0,0),(1,0),(0,1),(1,1);
# this permutation walks them around the perimeter.
_QUAD_CYCLE = np.array([0, 1, 3, 2])


def _mm(x: float) -> str:
    """Millimetres with 2 to 4 decimals, file-name safe (no exponent, no '+')."""
    s = f"{x * 1e3 + 0.0:.4f}"  # + 0.0 turns -0.0 into 0.0
    whole, frac = s.split(".")
    return f"{whole}.{frac.rstrip('0').ljust(2, '0')}"


@dataclasses.dataclass(frozen=True)
class MeshSpec:
    """Parameters of a graded square fabric mesh, SI units (m).

    side: edge length of the square, centred at the origin.
    h_centre: element size within ``refine_radius`` of ``centre``.
    h_edge: element size far from the centre (reached at distance
        ``refine_radius + (h_edge - h_centre) / grading``).
    refine_radius: radius around ``centre`` kept at ``h_centre``.
    centre: impact point (x, y); an impact 20 mm from the left edge is
        ``(-side/2 + 0.02, 0)``. A mesh node is placed exactly there.
    grading: growth of the element size per unit distance in the transition
        (dimensionless, 0 < grading <= 1).
    rotation: None (default) for unstructured quadrilaterals at the impact point; a number
        (degrees) for a *structured patch*: a square of side ``2 * refine_radius`` centred at
        ``centre``, its rows of squares of side ``h_centre`` turned ``rotation`` degrees from x,
        in unstructured quadrilaterals graded to ``h_edge``
        (:mod:`~fabric_fenicsx.fem.structured_patch`).

    ``h_centre == h_edge`` without a rotation gives a structured (transfinite) grid of squares.
    """

    side: float = SIDE_DEFAULT
    h_centre: float = 1.0e-3
    h_edge: float = 8.0e-3
    refine_radius: float = 0.02
    centre: tuple[float, float] = (0.0, 0.0)
    grading: float = 0.1
    rotation: float | None = None

    def __post_init__(self) -> None:
        for field in ("side", "h_centre", "h_edge", "refine_radius", "grading"):
            object.__setattr__(self, field, _as_float(field, getattr(self, field)))
        try:
            centre = tuple(float(c) for c in self.centre)
        except (TypeError, ValueError):
            raise ValueError(f"MeshSpec.centre = {self.centre!r}: must be two numbers (x, y) in m") from None
        if len(centre) != 2 or not all(math.isfinite(c) for c in centre):
            raise ValueError(f"MeshSpec.centre = {self.centre!r}: must be two finite numbers (x, y) in m")
        object.__setattr__(self, "centre", centre)
        if self.rotation is not None:
            object.__setattr__(self, "rotation", _as_float("rotation", self.rotation))

        for field in ("side", "h_centre", "h_edge", "grading"):
            if not getattr(self, field) > 0.0:
                raise ValueError(f"MeshSpec.{field} = {getattr(self, field)!r}: must be > 0")
        if self.refine_radius < 0.0:
            raise ValueError(f"MeshSpec.refine_radius = {self.refine_radius!r}: must be >= 0")
        if self.grading > 1.0:
            raise ValueError(f"MeshSpec.grading = {self.grading!r}: must be <= 1 (size growth per unit distance)")
        if self.h_centre > self.h_edge:
            raise ValueError(f"MeshSpec.h_centre = {self.h_centre!r}: must not exceed h_edge = {self.h_edge!r}")
        if self.h_edge > self.side / 2:
            raise ValueError(f"MeshSpec.h_edge = {self.h_edge!r}: must be <= side/2 = {self.side / 2!r}")
        margin = self.side / 2 - max(abs(c) for c in centre)
        if margin < self.h_centre:
            raise ValueError(
                f"MeshSpec.centre = {centre!r}: must lie inside the square |x|, |y| < side/2 = {self.side / 2!r}"
                f" and at least h_centre = {self.h_centre!r} from every edge")
        if self.rotation is not None:
            room = largest_patch_radius(self.side, centre, self.rotation, self.h_centre)
            if patch_half_side(self.refine_radius, self.h_centre) > room:
                raise ValueError(
                    f"MeshSpec.refine_radius = {self.refine_radius!r}: the structured patch (half-side "
                    f"{patch_half_side(self.refine_radius, self.h_centre)!r} m, {self.rotation:g} degrees) must keep h_centre from every edge "
                    f"of the square; at most {room!r} m here")

    @property
    def uniform(self) -> bool:
        return self.h_centre == self.h_edge and self.rotation is None

    @property
    def name(self) -> str:
        """File name encoding every parameter, e.g.
        ``fabric_s273.05mm_hc1.00mm_he8.00mm_r20.00mm_g0.10_c0.00_0.00mm.msh``."""
        cx, cy = self.centre
        grading = f"{self.grading + 0.0:.4f}".rstrip("0").ljust(4, "0")
        patch = "" if self.rotation is None else f"_rot{self.rotation + 0.0:.4f}".rstrip("0").rstrip(".")
        return (f"fabric_s{_mm(self.side)}mm_hc{_mm(self.h_centre)}mm_he{_mm(self.h_edge)}mm"
                f"_r{_mm(self.refine_radius)}mm_g{grading}_c{_mm(cx)}_{_mm(cy)}mm{patch}.msh")

    def as_dict(self) -> dict:
        d = dataclasses.asdict(self)
        d["centre"] = list(self.centre)
        if self.rotation is None:   # the unstructured meshes' sidecars stay as they were
            del d["rotation"]
        return d


def _as_float(field: str, value) -> float:
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"MeshSpec.{field} = {value!r}: must be a number (SI units, m)") from None
    if not math.isfinite(x):
        raise ValueError(f"MeshSpec.{field} = {value!r}: must be finite")
    return x


# --------------------------------------------------------------------------- gmsh


def build_msh(spec: MeshSpec, path: str | os.PathLike, verbose: bool = False) -> dict:
    """Mesh the square with gmsh and write ``path`` (MSH 4.1) atomically.

    Serial: call it on one rank (``load_mesh`` does). Physical groups: surface
    ``FABRIC`` "fabric", curves ``LEFT``/``RIGHT``/``BOTTOM``/``TOP``. Returns
    statistics ``{"num_quads", "num_nodes", "seconds", "algorithm",
    "min_scaled_jacobian"}``. Raises RuntimeError if no algorithm yields an
    all-quadrilateral mesh of acceptable quality.

    gmsh is initialised and finalised here (gmsh 4.8 cannot tell whether it is
    already running), so do not call this inside your own gmsh session.
    """
    import gmsh

    path = Path(path)
    t0 = time.perf_counter()
    gmsh.initialize(readConfigFiles=False)
    try:
        gmsh.option.setNumber("General.Terminal", 1 if verbose else 0)
        gmsh.model.add("fabric")
        if spec.uniform and spec.rotation is None:
            (surfaces, edges), algorithm = _geometry_uniform(gmsh, spec), "transfinite"
            gmsh.model.mesh.generate(2)
            quads, x = _quads(gmsh)
            if quads is None:
                raise RuntimeError(f"build_msh: transfinite meshing of {spec.name} left non-quadrilateral cells")
            sj = _min_scaled_jacobian(x[quads])
        else:
            geometry = _geometry_graded if spec.rotation is None else build_patch_geometry
            surfaces, edges = geometry(gmsh, spec)
            sj, algorithm, tried = -1.0, None, []
            for alg, rec in _ALGORITHMS:
                gmsh.model.mesh.clear()
                gmsh.option.setNumber("Mesh.Algorithm", alg)
                gmsh.option.setNumber("Mesh.RecombinationAlgorithm", rec)
                gmsh.model.mesh.generate(2)
                quads, x = _quads(gmsh)
                sj = _min_scaled_jacobian(x[quads]) if quads is not None else -1.0
                tried.append(f"algorithm {alg}/{rec}: "
                             + ("triangles left" if quads is None else f"min scaled Jacobian {sj:.3f}"))
                if sj >= _MIN_SCALED_JACOBIAN:
                    algorithm = f"{alg}/{rec}"
                    break
            if algorithm is None:
                raise RuntimeError(f"build_msh: no all-quad mesh of acceptable quality for {spec.name} "
                                   f"({'; '.join(tried)}); try a larger h_centre or smaller grading")

        gmsh.model.addPhysicalGroup(2, surfaces, FABRIC)
        gmsh.model.setPhysicalName(2, FABRIC, "fabric")
        for tag, curves in edges.items():
            gmsh.model.addPhysicalGroup(1, curves, tag)
            gmsh.model.setPhysicalName(1, tag, EDGE_NAMES[tag])

        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(f".{path.stem}.{os.getpid()}.tmp.msh")  # gmsh picks the format from ".msh"
        gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
        gmsh.write(str(tmp))
        os.replace(tmp, path)
        stats = {"num_quads": int(len(quads)), "num_nodes": int(len(x)), "algorithm": algorithm,
                 "min_scaled_jacobian": float(sj), "seconds": time.perf_counter() - t0}
    finally:
        gmsh.finalize()
    return stats


def _geometry_graded(gmsh, spec: MeshSpec) -> tuple[list[int], dict[int, list[int]]]:
    """Square with an embedded node at the impact point and a Threshold size field."""
    a = spec.side / 2
    g = gmsh.model.geo
    p = [g.addPoint(-a, -a, 0.0), g.addPoint(a, -a, 0.0), g.addPoint(a, a, 0.0), g.addPoint(-a, a, 0.0)]
    bottom, right, top, left = (g.addLine(p[i], p[(i + 1) % 4]) for i in range(4))
    surface = g.addPlaneSurface([g.addCurveLoop([bottom, right, top, left])])
    pc = g.addPoint(spec.centre[0], spec.centre[1], 0.0)
    g.synchronize()
    gmsh.model.mesh.embed(0, [pc], 2, surface)

    field = gmsh.model.mesh.field
    dist = field.add("Distance")
    field.setNumbers(dist, "PointsList", [pc])
    thr = field.add("Threshold")
    field.setNumber(thr, "InField", dist)
    field.setNumber(thr, "SizeMin", spec.h_centre)
    field.setNumber(thr, "SizeMax", spec.h_edge)
    field.setNumber(thr, "DistMin", spec.refine_radius)
    field.setNumber(thr, "DistMax", spec.refine_radius + (spec.h_edge - spec.h_centre) / spec.grading)
    field.setAsBackgroundMesh(thr)
    for option, value in (("Mesh.MeshSizeExtendFromBoundary", 0), ("Mesh.MeshSizeFromPoints", 0),
                          ("Mesh.MeshSizeFromCurvature", 0), ("Mesh.MeshSizeMax", spec.h_edge),
                          ("Mesh.RecombineAll", 1)):
        gmsh.option.setNumber(option, value)
    return [surface], {LEFT: [left], RIGHT: [right], BOTTOM: [bottom], TOP: [top]}


def _geometry_uniform(gmsh, spec: MeshSpec) -> tuple[list[int], dict[int, list[int]]]:
    """Four transfinite rectangles meeting at the impact point: a tensor grid of
    near-square cells of size <= h_edge with a node exactly at ``centre``."""
    a = spec.side / 2
    xs = (-a, spec.centre[0], a)
    ys = (-a, spec.centre[1], a)
    g = gmsh.model.geo
    pt = [[g.addPoint(xs[i], ys[j], 0.0) for j in range(3)] for i in range(3)]
    hor = [[g.addLine(pt[i][j], pt[i + 1][j]) for j in range(3)] for i in range(2)]  # hor[i][j]
    ver = [[g.addLine(pt[i][j], pt[i][j + 1]) for j in range(2)] for i in range(3)]  # ver[i][j]
    surfaces = [g.addPlaneSurface([g.addCurveLoop([hor[i][j], ver[i + 1][j], -hor[i][j + 1], -ver[i][j]])])
                for i in range(2) for j in range(2)]
    g.synchronize()  # before the mesh constraints: a later synchronize would drop them
    for i in range(2):
        n = math.ceil((xs[i + 1] - xs[i]) / spec.h_edge - 1e-9)
        for j in range(3):
            gmsh.model.mesh.setTransfiniteCurve(hor[i][j], n + 1)
    for j in range(2):
        n = math.ceil((ys[j + 1] - ys[j]) / spec.h_edge - 1e-9)
        for i in range(3):
            gmsh.model.mesh.setTransfiniteCurve(ver[i][j], n + 1)
    for s in surfaces:
        gmsh.model.mesh.setTransfiniteSurface(s)
        gmsh.model.mesh.setRecombine(2, s)
    return surfaces, {LEFT: [ver[0][0], ver[0][1]], RIGHT: [ver[2][0], ver[2][1]],
                      BOTTOM: [hor[0][0], hor[1][0]], TOP: [hor[0][2], hor[1][2]]}


def _quads(gmsh):
    """(quads (n, 4) rows of ``x`` in perimeter order, node coordinates x (m, 2)),
    or (None, x) if the mesh holds any 2D element that is not a 4-node quad."""
    tags, coords, _ = gmsh.model.mesh.getNodes()
    tags = np.asarray(tags, dtype=np.int64)
    order = np.argsort(tags)
    x = coords.reshape(-1, 3)[order, :2]
    types, _, nodes = gmsh.model.mesh.getElements(2)
    if len(types) != 1 or types[0] != 3:
        return None, x
    return np.searchsorted(tags[order], np.asarray(nodes[0], dtype=np.int64)).reshape(-1, 4), x


def _min_scaled_jacobian(p: np.ndarray) -> float:
    """Smallest corner sine (scaled Jacobian) of quads ``p`` (n, 4, 2) in perimeter order;
    negative for an inverted or non-convex cell."""
    e_next = np.roll(p, -1, axis=1) - p
    e_prev = np.roll(p, 1, axis=1) - p
    cross = e_next[..., 0] * e_prev[..., 1] - e_next[..., 1] * e_prev[..., 0]
    sj = cross / (np.linalg.norm(e_next, axis=2) * np.linalg.norm(e_prev, axis=2))
    # orientation-independent: a consistently clockwise mesh is as good as a counter-clockwise one
    sj *= np.sign(np.median(sj))
    return float(sj.min())


# --------------------------------------------------------------------------- cache + read


def default_cache_dir() -> Path:
    """``$FABRIC_FENICSX_MESH_DIR`` if set, else the repository's ``meshes/`` folder
    (independent of the working directory), else ``./meshes``."""
    env = os.environ.get("FABRIC_FENICSX_MESH_DIR")
    if env:
        return Path(env)
    repo_meshes = Path(__file__).resolve().parents[2] / "meshes"
    return repo_meshes if repo_meshes.is_dir() else Path("meshes")


def _sidecar(path: Path) -> Path:
    return path.with_name(path.name + ".json")


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def cache_is_valid(spec: MeshSpec, path: str | os.PathLike) -> bool:
    """True if ``path`` and its sidecar exist and the sidecar's spec, mesher
    version, size and sha256 all match (so a truncated or stale file fails)."""
    path = Path(path)
    try:
        meta = json.loads(_sidecar(path).read_text())
        return (meta.get("mesher_version") == MESHER_VERSION and meta.get("spec") == spec.as_dict()
                and meta.get("size") == path.stat().st_size and meta.get("sha256") == _sha256(path))
    except (OSError, ValueError):
        return False


def _build_cached(spec: MeshSpec, path: Path, verbose: bool) -> None:
    """Build ``path`` and then its sidecar, each written to a temporary name and
    renamed into place."""
    t0 = time.perf_counter()
    print(f"fabric_fenicsx.fem.mesh: building {path} ...", flush=True)
    stats = build_msh(spec, path, verbose=verbose)
    meta = {"mesher_version": MESHER_VERSION, "spec": spec.as_dict(), "size": path.stat().st_size,
            "sha256": _sha256(path), "stats": stats}
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp.json")
    tmp.write_text(json.dumps(meta, indent=1))
    os.replace(tmp, _sidecar(path))
    print(f"fabric_fenicsx.fem.mesh: {stats['num_quads']} quadrilaterals, {stats['num_nodes']} nodes "
          f"(algorithm {stats['algorithm']}, min scaled Jacobian {stats['min_scaled_jacobian']:.2f}) "
          f"in {time.perf_counter() - t0:.2f} s", flush=True)


def load_mesh(spec: MeshSpec, comm: MPI.Comm = MPI.COMM_WORLD, cache_dir: str | os.PathLike | None = None,
              verbose: bool = False):
    """Return ``(msh, cell_tags, facet_tags)`` for ``spec``, distributed over ``comm``.

    Rank 0 builds ``<cache_dir>/<spec.name>`` unless a valid cached copy exists
    (see :func:`cache_is_valid`), then reads it and DOLFINx distributes the cells.
    ``cache_dir=None`` means :func:`default_cache_dir`. Collective.
    """
    if not isinstance(spec, MeshSpec):
        raise ValueError(f"load_mesh: spec = {spec!r}: must be a MeshSpec")
    path = Path(cache_dir if cache_dir is not None else default_cache_dir()) / spec.name
    for attempt in range(2):
        error = None
        if comm.rank == 0:
            try:
                if attempt > 0 or not cache_is_valid(spec, path):
                    _build_cached(spec, path, verbose)
            except Exception as e:  # reported on every rank below, not only on rank 0
                error = f"{type(e).__name__}: {e}"
        error = comm.bcast(error, root=0)
        if error is not None:
            raise RuntimeError(f"load_mesh: building {path} failed on rank 0: {error}")
        try:
            return _read_msh(path, comm)
        except _UnreadableMsh as e:
            if attempt > 0:
                raise RuntimeError(f"load_mesh: {path} unreadable even after a rebuild: {e}") from None
    raise AssertionError("unreachable")


class _UnreadableMsh(RuntimeError):
    pass


def open_msh(gmsh, path) -> None:
    """Start gmsh quietly with the mesh file ``path`` merged into a new model (the caller
    finalizes gmsh, also when this raises)."""
    gmsh.initialize(readConfigFiles=False)
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.model.add("fabric_from_file")
    gmsh.merge(str(path))


def _read_msh(path: Path, comm: MPI.Comm):
    """``gmshio.read_from_msh(path, comm, 0, gdim=2)`` as it should be in 0.5.2."""
    import gmsh
    from dolfinx.io import gmshio

    error = None
    if comm.rank == 0:
        try:
            open_msh(gmsh, path)
            types, _, _ = gmsh.model.mesh.getElements(2)
            if list(types) != [3]:
                error = f"2D element types {list(types)} in {path}, expected only 4-node quadrilaterals (3)"
        except Exception as e:
            error = f"{type(e).__name__}: {e}"
        if error is not None:
            gmsh.finalize()
    error = comm.bcast(error, root=0)
    if error is not None:
        raise _UnreadableMsh(error)
    try:
        msh, cell_tags, facet_tags = gmshio.model_to_mesh(gmsh.model, comm, 0, gdim=2)
    finally:
        if comm.rank == 0:
            gmsh.finalize()
    msh.name = "fabric"
    return msh, cell_tags, facet_tags


# --------------------------------------------------------------------------- structured alternative


def uniform_square(n: int, side: float = SIDE_DEFAULT, comm: MPI.Comm = MPI.COMM_WORLD):
    """``n x n`` square quadrilaterals on [-side/2, side/2]^2 with the same tags as
    :func:`load_mesh` (cells ``FABRIC``, facets ``LEFT/RIGHT/BOTTOM/TOP``).
    Returns ``(msh, cell_tags, facet_tags)``. Collective."""
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(f"uniform_square: n = {n!r}: must be an integer >= 1")
    side = float(side)
    if not (math.isfinite(side) and side > 0):
        raise ValueError(f"uniform_square: side = {side!r}: must be finite and > 0")
    a = side / 2
    msh = dolfinx.mesh.create_rectangle(comm, [np.array([-a, -a]), np.array([a, a])], [n, n],
                                        cell_type=dolfinx.mesh.CellType.quadrilateral)
    return _tag_square(msh, side)


def graded_nodes(lo: float, hi: float, centre: float, h_centre: float, h_edge: float,
                 refine_radius: float, grading: float) -> np.ndarray:
    """Node coordinates on [lo, hi] with a node at ``centre``: spacing h_centre within
    ``refine_radius`` of it, then growing by ``grading`` per unit distance up to h_edge (the
    size law of the graded gmsh mesh, :class:`MeshSpec`); each side's last interval is
    stretched or shrunk so that its last node falls on the end."""
    def side(length: float) -> np.ndarray:
        d = [0.0]
        while d[-1] < length:
            beyond = max(d[-1] - refine_radius, 0.0)
            d.append(d[-1] + min(h_centre + grading * beyond, h_edge))
        d = np.array(d)
        if len(d) > 2 and (d[-1] - length) > 0.5 * (d[-1] - d[-2]):
            d = d[:-1]                                   # merge a short last interval
        return d * (length / d[-1])
    left, right = side(centre - lo), side(hi - centre)
    return np.concatenate((centre - left[:0:-1], centre + right))


def rectilinear_square(x_nodes: np.ndarray, y_nodes: np.ndarray, comm: MPI.Comm = MPI.COMM_WORLD):
    """The structured quadrilateral mesh of the grid ``x_nodes`` x ``y_nodes`` (a square
    [-side/2, side/2]^2: both arrays run from -side/2 to side/2), its edges along x and y, with
    the tags of :func:`load_mesh`. Built on rank 0 and distributed. Collective."""
    import ufl

    x_nodes, y_nodes = np.asarray(x_nodes, dtype=float), np.asarray(y_nodes, dtype=float)
    side = float(x_nodes[-1] - x_nodes[0])
    if not (np.all(np.diff(x_nodes) > 0) and np.all(np.diff(y_nodes) > 0)
            and np.isclose(y_nodes[-1] - y_nodes[0], side) and np.isclose(x_nodes[0], -side / 2)
            and np.isclose(y_nodes[0], -side / 2)):
        raise ValueError("rectilinear_square: x_nodes and y_nodes must increase and both span "
                         "[-side/2, side/2]")
    nx, ny = x_nodes.size, y_nodes.size
    if comm.rank == 0:
        X, Y = np.meshgrid(x_nodes, y_nodes, indexing="xy")
        points = np.column_stack((X.ravel(), Y.ravel()))
        i, j = np.meshgrid(np.arange(nx - 1), np.arange(ny - 1), indexing="xy")
        v0 = (j * nx + i).ravel()
        cells = np.column_stack((v0, v0 + 1, v0 + nx, v0 + nx + 1)).astype(np.int64)
    else:
        points, cells = np.zeros((0, 2)), np.zeros((0, 4), dtype=np.int64)
    domain = ufl.Mesh(ufl.VectorElement("Lagrange", "quadrilateral", 1))
    msh = dolfinx.mesh.create_mesh(comm, cells, points, domain)
    return _tag_square(msh, side)


def aligned_square(spec: MeshSpec, comm: MPI.Comm = MPI.COMM_WORLD):
    """A graded mesh whose edges run along x and y (the yarns of the 0 and 90 degree scenes):
    the rectilinear grid of :func:`graded_nodes` in x and y with the sizes of ``spec`` (fine
    within ``refine_radius`` of ``spec.centre``). Returns ``(msh, cell_tags, facet_tags)``."""
    a = spec.side / 2
    sizes = (spec.h_centre, spec.h_edge, spec.refine_radius, spec.grading)
    return rectilinear_square(graded_nodes(-a, a, spec.centre[0], *sizes),
                              graded_nodes(-a, a, spec.centre[1], *sizes), comm)


def _tag_square(msh, side: float):
    """(msh, cell_tags, facet_tags) of a square mesh [-side/2, side/2]^2: every cell ``FABRIC``,
    the edge facets ``LEFT/RIGHT/BOTTOM/TOP``."""
    a = side / 2
    tdim = msh.topology.dim
    num_cells = msh.topology.index_map(tdim).size_local + msh.topology.index_map(tdim).num_ghosts
    cells = np.arange(num_cells, dtype=np.int32)
    cell_tags = dolfinx.mesh.meshtags(msh, tdim, cells, np.full(num_cells, FABRIC, dtype=np.int32))

    tol = 1e-10 * side
    markers = {LEFT: lambda x: np.abs(x[0] + a) < tol, RIGHT: lambda x: np.abs(x[0] - a) < tol,
               BOTTOM: lambda x: np.abs(x[1] + a) < tol, TOP: lambda x: np.abs(x[1] - a) < tol}
    facets, values = [], []
    for tag, marker in markers.items():
        f = dolfinx.mesh.locate_entities_boundary(msh, tdim - 1, marker)
        facets.append(f)
        values.append(np.full(len(f), tag, dtype=np.int32))
    facets, values = np.concatenate(facets), np.concatenate(values)
    order = np.argsort(facets)
    facet_tags = dolfinx.mesh.meshtags(msh, tdim - 1, facets[order], values[order])
    cell_tags.name, facet_tags.name = "Cell tags", "Facet tags"
    msh.name = "fabric"
    return msh, cell_tags, facet_tags


# --------------------------------------------------------------------------- helpers


def edge_dofs(V: dolfinx.fem.FunctionSpace, facet_tags, tags: int | Iterable[int]) -> np.ndarray:
    """Indices into ``u.x.array`` of every block component of the dofs on the facets
    tagged ``tags`` (e.g. ``(BOTTOM, TOP)`` for the two clamped edges of case Y0,
    Table 3). Local to the process (owned and ghost dofs on local facets); after
    setting them call ``u.x.scatter_forward()``."""
    tags = [tags] if isinstance(tags, (int, np.integer)) else list(tags)
    for t in tags:
        if t not in EDGE_NAMES:
            raise ValueError(f"edge_dofs: tags = {tags!r}: each must be one of {sorted(EDGE_NAMES)} "
                             "(LEFT, RIGHT, BOTTOM, TOP)")
    msh = V.mesh
    fdim = msh.topology.dim - 1
    msh.topology.create_connectivity(fdim, msh.topology.dim)
    facets = facet_tags.indices[np.isin(facet_tags.values, tags)]
    blocks = dolfinx.fem.locate_dofs_topological(V, fdim, facets)
    bs = V.dofmap.index_map_bs
    return np.unique((bs * blocks[:, None] + np.arange(bs)).ravel()).astype(np.int32)


_MEASURES = ("min_edge", "sqrt_area", "area_over_diagonal")


def cell_sizes(msh: dolfinx.mesh.Mesh, measure: str = "min_edge") -> np.ndarray:
    """Size of every local cell (owned, then ghosts) of a first-order quadrilateral mesh.

    measure: ``"min_edge"`` shortest edge; ``"sqrt_area"``;
    ``"area_over_diagonal"`` area / longest diagonal, the length L for which
    dt = L / c is the exact stable step of the lumped-mass bilinear square
    (h / sqrt(2) for a square of side h).
    """
    if measure not in _MEASURES:
        raise ValueError(f"cell_sizes: measure = {measure!r}: must be one of {_MEASURES}")
    if msh.topology.cell_type != dolfinx.mesh.CellType.quadrilateral:
        raise ValueError(f"cell_sizes: cell type {msh.topology.cell_type}: only quadrilateral meshes")
    dofs = msh.geometry.dofmap.array.reshape(-1, 4)  # 4 nodes per cell: first-order geometry
    p = msh.geometry.x[dofs[:, _QUAD_CYCLE], :2]  # (n, 4, 2), perimeter order
    if measure == "min_edge":
        return np.linalg.norm(np.roll(p, -1, axis=1) - p, axis=2).min(axis=1)
    x, y = p[..., 0], p[..., 1]
    area = 0.5 * np.abs(np.sum(x * np.roll(y, -1, axis=1) - np.roll(x, -1, axis=1) * y, axis=1))
    if measure == "sqrt_area":
        return np.sqrt(area)
    diagonal = np.maximum(np.linalg.norm(p[:, 2] - p[:, 0], axis=1), np.linalg.norm(p[:, 3] - p[:, 1], axis=1))
    return area / diagonal


def min_cell_size(msh: dolfinx.mesh.Mesh, measure: str = "min_edge") -> float:
    """Global minimum of :func:`cell_sizes` over the owned cells of all ranks. Collective."""
    n_owned = msh.topology.index_map(msh.topology.dim).size_local
    sizes = cell_sizes(msh, measure)[:n_owned]
    local = float(sizes.min()) if n_owned else math.inf
    return msh.comm.allreduce(local, op=MPI.MIN)
