"""Fibril scale: damage of a yarn through rupture of misaligned fibrils (thesis section 2.3).

A yarn is a bundle of fibrils, each linear elastic up to a sudden break at the critical fibril
stretch U_crit. Because fibril j is misaligned by d_j = r_j d0 over the characteristic length
h0, it is stretched less than the yarn (Eq. 2-22) and the fibrils break one after another: the
yarn damages gradually. The damage parameter alpha in [0, 1] is the fraction of unbroken fibrils
(Eq. 2-24); it scales the yarn stiffnesses, A = alpha A^0, B = alpha B^0 (Eq. 2-26).

Two damage laws share one interface, ``alpha(mu, mu_crit)`` and ``mu_complete(mu_crit)``:

* :class:`ExponentialDamage` - the thesis's fitted law, Eq. 2-25 / A.12 without the history
  terms (beta = 124, damage range 0.03 in stretch);
* :class:`BundleDamage` - the statistical fibril bundle itself (Eq. 2-22/2-23), with the fibril
  critical stretch U_crit taken equal to the yarn's critical stretch mu_crit.

:func:`damage_update` adds the history of Eq. 2-25 / A.12, :func:`fit_beta` is the least-squares
fit that turned the bundle curve into Eq. 2-25. Pure numpy/scipy; no DOLFINx.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from numbers import Integral

import numpy as np
from scipy.optimize import least_squares

__all__ = [
    "ExponentialDamage",
    "FibrilBundle",
    "BundleDamage",
    "damage_law_from_dict",
    "damage_update",
    "crack_band_alpha",
    "fit_beta",
]


# --------------------------------------------------------------------------- validation helpers
def _positive_finite(name: str, value) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a real number, got {value!r}") from None
    if not math.isfinite(v) or v <= 0.0:
        raise ValueError(f"{name} must be finite and > 0, got {value!r}")
    return v


def _critical_stretch(name: str, value) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a real number, got {value!r}") from None
    if not math.isfinite(v) or v <= 1.0:
        raise ValueError(f"{name} must be a finite critical stretch > 1, got {value!r}")
    return v


def _real_array(name: str, value) -> np.ndarray:
    """``value`` as a float array, or a ValueError naming ``name`` (not numpy's own message)."""
    try:
        return np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a real number or an array of them, got {value!r}") from None


def _stretch_array(name: str, value) -> np.ndarray:
    a = _real_array(name, value)
    if not np.all(np.isfinite(a)):
        bad = a[~np.isfinite(a)]
        raise ValueError(f"{name} contains non-finite values (e.g. {bad.flat[0]!r}); "
                         "check the yarn stretch computed upstream")
    if np.any(a <= 0.0):
        raise ValueError(f"{name} must be a stretch > 0, got minimum {a.min()!r}")
    return a


def _integer(name: str, value, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, Integral) or int(value) < minimum:
        raise ValueError(f"{name} must be an integer >= {minimum}, got {value!r}")
    return int(value)


# --------------------------------------------------------------------------- exponential law
@dataclass(frozen=True)
class ExponentialDamage:
    """Fitted exponential damage law, Eq. 2-25 (= Eq. A.12) without the history terms.

    With s = mu - mu_crit and w = ``width`` (0.03 in the thesis),

        alpha = 1                                                   for s <= 0,
        alpha = (exp(-beta s) - exp(-beta w)) / (1 - exp(-beta w))  for 0 < s < w,
        alpha = 0                                                   for s >= w.

    The middle expression is exactly 0 at s = w and would turn negative beyond; the yarn has then
    lost every fibril, so alpha = 0 for s >= w is the law's definition of complete failure (the
    clamp is part of the law, not a numerical guard). alpha is continuous at both ends, with
    kinks there. ``beta`` measures the fibril misalignment (124 in the thesis, from [10]).
    """

    beta: float = 124.0
    width: float = 0.03

    def __post_init__(self):
        object.__setattr__(self, "beta", _positive_finite("beta", self.beta))
        object.__setattr__(self, "width", _positive_finite("width", self.width))

    def mu_complete(self, mu_crit: float) -> float:
        """Yarn stretch at which the last fibril breaks: mu_crit + width (Eq. 2-25)."""
        return _critical_stretch("mu_crit", mu_crit) + self.width

    def alpha(self, mu, mu_crit: float) -> np.ndarray:
        """Fraction of unbroken fibrils after monotone loading to yarn stretch ``mu`` (Eq. 2-25)."""
        mu = _stretch_array("mu", mu)
        mu_crit = _critical_stretch("mu_crit", mu_crit)
        b, w = self.beta, self.width
        s = np.clip(mu - mu_crit, 0.0, w)
        # (e^{-bs} - e^{-bw}) / (1 - e^{-bw}) rewritten with expm1 of non-positive arguments:
        # no overflow for large beta, no cancellation for small beta.
        a = np.exp(-b * s) * np.expm1(-b * (w - s)) / np.expm1(-b * w)
        return np.where(s <= 0.0, 1.0, np.where(s >= w, 0.0, a))

    def dalpha_dmu(self, mu, mu_crit: float) -> np.ndarray:
        """d alpha / d mu of Eq. 2-25: -beta exp(-beta s) / (1 - exp(-beta w)) for 0 < s < w.

        Zero for mu <= mu_crit and mu >= mu_crit + width; at the two kinks the one-sided value
        outside the damage range (0) is returned.
        """
        mu = _stretch_array("mu", mu)
        mu_crit = _critical_stretch("mu_crit", mu_crit)
        b, w = self.beta, self.width
        s = mu - mu_crit
        inside = (s > 0.0) & (s < w)
        d = b * np.exp(-b * np.clip(s, 0.0, w)) / np.expm1(-b * w)  # expm1 < 0: d < 0
        return np.where(inside, d, 0.0)

    def to_dict(self) -> dict:
        return {"law": "exponential", "beta": self.beta, "width": self.width}


# --------------------------------------------------------------------------- statistical bundle
class FibrilBundle:
    """Statistical bundle of n misaligned fibrils (Eq. 2-22, 2-23).

    Fibril j has misalignment d_j = r_j d0 with r_j ~ U(0, 1) drawn by
    ``numpy.random.default_rng(seed).random(n)``; x_j = d_j / h0. At yarn stretch
    mu = (h0 + dh) / h0 its stretch is (Eq. 2-22)

        U_j = sqrt(mu^2 + x_j^2) / sqrt(1 + x_j^2),

    and it ruptures once U_j >= U_crit, i.e. at the yarn stretch
    mu_j* = sqrt(U_crit^2 (1 + x_j^2) - x_j^2) = sqrt(U_crit^2 + x_j^2 (U_crit^2 - 1)).
    mu_j* grows with x_j for every U_crit > 1, so sorting x once orders the ruptures for any
    U_crit: a fibril is broken at stretch mu >= U_crit iff x_j <= sqrt((mu^2 - U_crit^2) /
    (U_crit^2 - 1)), which :func:`numpy.searchsorted` counts in O(log n) per stretch.
    Only monotone loading is described here; unloading is handled by :func:`damage_update`.
    """

    def __init__(self, d0_over_h0: float, n: int = 20000, seed: int = 0):
        try:
            d = float(d0_over_h0) if not isinstance(d0_over_h0, bool) else float("nan")
        except (TypeError, ValueError):
            raise ValueError(f"d0_over_h0 must be a real number, got {d0_over_h0!r}") from None
        if not math.isfinite(d) or d < 0.0:
            raise ValueError(f"d0_over_h0 must be finite and >= 0, got {d0_over_h0!r}")
        self.d0_over_h0 = d
        self.n = _integer("n", n, 1)
        self.seed = _integer("seed", seed, 0)
        r = np.random.default_rng(self.seed).random(self.n)
        x = np.sort(r * d)
        x.flags.writeable = False
        self._x_sorted = x
        # Eq. 2-23 with rho_j = 1: per-fibril weight h0^3 / (h0^2 + d_j^2)^{3/2}; suffix sums give
        # the unbroken part after the k most-aligned fibrils have broken.
        weight = (1.0 + x * x) ** -1.5
        self._weight_suffix = np.concatenate([np.cumsum(weight[::-1])[::-1], [0.0]])

    @classmethod
    def for_width(cls, width: float = 0.03, U_crit: float = 1.025, n: int = 20000,
                  seed: int = 0) -> "FibrilBundle":
        """Bundle whose most misaligned possible fibril (r = 1) breaks at yarn stretch U_crit + width.

        d0/h0 = sqrt(((U_crit + width)^2 - U_crit^2) / (U_crit^2 - 1)), so the bundle spans the
        same damage range as Eq. 2-25 with the same ``width``.
        """
        width = _positive_finite("width", width)
        U = _critical_stretch("U_crit", U_crit)
        return cls(math.sqrt(((U + width) ** 2 - U * U) / (U * U - 1.0)), n=n, seed=seed)

    @property
    def x_sorted(self) -> np.ndarray:
        """Misalignments x_j = d_j / h0, ascending (read-only)."""
        return self._x_sorted

    def rupture_stretch(self, U_crit: float) -> np.ndarray:
        """Yarn stretches mu_j* at which the fibrils break, ascending."""
        U = _critical_stretch("U_crit", U_crit)
        return np.sqrt(U * U + self._x_sorted ** 2 * (U * U - 1.0))

    def mu_complete(self, U_crit: float) -> float:
        """Yarn stretch at which the most misaligned possible fibril (d = d0) breaks.

        Every fibril of the sample is broken there (r_j < 1), so alpha(mu_complete) = 0.
        """
        U = _critical_stretch("U_crit", U_crit)
        return math.sqrt(U * U + self.d0_over_h0 ** 2 * (U * U - 1.0))

    def _n_broken(self, mu, U_crit: float) -> np.ndarray:
        mu = _stretch_array("mu", mu)
        U = _critical_stretch("U_crit", U_crit)
        loaded = mu >= U
        x_threshold = np.where(
            loaded, np.sqrt(np.maximum(mu * mu - U * U, 0.0) / (U * U - 1.0)), -1.0)
        return np.searchsorted(self._x_sorted, x_threshold, side="right")

    def alpha(self, mu, U_crit: float) -> np.ndarray:
        """Fraction of unbroken fibrils after monotone loading to yarn stretch ``mu`` (Eq. 2-24)."""
        return 1.0 - self._n_broken(mu, U_crit) / self.n

    def effective_modulus_ratio(self, mu, U_crit: float) -> np.ndarray:
        """E_I* / E_I of Eq. 2-23: (h0^3 / n) sum_j rho_j / (h0^2 + d_j^2)^{3/2} at stretch ``mu``.

        Below U_crit no fibril is broken and the ratio is the undamaged mean of
        (1 + x_j^2)^{-3/2} (-> 1 / sqrt(1 + (d0/h0)^2) for n -> infinity).
        """
        return self._weight_suffix[self._n_broken(mu, U_crit)] / self.n

    def alpha_limit(self, mu, U_crit: float) -> np.ndarray:
        """alpha of the infinite bundle (n -> infinity), for comparison with the sample.

        With r uniform, the broken fraction is P(r <= x_thr / x0), so
        alpha = 1 - sqrt((mu^2 - U_crit^2) / (mu_complete^2 - U_crit^2)) on the damage range:
        a square-root onset, infinitely steep at mu = U_crit.
        """
        mu = _stretch_array("mu", mu)
        U = _critical_stretch("U_crit", U_crit)
        if self.d0_over_h0 == 0.0:
            return np.where(mu >= U, 0.0, 1.0)
        span = self.mu_complete(U) ** 2 - U * U
        return 1.0 - np.sqrt(np.clip((mu * mu - U * U) / span, 0.0, 1.0))

    def __repr__(self) -> str:
        return f"FibrilBundle(d0_over_h0={self.d0_over_h0!r}, n={self.n}, seed={self.seed})"


@dataclass(frozen=True)
class BundleDamage:
    """The statistical bundle (Eq. 2-22/2-23) used directly as the yarn's damage law.

    Same interface as :class:`ExponentialDamage`; the fibril critical stretch is U_crit = mu_crit,
    so the first rupture happens at the yarn's mu_crit and the last at ``mu_complete(mu_crit)``.
    alpha is the tabulated bundle curve: a staircase with steps of 1/n.

    ``dalpha_dmu`` is deliberately not offered as a number: the finite bundle's alpha is piecewise
    constant (derivative 0 almost everywhere, a jump at every rupture), so no tangent exists that
    is both exact and useful; use :class:`ExponentialDamage` where a damage tangent is needed.
    """

    d0_over_h0: float
    n: int = 20000
    seed: int = 0
    bundle: FibrilBundle = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        b = FibrilBundle(self.d0_over_h0, self.n, self.seed)
        object.__setattr__(self, "d0_over_h0", b.d0_over_h0)
        object.__setattr__(self, "n", b.n)
        object.__setattr__(self, "seed", b.seed)
        object.__setattr__(self, "bundle", b)

    @classmethod
    def for_width(cls, width: float = 0.03, U_crit: float = 1.025, n: int = 20000,
                  seed: int = 0) -> "BundleDamage":
        """Bundle law spanning [U_crit, U_crit + width], see :meth:`FibrilBundle.for_width`."""
        b = FibrilBundle.for_width(width, U_crit, n, seed)
        return cls(b.d0_over_h0, b.n, b.seed)

    def alpha(self, mu, mu_crit: float) -> np.ndarray:
        """Fraction of unbroken fibrils at yarn stretch ``mu`` with U_crit = mu_crit (Eq. 2-24)."""
        return self.bundle.alpha(mu, mu_crit)

    def mu_complete(self, mu_crit: float) -> float:
        """Stretch at which the most misaligned possible fibril breaks (alpha = 0 from there)."""
        return self.bundle.mu_complete(mu_crit)

    def dalpha_dmu(self, mu, mu_crit: float):
        raise NotImplementedError(
            "BundleDamage.dalpha_dmu: the bundle's alpha is a staircase (steps of 1/n), its "
            "derivative is 0 almost everywhere; use ExponentialDamage(beta=fit_beta(...)[0]) "
            "where a damage tangent is required")

    def to_dict(self) -> dict:
        return {"law": "bundle", "d0_over_h0": self.d0_over_h0, "n": self.n, "seed": self.seed}


_LAWS = {"exponential": ExponentialDamage, "bundle": BundleDamage}


def damage_law_from_dict(d: dict):
    """Rebuild a damage law from the ``to_dict()`` of :class:`ExponentialDamage` or :class:`BundleDamage`."""
    if not isinstance(d, dict):
        raise ValueError(f"damage law description must be a dict, got {d!r}")
    law = d.get("law")
    if law not in _LAWS:
        raise ValueError(f"law must be one of {sorted(_LAWS)}, got {law!r}")
    params = {k: v for k, v in d.items() if k != "law"}
    allowed = {"exponential": {"beta", "width"}, "bundle": {"d0_over_h0", "n", "seed"}}[law]
    unknown = set(params) - allowed
    if unknown:
        raise ValueError(f"unknown parameter(s) {sorted(unknown)} for law {law!r}; "
                         f"valid: {sorted(allowed)}")
    if law == "bundle" and "d0_over_h0" not in params:
        raise ValueError("law 'bundle' needs d0_over_h0")
    return _LAWS[law](**params)


# --------------------------------------------------------------------------- history
def damage_update(alpha_hist, mu_max, law, mu_crit: float) -> np.ndarray:
    """Damage with history, Eq. 2-25 / A.12: alpha = min(1, alpha_hist, law.alpha(mu_max, mu_crit)).

    ``mu_max`` is the larger of the current and the history-maximum yarn stretch; ``alpha_hist``
    the damage stored so far. Arrays broadcast; alpha never increases.
    """
    a_hist = _real_array("damage_update: alpha_hist", alpha_hist)
    if np.any(np.isnan(a_hist)):
        raise ValueError("damage_update: alpha_hist contains NaN")
    if np.any((a_hist < 0.0) | (a_hist > 1.0)):
        raise ValueError(f"damage_update: alpha_hist must lie in [0, 1], got range "
                         f"[{a_hist.min()!r}, {a_hist.max()!r}]")
    a_law = law.alpha(mu_max, mu_crit)  # validates mu_max (NaN, <= 0) and mu_crit
    return np.minimum(1.0, np.minimum(a_hist, a_law))


# --------------------------------------------------------------------------- crack band
def crack_band_alpha(law, mu, mu_crit: float, scale) -> np.ndarray:
    """alpha of ``law`` with its softening branch shortened by the crack-band ``scale`` s in
    (0, 1]: alpha(mu_crit + (mu - mu_crit) / s) (Eq. 2-25 / 2-24). Damage starts at the same
    mu_crit; complete failure comes at mu_crit + s (mu_complete - mu_crit).

    A crack band (Bazant and Oh, Materiaux et Constructions 16 (1983) 155-177) would take
    s = l / h in a cell of length h > l, so that the softening work per unit length of a tear
    is that of a band of width l on every mesh. :mod:`fabric_fenicsx.studies.softening`
    measures why that cannot work for this fabric (docs/mesh_independence.md)."""
    mu = _stretch_array("mu", mu)
    mu_crit = _critical_stretch("mu_crit", mu_crit)
    s = _real_array("crack_band_alpha: scale", scale)
    if not np.all((s > 0.0) & (s <= 1.0)):
        raise ValueError(f"crack_band_alpha: scale must lie in (0, 1], got {s!r}")
    return law.alpha(np.where(mu > mu_crit, mu_crit + (mu - mu_crit) / s, mu), mu_crit)


# --------------------------------------------------------------------------- fit of beta
def _dalpha_dbeta(s: np.ndarray, beta: float, width: float) -> np.ndarray:
    # d/d beta of (e^{-bs} - E) / (1 - E), E = e^{-bw}, for 0 <= s <= w
    E = math.exp(-beta * width)
    one_minus_E = -math.expm1(-beta * width)
    es = np.exp(-beta * s)
    return (-s * es * one_minus_E + width * E * (1.0 - es)) / one_minus_E ** 2


def fit_beta(mu, alpha, mu_crit: float, width: float = 0.03) -> tuple[float, float]:
    """Least-squares fit of beta in Eq. 2-25 to a sampled damage curve alpha(mu).

    Only samples in the damage range mu_crit <= mu <= mu_crit + width are fitted (outside it the
    law is fixed at 1 or 0). The fit runs in log(beta) (so beta > 0) from the best point of a
    coarse log grid, with the analytic Jacobian. Returns (beta, rms residual of alpha).
    """
    mu = _real_array("fit_beta: mu", mu)
    alpha = _real_array("fit_beta: alpha", alpha)
    if mu.ndim != 1 or mu.shape != alpha.shape:
        raise ValueError(f"mu and alpha must be 1-D of equal length, got shapes "
                         f"{mu.shape} and {alpha.shape}")
    if not (np.all(np.isfinite(mu)) and np.all(np.isfinite(alpha))):
        raise ValueError("fit_beta: mu or alpha contains non-finite values")
    if np.any((alpha < 0.0) | (alpha > 1.0)):
        raise ValueError(f"fit_beta: alpha must lie in [0, 1], got range "
                         f"[{alpha.min()!r}, {alpha.max()!r}]")
    mu_crit = _critical_stretch("mu_crit", mu_crit)
    width = _positive_finite("width", width)
    s = mu - mu_crit
    keep = (s >= 0.0) & (s <= width)
    if np.count_nonzero((s > 0.0) & (s < width)) < 2:
        raise ValueError(f"fit_beta: need >= 2 samples with mu in ({mu_crit}, {mu_crit + width}), "
                         f"got {np.count_nonzero((s > 0.0) & (s < width))}")
    s, a = s[keep], alpha[keep]

    def model(beta):
        return np.exp(-beta * s) * np.expm1(-beta * (width - s)) / np.expm1(-beta * width)

    def residual(p):
        return model(math.exp(p[0])) - a

    def jac(p):
        beta = math.exp(p[0])
        return (_dalpha_dbeta(s, beta, width) * beta)[:, None]

    grid = np.logspace(-1, 4, 101)
    costs = [np.sum(residual([math.log(b)]) ** 2) for b in grid]
    p0 = math.log(grid[int(np.argmin(costs))])
    sol = least_squares(residual, [p0], jac=jac, method="lm", xtol=1e-15, ftol=1e-15, gtol=1e-15)
    if sol.status <= 0 or not np.isfinite(sol.x[0]):
        raise ValueError(f"fit_beta: least squares did not converge (status {sol.status}: "
                         f"{sol.message}); check the sampled curve")
    beta = math.exp(sol.x[0])
    rms = float(np.sqrt(np.mean(residual(sol.x) ** 2)))
    return beta, rms
