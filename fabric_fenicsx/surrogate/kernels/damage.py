"""The surrogate's damage iteration, compiled: :func:`damage_solver.solve_point` (appendix A.1)
with the target of the interpolated unit cell, alpha_i = min(alpha_i^hist, alpha(mu_i^max))
(Eq. 2-25 / A.12 or the bundle's Eq. 2-24) at the table's stretches mu_i.

numba compiles damage_solver's own functions (one implementation, run in Python by the unit
cell) with their ``target`` bound to :func:`_target`; the fibril-scale laws of
:mod:`fabric_fenicsx.material.fibril` are repeated here as scalar functions (tests compare them).
"""

from __future__ import annotations

import math
import types

import numpy as np
from numba import njit

from fabric_fenicsx.material import damage_solver
from fabric_fenicsx.surrogate.kernels import interp as interp_kernel
from fabric_fenicsx.material.fibril import BundleDamage, ExponentialDamage

EXPONENTIAL, BUNDLE = 0, 1


def law_arguments(law):
    """(kind, parameters, sorted misalignments) of a damage law for :func:`law_alpha`."""
    if isinstance(law, ExponentialDamage):
        return EXPONENTIAL, np.array([law.beta, law.width]), np.empty(0)
    if isinstance(law, BundleDamage):
        return BUNDLE, np.empty(0), np.ascontiguousarray(law.bundle.x_sorted)
    raise ValueError(f"the surrogate's damage iteration knows ExponentialDamage and BundleDamage, "
                     f"got {law!r}")


@njit(cache=True, nogil=True)
def law_alpha(mu, mu_crit, law):
    """alpha(mu) of :meth:`ExponentialDamage.alpha` (Eq. 2-25) or :meth:`BundleDamage.alpha`
    (Eq. 2-24, U_crit = mu_crit) for one stretch; NaN for a NaN stretch."""
    kind, params, x_sorted = law
    if math.isnan(mu):
        return math.nan
    if kind == EXPONENTIAL:
        b, w = params[0], params[1]
        s = min(max(mu - mu_crit, 0.0), w)
        if s <= 0.0:
            return 1.0
        if s >= w:
            return 0.0
        return math.exp(-b * s) * math.expm1(-b * (w - s)) / math.expm1(-b * w)
    if mu < mu_crit:
        return 1.0
    U2 = mu_crit * mu_crit
    x = math.sqrt(max(mu * mu - U2, 0.0) / (U2 - 1.0))
    return 1.0 - np.searchsorted(x_sorted, x, side="right") / x_sorted.size


@njit(cache=True, nogil=True)
def band_alpha(mu, mu_crit, scale, law):
    """:func:`law_alpha` with the softening branch shortened by the crack-band ``scale``:
    alpha(mu_crit + (mu - mu_crit) / scale) (:func:`fibril.crack_band_alpha`)."""
    if scale != 1.0 and mu > mu_crit:
        mu = mu_crit + (mu - mu_crit) / scale
    return law_alpha(mu, mu_crit, law)


@njit(cache=True, nogil=True, **interp_kernel.INNER)
def _at_most(hist, t):
    """min(hist, t), NaN if t is (as numpy.minimum)."""
    return t if (math.isnan(t) or t < hist) else hist


@njit(cache=True, nogil=True, **interp_kernel.INNER)
def _law_target(ctx, a1, a2):
    """min(alpha^hist, alpha(mu(alpha))) of one point at (a1, a2): ctx = (alpha1^hist,
    alpha2^hist, law, mu_crit, table, spec of (mu1, mu2), the point's E1, E2, alpha1,
    alpha2, mu (1, 2) and flag as arrays of one, and its crack-band scales (2,))."""
    h1, h2, law, mu_crit, table, spec, E1, E2, x1, x2, mu, flag, scale = ctx
    x1[0], x2[0] = a1, a2
    interp_kernel.lookup(E1, E2, x1, x2, table, spec, mu, flag)
    if flag[0] == 2:
        return math.nan, math.nan  # a tile is missing: the caller builds them first
    return (_at_most(h1, band_alpha(mu[0, 0], mu_crit[0], scale[0], law)),
            _at_most(h2, band_alpha(mu[0, 1], mu_crit[1], scale[1], law)))


@njit(cache=True, nogil=True, **interp_kernel.INNER)
def _target(ctx, a1, a2):
    """The iteration's target: :func:`_law_target` with a yarn below ALPHA_BROKEN broken."""
    broken = ctx[4][12]
    return _law_target(ctx, 0.0 if a1 < broken else a1, 0.0 if a2 < broken else a2)


def _compiled(module, names, **bound):
    """numba twins of ``module``'s functions ``names``, calling each other compiled, with the
    module's globals ``bound`` replaced (only compiled code calls them: no Python entry points)."""
    namespace = dict(vars(module), **bound)
    for name in names:
        code = getattr(module, name).__code__
        namespace[name] = njit(cache=True, nogil=True, **interp_kernel.INNER)(
            types.FunctionType(code, namespace, name))
    return namespace


