"""Removal of cells in an impact run: which cells go (deletion, erosion) and which fabric is
still attached to a clamped edge.

* **Deletion** (Table 2): a cell whose quadrature points all have SDV1 = 0 (both yarns broken,
  :attr:`~fabric_fenicsx.material.contract.DamageState.removed`).
* **Erosion**: a live cell with a yarn-direction Green strain above ``material.erosion_strain``
  at any point (no unit-cell state is there; docs/impact_model.md).

A removed cell carries no force from any weak-form term (the membrane's live-cell mask) and no
material stress (the material's :meth:`remove`), and takes part in contact only through its
live neighbours. Pieces cut loose from every clamped edge (a plug) are tracked as free nodes.
Every removed cell is recorded when it goes (rule, time, both yarns' integrity and strain, where
it is and its chords along the yarns: :mod:`.removal_log`).
"""
from __future__ import annotations

import math

import numpy as np
from dolfinx import fem
from mpi4py import MPI
from numba import njit
from petsc4py import PETSc

from fabric_fenicsx.fem.membrane import yarn_directions
from fabric_fenicsx.fem.polygons import polygon_centroids
from fabric_fenicsx.impact.output import cell_corners
from fabric_fenicsx.impact.removal_log import REMOVED_CELL_COLUMNS, chords_through_centroid, removal_records

__all__ = ["CellRemoval"]


class CellRemoval:
    """Live, deleted and eroded cells of this rank, and the live and free nodes.

    membrane: the :class:`~fabric_fenicsx.fem.membrane.Membrane`; material: its
    ``QuadratureMaterial``; clamped_blocks: local nodes (owned and ghost) of the clamped edges;
    erosion_strain: None for no removal at all (damage off)."""

    def __init__(self, membrane, material, clamped_blocks: np.ndarray, erosion_strain: float | None):
        self.m, self.material = membrane, material
        self.npc = membrane.n_points_per_cell
        self.erosion_strain = erosion_strain
        self.clamped_blocks = clamped_blocks
        n_cells, self.n_nodes = membrane.n_cells, membrane.n_owned_nodes
        self.live_cells = np.ones(n_cells, dtype=bool)
        self.deleted_cells = np.zeros(n_cells, dtype=bool)
        self.eroded_cells = np.zeros(n_cells, dtype=bool)
        self.live_nodes = np.ones(self.n_nodes, dtype=bool)
        self.free_nodes = np.zeros(self.n_nodes, dtype=bool)   # in pieces cut loose (plugs)
        self._node_flags = None
        self.records = np.zeros((0, len(REMOVED_CELL_COLUMNS)))
        """One row per cell this rank removed (:data:`~.removal_log.REMOVED_CELL_COLUMNS`)."""
        self._reported = 0
        self._geometry = None
        self._selected = None   # the cell index buffers of select

    def select(self) -> tuple[np.ndarray, np.ndarray]:
        """Cells to delete (all points SDV1 = 0) and to erode (a yarn strain beyond the
        erosion strain) now, among the live cells of this rank."""
        if self.erosion_strain is None:
            return np.zeros(0, np.int64), np.zeros(0, np.int64)
        state, (E1, E2) = self.material.state, self.material.strains
        if self._selected is None:
            self._selected = tuple(np.empty(self.live_cells.size, np.int64) for _ in range(2))
        delete, erode = self._selected
        n_delete, n_erode = _select(np.asarray(state.alpha1), np.asarray(state.alpha2), np.asarray(E1),
                                    np.asarray(E2), self.live_cells, self.npc, self.erosion_strain,
                                    delete, erode)
        return delete[:n_delete].copy(), erode[:n_erode].copy()

    def node_extremes(self, X: np.ndarray, u: np.ndarray, axis_xy, radius: float,
                      z_front: float) -> tuple[float, int, float]:
        """One pass over this rank's nodes (reference positions ``X``, displacements ``u``) for
        the end and blow-up tests of a step: the highest z of a live node (-inf if none), the
        attached live nodes inside ``radius`` of ``axis_xy`` below ``z_front``, and the largest
        |u_i| of the attached nodes (:func:`_node_extremes`)."""
        return _node_extremes(X, u, self.live_nodes, self.free_nodes, axis_xy[0], axis_xy[1],
                              radius, z_front)

    def remove(self, delete: np.ndarray, erode: np.ndarray, time: float = float("nan")) -> None:
        """Take the cells out of the material and of every weak-form term, recording each
        (:attr:`records`) with the state that removed it at ``time`` (s; t_n of the step). Local:
        a rank calls it only when it removes cells; :meth:`update_nodes`, which every rank calls
        after any rank removed cells, shares the live-cell mask with the other ranks."""
        cells = np.concatenate((delete, erode))
        self._record(time, delete, erode)
        self.live_cells[cells] = False
        self.deleted_cells[delete] = True
        self.eroded_cells[erode] = True
        points = (cells[:, None] * self.npc + np.arange(self.npc)).ravel()
        self.material.remove(points)
        self.m.remove_cells(cells, share=False)

    def _record(self, time: float, delete: np.ndarray, erode: np.ndarray) -> None:
        """Append the removed cells' rows (:func:`~.removal_log.removal_records`) before the
        material forgets their state."""
        if self._geometry is None:
            m = self.m
            corners = m.V.tabulate_dof_coordinates()[cell_corners(m.V, m.n_cells), :2]
            centroids = polygon_centroids(corners)
            chords = np.column_stack([chords_through_centroid(corners, d, centroids)
                                      for d in yarn_directions(m.angle)])
            start = m.msh.topology.index_map(2).local_range[0]
            self._geometry = (centroids, chords, start + np.arange(m.n_cells))
        centroids, chords, global_cells = self._geometry
        cells = np.concatenate((delete, erode)).astype(np.int64)
        rule = np.concatenate((np.zeros(len(delete)), np.ones(len(erode))))
        state = self.material.state
        rows = removal_records(time, rule, cells, global_cells, state.alpha1, state.alpha2,
                               *self.material.strains, self.npc, centroids, chords)
        self.records = np.concatenate((self.records, rows))

    def new_records(self) -> np.ndarray:
        """The rows recorded since the last call (this rank's)."""
        rows = self.records[self._reported:]
        self._reported = self.records.shape[0]
        return rows

    def _exchange_nodes(self, marked: np.ndarray) -> np.ndarray:
        """A node marked on any rank, marked on every rank that holds it (owned or ghost;
        collective): ``marked`` and the result are over this rank's local nodes."""
        f = self._node_flags
        f.x.array[:] = 0.0
        f.x.array[0::3] = marked
        f.vector.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        f.vector.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
        return f.x.array[0::3] > 0.0

    def update_nodes(self) -> None:
        """After cells were removed (collective): ``live_nodes``, the owned nodes touching at
        least one live cell on any rank, and ``free_nodes``, the live nodes in pieces of fabric
        cut loose from every clamped edge.

        A node is attached if a chain of live cells joins it to a clamped node: propagated
        cell by cell on each rank, exchanged across ranks through the ghost nodes, until no
        rank finds a new attached node. A piece that is not attached (a plug punched out by
        the projectile) is still simulated, but it neither keeps a perforation from ending
        the run nor counts as a blow-up when it flies away with the projectile."""
        m = self.m
        m.share_live_cells()
        if self._node_flags is None:
            self._node_flags = fem.Function(m.V)
            self._cell_nodes = m.V.dofmap.list.array.reshape(-1, m.V.dofmap.cell_dofs(0).size)[:m.n_cells]
        cells = self._cell_nodes[self.live_cells]
        n_local = self._node_flags.x.array.size // 3
        touched = np.zeros(n_local, dtype=bool)
        touched[cells.ravel()] = True
        self.live_nodes = self._exchange_nodes(touched)[:self.n_nodes]
        attached = np.zeros(n_local, dtype=bool)
        attached[self.clamped_blocks] = True
        while True:
            _attach(cells, attached)   # on this rank
            merged = self._exchange_nodes(attached)
            new = m.comm.allreduce(int(np.count_nonzero(merged & ~attached)), op=MPI.SUM)
            attached = merged
            if new == 0:
                break
        self.free_nodes = self.live_nodes & ~attached[:self.n_nodes]


