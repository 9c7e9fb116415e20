"""Explicit central-difference dynamics of the fabric membrane with a lumped mass.

Solves M a = f_ext - f_int(u) (the discrete referential balance of momentum, thesis Eq. 2-4)
with the central-difference (leapfrog) scheme

    v^{n+1/2} = v^{n-1/2} + (dt_{n-1/2} + dt_{n+1/2}) / 2 * a^n,
    u^{n+1}   = u^n + dt_{n+1/2} v^{n+1/2},

on the free dofs; clamped dofs have zero acceleration (their velocity stays what it was set to,
zero unless you prescribe a constant edge velocity).  The first step starts from v(0) with a half
step, v^{1/2} = v(0) + dt/2 a^0.

Energy bookkeeping (all MPI sums over owned dofs), consistent at time t_n = the state whose
internal force the last `step` evaluated:
  kinetic   0.5 v^n . M v^n with the full-step velocity v^n = v^{n-1/2} + dt_{n-1/2}/2 a^n
            (the average of the two half-step velocities for a constant dt);
  internal  work of the internal forces, sum of (f_int^{n-1} + f_int^n)/2 . du (trapezoidal);
            equals the stored energy while the material is elastic and no term dissipates;
  external  work of f_ext, same rule; support: work of the reactions at moving clamped dofs;
  damping   energy dissipated by the integrator's numerical damping, same rule;
  dissipated  the part of the internal work done by the weak-form terms that declare their work
            dissipated (:attr:`~fabric_fenicsx.fem.terms.MembraneTerm.dissipative`), same rule.
kinetic + internal + damping - external - support is conserved (= the initial kinetic energy) up
to the O(dt^2) error of the scheme.

Numerical damping (default off): stiffness-proportional Rayleigh damping C = beta K, applied as
the viscous stress increment beta (P^n - P^{n-1}) / dt_{n-1/2}, i.e. the damping force
beta (f_int^n - f_int^{n-1}) / dt = beta K v^{n-1/2} evaluated with the lagged velocity (standard
for explicit codes; it damps the geometric, prestress part of K too).  An impact run puts its
damping into the material's viscous yarn stress instead (``material.beta``).  Either lowers the
stable step; :meth:`CentralDifference.stable_dt` is the one rule
(:func:`fabric_fenicsx.fem.timestep.stable_dt`) with the integrator's and the material's beta and
the terms' viscosity.

Before each assembly the membrane's term context is brought up to date: ``membrane.velocity``
holds v^{n-1/2} (m/s, the lagged velocity, as for the damping force) and ``membrane.dt`` the
step dt_{n-1/2} (s) that led to u^n.
"""
from __future__ import annotations

import dataclasses
import math
import time

import numpy as np
from mpi4py import MPI
from numba import njit

from fabric_fenicsx.fem.timestep import stable_dt as damped_courant_limit
from fabric_fenicsx.material.contract import DamageState

__all__ = ["CentralDifference", "EnergyRecord", "LinearYarnMaterial"]


