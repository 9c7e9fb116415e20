"""The surrogate's look-up, compiled: evaluate each point's cell polynomial (values, and
derivatives for the time-step check), and check the inputs in one pass.

A table cell's interpolant is the polynomial sum_pq C_pq t1^p t2^q in the cell's local
coordinates (:func:`fabric_fenicsx.surrogate.interp.power_matrix`), stored flat, P x P coefficients per
row (row-major in (p, q); P = 4 cubic, P = 2 linear). Evaluating it per point is a gather of
P^2 coefficients per quantity and a few multiply-adds; with numpy that needs (points x
quantities x coefficients) temporaries and costs several times the arithmetic, so these are
loops compiled by numba (cached on disk after the first call).
"""

from __future__ import annotations

import math

from numba import njit

INNER = dict(no_cpython_wrapper=True, no_cfunc_wrapper=True)
"""Options of the helpers only compiled code calls: no Python or C entry point to compile (less
compile time on a first run; calling them from Python raises)."""


@njit(cache=True, nogil=True, error_model="numpy", **INNER)
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


@njit(cache=True, nogil=True, error_model="numpy", **INNER)
def _value_slopes(coef, k, P, a, b):
    """:func:`_value` and its derivatives d/da, d/db."""
    if P == 4:
        b2 = b * b
        b3 = b2 * b
        s0 = coef[k] + coef[k + 1] * b + coef[k + 2] * b2 + coef[k + 3] * b3
        s1 = coef[k + 4] + coef[k + 5] * b + coef[k + 6] * b2 + coef[k + 7] * b3
        s2 = coef[k + 8] + coef[k + 9] * b + coef[k + 10] * b2 + coef[k + 11] * b3
        s3 = coef[k + 12] + coef[k + 13] * b + coef[k + 14] * b2 + coef[k + 15] * b3
        e0 = coef[k + 1] + 2.0 * coef[k + 2] * b + 3.0 * coef[k + 3] * b2
        e1 = coef[k + 5] + 2.0 * coef[k + 6] * b + 3.0 * coef[k + 7] * b2
        e2 = coef[k + 9] + 2.0 * coef[k + 10] * b + 3.0 * coef[k + 11] * b2
        e3 = coef[k + 13] + 2.0 * coef[k + 14] * b + 3.0 * coef[k + 15] * b2
        return (s0 + a * (s1 + a * (s2 + a * s3)), s1 + a * (2.0 * s2 + 3.0 * a * s3),
                e0 + a * (e1 + a * (e2 + a * e3)))
    return (coef[k] + coef[k + 1] * b + a * (coef[k + 2] + coef[k + 3] * b),
            coef[k + 2] + coef[k + 3] * b, coef[k + 1] + a * coef[k + 3])


@njit(cache=True, nogil=True, error_model="numpy", **INNER)
def _locate(e1, e2, x1, x2, table):
    """A point's cell: (layer, k, w, a, b, i, j), layer -1 where a tile it needs is not built,
    0 intact (r = 1), 1 damaged; k the first row of its quantities (damaged: at the r node
    below, w the weight of the one above); a, b its local coordinates; i, j its cell."""
    (intact, damaged, ready_intact, ready_damaged, safe_intact, safe_damaged, E_lo, h, first,
     last, nr, nq, alpha_broken, P) = table
    nE = ready_intact.shape[0]
    s = (e1 - E_lo) / h
    i = min(max(int(math.floor(s)), first), last)
    s2 = (e2 - E_lo) / h
    j = min(max(int(math.floor(s2)), first), last)
    if x1 == x2:  # both yarns alike (the common case): r = 1, no division
        r = 1.0
    else:
        r = min(x1, x2) / max(x1, x2)
        if r < alpha_broken:
            r = 0.0
    cell = i * nE + j
    if r >= 1.0:
        return (0 if ready_intact[i, j] else -1), cell * nq, 0.0, s - i, s2 - j, i, j
    rs = math.sqrt(r) * (nr - 1)
    kr = min(int(rs), nr - 2)
    case = 0 if x1 < x2 else 1
    return ((1 if ready_damaged[i, j] else -1), ((case * nE * nE + cell) * nr + kr) * nq, rs - kr,
            s - i, s2 - j, i, j)


