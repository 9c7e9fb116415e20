"""The probability of perforation against impact velocity, fitted the way ballistic testing does
(``fabric-fenicsx v50``, docs/ballistic_limit.md).

Each counted run is a shot at velocity v that perforated (1) or was held (0). The probit model
P(v) = Phi((v - V50) / sigma) is fitted by maximum likelihood with statsmodels (``Probit``);
V50, sigma, V10 = V50 - 1.2816 sigma and V90 = V50 + 1.2816 sigma get 95 % intervals from the
profile likelihood ratio (the values whose likelihood-ratio statistic stays below the chi-square
quantile with one degree of freedom, 3.84): unlike the delta method it needs no normal
approximation of V50 = -b0 / b1, a ratio, and keeps its coverage at a few tens of shots (tested
on a stand-in in tests/studies/test_probit.py). Each profile point is a statsmodels fit with the
fixed quantity as an offset. Where no likelihood maximum exists (all runs alike, or every held
run slower than every perforating one: complete separation) there is no fit, only the bracket.

Beside the curve, a model-free estimate: the observed fraction perforated per velocity bin
with its Clopper-Pearson interval (:func:`binned`). Where a faster bin perforates significantly
less often than a slower one (their intervals do not overlap), or the fitted slope is not
positive, the outcomes are not monotone in velocity and one V50 does not describe them
(:func:`monotone_violations`). Pure numpy/scipy/statsmodels.
"""
from __future__ import annotations

import math
import warnings
from dataclasses import asdict, dataclass

import numpy as np

__all__ = ["LEVEL", "ProbitFit", "fit_probit", "separation", "binned", "monotone_violations",
           "probit_information"]

LEVEL = 0.95
"""Confidence level of every interval."""

Z90 = 1.2815515655446004
"""The standard normal's 90 % quantile: V90 = V50 + Z90 sigma, V10 = V50 - Z90 sigma."""


@dataclass(frozen=True)
class ProbitFit:
    """A probit fit (m/s). ``*_ci``: (low, high) of the 95 % profile-likelihood interval, an end
    ``None`` where the likelihood ratio stays below the threshold (the interval is open there).
    ``slope`` = 1 / sigma (s/m); ``loglik`` the maximised log-likelihood."""

    n: int
    perforated: int
    v50: float
    v50_ci: tuple
    sigma: float
    sigma_ci: tuple
    v10: float
    v10_ci: tuple
    v90: float
    v90_ci: tuple
    slope: float
    loglik: float

    @property
    def width(self) -> float:
        """Width of V50's interval (inf where it is open)."""
        lo, hi = self.v50_ci
        return math.inf if lo is None or hi is None else hi - lo

    def to_dict(self) -> dict:
        return {**asdict(self), "width": self.width if math.isfinite(self.width) else None}


def separation(v, perforated) -> tuple | None:
    """(fastest held, slowest perforated) where no held run is faster than a perforating one (no
    likelihood maximum exists: complete separation, or quasi-complete where both outcomes meet
    at one velocity; either end None if that outcome is missing); None where the outcomes
    overlap (a held run faster than a perforating one)."""
    v = np.asarray(v, float)
    y = np.asarray(perforated, bool)
    held = v[~y].max() if (~y).any() else None
    through = v[y].min() if y.any() else None
    if held is not None and through is not None and held > through:
        return None
    return (None if held is None else float(held), None if through is None else float(through))


def _probit(y, exog, offset, start=None):
    """statsmodels' probit fit; (params, loglik). Newton's method from ``start``; where it does
    not reach a finite maximum (a start far from it), BFGS from zero. Convergence warnings far
    out on a flat profile are expected and silenced; a fit that fails both ways raises."""
    import statsmodels.api as sm
    from statsmodels.tools.sm_exceptions import ConvergenceWarning, PerfectSeparationWarning

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        warnings.simplefilter("ignore", PerfectSeparationWarning)
        warnings.simplefilter("ignore", RuntimeWarning)
        model = sm.Probit(y, exog, offset=offset)
        try:
            res = model.fit(disp=0, method="newton", maxiter=100, start_params=start)
        except np.linalg.LinAlgError:
            res = None
        if res is None or not np.isfinite(res.llf):
            res = model.fit(disp=0, method="bfgs", maxiter=500, start_params=np.zeros(exog.shape[1]))
    if not np.isfinite(res.llf):
        raise FloatingPointError(f"the probit fit of {y.size} outcomes found no finite maximum "
                                 f"(parameters {np.asarray(res.params).tolist()})")
    return np.asarray(res.params, float), float(res.llf)


