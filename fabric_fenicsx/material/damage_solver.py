"""The damage coupling of the unit cell (appendix A.1), solved per point.

alpha_i = min(alpha_i^hist, alpha(mu_i^max(alpha))) (Eq. 2-25/A.12) is a fixed point of
target(alpha). With g(alpha) = alpha - target(alpha) >= 0 at alpha^hist, the loading path
reaches the largest root below alpha^hist. alpha = 0 (the yarn broken) is always a root too,
and where damage snaps target'(alpha) approaches 1 and more roots appear in between.

target is non-decreasing in alpha (a weaker yarn stretches more), so from an upper bound u
(g(u) > 0) the fixed-point step target(u) is again an upper bound of the largest root: it
never skips it. It is accelerated by the thesis's secant step where the secant slope shows a
contraction (target' < 0.95); a step that overshoots (g < 0) brackets a root, which the
Illinois variant of regula falsi closes. Where the fixed-point steps creep (target' near 1
over a long stretch: a snap), the yarn scans g on a grid below u and closes the highest sign
change. The yarns' coupling enters through target.

These fast steps work yarn by yarn, each assuming its current value is an upper bound of its
root; the coupling can break that (a yarn settles, then the other one's damage moves its root
up), and they can then run out of rounds short of tol. Where they do, a guaranteed path ends the
iteration (:func:`_bracket`). It rests on a bracket that always holds: target_i <= alpha_i^hist
(the min of Eq. 2-25), so g_i >= 0 at alpha_i = alpha_i^hist, and g_i = -target_i <= 0 at
alpha_i = 0, whatever the other yarn's value. So for an outer yarn o at x, the inner yarn's
highest root a*(x) in [0, alpha^hist] exists (scan and regula falsi, :func:`_scan`), and the
outer residual G(x) = x - target_o(x, a*(x)) is >= 0 at alpha_o^hist and <= 0 at 0: a scan from
the top and Illinois steps alternating with bisections close its highest sign change to a
bracket narrower than tol in at most 2 log2(1/tol) steps. Both yarns are tried as the outer one.
The answer is then a root within tol (status BRACKETED), or, where the bracket holds a jump of
target (no root: an interpolated target that is nearly singular, a snap), the bracket's upper
end with its residual (status UNCONVERGED): every point ends with an answer in [0, alpha^hist].

The iteration is scalar code for one point (:func:`solve_point`), written so that numba can
compile it unchanged: :mod:`fabric_fenicsx.surrogate.kernels.damage` compiles it with the surrogate's
target for the membrane's quadrature points; the unit cell (:func:`solve_damage`) runs the
same code in Python around its own solves. The point's target comes from :func:`target`.
"""

from __future__ import annotations

import math
from typing import Callable

import numpy as np

Evaluate = Callable[[np.ndarray, np.ndarray], np.ndarray]
"""evaluate(rows, alpha) -> target for those rows: alpha and target of shape (len(rows), 2)."""

CONVERGED, UNCONVERGED, BRACKETED = 0, 1, 2
"""Status of :func:`solve_point`: converged by the fast steps (to tol, or within ACCEPT after
MAX_ROUNDS rounds); no root within ACCEPT even on the guaranteed path (the answer is the upper
end of a bracket narrower than tol around a jump of the target); converged on the guaranteed
path (:func:`_bracket`) after the fast steps had not."""
FAST_ITERATIONS, SCAN_POINTS, MAX_ROUNDS, ACCEPT = 40, 32, 4, 1e-7
"""The iteration's defaults (see :func:`solve_damage`)."""


class DamageIterationError(RuntimeError):
    """The iteration did not converge; ``rows``: the unconverged points, ``alpha``: their
    last iterates (len(rows), 2), ``residual``: alpha - target(alpha) there."""

    def __init__(self, message: str, rows=None, alpha=None, residual=None):
        super().__init__(message)
        self.rows, self.alpha, self.residual = rows, alpha, residual


