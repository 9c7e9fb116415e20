"""Tests of fabric_fenicsx.fem.mesh: tags, area, grading, cache, MPI distribution."""

import json
import math
import os
import re
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
import ufl
from mpi4py import MPI

import dolfinx.fem
import dolfinx.mesh

from fabric_fenicsx.fem import mesh as fm

REPO = Path(__file__).resolve().parents[2]

# Coarse graded mesh: builds in ~0.1 s. Size reaches h_edge at r + (h_edge - h_centre)/grading = 60 mm.
SPEC = fm.MeshSpec(h_centre=4e-3, h_edge=16e-3, refine_radius=0.02, grading=0.3)
TAGS = (fm.LEFT, fm.RIGHT, fm.BOTTOM, fm.TOP)


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    return tmp_path_factory.mktemp("meshes")


@pytest.fixture(scope="module")
def graded(cache):
    return fm.load_mesh(SPEC, MPI.COMM_WORLD, cache_dir=cache)


def _integrate(msh, measure):
    form = dolfinx.fem.form(dolfinx.fem.Constant(msh, 1.0) * measure)
    return msh.comm.allreduce(dolfinx.fem.assemble_scalar(form), op=MPI.SUM)


def _edge_lengths(msh, facet_tags):
    ds = ufl.ds(domain=msh, subdomain_data=facet_tags)
    return {tag: _integrate(msh, ds(tag)) for tag in TAGS}


def _vertices(msh):
    """(n_cells, 4, 2) vertex coordinates in DOLFINx order (0,0),(1,0),(0,1),(1,1)."""
    return msh.geometry.x[msh.geometry.dofmap.array.reshape(-1, 4), :2]


def _corner_crosses(p):
    """Cross products of the two edges at each corner, walking the perimeter."""
    c = p[:, [0, 1, 3, 2]]
    e_next, e_prev = np.roll(c, -1, axis=1) - c, np.roll(c, 1, axis=1) - c
    return e_next[..., 0] * e_prev[..., 1] - e_next[..., 1] * e_prev[..., 0]


# ----------------------------------------------------------------------------- spec


def test_name_encodes_every_parameter():
    assert fm.MeshSpec().name == "fabric_s273.05mm_hc1.00mm_he8.00mm_r20.00mm_g0.10_c0.00_0.00mm.msh"
    changes = dict(side=0.3, h_centre=2e-3, h_edge=9e-3, refine_radius=0.03, grading=0.2,
                   centre=(-0.116525, 0.0))
    names = {fm.MeshSpec().name} | {fm.MeshSpec(**{k: v}).name for k, v in changes.items()}
    assert len(names) == len(changes) + 1
    for name in names:
        assert re.fullmatch(r"[A-Za-z0-9._-]+", name), name
    assert fm.MeshSpec(h_centre=0.001).name == fm.MeshSpec(h_centre=1e-3).name  # equal specs, equal names


@pytest.mark.parametrize("kwargs, field", [
    (dict(side=0.0), "side"),
    (dict(side=float("nan")), "side"),
    (dict(h_centre=-1e-3), "h_centre"),
    (dict(h_edge=0.0), "h_edge"),
    (dict(h_centre=9e-3, h_edge=8e-3), "h_centre"),
    (dict(h_edge=0.2), "h_edge"),
    (dict(refine_radius=-0.01), "refine_radius"),
    (dict(grading=0.0), "grading"),
    (dict(grading=2.0), "grading"),
    (dict(centre=(0.2, 0.0)), "centre"),
    (dict(centre=(0.0, -0.1365)), "centre"),  # inside, but closer than h_centre to the bottom edge
    (dict(centre=(0.0,)), "centre"),
    (dict(h_centre="fine"), "h_centre"),
])
def test_bad_spec_raises_naming_the_field(kwargs, field):
    with pytest.raises(ValueError, match=field):
        fm.MeshSpec(**kwargs)


# ----------------------------------------------------------------------------- graded mesh


