"""Yarn-scale unit cell: two crimped, crossing half-yarns as extensible elastica.

Thesis section 2.2 and appendix A. Each half-yarn i (warp 1, fill 2) runs from the
contact point BC1 (S = 0, phi_i = 0) to the membrane surface BC2 (S = L_i, moment free).
It carries the end force F_i along the membrane and the contact force V normal to it.

The equations are written as the stationarity of one Lagrangian (the stretch delta_i
eliminated through N_i = A_i delta_i, Eq. 2-15):

    L(phi, F, V) = sum_i int_0^L [ B_i/2 (phi_i' - Phi_i')^2 - N_i^2/(2 A_i)
                                   - F_i cos phi_i - V (sin phi_i - sin Phi_i) ] dS
                   + sum_i F_i lambda_i w_i,
    N_i = F_i cos phi_i + V sin phi_i                        (Eq. 2-19)

dL/dphi = 0 is the Galerkin form of the elastica (Eq. 2-17, A.10) with
Q_i = V cos phi_i - F_i sin phi_i (Eq. 2-20); dL/dF_i = 0 is the coupling of yarn and
membrane (Eq. 2-29/2-30, A.5); dL/dV = -D is the gap of Eq. A.3/A.4, with the contact
conditions V >= 0, D >= 0, V D = 0. The Jacobian is the Hessian of L: symmetric and exact.
The stored energy per reference area is Psi = (W_1 + W_2) / (2 w_1 w_2), whose derivatives
are P_i = dPsi/dlambda_i = F_i / (2 w_j) (Eq. 2-31).

Damage (Eq. 2-26/2-28, appendix A.1): A_i = alpha_i A_i^0, B_i = alpha_i B_i^0 with
alpha_i = min(alpha_i^hist, alpha(mu_i^max)) solved by a bracketing iteration
(:mod:`fabric_fenicsx.material.damage_solver`).
A yarn with alpha_i below ``ALPHA_BROKEN`` has failed completely and leaves the cell.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg

from fabric_fenicsx.material.damage_solver import DamageIterationError, solve_damage
from fabric_fenicsx.material.fabric import Fabric

ALPHA_BROKEN = 1e-6
"""A yarn whose alpha falls below this has failed completely: F_i = 0 and it leaves the
cell (no contact force). Below it the unit-cell Jacobian is near singular; above it the
weak yarn's force is under 1e-6 of the intact yarn's, so the threshold does not show in P."""

N_ELEMENTS_DEFAULT = 24
"""Linear elements per half-yarn, from the convergence study in ``benchmarks/bench_unitcell.py``
(second order): relative error against n = 768 of 1.0e-3 in P1 intact and 6e-3 in P1 at a
damaged state; the thesis's key strains do not move at n = 96 (two onsets by one 0.0005 step)."""

_GAUSS_POINTS = 3
ROUNDOFF_RESIDUAL = 1e-9
"""A scaled residual below which a Newton solve that can no longer descend (near-singular
cells: a nearly broken yarn losing contact) is taken as converged: forces within ~1e-6 N."""


class UnitCellError(RuntimeError):
    """The unit-cell Newton solve or damage iteration failed."""


@dataclass
class UnitCellResult:
    """The state of the unit cell at membrane strains (E1, E2).

    Forces in N, stresses P in N/m (force per reference length, Eq. 2-31), stored energy
    Psi in J/m^2 (per reference membrane area), angles in rad.
    """

    E1: float
    E2: float
    P1: float
    P2: float
    F1: float
    F2: float
    V: float
    mu1_max: float
    mu2_max: float
    alpha1: float
    alpha2: float
    in_contact: bool
    D: float
    Psi: float
    S1: np.ndarray
    S2: np.ndarray
    phi1: np.ndarray
    phi2: np.ndarray
    tangent: np.ndarray
    """dP_i/dlambda_j (N/m) with damage frozen; symmetric."""
    iterations: int

    @property
    def lambda1(self) -> float:
        return math.sqrt(1.0 + 2.0 * self.E1)

    @property
    def lambda2(self) -> float:
        return math.sqrt(1.0 + 2.0 * self.E2)


