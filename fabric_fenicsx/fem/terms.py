"""Terms of the membrane's weak form, each with its residual, its share of the stable time step
and its stored or dissipated energy.

**The equation the membrane solves** (thesis Eq. 2-4, discretised with a lumped mass):

    M a = f_ext - f_int,    f_int,a = R(u; N_a),    R(u; v) = sum over terms of int live r_term(u; v) dA,

with N_a the nodal test functions, a the nodal accelerations, f_ext the contact forces, and
``live`` the live-cell mask (1 in a live cell, 0 in a deleted or eroded one, so a removed cell
carries no force from any term). **The sign of a term**: r_term(u; v) is the internal virtual
work, the work the fabric's internal forces absorb in the virtual displacement v; for a term with
stored energy psi(u) it is the variation d psi(u)[v] (``ufl.derivative(psi, m.u, m.v)``), and for
a viscous term it is positive for v along the velocity (eta Grad(velocity) : Grad v). A term
with the other sign pushes the fabric and feeds it energy. A term gives:

- :meth:`MembraneTerm.integrand`: r_term, a UFL expression linear in the test function ``m.v``
  (the membrane multiplies it by the mask and integrates it with ``m.dx``); the membrane ``m``
  is the term's context: ``u``, ``velocity`` (v^{n-1/2}), ``dt``, ``F``, the yarn directions and
  stretches (:class:`~fabric_fenicsx.fem.membrane.Membrane`);
- :meth:`MembraneTerm.wave_modulus`: its stiffness (N/m) as a wave modulus, added to the
  material's to set the explicit stable time step dt ~ h / sqrt(modulus / rho_A);
- :meth:`MembraneTerm.viscosity`: its viscosity eta (N s/m) where it damps, the damping's
  share of the stable step (:func:`fabric_fenicsx.fem.timestep.stable_dt`);
- :attr:`MembraneTerm.dissipative`: True when its work is dissipated, not stored: the run books
  it as dissipation (``energies.terms_dissipation`` in summary.json), not as stored energy;
- :meth:`MembraneTerm.energy_density`: its stored energy per reference area (J/m^2, UFL), or
  None where it stores none or the energy is booked elsewhere (the yarns' by the material);
- :attr:`MembraneTerm.follows_integrity` with :meth:`MembraneTerm.follow`: the public switch
  for a term whose stiffness follows the yarns' damage; an impact run calls ``follow`` with the
  material's damage state and yarn tensions (:class:`FollowsIntegrity` is a ready mixin);
- :meth:`MembraneTerm.measure` (default ``m.dx``, the yarn stresses' quadrature) and
  :meth:`MembraneTerm.prepare` (called before every assembly, for terms with coefficients that
  follow the displacement).

A term whose residual is a fixed linear operator per cell may instead set
:attr:`MembraneTerm.per_cell` and give :meth:`MembraneTerm.add_cell_forces` (compiled or numpy,
over all owned cells at once, live-cell mask applied by the term): the membrane adds those
forces to the assembled ones and books the energy it returns (:class:`HourglassControl`).

A new term is one small class; see :class:`IsotropicShear` and demos/demo_weak_form.py. A scene
names extra terms as ``membrane.terms = ["package.module:Class"]`` (or a table with ``class``
and keyword arguments), so that the command line and the studies run them.
"""
from __future__ import annotations

import math

import basix
import numpy as np
import ufl
from numba import njit

__all__ = ["MembraneTerm", "FollowsIntegrity", "YarnTerm", "IsotropicShear", "HourglassControl",
           "fluctuation_matrices", "shape_gradients"]


