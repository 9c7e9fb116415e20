"""The membrane's yarn stresses at the quadrature points, compiled: the slack rule, the
stiffness-proportional viscous stress and its dissipation (see :mod:`fabric_fenicsx.fem.yarn_stress`,
class ``YarnStress``), one pass over the points instead of some thirty numpy passes; and the
passes around the surrogate's kernels in ``YarnStress.update`` (the live points' inputs and peak
strains, the table's clip, the tension field's strains put back) and the yarn tensions the
hourglass term reads before every assembly, each giving numpy's bits.
"""

from __future__ import annotations

import math

from numba import njit


@njit(cache=True, nogil=True)
def _slack(E_own, E_other, E_lo):
    """A yarn that cannot carry tension (wrinkled): compressed below the table's lower end, or
    compressed while the crossing yarn is not stretched (only a stretched crossing yarn keeps
    a compressed one taut, by crimp interchange)."""
    return E_own < E_lo or (E_own < 0.0 and E_other <= 0.0)


@njit(cache=True, nogil=True)
def slack(E1, E2, E_lo, slack1, slack2):
    """The slack masks of the warp and the fill (:func:`_slack`) into ``slack1``, ``slack2``."""
    for k in range(E1.size):
        slack1[k] = _slack(E1[k], E2[k], E_lo)
        slack2[k] = _slack(E2[k], E1[k], E_lo)


@njit(cache=True, nogil=True)
def _clipped(e, lo, hi):
    """numpy.minimum(numpy.maximum(e, lo), hi) of one strain (NaN stays NaN)."""
    e = e if (e >= lo or e != e) else lo
    return e if (e <= hi or e != e) else hi


@njit(cache=True, nogil=True)
def clip(E1, E2, lo, hi, c1, c2):
    """The strains clipped to the table [lo, hi] into ``c1``, ``c2`` (``YarnStress._clip``)."""
    for k in range(E1.size):
        c1[k], c2[k] = _clipped(E1[k], lo, hi), _clipped(E2[k], lo, hi)


@njit(cache=True, nogil=True)
def keep_given(r1, r2, E1, E2, lo, hi):
    """In place, the tension field's strains r_i (of the clipped strains) where they differ from
    the clipped E_i, else the strains E_i as given: numpy.where(r_i != clip(E_i), r_i, E_i)."""
    for k in range(E1.size):
        if not r1[k] != _clipped(E1[k], lo, hi):
            r1[k] = E1[k]
        if not r2[k] != _clipped(E2[k], lo, hi):
            r2[k] = E2[k]


@njit(cache=True, nogil=True)
def _maximum(a, b):
    """numpy.maximum(a, b) of two floats: NaN if either is, b where a == b (numpy gives the
    second of two zeros of opposite sign)."""
    return a if (a > b or a != a) else b


@njit(cache=True, nogil=True)
def live_inputs(idx, E1, E2, a1_hist, a2_hist, relaxed, E_peak, e1, e2, h1, h2, guess):
    """The live points' inputs of a step in one pass (``YarnStress.update``): at the m points
    ``idx`` (in order) their strains into ``e1``, ``e2``, damage history into ``h1``, ``h2`` and
    last tension-field strains (``relaxed``, (2, n)) into ``guess`` (2, m), and each one's
    largest strains ``E_peak`` (2, n) raised to its strains (numpy.maximum, in place)."""
    for k in range(idx.size):
        g = idx[k]
        e1[k], e2[k], h1[k], h2[k] = E1[g], E2[g], a1_hist[g], a2_hist[g]
        guess[0, k], guess[1, k] = relaxed[0, g], relaxed[1, g]
        E_peak[0, g] = _maximum(E_peak[0, g], E1[g])
        E_peak[1, g] = _maximum(E_peak[1, g], E2[g])


