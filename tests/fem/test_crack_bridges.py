"""Crack bridges (fabric_fenicsx.fem.crack_bridges): a crack of cells that meet corner to corner
leaves the yarns joined through those corners until the rule breaks a cell at each."""

import math

import numpy as np
import pytest
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components

from fabric_fenicsx.fem.crack_bridges import bridge_cells, corner_nodes

WARP = (1.0, 0.0)


def _grid(n: int, h: float, degrees: float = 0.0) -> np.ndarray:
    """Corners (n*n, 4, 2) of an n x n grid of squares of side h turned ``degrees`` about the
    origin; cell (i, j) is number i * n + j."""
    i, j = (a.ravel() for a in np.meshgrid(np.arange(n), np.arange(n), indexing="ij"))
    square = np.stack([np.column_stack((i + a, j + b)) for a, b in ((0, 0), (1, 0), (1, 1), (0, 1))], axis=1) * h
    c, s = math.cos(math.radians(degrees)), math.sin(math.radians(degrees))
    return square @ np.array([[c, s], [-s, c]])


def _joined_across(corners: np.ndarray, nodes: np.ndarray, broken: np.ndarray) -> bool:
    """Whether an intact cell left of x = 0 shares a chain of nodes with one right of it."""
    intact = np.flatnonzero(~broken)
    incidence = csr_matrix((np.ones(4 * intact.size), (np.repeat(np.arange(intact.size), 4), nodes[intact].ravel())))
    _, label = connected_components(incidence @ incidence.T, directed=False)
    x = corners[intact].mean(axis=1)[:, 0]
    return bool(np.intersect1d(label[x < 0], label[x > 0]).size)


def test_coinciding_corners_share_a_node():
    nodes = corner_nodes(_grid(3, 0.002))
    assert nodes.shape == (9, 4)
    assert np.unique(nodes).size == 16
    assert nodes[0, 2] == nodes[4, 0] == nodes[1, 1] == nodes[3, 3]   # the corner (1, 1) of four cells


def test_a_column_of_cells_along_the_grid_cuts_the_warp_without_bridges():
    corners = _grid(8, 0.002)
    corners[..., 0] -= 0.007                      # the column i = 3 straddles x = 0
    nodes = corner_nodes(corners)
    broken = np.zeros(64, dtype=bool)
    broken[3 * 8:3 * 8 + 6] = True                # a crack from the bottom edge, its tip inside
    cells, _ = bridge_cells(corners, nodes, broken, WARP)
    assert cells.size == 0
    full = broken.copy()
    full[3 * 8:4 * 8] = True
    assert not _joined_across(corners, nodes, full)


def test_on_a_grid_turned_45_degrees_a_column_across_the_warp_is_bridged_at_each_corner_until_cut():
    n = 8
    corners = _grid(n, 0.002, 45.0)
    nodes = corner_nodes(corners)
    broken = np.zeros(n * n, dtype=bool)
    broken[[k * n + k for k in range(n)]] = True          # cells (k, k): centres on x = 0
    assert _joined_across(corners, nodes, broken)         # the warp passes the corners (k, k)
    cells, via = bridge_cells(corners, nodes, broken, WARP)
    assert cells.size == n - 1                            # one per corner the column's cells share
    shared = [set(nodes[c]) & set(nodes[v]) for c, v in zip(cells, via)]
    assert all(shared) and broken[via].all()         # each beside a crack cell at its corner
    centres = corners[cells].mean(axis=1) / (0.002 / math.sqrt(2))   # in half diagonals
    assert np.allclose(np.abs(centres[:, 0]), 1.0) and np.allclose(centres[:, 1], 2 * np.arange(1, n))
    cut = broken.copy()
    cut[cells] = True
    assert not _joined_across(corners, nodes, cut)
    assert bridge_cells(corners, nodes, cut, WARP)[0].size == 0
    # along the fill the column is a line of cells joined corner to corner: no fill yarn crosses it
    assert bridge_cells(corners, nodes, broken, (0.0, 1.0))[0].size == 0


def test_the_del_zone_cuts_its_cracks_bridges_and_the_other_rules_do_not():
    from fabric_fenicsx.fem.crack_rules import crack_rule_on_cells
    from fabric_fenicsx.fem.yarn_crack import TIP
    from fabric_fenicsx.material.fabric import zylon_as

    n = 8
    corners = _grid(n, 0.002, 45.0)
    column = np.array([k * n + k for k in range(n)])
    live = np.ones(n * n, dtype=bool)
    for name, cuts in (("del_zone", True), ("shear_lag", False)):
        rule = crack_rule_on_cells(name, corners, (np.array(WARP), np.array([0.0, 1.0])), zylon_as())
        rule.add_crack(column, 0, 0.0)
        if not cuts:
            assert rule.nodes is None
            continue
        rule._cut_bridges(0, live)
        joined = np.flatnonzero(rule.kind[0] == TIP)
        assert joined.size == n - 1 and rule.summary()["warp"]["bridges_cut"] == n - 1
        assert np.all(rule.line[0, joined] == 0.0)


@pytest.mark.parametrize("family", ["structured45", "aligned"])
def test_the_tear_tests_slit_cuts_every_warp_across_its_span(family):
    from fabric_fenicsx.studies.tear import TearSetup, slit_cells

    setup = TearSetup(side=0.06, slit=0.012, notch="centre")
    if family == "aligned":
        corners = _grid(15, 0.004)
        corners -= 0.03
    else:
        corners = _grid(22, 0.004, 45.0)
        corners[..., 1] -= 22 * 0.004 / math.sqrt(2) - 0.0011    # a corner 1.1 mm above the middle
    nodes = corner_nodes(corners)
    slit = np.zeros(corners.shape[0], dtype=bool)
    slit[slit_cells(corners, setup)] = True
    y = corners.mean(axis=1)[:, 1]
    inside = np.abs(y) < 0.004                            # cells whose warp the slit cuts
    keep = inside | slit
    sub = corners[keep]
    assert not _joined_across(sub, corner_nodes(sub), slit[keep])
