"""Material points of the static scenes (:mod:`fabric_fenicsx.studies.static`): the unit cell
as a material point, the surrogate, the ``backend`` argument of
:func:`~fabric_fenicsx.studies.static.run_scenario`, and the free-fill response (P2 = 0) of any
material point. Nothing here imports DOLFINx.
"""

from __future__ import annotations

import math
from typing import Callable

import numpy as np

from fabric_fenicsx.material.contract import DamageState, MaterialPoint
from fabric_fenicsx.material.fabric import Fabric
from fabric_fenicsx.material.unitcell import UnitCell

"""Upper / lower bound of the yarn bending stiffness (section 3.2, after Warren)."""
E2_MIN = -0.45


# ----------------------------------------------------------------------------- material points
class UnitCellPoint:
    """The yarn unit cell (:class:`~fabric_fenicsx.material.unitcell.UnitCell`) as a material point."""

    supports_free_fill = True
    label = "unit cell"

    def __init__(self, fabric: Fabric, n_elements: int | None = None):
        self.cell = UnitCell(fabric, n_elements=n_elements)

    def respond(self, E1, E2, alpha_hist=(1.0, 1.0)):
        return self.cell.respond(E1, E2, alpha_hist=alpha_hist)

    def constitutive_update(self, E1, E2, state: DamageState):
        """:class:`~fabric_fenicsx.material.contract.MaterialLaw`, one unit-cell solve per point:
        (P1, P2, new DamageState), P_i signed as the unit cell gives them (Eq. 2-31)."""
        E1, E2 = np.atleast_1d(E1).astype(float), np.atleast_1d(E2).astype(float)
        rs = [self.respond(e1, e2, (a1, a2)) for e1, e2, a1, a2
              in zip(E1, E2, np.atleast_1d(state.alpha1), np.atleast_1d(state.alpha2))]
        P1, P2, a1, a2 = (np.array([getattr(r, k) for r in rs]) for k in ("P1", "P2", "alpha1", "alpha2"))
        return P1, P2, DamageState(a1, a2)

    def wave_modulus(self, E1, E2, state: DamageState, dlam: float = 1e-6):
        """:class:`~fabric_fenicsx.material.contract.MaterialLaw`: per point the largest
        eigenvalue (N/m) of the symmetric part of dP_i/dlambda_j at frozen damage, by central
        differences of the unit cell's solve in the stretches (4 solves per point)."""
        from fabric_fenicsx.surrogate.table import symmetric_eigmax

        def P(e1, e2, alpha):
            r = self.cell.solve(e1, e2, alpha=alpha)
            return np.array([r.P1, r.P2])

        E1, E2 = np.atleast_1d(E1).astype(float), np.atleast_1d(E2).astype(float)
        out = np.empty(E1.size)
        for k, (e1, e2, a1, a2) in enumerate(zip(E1, E2, np.atleast_1d(state.alpha1),
                                                np.atleast_1d(state.alpha2))):
            lam = np.sqrt(1.0 + 2.0 * np.array([e1, e2]))
            cols = []
            for j in range(2):
                step = np.zeros(2)
                step[j] = dlam
                Ep, Em = 0.5 * ((lam + step) ** 2 - 1.0), 0.5 * ((lam - step) ** 2 - 1.0)
                cols.append((P(*Ep, (a1, a2)) - P(*Em, (a1, a2))) / (2.0 * dlam))
            (t11, t21), (t12, t22) = cols
            out[k] = symmetric_eigmax(t11, t12, t21, t22)
        return out


def surrogate_point(fabric: Fabric):
    """The unit-cell surrogate as a material point (imported only when asked for)."""
    from fabric_fenicsx.surrogate.table import material_point
    return material_point(fabric)


BACKENDS: dict[str, Callable[[Fabric], MaterialPoint]] = {
    "unitcell": UnitCellPoint,
    "surrogate": surrogate_point,
}


