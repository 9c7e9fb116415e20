"""The stable time step of the explicit membrane: one rule for the integrator, the impact loop
and their messages.

    dt = safety x 2 / omega (sqrt(1 + xi^2) - xi),    omega = 2 c / L,    c^2 = K / rho_A,
    xi = omega / 2 x (beta + eta / K),

the damped Courant limit of the central difference with the damping force taken at the lagged
velocity (Belytschko, Liu and Moran, Nonlinear Finite Elements, Sec. 6.3). K (N/m) is the
largest wave modulus over the live points, the material's plus the weak-form terms'; rho_A
(kg/m^2) the areal density; L (m) the cell size whose L / c is the step of the mesh's highest
mode (``area_over_diagonal`` of :func:`fabric_fenicsx.fem.mesh.cell_sizes` in an impact run:
exact for the lumped bilinear square of an isotropic membrane; the shortest edge is exact where
the yarns run along the edges); beta (s) the stiffness-proportional damping coefficient of the
material's viscous stress and of the integrator; eta (N s/m) the viscosity of the weak-form
terms that damp (:meth:`~fabric_fenicsx.fem.terms.MembraneTerm.viscosity`), whose damping ratio
at omega is omega eta / (2 K). :class:`~fabric_fenicsx.fem.explicit.CentralDifference`
gathers these inputs (:meth:`~fabric_fenicsx.fem.explicit.CentralDifference.stable_dt`); the
impact loop lowers dt with it when the wave modulus rises, never raises it.

The damping coefficient beta is a property of the fabric and the run, not of the mesh:
beta = 2 xi / omega_cell with omega_cell the highest frequency a membrane of unit-cell-sized
cells carries (:func:`unit_cell_frequency`), the shortest wave the homogenised membrane
represents at all. On a mesh coarser than the unit cell its damping ratio at the highest mesh
frequency is xi L_cell / L_min < xi.
"""
from __future__ import annotations

import math

__all__ = ["stable_dt", "highest_frequency", "unit_cell_length", "unit_cell_frequency",
           "damping_coefficient"]


def stable_dt(modulus: float, areal_density: float, L_min: float, beta: float, safety: float,
              viscosity: float = 0.0) -> float:
    """safety x the damped Courant limit (s) for the wave modulus K = ``modulus`` (N/m), areal
    density rho_A (kg/m^2), cell size L_min (m), stiffness-proportional damping coefficient
    beta (s) and the terms' viscosity eta (N s/m); the rule of the module docstring."""
    for name, value, low in (("modulus", modulus, 0.0), ("areal_density", areal_density, 0.0),
                             ("L_min", L_min, 0.0)):
        if not (math.isfinite(value) and value > low):
            raise ValueError(f"stable_dt: {name} must be finite and > 0, got {value!r}")
    for name, value in (("beta", beta), ("viscosity", viscosity)):
        if not (math.isfinite(value) and value >= 0):
            raise ValueError(f"stable_dt: {name} must be finite and >= 0, got {value!r}")
    if not 0 < safety <= 1:
        raise ValueError(f"stable_dt: safety must be in (0, 1], got {safety!r}")
    omega = highest_frequency(modulus, areal_density, L_min)
    xi = 0.5 * beta * omega
    if viscosity:
        xi += 0.5 * omega * viscosity / modulus
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
