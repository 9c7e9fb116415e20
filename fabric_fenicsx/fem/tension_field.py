"""Tension-field relaxation of the yarn strains: a yarn that cannot carry compression wrinkles.

The unit cell gives a compressed yarn a compressive force P_j < 0 (an elastica in bending,
Eq. 2-31) while the crossing yarn i is stretched. The membrane has no bending stiffness, so it
carries no compression, and a yarn pushed below its force-free length wrinkles. Cutting P_j to
zero while P_i is still read at the apparent strain E_j is not a material law: P_i depends on
E_j through the contact (crimp interchange) but P_j no longer depends on E_i, so the stresses
are no gradient and a strain cycle through that band gives out work (measured: about -16 J/m^2
around a 0.004 x 0.004 square at E1 = 0.026, E2 = -0.022; the Y0 scene at 20 m/s gave 0.9 J
back over one rebound, docs/impact_model.md).

Tension-field theory (Pipkin's relaxed energy of a wrinkled membrane) instead takes the yarn at
the strain it wrinkles to: W_rel(E_i, E_j) = W(E_i, max(E_j, E_j*(E_i))), E_j* the strain where
P_j(E_i, E_j*) = 0. Its stresses are P_i(E_i, E_j*) and P_j = 0: a gradient field (dW/dE_j
vanishes at E_j*), so the work of a closed strain cycle is zero again. :func:`relaxed_strains`
returns the strains (E_i, E_j*) at which the unit cell is to be asked.

Where both yarns are equally intact (r = alpha_min / alpha_max = 1: the surrogate's intact layer,
forces scaled by alpha) E_j* depends on E_i alone: :class:`ForceFreeCurves` tabulates it per yarn,
built segment by segment where the run needs it and checked against the search (its own
tolerance, :data:`CURVE_TOL`); the other points, and intervals that failed the check, search.
The membrane's adapter searches by default (``YarnStress.curves``; why: docs/demo.md,
"2026-12-05: damage skip and tension-field table").
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fabric_fenicsx.material.unitcell import ALPHA_BROKEN
from fabric_fenicsx.surrogate.kernels import tension_field as curve_kernel
from fabric_fenicsx.surrogate.kernels.interp import ROOT_FOUND, ROOT_NONE

__all__ = ["relaxed_strains", "relax_in_place", "RelaxStats", "ForceFreeCurves", "CURVE_TOL", "CURVE_INTERVALS"]

CURVE_TOL = 1e-11
"""Largest difference in strain between the curve and the search's root (Newton to 1e-15) at an
interval's check points (1/4, 1/2, 3/4) for the interval to be used: 1e-11 of strain moves P_i
by about 1e-11 x |dP_i/dE_j| (1e-5 N/m), seven orders below the table's own interpolation error
(485 N/m, docs/surrogate.md). With 1e-9 the contact force of Y90 moved by 9e-5 of its peak in
the first 0.3 ms, with 1e-11 by 1e-7 (docs/demo.md, "2026-12-05")."""
CURVE_INTERVALS = 128
"""Curve intervals per table cell of the crossing yarn's strain (h / 128 = 1.56e-5 at h = 0.002):
the Hermite error falls 16 x per halving; 94 % of the intervals meet CURVE_TOL, the others hold
a kink of the table."""


@dataclass
class RelaxStats:
    """Counts over a run: point evaluations relaxed, and those left unrelaxed because P_j
    stayed compressive up to the table's top (no force-free length: none expected)."""
    relaxed: int = 0
    no_root: int = 0


def force_free_strain(surrogate, j, E_other, E_own, a1, a2, guess=None):
    """(root, status) of yarn j (0 warp, 1 fill): the strain in (E_own, 0] where its force
    vanishes, the crossing yarn at E_other, at frozen damage (a1, a2), and where P_j(E_other, 0)
    < 0 still, in (0, E_hi]; status ROOT_NONE (root = E_own) where there is none up to the
    table's top (``Surrogate.zero_force_strain``: Newton to 1e-15)."""
    root, status = surrogate.zero_force_strain(j + 1, E_other, E_own, np.zeros(E_own.size), a1, a2,
                                               guess)
    _beyond_rest_length(surrogate, j, E_other, E_own, a1, a2, root, status)
    return root, status