class _Yarn1D:
    """Linear-element Galerkin discretisation of one half-yarn (appendix A.2)."""

    def __init__(self, yarn, n_elements: int):
        self.yarn = yarn
        L = yarn.L
        self.nodes = np.linspace(0.0, L, n_elements + 1)
        h = L / n_elements
        xg, wg = np.polynomial.legendre.leggauss(_GAUSS_POINTS)
        left = self.nodes[:-1, None]
        self.Sq = (left + 0.5 * h * (xg[None, :] + 1.0)).ravel()
        self.wq = np.tile(0.5 * h * wg, n_elements)
        # Shape functions at quadrature points, for the free nodes 1..n (phi(0) = 0, BC1).
        xi = 0.5 * (xg + 1.0)
        Nq = np.zeros((self.Sq.size, n_elements + 1))
        rows = np.arange(self.Sq.size)
        elem = np.repeat(np.arange(n_elements), _GAUSS_POINTS)
        Nq[rows, elem] = np.tile(1.0 - xi, n_elements)
        Nq[rows, elem + 1] = np.tile(xi, n_elements)
        self.Nq = Nq[:, 1:]
        self.NqT_w = self.Nq.T * self.wq
        # Bending stiffness int phi_k' phi_j' dS and load int phi_k' Phi' dS (BC2 is natural).
        D = np.zeros((n_elements, n_elements + 1))
        D[np.arange(n_elements), np.arange(n_elements)] = -1.0 / h
        D[np.arange(n_elements), np.arange(n_elements) + 1] = 1.0 / h
        Dq = np.repeat(D, _GAUSS_POINTS, axis=0)[:, 1:]
        self.Kb = (Dq.T * self.wq) @ Dq
        dPhi_q = yarn.dPhi(self.Sq)
        self.bb = (Dq.T * self.wq) @ dPhi_q
        # The discrete reference shape is the Galerkin projection of Eq. 3-5 (the stress-free
        # state of the discrete yarn): zero strain then gives exactly zero force and gap.
        self.Phi_nodes = np.linalg.solve(self.Kb, self.bb)
        self.bending_const = float(self.Phi_nodes @ self.bb)
        Phi_q = self.Nq @ self.Phi_nodes
        self.w = float(self.wq @ np.cos(Phi_q))
        self.sinPhi_int = float(self.wq @ np.sin(Phi_q))
        self.n = n_elements

    def fields(self, phi, F, V, A):
        """Quadrature-point fields (phi, c, s, N, Q, mu) of Eq. 2-15, 2-19, 2-20."""
        ph = self.Nq @ phi
        c, s = np.cos(ph), np.sin(ph)
        N = F * c + V * s
        Q = V * c - F * s
        return c, s, N, Q, 1.0 + N / A

    def energy(self, phi, F, V, A, B):
        """Stored energy W_i = int B/2 (phi' - Phi')^2 + N^2/(2A) dS of the half-yarn (Eq. 2-7)."""
        _, _, N, _, _ = self.fields(phi, F, V, A)
        bend = 0.5 * B * (phi @ self.Kb @ phi - 2.0 * phi @ self.bb + self.bending_const)
        return bend + float(np.sum(self.wq * N**2)) / (2.0 * A)

    def mu_max(self, phi, F, V, A):
        """Maximum local stretch mu_i = 1 + N_i/A_i (Eq. A.11) over nodes and quadrature points."""
        _, _, N, _, _ = self.fields(phi, F, V, A)
        phin = np.concatenate(([0.0], phi))
        Nn = F * np.cos(phin) + V * np.sin(phin)
        return 1.0 + max(float(N.max()), float(Nn.max())) / A


@dataclass
class _State:
    phi1: np.ndarray
    phi2: np.ndarray
    F1: float = 0.0
    F2: float = 0.0
    V: float = 0.0
    contact: bool = True
    jacobian: np.ndarray | None = None

    def copy(self) -> "_State":
        return dataclasses.replace(self, phi1=self.phi1.copy(), phi2=self.phi2.copy())


