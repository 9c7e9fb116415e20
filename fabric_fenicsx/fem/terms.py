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
  None where the energy is booked elsewhere (the yarns' by the material);
- :meth:`MembraneTerm.measure` (default ``m.dx``, the yarn stresses' quadrature) and
  :meth:`MembraneTerm.prepare` (called before every assembly, for terms with coefficients that
  follow the displacement).

A new term is one small class; see :class:`IsotropicShear` and demos/demo_weak_form.py.
"""
from __future__ import annotations

import math

import basix
import numpy as np
import ufl
from dolfinx import fem

__all__ = ["MembraneTerm", "YarnTerm", "IsotropicShear", "HourglassControl"]


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

    def measure(self, m):
        """The integration measure of the term (default: the membrane's, ``m.dx``)."""
        return m.dx

    def prepare(self, m) -> None:
        """Update the term's coefficients from the current displacement (before assembly)."""


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


class HourglassControl(MembraneTerm):
    """Hourglass control for one-point integrated quadrilaterals (``quadrature_degree`` 1 for the
    yarn stresses), yarn by yarn, with the stiffness each yarn has against the fluctuation:

        psi = 1/2 sum_i [ k_hg alpha_i |D_p L_i|^2 + ratio T_i (D_z . L_i)^2 ],
        D = Grad u - <Grad u>,

    with <Grad u> the cell average of the displacement gradient, D_p its in-plane rows and D_z
    its out-of-plane row, L_i the reference yarn directions, k_hg = ratio x modulus (N/m),
    alpha_i the cell's yarn integrities and T_i = P_i / lambda_i >= 0 its yarn tensions (N/m).

    With one Gauss point a bilinear quadrilateral has zero-energy (hourglass) modes; the
    deviation of Grad u from its cell average is zero for every linear field and non-zero for
    exactly those modes, so penalising it controls them without resisting any homogeneous
    deformation (a patch test passes). This is a physical stabilisation in the sense of
    Flanagan and Belytschko (Int. J. Numer. Meth. Eng. 17 (1981) 679-706): a fraction ``ratio``
    of the stiffness each yarn really has against the in-cell fluctuation of its own tangent,
    its material stiffness in the plane (alpha_i x the intact straight yarn's, Eq. 2-31: a
    broken yarn resists nothing) and its geometric stiffness P_i / lambda_i out of the plane (a
    membrane resists a transverse wrinkle only through its tension; the material stiffness there
    stored 95 % of the hourglass energy, a third of the energy a small impact absorbed).
    Until :meth:`follow` connects the term to a material, alpha_i = 1 and T_i = modulus. The
    average is taken with the 2 x 2 Gauss rule the term is integrated with, so the residual is
    the exact variation of psi at frozen alpha_i, T_i (constant in the cell, updated before
    every assembly). Its wave modulus is bounded by k_hg (T_i is at most the straight yarn's
    tension at failure, far below its modulus).
    """

    name = "hourglass"
    DEGREE = 2

    def __init__(self, ratio: float, modulus: float):
        for label, value in (("ratio", ratio), ("modulus", modulus)):
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
                raise ValueError(f"HourglassControl {label} must be a finite number >= 0, got {value!r}")
        self.ratio, self.modulus = float(ratio), float(modulus)
        self.k = self.ratio * self.modulus
        self._mean = None
        self._integrity = None
        self._tension = None

    def follow(self, state, tension=None) -> None:
        """Follow the material: ``state()`` returns its
        :class:`~fabric_fenicsx.material.contract.DamageState` at the owned quadrature points
        (cell by cell) and ``tension()`` its yarn tensions P_i / lambda_i there (shape (2, n),
        N/m); both are read before every assembly."""
        self._integrity, self._tension = state, tension

    def _setup(self, m) -> None:
        cell = m.msh.ufl_cell()
        if cell.cellname() != "quadrilateral":
            raise ValueError(f"HourglassControl is for quadrilateral meshes, got {cell.cellname()}")
        space = fem.FunctionSpace(m.msh, ufl.TensorElement("DG", cell, 0, shape=(3, 2)))
        self._mean = fem.Function(space, name="mean_grad_u")
        points, weights = basix.make_quadrature(basix.CellType.quadrilateral, self.DEGREE)
        self._grad = fem.Expression(ufl.grad(m.u), points)
        detJ = fem.Expression(abs(ufl.JacobianDeterminant(m.msh)), points).eval(m._cells)
        w = detJ * weights[np.newaxis, :]
        self._w = w / w.sum(axis=1, keepdims=True)
        self._dofs = space.dofmap.list.array[:m.n_cells]
        scalar = fem.FunctionSpace(m.msh, ("DG", 0))
        self._alpha = [fem.Function(scalar, name=f"hourglass_alpha{i}") for i in (1, 2)]
        self._T = [fem.Function(scalar, name=f"hourglass_tension{i}") for i in (1, 2)]
        for a, T in zip(self._alpha, self._T):
            a.x.array[:] = 1.0
            T.x.array[:] = self.modulus
        self._cell_dofs = scalar.dofmap.list.array[:m.n_cells]
        wq = m.quadrature_weights_detJ.reshape(m.n_cells, -1)
        self._wq = wq / wq.sum(axis=1, keepdims=True)
        self._dx = ufl.dx(domain=m.msh, metadata={"quadrature_degree": self.DEGREE,
                                                  "quadrature_scheme": "default"})

    def _set_cellwise(self, functions, values) -> None:
        """Cell averages of point values (one row per yarn) into DG0 functions."""
        for f, v in zip(functions, values):
            f.x.array[self._cell_dofs] = (self._wq * np.reshape(v, self._wq.shape)).sum(axis=1)
            f.x.scatter_forward()

    def prepare(self, m) -> None:
        if self._mean is None:
            self._setup(m)
        grad = self._grad.eval(m._cells).reshape(m.n_cells, self._w.shape[1], 6)
        self._mean.x.array.reshape(-1, 6)[self._dofs] = np.einsum("cp,cpk->ck", self._w, grad)
        self._mean.x.scatter_forward()
        ones = np.ones(m.n_points)
        state = self._integrity() if self._integrity is not None else None
        self._set_cellwise(self._alpha, (ones, ones) if state is None else (state.alpha1, state.alpha2))
        self._set_cellwise(self._T, (self.modulus * ones,) * 2 if self._tension is None
                           else np.maximum(self._tension(), 0.0))

    def measure(self, m):
        if self._mean is None:
            self._setup(m)
        return self._dx

    def _parts(self, m, w):
        """[(stiffness, D_p L_i . w_p L_i + D_z . L_i w_z . L_i split)] for both yarns, as UFL:
        the bilinear form of psi between the fluctuation D and a gradient w."""
        if self._mean is None:
            self._setup(m)
        d = ufl.grad(m.u) - self._mean
        total = 0
        for a, T, L in zip(self._alpha, self._T, (m.L1, m.L2)):
            dL, wL = d * L, w * L
            total += self.k * a * (dL[0] * wL[0] + dL[1] * wL[1]) + self.ratio * T * dL[2] * wL[2]
        return total

    def energy_density(self, m):
        if self._mean is None:
            self._setup(m)
        return 0.5 * self._parts(m, ufl.grad(m.u) - self._mean)

    def integrand(self, m):
        return self._parts(m, ufl.grad(m.v))

    def wave_modulus(self) -> float:
        return self.k