def solve_damage(alpha_hist: np.ndarray, target_hist: np.ndarray, evaluate: Evaluate,
                 floor: float, tol: float = 1e-10, fast_iterations: int = FAST_ITERATIONS,
                 scan_points: int = SCAN_POINTS, max_rounds: int = MAX_ROUNDS,
                 accept: float = ACCEPT) -> np.ndarray:
    """The new integrities alpha (n, 2), given alpha^hist (n, 2) and target(alpha^hist), with
    ``evaluate(rows, alpha)`` giving the targets of several points at once; :func:`solve_point`
    per point (for few points with costly targets: the unit cell's).

    ``floor``: the smallest integrity the caller still treats as a yarn in the cell; a root
    below it is returned as 0 (broken). The iteration aims at |alpha - target(alpha)| <= tol;
    a point that has not got there after ``max_rounds`` is accepted if its residual is below
    ``accept`` (1e-7: the stress error it leaves, 1e-7 of the yarn's intact force, is four
    orders below the surrogate's table error; met where an interpolated target is nearly
    singular, e.g. a yarn within 2e-5 in stretch of complete failure, r -> 0). Otherwise the
    guaranteed bracketing of :func:`_bracket` finishes it; only a point with no root even
    there (a jump of the target larger than ``accept``) raises :class:`DamageIterationError`
    naming the first such point, its history and its last iterate.
    """
    alpha_hist = np.asarray(alpha_hist, dtype=float)
    target_hist = np.asarray(target_hist, dtype=float)
    alpha = np.empty_like(alpha_hist)
    residual = np.empty(2)
    failed = []
    for k in range(alpha_hist.shape[0]):
        status = solve_point((_row_target, (evaluate, k)), alpha_hist[k], target_hist[k], floor, tol,
                             fast_iterations, scan_points, max_rounds, accept, alpha[k], residual)
        if status == UNCONVERGED:
            failed.append((k, residual.copy()))
    if failed:
        raise iteration_error(np.array([k for k, _ in failed]), alpha_hist, alpha,
                              np.array([g for _, g in failed]))
    return alpha


class FallbackLog:
    """Points whose damage iteration needed the guaranteed path, kept by a caller that must
    not stop (the surrogate in an impact run): counts of BRACKETED (a root found there) and
    UNCONVERGED points (no root: a jump of the target; the bracket's upper end was used), and
    the first ``keep`` of them as dicts (status, E1, E2, alpha_hist, alpha, residual)."""

    def __init__(self, keep: int = 100):
        self.keep = keep
        self.bracketed = 0
        self.unconverged = 0
        self.states: list[dict] = []

    def record(self, status, E1, E2, alpha_hist, alpha, residual) -> None:
        """Add the points (arrays over points; alpha_hist, alpha, residual of shape (n, 2))."""
        status = np.asarray(status)
        self.bracketed += int(np.count_nonzero(status == BRACKETED))
        self.unconverged += int(np.count_nonzero(status == UNCONVERGED))
        for k in range(min(status.size, self.keep - len(self.states))):
            self.states.append({
                "status": "bracketed" if status[k] == BRACKETED else "unconverged",
                "E1": float(E1[k]), "E2": float(E2[k]),
                "alpha_hist": tuple(map(float, alpha_hist[k])), "alpha": tuple(map(float, alpha[k])),
                "residual": tuple(map(float, residual[k]))})

    def __repr__(self) -> str:
        return (f"FallbackLog(bracketed={self.bracketed}, unconverged={self.unconverged}, "
                f"states kept={len(self.states)})")


def iteration_error(rows, alpha_hist, alpha, residual) -> DamageIterationError:
    """The error for the unconverged ``rows`` (residual: alpha - target there)."""
    k = rows[0]
    return DamageIterationError(
        f"damage iteration (Eq. 2-25) did not converge for {rows.size} point(s), not even by "
        f"bisection: the target jumps there; first: point {k}, "
        f"alpha_hist={tuple(alpha_hist[k])}, last alpha={tuple(alpha[k])}, "
        f"alpha - target(alpha) = {tuple(residual[0])}", rows=rows, alpha=alpha[rows],
        residual=residual)