_solve_point = _compiled(damage_solver, ("_residual", "_settled", "_falsi_or_bisect", "_fast",
                                         "_scan", "_settled_residual", "_outer", "_nested",
                                         "_bracket", "solve_point"), target=_target)["solve_point"]


NEEDS_TILES, NEEDS_DAMAGED_TILES, NON_FINITE = 3, 4, 5
"""Status of :func:`update` beyond damage_solver's (CONVERGED, UNCONVERGED, BRACKETED): a tile
of the point's look-up at its history is not built; the damaged layer of its cell (every r, for
the iteration) is not built; the iteration met a non-finite table stretch (a table tile holds
NaN: a fault of the table, not of the point)."""


@njit(cache=True, nogil=True)
def update(E1, E2, a1, a2, table, spec_P, spec_mu, law, mu_crit, band, floor, tol, P, alpha,
           residual, status, mu_top=None, margin=0.0):
    """The constitutive update of n points: the new alpha (n, 2) from alpha^hist = (a1, a2)
    (Eq. 2-25 / A.12) and P1, P2 there into P (n, 2); per point ``status``: CONVERGED (damage
    unchanged, or its iteration converged), BRACKETED (converged on the iteration's guaranteed
    path), UNCONVERGED (no root within ACCEPT: alpha is the upper end of a bracket narrower than
    tol around a jump of the target; alpha - target in ``residual``), NON_FINITE (a non-finite
    alpha, from a non-finite table stretch), NEEDS_TILES or NEEDS_DAMAGED_TILES (the point is
    not done). ``band`` (n, 2): each point's crack-band scale of the softening branch per yarn
    (:func:`band_alpha`; 1 = the law as it is); ``mu_crit`` (n, 2): each point's critical stretch per
    yarn (the fabric's, or its strength scatter's). ``mu_top``: None, or per layer (intact,
    damaged) the largest stretch per yarn of each table cell's nodes, (nE, nE, 2): a point whose
    cell stays ``margin`` below its own critical stretches takes no iteration (the table's safe
    map is made for the field's lowest critical stretch). Every done point has 0 <= alpha <= alpha^hist.
    Returns the numbers of points that iterated and that are not done. Only the points whose cell can reach mu_crit (flag 1 of interp_kernel.lookup) look
    up their stretches. table: :func:`interp_kernel.lookup`'s; spec_P, spec_mu: its specs of
    (P1, P2) and (mu1, mu2)."""
    flag = np.empty(E1.size, np.int8)
    interp_kernel.lookup(E1, E2, a1, a2, table, spec_P, P, flag)
    mu, one = np.empty((1, 2)), np.empty(1, np.int8)
    x1, x2 = np.empty(1), np.empty(1)
    hist, target = np.empty(2), np.empty(2)
    broken, ready_damaged = table[12], table[3]
    iterated = waiting = 0
    for n in range(E1.size):
        alpha[n, 0], alpha[n, 1] = a1[n], a2[n]
        status[n] = damage_solver.CONVERGED
        if flag[n] == 2:
            status[n] = NEEDS_TILES
            waiting += 1
            continue
        if flag[n] == 0:
            continue
        if mu_top is not None:
            top = mu_top[0] if (a1[n] >= 1.0 and a2[n] >= 1.0) else mu_top[1]
            _, _, _, _, _, i, j = interp_kernel._locate(E1[n], E2[n], 1.0, 1.0, table)
            if top[i, j, 0] < mu_crit[n, 0] - margin and top[i, j, 1] < mu_crit[n, 1] - margin:
                continue
        hist[0], hist[1] = a1[n], a2[n]
        point = (a1[n], a2[n], law, mu_crit[n], table, spec_mu, E1[n:n + 1], E2[n:n + 1], x1, x2, mu,
                 one, band[n])
        target[0], target[1] = _law_target(point, a1[n], a2[n])
        if not (hist[0] - target[0] > tol or hist[1] - target[1] > tol):
            continue
        _, _, _, _, _, i, j = interp_kernel._locate(E1[n], E2[n], 1.0, 1.0, table)
        if not ready_damaged[i, j]:
            status[n] = NEEDS_DAMAGED_TILES
            waiting += 1
            continue
        iterated += 1
        residual[n, 0] = residual[n, 1] = math.nan
        status[n] = _solve_point(point, hist, target, floor, tol, damage_solver.FAST_ITERATIONS,
                                 damage_solver.SCAN_POINTS, damage_solver.MAX_ROUNDS,
                                 damage_solver.ACCEPT, alpha[n], residual[n])
        for k in range(2):
            if alpha[n, k] < broken:
                alpha[n, k] = 0.0
            if not math.isfinite(alpha[n, k]):
                status[n] = NON_FINITE
        x1[0], x2[0] = alpha[n, 0], alpha[n, 1]
        interp_kernel.lookup(E1[n:n + 1], E2[n:n + 1], x1, x2, table, spec_P, P[n:n + 1], one)
    return iterated, waiting