class UnitCell:
    """The unit cell of two crossing half-yarns with contact and damage.

    Parameters
    ----------
    fabric : the :class:`~fabric_fenicsx.material.fabric.Fabric`.
    n_elements : linear elements per half-yarn (default ``N_ELEMENTS_DEFAULT``).
    tol : Newton tolerance on the scaled residual (moments / (A^0 L), lengths / L).
    max_iter : Newton iterations per attempt.

    Calls along a loading path are warm-started from the previous solution. If Newton
    fails from there, the strain increment is subdivided (continuation); if that fails too,
    both are repeated with each yarn's equilibrium measured in its own damaged force scale
    (see :meth:`_solve`) before giving up.
    """

    def __init__(self, fabric: Fabric, n_elements: int | None = None, tol: float = 1e-12,
                 max_iter: int = 30):
        if not isinstance(fabric, Fabric):
            raise ValueError(f"fabric must be a Fabric, got {fabric!r}")
        n = N_ELEMENTS_DEFAULT if n_elements is None else n_elements
        if not isinstance(n, (int, np.integer)) or n < 2:
            raise ValueError(f"n_elements must be an integer >= 2, got {n_elements!r}")
        self.fabric = fabric
        self.n_elements = int(n)
        self.tol = tol
        self.max_iter = max_iter
        self.yarns = (_Yarn1D(fabric.warp, self.n_elements), _Yarn1D(fabric.fill, self.n_elements))
        self.A0 = np.array([fabric.warp.A0, fabric.fill.A0])
        self.B0 = np.array([fabric.warp.B0, fabric.fill.B0])
        self.mu_crit = np.array([fabric.warp.mu_crit, fabric.fill.mu_crit])
        self.w = np.array([y.w for y in self.yarns])
        self._force_scale = float(self.A0.max())
        self._reference = _State(self.yarns[0].Phi_nodes.copy(), self.yarns[1].Phi_nodes.copy())
        self._last: tuple[np.ndarray, np.ndarray, _State] | None = None  # (lambda, alpha, state)

    # ------------------------------------------------------------------ public API
    def solve(self, E1: float, E2: float | None, alpha=(1.0, 1.0)) -> UnitCellResult:
        """Unit cell at membrane strains (E1, E2) with damage frozen at ``alpha``.

        ``E2=None`` leaves the fill free (P2 = 0, thesis scenario 4) and solves for E2.
        """
        lam1, lam2, alpha = self._check(E1, E2, alpha, "alpha")
        return self._solve(lam1, lam2, alpha)

    def respond(self, E1: float, E2: float | None, alpha_hist=(1.0, 1.0)) -> UnitCellResult:
        """Unit cell at (E1, E2) with damage evolving from ``alpha_hist`` (appendix A.1).

        alpha_i = min(alpha_i^hist, alpha(mu_i^max)) (Eq. 2-25/A.12) is solved for both yarns
        by the bracketing iteration of :mod:`fabric_fenicsx.material.damage_solver`; the result's
        alpha1, alpha2 are the new
        history values. ``E2=None`` leaves the fill free (P2 = 0).
        """
        lam1, lam2, alpha_hist = self._check(E1, E2, alpha_hist, "alpha_hist")
        return self._respond(lam1, lam2, alpha_hist)

    def forget(self) -> None:
        """Forget the previous solution: the next solve starts from the reference
        (stress-free) state, so its result does not depend on what was solved before. Where
        the cell has several equilibria (compressed yarns) warm starts pick among them."""
        self._last = None

    # ------------------------------------------------------------------ damage iteration
    def _target(self, res: UnitCellResult, alpha_hist: np.ndarray) -> np.ndarray:
        mu = np.array([res.mu1_max, res.mu2_max])
        law = np.array([float(self.fabric.damage.alpha(mu[i], self.mu_crit[i])) for i in range(2)])
        return np.minimum(alpha_hist, law)

    def _respond(self, lam1, lam2, alpha_hist, tol=1e-10) -> UnitCellResult:
        res = self._solve(lam1, lam2, alpha_hist)
        target = self._target(res, alpha_hist)
        if np.all(alpha_hist - target <= tol):
            return res

        def evaluate(rows, alpha):
            return np.array([self._target(self._solve(lam1, lam2, a), alpha_hist) for a in alpha])

        try:
            alpha = solve_damage(alpha_hist[None], target[None], evaluate, floor=2 * ALPHA_BROKEN, tol=tol)[0]
        except DamageIterationError as err:
            raise UnitCellError(f"unit cell: {err}; at E1={res.E1:.6g}, E2={res.E2:.6g}. Smaller "
                                f"strain steps along the path change alpha_hist and may pass the "
                                f"jump") from err
        return self._solve(lam1, lam2, alpha)

    # ------------------------------------------------------------------ frozen-damage solve
    def _check(self, E1, E2, alpha, name):
        for label, val in (("E1", E1), ("E2", E2)):
            if label == "E2" and val is None:
                continue
            if not isinstance(val, (int, float, np.floating, np.integer)) or not math.isfinite(val):
                raise ValueError(f"{label} must be a finite number, got {val!r}")
            if val <= -0.5:
                raise ValueError(f"{label} = {val} is not a Green-Lagrange strain of a stretch (needs > -0.5)")
        a = np.asarray(alpha, dtype=float)
        if a.shape != (2,) or not np.all(np.isfinite(a)) or np.any(a < 0) or np.any(a > 1):
            raise ValueError(f"{name} must be two numbers in [0, 1] (warp, fill), got {alpha!r}")
        lam2 = None if E2 is None else math.sqrt(1.0 + 2.0 * E2)
        return math.sqrt(1.0 + 2.0 * E1), lam2, a

    def _solve(self, lam1, lam2, alpha) -> UnitCellResult:
        """The frozen-damage equilibrium (stationarity of the Lagrangian of the module text:
        Eq. 2-17, 2-29/2-30, A.3-A.5) at the stretches (lam1, lam2), by three paths in turn:

        1. Newton with active-set contact from the previous solution (:meth:`_newton_active_set`);
        2. continuation in the stretches from the reference state (:meth:`_continuation`);
        3. both again with each yarn's equilibrium measured in its own force scale
           (``yarn_scale``: the moment rows of yarn i divided by alpha_i A^0 L instead of
           A^0 L in the line search's merit and the convergence test, see :meth:`_newton`).

        Why path 3: a yarn at alpha_i carries moments of order alpha_i A^0 L, so in the merit
        of paths 1-2 its own balance counts alpha_i times less than the intact yarn's. Near
        r -> 0 (the table's r = 0 node, alpha = R_LIMIT = 1e-4) with B at its lower bound and the
        other yarn compressed out of contact (E1 = -0.034, E2 >= 0.064), contact release leaves
        the weak, nearly straight yarn unbalanced by V/F_2 ~ 5e-4 rad; the full Newton step
        rotates it back, which raises its length constraint (Eq. A.5) quadratically, above the
        merit the weak yarn's moments show: the line search cuts the step to 1/64 and Newton
        creeps (scaled residual 2e-9 after 30 iterations, in the whole lower-bound table the
        only three nodes neither path 1 nor 2 solved). In its own scale the weak yarn's
        imbalance dominates the merit and the full step is taken (9 iterations); with it every
        node of the lower-bound table (134,400 solves) is solved. Paths 1-2 are kept first
        because they give every state they solve the same digits as before (measured: the
        own-scale merit as the only one moves damaged upper-bound nodes by up to 8e-8
        relative; with it as path 3, 11,264 cached upper-bound nodes come out bit-identical),
        so cached tables (``tiles.FORMAT_VERSION``) and published results stay valid.
        """
        alpha = np.where(alpha < ALPHA_BROKEN, 0.0, alpha)
        lam_target = np.array([lam1, np.nan if lam2 is None else lam2])
        start = self._last
        if start is not None and (lam2 is None) != np.isnan(start[0][1]):
            start = None
        first = start[2] if start else self._reference
        failure = None
        damaged = bool(np.any((alpha > 0.0) & (alpha < 1.0)))
        for yarn_scale in ((False, True) if damaged else (False,)):
            try:
                state, its = self._newton_active_set(first.copy(), lam_target, alpha, yarn_scale)
                break
            except UnitCellError:
                pass
            try:
                state, its = self._continuation(lam_target, alpha, yarn_scale=yarn_scale)
                break
            except UnitCellError as err:
                failure = err
        else:
            E = [None if np.isnan(l) else 0.5 * (l * l - 1.0) for l in lam_target]
            raise UnitCellError(
                f"unit cell: equilibrium not found at E1={E[0]}, E2={E[1]}, "
                f"alpha={tuple(map(float, alpha))} from the previous solution, by continuation "
                f"from zero strain, or with each yarn's balance in its own force scale; last "
                f"failure: {failure}. No setting is known to help: please report this "
                f"state") from failure
        self._last = (lam_target, alpha, state)
        return self._result(state, lam_target, alpha, its)

    def _continuation(self, lam_to, alpha, max_depth=12, yarn_scale=False):
        """Reach lam_to from the reference state in substeps, halving a step that fails."""
        state = self._reference.copy()
        lam_from = np.where(np.isnan(lam_to), np.nan, 1.0)
        total = 0
        t_done = 0.0
        depth = 0
        dt = 0.25
        while t_done < 1.0:
            t_next = min(1.0, t_done + dt)
            lam = lam_from + t_next * (lam_to - lam_from)
            lam = np.where(np.isnan(lam_to), np.nan, lam)
            try:
                state_new, its = self._newton_active_set(state.copy(), lam, alpha, yarn_scale)
            except UnitCellError:
                depth += 1
                dt *= 0.5
                if depth > max_depth:
                    raise
                continue
            state, t_done, total = state_new, t_next, total + its
            dt = min(0.25, 2 * dt)
        return state, total

    def _newton_active_set(self, state: _State, lam, alpha, yarn_scale=False):
        broken = alpha == 0.0
        if broken.any():
            state.contact = False
            state.V = 0.0
            if broken[0]:
                state.F1 = 0.0
            if broken[1]:
                state.F2 = 0.0
        total = 0
        for _ in range(4):
            state, its = self._newton(state, lam, alpha, yarn_scale)
            total += its
            if broken.any():
                return state, total
            if state.contact and state.V < -1e-9 * self._force_scale:
                state.contact, state.V = False, 0.0
                continue
            if not state.contact and self._gap(state, alpha) < -1e-12 * self.yarns[0].yarn.L:
                state.contact = True
                continue
            return state, total
        raise UnitCellError(
            f"unit cell: contact status cycles between contact and separation at "
            f"lambda={tuple(lam)}, alpha={tuple(alpha)}")

    def _gap(self, state: _State, alpha) -> float:
        """D = D_1 + D_2 (Eq. A.3/A.4)."""
        D = 0.0
        for y, phi, F, a, A0 in zip(self.yarns, (state.phi1, state.phi2), (state.F1, state.F2), alpha, self.A0):
            if a == 0.0:
                continue
            c, s, N, Q, mu = y.fields(phi, F, state.V, a * A0)
            D += float(np.sum(y.wq * mu * s)) - y.sinPhi_int
        return D

    def _assemble(self, z, lam, alpha, free):
        """Residual (gradient of L) and Jacobian (Hessian of L) in the unknowns z."""
        n = self.n_elements
        F = z[2 * n:2 * n + 2]
        V = z[2 * n + 2]
        size = 2 * n + 3
        R = np.zeros(size)
        J = np.zeros((size, size))
        for i, y in enumerate(self.yarns):
            if alpha[i] == 0.0:
                continue
            A, B = alpha[i] * self.A0[i], alpha[i] * self.B0[i]
            sl = slice(i * n, (i + 1) * n)
            phi = z[sl]
            c, s, N, Q, mu = y.fields(phi, F[i], V, A)
            R[sl] = B * (y.Kb @ phi - y.bb) - y.NqT_w @ (mu * Q)
            J[sl, sl] = B * y.Kb + (y.NqT_w * (mu * N - Q * Q / A)) @ y.Nq
            J[sl, 2 * n + i] = y.NqT_w @ (mu * s - c * Q / A)
            J[sl, 2 * n + 2] = y.NqT_w @ (-mu * c - s * Q / A)
            wq = y.wq
            if not np.isnan(lam[i]):
                R[2 * n + i] = lam[i] * y.w - float(wq @ (mu * c))
            J[2 * n + i, 2 * n + i] = -float(wq @ (c * c)) / A
            J[2 * n + i, 2 * n + 2] = -float(wq @ (c * s)) / A
            R[2 * n + 2] -= float(wq @ (mu * s)) - y.sinPhi_int
            J[2 * n + 2, 2 * n + 2] -= float(wq @ (s * s)) / A
        J[2 * n:, :2 * n] = J[:2 * n, 2 * n:].T
        J[2 * n + 2, 2 * n:2 * n + 2] = J[2 * n:2 * n + 2, 2 * n + 2]
        return R, J

    def _free_mask(self, state: _State, lam, alpha):
        n = self.n_elements
        free = np.ones(2 * n + 3, dtype=bool)
        for i in range(2):
            if alpha[i] == 0.0:
                free[i * n:(i + 1) * n] = False
                free[2 * n + i] = False
            elif np.isnan(lam[i]):
                free[2 * n + i] = False  # force-controlled yarn: F_i stays as set (P_i = 0)
        if not state.contact:
            free[2 * n + 2] = False
        return free

    def _newton(self, state: _State, lam, alpha, yarn_scale=False):
        """Newton's method with a backtracking (Armijo) line search on the scaled residual
        norm: moment rows (Eq. 2-17/A.10) over A^0 L, constraint rows (Eq. A.5, A.3) over L;
        with ``yarn_scale`` yarn i's moment rows and force step over alpha_i A^0 L and
        alpha_i A^0 (its own damaged scale, see :meth:`_solve`)."""
        n = self.n_elements
        z = np.concatenate((state.phi1, state.phi2, [state.F1, state.F2, state.V]))
        free = self._free_mask(state, lam, alpha)
        scale = np.ones(2 * n + 3)
        scale[2 * n:] = self._force_scale
        rscale = np.full(2 * n + 3, self._force_scale * self.yarns[0].yarn.L)
        rscale[2 * n:] = self.yarns[0].yarn.L
        if yarn_scale:
            for i in range(2):
                if 0.0 < alpha[i] < 1.0:
                    rscale[i * n:(i + 1) * n] *= alpha[i]
                    scale[2 * n + i] *= alpha[i]

        def merit(zz):
            R, J = self._assemble(zz, lam, alpha, free)
            return R, J, float(np.linalg.norm((R / rscale)[free]))

        def converged_state():
            out = _State(z[:n].copy(), z[n:2 * n].copy(), float(z[2 * n]), float(z[2 * n + 1]),
                         float(z[2 * n + 2]), state.contact)
            out.jacobian = J
            return out

        R, J, m = merit(z)
        for it in range(1, self.max_iter + 1):
            Jf = J[np.ix_(free, free)]
            try:
                dz_f = scipy.linalg.solve(Jf, -R[free], check_finite=False, assume_a="sym")
            except (np.linalg.LinAlgError, ValueError) as err:
                raise UnitCellError(self._failure("singular Jacobian", lam, alpha, m, it)) from err
            dz = np.zeros_like(z)
            dz[free] = dz_f
            if not np.all(np.isfinite(dz)):
                raise UnitCellError(self._failure("non-finite Newton step", lam, alpha, m, it))
            t = 1.0
            while True:
                z_new = z + t * dz
                R_new, J_new, m_new = merit(z_new)
                if np.isfinite(m_new) and (m_new <= (1 - 1e-4 * t) * m or m_new < 1e-14):
                    break
                t *= 0.5
                if t < 1e-4:
                    if m < ROUNDOFF_RESIDUAL:  # no descent left at round-off level: converged
                        return converged_state(), it
                    raise UnitCellError(self._failure("line search failed", lam, alpha, m, it))
            z, R, J, m = z_new, R_new, J_new, m_new
            if m < self.tol or (np.max(np.abs(t * dz / scale)) < self.tol and m < ROUNDOFF_RESIDUAL):
                return converged_state(), it
        if m < ROUNDOFF_RESIDUAL:
            return converged_state(), self.max_iter
        raise UnitCellError(self._failure("no convergence", lam, alpha, m, self.max_iter))

    def _failure(self, what, lam, alpha, residual, its) -> str:
        E = [(l * l - 1) / 2 if not np.isnan(l) else None for l in lam]
        return (f"unit cell: Newton failed ({what}) at E1={E[0]}, E2={E[1]}, "
                f"alpha={tuple(map(float, alpha))}: scaled residual {residual:.3g} after {its} "
                f"iterations")

    def _result(self, state: _State, lam, alpha, its) -> UnitCellResult:
        n = self.n_elements
        lam_in, lam = lam, lam.copy()
        A = alpha * self.A0
        B = alpha * self.B0
        W = [0.0, 0.0]
        mu = [0.0, 0.0]
        phis = (state.phi1, state.phi2)
        F = (state.F1, state.F2)
        for i, y in enumerate(self.yarns):
            if alpha[i] == 0.0:
                mu[i] = float(self.fabric.damage.mu_complete(self.mu_crit[i]))
                continue
            W[i] = y.energy(phis[i], F[i], state.V, A[i], B[i])
            mu[i] = y.mu_max(phis[i], F[i], state.V, A[i])
            if np.isnan(lam[i]):
                c, s, N, Q, m = y.fields(phis[i], F[i], state.V, A[i])
                lam[i] = float(y.wq @ (m * c)) / y.w
        if np.isnan(lam[1]):  # fill broken and free: no fill length to speak of
            lam[1] = 1.0
        # Tangent dP/dlambda with damage frozen: dz/dlambda = -J^-1 dR/dlambda, dR_Fi/dlambda_i = w_i.
        tangent = np.zeros((2, 2))
        free = self._free_mask(state, lam_in, alpha)
        J = state.jacobian
        idx = np.flatnonzero(free)
        rhs = np.zeros((idx.size, 2))
        for j in range(2):
            pos = np.searchsorted(idx, 2 * n + j)
            if pos < idx.size and idx[pos] == 2 * n + j:
                rhs[pos, j] = -self.w[j]
        if idx.size:
            dz = scipy.linalg.solve(J[np.ix_(idx, idx)], rhs, check_finite=False, assume_a="sym")
            for i in range(2):
                pos = np.searchsorted(idx, 2 * n + i)
                if pos < idx.size and idx[pos] == 2 * n + i:
                    tangent[i] = dz[pos] / (2.0 * self.w[1 - i])
        E1 = 0.5 * (lam[0] ** 2 - 1.0)
        E2 = 0.5 * (lam[1] ** 2 - 1.0)
        return UnitCellResult(
            E1=E1, E2=E2, P1=state.F1 / (2.0 * self.w[1]), P2=state.F2 / (2.0 * self.w[0]),
            F1=state.F1, F2=state.F2, V=state.V, mu1_max=mu[0], mu2_max=mu[1],
            alpha1=float(alpha[0]), alpha2=float(alpha[1]), in_contact=bool(state.contact),
            D=self._gap(state, alpha),
            Psi=(W[0] + W[1]) / (2.0 * self.w[0] * self.w[1]),
            S1=self.yarns[0].nodes.copy(), S2=self.yarns[1].nodes.copy(),
            phi1=np.concatenate(([0.0], state.phi1)), phi2=np.concatenate(([0.0], state.phi2)),
            tangent=tangent, iterations=its)
