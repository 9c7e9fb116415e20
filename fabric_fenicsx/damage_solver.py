"""The damage coupling of the unit cell (appendix A.1), solved per yarn and per point.

alpha_i = min(alpha_i^hist, alpha(mu_i^max(alpha))) (Eq. 2-25/A.12) is a fixed point of
target(alpha). With g(alpha) = alpha - target(alpha) >= 0 at alpha^hist, the loading path
reaches the largest root below alpha^hist. alpha = 0 (the yarn broken) is always a root too,
and where damage snaps target'(alpha) approaches 1 and more roots appear in between.

target is non-decreasing in alpha (a weaker yarn stretches more), so from an upper bound u
(g(u) > 0) the fixed-point step target(u) is again an upper bound of the largest root: it
never skips it. It is accelerated by the thesis's secant step where the secant slope shows a
contraction (target' < 0.95); a step that overshoots (g < 0) brackets a root, which the
Illinois variant of regula falsi closes. Where the fixed-point steps creep (target' near 1
over a long stretch: a snap), the remaining points scan g on a grid below u and close the
highest sign change. Vectorised over points; the yarns' coupling enters through target.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

Evaluate = Callable[[np.ndarray, np.ndarray], np.ndarray]
"""evaluate(rows, alpha) -> target for those rows: alpha and target of shape (len(rows), 2)."""


class DamageIterationError(RuntimeError):
    """The iteration did not converge; ``rows``: the unconverged points, ``alpha``: their
    last iterates (len(rows), 2), ``residual``: alpha - target(alpha) there."""

    def __init__(self, message: str, rows=None, alpha=None, residual=None):
        super().__init__(message)
        self.rows, self.alpha, self.residual = rows, alpha, residual


def solve_damage(alpha_hist: np.ndarray, target_hist: np.ndarray, evaluate: Evaluate,
                 floor: float, tol: float = 1e-10, fast_iterations: int = 40,
                 scan_points: int = 32, max_rounds: int = 4, accept: float = 1e-7) -> np.ndarray:
    """The new integrities alpha (n, 2), given alpha^hist (n, 2) and target(alpha^hist).

    ``floor``: the smallest integrity the caller still treats as a yarn in the cell; a root
    below it is returned as 0 (broken). The iteration aims at |alpha - target(alpha)| <= tol;
    a point that has not got there after ``max_rounds`` is accepted if its residual is below
    ``accept`` (1e-7: the stress error it leaves, 1e-7 of the yarn's intact force, is four
    orders below the surrogate's table error; met where an interpolated target is nearly
    singular, e.g. a yarn within 2e-5 in stretch of complete failure, r -> 0). Otherwise
    raises :class:`DamageIterationError` naming the first unconverged point.
    """
    alpha = alpha_hist.copy()
    g = alpha_hist - target_hist
    todo = np.flatnonzero(np.any(np.abs(g) > tol, axis=1))
    for _ in range(max_rounds):
        if todo.size == 0:
            return alpha
        alpha[todo] = _fast(alpha_hist[todo], alpha[todo], lambda r, a: evaluate(todo[r], a),
                            floor, tol, fast_iterations)
        g = alpha[todo] - _target(evaluate, todo, alpha[todo])
        todo = todo[np.any((np.abs(g) > tol) & (alpha[todo] > 0), axis=1)]
        for i in (0, 1):
            if todo.size == 0:
                break
            # only the yarns still off their root: a converged yarn (often one below its
            # critical stretch, target = its history) must not be moved by a scan
            g = alpha[todo] - _target(evaluate, todo, alpha[todo])
            rows = todo[np.abs(g[:, i]) > tol]
            if rows.size:
                alpha[rows] = _scan(alpha_hist[rows], alpha[rows], i,
                                    lambda r, a, rows=rows: evaluate(rows[r], a), floor, tol, scan_points)
        if todo.size:
            g = alpha[todo] - _target(evaluate, todo, alpha[todo])
            todo = todo[np.any((np.abs(g) > tol) & (alpha[todo] > 0), axis=1)]
    if todo.size == 0:
        return alpha
    g = alpha[todo] - _target(evaluate, todo, alpha[todo])
    unconverged = np.any(np.abs(g) > accept, axis=1)
    todo, g = todo[unconverged], g[unconverged]
    if todo.size == 0:
        return alpha
    k = todo[0]
    raise DamageIterationError(
        f"damage iteration did not converge for {todo.size} point(s); first: point {k}, "
        f"alpha_hist={tuple(alpha_hist[k])}, last alpha={tuple(alpha[k])}, "
        f"alpha - target(alpha) = {tuple(g[0])}", rows=todo, alpha=alpha[todo], residual=g)


def _target(evaluate: Evaluate, rows: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    return evaluate(rows, alpha)


def _fast(hist, alpha, evaluate, floor, tol, iterations):
    """Fixed-point steps with contracting secant acceleration and bracket closing, from
    alpha (an upper bound of the path's root, g >= 0, or a converged value)."""
    n = hist.shape[0]
    rows = np.arange(n)
    u = alpha.copy()
    gu = u - evaluate(rows, u)
    prev_u = np.full_like(u, np.nan)
    prev_gu = np.full_like(u, np.nan)
    lo = np.full_like(u, np.nan)
    glo = np.full_like(u, np.nan)
    side = np.zeros(u.shape, dtype=np.int8)
    x = u.copy()
    done = (np.abs(gu) <= tol) | (u == 0.0)
    reopened = np.zeros_like(done)
    for _ in range(iterations):
        if done.all():
            break
        with np.errstate(divide="ignore", invalid="ignore"):
            slope = (prev_gu - gu) / (prev_u - u)  # = 1 - target'
            secant = u - gu / slope
            falsi = (lo * gu - u * glo) / (gu - glo)
        contracting = np.isfinite(secant) & (slope >= 0.05) & (slope <= 1.0)
        descend = np.maximum(np.where(contracting, secant, u - gu), floor)
        inside = np.isfinite(falsi) & (falsi > lo) & (falsi < u)
        closing = np.where(inside, falsi, 0.5 * (lo + u))
        x = np.where(done, x, np.where(np.isnan(lo), descend, closing))
        active_rows = np.flatnonzero(~done.all(axis=1))
        g = np.zeros_like(x)
        g[active_rows] = x[active_rows] - evaluate(active_rows, x[active_rows])
        # A yarn converged while the other yarn of its point moved on: re-bracket it.
        row_active = np.zeros_like(done)
        row_active[active_rows] = True
        stale = done & row_active & (np.abs(g) > tol) & (x > 0.0)
        if stale.any():
            high, low = stale & (g > 0), stale & (g < 0)
            u = np.where(high, x, np.where(low, hist, u))
            gu = np.where(high, g, np.where(low, np.nan, gu))
            lo = np.where(low, x, np.where(high, np.nan, lo))
            glo = np.where(low, g, np.where(high, np.nan, glo))
            prev_u = np.where(stale, np.nan, prev_u)
            prev_gu = np.where(stale, np.nan, prev_gu)
            side = np.where(stale, 0, side).astype(np.int8)
            done = done & ~stale
            reopened |= stale
        active = ~done & row_active
        conv = active & ((np.abs(g) <= tol) | (~np.isnan(lo) & (u - lo <= tol)))
        above = active & ~conv & (g > 0)
        below = active & ~conv & (g <= 0)
        glo = np.where(above & (side == 1), 0.5 * glo, glo)  # Illinois
        gu = np.where(below & (side == -1), 0.5 * gu, gu)
        prev_u = np.where(above, u, prev_u)
        prev_gu = np.where(above, gu, prev_gu)
        u = np.where(above, x, u)
        gu = np.where(above, g, gu)
        lo = np.where(below, x, lo)
        glo = np.where(below, g, glo)
        side = np.where(above, 1, np.where(below, -1, side)).astype(np.int8)
        broken = above & (x <= floor)  # still above the root at the floor: broken yarn
        x = np.where(broken, 0.0, x)
        done = done | conv | broken
    # Unconverged entries return their upper bound (still >= the path's root).
    return np.where(done, x, u)


def _scan(hist, alpha, i, evaluate, floor, tol, k):
    """Yarn i of each point: g on k grid points below its upper bound, then regula falsi in
    the highest interval where g changes sign (the other yarn held)."""
    n = hist.shape[0]
    u = alpha[:, i].copy()
    frac = np.linspace(0.0, 1.0, k + 1)[1:-1]
    grid = np.maximum(u[:, None] * frac[None, :], floor)  # (n, k-1), ascending
    rows = np.repeat(np.arange(n), frac.size)
    trial = np.repeat(alpha, frac.size, axis=0)
    trial[:, i] = grid.ravel()
    g = (trial[:, i] - evaluate(rows, trial)[:, i]).reshape(n, frac.size)
    nonpos = g <= 0
    has = nonpos.any(axis=1)
    top = np.where(has, frac.size - 1 - np.argmax(nonpos[:, ::-1], axis=1), 0)
    lo = np.where(has, grid[np.arange(n), top], 0.0)
    glo = np.where(has, g[np.arange(n), top], -1.0)
    hi = np.where(has & (top + 1 < frac.size), grid[np.arange(n), np.minimum(top + 1, frac.size - 1)], u)
    hi = np.where(has, hi, grid[:, 0])
    ghi = np.full(n, np.nan)
    x = 0.5 * (lo + hi)
    out = alpha.copy()
    done = np.zeros(n, bool)
    side = np.zeros(n, np.int8)
    for _ in range(80):
        trial = alpha.copy()
        trial[:, i] = x
        gx = x - evaluate(np.arange(n), trial)[:, i]
        conv = ~done & ((np.abs(gx) <= tol) | (hi - lo <= tol))
        broken = ~done & ~has & (hi <= 2 * floor) & (gx > 0)
        out[:, i] = np.where(conv, x, np.where(broken, 0.0, out[:, i]))
        done |= conv | broken
        if done.all():
            break
        above, below = ~done & (gx > 0), ~done & (gx <= 0)
        glo = np.where(above & (side == 1), 0.5 * glo, glo)
        ghi = np.where(below & (side == -1), 0.5 * ghi, ghi)
        hi, ghi = np.where(above, x, hi), np.where(above, gx, ghi)
        lo, glo = np.where(below, x, lo), np.where(below, gx, glo)
        side = np.where(above, 1, np.where(below, -1, side)).astype(np.int8)
        with np.errstate(divide="ignore", invalid="ignore"):
            falsi = (lo * ghi - hi * glo) / (ghi - glo)
        ok = np.isfinite(falsi) & (falsi > lo) & (falsi < hi)
        x = np.where(ok, falsi, 0.5 * (lo + hi))
    out[:, i] = np.where(done, out[:, i], x)
    return out