def _beyond_rest_length(surrogate, j, E_other, E_own, a1, a2, root, status):
    """:func:`force_free_strain`'s second search, in place: the points without a root up to the
    rest length (status ROOT_NONE) searched in (0, E_hi]; root = E_own where there is none
    there either. Returns those points' indices."""
    far = np.flatnonzero(status == ROOT_NONE)   # still compressive at the rest length
    if far.size:
        root[far], status[far] = surrogate.zero_force_strain(
            j + 1, E_other[far], np.zeros(far.size), np.full(far.size, surrogate.E_table[1]),
            a1[far], a2[far])
        none = far[status[far] == ROOT_NONE]
        root[none] = E_own[none]
    return far


class ForceFreeCurves:
    """The force-free strain X_j(E_i) of each yarn j of the intact layer (r = 1), tabulated over
    the crossing yarn's strain E_i in [0, E_hi] at CURVE_INTERVALS intervals per table cell,
    cubic Hermite (node values and slopes dX/dE_i = -(dP_j/dE_i) / (dP_j/dE_j), both from the
    table), built one table cell (a segment) at a time when a point first needs it: the nodes
    are the search's roots, and each interval is checked at 1/4, 1/2 and 3/4 against the search;
    an interval off by more than ``tol`` (a kink of the Catmull-Rom table inside it, or no root)
    is not used: its points search (:func:`relaxed_strains`). Building a segment costs
    4 CURVE_INTERVALS + 1 searches per yarn (a few milliseconds with its tiles built)."""

    def __init__(self, surrogate, intervals: int = CURVE_INTERVALS, tol: float = CURVE_TOL):
        self.sur, self.m, self.tol = surrogate, int(intervals), float(tol)
        self.step = surrogate.h / self.m
        segments = int(round(surrogate.E_table[1] / surrogate.h))
        n = segments * self.m
        self.x = np.full((2, n + 1), np.nan)
        self.s = np.full((2, n + 1), np.nan)
        self.ok = np.zeros((2, n), bool)
        self.built = np.zeros((2, segments), bool)
        self.checked = np.zeros(2, np.int64)   # intervals built, per yarn
        self.max_error = np.zeros(2)           # largest check error of the intervals in use

    def _roots(self, j, e):
        """The search's root of yarn j at crossing strains e (r = 1), NaN where there is none."""
        one = np.ones(e.size)
        root, status = force_free_strain(self.sur, j, e, np.full(e.size, self.sur.E_table[0]), one,
                                         one)
        return np.where(status == ROOT_FOUND, root, np.nan)

    def build(self, j, segments) -> None:
        """Solve and check yarn j's curve on ``segments`` (indices of table cells of E_i)."""
        m, step = self.m, self.step
        for c in np.unique(segments):
            k = c * m + np.arange(m + 1)
            e = k * step
            x = self._roots(j, e)
            one = np.ones(e.size)
            pts = (x, e) if j == 0 else (e, x)
            _, d1, d2 = self.sur.lookup(*(np.where(np.isnan(p), 0.0, p) for p in pts), one, one,
                                        (f"P{j + 1}",), derivative=True)
            own, other = (d1, d2) if j == 0 else (d2, d1)
            s = -other[:, 0] / own[:, 0] * step
            self.x[j, k], self.s[j, k] = x, s
            q = np.array([0.25, 0.5, 0.75])[:, None]
            X = ((2 * q ** 3 - 3 * q ** 2 + 1) * x[:-1] + (q ** 3 - 2 * q ** 2 + q) * s[:-1]
                 + (3 * q ** 2 - 2 * q ** 3) * x[1:] + (q ** 3 - q ** 2) * s[1:])
            exact = self._roots(j, ((k[:-1] + q) * step).ravel()).reshape(X.shape)
            error = np.abs(X - exact).max(axis=0)   # NaN where a root is missing: not ok
            ok = error <= self.tol
            self.ok[j, k[:-1]] = ok
            self.built[j, c] = True
            self.checked[j] += m
            if ok.any():
                self.max_error[j] = max(self.max_error[j], float(error[ok].max()))

    def relax(self, j, E_own, E_other, a1, a2):
        """(strains, relaxed count, points left to the search) of yarn j at the points: the
        curve's strain where they are intact-layer candidates (:func:`curve_kernel.relax_on_curve`)."""
        out, todo = np.empty(E_own.size), np.empty(E_own.size, np.int8)
        args = (self.x[j], self.s[j], self.ok[j], self.built[j], self.step, self.m)
        relaxed = curve_kernel.relax_on_curve(E_own, E_other, a1, a2, ALPHA_BROKEN, *args, out, todo)
        missing = np.flatnonzero(todo == curve_kernel.NEEDS_SEGMENT)
        if missing.size:
            k = np.minimum(np.floor(E_other[missing] / self.step).astype(np.int64), self.ok.shape[1] - 1)
            self.build(j, k // self.m)
            o, t = np.empty(missing.size), np.empty(missing.size, np.int8)
            relaxed += curve_kernel.relax_on_curve(E_own[missing], E_other[missing], a1[missing],
                                                   a2[missing], ALPHA_BROKEN, *args, o, t)
            out[missing], todo[missing] = o, t
        return out, relaxed, np.flatnonzero(todo == curve_kernel.SEARCH)


_NO_GUESS = np.empty(0)   # curve_kernel.candidates: no start guess


def _place(E_own, k, root, status):
    """:func:`curve_kernel.place_roots` of a search's (root, status): E_own[k] = root, and the
    numbers of roots found and of points without one."""
    return curve_kernel.place_roots(E_own, k, np.asarray(root, dtype=float),
                                    np.asarray(status, dtype=np.int8), ROOT_FOUND, ROOT_NONE)


def relaxed_strains(surrogate, E1, E2, a1, a2, stats: RelaxStats | None = None, guess=None,
                    curves: ForceFreeCurves | None = None):
    """(E1r, E2r): the strains of a tension field (module docstring), vectorised.

    surrogate: its signed ``lookup`` and ``zero_force_strain``
    (:class:`fabric_fenicsx.surrogate.table.Surrogate`) and ``E_table``; E1, E2 inside the
    table; a1, a2: the frozen damage. A yarn j is relaxed where it is compressed (E_j < 0) with
    P_j < 0 while the crossing yarn is stretched (E_i > 0): its strain becomes the root E_j* of
    P_j(E_i, .), searched in (E_j, 0] (the force-free length is near the rest length) and, where
    P_j(E_i, 0) < 0 still, in (0, E_hi]. Elsewhere the strains are returned unchanged (the slack
    rules of :mod:`fabric_fenicsx.fem.yarn_stress` apply there). ``guess``: (G1, G2) like E1,
    E2, where the searches start if inside their bracket (the last step's relaxed strains).
    ``curves``: None (every candidate searches) or the :class:`ForceFreeCurves` of
    ``surrogate``, which give the intact-layer points their force-free strain without a search."""
    E = [np.array(E1, dtype=float, copy=True), np.array(E2, dtype=float, copy=True)]
    relax_in_place(surrogate, E, a1, a2, stats, guess, curves)
    return E[0], E[1]


def relax_in_place(surrogate, E, a1, a2, stats: RelaxStats | None = None, guess=None,
                   curves: ForceFreeCurves | None = None) -> None:
    """:func:`relaxed_strains` of the list E = [E1, E2] (float arrays, overwritten; the curves
    put new arrays in the list). Without curves the candidates are gathered and the roots put
    back by compiled passes (:func:`curve_kernel.candidates`, :func:`curve_kernel.place_roots`),
    the search beyond the rest length made only when a point needs it."""
    if curves is not None:
        for j in (0, 1):
            i = 1 - j
            E[j], relaxed, k = curves.relax(j, E[j], E[i], a1, a2)
            if stats is not None:
                stats.relaxed += relaxed
            if k.size == 0:
                continue
            root, status = force_free_strain(surrogate, j, E[i][k], E[j][k], a1[k], a2[k],
                                             None if guess is None else guess[j][k])
            E[j][k] = root
            if stats is not None:
                stats.relaxed += int(np.count_nonzero(status == ROOT_FOUND))
                stats.no_root += int(np.count_nonzero(status == ROOT_NONE))
        return
    n = E[0].size
    a1, a2 = np.ascontiguousarray(a1, dtype=float), np.ascontiguousarray(a2, dtype=float)
    k, gathered = np.empty(n, np.int64), np.empty((5, n))
    for j in (0, 1):
        start = _NO_GUESS if guess is None else np.ascontiguousarray(guess[j], dtype=float)
        m = curve_kernel.candidates(E[j], E[1 - j], a1, a2, start, k, *gathered)
        if m == 0:
            continue
        other, own, b1, b2, g = gathered[:, :m]
        g = None if guess is None else g
        root, status = surrogate.zero_force_strain(j + 1, other, own, np.zeros(m), b1, b2, g)
        found, none = _place(E[j], k[:m], root, status)
        if none:   # force_free_strain's second search, where it has one to make
            far = _beyond_rest_length(surrogate, j, other, own, b1, b2, root, status)
            more, none = _place(E[j], k[:m][far], root[far], status[far])
            found += more
        if stats is not None:
            stats.relaxed += found
            stats.no_root += none
