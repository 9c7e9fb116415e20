"""The material-point contract: what every constitutive law of the package takes and returns.

A fabric material point is driven by the membrane's yarn strains E1, E2 (Eq. 2-3, Green strains
along warp and fill) and carries a damage history, the yarn integrities alpha1, alpha2 in [0, 1]
(Eq. 2-25: alpha_i = min over the history of alpha(mu_i^max), so damage never heals). It returns
the membrane stresses P1, P2 (N/m, force per reference length, Eq. 2-31), the new damage state
and, for the explicit integrator's stable time step, its wave modulus: the largest eigenvalue of
the symmetric part of dP_i/dlambda_j (N/m), so that a membrane wave runs at
sqrt(modulus / rho_A). A point whose two yarns are both broken (alpha1 = alpha2 = 0, SDV1 = 0 of
Table 2) carries nothing and is *removed*: :attr:`DamageState.removed` says so.

Three shapes of the same contract, for three callers:

- :class:`MaterialLaw`, vectorised and free of state (the caller keeps the history):
  :class:`fabric_fenicsx.surrogate.Surrogate`, the static scenes'
  :class:`fabric_fenicsx.studies.static.UnitCellPoint`, the test law
  :class:`fabric_fenicsx.fem.explicit.LinearYarnMaterial`.
- :class:`MaterialPoint`, one point at a time with the full unit-cell answer (contact force V,
  maximum stretches), what the static scenes of chapter 3 record: the unit cell, the surrogate.
- :class:`QuadratureMaterial`, the material at the membrane's quadrature points, which keeps the
  damage history itself (it lives with the material, not in the integrator) and is what
  :class:`fabric_fenicsx.fem.explicit.CentralDifference` calls:
  :class:`fabric_fenicsx.fem.yarn_stress.YarnStress` (a :class:`MaterialLaw` plus damping,
  the tension-only and slack rules and removal), ``LinearYarnMaterial``.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

__all__ = ["DamageState", "MaterialLaw", "MaterialPoint", "QuadratureMaterial", "POINT_FIELDS", "ENERGIES"]


@dataclass(frozen=True)
class DamageState:
    """Damage history of a set of points: warp and fill integrities alpha1, alpha2 in [0, 1]
    (1 intact, 0 broken; Eq. 2-25)."""

    alpha1: np.ndarray
    alpha2: np.ndarray

    @classmethod
    def intact(cls, n: int) -> "DamageState":
        """n undamaged points (alpha1 = alpha2 = 1)."""
        return cls(np.ones(n), np.ones(n))

    @property
    def removed(self) -> np.ndarray:
        """Points whose both yarns are broken (SDV1 = 0, Table 2): they carry nothing from now on."""
        return (np.asarray(self.alpha1) <= 0.0) & (np.asarray(self.alpha2) <= 0.0)


@runtime_checkable
class MaterialLaw(Protocol):
    """A constitutive law vectorised over points, without state of its own."""

    def constitutive_update(self, E1: np.ndarray, E2: np.ndarray,
                            state: DamageState) -> tuple[np.ndarray, np.ndarray, DamageState]:
        """(P1, P2, new state) for the yarn strains E1, E2 reached from the history ``state``:
        P_i in N/m (Eq. 2-31), the new alpha_i = min(alpha_i^hist, alpha(mu_i^max)) (Eq. 2-25)."""
        ...

    def wave_modulus(self, E1: np.ndarray, E2: np.ndarray, state: DamageState) -> np.ndarray:
        """Per point, the largest eigenvalue (N/m) of the symmetric part of dP_i/dlambda_j at
        frozen damage: the stiffness that sets the membrane's wave speed and stable time step."""
        ...


@runtime_checkable
class MaterialPoint(Protocol):
    """One material point as the static scenes drive it (chapter 3).

    ``respond(E1, E2, alpha_hist)`` returns an object with attributes E2, P1, P2 (N/m), V (N),
    alpha1, alpha2 (the new damage history). A point that can leave the fill free
    (``E2=None``: P2 = 0, E2 solved) sets ``supports_free_fill = True``; for any other one the
    scenes find E2 with P2 = 0 by a root find.
    """

    def respond(self, E1: float, E2: float | None, alpha_hist: tuple[float, float]): ...


POINT_FIELDS = ("P1", "P2", "E1", "E2", "SDV1", "SDV2", "SDV3")
"""The point fields an impact run writes (cell averages in impact.xdmf): membrane stresses
P1, P2 (N/m, elastic + viscous), yarn strains E1, E2 (Green), and Table 2's state variables
SDV1 (1 while either yarn carries load, 0 when both are broken), SDV2 = alpha1, SDV3 = alpha2."""

ENERGIES = ("viscous_dissipation", "damage_dissipation", "erosion_energy")
"""The energies a quadrature material books (J, this rank's points, accumulated over the run):
work of its viscous stress, energy released by damage (Eq. 2-25) and the stored energy of the
points taken out by :meth:`QuadratureMaterial.remove`."""


@runtime_checkable
class QuadratureMaterial(Protocol):
    """The material at the membrane's owned quadrature points (cell-major, n points), holding
    their damage history: everything the explicit integrator, the impact loop, cell removal and
    the output read.

    - ``update(E1, E2, dt)``: advance the state to the yarn strains E1, E2 (Green, shape (n,))
      of the current step, reached in the step ``dt`` (s; 0 on the first step; the rate of a
      viscous stress), and return the stresses P1, P2 (N/m, Eq. 2-31) the membrane integrates;
    - ``state``: the damage history (:class:`DamageState`) after the last update; its
      ``removed`` says which points have both yarns broken (Table 2);
    - ``strains``: (E1, E2) of the last update (cell removal erodes on them);
    - ``beta``: the stiffness-proportional damping coefficient (s) of its viscous stress, 0 for
      none (it enters the stable time step);
    - ``max_wave_modulus(lookahead=0.0)``: this rank's largest wave modulus (N/m) over its live
      points, at the strains extrapolated ``lookahead`` steps along their last increase;
    - ``tension()``: yarn tensions P_i / lambda_i (N/m, shape (2, n)) of the last update;
    - ``point_fields()``: the fields to write, a subset of :data:`POINT_FIELDS` keyed by name,
      each of shape (n,) (units as there); optionally also ``mu_crit1``, ``mu_crit2`` (a strength
      scatter's laws) and ``E1_peak``, ``E2_peak`` (each point's largest yarn Green strains);
    - ``energies()``: this rank's accumulated energies (J) keyed by :data:`ENERGIES`;
    - ``diagnostics()``: this rank's counters (int) of evaluations outside the law's range,
      reported in summary.json (``{}`` for none);
    - ``remove(points)``: take points out for good (a removed cell): no stress after it.
    """

    beta: float

    @property
    def state(self) -> DamageState: ...

    @property
    def strains(self) -> tuple[np.ndarray, np.ndarray]: ...

    def update(self, E1: np.ndarray, E2: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]: ...

    def max_wave_modulus(self, lookahead: float = 0.0) -> float: ...

    def tension(self) -> np.ndarray: ...

    def point_fields(self) -> dict[str, np.ndarray]: ...

    def energies(self) -> dict[str, float]: ...

    def diagnostics(self) -> dict[str, int]: ...

    def remove(self, points: np.ndarray) -> None: ...
