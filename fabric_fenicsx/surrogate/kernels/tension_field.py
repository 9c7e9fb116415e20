"""The tension field's force-free strains read from a tabulated curve, compiled (see
:mod:`fabric_fenicsx.fem.tension_field`, class ``ForceFreeCurves``): one pass over the points
instead of a Newton search per wrinkled point; and the passes around the searches (the
candidates gathered, the roots put back).
"""

from __future__ import annotations

import math

from numba import njit

CURVE, SEARCH, NEEDS_SEGMENT = 0, 1, 2
"""Per point of :func:`relax_on_curve`: done (relaxed from the curve, or not a candidate); to be
searched (a damaged point, r < 1, or a curve interval that failed its check); its curve segment
is not built yet."""


@njit(cache=True, nogil=True, error_model="numpy")
def relax_on_curve(E_own, E_other, a1, a2, broken, x, s, ok, built, step, m, out, todo):
    """The strain of the yarn ``E_own`` in a tension field (:mod:`fabric_fenicsx.fem.tension_field`)
    at n points into ``out`` and per point ``todo`` (CURVE, SEARCH, NEEDS_SEGMENT); returns how
    many were relaxed. A candidate is compressed (E_own < 0) while the crossing yarn is stretched
    (E_other > 0); of those, the points of the intact layer (alpha1 = alpha2 >= ``broken``: r = 1,
    whose force-free strain does not depend on alpha, the forces scale with it) read the
    force-free strain X(E_other) from the curve and are relaxed to it where E_own < X; the others
    are left to the search. The curve: nodes x (the force-free strains at E_other = k ``step``)
    and s (dX/dE_other there times ``step``), cubic Hermite between them; ``ok`` per interval:
    its check against the search held (else SEARCH); ``built`` per segment of ``m`` intervals."""
    relaxed = 0
    last = x.size - 2
    for n in range(E_own.size):
        e, o = E_own[n], E_other[n]
        out[n] = e
        todo[n] = CURVE
        if not (e < 0.0 and o > 0.0):
            continue
        if not (a1[n] == a2[n] and a1[n] >= broken):
            todo[n] = SEARCH
            continue
        t = o / step
        if not t <= last + 1.0:   # beyond the curve's top (the table's)
            todo[n] = SEARCH
            continue
        k = min(int(math.floor(t)), last)
        if not built[k // m]:
            todo[n] = NEEDS_SEGMENT
            continue
        if not ok[k]:
            todo[n] = SEARCH
            continue
        q = t - k
        q2 = q * q
        q3 = q2 * q
        X = ((2.0 * q3 - 3.0 * q2 + 1.0) * x[k] + (q3 - 2.0 * q2 + q) * s[k]
             + (3.0 * q2 - 2.0 * q3) * x[k + 1] + (q3 - q2) * s[k + 1])
        if e < X:
            out[n] = X
            relaxed += 1
    return relaxed


@njit(cache=True, nogil=True)
def candidates(E_own, E_other, a1, a2, guess, k, other, own, b1, b2, g):
    """The points of a yarn that may wrinkle, gathered for its force-free search
    (:func:`fabric_fenicsx.fem.tension_field.relax_in_place`): compressed (E_own < 0) while the
    crossing yarn is stretched (E_other > 0). Writes their indices into ``k`` and their E_other,
    E_own, a1, a2 and start ``guess`` (NaN where ``guess`` is empty: none) into the buffers,
    in order; returns how many."""
    m = 0
    for n in range(E_own.size):
        if E_own[n] < 0.0 and E_other[n] > 0.0:
            k[m] = n
            other[m], own[m], b1[m], b2[m] = E_other[n], E_own[n], a1[n], a2[n]
            g[m] = guess[n] if guess.size else math.nan
            m += 1
    return m


@njit(cache=True, nogil=True)
def place_roots(E_own, k, root, status, found, none):
    """E_own[k] = root (the searched strains put back) and the numbers of roots with status
    ``found`` and ``none`` (:func:`fabric_fenicsx.surrogate.kernels.interp.zero_force_strain`)."""
    n_found = n_none = 0
    for m in range(k.size):
        E_own[k[m]] = root[m]
        n_found += status[m] == found
        n_none += status[m] == none
    return n_found, n_none