@njit(cache=True, nogil=True, error_model="numpy", **INNER)
def _risk(x1, x2, i, j, table):
    """Flag 0: the point's damage cannot change (its cell's nodes all below mu_crit), 1: it may."""
    safe = table[4] if (x1 >= 1.0 and x2 >= 1.0) else table[5]
    return 0 if safe[i, j] else 1


@njit(cache=True, nogil=True, error_model="numpy", **INNER)
def _dead(x1, x2, c, spec, broken):
    """The value of quantity c where a yarn is broken, NaN where none is. A yarn is broken
    below ``broken`` (ALPHA_BROKEN), as in the unit cell, which takes such a yarn out of the
    cell (F_i = 0, mu_i = mu_i^complete): not only at alpha = 0 exactly, else an alpha of
    1e-300 would read the r = 0 node (solved at R_LIMIT) and give the yarn the force of
    alpha_i = R_LIMIT (e.g. P1 = 24.6 N/m instead of 0)."""
    if x2 < broken and not math.isnan(spec[3][c]):
        return spec[3][c]
    if x1 < broken:
        return spec[2][c]
    return math.nan


@njit(cache=True, nogil=True, error_model="numpy")
def lookup(E1, E2, a1, a2, table, spec, out, flag):
    """Table values at frozen damage (a1, a2) into ``out`` (m, len(quantities)), and per point
    ``flag``: 0 = its damage cannot change (its cell's nodes are all below mu_crit), 1 = it
    may, 2 = a tile its cell needs is not built yet (its row is not set).

    table: (intact, damaged, ready_intact, ready_damaged, safe_intact, safe_damaged, E_lo, h,
    first, last, nr, nq, alpha_broken, P): the flat coefficient tables of the intact and the
    damaged layer (P x P coefficients per row), the (nE, nE) cell maps, the grid, the cells'
    index range (the cubic kernel's taps stay on the grid), the r nodes (uniform in sqrt(r),
    linear in between), quantities per cell, the integrity below which a yarn is broken.
    spec: (quantities, scaled, dead1, dead2): their rows (``QUANTITIES`` index), whether each
    is a force (multiplied by alpha_max: the damage scaling of :class:`Surrogate`), and the
    value where alpha1 (alpha2) is below alpha_broken (the yarn broken, :func:`_dead`), NaN for
    none.

    Accuracy in r near 0 (a stated bound, not removed): between the r = 0 node (solved at
    R_LIMIT) and r_1 = 1/(r_nodes - 1)^2 the forces are interpolated linearly in sqrt(r), but
    near r -> 0 both yarns' forces are close to linear in r (the weak yarn's P ~ c r, the
    other's through crimp interchange); that errs by up to a quarter of the force's change over
    the first interval: alpha1 = 1e-3 gives 668 N/m where the unit cell gives 216 N/m at
    E = (0.02, 0.02). Against the intact stresses it is about 1 %; the measured bound is in
    docs/reliability.md (near zero damage).
    """
    coefs, nq, broken, P = table[:2], table[11], table[12], table[13]
    quantities, scaled = spec[0], spec[1]
    PP = P * P
    for n in range(E1.size):
        x1, x2 = a1[n], a2[n]
        layer, k, w, a, b, i, j = _locate(E1[n], E2[n], x1, x2, table)
        if layer < 0:
            flag[n] = 2
            continue
        coef = coefs[layer]
        amax = max(x1, x2)
        for c in range(quantities.size):
            k0 = (k + quantities[c]) * PP
            v = _value(coef, k0, P, a, b)
            if w > 0.0:
                v += w * (_value(coef, k0 + nq * PP, P, a, b) - v)
            if scaled[c]:
                v = v * amax if amax > 0.0 else 0.0
            dead = _dead(x1, x2, c, spec, broken)
            out[n, c] = v if math.isnan(dead) else dead
        flag[n] = _risk(x1, x2, i, j, table)


