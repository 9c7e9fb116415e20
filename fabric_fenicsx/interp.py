"""Vectorised interpolation on uniform grids (the surrogate's look-up kernels).

Two 1D kernels, combined as tensor products: linear (2 taps, C0) and Catmull-Rom cubic
convolution (4 taps, C1, third-order accurate for smooth data). Each returns the tap
offsets and the weights (and their derivatives in the grid coordinate) for a batch of
local coordinates t in [0, 1).
"""

from __future__ import annotations

import numpy as np

ORDERS = {1: "linear", 3: "cubic (Catmull-Rom)"}


def kernel(order: int, t: np.ndarray, derivative: bool = False):
    """Tap offsets (relative to the cell's left node) and weights of shape (taps, npts).

    With ``derivative=True`` also the weights' derivatives d/dt.
    """
    if order == 1:
        offsets = (0, 1)
        w = np.stack((1.0 - t, t))
        dw = np.stack((-np.ones_like(t), np.ones_like(t))) if derivative else None
    elif order == 3:
        offsets = (-1, 0, 1, 2)
        t2 = t * t
        t3 = t2 * t
        w = 0.5 * np.stack((-t3 + 2.0 * t2 - t,
                            3.0 * t3 - 5.0 * t2 + 2.0,
                            -3.0 * t3 + 4.0 * t2 + t,
                            t3 - t2))
        dw = (0.5 * np.stack((-3.0 * t2 + 4.0 * t - 1.0,
                              9.0 * t2 - 10.0 * t,
                              -9.0 * t2 + 8.0 * t + 1.0,
                              3.0 * t2 - 2.0 * t)) if derivative else None)
    else:
        raise ValueError(f"interpolation order must be one of {sorted(ORDERS)}, got {order!r}")
    return (offsets, w, dw) if derivative else (offsets, w)


def locate(x: np.ndarray, lo: float, h: float, n: int, order: int):
    """Cell index i and local coordinate t of points x on the grid lo + k h, k = 0..n-1.

    The cell is chosen so that all taps of ``order`` lie on the grid; the caller keeps x
    inside the range where that holds (ghost nodes for the cubic kernel).
    """
    s = (x - lo) / h
    first = 1 if order == 3 else 0
    last = n - 3 if order == 3 else n - 2
    i = np.clip(np.floor(s).astype(np.int64), first, last)
    return i, s - i


def power_matrix(order: int) -> np.ndarray:
    """M[k, p]: the kernel's weight of tap k is sum_p M[k, p] t^p (same taps as ``kernel``)."""
    if order == 1:
        return np.array([[1.0, -1.0], [0.0, 1.0]])
    if order == 3:
        return 0.5 * np.array([[0.0, -1.0, 2.0, -1.0],
                               [2.0, 0.0, -5.0, 3.0],
                               [0.0, 1.0, 4.0, -3.0],
                               [0.0, 0.0, -1.0, 1.0]])
    raise ValueError(f"interpolation order must be one of {sorted(ORDERS)}, got {order!r}")


def powers(t: np.ndarray, order: int, derivative: bool = False) -> np.ndarray:
    """[1, t, ..., t^order] (npts, order+1), or its derivative d/dt."""
    T = np.empty((t.size, order + 1))
    if not derivative:
        T[:, 0] = 1.0
        for p in range(1, order + 1):
            np.multiply(T[:, p - 1], t, out=T[:, p])
        return T
    T[:, 0] = 0.0
    if order >= 1:
        T[:, 1] = 1.0
    for p in range(2, order + 1):
        T[:, p] = T[:, p - 1] * t * (p / (p - 1))  # p t^(p-1) from (p-1) t^(p-2)
    return T
