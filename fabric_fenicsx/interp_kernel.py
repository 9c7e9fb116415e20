"""The surrogate's hot loops, compiled: evaluate each point's cell polynomial.

A table cell's interpolant is the polynomial sum_pq C_pq t1^p t2^q in the cell's local
coordinates (:func:`fabric_fenicsx.interp.power_matrix`), stored flat, P x P coefficients per
row (row-major in (p, q); P = 4 cubic, P = 2 linear). Evaluating it per point is a gather of
P^2 coefficients per quantity and a few multiply-adds; with numpy that needs (points x
quantities x coefficients) temporaries and costs several times the arithmetic, so these are
loops compiled by numba (cached on disk after the first call).
"""

from __future__ import annotations

import math

from numba import njit


@njit(cache=True, nogil=True)
def _value(coef, k, P, a, b):
    """sum_pq C_pq a^p b^q of the block at coef[k:]."""
    if P == 4:
        b2 = b * b
        b3 = b2 * b
        s0 = coef[k] + coef[k + 1] * b + coef[k + 2] * b2 + coef[k + 3] * b3
        s1 = coef[k + 4] + coef[k + 5] * b + coef[k + 6] * b2 + coef[k + 7] * b3
        s2 = coef[k + 8] + coef[k + 9] * b + coef[k + 10] * b2 + coef[k + 11] * b3
        s3 = coef[k + 12] + coef[k + 13] * b + coef[k + 14] * b2 + coef[k + 15] * b3
        return s0 + a * (s1 + a * (s2 + a * s3))
    return coef[k] + coef[k + 1] * b + a * (coef[k + 2] + coef[k + 3] * b)


@njit(cache=True, nogil=True)
def _slope_a(coef, k, P, a, b):
    """d/da of :func:`_value`."""
    if P == 4:
        b2 = b * b
        b3 = b2 * b
        s1 = coef[k + 4] + coef[k + 5] * b + coef[k + 6] * b2 + coef[k + 7] * b3
        s2 = coef[k + 8] + coef[k + 9] * b + coef[k + 10] * b2 + coef[k + 11] * b3
        s3 = coef[k + 12] + coef[k + 13] * b + coef[k + 14] * b2 + coef[k + 15] * b3
        return s1 + a * (2.0 * s2 + 3.0 * a * s3)
    return coef[k + 2] + coef[k + 3] * b


@njit(cache=True, nogil=True)
def _slope_b(coef, k, P, a, b):
    """d/db of :func:`_value`."""
    if P == 4:
        b2 = b * b
        e0 = coef[k + 1] + 2.0 * coef[k + 2] * b + 3.0 * coef[k + 3] * b2
        e1 = coef[k + 5] + 2.0 * coef[k + 6] * b + 3.0 * coef[k + 7] * b2
        e2 = coef[k + 9] + 2.0 * coef[k + 10] * b + 3.0 * coef[k + 11] * b2
        e3 = coef[k + 13] + 2.0 * coef[k + 14] * b + 3.0 * coef[k + 15] * b2
        return e0 + a * (e1 + a * (e2 + a * e3))
    return coef[k + 1] + a * coef[k + 3]


@njit(cache=True, nogil=True)
def evaluate(coef, P, rows, t1, t2, rows_next, tr, out, d1, d2, derivative, scale):
    """Interpolated values at m points into ``out`` (m, nq), and with ``derivative`` their
    derivatives d/dE1, d/dE2 into ``d1``, ``d2`` (``scale`` = 1/h, h the grid step).

    rows: (m, nq) the row of each point's cell for each quantity asked. With ``tr`` of size
    m, also rows_next (m, nq): the point's value is (1 - tr) v(rows) + tr v(rows_next)
    (linear in between two r nodes).
    """
    m, nq = rows.shape
    blend = tr.size == m
    PP = P * P
    for n in range(m):
        a, b = t1[n], t2[n]
        for c in range(nq):
            k0 = rows[n, c] * PP
            v = _value(coef, k0, P, a, b)
            if derivative:
                g1 = _slope_a(coef, k0, P, a, b)
                g2 = _slope_b(coef, k0, P, a, b)
            if blend:
                w = tr[n]
                k1 = rows_next[n, c] * PP
                v += w * (_value(coef, k1, P, a, b) - v)
                if derivative:
                    g1 += w * (_slope_a(coef, k1, P, a, b) - g1)
                    g2 += w * (_slope_b(coef, k1, P, a, b) - g2)
            out[n, c] = v
            if derivative:
                d1[n, c] = g1 * scale
                d2[n, c] = g2 * scale


@njit(cache=True, nogil=True)
def lookup(E1, E2, a1, a2, intact, damaged, ready_intact, ready_damaged, safe_intact,
           safe_damaged, E_lo, h, first, last, nr, nq, quantities, scaled, dead1, dead2,
           alpha_broken, P, out, flag):
    """Table values at frozen damage (a1, a2) into ``out`` (m, len(quantities)), with the
    damage scaling of :meth:`Surrogate.lookup`, and per point ``flag``: 0 = its damage cannot
    change (its cell's nodes are all below mu_crit), 1 = it may, 2 = a tile its cell needs is
    not built yet (``out`` not set).

    The arithmetic of :meth:`Surrogate._cells`, :meth:`Surrogate._lookup` (value only) and
    :meth:`Surrogate._below_damage`, fused. intact, damaged: the flat coefficient tables;
    ready_*, safe_*: the (nE, nE) cell maps; quantities: their rows (``QUANTITIES`` index);
    scaled: forces, multiplied by alpha_max; dead1, dead2: the value where alpha1 (alpha2) is
    0, NaN for none.
    """
    nE = ready_intact.shape[0]
    PP = P * P
    nc = quantities.size
    for n in range(E1.size):
        s = (E1[n] - E_lo) / h
        i = min(max(int(math.floor(s)), first), last)
        s2 = (E2[n] - E_lo) / h
        j = min(max(int(math.floor(s2)), first), last)
        a, b = s - i, s2 - j
        x1, x2 = a1[n], a2[n]
        amax = max(x1, x2)
        amin = min(x1, x2)
        r = amin / amax if amax > 0.0 else 1.0
        if r < alpha_broken:
            r = 0.0
        cell = i * nE + j
        if r >= 1.0:
            if not ready_intact[i, j]:
                flag[n] = 2
                continue
            k = cell * nq
            for c in range(nc):
                out[n, c] = _value(intact, (k + quantities[c]) * PP, P, a, b)
        else:
            if not ready_damaged[i, j]:
                flag[n] = 2
                continue
            rs = math.sqrt(r) * (nr - 1)
            kr = min(int(rs), nr - 2)
            w = rs - kr
            case = 0 if x1 < x2 else 1
            k = ((case * nE * nE + cell) * nr + kr) * nq
            for c in range(nc):
                v = _value(damaged, (k + quantities[c]) * PP, P, a, b)
                out[n, c] = v + w * (_value(damaged, (k + nq + quantities[c]) * PP, P, a, b) - v)
        for c in range(nc):
            if scaled[c]:
                out[n, c] = out[n, c] * amax if amax > 0.0 else 0.0
            if x1 == 0.0 and not math.isnan(dead1[c]):
                out[n, c] = dead1[c]
            if x2 == 0.0 and not math.isnan(dead2[c]):
                out[n, c] = dead2[c]
        if x1 >= 1.0 and x2 >= 1.0:
            flag[n] = 0 if safe_intact[i, j] else 1
        else:
            flag[n] = 0 if safe_damaged[i, j] else 1