@njit(cache=True, nogil=True)
def _node_extremes(X, u, live, free, ax, ay, radius, z_front):
    """One pass over this rank's nodes for the end and blow-up tests of an impact step:
    (highest z of a live node, -inf if none; live nodes still attached to a clamped edge
    (not ``free``) inside the projectile's radius and below ``z_front``, the height of its back
    face; largest |u_i| of those attached nodes)."""
    z_max = -math.inf
    front = 0
    moved = 0.0
    r2max = radius * radius
    for a in range(X.shape[0]):
        if not live[a]:
            continue
        z = X[a, 2] + u[3 * a + 2]
        z_max = max(z_max, z)
        if free[a]:
            continue
        dx = X[a, 0] + u[3 * a] - ax
        dy = X[a, 1] + u[3 * a + 1] - ay
        if dx * dx + dy * dy < r2max and z < z_front:
            front += 1
        for c in range(3):
            moved = max(moved, abs(u[3 * a + c]))
    return z_max, front, moved


@njit(cache=True, nogil=True)
def _select(alpha1, alpha2, E1, E2, live_cells, npc, erosion_strain, delete, erode):
    """One pass over the live cells for :meth:`CellRemoval.select`: into ``delete`` the cells
    whose points all have both yarns broken (alpha1 <= 0 and alpha2 <= 0), into ``erode`` the
    others with a yarn strain above ``erosion_strain`` at a point (none if a strain there is
    NaN, as for the NaN-propagating maximum); returns how many of each, in increasing order."""
    n_delete = n_erode = 0
    for c in range(live_cells.size):
        if not live_cells[c]:
            continue
        dead, over, nan = True, False, False
        for p in range(c * npc, (c + 1) * npc):
            dead = dead and alpha1[p] <= 0.0 and alpha2[p] <= 0.0
            if math.isnan(E1[p]) or math.isnan(E2[p]):
                nan = True
            elif E1[p] > erosion_strain or E2[p] > erosion_strain:
                over = True
        if dead:
            delete[n_delete] = c
            n_delete += 1
        elif over and not nan:
            erode[n_erode] = c
            n_erode += 1
    return n_delete, n_erode


@njit(cache=True, nogil=True)
def _attach(cells, attached):
    """Grow the node mask ``attached`` in place to its closure over the cells ``cells`` (rows of
    node indices): every node of a cell with an attached node is attached, until no cell adds
    one (the smallest such set containing the given one: it does not depend on the order in
    which the cells are visited)."""
    grown = True
    while grown:
        grown = False
        for c in range(cells.shape[0]):
            touching = False
            for a in range(cells.shape[1]):
                touching = touching or attached[cells[c, a]]
            if not touching:
                continue
            for a in range(cells.shape[1]):
                if not attached[cells[c, a]]:
                    attached[cells[c, a]] = True
                    grown = True
