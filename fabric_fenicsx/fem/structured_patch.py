"""A structured patch in the fabric mesh: rows of squares turned by an angle from x at the
impact point, in unstructured quadrilaterals graded outwards (``mesh.kind = "structured"``).

A mesh whose rows run at 0, 30 or 45 degrees to the yarns with cells of one size is what tells
the yarns' directions from the cells' in a tear (the cells' *orientation*); the aligned grid
and the unstructured graded mesh mix it with a change of size or of shape. Pure geometry and
gmsh calls: no DOLFINx here (the scene's checks use :func:`largest_patch_radius`).
"""
from __future__ import annotations

import math

__all__ = ["patch_half_side", "largest_patch_radius", "build_patch_geometry"]

LEFT, RIGHT, BOTTOM, TOP = 1, 2, 3, 4  # the facet tags of fabric_fenicsx.fem.mesh


def patch_half_side(refine_radius: float, h_centre: float) -> float:
    """Half the side of a structured patch (m): ``refine_radius`` rounded to a whole number of
    ``h_centre`` cells (at least one), so that its cells are squares of side ``h_centre`` and a
    node lies at its centre."""
    return max(1, round(refine_radius / h_centre)) * h_centre


def largest_patch_radius(side: float, centre: tuple[float, float], rotation: float, margin: float) -> float:
    """The largest half-side (m) of a square centred at ``centre`` and turned ``rotation``
    degrees that keeps ``margin`` from every edge of the square [-side/2, side/2]^2."""
    t = math.radians(rotation)
    reach = abs(math.cos(t)) + abs(math.sin(t))        # a corner's reach along x or y per half-side
    room = side / 2 - margin - max(abs(centre[0]), abs(centre[1]))
    return max(room, 0.0) / reach


def build_patch_geometry(gmsh, spec) -> tuple[list[int], dict[int, list[int]]]:
    """The gmsh geometry of a :class:`~fabric_fenicsx.fem.mesh.MeshSpec` with a rotation: a
    structured patch (:func:`patch_half_side`, turned ``spec.rotation`` degrees) of transfinite
    squares of side ``h_centre`` at ``centre``, in a square meshed with unstructured
    quadrilaterals whose size grows from ``h_centre`` at the patch to ``h_edge``. Returns
    (surfaces, {edge tag: curves}) for the caller's physical groups."""
    a, r = spec.side / 2, patch_half_side(spec.refine_radius, spec.h_centre)
    n = 2 * round(r / spec.h_centre)
    t = math.radians(spec.rotation)
    c, s = math.cos(t), math.sin(t)
    g = gmsh.model.geo
    p = [g.addPoint(-a, -a, 0.0), g.addPoint(a, -a, 0.0), g.addPoint(a, a, 0.0), g.addPoint(-a, a, 0.0)]
    bottom, right, top, left = (g.addLine(p[i], p[(i + 1) % 4]) for i in range(4))
    corners = [(spec.centre[0] + c * x - s * y, spec.centre[1] + s * x + c * y)
               for x, y in ((-r, -r), (r, -r), (r, r), (-r, r))]
    q = [g.addPoint(x, y, 0.0) for x, y in corners]
    sides = [g.addLine(q[i], q[(i + 1) % 4]) for i in range(4)]
    inner = g.addCurveLoop(sides)
    patch = g.addPlaneSurface([inner])
    outside = g.addPlaneSurface([g.addCurveLoop([bottom, right, top, left]), inner])
    g.synchronize()
    for line in sides:
        gmsh.model.mesh.setTransfiniteCurve(line, n + 1)
    gmsh.model.mesh.setTransfiniteSurface(patch, "Left", q)
    gmsh.model.mesh.setRecombine(2, patch)

    field = gmsh.model.mesh.field
    dist = field.add("Distance")
    field.setNumbers(dist, "CurvesList", sides)
    field.setNumber(dist, "NumPointsPerCurve", 4 * n)
    thr = field.add("Threshold")
    field.setNumber(thr, "InField", dist)
    field.setNumber(thr, "SizeMin", spec.h_centre)
    field.setNumber(thr, "SizeMax", spec.h_edge)
    field.setNumber(thr, "DistMin", 0.0)
    field.setNumber(thr, "DistMax", max((spec.h_edge - spec.h_centre) / spec.grading, spec.h_centre))
    field.setAsBackgroundMesh(thr)
    for option, value in (("Mesh.MeshSizeExtendFromBoundary", 0), ("Mesh.MeshSizeFromPoints", 0),
                          ("Mesh.MeshSizeFromCurvature", 0), ("Mesh.MeshSizeMax", spec.h_edge),
                          ("Mesh.RecombineAll", 1)):
        gmsh.option.setNumber(option, value)
    return [patch, outside], {LEFT: [left], RIGHT: [right], BOTTOM: [bottom], TOP: [top]}
