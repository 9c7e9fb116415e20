"""The fabric's strength scatter: a random field on its yarn segments.

Every yarn segment of the fabric (a warp yarn between two fill crossings, a fill yarn between
two warp crossings; length h0 = the yarn spacing, the length of Eq. 2-22) has its own damage
law alpha(mu) = alpha_25(mu_c + (mu - mu_c) / s): the thesis's Eq. 2-25 with the segment's own
critical stretch mu_c and softening scale s. A segment is named by (family, yarn a, segment b),
its indices in the reference configuration rotated by the material angle (:func:`segment_index`);
its values come from a counter-based hash of (seed, family, a, b, draw), so any rank and any
mesh computes the same value for the same segment, without communication or a stored table.

Models (scene key ``material.scatter``):

* ``"none"``: the thesis's fitted mean, mu_c = mu_crit and s = 1 everywhere.
* ``"fibrils"``: the thesis's own statistics kept per segment (Sec. 2.3): the segment draws its
  n fibrils, r_j uniform (Eq. 2-22), each breaking at the yarn stretch
  mu_j* = sqrt(U^2 + x_j^2 (U^2 - 1)), x_j = r_j d0/h0, U = mu_crit. d0/h0 is the misalignment
  for which the least-squares fit of Eq. 2-25 to the infinite bundle gives the thesis's
  beta (:func:`misalignment_for_beta`; the thesis does not state d0/h0, only the fit's result).
  The segment keeps mu_c = U (its first fibril breaks there for any draw) and the scale
  s = mean_j(mu_j* - U) / E[mu* - U]: Eq. 2-25 stretched by the ratio of its mean rupture
  stretch to the bundle's.
* ``"weibull"``: the segment's critical strain mu_c - 1 is Weibull distributed with modulus m
  and median mu_crit - 1 (the thesis's value, derived at the segment's length h0); s = 1.

A cell of the membrane covers many segments; :func:`cell_laws` gives its law from them: the
weakest segment it covers (its docstring says why, measured). Pure numpy and numba; no DOLFINx.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit
from scipy.optimize import brentq

from fabric_fenicsx.material.fibril import ExponentialDamage, FibrilBundle, fit_beta

__all__ = ["SCATTER_MODELS", "FAMILIES", "WEIBULL_MODULUS", "ZYLON_AS_FILAMENTS",
           "StrengthScatter", "DamageRange", "segment_uniform", "segment_index",
           "misalignment_for_beta", "cell_laws", "CELL_RULES", "failure_stretch", "fibril_draws", "point_laws"]

SCATTER_MODELS = ("none", "fibrils", "weibull")
FAMILIES = ("warp", "fill")

WEIBULL_MODULUS = 11.7
"""Default Weibull modulus of the segment strength: the median of the six single-yarn fits of
Kevlar 49 (gauge 50-425 mm: 21.7, 11.5, 14.3, 11.9, 7.9, 8.8; Table 2 of the ICF13 paper on
Kevlar 49 fabric and yarn statistics, Zhu, Mobasher and Rajan, 13th International Conference
on Fracture, Beijing 2013). Aramid stands in for PBO: no Weibull fit of Zylon yarns was found
(docs/impact_model.md)."""

ZYLON_AS_FILAMENTS = 326
"""Filaments in a 500 denier (555 dtex) Zylon AS yarn: 555 dtex / 1.7 dtex per filament
(Toyobo, Zylon technical information, 2005, Basic properties)."""


# --------------------------------------------------------------------------- keyed uniforms
@njit(cache=True, inline="always")
def _mix(z):
    """SplitMix64's finaliser (Steele, Lea and Flood, OOPSLA 2014): a bijection of uint64 that
    spreads every input bit over the output."""
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return z ^ (z >> np.uint64(31))


@njit(cache=True)
def _uniform(seed, family, yarn, segment, draw):
    z = _mix(np.uint64(seed) + np.uint64(0x9E3779B97F4A7C15))
    z = _mix(z ^ np.uint64(family))
    z = _mix(z ^ np.uint64(yarn))       # int64 -> uint64: two's complement, negatives kept apart
    z = _mix(z ^ np.uint64(segment))
    z = _mix(z ^ np.uint64(draw))
    return ((z >> np.uint64(11)) + 0.5) * (1.0 / 9007199254740992.0)   # in (0, 1)


@njit(cache=True)
def _uniforms(seed, family, yarn, segment, draw, out):
    for k in range(out.size):
        out[k] = _uniform(seed, family, yarn[k], segment[k], draw)


def segment_uniform(seed: int, family: int, yarn, segment, draw: int = 0) -> np.ndarray:
    """Uniform numbers in (0, 1), one per (yarn, segment) of ``family`` (0 warp, 1 fill), from
    a hash of (seed, family, yarn, segment, draw): the same on every machine, rank and mesh."""
    yarn, segment = np.broadcast_arrays(np.asarray(yarn, np.int64), np.asarray(segment, np.int64))
    out = np.empty(yarn.shape)
    _uniforms(int(seed), int(family), np.ascontiguousarray(yarn).ravel(),
              np.ascontiguousarray(segment).ravel(), int(draw), out.reshape(-1))
    return out


def fibril_draws(seed: int, family: int, yarn: int, segment: int, n: int) -> np.ndarray:
    """The r_j (Eq. 2-22) of the n fibrils of one segment, as the ``"fibrils"`` model draws them
    (draw j of the segment's key)."""
    return np.array([segment_uniform(seed, family, [yarn], [segment], j)[0] for j in range(n)])


@njit(cache=True)
def _fibril_scales(seed, family, yarn, segment, n, d, U, mean_offset, out):
    """Per segment: mean_j (mu_j* - U) / mean_offset over its n fibrils (see the module)."""
    c = U * U - 1.0
    for k in range(out.size):
        acc = 0.0
        for j in range(n):
            x = _uniform(seed, family, yarn[k], segment[k], j) * d
            acc += math.sqrt(U * U + x * x * c) - U
        out[k] = acc / n / mean_offset


# --------------------------------------------------------------------------- geometry
def segment_index(points: np.ndarray, angle_deg: float, spacing: tuple[float, float]):
    """(yarn, segment) indices of reference points (n, 2) (m) for warp and fill:
    ((a_warp, b_warp), (a_fill, b_fill)). Warp runs along d1 = (cos angle, sin angle), fill
    along d2 = (-sin angle, cos angle); ``spacing`` = (2 w1, 2 w2), the projected warp and fill
    segment lengths (the yarn spacings). A warp yarn's index counts along d2 in steps of 2 w2,
    its segment along d1 in steps of 2 w1; the fill the other way round."""
    t = math.radians(float(angle_deg))
    c, s = math.cos(t), math.sin(t)
    x = points[:, 0] * c + points[:, 1] * s      # along the warp
    y = -points[:, 0] * s + points[:, 1] * c     # along the fill
    i1 = np.floor(x / spacing[0]).astype(np.int64)
    i2 = np.floor(y / spacing[1]).astype(np.int64)
    return (i2, i1), (i1, i2)


# --------------------------------------------------------------------------- damage law
def failure_stretch(law, mu_crit, scale) -> np.ndarray:
    """Stretch of complete failure (alpha = 0) of ``law`` with critical stretch ``mu_crit`` and
    softening scale ``scale`` (arrays): mu_crit + scale (law.mu_complete(mu_crit) - mu_crit)."""
    mu_crit, scale = np.asarray(mu_crit, float), np.asarray(scale, float)
    if isinstance(law, ExponentialDamage):
        span = np.full(mu_crit.shape, law.width)
    else:
        span = np.vectorize(lambda m: law.mu_complete(float(m)) - float(m))(mu_crit)
    return mu_crit + scale * span


@njit(cache=True, nogil=True)
def _first_outside(mu_crit, band, width, mu_safe, mu_complete):
    """:func:`point_laws`' check for the exponential law (failure at mu_crit + band width): the
    first flat index of (n, 2) ``mu_crit``, ``band`` outside the table's damage range, -1 if none
    (NaN counts as outside, as numpy's comparisons)."""
    for k in range(mu_crit.shape[0]):
        for i in range(2):
            m, s = mu_crit[k, i], band[k, i]
            if not (m >= mu_safe[i] - 1e-12 and m + s * width <= mu_complete[i] + 1e-12 and s > 0.0):
                return 2 * k + i
    return -1


def point_laws(law, critical_stretch, softening_scale, shape, mu_crit, band, mu_safe, mu_complete) -> None:
    """Each point's critical stretches (per yarn a scalar or an array of ``shape``) into
    ``mu_crit`` (n, 2) and its softening scales multiplied into ``band`` (n, 2), checked against
    a table that holds critical stretches from ``mu_safe`` and failure up to ``mu_complete``
    (per yarn; :class:`fabric_fenicsx.surrogate.table.Surrogate`'s damage range)."""
    for i in range(2):
        if critical_stretch is not None:
            mu_crit[:, i] = np.broadcast_to(np.asarray(critical_stretch[i], float), shape).ravel()
        if softening_scale is not None:
            band[:, i] *= np.broadcast_to(np.asarray(softening_scale[i], float), shape).ravel()
    if isinstance(law, ExponentialDamage):   # one compiled pass: the check ran every step
        first = _first_outside(mu_crit, band, float(law.width), np.asarray(mu_safe, float),
                               np.asarray(mu_complete, float))
    else:
        with np.errstate(invalid="ignore"):
            failure = failure_stretch(law, mu_crit, band)            # alpha = 0 from there on
            ok = (mu_crit >= mu_safe - 1e-12) & (failure <= mu_complete + 1e-12) & (band > 0.0)
        first = -1 if ok.all() else int(np.flatnonzero(~ok.ravel())[0])
    if first >= 0:
        n, i = divmod(first, 2)
        raise ValueError(
            f"point {n}, {FAMILIES[i]}: critical stretch {mu_crit[n, i]!r} with softening scale "
            f"{band[n, i]!r} lies outside the table's damage range (critical stretch >= "
            f"{mu_safe[i]!r}, complete failure <= {mu_complete[i]!r}); build the Surrogate with "
            f"the field's damage_range")


def misalignment_for_beta(beta: float, width: float, U_crit: float) -> float:
    """d0/h0 of the fibril bundle (Eq. 2-22, infinitely many fibrils) whose least-squares fit by
    Eq. 2-25 (:func:`fibril.fit_beta` on 601 stretches over [U, U + width]) gives ``beta``:
    the thesis's fit run backwards. The fit depends on d0/h0 only through the bundle's span."""
    mu = np.linspace(U_crit, U_crit + width, 601)

    def excess(d):
        bundle = FibrilBundle(d, n=1)
        return fit_beta(mu, bundle.alpha_limit(mu, U_crit), U_crit, width)[0] - beta

    hi = FibrilBundle.for_width(width, U_crit, n=1).d0_over_h0   # span = width: the smallest beta
    if excess(hi) > 0:
        raise ValueError(f"beta = {beta} is below the fit of a bundle spanning the whole width "
                         f"{width}; no misalignment gives it")
    lo = 0.25 * hi                                               # span ~ width / 16: beta ~ 10^3
    if excess(lo) < 0:
        raise ValueError(f"beta = {beta} needs a bundle narrower than a 16th of the width {width}")
    return brentq(excess, lo, hi, xtol=1e-12)


@dataclass(frozen=True)
class DamageRange:
    """Bounds of a damage field per yarn (warp, fill): the lowest critical stretch and the
    highest stretch of complete failure; the surrogate's table is built to hold them."""

    mu_crit_min: np.ndarray
    mu_complete_max: np.ndarray

    @classmethod
    def of_laws(cls, fabric, mu_crit: np.ndarray, scale: np.ndarray) -> "DamageRange":
        """The range of per-point laws ``mu_crit``, ``scale`` (n, 2), and of the fabric's own."""
        lo = np.array([min(fabric.yarns[i].mu_crit, float(mu_crit[:, i].min(initial=np.inf)))
                       for i in range(2)])
        hi = np.array([float(failure_stretch(fabric.damage, mu_crit[:, i], scale[:, i]).max(initial=0.0))
                       for i in range(2)])
        return cls(lo, hi)

    @staticmethod
    def union(*ranges: "DamageRange | None") -> "DamageRange | None":
        """The smallest range holding every given one (None, the fabric's own law, adds nothing;
        None if all are None)."""
        ranges = [r for r in ranges if r is not None]
        if not ranges:
            return None
        return DamageRange(np.min([r.mu_crit_min for r in ranges], axis=0),
                           np.max([r.mu_complete_max for r in ranges], axis=0))


@dataclass(frozen=True)
class StrengthScatter:
    """The strength scatter of a fabric (scene keys ``material.scatter``, ``material.seed``,
    ``material.weibull_modulus``, ``material.fibrils``); see the module docstring."""

    model: str = "none"
    seed: int = 0
    weibull_modulus: float = WEIBULL_MODULUS
    fibrils: int = ZYLON_AS_FILAMENTS

    def __post_init__(self):
        if self.model not in SCATTER_MODELS:
            raise ValueError(f"material.scatter = {self.model!r}: must be one of {list(SCATTER_MODELS)}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, (int, np.integer)) or self.seed < 0:
            raise ValueError(f"material.seed = {self.seed!r}: must be an integer >= 0")
        m = self.weibull_modulus
        if isinstance(m, bool) or not isinstance(m, (int, float)) or not (math.isfinite(m) and m > 0):
            raise ValueError(f"material.weibull_modulus = {m!r}: must be a finite number > 0")
        n = self.fibrils
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
            raise ValueError(f"material.fibrils = {n!r}: must be an integer >= 1 (fibrils per yarn)")

    @property
    def on(self) -> bool:
        return self.model != "none"

    def as_dict(self) -> dict:
        d = {"model": self.model, "seed": int(self.seed)}
        if self.model == "weibull":
            d["weibull_modulus"] = float(self.weibull_modulus)
        if self.model == "fibrils":
            d["fibrils"] = int(self.fibrils)
        return d

    def segment_laws(self, fabric, family: int, yarn, segment) -> tuple[np.ndarray, np.ndarray]:
        """(mu_c, s) of the segments (yarn, segment) of ``family`` (0 warp, 1 fill)."""
        yarn = np.ascontiguousarray(yarn, np.int64).ravel()
        segment = np.ascontiguousarray(segment, np.int64).ravel()
        mu_crit = fabric.yarns[family].mu_crit
        if self.model == "none":
            return np.full(yarn.size, mu_crit), np.ones(yarn.size)
        if self.model == "weibull":
            u = segment_uniform(self.seed, family, yarn, segment)
            m = float(self.weibull_modulus)
            strain = (mu_crit - 1.0) * (np.log1p(-u) / -math.log(2.0)) ** (1.0 / m)
            return 1.0 + strain, np.ones(yarn.size)
        law = fabric.damage
        if not isinstance(law, ExponentialDamage):
            raise ValueError("material.scatter = 'fibrils' needs the exponential damage law "
                             f"(Eq. 2-25) whose beta it reads, got {law!r}")
        d = misalignment_for_beta(law.beta, law.width, mu_crit)
        r = (np.arange(4096) + 0.5) / 4096   # E[mu* - U] for r ~ U(0, 1), midpoint rule
        mean_offset = float(np.mean(np.sqrt(mu_crit ** 2 + (r * d) ** 2 * (mu_crit ** 2 - 1)) - mu_crit))
        out = np.empty(yarn.size)
        _fibril_scales(self.seed, family, yarn, segment, int(self.fibrils), d, mu_crit,
                       mean_offset, out)
        return np.full(yarn.size, mu_crit), out

    def damage_range(self, fabric, mu_crit: np.ndarray, scale: np.ndarray) -> DamageRange | None:
        """The :class:`DamageRange` of per-point laws ``mu_crit``, ``scale`` (n, 2) (None when
        the scatter is off: the fabric's own law)."""
        return DamageRange.of_laws(fabric, mu_crit, scale) if self.on else None


# --------------------------------------------------------------------------- cells
CELL_RULES = ("weakest", "patch", "yarn")
"""How a cell reads the segments it covers (:func:`cell_laws`); the first is the default."""


def cell_laws(scatter: StrengthScatter, fabric, angle_deg: float, corners: np.ndarray,
              samples_per_segment: int = 2, rule: str = "weakest") -> tuple[np.ndarray, np.ndarray]:
    """(mu_c, s), each (n_cells, 2) for warp and fill, of quadrilateral cells with reference
    corners ``corners`` (n_cells, 4, 2) in perimeter order.

    ``rule = "weakest"`` (the default): per family, the law of the weakest segment the cell
    covers (the lowest stretch at half damage, mu_c + s (mu_half - mu_c)), over every yarn of
    the family in it. Measured, a strip of this membrane breaks when its weakest cell starts to
    damage (a tear then runs across it: the strip's strength follows its weakest cell's critical
    strain with correlation 0.95-0.98 over 100 seeds); with the weakest segment per cell, the
    weakest cell of any mesh holds the weakest segment of the fabric, and the strip's strength
    distribution is the same on 1 and 2 mm cells (docs/mesh_independence.md section 10).
    ``rule = "patch"`` (a patch at one strain: per yarn its weakest segment in the cell, the mean
    over the yarns, weighted by their share of the cell) and ``rule = "yarn"`` (only the yarn
    through the cell's centre) were measured too: both make finer meshes weaker.

    Segments are found by sampling the cell's bilinear map on a grid ``samples_per_segment``
    times finer than the shorter segment. With scatter "none" every cell gets the fabric's law
    exactly.
    """
    if rule not in CELL_RULES:
        raise ValueError(f"rule must be one of {list(CELL_RULES)}, got {rule!r}")
    corners = np.asarray(corners, float)
    nc = corners.shape[0]
    if not scatter.on or nc == 0:
        mu = np.array([fabric.warp.mu_crit, fabric.fill.mu_crit])
        return np.broadcast_to(mu, (nc, 2)).copy(), np.ones((nc, 2))
    spacing = (2.0 * fabric.warp.w, 2.0 * fabric.fill.w)
    # a sample grid per cell fine enough for its own size; cells of one grid size go together,
    # a bounded number of samples at a time
    extent = np.linalg.norm(corners[:, :, None, :] - corners[:, None, :, :], axis=-1).max(axis=(1, 2))
    ks = np.maximum(2, np.ceil(samples_per_segment * extent / min(spacing)).astype(np.int64) + 1)
    mu_out, s_out = np.empty((nc, 2)), np.empty((nc, 2))
    for k in np.unique(ks):
        chosen = np.flatnonzero(ks == k)
        per_chunk = max(1, _MAX_SAMPLES // int(k * k))
        for first in range(0, chosen.size, per_chunk):
            part = chosen[first:first + per_chunk]
            mu_out[part], s_out[part] = _cell_laws_on_grid(scatter, fabric, angle_deg, corners[part],
                                                           int(k), spacing, rule)
    return mu_out, s_out


_MAX_SAMPLES = 2_000_000
"""Sample points of :func:`cell_laws` handled at once (memory: about 100 bytes each)."""


def _cell_laws_on_grid(scatter, fabric, angle_deg, corners, k, spacing, rule):
    """:func:`cell_laws` of cells sampled on a k x k grid of their bilinear map."""
    nc = corners.shape[0]
    t = (np.arange(k) + 0.5) / k
    u, v = np.meshgrid(t, t, indexing="ij")
    u, v = u.ravel(), v.ravel()
    shape = np.stack([(1 - u) * (1 - v), u * (1 - v), u * v, (1 - u) * v])     # (4, k*k)
    points = np.einsum("qs,cqx->csx", shape, corners).reshape(-1, 2)           # (nc*k*k, 2)
    cell = np.repeat(np.arange(nc), k * k)
    exp_law = fabric.damage if isinstance(fabric.damage, ExponentialDamage) else None
    mu_out, s_out = np.empty((nc, 2)), np.empty((nc, 2))
    centres = segment_index(corners.mean(axis=1), angle_deg, spacing)
    for family, (a, b) in enumerate(segment_index(points, angle_deg, spacing)):
        if rule == "yarn":   # keep the samples on the centre's yarn only
            on = a == np.repeat(centres[family][0], k * k)
            a, b, cell_f = a[on], b[on], cell[on]
        else:
            cell_f = cell
        pairs, inverse = np.unique(np.stack([a, b], 1), axis=0, return_inverse=True)
        inverse = inverse.ravel()
        mu_seg, s_seg = scatter.segment_laws(fabric, family, pairs[:, 0], pairs[:, 1])
        span_half = _half_damage_offset(exp_law, fabric.damage, fabric.yarns[family].mu_crit)
        strength = (mu_seg + s_seg * span_half)[inverse]
        # per (cell, yarn), or per cell for "weakest": the weakest sample's segment, weighted by
        # the group's number of samples
        group = np.zeros_like(a) if rule == "weakest" else a
        order = np.lexsort((strength, group, cell_f))
        key_cell, key_group = cell_f[order], group[order]
        start = np.flatnonzero(np.r_[True, (np.diff(key_cell) != 0) | (np.diff(key_group) != 0)])
        weakest = order[start]                    # first of each group: the lowest strength
        count = np.diff(np.r_[start, order.size])
        group_cell = cell_f[weakest]
        seg = inverse[weakest]
        total = np.bincount(group_cell, weights=count, minlength=nc)
        mu_out[:, family] = np.bincount(group_cell, weights=count * mu_seg[seg], minlength=nc) / total
        s_out[:, family] = np.bincount(group_cell, weights=count * s_seg[seg], minlength=nc) / total
    return mu_out, s_out


def _half_damage_offset(exp_law, law, mu_crit: float) -> float:
    """mu - mu_crit at alpha = 1/2 of the law (the ordering of segments by strength)."""
    if exp_law is not None:
        b, w = exp_law.beta, exp_law.width
        # (e^{-b s} - e^{-b w}) / (1 - e^{-b w}) = 1/2
        return -math.log(0.5 * (1.0 + math.exp(-b * w))) / b
    return brentq(lambda s: float(law.alpha(mu_crit + s, mu_crit)) - 0.5, 0.0,
                  law.mu_complete(mu_crit) - mu_crit)