class MembraneTerm:
    """Base of a weak-form term; subclasses override :meth:`integrand` and, where they have
    stiffness or energy of their own, :meth:`wave_modulus` and :meth:`energy_density`."""

    name = "term"
    per_cell = False
    """True for a term that adds its forces itself (:meth:`add_cell_forces`) instead of being
    assembled from its UFL :meth:`integrand`."""
    dissipative = False
    """True for a term whose work is dissipated (a viscous term): booked as dissipation in the
    energy balance, not as stored energy."""
    follows_integrity = False
    """True for a term that follows the yarns' damage: an impact run then calls :meth:`follow`
    before the first step."""

    def integrand(self, m):
        """r(u; v): the term's integrand of the residual, linear in ``m.v`` (per reference area)."""
        raise NotImplementedError

    def wave_modulus(self) -> float:
        """The term's stiffness as a wave modulus (N/m), added to the material's for dt."""
        return 0.0

    def viscosity(self) -> float:
        """The term's viscosity eta (N s/m), its damping's share of the stable time step:
        a damping force eta Grad(velocity) : Grad v has the damping ratio omega eta / (2 K) at
        the mesh's highest frequency omega. 0 for a term that does not damp."""
        return 0.0

    def energy_density(self, m):
        """Stored energy per reference area (J/m^2) as a UFL expression, or None."""
        return None

    def follow(self, state, tension=None) -> None:
        """For a term with :attr:`follows_integrity`: ``state()`` returns the material's
        :class:`~fabric_fenicsx.material.contract.DamageState` at the owned quadrature points
        (cell by cell) and ``tension()`` its yarn tensions P_i / lambda_i there (shape (2, n),
        N/m); both are to be read before every assembly (in :meth:`prepare`)."""
        raise NotImplementedError(f"{type(self).__name__} sets follows_integrity but has no follow()")

    def measure(self, m):
        """The integration measure of the term (default: the membrane's, ``m.dx``)."""
        return m.dx

    def prepare(self, m) -> None:
        """Update the term's coefficients from the current displacement (before assembly)."""

    def add_cell_forces(self, m, forces: np.ndarray) -> float:
        """A :attr:`per_cell` term: add its nodal forces (N) of the owned cells, live-cell mask
        applied, into ``forces`` (the local nodes with ghosts, shape (n, 3)) at the state of the
        last :meth:`prepare`; return its stored energy (J) in those cells."""
        raise NotImplementedError

    def cell_energy(self, m) -> float:
        """A :attr:`per_cell` term: the stored energy (J) :meth:`add_cell_forces` returns, at
        the state of the last :meth:`prepare` (override to skip the forces)."""
        return self.add_cell_forces(m, np.zeros((m.u.x.array.size // 3, 3)))


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


def _cell_weights(m) -> np.ndarray:
    """Each owned cell's quadrature weights normalised to sum 1, shape (n_cells, points)."""
    w = m.quadrature_weights_detJ.reshape(m.n_cells, -1)
    return w / w.sum(axis=1, keepdims=True)


def _cell_means(wq: np.ndarray, values) -> np.ndarray:
    """Cell averages, shape (len(values), n_cells), of point values (one row per yarn) with the
    weights of :func:`_cell_weights`."""
    return np.stack([(wq * np.reshape(v, wq.shape)).sum(axis=1) for v in values])


class FollowsIntegrity:
    """Mixin for a term whose stiffness follows the weave's integrity: per cell the factor
    min(alpha1, alpha2) of the cell means of the material's damage (a cell with a broken yarn
    family has no weave left to resist), once :meth:`follow` connects it to a material; 1
    before. Multiply the term's stiffness by :meth:`_coefficient` in its UFL expressions."""

    follows_integrity = True
    _integrity = None
    _scale = None
    _wq = None

    def follow(self, state, tension=None) -> None:
        """``state()`` returns the material's DamageState at the owned quadrature points (cell
        by cell), read before every assembly."""
        self._integrity = state

    def _coefficient(self, m):
        """The integrity factor in the UFL form: a DG0 function once the term follows a
        material, else 1."""
        if self._integrity is None:
            return 1.0
        if self._scale is None:
            from dolfinx import fem
            self._scale = fem.Function(fem.FunctionSpace(m.msh, ("DG", 0)), name=f"{self.name}_integrity")
            self._scale.x.array[:] = 1.0
        return self._scale

    def prepare(self, m) -> None:
        if self._integrity is None or self._scale is None:
            return
        if self._wq is None:
            self._wq = _cell_weights(m)
        state = self._integrity()
        self._scale.x.array[m._live_dofs] = _cell_means(self._wq, (state.alpha1, state.alpha2)).min(axis=0)
        self._scale.x.scatter_forward()


class IsotropicShear(FollowsIntegrity, MembraneTerm):
    """A small isotropic in-plane shear stiffness G (N/m): the variation of
    psi = G dev(E) : dev(E) with the membrane Green strain E = (F^T F - I) / 2 (Eq. 2-2).

    Not part of the thesis model, which neglects shear stresses (Sec. 2.1); a regularisation of
    the trellising modes and the example of a term. At small strain psi gives both the
    longitudinal and the shear wave modulus G (uniaxial E11: psi = G E11^2 / 2; shear E12:
    psi = 2 G E12^2), which is what :meth:`wave_modulus` returns. On bilinear quadrilaterals with
    a lumped mass the highest discrete frequency of this term alone is 1.36-1.38 x the continuum
    estimate (measured on 4 x 4 to 12 x 12 meshes), so for G up to the yarns' modulus the true
    stable step is at least 0.97 of the estimate, inside the safety factor (run.dt_safety 0.8);
    a shear-dominated membrane (G >> yarn modulus) would need a lower safety factor. In an
    impact run G follows the weave's integrity (:class:`FollowsIntegrity`): without that, a
    cell whose yarns had broken kept a film of stiffness G (measured: G = 1e5 N/m held the
    projectile of the `make demo` scene, rebounding at 41-42 m/s, cells deleted instead of
    eroded)."""

    name = "isotropic_shear"

    def __init__(self, shear_modulus: float):
        if not (isinstance(shear_modulus, (int, float)) and math.isfinite(shear_modulus)
                and shear_modulus >= 0):
            raise ValueError(f"shear_modulus must be a finite number >= 0 in N/m, got {shear_modulus!r}")
        self.G = float(shear_modulus)

    def energy_density(self, m):
        E = 0.5 * (m.F.T * m.F - ufl.Identity(2))
        devE = E - 0.5 * ufl.tr(E) * ufl.Identity(2)
        return self._coefficient(m) * self.G * ufl.inner(devE, devE)

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
    average and psi are taken with the 2 x 2 Gauss rule; alpha_i and T_i are the cell averages
    of the material's point values, frozen in each assembly (read before every one).

    At frozen alpha_i, T_i psi is quadratic in the cell's nodal displacements u_a:
    D L_i = sum_a u_a g_ai(x) with g_ai = (Grad N_a - <Grad N_a>) . L_i, so each cell's force
    is f_a = sum_i s_i sum_b M_i,ab u_b (per component; s_i = k_hg alpha_i in the plane,
    ratio T_i out of it) with the 4 x 4 matrices M_i,ab = int g_ai g_bi dA fixed by the
    reference geometry (:func:`fluctuation_matrices`). The term adds its forces that way, one
    compiled pass over the cells (:attr:`per_cell`), instead of assembling a second UFL form at
    2 x 2 points every step (benchmarks/bench_hourglass.py prints its cost). Its wave
    modulus is bounded by k_hg (T_i is at most the straight yarn's tension at failure, far
    below its modulus).
    """

    name = "hourglass"
    per_cell = True
    follows_integrity = True
    DEGREE = 2

    def __init__(self, ratio: float, modulus: float):
        for label, value in (("ratio", ratio), ("modulus", modulus)):
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
                raise ValueError(f"HourglassControl {label} must be a finite number >= 0, got {value!r}")
        self.ratio, self.modulus = float(ratio), float(modulus)
        self.k = self.ratio * self.modulus
        self._M = None
        self._integrity = None
        self._tension = None

    def follow(self, state, tension=None) -> None:
        """Follow the material: ``state()`` returns its
        :class:`~fabric_fenicsx.material.contract.DamageState` at the owned quadrature points
        (cell by cell) and ``tension()`` its yarn tensions P_i / lambda_i there (shape (2, n),
        N/m); both are read before every assembly."""
        self._integrity, self._tension = state, tension

    def _setup(self, m) -> None:
        if m.msh.topology.cell_type.name != "quadrilateral":
            raise ValueError("HourglassControl is for quadrilateral meshes, got "
                             f"{m.msh.topology.cell_type.name}")
        from fabric_fenicsx.fem.membrane import yarn_directions

        self._nodes = m.V.dofmap.list.array.reshape(-1, 4)[:m.n_cells]
        self._M = fluctuation_matrices(m.V.tabulate_dof_coordinates()[:, :2][self._nodes],
                                       np.array(yarn_directions(m.angle)), self.DEGREE)
        self._wq = _cell_weights(m)
        self._s = np.empty((m.n_cells, 2, 2))    # s per cell, yarn and (in-plane, out-of-plane)
        self._ones = np.ones(self._wq.size)      # alpha_i and T_i before the term follows a material
        self._full_tension = np.full((2, self._wq.size), self.modulus)

    def prepare(self, m) -> None:
        if self._M is None:
            self._setup(m)
        state = self._integrity() if self._integrity is not None else None
        npts = self._wq.size
        alpha1, alpha2 = ((self._ones, self._ones) if state is None
                          else (np.asarray(state.alpha1, float), np.asarray(state.alpha2, float)))
        tension = self._full_tension if self._tension is None else self._tension()
        _hourglass_stiffness(self._wq, alpha1, alpha2, tension, m.live.x.array, m._live_dofs, self.k,
                             self.ratio, self._s)

    def add_cell_forces(self, m, forces: np.ndarray) -> float:
        return _add_hourglass_forces(self._M, self._nodes, self._s, m.u.x.array.reshape(-1, 3), forces)

    def cell_energy(self, m) -> float:
        return _add_hourglass_forces(self._M, self._nodes, self._s, m.u.x.array.reshape(-1, 3),
                                     np.zeros((0, 3)))   # no rows: the energy only

    def wave_modulus(self) -> float:
        return self.k


def shape_gradients(X: np.ndarray, degree: int = 2) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(N, Grad N, W) of bilinear quadrilaterals with reference node coordinates ``X`` (n_cells,
    4, 2, in basix's vertex order) at the Gauss points of ``degree``: the shape functions N
    (q, a), their gradients Grad N_a (n_cells, q, a, 2) and the points' weights W = |det J| w
    (n_cells, q). A degenerate cell (zero Jacobian at a point) is refused."""
    points, weights = basix.make_quadrature(basix.CellType.quadrilateral, degree)
    element = basix.create_element(basix.ElementFamily.P, basix.CellType.quadrilateral, 1,
                                   basix.LagrangeVariant.equispaced)
    table = element.tabulate(1, points)
    N, dN = table[0, :, :, 0], table[1:, :, :, 0]                   # (q, a); (2, q, a): d/dxi_j
    J = np.einsum("caI,jqa->cqIj", X, dN)                           # dX_I / dxi_j
    detJ = np.abs(J[..., 0, 0] * J[..., 1, 1] - J[..., 0, 1] * J[..., 1, 0])   # either orientation
    if not np.all(detJ > 0):
        raise ValueError("shape_gradients: a degenerate quadrilateral (zero Jacobian at a "
                         "Gauss point): fix the mesh")
    grad = np.einsum("jqa,cqjI->cqaI", dN, np.linalg.inv(J))        # Grad N_a at the points
    return N, grad, detJ * weights


def fluctuation_matrices(X: np.ndarray, directions: np.ndarray, degree: int = 2) -> np.ndarray:
    """M_i,ab = int_cell g_ai g_bi dA, g_ai = (Grad N_a - <Grad N_a>) . L_i, for bilinear
    quadrilaterals with reference node coordinates ``X`` (n_cells, 4, 2, in basix's vertex
    order) and yarn directions ``directions`` (2, 2): shape (n_cells, 2, 4, 4). Integrated and
    averaged (<.>, area-weighted) with the Gauss rule of ``degree``."""
    _, grad, W = shape_gradients(X, degree)                         # W: (c, q)
    mean = np.einsum("cq,cqaI->caI", W / W.sum(axis=1, keepdims=True), grad)
    g = np.einsum("cqaI,iI->cqai", grad - mean[:, None], directions)
    return np.einsum("cq,cqai,cqbi->ciab", W, g, g)


@njit(cache=True, nogil=True)
def _hourglass_stiffness(wq, alpha1, alpha2, tension, live, live_dofs, k, ratio, s):
    """s[c, i] = (k <alpha_i>, ratio <max(T_i, 0)>) x live_c per cell c and yarn i, <.> the
    cell means with the normalised weights ``wq`` (n_cells, points), live_c = live[live_dofs[c]]
    (the live-cell mask's value of the cell)."""
    npc = wq.shape[1]
    for c in range(wq.shape[0]):
        a1 = a2 = t1 = t2 = 0.0
        for q in range(npc):
            p, w = c * npc + q, wq[c, q]
            a1 += w * alpha1[p]
            a2 += w * alpha2[p]
            t1 += w * max(tension[0, p], 0.0)
            t2 += w * max(tension[1, p], 0.0)
        live_c = live[live_dofs[c]]
        s[c, 0, 0], s[c, 0, 1] = k * a1 * live_c, ratio * t1 * live_c
        s[c, 1, 0], s[c, 1, 1] = k * a2 * live_c, ratio * t2 * live_c


@njit(cache=True, nogil=True)
def _add_hourglass_forces(M, nodes, stiffness, u, forces):
    """f_a += sum_i s_i sum_b M_i,ab u_b per cell (s_i = stiffness[c, i, 0] for x, y and
    stiffness[c, i, 1] for z) into ``forces``; returns 1/2 sum u . f of these cells (J).
    ``forces`` without rows: the energy only, nothing added."""
    add = forces.shape[0] > 0
    energy = 0.0
    for c in range(M.shape[0]):
        for a in range(4):
            fx = fy = fz = 0.0
            for b in range(4):
                in_plane = stiffness[c, 0, 0] * M[c, 0, a, b] + stiffness[c, 1, 0] * M[c, 1, a, b]
                out_of_plane = stiffness[c, 0, 1] * M[c, 0, a, b] + stiffness[c, 1, 1] * M[c, 1, a, b]
                nb = nodes[c, b]
                fx += in_plane * u[nb, 0]
                fy += in_plane * u[nb, 1]
                fz += out_of_plane * u[nb, 2]
            na = nodes[c, a]
            if add:
                forces[na, 0] += fx
                forces[na, 1] += fy
                forces[na, 2] += fz
            energy += 0.5 * (fx * u[na, 0] + fy * u[na, 1] + fz * u[na, 2])
    return energy