@njit(cache=True, nogil=True, error_model="numpy")
def lookup_derivatives(E1, E2, a1, a2, table, spec, out, d1, d2, flag):
    """:func:`lookup` with the derivatives d/dE1, d/dE2 into ``d1``, ``d2`` (a broken yarn's
    quantities: 0). Apart from it: the extra arithmetic slows the value loop 2x."""
    for n in range(E1.size):
        x1, x2 = a1[n], a2[n]
        layer, k, w, a, b, i, j = _locate(E1[n], E2[n], x1, x2, table)
        if layer < 0:
            flag[n] = 2
            continue
        coef = table[0] if layer == 0 else table[1]
        for c in range(spec[0].size):
            out[n, c], d1[n, c], d2[n, c] = _quantity_slopes(coef, table, spec, c, k, w, a, b,
                                                             x1, x2)
        flag[n] = _risk(x1, x2, i, j, table)


@njit(cache=True, nogil=True, error_model="numpy", **INNER, inline="always")
def _quantity_slopes(coef, table, spec, c, k, w, a, b, x1, x2):
    """Quantity c of ``spec`` and its derivatives d/dE1, d/dE2 at a point located in the
    layer whose coefficients are ``coef`` (:func:`_locate`)."""
    h, nq, broken, P = table[7], table[11], table[12], table[13]
    PP = P * P
    dead = _dead(x1, x2, c, spec, broken)
    if not math.isnan(dead):
        return dead, 0.0, 0.0
    k0 = (k + spec[0][c]) * PP
    v, g1, g2 = _value_slopes(coef, k0, P, a, b)
    if w > 0.0:
        v1, h1, h2 = _value_slopes(coef, k0 + nq * PP, P, a, b)
        v, g1, g2 = v + w * (v1 - v), g1 + w * (h1 - g1), g2 + w * (h2 - g2)
    factor = 1.0
    if spec[1][c]:
        amax = max(x1, x2)
        factor = amax if amax > 0.0 else 0.0
    return v * factor, g1 * factor / h, g2 * factor / h


ROOT_FOUND, ROOT_NONE, ROOT_TENSION, ROOT_NEEDS_TILES = 0, 1, 3, 2
"""Status of :func:`zero_force_strain` per point."""
AT_LO, AT_X, AT_RIGHT = 0, 1, 2


@njit(cache=True, nogil=True, error_model="numpy")
def zero_force_strain(yarn, E_other, lo, hi, guess, a1, a2, table, spec, tol, max_iter, out,
                      status):
    """Per point the strain x in [lo, hi] of ``yarn`` (0 warp, 1 fill) where its force P
    (``spec``: that one quantity) is zero, the crossing yarn at E_other: Newton's method kept
    inside the bracket, bisection where a step leaves it, until a step or the bracket is below
    ``tol``; it starts from ``guess`` where that lies inside the bracket (the last step's root:
    one or two Newton steps), else from hi. ``status``: ROOT_FOUND; ROOT_TENSION where P(lo) >=
    0 (nothing to find, out = lo); ROOT_NONE where P(hi) < 0 too (out = lo); ROOT_NEEDS_TILES
    where a tile on the way is not built (out not set). Returns how many points have that status
    (numpy.count_nonzero(status == ROOT_NEEDS_TILES)): the caller looks for them only then."""
    # The force is evaluated at one place, a loop over the evaluations (``at``: which one, P(lo),
    # P(x) at the Newton iterate or P(right)): numba copies an inlined function (_quantity_slopes)
    # once per call site, and with four sites that copy took 19 s of the kernel's 20 s compile.
    waiting = 0
    for n in range(E_other.size):
        e, x1, x2 = E_other[n], a1[n], a2[n]
        left, right = lo[n], hi[n]
        out[n] = left
        at, xe = AT_LO, left
        x = step = g = d = 0.0
        right_known = False
        it = 0
        while True:
            # P of ``yarn`` at its own strain xe and dP/dxe; ok False where a tile is not built
            e1, e2 = (xe, e) if yarn == 0 else (e, xe)
            layer, k, w, a, b, i, j = _locate(e1, e2, x1, x2, table)
            ok = layer >= 0
            v = slope = 0.0
            if ok:
                coef = table[0] if layer == 0 else table[1]
                v, g1, g2 = _quantity_slopes(coef, table, spec, 0, k, w, a, b, x1, x2)
                slope = g1 if yarn == 0 else g2
            if at == AT_LO:
                if not ok:
                    status[n] = ROOT_NEEDS_TILES
                    break
                if v >= 0.0:
                    status[n] = ROOT_TENSION
                    break
                # Newton from the guess (else from hi) inside [left, right]; P(right) >= 0 is
                # checked only when a step would leave the bracket on that side (a good guess
                # needs no check).
                x = guess[n] if left < guess[n] < right else right
                status[n] = ROOT_FOUND
                at, xe = AT_X, x
                continue
            if at == AT_X:
                g, d = v, slope
                if it == max_iter:
                    out[n] = x
                    break
                it += 1
                if not ok:
                    status[n] = ROOT_NEEDS_TILES
                    out[n] = x
                    break
                if g == 0.0:
                    out[n] = x
                    break
                if g < 0.0:
                    left = x
                else:
                    right, right_known = x, True
                step = x - g / d if d > 0.0 else math.nan
                if not (left <= step <= right) and not right_known:
                    at, xe = AT_RIGHT, right
                    continue
            else:  # P(right)
                if not ok:
                    status[n] = ROOT_NEEDS_TILES
                    out[n] = x
                    break
                if v < 0.0:
                    status[n] = ROOT_NONE
                    out[n] = lo[n]
                    break
                right_known = True
            new = step if left <= step <= right else 0.5 * (left + right)
            if abs(new - x) <= tol or right - left <= tol:
                out[n] = new
                break
            x = new
            at, xe = AT_X, x
        if status[n] == ROOT_NEEDS_TILES:
            waiting += 1
    return waiting