class LinearYarnMaterial:
    """Stand-in material for tests: tension-only linear yarns, P_i = k_i max(lambda_i - 1, 0)
    (N/m), lambda_i = sqrt(1 + 2 E_i) (Eq. 2-3), no damage.  Not a fabric model.

    It implements both shapes of the material-point contract
    (:mod:`fabric_fenicsx.material.contract`): the state-free ``MaterialLaw``
    (``constitutive_update``, ``wave_modulus``) and the ``QuadratureMaterial`` the integrator
    calls (``update(E1, E2, dt) -> (P1, P2)``, ``state``, ``strains``, ``max_wave_modulus()``,
    ``tension()``, ``point_fields()``, ``energies()``, ``diagnostics()``, ``remove``, ``beta``).
    """

    beta = 0.0
    """No viscous stress of its own (s)."""

    def __init__(self, k1: float, k2: float):
        for name, k in (("k1", k1), ("k2", k2)):
            if not np.isfinite(k) or k <= 0:
                raise ValueError(f"{name} must be a finite positive stiffness in N/m, got {k!r}")
        self.k1, self.k2 = float(k1), float(k2)
        self._state: DamageState | None = None
        self._removed = np.zeros(0, dtype=np.int64)
        self._E = self._P = (np.zeros(0), np.zeros(0))

    @staticmethod
    def _stretch(E: np.ndarray, name: str) -> np.ndarray:
        E = np.asarray(E, dtype=float)
        if np.any(E <= -0.5):
            raise ValueError(f"{name} must be > -0.5 (stretch > 0), got min {E.min()!r}")
        return np.sqrt(1.0 + 2.0 * E)

    def constitutive_update(self, E1, E2, state: DamageState):
        """Yarn stresses for the yarn strains E1, E2 (Eq. 2-3): (P1, P2, state unchanged)."""
        lam1, lam2 = self._stretch(E1, "E1"), self._stretch(E2, "E2")
        P1 = self.k1 * np.maximum(lam1 - 1.0, 0.0)
        P2 = self.k2 * np.maximum(lam2 - 1.0, 0.0)
        return P1, P2, state

    def wave_modulus(self, E1, E2, state: DamageState) -> np.ndarray:
        """max(k1, k2) at every point (N/m): the tangent is diagonal, diag(k1, k2) in tension."""
        return np.full(np.shape(E1), self.max_wave_modulus())

    @property
    def state(self) -> DamageState:
        """Damage state of the points of the last :meth:`update` (always intact)."""
        return self._state

    @property
    def strains(self) -> tuple[np.ndarray, np.ndarray]:
        """Yarn strains (E1, E2) of the last :meth:`update`."""
        return self._E

    def update(self, E1, E2, dt: float = 0.0):
        """(P1, P2) at the membrane's points; points taken out by :meth:`remove` carry nothing.
        ``dt`` (the step that led to these strains) is not used: the law has no rate."""
        if self._state is None or self._state.alpha1.shape != np.shape(E1):
            self._state = DamageState.intact(np.size(E1))
        P1, P2, self._state = self.constitutive_update(E1, E2, self._state)
        P1[self._removed] = 0.0
        P2[self._removed] = 0.0
        self._E, self._P = (np.array(E1, dtype=float), np.array(E2, dtype=float)), (P1, P2)
        return P1, P2

    def max_wave_modulus(self, lookahead: float = 0.0) -> float:
        """max over both yarns of dP_i/dlambda_i (N/m), at any strain (``lookahead`` unused)."""
        return max(self.k1, self.k2)

    def tension(self) -> np.ndarray:
        """Yarn tensions P_i / lambda_i (N/m, shape (2, n)) of the last :meth:`update`."""
        lam = np.sqrt(1.0 + 2.0 * np.stack(self._E))
        return np.stack(self._P) / lam

    def point_fields(self) -> dict[str, np.ndarray]:
        """Stresses (N/m) and strains of the last :meth:`update` at every point."""
        return {"P1": self._P[0], "P2": self._P[1], "E1": self._E[0], "E2": self._E[1]}

    def energies(self) -> dict[str, float]:
        """No viscous, damage or removal energies: a linear elastic law."""
        return {"viscous_dissipation": 0.0, "damage_dissipation": 0.0, "erosion_energy": 0.0}

    def diagnostics(self) -> dict[str, int]:
        """No counters."""
        return {}

    def remove(self, points) -> None:
        """Take points out for good: no stress there from now on."""
        self._removed = np.union1d(self._removed, np.asarray(points, dtype=np.int64))

    def energy_density(self, E1, E2) -> np.ndarray:
        """Stored energy per reference area (J/m^2), 0.5 k_i (lambda_i - 1)^2 on tension."""
        lam1, lam2 = self._stretch(E1, "E1"), self._stretch(E2, "E2")
        return 0.5 * (self.k1 * np.maximum(lam1 - 1.0, 0.0) ** 2
                      + self.k2 * np.maximum(lam2 - 1.0, 0.0) ** 2)


@dataclasses.dataclass(frozen=True)
class EnergyRecord:
    """Energies (J) at time `time` (s); see the module docstring for their definitions."""
    time: float
    kinetic: float
    internal: float
    external: float
    support: float
    damping: float
    dissipated: float = 0.0
    """Work (J) of the weak-form terms that declare it dissipated; part of ``internal``."""

    @property
    def total(self) -> float:
        """kinetic + internal + damping - external - support: constant for an exact balance."""
        return self.kinetic + self.internal + self.damping - self.external - self.support