def target(ctx, a1, a2):
    """The point's target at (alpha1, alpha2): ``ctx`` = (evaluate, data), evaluate(data, a1, a2)
    -> (target1, target2). The compiled twins (:mod:`damage_kernel`) bind this name to the
    surrogate's compiled target instead (numba caches no code that takes functions as
    arguments)."""
    evaluate, data = ctx
    return evaluate(data, a1, a2)


def _row_target(data, a1, a2):
    evaluate, k = data
    t = evaluate(np.array([k]), np.array([[a1, a2]]))[0]
    return t[0], t[1]


# --------------------------------------------------------------------------- one point
def solve_point(ctx, hist, target_hist, floor, tol, fast_iterations, scan_points,
                max_rounds, accept, alpha, residual):
    """The new integrities of one point into ``alpha`` (2,), from ``hist`` = alpha^hist and
    ``target_hist`` = target(alpha^hist): the fast steps, then, if they end with a residual
    above ``accept``, the guaranteed bracketing (:func:`_bracket`). Returns CONVERGED,
    BRACKETED or UNCONVERGED; with the last two alpha - target(alpha) is in ``residual`` (2,).
    Always 0 <= alpha <= hist. See :func:`solve_damage` for the arguments."""
    alpha[0], alpha[1] = hist[0], hist[1]
    if abs(hist[0] - target_hist[0]) <= tol and abs(hist[1] - target_hist[1]) <= tol:
        return CONVERGED
    g = np.empty(2)
    for _ in range(max_rounds):
        _fast(ctx, hist, alpha, floor, tol, fast_iterations)
        if _settled(ctx, alpha, tol, g):
            return CONVERGED
        for i in range(2):
            _residual(ctx, alpha, g)
            if abs(g[i]) > tol:
                _scan(ctx, alpha, i, floor, tol, scan_points)
        if _settled(ctx, alpha, tol, g):
            return CONVERGED
    _residual(ctx, alpha, g)
    residual[0], residual[1] = g[0], g[1]
    if abs(g[0]) > accept or abs(g[1]) > accept:
        return _bracket(ctx, hist, floor, tol, scan_points, accept, alpha, residual)
    return CONVERGED


def _bracket(ctx, hist, floor, tol, k, accept, alpha, residual):
    """The guaranteed path (see the module text): nested bracketing with yarn 0, then yarn 1,
    as the outer yarn; the first that ends at a root within ``accept`` gives ``alpha``, else
    the one with the smaller residual. Returns BRACKETED or UNCONVERGED, with
    alpha - target(alpha) in ``residual``."""
    best = np.empty(2)
    best_g = np.empty(2)
    trial = np.empty(2)
    g = np.empty(2)
    best_size = math.inf
    for outer in range(2):
        _nested(ctx, hist, outer, floor, tol, k, trial, g)
        s0, s1 = _settled_residual(trial[0], g[0]), _settled_residual(trial[1], g[1])
        size = math.inf if (math.isnan(s0) or math.isnan(s1)) else max(s0, s1)
        if size < best_size:
            best_size = size
            best[0], best[1], best_g[0], best_g[1] = trial[0], trial[1], g[0], g[1]
        if size <= accept:
            break
    if best_size == math.inf:  # non-finite targets everywhere: report the last try
        best[0], best[1], best_g[0], best_g[1] = trial[0], trial[1], g[0], g[1]
    alpha[0], alpha[1] = best[0], best[1]
    residual[0], residual[1] = best_g[0], best_g[1]
    return BRACKETED if best_size <= accept else UNCONVERGED


