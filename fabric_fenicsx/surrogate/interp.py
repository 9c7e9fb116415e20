"""Interpolation on uniform grids (the surrogate's look-up kernels).

Two 1D kernels, combined as tensor products: linear (2 taps, C0) and Catmull-Rom cubic
convolution (4 taps, C1, third-order accurate for smooth data). A kernel's weights are
polynomials in the local coordinate t in [0, 1) of a grid cell (:func:`power_matrix`), so a
table cell's interpolant is one polynomial, evaluated by :mod:`fabric_fenicsx.surrogate.kernels.interp`.
"""

from __future__ import annotations

import numpy as np

ORDERS = {1: "linear", 3: "cubic (Catmull-Rom)"}
TAPS = {1: (0, 1), 3: (-1, 0, 1, 2)}
"""Tap offsets of each kernel, relative to the cell's left node."""


def cell_range(order: int, n: int) -> tuple[int, int]:
    """First and last cell index on a grid of n nodes whose taps all lie on the grid."""
    taps = TAPS[order]
    return -taps[0], n - 1 - taps[-1]


def locate(x: np.ndarray, lo: float, h: float, n: int, order: int):
    """Cell index i and local coordinate t of points x on the grid lo + k h, k = 0..n-1.

    The cell is chosen so that all taps of ``order`` lie on the grid; the caller keeps x
    inside the range where that holds (ghost nodes for the cubic kernel).
    """
    s = (x - lo) / h
    first, last = cell_range(order, n)
    i = np.clip(np.floor(s).astype(np.int64), first, last)
    return i, s - i


def power_matrix(order: int) -> np.ndarray:
    """M[k, p]: the kernel's weight of tap k (``TAPS[order][k]``) is sum_p M[k, p] t^p.

    Catmull-Rom: w = ((-t^3 + 2t^2 - t), (3t^3 - 5t^2 + 2), (-3t^3 + 4t^2 + t), (t^3 - t^2)) / 2;
    linear: w = (1 - t, t)."""
    if order == 1:
        return np.array([[1.0, -1.0], [0.0, 1.0]])
    if order == 3:
        return 0.5 * np.array([[0.0, -1.0, 2.0, -1.0],
                               [2.0, 0.0, -5.0, 3.0],
                               [0.0, 1.0, 4.0, -3.0],
                               [0.0, 0.0, -1.0, 1.0]])
    raise ValueError(f"interpolation order must be one of {sorted(ORDERS)}, got {order!r}")
