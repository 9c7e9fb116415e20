"""The compiled passes of the contact search (fabric_fenicsx.fem.projectile) against the code they
replace, bit for bit over random points: the gap and normal of one point (factored out of the
per-point pass), the points inside the solid found in one pass instead of the bounding-cylinder
mask, the gap of its candidates and numpy's selections, and the finiteness checks of the inputs."""
import math

import numpy as np
import pytest
from numba import njit

from fabric_fenicsx.fem.projectile import (Projectile, _all_finite, _all_finite_positive,
                                           _gap_and_normal, _in_cylinder, _inside)


@njit(cache=False)
def _previous_gap_and_normal(x, z_face, R, half, fillet, ax, ay, gap, normal):
    """The per-point pass as it was before its body became a function of one point."""
    for p in range(x.shape[0]):
        dx, dy = x[p, 0] - ax, x[p, 1] - ay
        r = math.hypot(dx, dy)
        hm = x[p, 2] - z_face - half
        front = hm < 0.0
        rr = fillet if front else 0.0
        qx = r - R + rr
        qy = abs(hm) - half + rr
        mx, my = max(qx, 0.0), max(qy, 0.0)
        mlen = math.hypot(mx, my)
        if mlen > 0.0:
            gap[p] = mlen - rr
            gx, gy = mx / mlen, my / mlen
        else:
            gap[p] = max(qx, qy) - rr
            side_in = qx > qy + 1e-12 * (R + half)
            gx, gy = (1.0, 0.0) if side_in else (0.0, 1.0)
        er_x, er_y = (1.0, 0.0) if r == 0.0 else (dx / r, dy / r)
        normal[p, 0], normal[p, 1] = gx * er_x, gx * er_y
        normal[p, 2] = -gy if front else gy


def same(x, y):
    x, y = np.asarray(x), np.asarray(y)
    return x.dtype == y.dtype and x.shape == y.shape and x.tobytes() == y.tobytes()


def points(rng, n, proj, z_face):
    """Points around the solid: inside, outside, on the axis, on the bounds of the bounding
    cylinder and at coordinates of zero of both signs."""
    R, L = proj.radius, proj.length
    ax, ay = proj.axis_xy
    x = np.column_stack((rng.uniform(ax - 1.3 * R, ax + 1.3 * R, n), rng.uniform(ay - 1.3 * R, ay + 1.3 * R, n),
                         rng.uniform(z_face - 0.2 * L, z_face + 1.2 * L, n)))
    near_face = rng.random(n) < 0.4   # most contact is a few um below the face
    x[near_face, 2] = z_face + rng.uniform(-5e-6, 2e-5, int(near_face.sum()))
    for column, values in ((0, (ax, 0.0, -0.0)), (1, (ay, 0.0, -0.0)),
                           (2, (z_face, z_face + L, 0.0, -0.0))):
        for value in values:
            x[rng.random(n) < 0.03, column] = value
    return x


@pytest.mark.parametrize("fillet, axis, z_face", [(0.0, (0.0, 0.0), 0.0), (2e-3, (0.001, -0.002), -1e-3),
                                                  (0.8e-3, (0.0, 0.0), -0.0)])
def test_inside_equals_the_numpy_selections(fillet, axis, z_face):
    rng = np.random.default_rng(7)
    proj = Projectile(fillet=fillet, axis_xy=axis)
    R, half, L = proj.radius, 0.5 * proj.length, proj.length
    for n in (0, 1, 9, 3000):
        x = points(rng, n, proj, z_face)
        # before: the bounding-cylinder mask, the gap of its points, numpy's selections
        mask = np.empty(n, bool)
        _in_cylinder(x, z_face, z_face + L, axis[0], axis[1], R**2, mask)
        idx = np.flatnonzero(mask)
        gap, nrm = np.empty(idx.size), np.empty((idx.size, 3))
        _previous_gap_and_normal(np.ascontiguousarray(x[idx]), z_face, R, half, fillet, *axis, gap, nrm)
        inside = gap < 0.0
        idx, pen, nrm = idx[inside], -gap[inside], nrm[inside]
        # now: one pass
        k, p, normal = np.empty(n, np.int64), np.empty(n), np.empty((n, 3))
        m, deepest = _inside(x, z_face, L, R, half, fillet, axis[0], axis[1], R**2, k, p, normal)
        assert m == idx.size and (n < 3000 or 0 < m < n)
        assert same(k[:m], idx) and same(p[:m], pen) and same(normal[:m], nrm)
        assert deepest == (pen.max() if m else -np.inf)


@pytest.mark.parametrize("fillet", [0.0, 2e-3])
def test_gap_and_normal_of_one_point_equals_the_previous_pass(fillet):
    rng = np.random.default_rng(8)
    proj = Projectile(fillet=fillet)
    for n in (0, 1, 2000):
        x = points(rng, n, proj, 0.0)
        gap, normal = proj.gap_and_normal(x, 0.0)
        g, nrm = np.empty(n), np.empty((n, 3))
        _previous_gap_and_normal(x, 0.0, proj.radius, 0.5 * proj.length, fillet, 0.0, 0.0, g, nrm)
        assert same(gap, g) and same(normal, nrm)
        assert n < 2000 or (np.any(gap < 0) and np.any(gap > 0))
    g1, n1 = np.empty(1), np.empty((1, 3))
    _gap_and_normal(np.zeros((1, 3)), 0.0, proj.radius, 0.5 * proj.length, fillet, 0.0, 0.0, g1, n1)
    assert g1[0] <= 0.0   # on the axis, at the face


def test_finiteness_checks_equal_numpy():
    rng = np.random.default_rng(9)
    for shape in ((0, 3), (1, 3), (7, 3), (400, 3), (400,)):
        for bad in (None, np.nan, np.inf, -np.inf, 0.0, -0.0, -1e-300):
            a = rng.uniform(1e-9, 1.0, shape)
            if bad is not None and a.size:
                a.flat[rng.integers(a.size)] = bad
            views = [a, a[::2], a.T] if a.ndim == 2 else [a, a[::3], np.broadcast_to(a[:1], a.shape)]
            for view in views:
                assert _all_finite(view) == bool(np.isfinite(view).all())
                assert _all_finite_positive(view) == bool((np.isfinite(view) & (view > 0.0)).all())