def test_graded_mesh_tags_area_and_cells(graded):
    msh, cell_tags, facet_tags = graded
    side = SPEC.side
    assert msh.topology.cell_type == dolfinx.mesh.CellType.quadrilateral
    assert set(np.unique(cell_tags.values)) == {fm.FABRIC}
    lengths = _edge_lengths(msh, facet_tags)
    for tag in TAGS:
        assert lengths[tag] == pytest.approx(side, rel=1e-12), fm.EDGE_NAMES[tag]
    assert sum(lengths.values()) == pytest.approx(4 * side, rel=1e-12)
    assert _integrate(msh, ufl.dx(domain=msh)) == pytest.approx(side**2, rel=1e-12)
    # every cell convex and consistently oriented after the gmsh -> DOLFINx permutation
    cross = _corner_crosses(_vertices(msh))
    assert np.all(cross > 0) or np.all(cross < 0)
    # a node sits exactly at the impact point
    assert np.linalg.norm(msh.geometry.x[:, :2] - SPEC.centre, axis=1).min() < 1e-12


def test_graded_sizes_follow_the_threshold_field(graded):
    msh = graded[0]
    h = fm.cell_sizes(msh, "sqrt_area")
    r = np.linalg.norm(_vertices(msh).mean(axis=1) - SPEC.centre, axis=1)
    ramp_end = SPEC.refine_radius + (SPEC.h_edge - SPEC.h_centre) / SPEC.grading
    h_fine, h_coarse = np.median(h[r < SPEC.refine_radius / 2]), np.median(h[r > ramp_end + SPEC.h_edge])
    assert 0.7 * SPEC.h_centre < h_fine < 1.3 * SPEC.h_centre
    assert 0.7 * SPEC.h_edge < h_coarse < 1.3 * SPEC.h_edge
    ratio = h_fine / h_coarse
    assert SPEC.h_centre / SPEC.h_edge / 1.5 < ratio < SPEC.h_centre / SPEC.h_edge * 1.5
    # the shortest edge is a fair fraction of h_centre (it sets the explicit time step)
    assert 0.3 * SPEC.h_centre < fm.min_cell_size(msh) <= 1.1 * SPEC.h_centre


def test_impact_near_an_edge(cache):
    spec = fm.MeshSpec(h_centre=4e-3, h_edge=16e-3, grading=0.3, centre=(-SPEC.side / 2 + 0.02, 0.0))
    msh, _, facet_tags = fm.load_mesh(spec, MPI.COMM_WORLD, cache_dir=cache)
    assert np.linalg.norm(msh.geometry.x[:, :2] - spec.centre, axis=1).min() < 1e-12
    assert _integrate(msh, ufl.dx(domain=msh)) == pytest.approx(spec.side**2, rel=1e-12)
    assert _edge_lengths(msh, facet_tags)[fm.LEFT] == pytest.approx(spec.side, rel=1e-12)
    h = fm.cell_sizes(msh, "sqrt_area")
    r = np.linalg.norm(_vertices(msh).mean(axis=1) - spec.centre, axis=1)
    assert 0.7 * spec.h_centre < np.median(h[r < 0.01]) < 1.3 * spec.h_centre


def test_uniform_spec_is_a_structured_grid_through_the_centre(cache):
    h = 10e-3
    spec = fm.MeshSpec(h_centre=h, h_edge=h, centre=(0.03, -0.05))
    msh, _, facet_tags = fm.load_mesh(spec, MPI.COMM_WORLD, cache_dir=cache)
    a = spec.side / 2
    per_axis = [math.ceil((c + a) / h) + math.ceil((a - c) / h) for c in spec.centre]
    assert msh.topology.index_map(2).size_global == per_axis[0] * per_axis[1]
    p = _vertices(msh)
    # rectangles aligned with x (warp) and y (fill): edge 0-1 horizontal, 0-2 vertical
    assert np.allclose(p[:, 1, 1], p[:, 0, 1]) and np.allclose(p[:, 2, 0], p[:, 0, 0])
    assert fm.cell_sizes(msh, "min_edge").max() <= h * (1 + 1e-9)
    assert np.linalg.norm(msh.geometry.x[:, :2] - spec.centre, axis=1).min() < 1e-12
    assert sum(_edge_lengths(msh, facet_tags).values()) == pytest.approx(4 * spec.side, rel=1e-12)


# ----------------------------------------------------------------------------- cache


def test_cache_is_reused_and_parameters_change_the_file(cache, capsys):
    fm.load_mesh(SPEC, MPI.COMM_WORLD, cache_dir=cache)
    path = cache / SPEC.name
    mtime = path.stat().st_mtime_ns
    capsys.readouterr()
    fm.load_mesh(SPEC, MPI.COMM_WORLD, cache_dir=cache)
    assert path.stat().st_mtime_ns == mtime
    assert "building" not in capsys.readouterr().out
    other = fm.MeshSpec(h_centre=SPEC.h_centre, h_edge=SPEC.h_edge, refine_radius=0.03, grading=SPEC.grading)
    fm.load_mesh(other, MPI.COMM_WORLD, cache_dir=cache)
    assert "building" in capsys.readouterr().out
    assert other.name != SPEC.name and (cache / other.name).exists()
    assert path.stat().st_mtime_ns == mtime


