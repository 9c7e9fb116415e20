"""The unit-cell surrogate at the membrane's quadrature points: the quadrature-point adapter.

:class:`YarnStress` is the :class:`~fabric_fenicsx.material.contract.QuadratureMaterial` of an
impact run. It keeps the damage history of every owned quadrature point (alpha1, alpha2,
Eq. 2-25) and turns the yarn strains of a step into the yarn stresses the membrane integrates:
the surrogate's P_i (Eq. 2-31), asked at the tension field's strains (a compressed yarn wrinkles to
its force-free strain, :mod:`fabric_fenicsx.fem.tension_field`), under the membrane's tension-only
and slack rules, plus a stiffness-proportional viscous stress; it books the energy released by
damage, the viscous work and the energy of removed points, and gives the wave modulus that sets
the stable time step.
The modelling choices behind each rule are in docs/impact_model.md.
"""
from __future__ import annotations

import numpy as np

from fabric_fenicsx.material.contract import DamageState
from fabric_fenicsx.material.fabric import Fabric
from fabric_fenicsx.fem.tension_field import ForceFreeCurves, RelaxStats, relax_in_place
from fabric_fenicsx.surrogate.kernels import yarn_stress as yarn_stress_kernel
from fabric_fenicsx.surrogate.table import lambda_tangent, symmetric_eigmax

__all__ = ["YarnStress", "straight_yarn_modulus", "WAVE_MODULUS_MARGIN"]

WAVE_MODULUS_MARGIN = 1.05
"""Bound of the wave modulus per point, in units of max(alpha1, alpha2) x the straight intact
yarn's modulus: over the default table (401 x 401 strain states at alpha 1, 0.5, 0.1, 0.01) the
largest eigenvalue of the interpolated tangent is 1.028 of it at every state the membrane can
reach, except on the jumps of the unit cell's compressive branch (10.4 x at alpha1 = 0.01,
E2 = -0.054), where the slope is that of the interpolant across a jump, not a wave speed."""


_NONE = np.zeros(0, np.int64)   # YarnStress.update: no point's damage changed

_PATH_S, _PATH_W = np.polynomial.legendre.leggauss(6)
_PATH_S, _PATH_W = 0.5 * (_PATH_S + 1.0), 0.5 * _PATH_W  # on [0, 1]: YarnStress.path_energy


def straight_yarn_modulus(fabric: Fabric) -> float:
    """Largest dP_i/dlambda_i (N/m) of a straight intact yarn, A_i w_i / (L_i 2 w_j) (Eq. 2-31
    with F_i = A_i (mu_i - 1), mu_i = lambda_i w_i / L_i once the crimp is pulled out)."""
    w = (fabric.warp.w, fabric.fill.w)
    return max(fabric.warp.A0 * w[0] / (fabric.warp.L * 2 * w[1]),
               fabric.fill.A0 * w[1] / (fabric.fill.L * 2 * w[0]))


