"""Yarn strains at the quadrature points by a compiled pass over the points (Eq. 2-1, 2-3).

On the membrane's P1 element the yarn tangent a_i = F L_i of a point is linear in its cell's
nodal displacements: a_i = L_i + sum_a u_a (Grad N_a . L_i), with Grad N_a the reference
gradients of the shape functions at the point, fixed by the reference mesh. :class:`PointStrains`
tabulates g_ai = Grad N_a . L_i once and evaluates E_i = (a_i . a_i - 1) / 2 for every owned
point in one compiled loop: the same quantity as the UFL expression of
:class:`~fabric_fenicsx.fem.membrane.Membrane` (tests compare them to round-off), without
DOLFINx's per-call packing of an Expression.
"""
from __future__ import annotations

import basix
import numpy as np
from numba import njit

__all__ = ["PointStrains"]


class PointStrains:
    """E1, E2 at the owned quadrature points of a P1 membrane, cell-major.

    nodes: (n_cells, nodes per cell) local node indices of the displacement space; X: their
    reference coordinates (n_cells, nodes per cell, 2); cell: ``"quadrilateral"`` or
    ``"triangle"``; points: reference quadrature points (q, 2); L1, L2: yarn directions."""

    def __init__(self, nodes: np.ndarray, X: np.ndarray, cell: str, points: np.ndarray,
                 L1: np.ndarray, L2: np.ndarray):
        element = basix.create_element(basix.ElementFamily.P, getattr(basix.CellType, cell), 1,
                                       basix.LagrangeVariant.equispaced)
        dN = element.tabulate(1, points)[1:, :, :, 0]                   # (2, q, a): d/dxi_j
        J = np.einsum("caI,jqa->cqIj", X, dN)                           # dX_I / dxi_j
        grad = np.einsum("jqa,cqjI->cqaI", dN, np.linalg.inv(J))        # Grad N_a, (c, q, a, 2)
        L = np.stack((L1, L2))                                          # (i, I)
        g = np.einsum("cqaI,iI->cqia", grad, L)                         # (c, q, i, a)
        self.g = np.ascontiguousarray(g.reshape(-1, 2, nodes.shape[1]))
        self.point_nodes = np.ascontiguousarray(np.repeat(nodes, points.shape[0], axis=0), dtype=np.int64)
        self.L = np.ascontiguousarray(np.concatenate((L, np.zeros((2, 1))), axis=1))  # 3D

    def __call__(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(E1, E2) for the local displacement dofs ``u`` (owned and ghost, 3 per node),
        fresh arrays."""
        n = self.point_nodes.shape[0]
        E1, E2 = np.empty(n), np.empty(n)
        _yarn_strains(self.point_nodes, self.g, self.L, u.reshape(-1, 3), E1, E2)
        return E1, E2


@njit(cache=True, nogil=True)
def _yarn_strains(point_nodes, g, L, u, E1, E2):
    """E_i = (a_i . a_i - 1) / 2 with a_i = L_i + sum_a u_a g_ai at every point."""
    for p in range(point_nodes.shape[0]):
        for i in range(2):
            a0, a1, a2 = L[i, 0], L[i, 1], L[i, 2]
            for a in range(point_nodes.shape[1]):
                n = point_nodes[p, a]
                w = g[p, i, a]
                a0 += w * u[n, 0]
                a1 += w * u[n, 1]
                a2 += w * u[n, 2]
            e = 0.5 * (a0 * a0 + a1 * a1 + a2 * a2 - 1.0)
            if i == 0:
                E1[p] = e
            else:
                E2[p] = e
