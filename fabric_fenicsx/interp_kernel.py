"""The surrogate's hot loop, compiled: evaluate each point's cell polynomial.

A table cell's interpolant is the polynomial sum_pq C_pq t1^p t2^q in the cell's local
coordinates (:func:`fabric_fenicsx.interp.power_matrix`). Evaluating it per point is a
gather of (order+1)^2 coefficients per quantity and a few multiply-adds; with numpy that
needs (points x quantities x coefficients) temporaries and costs several times the
arithmetic, so it is one loop here, compiled by numba (cached on disk after the first call).
"""

from __future__ import annotations

from numba import njit


@njit(cache=True, nogil=True)
def evaluate(coef, P, rows, t1, t2, rows_next, tr, out, d1, d2, derivative, scale):
    """Interpolated values at m points into ``out`` (m, nq), and with ``derivative`` their
    derivatives d/dE1, d/dE2 into ``d1``, ``d2`` (``scale`` = 1/h, h the grid step).

    coef: flat cell polynomials, P x P per row (row-major in (p, q)), P = 4 (cubic) or 2
    (linear); rows: (m, nq) the row of each point's cell for each quantity asked. With
    ``tr`` of size m, also rows_next (m, nq): the point's value is (1 - tr) v(rows) +
    tr v(rows_next) (linear in between two r nodes, so the coefficients are blended).
    """
    m, nq = rows.shape
    blend = tr.size == m
    PP = P * P
    for n in range(m):
        a, b = t1[n], t2[n]
        b2 = b * b
        b3 = b2 * b
        a2 = a * a
        a3 = a2 * a
        for c in range(nq):
            # row sums s_p = sum_q C_pq b^q and e_p = ds_p/db, blended between the r nodes
            # (helper functions would not be inlined: they cost 2 x here)
            k = rows[n, c] * PP
            if P == 4:
                s0 = coef[k] + coef[k + 1] * b + coef[k + 2] * b2 + coef[k + 3] * b3
                s1 = coef[k + 4] + coef[k + 5] * b + coef[k + 6] * b2 + coef[k + 7] * b3
                s2 = coef[k + 8] + coef[k + 9] * b + coef[k + 10] * b2 + coef[k + 11] * b3
                s3 = coef[k + 12] + coef[k + 13] * b + coef[k + 14] * b2 + coef[k + 15] * b3
                e0 = coef[k + 1] + 2.0 * coef[k + 2] * b + 3.0 * coef[k + 3] * b2
                e1 = coef[k + 5] + 2.0 * coef[k + 6] * b + 3.0 * coef[k + 7] * b2
                e2 = coef[k + 9] + 2.0 * coef[k + 10] * b + 3.0 * coef[k + 11] * b2
                e3 = coef[k + 13] + 2.0 * coef[k + 14] * b + 3.0 * coef[k + 15] * b2
                if blend:
                    w = tr[n]
                    k = rows_next[n, c] * PP
                    s0 += w * (coef[k] + coef[k + 1] * b + coef[k + 2] * b2 + coef[k + 3] * b3 - s0)
                    s1 += w * (coef[k + 4] + coef[k + 5] * b + coef[k + 6] * b2 + coef[k + 7] * b3 - s1)
                    s2 += w * (coef[k + 8] + coef[k + 9] * b + coef[k + 10] * b2 + coef[k + 11] * b3 - s2)
                    s3 += w * (coef[k + 12] + coef[k + 13] * b + coef[k + 14] * b2 + coef[k + 15] * b3 - s3)
                    e0 += w * (coef[k + 1] + 2.0 * coef[k + 2] * b + 3.0 * coef[k + 3] * b2 - e0)
                    e1 += w * (coef[k + 5] + 2.0 * coef[k + 6] * b + 3.0 * coef[k + 7] * b2 - e1)
                    e2 += w * (coef[k + 9] + 2.0 * coef[k + 10] * b + 3.0 * coef[k + 11] * b2 - e2)
                    e3 += w * (coef[k + 13] + 2.0 * coef[k + 14] * b + 3.0 * coef[k + 15] * b2 - e3)
            else:  # P == 2, bilinear
                s0 = coef[k] + coef[k + 1] * b
                s1 = coef[k + 2] + coef[k + 3] * b
                e0, e1 = coef[k + 1], coef[k + 3]
                if blend:
                    w = tr[n]
                    k = rows_next[n, c] * PP
                    s0 += w * (coef[k] + coef[k + 1] * b - s0)
                    s1 += w * (coef[k + 2] + coef[k + 3] * b - s1)
                    e0 += w * (coef[k + 1] - e0)
                    e1 += w * (coef[k + 3] - e1)
                s2 = s3 = e2 = e3 = 0.0
            out[n, c] = s0 + a * s1 + a2 * s2 + a3 * s3
            if derivative:
                d1[n, c] = (s1 + 2.0 * a * s2 + 3.0 * a2 * s3) * scale
                d2[n, c] = (e0 + a * e1 + a2 * e2 + a3 * e3) * scale
