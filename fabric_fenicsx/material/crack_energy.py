"""The energy a yarn takes to break, and the damage law of a cell longer than the yarn's segment.

The fibril statistics of the thesis (Eq. 2-22 to 2-25) are those of one segment of a yarn, of
length h0 (the yarn spacing, 0.726 mm for Table 1's 35 yarns per inch). A straight yarn segment
carries F = alpha(mu) A (mu - 1) (Eq. 2-26 with the crimp pulled out), so that the work per unit
length and per unit A to break it (alpha = 0) is

    W(m, s) = m^2 / 2 + s m I0 + s^2 I1,    I0 = int_0^span a(u) du,  I1 = int_0^span u a(u) du,

with m = mu_crit - 1 the strain where damage starts, a(u) = alpha(mu_crit + u) the law's
softening profile over its span (0.03 for Eq. 2-25) and s the softening scale (the profile
stretched to s span). A tear through a row of unit cells takes W(m0, 1) A h0 per yarn it cuts.

A membrane cell of extent c > h0 along the yarn that tears smears that energy over c: with the
segment's own law it would take c / h0 times too much. The cell's law of equal energy
(:func:`equal_energy_law`, the crack band of Bazant and Oh, Materiaux et Constructions 16 (1983)
155-177, with the segment as the band) takes W(m, s) = (h0 / c) W(m0, 1): first by a shorter
softening branch (s < 1, damage still starting at mu_crit), and where even s = ``S_MIN`` holds
too much energy (the work done before damage alone exceeds the target: c > about 1.3 h0 for
Table 1's warp), by an earlier start of damage (m < m0) with the shortest branch: the strength
reduction of a band larger than the process zone (Bazant and Oh, section 4). Pure numpy.
"""
from __future__ import annotations

import numpy as np

__all__ = ["S_MIN", "softening_moments", "breaking_work", "equal_energy_law"]

S_MIN = 0.1
"""Shortest softening branch of a cell's law, as a fraction of the law's span (0.003 in stretch
for Eq. 2-25): about the surrogate table's strain resolution, so that damage still runs over a
few steps of the table rather than inside one interval."""


def softening_moments(law, mu_crit: float, n: int = 4001) -> tuple[float, float, float]:
    """(I0, I1, span) of the damage law's softening profile a(u) = alpha(mu_crit + u), u in
    [0, span] (span = mu_complete - mu_crit): the integrals of a and u a (trapezoidal rule on
    ``n`` points; the profile is smooth inside its span)."""
    span = float(law.mu_complete(mu_crit) - mu_crit)
    u = np.linspace(0.0, span, n)
    a = np.asarray(law.alpha(mu_crit + u, mu_crit), float)
    return float(np.trapz(a, u)), float(np.trapz(u * a, u)), span


def breaking_work(m, s, I0: float, I1: float) -> np.ndarray:
    """W(m, s) of the module docstring: work per unit length and per unit A (dimensionless) to
    break a straight yarn whose damage starts at strain ``m`` with softening scale ``s``."""
    m, s = np.asarray(m, float), np.asarray(s, float)
    return 0.5 * m * m + s * m * I0 + s * s * I1


def equal_energy_law(m0, s0, ratio, I0: float, I1: float, s_min: float = S_MIN):
    """(m, s): per point the damage onset strain and softening scale of a cell whose breaking
    work is ``ratio`` (= h0 / c, clipped to at most 1) times that of the segment's law (m0, s0)
    (arrays of one shape). ratio >= 1 keeps (m0, s0): a cell no longer than the segment keeps
    the segment's law. See the module docstring for the two branches; both are the roots of
    W(m, s) = target, quadratic in s at m = m0 and in m at s = s_min."""
    m0, s0 = np.asarray(m0, float), np.asarray(s0, float)
    q = np.minimum(np.asarray(ratio, float), 1.0)
    if np.any(~(q > 0.0)):
        raise ValueError(f"the ratio h0 / c must be > 0, got {np.min(q)!r}")
    s_min = np.minimum(s_min, s0)
    target = q * breaking_work(m0, s0, I0, I1)
    longer = target >= breaking_work(m0, s_min, I0, I1)
    # at m = m0: I1 s^2 + m0 I0 s + (m0^2 / 2 - target) = 0, the positive root
    c = 0.5 * m0 * m0 - target
    s = (-m0 * I0 + np.sqrt(np.maximum(m0 * m0 * I0 * I0 - 4.0 * I1 * c, 0.0))) / (2.0 * I1)
    # at s = s_min: m^2 / 2 + s_min I0 m + (s_min^2 I1 - target) = 0, the positive root
    m = -s_min * I0 + np.sqrt(np.maximum((s_min * I0) ** 2 - 2.0 * (s_min * s_min * I1 - target), 0.0))
    return np.where(longer, m0, m), np.where(longer, np.clip(s, s_min, s0), s_min)
