"""The per-node arithmetic of the penalty contact, compiled (it runs at every step).

:func:`near_nodes` picks the live nodes inside the projectile's bounding cylinder from the
reference positions and displacements; :func:`penalty_forces` is the force law of
:meth:`fabric_fenicsx.fem.projectile.PenaltyContact.forces` (penalty spring, critically damped
dashpot with the no-adhesion clip, Coulomb friction with the stick cap) for the nodes found
inside the solid, with the sums its ``info`` reports; :func:`count_touching` counts the touching
nodes still attached to a clamped edge. They do what the numpy expressions they replace did, in
one pass and without temporaries; sums are taken node by node.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["near_nodes", "penalty_forces", "count_touching"]


@njit(cache=True, nogil=True)
def near_nodes(X, u, live, ax, ay, radius, z_face, length):
    """Indices of the live nodes whose current position X + u lies strictly inside the
    cylinder of ``radius`` around (ax, ay) between z_face and z_face + length, and their
    positions (k, 3)."""
    n = X.shape[0]
    sel = np.empty(n, np.int64)
    k = 0
    r2max = radius * radius
    for a in range(n):
        if not live[a]:
            continue
        z = X[a, 2] + u[3 * a + 2]
        if not (z > z_face and z < z_face + length):
            continue
        dx = X[a, 0] + u[3 * a] - ax
        dy = X[a, 1] + u[3 * a + 1] - ay
        if dx * dx + dy * dy < r2max:
            sel[k] = a
            k += 1
    sel = sel[:k]
    x = np.empty((k, 3))
    for j in range(k):
        a = sel[j]
        for c in range(3):
            x[j, c] = X[a, c] + u[3 * a + c]
    return sel, x


@njit(cache=True, nogil=True)
def penalty_forces(idx, pen, nrm, v, m, k, vz, damping_ratio, friction, dt, f_nodes, sums):
    """Forces on the nodes ``idx`` (rows of ``f_nodes``, which is zero elsewhere) that
    penetrate ``pen`` along the outward normals ``nrm``: normal force max(k p + c pdot, 0),
    c = 2 zeta sqrt(k m), pdot = -(v - vz e_z) . n; friction -min(mu f_n, m |v_t| / dt) v_t/|v_t|.
    Writes ``sums`` (10,): the penalty energy, friction work and damping work (J), the numbers
    of released and sliding nodes, the sums of the normal and friction force magnitudes (N),
    and the force on the projectile, -sum of the nodal forces (N, x, y, z): the ``info`` and
    ``f_projectile`` of ``PenaltyContact.forces``."""
    e_pen = w_fric = w_damp = fn_sum = ft_sum = 0.0
    released = sliding = 0
    fpx = fpy = fpz = 0.0
    for j in range(idx.size):
        a = idx[j]
        c = 2.0 * damping_ratio * math.sqrt(k[j] * m[j])
        vr0, vr1, vr2 = v[a, 0], v[a, 1], v[a, 2] - vz
        n0, n1, n2 = nrm[j, 0], nrm[j, 1], nrm[j, 2]
        vn = vr0 * n0 + vr1 * n1 + vr2 * n2
        elastic = k[j] * pen[j]
        push = elastic + c * (-vn)
        fn = max(push, 0.0)
        t0, t1, t2 = vr0 - vn * n0, vr1 - vn * n1, vr2 - vn * n2
        speed = math.sqrt(t0 * t0 + t1 * t1 + t2 * t2)
        coulomb = friction * fn
        stick = m[j] * speed / dt
        ft = min(coulomb, stick)
        inv = 1.0 / speed if speed > 0.0 else 1.0
        g0, g1, g2 = -ft * (t0 * inv), -ft * (t1 * inv), -ft * (t2 * inv)   # friction force
        f0 = fn * n0 + g0
        f1 = fn * n1 + g1
        f2 = fn * n2 + g2
        f_nodes[a, 0], f_nodes[a, 1], f_nodes[a, 2] = f0, f1, f2
        fpx -= f0
        fpy -= f1
        fpz -= f2
        e_pen += 0.5 * k[j] * pen[j] * pen[j]
        w_fric += g0 * vr0 + g1 * vr1 + g2 * vr2
        w_damp += (fn - elastic) * vn
        released += push < 0.0
        sliding += coulomb <= stick and ft > 0.0
        fn_sum += fn
        ft_sum += ft
    sums[0], sums[1], sums[2] = e_pen, dt * w_fric, dt * w_damp
    sums[3], sums[4], sums[5], sums[6] = released, sliding, fn_sum, ft_sum
    sums[7], sums[8], sums[9] = fpx, fpy, fpz


@njit(cache=True, nogil=True)
def count_touching(f_nodes, sel, free):
    """How many of the nodes ``sel`` carry a contact force (a non-zero row of ``f_nodes``, one
    row per node of ``sel``) and are not ``free`` (still attached to a clamped edge)."""
    count = 0
    for j in range(sel.size):
        if not free[sel[j]] and (f_nodes[j, 0] != 0.0 or f_nodes[j, 1] != 0.0 or f_nodes[j, 2] != 0.0):
            count += 1
    return count