class CentralDifference:
    """Explicit central-difference integrator for a `Membrane` with a lumped mass.

    Args:
        membrane: the `fabric_fenicsx.fem.membrane.Membrane`; its displacement `u` is the state.
        material: the :class:`~fabric_fenicsx.material.contract.QuadratureMaterial` at the
            membrane's owned points (``update(E1, E2, dt) -> (P1, P2)``, ``max_wave_modulus()``,
            ``beta``); it keeps its damage history itself (see ``LinearYarnMaterial``,
            ``YarnStress``).
        areal_density: rho_A of the reference fabric (kg/m^2).
        clamped_dofs: local unrolled dof indices with zero acceleration (ghost indices allowed,
            they are ignored here because their owner handles them).
        damping: Rayleigh stiffness-proportional coefficient beta (s), default 0.
        cell_size: the length L (m) of the stable-step rule; default the shortest reference edge
            (:meth:`Membrane.min_edge_length`, exact for yarns along the edges); an impact run
            passes the smallest ``area_over_diagonal`` cell size.
        safety: the default safety factor of :meth:`stable_dt`.

    Attributes:
        u: owned displacement dofs (a view of membrane.u; call `membrane.u.x.scatter_forward()`
            after editing it by hand).
        v: owned velocity dofs: v(0) before the first step, v^{n+1/2} afterwards.
        mass: lumped mass per owned dof (kg).
        energy: `EnergyRecord` at the time of the last evaluated internal force.
        timings: accumulated wall time (s) per phase: strain, material, assembly, rest.
    """

    def __init__(self, membrane, material, areal_density: float, clamped_dofs,
                 damping: float = 0.0, cell_size: float | None = None, safety: float = 0.9):
        if not np.isfinite(damping) or damping < 0:
            raise ValueError(f"damping (Rayleigh beta, s) must be finite and >= 0, got {damping!r}")
        if not 0 < safety <= 1:
            raise ValueError(f"safety must be in (0, 1], got {safety!r}")
        self.cell_size = float(membrane.min_edge_length() if cell_size is None else cell_size)
        self.safety = float(safety)
        self.membrane = membrane
        self.material = material
        self.areal_density = float(areal_density)
        self.beta = float(damping)
        n = membrane.n_owned_dofs
        self.mass = membrane.lumped_mass(areal_density)

        clamped = np.asarray(clamped_dofs, dtype=np.int64).ravel()
        n_local = membrane.u.x.array.size
        if clamped.size and (clamped.min() < 0 or clamped.max() >= n_local):
            raise ValueError(f"clamped_dofs must be local dof indices in [0, {n_local}), got range "
                             f"[{clamped.min()}, {clamped.max()}]")
        self.clamped = np.unique(clamped[clamped < n])
        self.free = np.ones(n, dtype=bool)
        self.free[self.clamped] = False
        self._inv_mass_free = np.where(self.free, 1.0 / self.mass, 0.0)

        self.u = membrane.u.x.array[:n]
        self.v = np.zeros(n)

        self.time = 0.0
        self.n_steps = 0
        self._dt_prev = 0.0
        self._du = np.zeros(n)
        self._f_int = np.zeros(n)
        self._f_ext = np.zeros(n)
        self._f_damp = np.zeros(n)
        self._res_c = np.zeros(self.clamped.size)
        self._works = np.zeros(5)  # internal, external, support, damping, dissipated
        self._f_diss = np.zeros(n)
        # the step's work arrays, made once: the forces of step n are written into the spare
        # buffers and swapped with those of step n - 1 (kept for the trapezoidal works)
        self._spare = {name: np.zeros(n) for name in ("f_int", "f_ext", "f_damp", "f_diss")}
        self._residual, self._acc = np.zeros(n), np.zeros(n)
        self._local, self._total = np.zeros(7), np.zeros(7)
        self.energy = EnergyRecord(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
        self.timings = {"strain": 0.0, "material": 0.0, "assembly": 0.0, "rest": 0.0}

    def stable_dt(self, safety: float | None = None, material_modulus: float | None = None) -> float:
        """The stable step (s) of this membrane by the one rule,
        :func:`fabric_fenicsx.fem.timestep.stable_dt`: wave modulus K = the material's (largest
        over all ranks) plus the terms' (``Membrane.terms_wave_modulus``), the areal density,
        :attr:`cell_size`, beta = the integrator's + the material's (``material.beta``), the
        terms' viscosity (``Membrane.terms_viscosity``) and ``safety`` (default
        :attr:`safety`). ``material_modulus`` (N/m): the material's largest wave modulus over
        all ranks where the caller has it; else it is asked now (collective)."""
        safety = self.safety if safety is None else safety
        if material_modulus is None:
            material_modulus = self.membrane.comm.allreduce(float(self.material.max_wave_modulus()),
                                                            op=MPI.MAX)
        modulus = float(material_modulus) + self.membrane.terms_wave_modulus()
        if not np.isfinite(modulus) or modulus <= 0:
            raise ValueError("the wave modulus (material.max_wave_modulus() plus the membrane's "
                             f"terms') must be finite and > 0 N/m, got {modulus!r}")
        return damped_courant_limit(modulus, self.areal_density, self.cell_size, self.damping_beta,
                                    safety, self.membrane.terms_viscosity())

    @property
    def damping_beta(self) -> float:
        """The stiffness-proportional damping coefficient (s) acting on the membrane: the
        integrator's plus the material's viscous stress's."""
        return self.beta + float(getattr(self.material, "beta", 0.0))

    def evaluated_state(self) -> tuple[float, np.ndarray, np.ndarray]:
        """(t_n, u^n, v^n): the state at the time of the last evaluated internal force, to which
        :attr:`energy` and the material's strains and stresses belong. The last step has
        already moved u to u^{n+1} and v to v^{n+1/2}: u^n = u^{n+1} - dt v^{n+1/2} and
        v^n = v^{n+1/2} - dt/2 a^n. Before the first step: the initial state."""
        if self.n_steps == 0:
            return self.time, self.u.copy(), self.v.copy()
        acc = (self._f_ext - self._f_int - self._f_damp) * self._inv_mass_free
        return self.energy.time, self.u - self._du, self.v - (0.5 * self._dt_prev) * acc

    def step(self, dt: float, f_ext: np.ndarray | None = None) -> EnergyRecord:
        """Advance u from t_n to t_n + dt under the external nodal forces f_ext (N, owned dofs,
        at t_n; None for no load).  Returns the energies at t_n."""
        if not math.isfinite(dt) or dt <= 0:
            raise ValueError(f"dt must be a finite positive time step in s, got {dt!r}")
        m = self.membrane
        n = m.n_owned_dofs
        spare = self._spare
        f_ext_now = spare["f_ext"]   # a copy: it is kept for the work increment
        if f_ext is None:
            f_ext_now.fill(0.0)
        else:
            f_ext = np.asarray(f_ext, dtype=float)
            if f_ext.shape != (n,):
                raise ValueError(f"f_ext must have shape ({n},) (owned dofs), got {f_ext.shape}")
            np.copyto(f_ext_now, f_ext)
        f_ext = f_ext_now

        t0 = time.perf_counter()
        E1, E2 = m.yarn_strains()
        t1 = time.perf_counter()
        P1, P2 = self.material.update(E1, E2, self._dt_prev)
        t2 = time.perf_counter()
        m.set_stress(P1, P2)
        m.set_term_context(self.v, self._dt_prev)
        f_int = m.internal_force(out=spare["f_int"])
        f_diss = m.dissipative_force(out=spare["f_diss"])
        t3 = time.perf_counter()

        damping = self.beta / self._dt_prev if self.beta > 0.0 and self._dt_prev > 0.0 else 0.0
        f_damp, residual, acc = spare["f_damp"], self._residual, self._acc
        # Trapezoidal work over [t_{n-1}, t_n]; reactions act on clamped dofs only.
        local = self._local
        local[4] = 0.0
        _forces_and_works(f_int, f_ext, self._f_int, self._f_ext, self._f_damp, self._inv_mass_free,
                          self._du, self.v, self.mass, damping, 0.5 * self._dt_prev, f_damp, residual,
                          acc, local)
        c = self.clamped
        res_c = residual[c]
        local[2] = -0.5 * np.dot(res_c + self._res_c, self._du[c])
        if f_diss is not None:
            local[4] = 0.5 * np.dot(f_diss + self._f_diss, self._du)
        # only the finiteness of the sum is tested: where every partial sum is known to be
        # finite the sum is not made (the message below makes it); MPI ranks still sum
        local[6] = 0.0 if not m.parallel and _small(E1, E2, P1, P2) else _point_sums(E1, E2, P1, P2)
        total = self._total
        if m.parallel:
            m.comm.Allreduce(local, total, op=MPI.SUM)
        else:   # the sum over one rank is its own values
            total[:] = local
        if not all(map(math.isfinite, total)):
            if not m.parallel:
                total[6] = _point_sums(E1, E2, P1, P2)
            raise FloatingPointError(
                f"explicit step {self.n_steps} at t = {self.time:.6e} s produced non-finite values "
                f"(work increments, kinetic energy, strain/stress sums = {total}); "
                f"the step that led here was dt = {self._dt_prev:.3e} s and the next is "
                f"dt = {dt:.3e} s (safety {self.safety:g} x the damped Courant limit of "
                f"fabric_fenicsx.fem.timestep.stable_dt). Lower the safety factor or check the "
                f"material response for these strains.")
        self._works += total[:5]
        self.energy = EnergyRecord(self.time, float(total[5]), *self._works.tolist())

        _leapfrog(self.v, self.u, self._du, acc, 0.5 * (self._dt_prev + dt), dt)
        if m.parallel:
            m.u.x.scatter_forward()

        spare["f_int"], spare["f_ext"], spare["f_damp"] = self._f_int, self._f_ext, self._f_damp
        self._f_int, self._f_ext, self._f_damp = f_int, f_ext, f_damp
        if f_diss is not None:
            spare["f_diss"], self._f_diss = self._f_diss, f_diss
        self._res_c = res_c
        self._dt_prev = dt
        self.time += dt
        self.n_steps += 1
        t4 = time.perf_counter()
        tm = self.timings
        tm["strain"] += t1 - t0
        tm["material"] += t2 - t1
        tm["assembly"] += t3 - t2
        tm["rest"] += t4 - t3
        return self.energy


def _sum(a) -> float:
    """np.sum(a) (the same pairwise sum) without its dispatch for an ndarray."""
    return a.sum() if type(a) is np.ndarray else np.sum(a)


def _point_sums(E1, E2, P1, P2) -> float:
    """The sum of the points' strains and stresses that the step tests for finiteness."""
    return float(_sum(E1) + _sum(E2) + _sum(P1) + _sum(P2))


_SUM_BOUND = 1e300
"""n values of magnitude at most _SUM_BOUND / n sum to a finite float in any order (their partial
sums stay below _SUM_BOUND (1 + 2^-53)^n, far from the largest float, 1.8e308)."""


def _small(E1, E2, P1, P2) -> bool:
    """Whether the four arrays are 1-D float64 arrays whose values are all at most
    _SUM_BOUND / (their number + 1) in magnitude, so that their sum in any order is finite."""
    if not (type(E1) is type(E2) is type(P1) is type(P2) is np.ndarray
            and E1.dtype == E2.dtype == P1.dtype == P2.dtype == np.float64
            and E1.ndim == E2.ndim == P1.ndim == P2.ndim == 1):
        return False
    return _bounded(E1, E2, P1, P2, _SUM_BOUND / (E1.size + E2.size + P1.size + P2.size + 1))


@njit(cache=True, nogil=True)
def _bounded(a, b, c, d, bound):
    """Whether |x| <= bound for every value of the four arrays (False at a NaN)."""
    ok = True
    for x in (a, b, c, d):
        for k in range(x.size):
            ok &= abs(x[k]) <= bound
    return ok


@njit(cache=True, nogil=True)
def _forces_and_works(f_int, f_ext, f_int_prev, f_ext_prev, f_damp_prev, inv_mass, du, v, mass,
                      damping, half_dt_prev, f_damp, residual, acc, works):
    """One pass over the dofs of :meth:`CentralDifference.step`: the damping force
    damping (f_int - f_int_prev), the residual f_ext - f_int - f_damp, the acceleration, and
    into ``works`` the trapezoidal work increments of f_int (0), f_ext (1) and f_damp (3) over
    ``du`` and the kinetic energy of the full-step velocity v + half_dt_prev a (5)."""
    w_int = w_ext = w_damp = kinetic = 0.0
    for k in range(f_int.size):
        fd = damping * (f_int[k] - f_int_prev[k])
        r = f_ext[k] - f_int[k] - fd
        a = r * inv_mass[k]
        f_damp[k], residual[k], acc[k] = fd, r, a
        w_int += (f_int[k] + f_int_prev[k]) * du[k]
        w_ext += (f_ext[k] + f_ext_prev[k]) * du[k]
        w_damp += (fd + f_damp_prev[k]) * du[k]
        vf = v[k] + half_dt_prev * a
        kinetic += mass[k] * vf * vf
    works[0], works[1], works[3], works[5] = 0.5 * w_int, 0.5 * w_ext, 0.5 * w_damp, 0.5 * kinetic


@njit(cache=True, nogil=True)
def _leapfrog(v, u, du, acc, dt_mid, dt):
    """v += dt_mid a; du = dt v; u += du (the central-difference update of the owned dofs)."""
    for k in range(v.size):
        v[k] += dt_mid * acc[k]
        du[k] = v[k] * dt
        u[k] += du[k]
