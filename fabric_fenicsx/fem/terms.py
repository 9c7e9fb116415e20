"""Terms of the membrane's weak form, each with its residual, its share of the stable time step
and its stored energy.

The membrane's residual is R(u; v) = sum over its terms of int live * r_term(u; v) dA, where
``live`` is the membrane's live-cell mask (1 in a live cell, 0 in a deleted or eroded one), so a
removed cell carries no force from any term. A term gives:

- :meth:`MembraneTerm.integrand`: r_term, a UFL expression linear in the test function ``m.v``
  (the membrane multiplies it by the mask and integrates it with ``m.dx``);
- :meth:`MembraneTerm.wave_modulus`: its stiffness (N/m) as a wave modulus, added to the
  material's to set the explicit stable time step dt ~ h / sqrt(modulus / rho_A);
- :meth:`MembraneTerm.energy_density`: its stored energy per reference area (J/m^2, UFL), or
  None where the energy is booked elsewhere (the yarns' by the material).

A new term is one small class; see :class:`IsotropicShear` and demos/demo_weak_form.py.
"""
from __future__ import annotations

import math

import ufl

__all__ = ["MembraneTerm", "YarnTerm", "IsotropicShear"]


class MembraneTerm:
    """Base of a weak-form term; subclasses override :meth:`integrand` and, where they have
    stiffness or energy of their own, :meth:`wave_modulus` and :meth:`energy_density`."""

    name = "term"

    def integrand(self, m):
        """r(u; v): the term's integrand of the residual, linear in ``m.v`` (per reference area)."""
        raise NotImplementedError

    def wave_modulus(self) -> float:
        """The term's stiffness as a wave modulus (N/m), added to the material's for dt."""
        return 0.0

    def energy_density(self, m):
        """Stored energy per reference area (J/m^2) as a UFL expression, or None."""
        return None


class YarnTerm(MembraneTerm):
    """The yarn stresses of the unit cell: P : Grad v with P = P1 l1 (x) L1 + P2 l2 (x) L2
    (Eq. 2-4, 2-5), P_i from the membrane's quadrature functions P1, P2.

    Its stiffness is the material's (the integrator asks the material for its wave modulus) and
    its stored energy is booked by the material, so both are left at the base's values here."""

    name = "yarns"

    def integrand(self, m):
        # Written per yarn, sum_i P_i l_i . (Grad v L_i), it compiles to a ~10 % faster kernel
        # than inner(P, grad(v)).
        grad_v = ufl.grad(m.v)
        return (m.P1 / m.lambda1 * ufl.dot(m.a1, grad_v * m.L1)
                + m.P2 / m.lambda2 * ufl.dot(m.a2, grad_v * m.L2))


class IsotropicShear(MembraneTerm):
    """A small isotropic in-plane shear stiffness G (N/m): the variation of
    psi = G dev(E) : dev(E) with the membrane Green strain E = (F^T F - I) / 2 (Eq. 2-2).

    Not part of the thesis model, which neglects shear stresses (Sec. 2.1); a regularisation of
    the trellising modes and the example of a term. At small strain psi gives both the
    longitudinal and the shear wave modulus G (uniaxial E11: psi = G E11^2 / 2; shear E12:
    psi = 2 G E12^2), which is what :meth:`wave_modulus` returns. On bilinear quadrilaterals with
    a lumped mass the highest discrete frequency of this term alone is 1.36-1.38 x the continuum
    estimate (measured on 4 x 4 to 12 x 12 meshes), so for G up to the yarns' modulus the true
    stable step is at least 0.97 of the estimate, inside the safety factor (run.dt_safety 0.8);
    a shear-dominated membrane (G >> yarn modulus) would need a lower safety factor."""

    name = "isotropic_shear"

    def __init__(self, shear_modulus: float):
        if not (isinstance(shear_modulus, (int, float)) and math.isfinite(shear_modulus)
                and shear_modulus >= 0):
            raise ValueError(f"shear_modulus must be a finite number >= 0 in N/m, got {shear_modulus!r}")
        self.G = float(shear_modulus)

    def energy_density(self, m):
        E = 0.5 * (m.F.T * m.F - ufl.Identity(2))
        devE = E - 0.5 * ufl.tr(E) * ufl.Identity(2)
        return self.G * ufl.inner(devE, devE)

    def integrand(self, m):
        return ufl.derivative(self.energy_density(m), m.u, m.v)

    def wave_modulus(self) -> float:
        return self.G