def test_truncated_cache_file_is_rebuilt_not_used(tmp_path, capsys):
    msh0 = fm.load_mesh(SPEC, MPI.COMM_WORLD, cache_dir=tmp_path)[0]
    path = tmp_path / SPEC.name
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    assert not fm.cache_is_valid(SPEC, path)
    capsys.readouterr()
    msh, _, facet_tags = fm.load_mesh(SPEC, MPI.COMM_WORLD, cache_dir=tmp_path)
    assert "building" in capsys.readouterr().out
    assert fm.cache_is_valid(SPEC, path)
    assert msh.topology.index_map(2).size_global == msh0.topology.index_map(2).size_global
    assert _integrate(msh, ufl.dx(domain=msh)) == pytest.approx(SPEC.side**2, rel=1e-12)


def test_truncated_msh_is_refused_by_the_reader(tmp_path):
    fm.build_msh(SPEC, tmp_path / "full.msh")
    data = (tmp_path / "full.msh").read_bytes()
    (tmp_path / "cut.msh").write_bytes(data[: int(0.9 * len(data))])
    with pytest.raises(RuntimeError):
        fm._read_msh(tmp_path / "cut.msh", MPI.COMM_WORLD)


# ----------------------------------------------------------------------------- structured + helpers


def test_uniform_square_tags_sizes_and_edge_dofs():
    n, side = 8, 0.2
    msh, cell_tags, facet_tags = fm.uniform_square(n, side, MPI.COMM_WORLD)
    assert msh.topology.index_map(2).size_global == n * n
    assert set(np.unique(cell_tags.values)) == {fm.FABRIC}
    for tag, length in _edge_lengths(msh, facet_tags).items():
        assert length == pytest.approx(side, rel=1e-12), fm.EDGE_NAMES[tag]
    h = side / n
    assert np.allclose(fm.cell_sizes(msh, "min_edge"), h)
    assert np.allclose(fm.cell_sizes(msh, "sqrt_area"), h)
    assert np.allclose(fm.cell_sizes(msh, "area_over_diagonal"), h / np.sqrt(2))
    assert fm.min_cell_size(msh) == pytest.approx(h)

    V = dolfinx.fem.FunctionSpace(msh, ufl.VectorElement("Lagrange", msh.ufl_cell(), 1, dim=3))
    x = V.tabulate_dof_coordinates()
    a = side / 2
    on_edge = {fm.LEFT: lambda p: np.isclose(p[:, 0], -a), fm.RIGHT: lambda p: np.isclose(p[:, 0], a),
               fm.BOTTOM: lambda p: np.isclose(p[:, 1], -a), fm.TOP: lambda p: np.isclose(p[:, 1], a)}
    for tag, test in on_edge.items():
        dofs = fm.edge_dofs(V, facet_tags, tag)
        assert len(dofs) == 3 * (n + 1)  # serial: every node on the edge, three components each
        assert np.all(test(x[dofs // 3]))
        assert np.array_equal(np.bincount(dofs % 3), [n + 1] * 3)
    all_dofs = fm.edge_dofs(V, facet_tags, TAGS)
    assert len(all_dofs) == 3 * 4 * n  # corners counted once


def test_edge_dofs_clamp_exactly_the_boundary_nodes_of_the_graded_mesh(graded):
    msh, _, facet_tags = graded
    V = dolfinx.fem.FunctionSpace(msh, ufl.VectorElement("Lagrange", msh.ufl_cell(), 1, dim=3))
    x = V.tabulate_dof_coordinates()
    a = SPEC.side / 2
    dofs = fm.edge_dofs(V, facet_tags, (fm.BOTTOM, fm.TOP))
    expected = np.flatnonzero(np.isclose(np.abs(x[:, 1]), a, rtol=0, atol=1e-12))
    assert np.array_equal(np.unique(dofs // 3), expected)
    # each tag sits on its own edge: LEFT x = -a, RIGHT x = +a, BOTTOM y = -a, TOP y = +a
    for tag, (axis, sign) in {fm.LEFT: (0, -1), fm.RIGHT: (0, 1), fm.BOTTOM: (1, -1), fm.TOP: (1, 1)}.items():
        assert np.allclose(x[fm.edge_dofs(V, facet_tags, tag) // 3, axis], sign * a, rtol=0, atol=1e-12)
    u = dolfinx.fem.Function(V)
    u.x.array[:] = 1.0
    u.x.array[dofs] = 0.0
    assert np.count_nonzero(u.x.array == 0.0) == 3 * len(expected)


def test_helpers_reject_bad_input(graded):
    msh, _, facet_tags = graded
    V = dolfinx.fem.FunctionSpace(msh, ufl.VectorElement("Lagrange", msh.ufl_cell(), 1, dim=3))
    with pytest.raises(ValueError, match="tags"):
        fm.edge_dofs(V, facet_tags, 7)
    with pytest.raises(ValueError, match="measure"):
        fm.cell_sizes(msh, "diameter")
    with pytest.raises(ValueError, match="n"):
        fm.uniform_square(0)
    with pytest.raises(ValueError, match="spec"):
        fm.load_mesh({"h_centre": 1e-3})


# ----------------------------------------------------------------------------- MPI

_MPI_SCRIPT = textwrap.dedent("""
    import json, sys
    import numpy as np, ufl, dolfinx.fem
    from mpi4py import MPI
    from fabric_fenicsx.fem import mesh as fm
    spec = fm.MeshSpec(**json.loads(sys.argv[1]))
    msh, ct, ft = fm.load_mesh(spec, MPI.COMM_WORLD, cache_dir=sys.argv[2])
    comm = msh.comm
    one = dolfinx.fem.Constant(msh, 1.0)
    total = lambda m: comm.allreduce(dolfinx.fem.assemble_scalar(dolfinx.fem.form(one * m)), op=MPI.SUM)
    ds = ufl.ds(domain=msh, subdomain_data=ft)
    V = dolfinx.fem.FunctionSpace(msh, ufl.VectorElement("Lagrange", msh.ufl_cell(), 1, dim=3))
    dofs = fm.edge_dofs(V, ft, (fm.BOTTOM, fm.TOP))
    n_owned = V.dofmap.index_map.size_local * V.dofmap.index_map_bs
    out = dict(size=comm.size, cells=msh.topology.index_map(2).size_global,
               local_cells=comm.allgather(msh.topology.index_map(2).size_local),
               area=total(ufl.dx(domain=msh)), edges=[total(ds(t)) for t in (1, 2, 3, 4)],
               clamped=comm.allreduce(int(np.count_nonzero(dofs < n_owned)), op=MPI.SUM),
               h_min=fm.min_cell_size(msh))
    if comm.rank == 0:
        print("RESULT " + json.dumps(out))
""")


@pytest.mark.skipif(shutil.which("mpirun") is None, reason="mpirun not available")
def test_two_ranks_see_the_same_mesh(graded, cache):
    msh, _, facet_tags = graded
    V = dolfinx.fem.FunctionSpace(msh, ufl.VectorElement("Lagrange", msh.ufl_cell(), 1, dim=3))
    serial_clamped = len(fm.edge_dofs(V, facet_tags, (fm.BOTTOM, fm.TOP)))
    spec = json.dumps(SPEC.as_dict())
    env = dict(os.environ, PYTHONPATH=f"{REPO}{os.pathsep}{os.environ.get('PYTHONPATH', '')}")
    run = subprocess.run(["mpirun", "--allow-run-as-root", "--oversubscribe", "-n", "2", sys.executable,
                          "-c", _MPI_SCRIPT, spec, str(cache)],
                         capture_output=True, text=True, timeout=300, env=env)
    assert run.returncode == 0, run.stderr[-2000:]
    line = [ln for ln in run.stdout.splitlines() if ln.startswith("RESULT ")]
    assert len(line) == 1, run.stdout
    out = json.loads(line[0][len("RESULT "):])
    assert out["size"] == 2
    assert out["cells"] == msh.topology.index_map(2).size_global
    assert all(n > 0 for n in out["local_cells"])  # really distributed
    assert out["area"] == pytest.approx(SPEC.side**2, rel=1e-12)
    assert out["edges"] == pytest.approx([SPEC.side] * 4, rel=1e-12)
    assert out["clamped"] == serial_clamped
    assert out["h_min"] == pytest.approx(fm.min_cell_size(msh), rel=1e-12)
