"""Structured graded meshes whose edges follow the yarns of the 0 and 90 degree scenes
(fem.mesh.graded_nodes, rectilinear_square, aligned_square)."""
import numpy as np
import pytest
import ufl
from mpi4py import MPI

import dolfinx.fem

from fabric_fenicsx.fem import mesh as fm


def test_graded_nodes_follow_the_size_law_and_hit_centre_and_ends():
    x = fm.graded_nodes(-0.1, 0.15, 0.02, 1e-3, 8e-3, 0.01, 0.1)
    h = np.diff(x)
    assert x[0] == pytest.approx(-0.1, abs=1e-15) and x[-1] == pytest.approx(0.15, abs=1e-15)
    assert np.any(np.abs(x - 0.02) < 1e-15)                          # a node at the centre
    near = np.abs(0.5 * (x[1:] + x[:-1]) - 0.02) < 0.01
    assert np.allclose(h[near], 1e-3, rtol=0.05)                     # h_centre within the radius
    assert h.max() <= 8e-3 * 1.5 and h.min() > 0.9e-3
    assert np.all(np.abs(np.diff(h)) <= 0.1 * 8e-3 + 1e-12 + 0.5 * h[1:])  # no jumps beyond the law


def test_aligned_square_is_a_graded_grid_along_x_and_y_with_the_edge_tags():
    spec = fm.MeshSpec(side=0.1, h_centre=2e-3, h_edge=8e-3, refine_radius=0.01, grading=0.2)
    msh, cell_tags, facet_tags = fm.aligned_square(spec, MPI.COMM_WORLD)
    x = msh.geometry.x[:, :2]
    geo = msh.geometry.dofmap.array.reshape(-1, 4)[:msh.topology.index_map(2).size_local]
    edges = x[geo[:, [1, 2, 3, 3]]] - x[geo[:, [0, 0, 1, 2]]]
    assert np.all(np.min(np.abs(edges), axis=2) < 1e-15)            # every edge along x or y
    V = dolfinx.fem.FunctionSpace(msh, ("Lagrange", 1))
    area = dolfinx.fem.assemble_scalar(dolfinx.fem.form(dolfinx.fem.Constant(msh, 1.0) * ufl.dx(domain=msh)))
    assert MPI.COMM_WORLD.allreduce(area) == pytest.approx(0.01, rel=1e-12)
    for tag in (fm.LEFT, fm.RIGHT, fm.BOTTOM, fm.TOP):
        n = MPI.COMM_WORLD.allreduce(int(np.count_nonzero(facet_tags.values == tag)))
        assert n == fm.graded_nodes(-0.05, 0.05, 0.0, 2e-3, 8e-3, 0.01, 0.2).size - 1
    assert V.dofmap.index_map.size_global == fm.graded_nodes(-0.05, 0.05, 0.0, 2e-3, 8e-3, 0.01, 0.2).size ** 2