@njit(cache=True, nogil=True)
def put_live(idx, r1, r2, out):
    """out[:, idx] = (r1, r2): values of the m live points ``idx`` into the (2, n) ``out``."""
    for k in range(idx.size):
        out[0, idx[k]], out[1, idx[k]] = r1[k], r2[k]


@njit(cache=True, nogil=True)
def stresses(E1, E2, live, p1, p2, ref, E_lo, beta_over_dt, w, lam_prev, P_v_prev, P_el, P_v,
             lam, P):
    """Yarn stresses of one step at all n points (zero at the points not ``live``).

    E1, E2 (n): the strains; live (n): the live points (mask); p1, p2 (m): the surrogate's
    tension-only P_i at the m live points, in order; ref (2, n): P(E^{n-1}, alpha^n) for
    the viscous stress P_v = max(P_el + beta / dt (P_el - ref), 0) - P_el (``beta_over_dt`` =
    0: none). Writes P_el, P_v, lam (2, n) (lam_i = sqrt(1 + 2 E_i)) and P = P_el + P_v, and
    returns (points below the table, slack points the surrogate gave a tension, viscous work
    over the step: the trapezoidal sum of w (P_v + P_v_prev) / 2 d lambda, J).
    """
    below, slack_tension = 0, 0
    work = 0.0
    k = 0
    for g in range(E1.size):
        e1, e2 = E1[g], E2[g]
        q1 = q2 = v1 = v2 = 0.0
        if live[g]:
            s1, s2 = _slack(e1, e2, E_lo), _slack(e2, e1, E_lo)
            below += e1 < E_lo or e2 < E_lo
            slack_tension += (s1 and p1[k] > 0.0) or (s2 and p2[k] > 0.0)
            q1 = 0.0 if s1 else p1[k]
            q2 = 0.0 if s2 else p2[k]
            if beta_over_dt > 0.0:
                v1 = max(q1 + beta_over_dt * (q1 - ref[0, g]), 0.0) - q1
                v2 = max(q2 + beta_over_dt * (q2 - ref[1, g]), 0.0) - q2
            k += 1
        l1, l2 = math.sqrt(1.0 + 2.0 * e1), math.sqrt(1.0 + 2.0 * e2)
        work += w[g] * (0.5 * (v1 + P_v_prev[0, g]) * (l1 - lam_prev[0, g])
                        + 0.5 * (v2 + P_v_prev[1, g]) * (l2 - lam_prev[1, g]))
        P_el[0, g], P_el[1, g], P_v[0, g], P_v[1, g], lam[0, g], lam[1, g] = q1, q2, v1, v2, l1, l2
        P[0, g], P[1, g] = q1 + v1, q2 + v2
    return below, slack_tension, work


@njit(cache=True, nogil=True)
def tension(P_el, lam, T):
    """The yarn tensions P_el / lam into ``T`` (all (2, n)), zero where lam is not > 0:
    numpy.divide(P_el, lam, out=numpy.zeros_like(P_el), where=lam > 0.0)."""
    for i in range(P_el.shape[0]):
        for g in range(P_el.shape[1]):
            T[i, g] = P_el[i, g] / lam[i, g] if lam[i, g] > 0.0 else 0.0


@njit(cache=True, nogil=True)
def new_damage(a1_hist, a2_hist, live, b1, b2, a1, a2, changed):
    """alpha1, alpha2 (n) of the step into ``a1``, ``a2``: the surrogate's ``b1``, ``b2`` at
    the live points (mask, in order), the history elsewhere; the live points (their index
    among the live ones) whose alpha changed into ``changed``. Returns how many changed."""
    k = m = 0
    for g in range(a1_hist.size):
        a1[g], a2[g] = a1_hist[g], a2_hist[g]
        if live[g]:
            if b1[k] != a1_hist[g] or b2[k] != a2_hist[g]:
                changed[m] = k
                m += 1
            a1[g], a2[g] = b1[k], b2[k]
            k += 1
    return m
