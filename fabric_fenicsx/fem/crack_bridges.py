"""Crack bridges: the corners through which a yarn crossing a crack of cells is not cut.

A crack of yarn family i is a set of cells whose yarn i is broken. The one-point cell carries
yarn i's stretch between its nodes, and cells that share a node share its displacement, so a
crack cuts the yarns only where its cells share edges. Where two of its cells meet at a corner
only, the intact cells on either side of that corner along the yarn stay joined through it, and
the yarn through the node carries its load across the crack: a bridge. On a grid turned 45
degrees to the yarns a column of cells across the warp meets corner to corner, and one-point
cells there read the warp's stretch from the two nodes on a cell's warp diagonal, so half the
warp chains cross such a column at its corners, uncut (docs/tear_test.md, "What the cut yarns
carry").

A node is a bridge of family i when its cells include broken cells on both sides across the yarn
(the crack passes through it) and intact cells on both sides along the yarn (a yarn passes
through it), sides told by the cells' centres from the node. The bridge is cut by breaking, per
node, the intact cell, on either side, that the yarn through the node enters most directly (the
smallest |across| / |along|; the lower cell number on a tie).
"""
from __future__ import annotations

import numpy as np

__all__ = ["corner_nodes", "bridge_cells"]


def corner_nodes(corners: np.ndarray) -> np.ndarray:
    """The node number of each corner of the cells (reference corners (n, k, 2)): corners that
    coincide within a millionth of the median cell width share a node. Shape (n, k)."""
    corners = np.asarray(corners, float)
    edges = np.linalg.norm(np.roll(corners, -1, axis=1) - corners, axis=-1)
    tol = 1e-6 * float(np.median(edges)) if edges.size else 1.0
    key = np.round(corners.reshape(-1, 2) / tol).astype(np.int64)
    _, node = np.unique(key, axis=0, return_inverse=True)
    return node.reshape(corners.shape[:2])


def bridge_cells(corners: np.ndarray, nodes: np.ndarray, broken: np.ndarray, direction) -> tuple[np.ndarray, np.ndarray]:
    """(cells, via): the intact cells to break so that no node bridges the crack of the cells
    ``broken`` (a mask, removed cells included) along the yarn direction ``direction`` (module
    docstring), one per bridge node, sorted and unique; ``via`` a broken cell at the same node
    (the crack the cell joins). ``nodes`` from :func:`corner_nodes`."""
    corners, nodes = np.asarray(corners, float), np.asarray(nodes, np.int64)
    n_cells, k = nodes.shape
    d = np.asarray(direction, float)
    d = d / np.linalg.norm(d)
    cell = np.repeat(np.arange(n_cells), k)
    node = nodes.ravel()
    offset = corners.mean(axis=1)[cell] - corners.reshape(-1, 2)
    along, across = offset @ d, offset @ np.array([-d[1], d[0]])
    tol = 1e-6 * float(np.median(np.abs(offset))) if offset.size else 0.0
    b = np.asarray(broken, bool)[cell]
    n_nodes = int(node.max(initial=-1)) + 1

    def at_node(mask):
        out = np.zeros(n_nodes, dtype=bool)
        out[node[mask]] = True
        return out

    bridge = (at_node(b & (across > tol)) & at_node(b & (across < -tol))
              & at_node(~b & (along > tol)) & at_node(~b & (along < -tol)))
    far = np.flatnonzero(~b & bridge[node] & (np.abs(along) > tol))
    if far.size == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    slope = np.abs(across[far]) / np.abs(along[far])
    order = np.lexsort((cell[far], slope, node[far]))
    first = far[order[np.r_[True, node[far][order][1:] != node[far][order][:-1]]]]
    via_of_node = np.full(n_nodes, -1, np.int64)
    crack = np.flatnonzero(b & bridge[node])
    via_of_node[node[crack]] = cell[crack]
    cells, keep = np.unique(cell[first], return_index=True)
    return cells, via_of_node[node[first]][keep]