@njit(cache=True, nogil=True)
def prepare_inputs(E1, E2, a1, a2, E_fail, E_lo, E_hi, E, alpha, counts, ranges):
    """The surrogate's inputs in one pass: E (2, n) = (E1, E2) clipped to the table [E_lo,
    E_hi]; alpha (2, n) = (a1, a2), 0 where E_i > E_fail[i] (the yarn certainly broken).
    Adds to ``counts`` the points beyond failure (warp, fill), compressed below the table
    (warp, fill) and invalid (a non-finite value, E <= -0.5 or alpha outside [0, 1]); writes
    the strain range seen, ``ranges`` (2, 2) = ((E1 min, E2 min), (E1 max, E2 max)).
    """
    lo1 = lo2 = math.inf
    hi1 = hi2 = -math.inf
    for n in range(E1.size):
        e = (E1[n], E2[n])
        x = (a1[n], a2[n])
        if not (e[0] > -0.5 and e[1] > -0.5 and 0.0 <= x[0] <= 1.0 and 0.0 <= x[1] <= 1.0
                and e[0] < math.inf and e[1] < math.inf):
            counts[4] += 1
            continue
        lo1, hi1 = min(lo1, e[0]), max(hi1, e[0])
        lo2, hi2 = min(lo2, e[1]), max(hi2, e[1])
        for i in range(2):
            alpha[i, n] = x[i]
            if e[i] > E_fail[i]:
                counts[i] += 1
                alpha[i, n] = 0.0
            if e[i] < E_lo:
                counts[2 + i] += 1
            E[i, n] = min(max(e[i], E_lo), E_hi)
    ranges[0, 0], ranges[0, 1], ranges[1, 0], ranges[1, 1] = lo1, lo2, hi1, hi2


@njit(cache=True, nogil=True)
def record_inputs(counts, ranges, beyond_failure, compression, E_min, E_max):
    """A :func:`prepare_inputs` pass's ``counts`` and strain ``ranges`` into the surrogate's range
    statistics, in place: the points beyond failure and below the table added per yarn, the range
    seen widened as numpy.minimum / numpy.maximum do it (NaN if either is, the second of two
    equal values)."""
    for i in range(2):
        beyond_failure[i] += counts[i]
        compression[i] += counts[2 + i]
        lo, hi = E_min[i], E_max[i]
        E_min[i] = lo if (lo < ranges[0, i] or lo != lo) else ranges[0, i]
        E_max[i] = hi if (hi > ranges[1, i] or hi != hi) else ranges[1, i]
