"""Tests of the structured patch (``mesh.kind = "structured"``) and of a user's mesh file
(``mesh.kind = "file"``): the patch's rows run at the asked angle with cells of the asked size,
the old meshes' cache names stay, and a file that is not a square of quadrilaterals is refused."""

import math

import gmsh
import numpy as np
import pytest
from mpi4py import MPI

from fabric_fenicsx.fem import mesh as fm
from fabric_fenicsx.fem.mesh_file import read_square_msh
from fabric_fenicsx.fem.structured_patch import largest_patch_radius, patch_half_side


def _cells(path):
    """(corners (n, 4, 2) in perimeter order) of a gmsh file."""
    gmsh.initialize(readConfigFiles=False)
    gmsh.option.setNumber("General.Terminal", 0)
    try:
        gmsh.merge(str(path))
        quads, x = fm._quads(gmsh)
    finally:
        gmsh.finalize()
    return x[quads]


@pytest.mark.parametrize("rotation", [0.0, 30.0, 45.0])
def test_the_patch_rows_run_at_the_rotation_with_cells_of_h(tmp_path, rotation):
    h = 2e-3
    spec = fm.MeshSpec(side=0.06, h_centre=h, h_edge=4e-3, refine_radius=0.012, grading=0.3, rotation=rotation)
    stats = fm.build_msh(spec, tmp_path / spec.name)
    assert stats["min_scaled_jacobian"] > 0.3
    corners = _cells(tmp_path / spec.name)
    centres = corners.mean(axis=1)
    t = math.radians(rotation)
    local = centres @ np.array([[math.cos(t), -math.sin(t)], [math.sin(t), math.cos(t)]])
    inside = np.all(np.abs(local) < patch_half_side(0.012, h), axis=1)
    assert inside.sum() == (2 * round(0.012 / h)) ** 2          # the whole patch, squares of side h
    edges = np.roll(corners[inside], -1, axis=1) - corners[inside]
    lengths = np.linalg.norm(edges, axis=2)
    assert np.allclose(lengths, h, rtol=1e-9)
    angles = np.degrees(np.arctan2(edges[..., 1], edges[..., 0])) % 90.0
    assert np.allclose(np.minimum(np.abs(angles - rotation % 90.0), 90.0 - np.abs(angles - rotation % 90.0)), 0.0,
                       atol=1e-6)
    # a node at the impact point
    nodes = corners.reshape(-1, 2)
    assert np.min(np.linalg.norm(nodes, axis=1)) < 1e-12


def test_a_patch_that_does_not_fit_is_refused_and_names_the_room():
    room = largest_patch_radius(0.06, (0.0, 0.0), 45.0, 2e-3)
    assert room == pytest.approx((0.03 - 2e-3) / math.sqrt(2))
    with pytest.raises(ValueError, match="at most"):
        fm.MeshSpec(side=0.06, h_centre=2e-3, h_edge=4e-3, refine_radius=0.024, rotation=45.0)
    fm.MeshSpec(side=0.06, h_centre=2e-3, h_edge=4e-3, refine_radius=0.024, rotation=0.0)   # fits unturned


def test_unstructured_meshes_keep_their_cache_names():
    spec = fm.MeshSpec()
    assert "rotation" not in spec.as_dict()
    assert spec.name == "fabric_s273.05mm_hc1.00mm_he8.00mm_r20.00mm_g0.10_c0.00_0.00mm.msh"
    assert fm.MeshSpec(rotation=30.0).name != fm.MeshSpec(rotation=45.0).name != spec.name


def test_a_users_file_is_read_with_its_edges_found_by_position(tmp_path):
    spec = fm.MeshSpec(side=0.06, h_centre=4e-3, h_edge=6e-3, refine_radius=0.012, grading=0.3, rotation=30.0)
    fm.build_msh(spec, tmp_path / "mine.msh")
    msh, _, facets = read_square_msh(tmp_path / "mine.msh", 0.06, MPI.COMM_WORLD)
    for tag in fm.EDGE_NAMES:
        assert np.count_nonzero(facets.values == tag) > 0
    with pytest.raises(ValueError, match="must cover the square"):
        read_square_msh(tmp_path / "mine.msh", 0.05, MPI.COMM_WORLD)


def test_a_file_of_triangles_is_refused_with_what_it_holds(tmp_path):
    gmsh.initialize(readConfigFiles=False)
    gmsh.option.setNumber("General.Terminal", 0)
    try:
        gmsh.model.add("triangles")
        gmsh.model.occ.addRectangle(-0.03, -0.03, 0, 0.06, 0.06)
        gmsh.model.occ.synchronize()
        gmsh.option.setNumber("Mesh.MeshSizeMax", 0.01)
        gmsh.model.mesh.generate(2)
        gmsh.write(str(tmp_path / "tri.msh"))
    finally:
        gmsh.finalize()
    with pytest.raises(ValueError, match="only 4-node quadrilaterals"):
        read_square_msh(tmp_path / "tri.msh", 0.06, MPI.COMM_WORLD)
    (tmp_path / "junk.msh").write_text("not a mesh")
    with pytest.raises(ValueError, match="mesh file"):
        read_square_msh(tmp_path / "junk.msh", 0.06, MPI.COMM_WORLD)
