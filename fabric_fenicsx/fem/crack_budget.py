"""A crack cell's break with the work of one segment per yarn it cuts, in the unit cell's energy.

A tear through a row of unit cells breaks one segment, of length h0 (the yarn spacing on which
the fibril statistics of Eq. 2-22 to 2-25 are defined), of every yarn it cuts: it takes W_i h0
per unit of its length across the yarns, W_i the unit cell's work to break family i per unit
reference area along its own uniaxial path (the other yarn's strain 0, the segment's law):
:func:`unit_cell_breaking_work`, the damage dissipation
:class:`~fabric_fenicsx.fem.yarn_stress.YarnStress` books along that path. A membrane cell of
extent c along yarn i (its corners' range of x . d_i) on a crack's line cuts the yarns over its
width across, area / c, so that a crack takes that work per unit length on any mesh if each of
its cells gives up, per unit of reference area,

    b_i = min(h0 / c, 1) W_i

(a cell no longer than a segment breaks as a segment). How well the cells' widths tile the tear's
line is the mesh's: the broken cells' area / c summed over the tear's length is 0.96 to 1.05 on
the tear test's 1 and 2 mm meshes (docs/tear_test.md). The law of equal energy
(:mod:`fabric_fenicsx.material.crack_energy`) budgets the straight yarn's work along the law's own
path from intact, over each cell's width; a del-zone cell snaps to alpha 1/2 at its yarn's raised
stretch and does not take that path, and what a tear's unit cell gives up is not the straight
yarn's work (its crimp, the fill's share: 17-27 % more per 1 mm tear cell): the work per cut yarn
followed the cell's extent c, aligned 2.01 against 1.71-1.78 J/m on the turned and graded 1 mm
meshes (docs/tear_test.md). Along the uniaxial path W_i is the straight yarn's W(m0, 1) times its
modulus within 1.3 % (Zylon AS's warp: 3470 against 3516 J/m^2).

The **budget** (``ShearLag(budget=True)``, ``material.failure = "del_zone_budget"``): a crack cell
that has snapped holds its alpha_i at 1/2, and breaks through (alpha_i = 0) in the step at which
breaking would bring its dissipation of family i nearest its budget: D_i + w [Psi(alpha) -
Psi(alpha with alpha_i = 0)] at the step's strains, D_i the point's dissipation of family i so far
(:attr:`YarnStress.point_dissipation <fabric_fenicsx.fem.yarn_stress.YarnStress.point_dissipation>`),
w its weight, Psi the stored energy (:meth:`YarnStress.path_energy
<fabric_fenicsx.fem.yarn_stress.YarnStress.path_energy>`), rising by what it rose over the last
step (:func:`break_through`). Between the snap and the break the cell carries half its yarns' force
elastically, so that what breaking would give up rises smoothly with its strain: a law that went on
softening below 1/2 opened within a few steps at the tip and passed the budget by 8 % (median
over the aligned 1 mm tear's cells). Where the energy the cell stores at its snap already exceeds
its budget it breaks at once with that energy: a band longer than the process zone keeps its
strength (Bazant and Oh, Materiaux et Constructions 16 (1983) 155-177); a root snaps at its
segment's strength, where the straight yarn stores m0^2 / 2 of the segment's W(m0, 1) (58 % for
Eq. 2-25), so that a root in a cell longer than about 1.7 h0 breaks as it snaps. With a strength scatter each point's budget is W_i times its law's straight-yarn work
over the fabric's (:func:`~fabric_fenicsx.material.crack_energy.breaking_work`).
Pure numpy but for :func:`unit_cell_breaking_work`, which asks the surrogate.
"""
from __future__ import annotations

import weakref

import numpy as np

from fabric_fenicsx.fem.yarn_crack import BROKEN_ALPHA

__all__ = ["BREAKING_PATH_STEPS", "unit_cell_breaking_work", "break_through"]

BREAKING_PATH_STEPS = 3000
"""Steps of the uniaxial strain path of :func:`unit_cell_breaking_work`: 3000 and 6000 steps give
Zylon AS's warp budget within 0.1 % of each other (tests/fem/test_crack_budget.py)."""


_WORKS: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()
"""surrogate -> {(family, steps): W_i}: the path is a second a family, and every pull of a
study (or rule of an ensemble) on one surrogate asks the same."""


def unit_cell_breaking_work(surrogate, family: int, steps: int = BREAKING_PATH_STEPS) -> float:
    """W_i of the module docstring (J/m^2 of reference area): the damage dissipation of one
    point of ``surrogate`` strained along yarn ``family`` (0 warp, 1 fill) from 0 to past the
    segment's law's complete failure in ``steps`` equal steps, the other yarn's strain 0.
    Computed once per surrogate, family and ``steps``."""
    if family not in (0, 1):
        raise ValueError(f"family must be 0 (warp) or 1 (fill), got {family!r}")
    if steps < 100:
        raise ValueError(f"steps = {steps!r}: the path needs at least 100 steps to resolve the law")
    known = _WORKS.setdefault(surrogate, {})
    if (family, steps) not in known:
        known[(family, steps)] = _breaking_path(surrogate, family, steps)
    return known[(family, steps)]


def _breaking_path(surrogate, family: int, steps: int) -> float:
    """:func:`unit_cell_breaking_work` along its path, not memoised."""
    from fabric_fenicsx.fem.yarn_stress import YarnStress

    fabric = surrogate.fabric
    mu_crit = fabric.yarns[family].mu_crit
    mu_end = 1.0 + 1.5 * (float(fabric.damage.mu_complete(mu_crit)) - 1.0)
    E_end = 0.5 * (mu_end * mu_end - 1.0)
    point = YarnStress(surrogate, np.ones(1), True)
    zero = np.zeros(1)
    for E in np.linspace(0.0, E_end, steps + 1)[1:]:   # one point: a path, not a hot loop
        e = np.full(1, E)
        point.update(*((e, zero) if family == 0 else (zero, e)))
    left = (point.alpha1, point.alpha2)[family][0]
    if left > 0.0:
        raise RuntimeError(f"unit_cell_breaking_work: family {family} kept alpha {left:.3g} at Green strain "
                           f"{E_end:.4g}; the damage law's complete failure lies beyond mu {mu_end:.4f}")
    return float(point.damage_dissipation)


def break_through(total, budget, alpha, rise=0.0) -> np.ndarray:
    """A snapped crack cell's new alpha_i: 0 where ``total`` (what it would give up broken now, J)
    is nearer the ``budget`` (J) than it will be a step on, rising by ``rise`` (J, its rise over
    the last step) as it did: total + rise / 2 >= budget; else its ``alpha`` at most 1/2 (held).
    Arrays of one shape (``rise`` may be a scalar)."""
    total, budget, alpha, rise = (np.asarray(x, float) for x in (total, budget, alpha, rise))
    return np.where(total + 0.5 * np.maximum(rise, 0.0) >= budget, 0.0, np.minimum(alpha, BROKEN_ALPHA))