def fit_probit(v, perforated, level: float = LEVEL, intervals: str = "all") -> ProbitFit | None:
    """The probit fit of the outcomes ``perforated`` (bool) at velocities ``v`` (m/s), or None
    where no maximum exists (:func:`separation`) or the fitted slope is not positive (the
    outcomes do not rise with velocity). ``intervals``: ``"all"``, ``"v50"`` (V50's only: the
    estimate's stopping test) or ``"none"`` (the maximum only: the sequential design); the
    intervals not computed are (None, None)."""
    if intervals not in ("all", "v50", "none"):
        raise ValueError(f"intervals must be all, v50 or none, got {intervals!r}")
    from scipy.stats import chi2

    v = np.asarray(v, float)
    y = np.asarray(perforated, bool).astype(float)
    if v.shape != y.shape or v.ndim != 1:
        raise ValueError(f"need one outcome per velocity, got {v.shape} and {y.shape}")
    if not np.all(np.isfinite(v)):
        raise ValueError(f"velocities must be finite, got {v[~np.isfinite(v)][:3]}")
    if separation(v, y.astype(bool)) is not None:
        return None
    (b0, b1), llf = _probit(y, np.column_stack([np.ones_like(v), v]), None)
    if not b1 > 0:
        return None
    threshold = float(chi2.ppf(level, 1))
    v50, sigma = -b0 / b1, 1.0 / b1
    span = max(v.max() - v.min(), sigma)

    def quantile_ci(z):
        vq = v50 + z * sigma

        def deviance(m):
            (_,), ll = _probit(y, (v - m)[:, None], np.full_like(v, z), start=[b1])
            return 2.0 * (llf - ll) - threshold
        return vq, _roots(deviance, vq, 20.0 * span, xtol=1e-3 * sigma)

    def sigma_ci():
        def deviance(b):
            (_,), ll = _probit(y, np.ones((v.size, 1)), b * v, start=[-b * v50])
            return 2.0 * (llf - ll) - threshold
        lo_b, hi_b = _roots(deviance, b1, b1, lower=b1 * 1e-6, upper_factor=1e3, xtol=1e-3 * b1)
        return (None if hi_b is None else 1.0 / hi_b, None if lo_b is None else 1.0 / lo_b)

    v50, v50_ci = quantile_ci(0.0) if intervals != "none" else (v50, (None, None))
    if intervals == "all":
        (v10, v10_ci), (v90, v90_ci), s_ci = quantile_ci(-Z90), quantile_ci(Z90), sigma_ci()
    else:
        (v10, v10_ci), (v90, v90_ci), s_ci = (v50 - Z90 * sigma, (None, None)), (v50 + Z90 * sigma, (None, None)), \
            (None, None)
    return ProbitFit(n=int(v.size), perforated=int(y.sum()), v50=float(v50), v50_ci=v50_ci,
                     sigma=float(sigma), sigma_ci=s_ci, v10=float(v10), v10_ci=v10_ci,
                     v90=float(v90), v90_ci=v90_ci, slope=float(b1), loglik=llf)


def _roots(f, x0: float, reach: float, lower: float | None = None, upper_factor: float | None = None,
           xtol: float = 1e-6) -> tuple:
    """Where ``f`` (negative at ``x0``) crosses zero below and above ``x0``: searched out to
    ``reach`` on each side (or down to ``lower`` and up to ``x0 * upper_factor``) in doubling
    steps, then refined by Brent's method to ``xtol``; None on a side where it stays negative."""
    from scipy.optimize import brentq

    def side(direction):
        step = reach / 64.0 if lower is None else None
        inner = x0
        for i in range(1, 12):
            if lower is None:
                outer = x0 + direction * step * 2 ** (i - 1)
                if abs(outer - x0) > reach:
                    return None
            else:
                outer = x0 * (0.5 ** i if direction < 0 else 2.0 ** i)
                if outer < lower or outer > x0 * upper_factor:
                    return None
            if f(outer) > 0:
                lo, hi = sorted((inner, outer))
                return float(brentq(f, lo, hi, xtol=xtol))
            inner = outer
        return None
    return side(-1), side(+1)


def binned(v, perforated, edges, level: float = LEVEL) -> list[dict]:
    """The observed fraction perforated in each velocity bin [edges[i], edges[i+1]) (the last
    bin closed) with its Clopper-Pearson interval: rows {lo, hi, v_mean, n, perforated,
    fraction, ci}; empty bins are left out."""
    from statsmodels.stats.proportion import proportion_confint

    v = np.asarray(v, float)
    y = np.asarray(perforated, bool)
    edges = np.asarray(edges, float)
    which = np.clip(np.searchsorted(edges, v, side="right") - 1, 0, edges.size - 2)
    rows = []
    for i in range(edges.size - 1):
        inside = which == i
        n = int(inside.sum())
        if not n:
            continue
        k = int(y[inside].sum())
        lo, hi = proportion_confint(k, n, alpha=1.0 - level, method="beta")
        rows.append({"lo": float(edges[i]), "hi": float(edges[i + 1]), "v_mean": float(v[inside].mean()),
                     "n": n, "perforated": k, "fraction": k / n, "ci": (float(lo), float(hi))})
    return rows


def monotone_violations(bins: list[dict]) -> list[tuple]:
    """Pairs of :func:`binned` rows (slower, faster) where the faster bin perforates significantly
    less often: its interval lies wholly below the slower bin's."""
    return [(a, b) for i, a in enumerate(bins) for b in bins[i + 1:] if b["ci"][1] < a["ci"][0]]


def probit_information(v, v50: float, sigma: float, each: bool = False) -> np.ndarray:
    """Fisher information of (V50, sigma) from shots at velocities ``v`` (one each) under the
    probit curve: sum of w / sigma^2 [[1, z], [z, z^2]], z = (v - V50) / sigma,
    w = phi(z)^2 / (Phi(z) (1 - Phi(z))). The outcome does not enter, so runs still running
    count too (the sequential design, :mod:`fabric_fenicsx.studies.neyer`). ``each``: one 2 x 2
    matrix per velocity (shape (n, 2, 2)) instead of their sum."""
    from scipy.special import log_ndtr

    z = (np.atleast_1d(np.asarray(v, float)) - v50) / sigma
    # phi^2 / (Phi (1 - Phi)) in logs: finite far out in the tails, where Phi (1 - Phi) underflows
    log_w = -z * z - math.log(2.0 * math.pi) - log_ndtr(z) - log_ndtr(-z)
    w = np.exp(log_w)
    m = np.stack([np.stack([w, w * z], -1), np.stack([w * z, w * z * z], -1)], -2) / sigma ** 2
    return m if each else m.sum(axis=0)
