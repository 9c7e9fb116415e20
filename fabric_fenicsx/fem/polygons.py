"""Areas and centroids of the cells as polygons (reference corners in perimeter order): the
shoelace formula, for the removal log, the time step's sizing and the failure rules."""
from __future__ import annotations

import numpy as np

__all__ = ["polygon_areas", "polygon_centroids"]


def polygon_areas(corners: np.ndarray) -> np.ndarray:
    """Areas of simple polygons (corners in perimeter order, either sense), shape (n, k, 2) ->
    (n,): the shoelace formula."""
    p, q = corners, np.roll(corners, -1, axis=1)
    return 0.5 * np.abs((p[..., 0] * q[..., 1] - q[..., 0] * p[..., 1]).sum(axis=1))


def polygon_centroids(corners: np.ndarray) -> np.ndarray:
    """Area centroids of simple polygons (corners in perimeter order, either sense), shape
    (n, k, 2) -> (n, 2): the shoelace formula, c = sum (p_j + p_j+1) (p_j x p_j+1) / (6 A)."""
    p, q = corners, np.roll(corners, -1, axis=1)
    cross = p[..., 0] * q[..., 1] - q[..., 0] * p[..., 1]
    area = 0.5 * cross.sum(axis=1)
    return ((p + q) * cross[..., None]).sum(axis=1) / (6.0 * area[:, None])
