"""The floor an explicit membrane step is measured against (used by bench_impact.py).

A minimal explicit step of the same membrane, on the same mesh and quadrature points as the
product's: the displacement gradient at each point (the product's own Jacobians, compiled), the
yarn strains E_i (Eq. 2-3), a linear tension-only yarn law P_i = k (lambda_i - 1)+, the internal
force P : Grad v (Eq. 2-4, 2-5) scattered to the nodes, and the lumped-mass central-difference
update. Everything the product does beyond this (the unit cell's surrogate, damage, damping,
hourglass control, contact, the time-step checks, the energy ledger, DOLFINx's assembly of a
general weak form, Python between the parts) is what the ratio product / floor measures.
"""
from __future__ import annotations

import time

import numpy as np
from numba import njit


def floor_data(membrane):
    """Arrays of the floor step from a :class:`~fabric_fenicsx.fem.membrane.Membrane`: each owned
    cell's nodes, the reference gradients of its shape functions at its quadrature points
    (n_points, nodes per cell, 2), the points' reference areas and the yarn directions."""
    import basix

    from fabric_fenicsx.fem.membrane import yarn_directions

    m = membrane
    cell = m.msh.topology.cell_type.name
    nodes = m.V.dofmap.list.array.reshape(m.n_cells, -1)
    points, _ = basix.make_quadrature(getattr(basix.CellType, cell), m.quadrature_degree)
    element = basix.create_element(basix.ElementFamily.P, getattr(basix.CellType, cell), 1,
                                   basix.LagrangeVariant.equispaced)
    dN = element.tabulate(1, points)[1:, :, :, 0]                      # (2, q, a)
    X = m.V.tabulate_dof_coordinates()[:, :2][nodes]                  # (c, a, 2)
    J = np.einsum("caI,jqa->cqIj", X, dN)
    grad = np.einsum("jqa,cqjI->cqaI", dN, np.linalg.inv(J))         # (c, q, a, 2)
    grad = grad.reshape(-1, grad.shape[2], 2)                         # point-major
    point_nodes = np.repeat(nodes, points.shape[0], axis=0)
    L = np.array(yarn_directions(m.angle))
    return point_nodes.astype(np.int64), np.ascontiguousarray(grad), m.quadrature_weights_detJ.copy(), L


@njit(cache=True, nogil=True)
def _internal_force(point_nodes, grad, weights, L, k, u, f):
    """f = internal force of the linear tension-only yarns at displacement u (both (n, 3))."""
    f[:] = 0.0
    for p in range(point_nodes.shape[0]):
        F = np.zeros((3, 2))
        F[0, 0] = 1.0
        F[1, 1] = 1.0
        for a in range(point_nodes.shape[1]):
            n = point_nodes[p, a]
            for i in range(3):
                F[i, 0] += u[n, i] * grad[p, a, 0]
                F[i, 1] += u[n, i] * grad[p, a, 1]
        for y in range(2):
            a0 = F[0, 0] * L[y, 0] + F[0, 1] * L[y, 1]
            a1 = F[1, 0] * L[y, 0] + F[1, 1] * L[y, 1]
            a2 = F[2, 0] * L[y, 0] + F[2, 1] * L[y, 1]
            lam = np.sqrt(a0 * a0 + a1 * a1 + a2 * a2)
            P = k * max(lam - 1.0, 0.0)
            if P == 0.0:
                continue
            s = weights[p] * P / lam
            for a in range(point_nodes.shape[1]):
                g = grad[p, a, 0] * L[y, 0] + grad[p, a, 1] * L[y, 1]
                n = point_nodes[p, a]
                f[n, 0] += s * a0 * g
                f[n, 1] += s * a1 * g
                f[n, 2] += s * a2 * g


@njit(cache=True, nogil=True)
def _update(u, v, f, inv_mass, dt):
    """Central difference with a lumped mass: v += dt a, u += dt v."""
    for n in range(u.shape[0]):
        for i in range(3):
            v[n, i] -= dt * f[n, i] * inv_mass[n, i]
            u[n, i] += dt * v[n, i]


def floor_seconds_per_step(membrane, mass: np.ndarray, k: float, dt: float, steps: int = 2000) -> float:
    """Wall time (s) of one floor step on ``membrane``'s mesh (serial), measured over ``steps``
    steps of a small transverse velocity (the yarns stretch, so the law is exercised), after one
    call to compile. ``mass``: the lumped mass per owned dof (kg), ``k``: the yarns' modulus
    (N/m)."""
    point_nodes, grad, weights, L = floor_data(membrane)
    n = membrane.V.tabulate_dof_coordinates().shape[0]
    inv_mass = np.zeros((n, 3))
    inv_mass.reshape(-1)[:mass.size] = 1.0 / mass
    u, v, f = np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 3))
    v[:, 2] = 1.0
    _internal_force(point_nodes, grad, weights, L, k, u, f)
    _update(u, v, f, inv_mass, dt)
    t0 = time.perf_counter()
    for _ in range(steps):
        _internal_force(point_nodes, grad, weights, L, k, u, f)
        _update(u, v, f, inv_mass, dt)
    if not np.all(np.isfinite(u)):
        raise FloatingPointError("floor step: non-finite displacement; lower dt")
    return (time.perf_counter() - t0) / steps


if __name__ == "__main__":
    print("benchmarks/floor_step.py: the floor step of bench_impact.py (run that one)")