def _settled_residual(a, g):
    """|alpha - target| of a yarn, 0 for a broken one (alpha = 0: :func:`_settled`)."""
    return 0.0 if a <= 0.0 else abs(g)


def _nested(ctx, hist, o, floor, tol, k, trial, g):
    """One nested bracketing with outer yarn ``o``: into ``trial`` the integrities (x, a*(x))
    at the outer yarn's highest sign change of G(x) = x - target_o(x, a*(x)) in [0, hist_o]
    (to a bracket narrower than tol), and into ``g`` alpha - target there."""
    hi = hist[o]
    ghi = _outer(ctx, hist, o, hi, floor, tol, k, trial, g)
    if not ghi > tol:  # the outer yarn keeps its history (G(hist_o) >= 0 always)
        return
    lo, glo, has = 0.0, -1.0, False
    for j in range(k - 1, 0, -1):  # from the top: the highest sign change
        x = max(hist[o] * (j / k), floor)
        gx = _outer(ctx, hist, o, x, floor, tol, k, trial, g)
        if abs(gx) <= tol:
            return
        if gx < 0:
            lo, glo, has = x, gx, True
            break
        hi, ghi = x, gx
        if x <= floor:
            break
    if not has and hi <= 2 * floor:  # above its root down to the floor: the yarn is broken
        _outer(ctx, hist, o, 0.0, floor, tol, k, trial, g)
        return
    if not has:  # G(0) = -target_o(0, .) <= 0: the bracket is [0, hi]
        lo, glo = 0.0, -1.0
    side = 0
    for it in range(400):
        if hi - lo <= tol:
            break
        if it % 2 == 1:
            x = 0.5 * (lo + hi)  # a bisection every other step: the bracket halves
        else:
            x = _falsi_or_bisect(lo, glo, hi, ghi)
        gx = _outer(ctx, hist, o, x, floor, tol, k, trial, g)
        if abs(gx) <= tol:
            return
        if gx > 0:
            if side == 1:
                glo *= 0.5  # Illinois
            hi, ghi, side = x, gx, 1
        elif gx < 0:
            if side == -1:
                ghi *= 0.5
            lo, glo, side = x, gx, -1
        else:  # NaN: no sign to bracket with
            break
    _outer(ctx, hist, o, hi, floor, tol, k, trial, g)  # the upper end: G(hi) > 0


def _outer(ctx, hist, o, x, floor, tol, k, trial, g):
    """G(x) of :func:`_nested`: the outer yarn o at x, the inner yarn at its highest root
    below its history (g_inner >= 0 there always), both into ``trial``, alpha - target into
    ``g``; returns g[o]."""
    i = 1 - o
    trial[o] = x
    trial[i] = hist[i]
    _residual(ctx, trial, g)
    if g[i] > tol:
        _scan(ctx, trial, i, floor, tol, k)
        _residual(ctx, trial, g)
    return g[o]


def _residual(ctx, alpha, g):
    t1, t2 = target(ctx, alpha[0], alpha[1])
    g[0], g[1] = alpha[0] - t1, alpha[1] - t2


def _settled(ctx, alpha, tol, g):
    """Both yarns at a root (to tol) or broken."""
    _residual(ctx, alpha, g)
    return ((abs(g[0]) <= tol or alpha[0] <= 0.0) and (abs(g[1]) <= tol or alpha[1] <= 0.0))


