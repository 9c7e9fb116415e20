"""The explicit time step of an impact run: the damped Courant limit and when to re-check it.

dt = safety L_min / c_max (sqrt(1 + xi^2) - xi), c_max^2 = K_max / rho_A, with K_max the
largest wave modulus over the live points (the material's plus the weak-form terms') and
xi = beta omega / 2 the damping ratio of the stiffness-proportional damping at the highest mesh
frequency omega = 2 c_max / L_min. dt is only ever lowered; see docs/impact_model.md.

The damping coefficient beta is a property of the fabric and the run, not of the mesh:
beta = 2 xi / omega_cell with omega_cell the highest frequency a membrane of unit-cell-sized
cells carries (:func:`unit_cell_frequency`), the shortest wave the homogenised membrane
represents at all. On a mesh coarser than the unit cell its damping ratio at the highest mesh
frequency is xi L_cell / L_min < xi.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["DtChange", "stable_dt", "check_due", "highest_frequency", "unit_cell_length",
           "unit_cell_frequency", "damping_coefficient"]


@dataclass
class DtChange:
    """A lowering of the time step (summary ``dt_changes``)."""
    step: int
    time: float
    dt_old: float
    dt_new: float
    modulus: float


def stable_dt(modulus: float, areal_density: float, L_min: float, beta: float, safety: float) -> float:
    """safety x the damped Courant limit (s) for the wave modulus ``modulus`` (N/m), areal
    density rho_A (kg/m^2), smallest cell size L_min (m) and damping coefficient beta (s)."""
    omega = highest_frequency(modulus, areal_density, L_min)
    xi = 0.5 * beta * omega
    return safety * 2.0 / omega * (math.sqrt(1.0 + xi * xi) - xi)


def highest_frequency(modulus: float, areal_density: float, length: float) -> float:
    """omega = 2 c / length (rad/s), c^2 = modulus / rho_A: the highest frequency of a lumped
    bilinear membrane with cells of size ``length`` (area over diagonal, m)."""
    return 2.0 * math.sqrt(modulus / areal_density) / length


def unit_cell_length(fabric) -> float:
    """Area over diagonal (m) of the unit cell, the 2 w_1 x 2 w_2 rectangle of one crossing
    (w_i: projected half-length of yarn i): the ``L_min`` a mesh of unit cells would have."""
    a, b = 2.0 * fabric.warp.w, 2.0 * fabric.fill.w
    return a * b / math.hypot(a, b)


def unit_cell_frequency(fabric, modulus: float) -> float:
    """omega_cell (rad/s): :func:`highest_frequency` of a membrane whose cells are unit cells
    (:func:`unit_cell_length`)."""
    return highest_frequency(modulus, fabric.areal_density, unit_cell_length(fabric))


def damping_coefficient(xi: float, omega_ref: float) -> float:
    """beta = 2 xi / omega_ref (s): stiffness-proportional damping with the fraction ``xi`` of
    critical damping at ``omega_ref``."""
    return 2.0 * xi / omega_ref


def check_due(step: int, step_touch: int | None, interval: int) -> bool:
    """Re-check dt every ``interval`` steps, and at every step of the first ``interval`` after
    the first touch (the strain increments the look-ahead extrapolates are not known before)."""
    return step > 0 and (step % interval == 0 or (
        step_touch is not None and step - step_touch <= interval))
