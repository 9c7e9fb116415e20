"""Ballistic impact of a woven-fabric ply by a rigid flat-ended cylinder (thesis chapter 4).

The fabric is the membrane of ``fabric_fenicsx.fem.membrane`` (flat reference mesh, three
displacement components, F = I_32 + Grad u, yarn directions from the material angle, P from
Eq. 2-5 with P_i from the unit-cell surrogate, Eq. 2-31), integrated by the explicit central
difference of ``fabric_fenicsx.fem.explicit`` with the lumped mass of the areal density.
The projectile of ``fabric_fenicsx.fem.projectile`` is a rigid body moving along the fabric
normal, coupled by node-to-surface penalty contact with Coulomb friction; its equation of
motion uses the contact force summed over all MPI ranks.

Modelling decisions (the numbers behind them are in the project's report):

* **Stiffness-proportional damping** (``run.damping`` = fraction xi of critical damping at
  omega_max, the highest mesh frequency of straight intact yarns): a viscous yarn stress
  P_v = beta [P(E^n, alpha^n) - P(E^{n-1}, alpha^n)] / dt with beta = 2 xi / omega_max,
  i.e. beta K lambda_dot with the secant of the *current, damaged* material at frozen damage.
  A broken yarn has no stiffness, so it carries no viscous force either. Its dissipation is
  booked per quadrature point (trapezoidal rule on the yarn stretches). Default xi = 0.1,
  from a measurement on Y90 at 57.3 m/s (2 mm mesh): the central deflection at damage onset
  is 23.18, 23.27, 23.42, 23.38 mm for xi = 0, 0.05, 0.1, 0.3, the residual velocity 48.70,
  47.99, 48.64 m/s for xi = 0, 0.1, 0.3. Ringing does not start damage early here because
  the critically damped contact removes the chatter (peak / mean contact force per 10 us
  window: median 1.1, against 2.0-2.2 with an undamped penalty, where the onset moves to
  23.8-24.5 mm). 0.1, the smallest value the prototype found converged, is kept as a
  margin; it costs 10 % of the time step and changes no result beyond the run-to-run
  scatter of the tearing phase (about 1 %, see below).
* **Time step**: dt = safety L_min / c_max (sqrt(1 + xi^2) - xi), c_max^2 = K_max / rho_A,
  L_min = min_cell_size(msh, "area_over_diagonal") (exact for a lumped bilinear square),
  K_max the largest wave modulus over the live points: the largest eigenvalue of the
  symmetric part of the surrogate tangent dP_i/dlambda_j (rows of yarns that can carry
  tension only: not broken, not slack) or the geometric stiffness P_i / lambda_i, at the
  strains extrapolated to the next check, bounded per point by 1.05 max(alpha1, alpha2) times
  the straight intact yarn's modulus (``WAVE_MODULUS_MARGIN``: no unit-cell state is stiffer;
  the interpolant's slope across a jump of the compressive branch, up to 11 x that modulus,
  collapsed dt 3 x in every damaged run before). Re-checked every ``run.dt_check_interval`` steps
  (and at each of the first ones after the first touch); dt is only ever lowered, and each
  change is reported. Deleted and eroded cells take no part, so a runaway cell cannot
  shrink dt; nor can the unit cell's compressive branch, which the tension-only membrane
  never feels.
* **Damage and deletion** (Table 2): SDV1 = 0 where alpha1 = alpha2 = 0, else 1; SDV2 =
  alpha1, SDV3 = alpha2. A cell whose quadrature points all have SDV1 = 0 is *deleted*.
* **Erosion**: a cell with a yarn-direction Green strain E_i > ``material.erosion_strain``
  (default 1.0, stretch 1.73) at any quadrature point is *eroded*. The unit cell has no
  physical state beyond E_fail (about 0.09: the surrogate's strain beyond which a yarn is
  certainly broken), so such a cell is a crack held open by the surviving yarn family, its
  element a strip stretched across the opening. Deleted and eroded cells carry no internal
  force and no viscous force, their nodes take part in contact only through a live cell,
  and they are holes in the output (SDV1 = 0). Both are counted; the stored energy an eroded
  cell still held is booked as ``erosion_energy``.
* **Compression (wrinkling)**: the surrogate is tension-only, and a yarn is also taken as
  slack (P_i = 0) when it is compressed below the table's lower end (``E_table[0]``) or
  compressed while the crossing yarn is not stretched (E_i < 0, E_j <= 0: only a stretched
  crossing yarn keeps a compressed one taut, by crimp interchange). Looked up at the
  table's end instead, crimp interchange (a stretched warp keeps the fill taut at E2 =
  -0.03) gave a constant tension that pulled cells together without bound and pumped
  energy into the fabric (seen with a table ending at -0.03: E2 -> -0.3, a projectile
  rebounding faster than it came); in biaxial compression the unit cell's branch has jumps
  whose interpolant leaves small spurious tensions with slopes of up to 1.4e8 N/m.
* **Energy dissipated by damage** is the energy released at fixed strain when alpha drops:
  sum over points of dA [W(E^n, alpha^{n-1}) - W(E^n, alpha^n)], computed only at the
  points whose damage grows in a step. W is the stored energy at frozen damage, taken as
  the work of the membrane's yarn stresses along the straight strain path from the
  reference state (:meth:`YarnStress.path_energy`): equal to the unit cell's Psi in
  tension; an estimate where a yarn is compressed, because the tension-only and slack
  rules make the membrane's stresses differ from the gradient of Psi there (Psi itself
  would count compression energy the membrane never stores: with it the stored energy
  went negative, -1.4 J of 18 J absorbed, at 57.3 m/s). The stored energy reported is
  the work of the elastic yarn stresses minus the damage and erosion losses.
* **Sensitivity**: once yarns wrinkle and tear the dynamics amplify round-off (about x10
  per 50 us): a serial run with v0 changed by 1e-12 differs by 7e-5 in residual velocity
  after 600 us with damage off, and by about 1 % at perforation with damage on. MPI runs
  differ from serial runs by the same amount (summation order), not more.
* **Energy balance**: KE_fabric + KE_projectile + W_internal - W_contact = KE_0, where
  W_internal (work of the internal forces: stored + damage + erosion + viscous) and W_contact
  (work of the contact forces on fabric and projectile, = -(penalty energy + friction and
  contact damping dissipation)) are trapezoidal sums, consistent with the central-difference
  full-step kinetic energies. ``energy_error`` = max_t |balance - KE_0| / KE_0.
"""