def _factory(backend) -> Callable[[Fabric], MaterialPoint]:
    """Turn the ``backend`` argument of :func:`run_scenario` into a factory fabric -> point."""
    if backend is None:
        return UnitCellPoint
    if isinstance(backend, str):
        if backend not in BACKENDS:
            raise ValueError(f"backend must be one of {sorted(BACKENDS)}, got {backend!r}")
        return BACKENDS[backend]
    if not isinstance(backend, type) and hasattr(backend, "respond"):
        def same(fabric, _point=backend):
            return _point
        same.single = True
        return same
    if callable(backend):
        return backend
    raise ValueError(f"backend must be None, a name in {sorted(BACKENDS)}, a material point with "
                     f"respond(E1, E2, alpha_hist) or a factory fabric -> material point; got {backend!r}")


def _label(point) -> str:
    return str(getattr(point, "label", type(point).__name__))


def respond_free_fill(point, E1: float, alpha_hist, E2_guess: float = 0.0,
                      search_step: float = 2.5e-4, xtol: float = 1e-12, subdivisions: int = 8):
    """Response at E1 with the fill free (P2 = 0, scenario 4) for any material point.

    E2 is a root of P2(E1, E2; alpha_hist) = 0, the first one met marching from ``E2_guess``
    against the sign of P2 (P2 grows with E2 while the yarns are intact), with a step that
    starts at ``search_step`` and doubles up to 0.05. Near the warp's complete failure P2(E2)
    is not monotone (it jumps where the warp breaks, and a second root lies on the broken
    branch), so a step that moves P2 away from zero is re-sampled at ``subdivisions`` points
    before the march goes on: a narrow root next to the guess is not stepped over. The
    bracket is closed by Brent's method to ``xtol`` in E2. A fill that carries no force at
    all (P2 = 0 at the guess, e.g. a broken fill) keeps the guess. Damage evolves from
    ``alpha_hist`` at every trial E2, so the returned state is that of the root.
    """
    from scipy.optimize import brentq

    trials = {}

    def p2(E2):
        E2 = float(E2)
        r = point.respond(E1, E2, alpha_hist)
        value = float(r.P2)
        if not math.isfinite(value):
            raise FloatingPointError(f"material point returned P2 = {value} at E1 = {E1}, "
                                     f"E2 = {E2}, alpha_hist = {tuple(alpha_hist)}")
        trials[E2] = r
        return value

    def fail(E2, P2):
        return RuntimeError(
            f"free fill: no E2 with P2 = 0 between E2 = {E2_guess:.6g} (P2 = {f_guess:.6g} N/m) "
            f"and E2 = {E2:.6g} (P2 = {P2:.6g} N/m) at E1 = {E1:.6g}, alpha_hist = "
            f"{tuple(alpha_hist)}; the material point's P2 must change sign in E2")

    a = float(E2_guess)
    fa = f_guess = p2(a)
    if fa == 0.0:
        return trials[a]
    direction = -1.0 if fa > 0.0 else 1.0
    h = float(search_step)
    bracket = None
    while bracket is None:
        if (direction < 0 and a <= E2_MIN) or abs(a - E2_guess) > 1.0:
            raise fail(a, fa)
        b = max(a + direction * h, E2_MIN)
        fb = p2(b)
        if (fb > 0.0) != (fa > 0.0) or fb == 0.0:
            bracket = (a, fa, b)
        elif (fb - fa) * direction <= 0.0:  # P2 moved away from zero: look inside the step
            x_prev, f_prev = a, fa
            for x in a + (b - a) * np.arange(1, subdivisions) / subdivisions:
                fx = p2(x)
                if (fx > 0.0) != (f_prev > 0.0) or fx == 0.0:
                    bracket = (x_prev, f_prev, x)
                    break
                x_prev, f_prev = x, fx
        a, fa, h = b, fb, min(2.0 * h, 0.05)
    lo, f_lo, hi = bracket
    if trials[hi].P2 == 0.0:
        return trials[hi]
    root = brentq(p2, min(lo, hi), max(lo, hi), xtol=xtol)
    r = trials[root] if root in trials else point.respond(E1, root, alpha_hist)
    scale = max(abs(f_lo), abs(float(trials[hi].P2)))
    if abs(float(r.P2)) > 1e-6 * scale:
        raise RuntimeError(f"free fill: P2 jumps from {f_lo:.6g} to {float(trials[hi].P2):.6g} N/m "
                           f"between E2 = {lo:.8g} and {hi:.8g} at E1 = {E1:.6g} without a root "
                           f"(left P2 = {float(r.P2):.6g} N/m at E2 = {root:.8g}); try a smaller step")
    return r