class YarnStress:
    """The surrogate at the live quadrature points, with damage-scaled stiffness-proportional
    damping: the :class:`~fabric_fenicsx.material.contract.QuadratureMaterial` that
    ``CentralDifference`` calls (``update``, ``state``, ``max_wave_modulus``, ``remove``).

    surrogate: a :class:`fabric_fenicsx.surrogate.table.Surrogate`; weights: reference area dA of
    each point (m^2); damage: evolve alpha (Eq. 2-25) or keep alpha = 1 and ask the
    surrogate's intact layer only; beta: damping coefficient (s) of the viscous stress, whose
    rate takes the ``dt`` of :meth:`update`.

    Local (this rank) accumulators, J: ``viscous_dissipation``, ``damage_dissipation``,
    ``erosion_energy``. ``beyond_table``: point evaluations with a strain above the table
    (damage off only; with damage on such a yarn is broken). ``modulus_bounded``: point
    evaluations of :meth:`wave_modulus` whose tangent exceeded the bound and was cut to it.
    straight_modulus: the straight intact yarn's dP/dlambda (N/m), default from the fabric.
    laws: None (the fabric's damage law at every point) or (mu_crit, scale), each (n, 2): every
    point's own critical stretch and softening scale per yarn, a strength scatter's field
    (:func:`fabric_fenicsx.material.scatter.cell_laws`); the surrogate must have been built with
    its ``damage_range``.
    """

    def __init__(self, surrogate, weights: np.ndarray, damage: bool, beta: float = 0.0,
                 straight_modulus: float | None = None, laws=None):
        self.sur = surrogate
        self.k_straight = float(straight_yarn_modulus(surrogate.fabric) if straight_modulus is None
                                else straight_modulus)
        self.modulus_bounded = 0
        self.w = np.asarray(weights, dtype=float)
        n = self.w.size
        self.damage = bool(damage)
        self.beta = float(beta)
        self.live = np.ones(n, dtype=bool)
        self._idx = np.arange(n)
        self.E1, self.E2 = np.zeros(n), np.zeros(n)
        self.E1_prev, self.E2_prev = self.E1, self.E2
        self.lam = np.ones((2, n))
        self.E_relaxed = np.zeros((2, n))   # the tension field's strains of the last update
        self.E_peak = np.zeros((2, n))      # each point's largest yarn strains while live
        self.P_el = np.zeros((2, n))
        self.P_v = np.zeros((2, n))
        self.alpha1, self.alpha2 = np.ones(n), np.ones(n)
        self.viscous_dissipation = 0.0
        self.damage_dissipation = 0.0
        self.point_dissipation = np.zeros((2, n))
        """Each point's damage dissipation so far per yarn family (J, rows warp and fill): a step's
        release at the points where both families damaged is split as warp first, then fill."""
        self._budget_total = np.full((2, n), np.nan)   # a budgeted point's total at its last step
        self.erosion_energy = 0.0
        self.beyond_table = 0
        self.below_table = 0
        self.slack_tension = 0
        self.relax_stats = RelaxStats()
        # None: every wrinkled point searches its force-free strain (the default: the curves
        # change the answers by more than round-off, docs/demo.md, "2026-12-05"); or the
        # ForceFreeCurves of the surrogate (a Surrogate table, not a stand-in) to read them there
        self.curves: ForceFreeCurves | None = None
        self.E_lo, self.E_hi = surrogate.E_table
        self.mu_crit = self.scale = None
        self.damage_drive = None
        """None (the thesis's rule: a point's damage follows its own strains) or a callable
        (E1, E2, live) -> (Ebar1, Ebar2) over every point giving the strains that drive the
        damage (:class:`~fabric_fenicsx.fem.yarn_average.YarnAverage`)."""
        self.failure = None
        """None (the thesis's rule: every point damages by its own law) or a rule that hands the
        points their damage laws and accepts or takes back each new damage
        (:class:`~fabric_fenicsx.fem.yarn_crack.YarnCrack`: ``laws``, ``admit``)."""
        if laws is not None:
            mu_crit, scale = (np.asarray(x, float) for x in laws)
            if mu_crit.shape != (n, 2) or scale.shape != (n, 2):
                raise ValueError(f"laws must be two arrays of shape ({n}, 2), got {mu_crit.shape} "
                                 f"and {scale.shape}")
            self.mu_crit, self.scale = mu_crit.T.copy(), scale.T.copy()   # (2, n): rows per yarn

    def _driving_strains(self, r1, r2):
        """The live points' strains that drive their damage (``damage_drive``) from their own
        tension-field strains (r1, r2)."""
        n = self.w.size
        R1, R2 = np.zeros(n), np.zeros(n)
        R1[self._idx], R2[self._idx] = r1, r2
        D1, D2 = self.damage_drive(R1, R2, self.live)
        return D1[self._idx], D2[self._idx]

    # ------------------------------------------------------------------ surrogate access
    def _clip(self, E: np.ndarray) -> np.ndarray:
        return np.minimum(np.maximum(E, self.E_lo), self.E_hi)   # np.clip's overhead is 10 x this

    def _relax(self, E1, E2, a1, a2, guess=None):
        """The strains the unit cell is asked at: a compressed yarn whose unit-cell force is
        compressive while the crossing yarn is stretched is taken at its force-free strain
        (tension field, :mod:`fabric_fenicsx.fem.tension_field`); every other strain as given.
        ``guess``: where the force-free searches start (the last step's relaxed strains)."""
        E1, E2 = np.ascontiguousarray(E1, dtype=float), np.ascontiguousarray(E2, dtype=float)
        r = [np.empty(E1.size), np.empty(E1.size)]
        yarn_stress_kernel.clip(E1, E2, self.E_lo, self.E_hi, *r)
        relax_in_place(self.sur, r, a1, a2, self.relax_stats, guess, self.curves)
        yarn_stress_kernel.keep_given(*r, E1, E2, self.E_lo, self.E_hi)
        return r[0], r[1]

    def _intact(self, E1, E2, relaxed=None):
        """P1, P2 of intact yarns (alpha = 1: the surrogate's intact layer only), tension-only,
        at the tension field's strains ``relaxed`` = (R1, R2) of (E1, E2) (found when None)."""
        self.beyond_table += int(np.count_nonzero((E1 > self.E_hi) | (E2 > self.E_hi)))
        self.sur.stats.record(E1, E2)
        one = np.ones(E1.size)
        E1, E2 = self._relax(E1, E2, one, one) if relaxed is None else relaxed
        vals = self.sur.lookup(self._clip(E1), self._clip(E2), one, one, ("P1", "P2"))
        return np.maximum(vals[:, 0], 0.0), np.maximum(vals[:, 1], 0.0)

    def slack(self, E1, E2) -> tuple[np.ndarray, np.ndarray]:
        """Masks of the yarns that cannot carry tension (wrinkled, P_i = 0): compressed below
        the table's lower end, or compressed while the other yarn is not stretched (only a
        stretched crossing yarn keeps a compressed one taut, by crimp interchange)."""
        slack1, slack2 = np.empty(E1.size, bool), np.empty(E1.size, bool)
        yarn_stress_kernel.slack(E1, E2, self.E_lo, slack1, slack2)
        return slack1, slack2

    def _frozen_P(self, E1, E2, a1, a2):
        """P1, P2 at frozen damage with the tension field and slack rules of :meth:`update`."""
        if self.damage:
            P1, P2, _, _ = self.sur.evaluate(*self._relax(E1, E2, a1, a2), a1, a2)
        else:
            P1, P2 = self._intact(E1, E2)
        s1, s2 = self.slack(E1, E2)
        return np.where(s1, 0.0, P1), np.where(s2, 0.0, P2)

    def path_energy(self, E1, E2, a1, a2) -> np.ndarray:
        """Energy per reference area (J/m^2) stored at frozen damage (a1, a2): the work of the
        membrane's yarn stresses (tension-only, slack rules) along the straight strain path
        from the reference state, sum_i int_0^1 P_i(s E) dlambda_i/ds ds, by 6-point
        Gauss-Legendre quadrature in s. For an intact or uniformly damaged unit cell in
        tension this is its stored energy Psi (Eq. 2-26/2-28); where a yarn is compressed it
        stays the energy of the stresses the membrane actually uses."""
        if E1.size == 0:
            return np.zeros(0)
        s, w = _PATH_S, _PATH_W
        n = E1.size
        S = np.repeat(s, n)
        e1, e2 = np.tile(E1, s.size) * S, np.tile(E2, s.size) * S
        P1, P2 = self._frozen_P(e1, e2, np.tile(a1, s.size), np.tile(a2, s.size))
        dl1 = np.tile(E1, s.size) / np.sqrt(1.0 + 2.0 * e1)   # d lambda_i / ds
        dl2 = np.tile(E2, s.size) / np.sqrt(1.0 + 2.0 * e2)
        return (w[:, None] * (P1 * dl1 + P2 * dl2).reshape(s.size, n)).sum(axis=0)

    # ------------------------------------------------------------------ QuadratureMaterial
    @property
    def state(self) -> DamageState:
        """Damage history (alpha1, alpha2) of every owned point after the last :meth:`update`."""
        return DamageState(self.alpha1, self.alpha2)

    @property
    def strains(self) -> tuple[np.ndarray, np.ndarray]:
        """Yarn strains (E1, E2) of the last :meth:`update`."""
        return self.E1, self.E2

    def point_fields(self) -> dict[str, np.ndarray]:
        """The fields an impact run writes (:data:`~fabric_fenicsx.material.contract.POINT_FIELDS`)
        at every owned point after the last :meth:`update`, and each point's largest yarn strains
        while live (``E1_peak``, ``E2_peak``: :attr:`E_peak`, written to damage.npz)."""
        sdv1 = ((self.alpha1 > 0) | (self.alpha2 > 0)).astype(float)
        fields = {"P1": self.P_el[0] + self.P_v[0], "P2": self.P_el[1] + self.P_v[1], "E1": self.E1,
                  "E2": self.E2, "SDV1": sdv1, "SDV2": self.alpha1, "SDV3": self.alpha2,
                  "E1_peak": self.E_peak[0], "E2_peak": self.E_peak[1]}
        if self.mu_crit is not None:
            fields.update(mu_crit1=self.mu_crit[0], mu_crit2=self.mu_crit[1])
        return fields

    def energies(self) -> dict[str, float]:
        """This rank's accumulated energies (J): viscous work, damage dissipation, energy of
        removed points."""
        return {"viscous_dissipation": self.viscous_dissipation,
                "damage_dissipation": self.damage_dissipation, "erosion_energy": self.erosion_energy}

    def diagnostics(self) -> dict[str, int]:
        """This rank's counters of point evaluations (summary.json ``surrogate``): above the
        table with damage off, compressed below it, slack with a positive table tension, wave
        moduli cut to their bound, wrinkled yarns, wrinkled yarns without a force-free strain."""
        return {"beyond_table": self.beyond_table, "below_table": self.below_table,
                "slack_tension": self.slack_tension, "modulus_bounded": self.modulus_bounded,
                "wrinkled": self.relax_stats.relaxed, "wrinkled_without_root": self.relax_stats.no_root}

    def update(self, E1, E2, dt: float = 0.0):
        """(P1, P2) at every owned point from the damage history this adapter keeps: elastic +
        viscous yarn stress at the live points (Eq. 2-31 from the surrogate, alpha from
        Eq. 2-25), zero at the points of removed cells; the history advances to the new alpha.
        ``dt`` (s): the step that led to these strains, the viscous stress's rate (0: none)."""
        n = self.w.size
        idx = self._idx   # the live points
        m = idx.size
        a1h, a2h = self.alpha1, self.alpha2
        e1, e2, h1, h2, guess = np.empty(m), np.empty(m), np.empty(m), np.empty(m), np.empty((2, m))
        E1, E2 = np.ascontiguousarray(E1, dtype=float), np.ascontiguousarray(E2, dtype=float)
        yarn_stress_kernel.live_inputs(idx, E1, E2, a1h, a2h, self.E_relaxed, self.E_peak, e1, e2,
                                       h1, h2, guess)
        changed = _NONE
        r1, r2 = self._relax(e1, e2, h1, h2, guess)
        yarn_stress_kernel.put_live(idx, r1, r2, self.E_relaxed)
        if self.damage:
            laws = ({} if self.mu_crit is None or self.failure is not None else
                    {"critical_stretch": self.mu_crit[:, idx], "softening_scale": self.scale[:, idx]})
            if self.failure is not None:   # the rule hands out the laws (the scatter's among them)
                laws = self.failure.laws(idx)
                p1, p2, b1, b2 = self.sur.update(r1, r2, h1, h2, **laws)
                (b1, b2), redo = self.failure.admit(self.sur, idx, r1, r2, np.stack((h1, h2)),
                                                    np.stack((b1, b2)))
                if getattr(self.failure, "budget", False):
                    redo = np.union1d(redo, self._break_budgeted(idx, e1, e2, h1, h2, b1, b2))
                if redo.size:   # the stresses at the damage kept
                    p1, p2 = p1.copy(), p2.copy()
                    p1[redo], p2[redo], _, _ = self.sur.evaluate(r1[redo], r2[redo], b1[redo], b2[redo])
            elif self.damage_drive is None:
                p1, p2, b1, b2 = self.sur.update(r1, r2, h1, h2, **laws)
            else:   # the damage from the driving strains, the stresses from the point's own
                d1, d2 = self._driving_strains(r1, r2)
                _, _, b1, b2 = self.sur.update(d1, d2, h1, h2, **laws)
                p1, p2, _, _ = self.sur.evaluate(r1, r2, b1, b2)
            a1, a2, changed = np.empty(n), np.empty(n), np.empty(b1.size, np.int64)
            changed = changed[:yarn_stress_kernel.new_damage(a1h, a2h, self.live, b1, b2, a1, a2,
                                                             changed)]
            if changed.size:
                self._book_dissipation(idx[changed], e1[changed], e2[changed], b1[changed], b2[changed])
        else:
            a1, a2 = a1h.copy(), a2h.copy()
            p1, p2 = self._intact(e1, e2, (r1, r2))
        # Wrinkled yarns carry nothing (see `slack` and the module docstring): below the
        # table a lookup at its end would freeze a positive crimp-interchange tension and pull
        # the cell together without bound; in biaxial compression the unit cell's branch has
        # jumps whose interpolant leaves small spurious tensions with huge slopes.
        beta_over_dt = self.beta / dt if self.beta > 0.0 and dt > 0.0 else 0.0
        ref = self.P_el  # P(E^{n-1}, alpha^{n-1}); at the points whose alpha changed: alpha^n
        if beta_over_dt and changed.size:
            c = idx[changed]
            ref = ref.copy()
            ref[:, c] = self._frozen_P(self.E1[c], self.E2[c], a1[c], a2[c])
        P_el, P_v, lam, P = np.empty((2, n)), np.empty((2, n)), np.empty((2, n)), np.empty((2, n))
        below, slack_tension, work = yarn_stress_kernel.stresses(
            E1, E2, self.live, p1, p2, ref, self.E_lo, beta_over_dt, self.w, self.lam, self.P_v,
            P_el, P_v, lam, P)
        self.below_table += below
        self.slack_tension += slack_tension
        self.viscous_dissipation += work
        self.E1_prev, self.E2_prev = self.E1, self.E2
        self.E1, self.E2 = E1.copy(), E2.copy()
        self.lam, self.P_el, self.P_v = lam, P_el, P_v
        self.alpha1, self.alpha2 = a1, a2
        return P[0], P[1]

    def _book_dissipation(self, c, e1, e2, b1, b2) -> None:
        """Book the energy released at points ``c`` (strains e1, e2) as their alpha went from the
        history's to (b1, b2): in total and per point and family (the fill's share computed
        apart only where both changed)."""
        a1, a2 = self.alpha1[c], self.alpha2[c]
        both = np.flatnonzero((b1 != a1) & (b2 != a2))
        n = c.size
        psi = self.path_energy(np.concatenate((e1, e1, e1[both])), np.concatenate((e2, e2, e2[both])),
                               np.concatenate((a1, b1, b1[both])), np.concatenate((a2, b2, a2[both])))
        released = self.w[c] * (psi[:n] - psi[n:2 * n])   # before, after, warp alone where both
        self.damage_dissipation += float(released.sum())
        warp = np.where(b1 != a1, released, 0.0)
        warp[both] = self.w[c[both]] * (psi[:n][both] - psi[2 * n:])
        self.point_dissipation[0, c] += warp
        self.point_dissipation[1, c] += released - warp

    def _break_budgeted(self, idx, e1, e2, h1, h2, b1, b2) -> np.ndarray:
        """Set, in place, the new alpha (b1, b2) of the live points ``idx`` that the failure rule
        budgets (``failure.budgets``): broken through where breaking would bring their family's
        dissipation to the budget, else held (:func:`~fabric_fenicsx.fem.crack_budget.break_through`);
        returns their positions in ``idx``."""
        from fabric_fenicsx.fem.crack_budget import break_through

        done = [_NONE]
        for i, b in enumerate((b1, b2)):
            at, budget = self.failure.budgets(self.sur, i, idx, (h1, h2), (b1, b2))
            if at.size == 0:
                continue
            p, k = idx[at], at.size
            old = [h1[at], h2[at]]
            gone = [old[0].copy(), old[1].copy()]
            gone[i][:] = 0.0
            psi = self.path_energy(np.tile(e1[at], 2), np.tile(e2[at], 2), np.concatenate((old[0], gone[0])),
                                   np.concatenate((old[1], gone[1])))
            total = self.point_dissipation[i, p] + self.w[p] * (psi[:k] - psi[k:])
            rise = np.nan_to_num(total - self._budget_total[i, p])   # since the last step (0 at the snap)
            self._budget_total[i, p] = total
            b[at] = break_through(total, self.w[p] * budget, old[i], rise)
            done.append(at)
        return np.concatenate(done)

    def tension(self) -> np.ndarray:
        """Yarn tensions P_i / lambda_i (N/m, shape (2, n)) at every owned point after the last
        :meth:`update`, elastic part (zero at removed points and slack yarns): the geometric
        stiffness of each yarn against a transverse perturbation (zero where a yarn has no
        length left: a slack, collapsed yarn carries nothing)."""
        T = np.empty(self.P_el.shape)
        yarn_stress_kernel.tension(self.P_el, self.lam, T)
        return T

    def wave_modulus(self, lookahead: float = 0.0) -> float:
        """Largest wave modulus (N/m) over this rank's live points: the largest eigenvalue of
        the symmetric part of dP_i/dlambda_j (damage frozen, rows of yarns that can carry
        tension only) or the geometric stiffness
        P_i / lambda_i, at the strains extrapolated ``lookahead`` steps ahead along their last
        increase (so that the step chosen now is still stable when the next check comes).

        Per point the tangent is bounded by ``WAVE_MODULUS_MARGIN`` max(alpha1, alpha2) times the
        straight intact yarn's modulus: no state of the unit cell is stiffer than its straight
        yarns (Eq. 2-31 with the crimp pulled out); steeper slopes of the interpolant are those
        across a jump of its compressive branch, which would otherwise collapse dt 3 x in every
        damaged run (docs/impact_model.md, "Time step"). Cut evaluations are counted in ``modulus_bounded``."""
        idx = self._idx
        if idx.size == 0:
            return 0.0
        E1, E2 = self.E1[idx], self.E2[idx]
        if lookahead > 0:
            E1 = E1 + lookahead * np.maximum(E1 - self.E1_prev[idx], 0.0)
            E2 = E2 + lookahead * np.maximum(E2 - self.E2_prev[idx], 0.0)
        slack1, slack2 = self.slack(E1, E2)
        E1, E2 = self._clip(E1), self._clip(E2)
        a1 = self.alpha1[idx] if self.damage else np.ones(idx.size)
        a2 = self.alpha2[idx] if self.damage else np.ones(idx.size)
        # the searches start at the last update's roots: the same simple roots to round-off
        # (Surrogate.zero_force_strain), three times fewer evaluations than from the bracket's end
        R1, R2 = self._relax(E1, E2, a1, a2, self.E_relaxed[:, idx])
        wrinkled1, wrinkled2 = R1 != E1, R2 != E2
        E1, E2 = R1, R2
        vals, d1, d2 = self.sur.lookup(E1, E2, a1, a2, ("P1", "P2"), derivative=True)
        d11, d12, d21, d22 = lambda_tangent(E1, E2, d1, d2)
        # Only a yarn that can carry tension has stiffness: not a broken one, not a slack one,
        # not a wrinkled one (at its force-free strain P_i is zero up to round-off, which must
        # not decide whether its stiffness counts: dt would jump with it), and not a compressed
        # one whose unit-cell P_i <= 0 (tension-only). The unit cell's compressive branch, never
        # felt by the membrane, has jumps (tangents up to 4e8 N/m near E1 = E2 = -0.045, 60 x
        # the straight yarn) that would otherwise collapse dt.
        on1 = (a1 > 0) & ~slack1 & ~wrinkled1 & ((E1 >= 0) | (vals[:, 0] > 0))
        on2 = (a2 > 0) & ~slack2 & ~wrinkled2 & ((E2 >= 0) | (vals[:, 1] > 0))
        t11, t12 = np.where(on1, d11, 0.0), np.where(on1, d12, 0.0)
        t21, t22 = np.where(on2, d21, 0.0), np.where(on2, d22, 0.0)
        eig = symmetric_eigmax(t11, t12, t21, t22)
        bound = WAVE_MODULUS_MARGIN * self.k_straight * np.maximum(a1, a2)
        above = eig > bound
        if above.any():
            self.modulus_bounded += int(np.count_nonzero(above))
            eig = np.where(above, bound, eig)
        geometric = np.maximum(np.maximum(self.P_el[0, idx], 0) / np.sqrt(1 + 2 * E1),
                               np.maximum(self.P_el[1, idx], 0) / np.sqrt(1 + 2 * E2))
        return float(max(eig.max(), geometric.max(), 0.0))

    def max_wave_modulus(self, lookahead: float = 0.0) -> float:
        """Rank-local :meth:`wave_modulus` (the contract's name)."""
        return self.wave_modulus(lookahead)

    def remove(self, points: np.ndarray) -> None:
        """Take points out (removed cells): no stress from now on; book their stored energy."""
        points = np.asarray(points, dtype=np.int64)
        points = points[self.live[points]]
        if points.size == 0:
            return
        psi = self.path_energy(self.E1[points], self.E2[points], self.alpha1[points] if self.damage
                               else np.ones(points.size), self.alpha2[points] if self.damage else
                               np.ones(points.size))
        self.erosion_energy += float(self.w[points] @ psi)
        self.live[points] = False
        self._idx = np.flatnonzero(self.live)
        self.P_el[:, points] = 0.0
        self.P_v[:, points] = 0.0