from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from fabric_fenicsx import yarn_stress_kernel
from fabric_fenicsx.fem.explicit import CentralDifference
from fabric_fenicsx.fem.membrane import Membrane
from fabric_fenicsx.fem.mesh import (BOTTOM, LEFT, RIGHT, TOP, MeshSpec, edge_dofs, load_mesh,
                                     min_cell_size, uniform_square)
from fabric_fenicsx.fem.projectile import PenaltyContact, Projectile, ProjectileState, advance
from fabric_fenicsx.materials import Fabric, zylon_as
from fabric_fenicsx.scene import Scene
from fabric_fenicsx.provenance import code_fingerprint
from fabric_fenicsx.surrogate import SurrogateError, lambda_tangent
from fabric_fenicsx.unitcell import UnitCellError

__all__ = ["ImpactError", "YarnStress", "ImpactSimulation", "run_impact", "build_fabric",
           "straight_yarn_modulus", "chatter_statistics"]

EDGE_TAGS = {"left": LEFT, "right": RIGHT, "bottom": BOTTOM, "top": TOP}
HISTORY_COLUMNS = (
    "time", "projectile_z", "projectile_velocity", "contact_force", "fabric_kinetic",
    "projectile_kinetic", "internal_work", "stored_energy", "damage_dissipation", "erosion_energy",
    "viscous_dissipation", "penalty_energy", "contact_dissipation", "energy_error",
    "central_deflection", "dt", "n_contact", "deleted_cells", "eroded_cells")
"""history.csv: time (s); projectile face height (m) and velocity (m/s, > 0 into the fabric);
contact force on the projectile (N, > 0 resisting); energies (J); energy_error (relative);
central deflection (m, > 0 along the impact); dt (s); contact nodes; removed cell counts."""

_BLOW_UP_ENERGY = 1.2   # kinetic energy above this multiple of KE_0 = numerical trouble
_NEGATIVE_WORK = 0.05   # yarns that gave back more than this fraction of KE_0 beyond what they got
WAVE_MODULUS_MARGIN = 1.05
"""Bound of the wave modulus per point, in units of max(alpha1, alpha2) x the straight intact
yarn's modulus: over the default table (401 x 401 strain states at alpha 1, 0.5, 0.1, 0.01) the
largest eigenvalue of the interpolated tangent is 1.028 of it at every state the membrane can
reach, except on the jumps of the unit cell's compressive branch (10.4 x at alpha1 = 0.01,
E2 = -0.054), where the slope is that of the interpolant across a jump, not a wave speed."""


_PATH_S, _PATH_W = np.polynomial.legendre.leggauss(6)
_PATH_S, _PATH_W = 0.5 * (_PATH_S + 1.0), 0.5 * _PATH_W  # on [0, 1]: YarnStress.path_energy


class ImpactError(RuntimeError):
    """The impact run stopped on numerical trouble; the message names step, place and fix."""


def build_fabric(scene: Scene) -> Fabric:
    """The scene's fabric: a TOML file (``fabric.file``) or a built-in (Table 1)."""
    if scene.fabric.file:
        return Fabric.load(scene.fabric.file)
    return zylon_as(bending=scene.fabric.bending)


def straight_yarn_modulus(fabric: Fabric) -> float:
    """Largest dP_i/dlambda_i (N/m) of a straight intact yarn, A_i w_i / (L_i 2 w_j) (Eq. 2-31
    with F_i = A_i (mu_i - 1), mu_i = lambda_i w_i / L_i once the crimp is pulled out)."""
    w = (fabric.warp.w, fabric.fill.w)
    return max(fabric.warp.A0 * w[0] / (fabric.warp.L * 2 * w[1]),
               fabric.fill.A0 * w[1] / (fabric.fill.L * 2 * w[0]))


