"""The membrane's yarn stresses at the quadrature points, compiled: the slack rule, the
stiffness-proportional viscous stress and its dissipation (see :mod:`fabric_fenicsx.fem.yarn_stress`,
class ``YarnStress``), one pass over the points instead of some thirty numpy passes.
"""

from __future__ import annotations

import math

import numpy as np
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


def stresses(E1, E2, live, p1, p2, ref, E_lo, beta_over_dt, w, lam_prev, P_v_prev, P_el, P_v,
             lam):
    """:func:`_stresses` with ``ref`` in Fortran order: the caller passes a column selection
    (Fortran order) on most steps and a copy of it (C order) on the steps where damage changed;
    without this numba compiles the kernel once more at the first damage (0.4 s)."""
    return _stresses(E1, E2, live, p1, p2, np.asfortranarray(ref), E_lo, beta_over_dt, w,
                     lam_prev, P_v_prev, P_el, P_v, lam)


@njit(cache=True, nogil=True)
def _stresses(E1, E2, live, p1, p2, ref, E_lo, beta_over_dt, w, lam_prev, P_v_prev, P_el, P_v,
              lam):
    """Yarn stresses of one step at all n points (zero at the points not ``live``).

    E1, E2 (n): the strains; live (n): the live points (mask); p1, p2 (m): the surrogate's
    tension-only P_i at the m live points, in order; ref (2, m): P(E^{n-1}, alpha^n) there for
    the viscous stress P_v = max(P_el + beta / dt (P_el - ref), 0) - P_el (``beta_over_dt`` =
    0: none). Writes P_el, P_v, lam (2, n) (lam_i = sqrt(1 + 2 E_i)) and returns (points below
    the table, slack points the surrogate gave a tension, viscous work over the step: the
    trapezoidal sum of w (P_v + P_v_prev) / 2 d lambda, J).
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
                v1 = max(q1 + beta_over_dt * (q1 - ref[0, k]), 0.0) - q1
                v2 = max(q2 + beta_over_dt * (q2 - ref[1, k]), 0.0) - q2
            k += 1
        l1, l2 = math.sqrt(1.0 + 2.0 * e1), math.sqrt(1.0 + 2.0 * e2)
        work += w[g] * (0.5 * (v1 + P_v_prev[0, g]) * (l1 - lam_prev[0, g])
                        + 0.5 * (v2 + P_v_prev[1, g]) * (l2 - lam_prev[1, g]))
        P_el[0, g], P_el[1, g], P_v[0, g], P_v[1, g], lam[0, g], lam[1, g] = q1, q2, v1, v2, l1, l2
    return below, slack_tension, work


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
