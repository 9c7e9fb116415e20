"""Residual velocity above the ballistic limit: the Lambert-Jonas law (J. P. Lambert and
G. H. Jonas, BRL-R-1852, 1976), Vr = a (V^p - Vbl^p)^(1/p) for V > Vbl, 0 below, fitted to the
perforating runs of a ballistic-limit estimate (``fabric-fenicsx v50``) by scipy's bounded
least squares (analytic Jacobian, best of three starts), with 95 % intervals of a, p and Vbl from
a case-resampling bootstrap (percentile intervals of the refits of resampled runs, each started
from the fit of all runs, seeded: the same runs give the same intervals).
A bootstrap because p and Vbl are strongly correlated and their least-squares distribution is
far from normal with the ten-odd points a study has. Pure numpy/scipy.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

__all__ = ["residual_velocity", "LambertJonasFit", "fit_lambert_jonas"]

P_BOUNDS = (1.0, 10.0)
"""The exponent's range (p = 2 is the energy balance of a rigid projectile with a massless plate)."""

A_MAX = 1.0
"""Upper bound of a: in Lambert and Jonas's derivation a = m_p / (m_p + m_plug), at most 1 (no
plug); without the bound a few scattered points near the limit can fit a > 1 with p -> 1."""


def residual_velocity(v, a: float, p: float, vbl: float) -> np.ndarray:
    """Lambert-Jonas: a (V^p - Vbl^p)^(1/p) above Vbl, 0 at and below it (m/s)."""
    v = np.asarray(v, float)
    return a * np.maximum(v ** p - vbl ** p, 0.0) ** (1.0 / p)


@dataclass(frozen=True)
class LambertJonasFit:
    """Fitted a, p, Vbl (m/s) with 95 % bootstrap intervals (low, high), the rms residual (m/s),
    the number of perforating runs and of bootstrap refits, and the parameters the fit left on a
    bound of their range (``at_bound``: not determined by these runs)."""

    a: float
    p: float
    vbl: float
    a_ci: tuple
    p_ci: tuple
    vbl_ci: tuple
    rms: float
    n: int
    resamples: int
    at_bound: tuple = ()

    def to_dict(self) -> dict:
        return asdict(self)


STARTS = ((0.95, 2.0, 0.5), (0.9, 3.0, 0.9), (0.99, 1.5, 0.2))
"""Starts of the least squares: (a, p, Vbl as a fraction of the slowest perforation)."""


def _jacobian(v, a: float, p: float, vbl: float) -> np.ndarray:
    """d Vr / d (a, p, Vbl) of :func:`residual_velocity` at the runs above Vbl (0 at or below it)."""
    d = np.maximum(v ** p - vbl ** p, 0.0)
    live = d > 0.0
    jac = np.zeros((v.size, 3))
    dl, vl = d[live], v[live]
    root = dl ** (1.0 / p)
    jac[live, 0] = root
    dd_dp = vl ** p * np.log(vl) - (vbl ** p * np.log(vbl) if vbl > 0.0 else 0.0)
    jac[live, 1] = a * root * (-np.log(dl) / p ** 2 + dd_dp / (p * dl))
    jac[live, 2] = -a * root / dl * vbl ** (p - 1.0)
    return jac


def _fit(v, vr, vbl_max: float, start=None):
    """Least squares from the :data:`STARTS`, the best of them: one start alone can stay on a
    flat ridge (Vbl -> 0 with p large). A bootstrap refit (``start``: the fit of all runs) starts
    there only, and from the others too where that ends on a bound of p or Vbl."""
    from scipy.optimize import least_squares

    lower, upper = (1e-3, P_BOUNDS[0], 0.0), (A_MAX, P_BOUNDS[1], vbl_max)

    def solve(x0):
        x0 = np.clip(x0, lower, upper)
        return least_squares(lambda x: residual_velocity(v, *x) - vr, x0, jac=lambda x: _jacobian(v, *x),
                             bounds=(lower, upper), x_scale=(1.0, 1.0, max(vbl_max, 1.0)))

    generic = [(a0, p0, f * vbl_max) for a0, p0, f in STARTS]
    best = None
    if start is not None:
        best = solve((start[0], start[1], min(start[2], vbl_max)))
        p, vbl = best.x[1:]
        if not (p >= P_BOUNDS[1] * (1 - 1e-6) or vbl <= 1e-6 * vbl_max or vbl >= vbl_max * (1 - 1e-6)):
            generic = []
    for x0 in generic:
        r = solve(x0)
        if best is None or r.cost < best.cost:
            best = r
    return best.x, float(np.sqrt(2.0 * best.cost / v.size))


def fit_lambert_jonas(v, vr, resamples: int = 400, seed: int = 0) -> LambertJonasFit:
    """Fit a (up to :data:`A_MAX`), p (within :data:`P_BOUNDS`), Vbl (0 up to the slowest perforating velocity) to
    perforating runs at velocities ``v`` with residual velocities ``vr`` (m/s); needs at least
    four runs at three or more different velocities (three parameters)."""
    v = np.asarray(v, float)
    vr = np.asarray(vr, float)
    if v.shape != vr.shape or v.ndim != 1:
        raise ValueError(f"need one residual velocity per velocity, got {v.shape} and {vr.shape}")
    if v.size < 4 or np.unique(v).size < 3:
        raise ValueError(f"Lambert-Jonas has three parameters: it needs at least 4 perforating runs at 3 "
                         f"velocities, got {v.size} runs at {np.unique(v).size}")
    if not (np.all(np.isfinite(v)) and np.all(np.isfinite(vr))) or np.any(vr < 0) or np.any(vr > v):
        raise ValueError("residual velocities must be finite, >= 0 and below the impact velocity")
    x, rms = _fit(v, vr, float(v.min()))
    rng = np.random.default_rng(seed)
    boot = []
    for _ in range(resamples):
        i = rng.integers(0, v.size, v.size)
        if np.unique(v[i]).size < 3:
            continue
        boot.append(_fit(v[i], vr[i], float(v[i].min()), start=x)[0])
    boot = np.array(boot).reshape(-1, 3)
    lo, hi = (np.percentile(boot, (2.5, 97.5), axis=0) if len(boot) else (np.full(3, np.nan),) * 2)
    bounds = ((1e-3, A_MAX), P_BOUNDS, (0.0, float(v.min())))
    at_bound = tuple(name for name, value, (lo, hi) in zip(("a", "p", "vbl"), x, bounds)
                     if min(abs(value - lo), abs(value - hi)) <= 1e-6 * max(abs(hi), 1.0))
    return LambertJonasFit(a=float(x[0]), p=float(x[1]), vbl=float(x[2]), at_bound=at_bound,
                           a_ci=(float(lo[0]), float(hi[0])), p_ci=(float(lo[1]), float(hi[1])),
                           vbl_ci=(float(lo[2]), float(hi[2])), rms=rms, n=int(v.size), resamples=len(boot))