def _fast(ctx, hist, alpha, floor, tol, iterations):
    """Fixed-point steps with contracting secant acceleration and bracket closing, from
    alpha (an upper bound of the path's root, g >= 0, or a converged value), in place."""
    nan = math.nan
    u = alpha.copy()
    gu = np.empty(2)
    _residual(ctx, u, gu)
    prev_u = np.full(2, nan)
    prev_gu = np.full(2, nan)
    lo = np.full(2, nan)
    glo = np.full(2, nan)
    side = np.zeros(2, np.int64)
    x = u.copy()
    g = np.empty(2)
    done = np.empty(2, np.bool_)
    for k in range(2):
        done[k] = abs(gu[k]) <= tol or u[k] == 0.0
    for _ in range(iterations):
        if done[0] and done[1]:
            break
        for k in range(2):
            if done[k]:
                continue
            if math.isnan(lo[k]):
                d = u[k] - gu[k]
                if prev_u[k] != u[k] and not math.isnan(prev_u[k]):
                    slope = (prev_gu[k] - gu[k]) / (prev_u[k] - u[k])  # = 1 - target'
                    if 0.05 <= slope <= 1.0:
                        secant = u[k] - gu[k] / slope
                        if math.isfinite(secant):
                            d = secant
                x[k] = d if not d < floor else floor
            else:
                x[k] = _falsi_or_bisect(lo[k], glo[k], u[k], gu[k])
        _residual(ctx, x, g)
        for k in range(2):
            if done[k]:
                if abs(g[k]) <= tol or x[k] <= 0.0:
                    continue
                # converged while the other yarn moved on: re-bracket it, then go on with it
                prev_u[k], prev_gu[k], side[k], done[k] = nan, nan, 0, False
                if g[k] > 0:
                    u[k], gu[k], lo[k], glo[k] = x[k], g[k], nan, nan
                else:
                    u[k], gu[k], lo[k], glo[k] = hist[k], nan, x[k], g[k]
            if abs(g[k]) <= tol or (not math.isnan(lo[k]) and u[k] - lo[k] <= tol):
                done[k] = True
            elif g[k] > 0:
                if side[k] == 1:
                    glo[k] *= 0.5  # Illinois
                prev_u[k], prev_gu[k] = u[k], gu[k]
                u[k], gu[k], side[k] = x[k], g[k], 1
                if x[k] <= floor:  # still above the root at the floor: broken yarn
                    x[k], done[k] = 0.0, True
            else:
                if side[k] == -1:
                    gu[k] *= 0.5
                lo[k], glo[k], side[k] = x[k], g[k], -1
    for k in range(2):
        alpha[k] = x[k] if done[k] else u[k]  # unconverged: the upper bound (>= the root)


def _falsi_or_bisect(lo, glo, hi, ghi):
    """Regula falsi in [lo, hi] where it falls inside, else the midpoint."""
    if ghi != glo:
        falsi = (lo * ghi - hi * glo) / (ghi - glo)
        if math.isfinite(falsi) and lo < falsi < hi:
            return falsi
    return 0.5 * (lo + hi)


def _scan(ctx, alpha, i, floor, tol, k):
    """Yarn i: g on k - 1 grid points below its upper bound alpha[i], then regula falsi in
    the highest interval where g changes sign (the other yarn held), in place."""
    u = alpha[i]
    trial = alpha.copy()
    g = np.empty(2)
    has, lo, glo, hi = False, 0.0, -1.0, u
    first = max(u / k, floor)
    for j in range(k - 1, 0, -1):  # from the top: the highest sign change
        trial[i] = max(u * (j / k), floor)
        _residual(ctx, trial, g)
        if g[i] <= 0:
            has, lo, glo = True, trial[i], g[i]
            break
        hi = trial[i]
    if not has:
        lo, hi = 0.0, first
    ghi = math.nan
    x = 0.5 * (lo + hi)
    side = 0
    for _ in range(80):
        trial[i] = x
        _residual(ctx, trial, g)
        gx = g[i]
        if abs(gx) <= tol or hi - lo <= tol:
            alpha[i] = x
            return
        if not has and hi <= 2 * floor and gx > 0:
            alpha[i] = 0.0
            return
        if gx > 0:
            if side == 1:
                glo *= 0.5
            hi, ghi, side = x, gx, 1
        else:
            if side == -1:
                ghi *= 0.5
            lo, glo, side = x, gx, -1
        x = _falsi_or_bisect(lo, glo, hi, ghi)
    alpha[i] = x