# ============================================================================ material
class YarnStress:
    """The surrogate at the live quadrature points, with damage-scaled stiffness-proportional
    damping: the material ``CentralDifference`` calls (``update`` and ``max_wave_modulus``).

    surrogate: a :class:`fabric_fenicsx.surrogate.Surrogate`; weights: reference area dA of
    each point (m^2); damage: evolve alpha (Eq. 2-25) or keep alpha = 1 and ask the
    surrogate's intact layer only; beta: damping coefficient (s). Set ``dt_prev`` (the last
    step) before each ``CentralDifference.step``.

    Local (this rank) accumulators, J: ``viscous_dissipation``, ``damage_dissipation``,
    ``erosion_energy``. ``beyond_table``: point evaluations with a strain above the table
    (damage off only; with damage on such a yarn is broken). ``modulus_bounded``: point
    evaluations of :meth:`wave_modulus` whose tangent exceeded the bound and was cut to it.
    straight_modulus: the straight intact yarn's dP/dlambda (N/m), default from the fabric.
    """

    def __init__(self, surrogate, weights: np.ndarray, damage: bool, beta: float = 0.0,
                 straight_modulus: float | None = None):
        self.sur = surrogate
        self.k_straight = float(straight_yarn_modulus(surrogate.fabric) if straight_modulus is None
                                else straight_modulus)
        self.modulus_bounded = 0
        self.w = np.asarray(weights, dtype=float)
        n = self.w.size
        self.damage = bool(damage)
        self.beta = float(beta)
        self.dt_prev = 0.0
        self.live = np.ones(n, dtype=bool)
        self._idx = np.arange(n)
        self._sel = slice(None)
        self.E1, self.E2 = np.zeros(n), np.zeros(n)
        self.E1_prev, self.E2_prev = self.E1, self.E2
        self.lam = np.ones((2, n))
        self.P_el = np.zeros((2, n))
        self.P_v = np.zeros((2, n))
        self.alpha1, self.alpha2 = np.ones(n), np.ones(n)
        self.viscous_dissipation = 0.0
        self.damage_dissipation = 0.0
        self.erosion_energy = 0.0
        self.beyond_table = 0
        self.below_table = 0
        self.slack_tension = 0
        self.E_lo, self.E_hi = surrogate.E_table

    # ------------------------------------------------------------------ surrogate access
    def _clip(self, E: np.ndarray) -> np.ndarray:
        return np.clip(E, self.E_lo, self.E_hi)

    def _intact(self, E1, E2):
        """P1, P2 of intact yarns (alpha = 1: the surrogate's intact layer only), tension-only."""
        self.beyond_table += int(np.count_nonzero((E1 > self.E_hi) | (E2 > self.E_hi)))
        self.sur.stats.record(E1, E2)
        one = np.ones(E1.size)
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
        """P1, P2 at frozen damage with the slack rule of :meth:`update`."""
        if self.damage:
            P1, P2, _, _ = self.sur.evaluate(E1, E2, a1, a2)
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

    # ------------------------------------------------------------------ CentralDifference API
    def update(self, E1, E2, alpha1_hist, alpha2_hist):
        """(P1, P2, alpha1, alpha2) at every owned point: elastic + viscous yarn stress at the
        live points (Eq. 2-31 from the surrogate), zero at the points of removed cells."""
        n = self.w.size
        idx = self._idx
        sel = self._sel   # the live points: a slice while none was removed (no gathers)
        a1h, a2h = np.asarray(alpha1_hist, dtype=float), np.asarray(alpha2_hist, dtype=float)
        e1, e2 = E1[sel], E2[sel]
        changed = np.zeros(0, np.int64)
        if self.damage:
            p1, p2, b1, b2 = self.sur.update(e1, e2, a1h[sel], a2h[sel])
            a1, a2, changed = np.empty(n), np.empty(n), np.empty(b1.size, np.int64)
            changed = changed[:yarn_stress_kernel.new_damage(a1h, a2h, self.live, b1, b2, a1, a2,
                                                             changed)]
            if changed.size:
                c = idx[changed]
                psi = self.path_energy(np.tile(e1[changed], 2), np.tile(e2[changed], 2),
                                       np.concatenate((a1h[c], b1[changed])),
                                       np.concatenate((a2h[c], b2[changed])))  # before, after
                self.damage_dissipation += float(self.w[c] @ (psi[:c.size] - psi[c.size:]))
        else:
            a1, a2 = a1h.copy(), a2h.copy()
            p1, p2 = self._intact(e1, e2)
        # Wrinkled yarns carry nothing (see `slack` and the module docstring): below the
        # table a lookup at its end would freeze a positive crimp-interchange tension and pull
        # the cell together without bound; in biaxial compression the unit cell's branch has
        # jumps whose interpolant leaves small spurious tensions with huge slopes.
        beta_over_dt = self.beta / self.dt_prev if self.beta > 0.0 and self.dt_prev > 0.0 else 0.0
        ref = self.P_el[:, sel]  # P(E^{n-1}, alpha^{n-1}); at the points whose alpha changed:
        if beta_over_dt and changed.size:
            c = idx[changed]
            ref = ref.copy()
            ref[:, changed] = self._frozen_P(self.E1[c], self.E2[c], a1[c], a2[c])  # alpha^n
        P_el, P_v, lam = np.empty((2, n)), np.empty((2, n)), np.empty((2, n))
        below, slack_tension, work = yarn_stress_kernel.stresses(
            E1, E2, self.live, p1, p2, ref, self.E_lo, beta_over_dt, self.w, self.lam, self.P_v,
            P_el, P_v, lam)
        self.below_table += below
        self.slack_tension += slack_tension
        self.viscous_dissipation += work
        self.E1_prev, self.E2_prev = self.E1, self.E2
        self.E1, self.E2 = E1.copy(), E2.copy()
        self.lam, self.P_el, self.P_v = lam, P_el, P_v
        self.alpha1, self.alpha2 = a1, a2
        return P_el[0] + P_v[0], P_el[1] + P_v[1], a1, a2

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
        damaged run (docs/impact.md). Cut evaluations are counted in ``modulus_bounded``."""
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
        vals, d1, d2 = self.sur.lookup(E1, E2, a1, a2, ("P1", "P2"), derivative=True)
        d11, d12, d21, d22 = lambda_tangent(E1, E2, d1, d2)
        # Only a yarn that can carry tension has stiffness: not a broken one, not a slack one,
        # and not a compressed one whose unit-cell P_i <= 0 (tension-only). The unit cell's
        # compressive branch, never felt by the membrane, has jumps (tangents up to 4e8 N/m
        # near E1 = E2 = -0.045, 60 x the straight yarn) that would otherwise collapse dt.
        on1 = (a1 > 0) & ~slack1 & ((E1 >= 0) | (vals[:, 0] > 0))
        on2 = (a2 > 0) & ~slack2 & ((E2 >= 0) | (vals[:, 1] > 0))
        t11, t12 = np.where(on1, d11, 0.0), np.where(on1, d12, 0.0)
        t21, t22 = np.where(on2, d21, 0.0), np.where(on2, d22, 0.0)
        b = 0.5 * (t12 + t21)
        eig = 0.5 * (t11 + t22) + np.sqrt(0.25 * (t11 - t22) ** 2 + b * b)
        bound = WAVE_MODULUS_MARGIN * self.k_straight * np.maximum(a1, a2)
        above = eig > bound
        if above.any():
            self.modulus_bounded += int(np.count_nonzero(above))
            eig = np.where(above, bound, eig)
        geometric = np.maximum(np.maximum(self.P_el[0, idx], 0) / np.sqrt(1 + 2 * E1),
                               np.maximum(self.P_el[1, idx], 0) / np.sqrt(1 + 2 * E2))
        return float(max(eig.max(), geometric.max(), 0.0))

    def max_wave_modulus(self) -> float:
        """Rank-local :meth:`wave_modulus` (``CentralDifference.stable_dt`` compatibility)."""
        return self.wave_modulus()

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
        self._sel = self._idx
        self.P_el[:, points] = 0.0
        self.P_v[:, points] = 0.0


# ============================================================================ helpers
def chatter_statistics(t: np.ndarray, force: np.ndarray, window: float = 10e-6,
                       first: float = 10e-6) -> dict:
    """Contact chatter of a contact-force history (rank 0's per-step record).

    first_touch_peak_N: the largest force within ``first`` s of the first contact, against
    plateau_mean_N, the mean force over the rest of the contact period. For consecutive
    windows of ``window`` s after the first-touch period, the ratio peak / mean force: its
    median and maximum over the windows whose mean is at least 10 % of the plateau mean
    (the fading tail after a perforation is left out)."""
    t, force = np.asarray(t, dtype=float), np.asarray(force, dtype=float)
    out = {"first_touch_peak_N": 0.0, "plateau_mean_N": 0.0, "window_s": window, "first_s": first,
           "window_peak_over_mean_median": None, "window_peak_over_mean_max": None, "n_windows": 0}
    on = np.flatnonzero(force > 0)
    if on.size == 0:
        return out
    t0, t1 = t[on[0]], t[on[-1]]
    out["first_touch_peak_N"] = float(force[(t >= t0) & (t <= t0 + first)].max())
    sel = (t > t0 + first) & (t <= t1)
    if not sel.any():
        return out
    f = force[sel]
    out["plateau_mean_N"] = float(f.mean())
    k = ((t[sel] - t0 - first) // window).astype(np.int64)
    counts = np.bincount(k)
    sums = np.bincount(k, weights=f)
    peaks = np.full(counts.size, -np.inf)
    np.maximum.at(peaks, k, f)
    keep = (counts >= 3) & (sums > 0.1 * out["plateau_mean_N"] * counts)
    ratios = peaks[keep] / (sums[keep] / counts[keep])
    if ratios.size:
        out.update(window_peak_over_mean_median=float(np.median(ratios)),
                   window_peak_over_mean_max=float(ratios.max()), n_windows=int(ratios.size))
    return out


@dataclass
class _Clock:
    contact: float = 0.0
    output: float = 0.0
    bookkeeping: float = 0.0   # includes dt_check
    dt_check: float = 0.0


@dataclass
class _DtChange:
    step: int
    time: float
    dt_old: float
    dt_new: float
    modulus: float


@dataclass
class _Books:
    """Global energies (J) and run state, identical on every rank."""
    W_projectile: float = 0.0       # work of the contact force on the projectile
    penalty_energy: float = 0.0
    friction_estimate: float = 0.0  # -sum friction_work (first-order split, PenaltyContact)
    viscous: float = 0.0
    damage: float = 0.0
    erosion: float = 0.0
    energy_error: float = 0.0
    error_now: float = 0.0
    deleted: int = 0
    eroded: int = 0
    n_contact: int = 0
    contact_force: float = 0.0
    central_uz: float = 0.0
    z_max: float = 0.0
    n_front: int = 0
    t_touch: float | None = None
    step_touch: int | None = None
    beyond_table: int = 0       # point evaluations above the table (damage off)
    below_table: int = 0        # point evaluations with a yarn compressed below the table
    slack_tension: int = 0      # ... where a slack rule zeroed a positive table tension
    t_last_contact: float | None = None
    damage_onset_time: float | None = None
    damage_onset_deflection: float | None = None


# ============================================================================ simulation
class ImpactSimulation:
    """One impact scene on ``comm``: build everything the scene uses, then :meth:`run`.

    out_dir: output folder (created); verbose: progress lines on rank 0.
    """

    def __init__(self, scene: Scene, out_dir: str | os.PathLike, comm: MPI.Comm = MPI.COMM_WORLD,
                 verbose: bool = True):
        from fabric_fenicsx.impact_output import ImpactOutput
        from fabric_fenicsx.surrogate import Surrogate

        t_build = time.perf_counter()
        self.scene, self.comm, self.verbose = scene, comm, verbose
        self.rank0 = comm.rank == 0
        self.out_dir = Path(out_dir)
        sc = scene

        # -- mesh, membrane
        ms = sc.mesh
        if ms.kind == "uniform":
            self.msh, _, facet_tags = uniform_square(ms.n, ms.side, comm)
        else:
            spec = MeshSpec(side=ms.side, h_centre=ms.h_centre, h_edge=ms.h_edge,
                            refine_radius=ms.refine_radius, centre=(sc.projectile.x, sc.projectile.y),
                            grading=ms.grading)
            self.msh, _, facet_tags = load_mesh(spec, comm)
        self.membrane = m = Membrane(self.msh, angle=math.radians(sc.material.angle),
                                     quadrature_degree=ms.quadrature_degree)
        self.n_cells_global = comm.allreduce(m.n_cells, op=MPI.SUM)
        self.npc = m.n_points_per_cell

        # -- material
        self.fabric = build_fabric(sc)
        self.rho_A = self.fabric.areal_density
        workers = 1 if comm.size > 1 else None
        cache = sc.material.surrogate_cache or None
        self.surrogate = Surrogate(self.fabric, cache_dir=cache, workers=workers,
                                   progress=verbose and self.rank0)
        self.L_min = min_cell_size(self.msh, "area_over_diagonal")
        k_straight = straight_yarn_modulus(self.fabric)
        self.omega_straight = 2.0 * math.sqrt(k_straight / self.rho_A) / self.L_min
        self.xi = sc.run.damping
        beta = 2.0 * self.xi / self.omega_straight
        self.material = YarnStress(self.surrogate, m.quadrature_weights_detJ, sc.material.damage, beta,
                                   straight_modulus=k_straight)

        clamped = edge_dofs(m.V, facet_tags, [EDGE_TAGS[e] for e in sc.boundary.clamped])
        self._clamped_blocks = np.unique(clamped // 3)   # local nodes, owned and ghost
        self.cd = CentralDifference(m, self.material, self.rho_A, clamped, damping=0.0)
        self.n_nodes = m.n_owned_nodes
        self.X = m.V.tabulate_dof_coordinates()[:self.n_nodes].copy()
        self.X[:, 2] = 0.0
        self.node_mass = self.cd.mass[0::3].copy()

        # -- projectile and contact
        p = sc.projectile
        self.projectile = Projectile(diameter=p.diameter, length=p.length, fillet=p.fillet, mass=p.mass,
                                     velocity=p.velocity, friction=p.friction, axis_xy=(p.x, p.y),
                                     z0=p.standoff)
        self.contact = PenaltyContact(self.projectile, damping_ratio=p.contact_damping,
                                      penalty_fraction=p.penalty_fraction)
        self.state = ProjectileState.initial(self.projectile)
        self.KE0 = self.state.kinetic_energy

        # -- cells <-> points <-> nodes
        self.live_cells = np.ones(m.n_cells, dtype=bool)
        self.deleted_cells = np.zeros(m.n_cells, dtype=bool)
        self.eroded_cells = np.zeros(m.n_cells, dtype=bool)
        self.live_nodes = np.ones(self.n_nodes, dtype=bool)
        self.free_nodes = np.zeros(self.n_nodes, dtype=bool)   # in pieces cut loose (plugs)
        self._node_flags = None
        self.axis_xy = np.array([p.x, p.y])
        dist = np.hypot(self.X[:, 0] - p.x, self.X[:, 1] - p.y)
        local = (float(dist.min()), comm.rank) if self.n_nodes else (math.inf, comm.rank)
        _, self.centre_rank = comm.allreduce(local, op=MPI.MINLOC)
        self.centre_node = int(np.argmin(dist)) if comm.rank == self.centre_rank else -1

        # -- time step
        self.dt = self.stable_dt(self._global_modulus())
        self.dt_initial = self.dt
        self.dt_changes: list[_DtChange] = []

        self.output = ImpactOutput(self.out_dir, m, list(sc.output.fields) if sc.output.xdmf_interval > 0 else [],
                                   comm, HISTORY_COLUMNS)
        self.books = _Books()
        self.clock = _Clock()
        self._tile_seconds0 = self.surrogate.build_seconds
        self.build_seconds = time.perf_counter() - t_build
        self._say(f"impact: {sc.source}: {self.n_cells_global} cells on {comm.size} rank(s), "
                  f"L_min = {self.L_min * 1e3:.3f} mm, damping xi = {self.xi:g} (beta = {beta:.3e} s), "
                  f"dt = {self.dt:.4e} s, v0 = {p.velocity:g} m/s, damage {'on' if sc.material.damage else 'off'}, "
                  f"clamped {sc.boundary.clamped}, angle {sc.material.angle:g} deg")

    # ------------------------------------------------------------------ small helpers
    def _say(self, text: str) -> None:
        if self.verbose and self.rank0:
            print(text, flush=True)

    def _global_modulus(self) -> float:
        return self.comm.allreduce(self.material.wave_modulus(), op=MPI.MAX)

    def stable_dt(self, modulus: float) -> float:
        """safety * L_min / c_max, lowered for the damping (see the module docstring). Before
        the fabric is loaded the modulus is that of the reference state (crimped yarns)."""
        if not (math.isfinite(modulus) and modulus > 0):
            raise ImpactError(f"stable time step: the largest wave modulus is {modulus!r} N/m; the "
                              "surrogate returned no stiffness at the live points (all yarns broken or "
                              "a table problem): check the surrogate with `fabric-fenicsx surrogate`")
        c = math.sqrt(modulus / self.rho_A)
        omega = 2.0 * c / self.L_min
        xi = 0.5 * self.material.beta * omega
        return self.scene.run.dt_safety * 2.0 / omega * (math.sqrt(1.0 + xi * xi) - xi)

    def _exchange_nodes(self, marked: np.ndarray) -> np.ndarray:
        """A node marked on any rank, marked on every rank that holds it (owned or ghost;
        collective): ``marked`` and the result are over this rank's local nodes."""
        f = self._node_flags
        f.x.array[:] = 0.0
        f.x.array[0::3] = marked
        f.vector.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        f.vector.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
        return f.x.array[0::3] > 0.0

    def _update_removed_cells(self) -> None:
        """After cells were removed (collective): ``live_nodes``, the owned nodes touching at
        least one live cell on any rank, and ``free_nodes``, the live nodes in pieces of fabric
        cut loose from every clamped edge.

        A node is attached if a chain of live cells joins it to a clamped node: propagated
        cell by cell on each rank, exchanged across ranks through the ghost nodes, until no
        rank finds a new attached node. A piece that is not attached (a plug punched out by
        the projectile) is still simulated, but it neither keeps a perforation from ending
        the run nor counts as a blow-up when it flies away with the projectile."""
        if self._node_flags is None:
            m = self.membrane
            self._node_flags = fem.Function(m.V)
            self._cell_nodes = m.V.dofmap.list.array.reshape(-1, m.V.dofmap.cell_dofs(0).size)[:m.n_cells]
        cells = self._cell_nodes[self.live_cells]
        n_local = self._node_flags.x.array.size // 3
        touched = np.zeros(n_local, dtype=bool)
        touched[cells.ravel()] = True
        self.live_nodes = self._exchange_nodes(touched)[:self.n_nodes]
        attached = np.zeros(n_local, dtype=bool)
        attached[self._clamped_blocks] = True
        while True:
            while True:   # on this rank
                grown = attached.copy()
                grown[cells[attached[cells].any(axis=1)].ravel()] = True
                if np.array_equal(grown, attached):
                    break
                attached = grown
            merged = self._exchange_nodes(attached)
            new = self.comm.allreduce(int(np.count_nonzero(merged & ~attached)), op=MPI.SUM)
            attached = merged
            if new == 0:
                break
        self.free_nodes = self.live_nodes & ~attached[:self.n_nodes]

    def _removal(self) -> tuple[np.ndarray, np.ndarray]:
        """Cells to delete (all points SDV1 = 0) and to erode (a yarn strain beyond the
        erosion strain) now, among the live cells of this rank."""
        mat = self.material
        npc = self.npc
        if not self.scene.material.damage:
            return np.zeros(0, np.int64), np.zeros(0, np.int64)
        sdv1 = (mat.alpha1 > 0) | (mat.alpha2 > 0)
        dead = ~sdv1.reshape(-1, npc).any(axis=1)
        strain = np.maximum(mat.E1, mat.E2).reshape(-1, npc).max(axis=1)
        over = strain > self.scene.material.erosion_strain
        delete = np.flatnonzero(dead & self.live_cells)
        erode = np.flatnonzero(over & ~dead & self.live_cells)
        return delete, erode

    def _remove(self, delete: np.ndarray, erode: np.ndarray) -> None:
        cells = np.concatenate((delete, erode))
        self.live_cells[cells] = False
        self.deleted_cells[delete] = True
        self.eroded_cells[erode] = True
        points = (cells[:, None] * self.npc + np.arange(self.npc)).ravel()
        self.material.remove(points)

    def _contact(self, dt: float):
        """Contact forces at t_n on this rank's live owned nodes near the projectile."""
        s, proj = self.state, self.projectile
        n_dofs = self.membrane.n_owned_dofs
        zero_info = dict(penalty_energy=0.0, friction_work=0.0, damping_work=0.0, n_active=0,
                         n_attached=0, max_penetration=0.0, normal_force=0.0)
        margin = abs(s.vz) * dt + 1e-9
        if not proj.may_touch(self.books.z_max, s.z, margin):
            return None, np.zeros(3), zero_info
        x = self.X + self.cd.u.reshape(-1, 3)
        r2 = (x[:, 0] - self.axis_xy[0]) ** 2 + (x[:, 1] - self.axis_xy[1]) ** 2
        near = (self.live_nodes & (r2 < proj.radius ** 2) & (x[:, 2] > s.z) & (x[:, 2] < s.z + proj.length))
        sel = np.flatnonzero(near)
        if sel.size == 0:
            return None, np.zeros(3), zero_info
        v = self.cd.v.reshape(-1, 3)
        f_nodes, f_p, info = self.contact.forces(x[sel], v[sel], self.node_mass[sel], dt, s)
        # touching nodes of fabric still attached to a clamped edge (a plug riding on the
        # face does not keep the run from ending)
        info["n_attached"] = int(np.count_nonzero(np.any(f_nodes != 0.0, axis=1) & ~self.free_nodes[sel]))
        f_ext = np.zeros(n_dofs)
        f_ext.reshape(-1, 3)[sel] = f_nodes
        return f_ext, f_p, info

    # ------------------------------------------------------------------ run
    def run(self) -> dict:
        """Integrate until perforation, rebound or the time limit; write the output; return the
        summary (identical on every rank)."""
        sc, comm, cd, mat, books = self.scene, self.comm, self.cd, self.material, self.books
        out = self.output
        t_wall0 = time.perf_counter()
        run = sc.run
        dt = dt_shown = self.dt
        dt_prev = 0.0
        fz_prev = 0.0
        z_prev = self.state.z
        next_history = 0.0
        next_frame = 0.0 if sc.output.xdmf_interval > 0 else math.inf
        last_progress = time.perf_counter()
        steps_at_progress = 0
        force_t, force_f = [], []
        end_reason = None
        step = 0
        damage_on = sc.material.damage

        while True:
            t_n = cd.time
            # -------------------------------------------------- contact at t_n
            tc = time.perf_counter()
            f_ext, f_p, info = self._contact(dt)
            uz_c = float(cd.u[3 * self.centre_node + 2]) if self.centre_node >= 0 else 0.0
            self.clock.contact += time.perf_counter() - tc

            # -------------------------------------------------- fabric step t_n -> t_n+1
            mat.dt_prev = dt_prev
            try:
                energy = cd.step(dt, f_ext)
            except (FloatingPointError, ValueError, SurrogateError, UnitCellError) as err:
                raise ImpactError(self._trouble(step, t_n, f"{type(err).__name__}: {err}")) from err

            tb = time.perf_counter()
            delete, erode = self._removal()
            if delete.size or erode.size:
                self._remove(delete, erode)
            damaged = bool(np.any(mat.alpha1 < 1.0) or np.any(mat.alpha2 < 1.0)) if damage_on else False
            x_new = self.X[:, 2] + cd.u[2::3]
            live_z = x_new[self.live_nodes]
            r2 = ((self.X[:, 0] + cd.u[0::3] - self.axis_xy[0]) ** 2
                  + (self.X[:, 1] + cd.u[1::3] - self.axis_xy[1]) ** 2)
            attached = self.live_nodes & ~self.free_nodes
            front = int(np.count_nonzero(attached & (r2 < self.projectile.radius ** 2)
                                         & (x_new < self.state.z + self.projectile.length)))
            # every N steps, and at every step of the first N after the first touch (the
            # strain increments the look-ahead extrapolates are not known before it)
            check = step > 0 and (step % run.dt_check_interval == 0 or (
                books.step_touch is not None and step - books.step_touch <= run.dt_check_interval))
            loc_sum = np.array([f_p[2], info["penalty_energy"], -info["friction_work"], info["n_active"],
                                mat.viscous_dissipation, mat.damage_dissipation, mat.erosion_energy,
                                delete.size, erode.size, float(damaged), uz_c, front,
                                mat.beyond_table, mat.below_table, mat.slack_tension, info["n_attached"]])
            glob = np.empty_like(loc_sum)
            comm.Allreduce(loc_sum, glob, op=MPI.SUM)
            tw = time.perf_counter()
            try:
                modulus = mat.wave_modulus(run.dt_check_interval) if check else 0.0
            except (FloatingPointError, ValueError, SurrogateError, UnitCellError) as err:
                raise ImpactError(self._trouble(step, t_n, f"time-step check: {type(err).__name__}: "
                                                f"{err}")) from err
            self.clock.dt_check += time.perf_counter() - tw
            loc_max = np.array([live_z.max() if live_z.size else -math.inf, modulus,
                                float(np.abs(cd.u.reshape(-1, 3)[attached]).max(initial=0.0))])
            gmax = np.empty_like(loc_max)
            comm.Allreduce(loc_max, gmax, op=MPI.MAX)
            (fz, pen, fric, n_act, visc, dmg, ero, n_del, n_ero, dmg_flag, uz_c, n_front,
             beyond, below, slack_t, n_attached) = glob
            if n_del or n_ero:
                self._update_removed_cells()
            books.deleted += int(n_del)
            books.eroded += int(n_ero)
            books.penalty_energy, books.viscous, books.damage, books.erosion = pen, visc, dmg, ero
            books.friction_estimate += fric
            books.n_contact = int(n_act)
            books.contact_force = fz
            books.central_uz = uz_c
            books.z_max = gmax[0]
            books.n_front = int(n_front)
            if n_act > 0 and books.t_touch is None:
                books.t_touch, books.step_touch = t_n, step
            if n_attached > 0:
                books.t_last_contact = t_n
            if dmg_flag and books.damage_onset_time is None:
                books.damage_onset_time = t_n
                books.damage_onset_deflection = -uz_c
                self._say(f"  damage starts at t = {t_n * 1e6:.2f} us, central deflection {-uz_c * 1e3:.2f} mm")

            # -------------------------------------------------- projectile and energy at t_n
            s = self.state
            vz_full = s.vz + 0.5 * dt_prev * fz / s.mass
            books.W_projectile += 0.5 * (fz_prev + fz) * (s.z - z_prev)
            KE_p = 0.5 * s.mass * vz_full ** 2
            W_contact = energy.external + books.W_projectile
            total = energy.kinetic + KE_p + energy.internal - W_contact - energy.support
            books.error_now = abs(total - self.KE0) / self.KE0
            books.energy_error = max(books.energy_error, books.error_now)
            z_prev, fz_prev = s.z, fz
            self.state = advance(s, fz, dt)
            if self.rank0:
                force_t.append(t_n)
                force_f.append(fz)
            self.clock.bookkeeping += time.perf_counter() - tb

            # -------------------------------------------------- output at t_n
            to = time.perf_counter()
            if t_n >= next_history:
                row = self._history_row(t_n, energy, KE_p, vz_full, W_contact, dt)
                out.history(row)
                next_history += sc.output.history_interval
                while next_history <= t_n:
                    next_history += sc.output.history_interval
            if t_n >= next_frame:
                self._frame(t_n)
                next_frame += sc.output.xdmf_interval
                while next_frame <= t_n:
                    next_frame += sc.output.xdmf_interval
            self.clock.output += time.perf_counter() - to

            # -------------------------------------------------- trouble
            kinetic = energy.kinetic + KE_p
            W_el = energy.internal - books.viscous
            tripped = [what for bad, what in (
                (kinetic > _BLOW_UP_ENERGY * self.KE0,
                 f"kinetic energy {kinetic:.4g} J > {_BLOW_UP_ENERGY:g} x the impact energy KE_0 = "
                 f"{self.KE0:.4g} J"),
                (W_el < -_NEGATIVE_WORK * self.KE0,
                 f"the yarns gave back {-W_el:.4g} J more than they received (> {_NEGATIVE_WORK:g} KE_0)"),
                (gmax[2] > sc.mesh.side,
                 f"fabric attached to a clamped edge moved {gmax[2]:.4g} m, more than the fabric's side "
                 f"{sc.mesh.side:g} m")) if bad]
            if tripped:
                raise ImpactError(self._trouble(step, t_n, "blow-up: " + "; ".join(tripped)))
            if books.error_now > run.energy_tolerance:
                raise ImpactError(self._trouble(
                    step, t_n, f"energy balance error {books.error_now:.3%} > run.energy_tolerance = "
                    f"{run.energy_tolerance:g} (damage {'on' if damage_on else 'off'}; the balance "
                    f"KE + W_internal - W_contact = KE_0 no longer holds: the step is too large for "
                    f"the contact or the fabric's stiffness)"))

            # -------------------------------------------------- time step
            step += 1
            dt_prev = dt
            if check and gmax[1] > 0:
                dt_new = self.stable_dt(gmax[1])
                if dt_new < dt:
                    self.dt_changes.append(_DtChange(step, cd.time, dt, dt_new, float(gmax[1])))
                    # every change is in the summary; on screen those of 1 % or more since the last shown
                    if dt_new < 0.99 * dt_shown:
                        self._say(f"  dt {dt_shown:.4e} -> {dt_new:.4e} s at step {step} (t = "
                                  f"{cd.time * 1e6:.2f} us, wave modulus {gmax[1]:.4g} N/m)")
                        dt_shown = dt_new
                    dt = dt_new

            # -------------------------------------------------- progress
            now = time.perf_counter()
            if (self.verbose and sc.output.progress_interval > 0
                    and now - last_progress >= sc.output.progress_interval):
                rate = (step - steps_at_progress) / (now - last_progress)
                self._say(f"  t = {cd.time * 1e6:8.2f} us  step {step:7d}  {rate:7.1f} steps/s  "
                          f"v = {-self.state.vz:8.3f} m/s  F = {fz:9.1f} N  dt = {dt:.3e} s  "
                          f"removed {books.deleted}+{books.eroded}  energy error {books.error_now:.2e}")
                last_progress, steps_at_progress = now, step

            # -------------------------------------------------- end
            released = (books.t_last_contact is not None and n_attached == 0
                        and cd.time - books.t_last_contact >= run.release_time)
            if released and self.state.vz > 0:
                end_reason = "rebound"
            elif released and books.n_front == 0:
                end_reason = "perforated"
            elif cd.time >= run.t_end:
                end_reason = "time_limit"
            elif run.max_steps and step >= run.max_steps:
                end_reason = "max_steps"
            if end_reason:
                break

        self.books.beyond_table, self.books.below_table = int(beyond), int(below)
        self.books.slack_tension = int(slack_t)
        wall = time.perf_counter() - t_wall0
        return self._finish(end_reason, step, dt, wall, np.array(force_t), np.array(force_f), energy)

    # ------------------------------------------------------------------ output pieces
    def _history_row(self, t, energy, KE_p, vz_full, W_contact, dt) -> dict:
        b = self.books
        W_el = energy.internal - b.viscous
        return {"time": t, "projectile_z": self.state.z, "projectile_velocity": -vz_full,
                "contact_force": b.contact_force, "fabric_kinetic": energy.kinetic,
                "projectile_kinetic": KE_p, "internal_work": energy.internal,
                "stored_energy": W_el - b.damage - b.erosion, "damage_dissipation": b.damage,
                "erosion_energy": b.erosion, "viscous_dissipation": b.viscous,
                "penalty_energy": b.penalty_energy,
                "contact_dissipation": -W_contact - b.penalty_energy, "energy_error": b.error_now,
                "central_deflection": -b.central_uz, "dt": dt, "n_contact": b.n_contact,
                "deleted_cells": b.deleted, "eroded_cells": b.eroded}

    def point_fields(self) -> dict[str, np.ndarray]:
        """Point values (owned quadrature points) of the cell-wise output fields."""
        mat = self.material
        sdv1 = ((mat.alpha1 > 0) | (mat.alpha2 > 0)).astype(float)
        return {"P1": mat.P_el[0] + mat.P_v[0], "P2": mat.P_el[1] + mat.P_v[1], "E1": mat.E1, "E2": mat.E2,
                "SDV1": sdv1, "SDV2": mat.alpha1, "SDV3": mat.alpha2}

    def _frame(self, t: float) -> None:
        self.output.frame(t, self.cd.u, self.cd.v, self.point_fields(), self.live_cells)

    def _trouble(self, step: int, t: float, what: str) -> str:
        """A message naming step, time, place and the likely fix."""
        u = self.cd.u.reshape(-1, 3)
        bad = np.flatnonzero(~np.all(np.isfinite(u), axis=1))
        if bad.size:
            place = f"first non-finite node at reference (x, y) = {self.X[bad[0], :2]} m on rank {self.comm.rank}"
        else:
            k = int(np.argmax(np.abs(u).sum(axis=1))) if u.size else 0
            place = (f"largest displacement {u[k]} m at reference (x, y) = {self.X[k, :2]} m on rank "
                     f"{self.comm.rank}" if u.size else "no owned nodes")
        return (f"impact run stopped at step {step}, t = {t:.6e} s: {what}; {place}; "
                f"dt = {self.cd._dt_prev:.3e} s, projectile at z = {self.state.z:.4e} m moving "
                f"{-self.state.vz:.3f} m/s. Likely fixes: lower run.dt_safety, raise run.damping, "
                f"lower projectile.penalty_fraction, or refine the mesh at the impact point "
                f"(mesh.h_centre); see {self.out_dir / 'history.csv'}")

    def _finish(self, end_reason, n_steps, dt, wall, force_t, force_f, energy) -> dict:
        sc, b, cd, comm = self.scene, self.books, self.cd, self.comm
        v0 = sc.projectile.velocity
        v_res = -self.state.vz
        perforated = bool(end_reason == "perforated" or (end_reason != "rebound" and b.n_front == 0
                                                          and self.state.vz < 0 and b.t_touch is not None))
        W_el = energy.internal - b.viscous
        self._frame(cd.time)
        timings = dict(cd.timings)
        steps = max(n_steps, 1)
        # The surrogate solves missing table tiles inside its lookups (constitutive update and
        # dt checks): that one-off cost is reported apart from the per-step work.
        tiles = self.surrogate.build_seconds - self._tile_seconds0
        tiles_in_update = min(tiles, timings["material"])
        split = {"strain": timings["strain"], "constitutive": timings["material"] - tiles_in_update,
                 "assembly": timings["assembly"], "contact": self.clock.contact,
                 "output": self.clock.output, "integrator": timings["rest"],
                 "dt_check": max(self.clock.dt_check - (tiles - tiles_in_update), 0.0),
                 "bookkeeping": self.clock.bookkeeping - self.clock.dt_check,
                 "surrogate_tiles": tiles}
        chatter = chatter_statistics(force_t, force_f) if self.rank0 else None
        chatter = comm.bcast(chatter, root=0)
        summary = {
            "scene": str(sc.source), "description": sc.description,
            "v0": v0, "residual_velocity": v_res, "perforated": perforated,
            "absorbed_energy": 0.5 * sc.projectile.mass * (v0 ** 2 - v_res ** 2),
            "max_deflection": b.damage_onset_deflection,
            "damage_onset_time": b.damage_onset_time,
            "energy_error": b.energy_error, "end_reason": end_reason,
            "end_time": cd.time, "wall_time_s": wall, "build_time_s": self.build_seconds,
            "n_cells": self.n_cells_global, "n_steps": n_steps, "dt": dt, "dt_initial": self.dt_initial,
            "dt_changes": [vars(c) for c in self.dt_changes], "n_ranks": comm.size,
            "deleted_cells": b.deleted, "eroded_cells": b.eroded,
            "free_nodes": comm.allreduce(int(np.count_nonzero(self.free_nodes)), op=MPI.SUM),
            "energies": {"projectile_kinetic_0": self.KE0,
                         "projectile_kinetic": 0.5 * sc.projectile.mass * v_res ** 2,
                         "fabric_kinetic": energy.kinetic, "internal_work": energy.internal,
                         "elastic_work": W_el, "stored_energy": W_el - b.damage - b.erosion,
                         "damage_dissipation": b.damage, "erosion_energy": b.erosion,
                         "viscous_dissipation": b.viscous, "penalty_energy": b.penalty_energy,
                         "contact_dissipation": -(energy.external + b.W_projectile) - b.penalty_energy,
                         "friction_dissipation_estimate": b.friction_estimate},
            "contact_chatter": chatter, "touch_time": b.t_touch,
            "time_per_step_s": {k: v / steps for k, v in split.items() if k != "surrogate_tiles"},
            "time_total_s": split,
            "surrogate": {"key": self.surrogate.key, "resolution": self.surrogate.h,
                          "solves_this_run": comm.allreduce(self.surrogate.solves, op=MPI.SUM),
                          "points_beyond_table_damage_off": b.beyond_table,
                          "points_compressed_below_table": b.below_table,
                          "points_slack_with_table_tension": b.slack_tension,
                          "wave_modulus_bounded": comm.allreduce(self.material.modulus_bounded,
                                                                 op=MPI.SUM),
                          "range": self.surrogate.report_range() if self.rank0 else ""},
            "mesh": {"L_min": self.L_min, "kind": sc.mesh.kind},
            "damping": {"xi": self.xi, "beta": self.material.beta, "omega_max": self.omega_straight},
            "settings": sc.to_dict(),
            **code_fingerprint(),
        }
        if b.beyond_table:
            st = self.surrogate.stats
            self._say(f"impact: WARNING: with damage off, {b.beyond_table} point evaluations had a yarn "
                      f"strain above the surrogate's table (E > {self.surrogate.E_table[1]:.4g}; largest "
                      f"E1 = {st.E_max[0]:.4g}, E2 = {st.E_max[1]:.4g} on rank 0): their stress was "
                      "taken at the table's end, so the run left the model's range there")
        self.output.finish(summary, self.live_cells, self.point_fields(), sc.output.png)
        self._say(f"impact: {end_reason} at t = {cd.time * 1e6:.1f} us after {n_steps} steps "
                  f"({wall:.1f} s): v0 = {v0:g} m/s, residual velocity {v_res:.3f} m/s, absorbed "
                  f"{summary['absorbed_energy']:.2f} J, energy error {b.energy_error:.2e}, removed cells "
                  f"{b.deleted} deleted + {b.eroded} eroded")
        if self.rank0 and self.output.xdmf_path is not None and self.verbose:
            print(f"impact: XDMF for ParaView: {self.output.xdmf_path.resolve()} "
                  "(Warp By Vector 'displacement'; Threshold SDV1 > 0 hides the holes)", flush=True)
        return summary


def run_impact(scene: Scene, out_dir: str | os.PathLike, comm: MPI.Comm = MPI.COMM_WORLD,
               verbose: bool = True) -> dict:
    """Build and run one impact scene; returns the summary (also in out_dir/summary.json)."""
    sim = ImpactSimulation(scene, out_dir, comm, verbose)
    try:
        return sim.run()
    finally:
        sim.output.close()
