"""Meshes from outside the scene's own mesher: a user's gmsh file of the square fabric
(``mesh.kind = "file"``) and unstructured quadrilaterals of one size on a rectangle (the free
family of the strip and tear tests)."""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from mpi4py import MPI

from fabric_fenicsx.fem.mesh import (EDGE_NAMES, FABRIC, _min_scaled_jacobian, _quads, _read_msh, _tag_square,
                                     _UnreadableMsh, open_msh)

__all__ = ["read_square_msh", "square_msh_problem", "free_rectangle"]


def read_square_msh(path: str | os.PathLike, side: float, comm: MPI.Comm = MPI.COMM_WORLD):
    """``(msh, cell_tags, facet_tags)`` of a user's gmsh file: 4-node quadrilaterals covering the
    square [-side/2, side/2]^2, its edges ``LEFT/RIGHT/BOTTOM/TOP`` found by position (the file's
    own physical groups are not needed). A file that is not such a mesh (other cells, another
    square, an inverted cell, an edge without facets) raises ValueError saying what it found.
    Collective."""
    path = Path(path)
    if comm.rank == 0:
        try:
            problem = square_msh_problem(path, float(side))
        except Exception as e:   # gmsh's own words for a file it cannot read
            problem = f"gmsh cannot read it: {type(e).__name__}: {e}"
    else:
        problem = None
    problem = comm.bcast(problem, root=0)
    if problem:
        raise ValueError(f"mesh file {str(path)!r}: {problem}")
    try:
        msh, _, _ = _read_msh(path, comm)
    except _UnreadableMsh as e:
        raise ValueError(f"mesh file {str(path)!r}: {e}") from None
    msh, cell_tags, facet_tags = _tag_square(msh, float(side))
    counts = [comm.allreduce(int(np.count_nonzero(facet_tags.values == tag)), op=MPI.SUM) for tag in EDGE_NAMES]
    missing = [EDGE_NAMES[t] for t, n in zip(EDGE_NAMES, counts) if n == 0]
    if missing:
        raise ValueError(f"mesh file {str(path)!r}: no cell edge lies on the {', '.join(missing)} edge(s) of the "
                         f"square of side {side!r} m; every edge of the square must be meshed")
    return msh, cell_tags, facet_tags


def square_msh_problem(path: Path, side: float) -> str:
    """What keeps the file ``path`` from being a mesh of quadrilaterals of the square of side
    ``side`` centred at the origin ("" if nothing), read with gmsh in this process; a file gmsh
    cannot read raises gmsh's own exception."""
    import gmsh

    try:
        open_msh(gmsh, path)
        types, _, _ = gmsh.model.mesh.getElements(2)
        if len(types) == 0:
            return "no 2D cells"
        if list(types) != [3]:
            names = [gmsh.model.mesh.getElementProperties(t)[0] for t in types]
            return f"2D cells {names}: only 4-node quadrilaterals are accepted (recombine the mesh)"
        quads, x = _quads(gmsh)
    finally:
        gmsh.finalize()
    used = x[np.unique(quads)]
    lo, hi = used.min(axis=0), used.max(axis=0)
    tol = 1e-6 * side
    if np.any(np.abs(lo + side / 2) > tol) or np.any(np.abs(hi - side / 2) > tol):
        return (f"its cells span x {lo[0]:.6g} to {hi[0]:.6g}, y {lo[1]:.6g} to {hi[1]:.6g} m; a fabric mesh must "
                f"cover the square [-side/2, side/2]^2 with mesh.side = {side!r} m (centred at the origin)")
    sj = _min_scaled_jacobian(x[quads])
    if sj <= 0.0:
        return f"a cell is inverted or not convex (smallest scaled Jacobian {sj:.3g}); fix the mesh"
    return ""


def free_rectangle(lower: tuple[float, float], upper: tuple[float, float], h: float,
                   comm: MPI.Comm = MPI.COMM_WORLD):
    """Unstructured quadrilaterals of size about ``h`` on the rectangle ``lower``-``upper`` (gmsh,
    Frontal-Delaunay with blossom recombination: the graded family's mesher at one size).
    Returns the DOLFINx mesh. Collective."""
    import gmsh
    from dolfinx.io import gmshio

    if comm.rank == 0:
        gmsh.initialize(readConfigFiles=False)
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("rectangle")
        g = gmsh.model.geo
        (x0, y0), (x1, y1) = lower, upper
        p = [g.addPoint(x0, y0, 0), g.addPoint(x1, y0, 0), g.addPoint(x1, y1, 0), g.addPoint(x0, y1, 0)]
        lines = [g.addLine(p[i], p[(i + 1) % 4]) for i in range(4)]
        surface = g.addPlaneSurface([g.addCurveLoop(lines)])
        g.synchronize()
        gmsh.model.addPhysicalGroup(2, [surface], FABRIC)
        for option, value in (("Mesh.MeshSizeMin", h), ("Mesh.MeshSizeMax", h), ("Mesh.Algorithm", 6),
                              ("Mesh.RecombinationAlgorithm", 1), ("Mesh.RecombineAll", 1)):
            gmsh.option.setNumber(option, value)
        gmsh.model.mesh.generate(2)
    try:
        msh, _, _ = gmshio.model_to_mesh(gmsh.model, comm, 0, gdim=2)
    finally:
        if comm.rank == 0:
            gmsh.finalize()
    return msh
