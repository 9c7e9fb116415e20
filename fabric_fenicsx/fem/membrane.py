"""Geometrically nonlinear woven-fabric membrane (thesis Sec. 2.1, Eq. 2-1 to 2-6), DOLFINx 0.5.2.

The fabric is a membrane without bending stiffness on a flat 2D reference mesh that carries a
3-component displacement u, so the membrane deformation gradient is the 3 x 2 matrix
F = I_32 + Grad u.  The warp (yarn 1) and fill (yarn 2) run along the orthogonal reference unit
vectors L1 = (cos t, sin t), L2 = (-sin t, cos t) for the material angle t.  With a_i = F L_i,
lambda_i = |a_i| and l_i = a_i / lambda_i, the yarn strains are E_i = (lambda_i^2 - 1) / 2
(Eq. 2-3) and the first Piola-Kirchhoff stress is P = P1 l1 (x) L1 + P2 l2 (x) L2 (Eq. 2-5),
P_i in N/m (force per reference length).  P1 and P2 live in a quadrature space: the material
(the unit-cell surrogate) is evaluated pointwise in numpy and the values are written straight
into the quadrature functions.  The internal force vector is the weak form of Div P
(Eq. 2-4): f_int = assemble of int P : Grad v dA.

Point arrays (strains, stresses, weights) always cover the quadrature points of the cells owned
by this rank, cell-major: index = cell * n_points_per_cell + point.  Dof arrays (forces, masses,
displacements) cover the owned dofs of the blocked space: index = 3 * node + component.
"""
from __future__ import annotations

import typing

import basix
import numpy as np
import ufl
from dolfinx import fem, la
from dolfinx.fem import petsc as fem_petsc
from mpi4py import MPI
from petsc4py import PETSc

from fabric_fenicsx.fem.packing import CoefficientPacker
from fabric_fenicsx.fem.point_strains import PointStrains
from fabric_fenicsx.fem.terms import MembraneTerm, YarnTerm

__all__ = ["Membrane", "yarn_directions"]

_BASIX_CELL = {"quadrilateral": basix.CellType.quadrilateral,
               "triangle": basix.CellType.triangle}
_CELL_EDGES = {"quadrilateral": ((0, 1), (0, 2), (1, 3), (2, 3)),
               "triangle": ((0, 1), (1, 2), (0, 2))}


def yarn_directions(angle: float) -> tuple[np.ndarray, np.ndarray]:
    """Reference warp and fill unit vectors L1, L2 (orthogonal, thesis Sec. 2.1) for the
    material angle `angle` (rad) measured from the x axis."""
    if not np.isfinite(angle):
        raise ValueError(f"angle must be a finite number of radians, got {angle!r}")
    c, s = np.cos(angle), np.sin(angle)
    return np.array([c, s]), np.array([-s, c])


class Membrane:
    """Woven-fabric membrane: kinematics, yarn strains and internal force (Eq. 2-1 to 2-6).

    Args:
        msh: flat 2D mesh (tdim = gdim = 2) of the reference configuration, lengths in m.
        angle: material angle (rad) of the warp direction L1 from the x axis.
        quadrature_degree: degree of the quadrature rule carrying P1, P2 (2 gives 2 x 2 Gauss
            points on quadrilaterals).
        jit_params: DOLFINx JIT parameters for the strain expression and the forms, e.g.
            {"cffi_extra_compile_args": ["-O3", "-march=native"]} (3.7x faster strain evaluation
            here, but the compiled kernels then only run on CPUs like this one).

    Attributes:
        V: P1 function space with 3 displacement components.
        u: displacement Function (m).
        v: test function on V.
        F: UFL deformation gradient I_32 + Grad u (3 x 2).
        P1, P2: quadrature Functions holding the yarn stresses (N/m).
        dx: integration measure with the quadrature metadata.
        terms: the weak-form terms (:mod:`fabric_fenicsx.fem.terms`), first the yarn term;
            add one with :meth:`add_term`.
        live: DG0 live-cell mask (1 live, 0 removed) that multiplies every term.
        quadrature_weights_detJ: reference area dA (m^2) of every owned quadrature point.
        parallel: more than one rank, so there are ghost values to share. On one rank there are
            none, and the scatters and ghost updates of a step, which change nothing there, are
            skipped.

    The term context: a term's :meth:`~fabric_fenicsx.fem.terms.MembraneTerm.integrand` receives
    the membrane and may use ``u``, ``v``, ``F``, ``L1``, ``L2``, ``a1``, ``a2``, ``lambda1``,
    ``lambda2``, ``dx`` and, for rate-dependent terms, ``velocity`` (a Function holding the
    lagged velocity v^{n-1/2}, m/s, set by the integrator before each assembly; created on first
    use) and ``dt`` (a Constant, the step dt_{n-1/2} that led to u^n, s).
    """

    def __init__(self, msh, angle: float = 0.0, quadrature_degree: int = 2,
                 jit_params: dict | None = None):
        if msh.topology.dim != 2 or msh.geometry.dim != 2:
            raise ValueError("msh must be a flat 2D mesh (tdim = gdim = 2), got "
                             f"tdim={msh.topology.dim}, gdim={msh.geometry.dim}")
        cell_name = msh.topology.cell_type.name
        if cell_name not in _BASIX_CELL:
            raise ValueError(f"msh cell type must be quadrilateral or triangle, got {cell_name}")
        if int(quadrature_degree) != quadrature_degree or quadrature_degree < 1:
            raise ValueError("quadrature_degree must be an integer >= 1, "
                             f"got {quadrature_degree!r}")
        q = int(quadrature_degree)
        self.msh = msh
        self.comm = msh.comm
        self.parallel = self.comm.size > 1
        self.angle = float(angle)
        self.quadrature_degree = q
        self.jit_params = dict(jit_params or {})
        L1, L2 = yarn_directions(self.angle)

        cell = msh.ufl_cell()
        self.V = fem.FunctionSpace(msh, ufl.VectorElement("Lagrange", cell, 1, dim=3))
        self.u = fem.Function(self.V, name="displacement")
        self.v = ufl.TestFunction(self.V)
        self.dx = ufl.dx(domain=msh, metadata={"quadrature_degree": q,
                                               "quadrature_scheme": "default"})

        # Kinematics (Eq. 2-1, 2-3): a_i = F L_i, lambda_i = |a_i|.
        I32 = ufl.as_matrix([[1.0, 0.0], [0.0, 1.0], [0.0, 0.0]])
        self.L1 = ufl.as_vector([float(L1[0]), float(L1[1])])
        self.L2 = ufl.as_vector([float(L2[0]), float(L2[1])])
        self.F = I32 + ufl.grad(self.u)
        self.a1 = self.F * self.L1
        self.a2 = self.F * self.L2
        self.lambda1 = ufl.sqrt(ufl.dot(self.a1, self.a1))
        self.lambda2 = ufl.sqrt(ufl.dot(self.a2, self.a2))

        Qe = ufl.FiniteElement("Quadrature", cell, degree=q, quad_scheme="default")
        self.Q = fem.FunctionSpace(msh, Qe)
        self.P1 = fem.Function(self.Q, name="P1")
        self.P2 = fem.Function(self.Q, name="P2")

        points, weights = basix.make_quadrature(_BASIX_CELL[cell_name], q)
        self.n_points_per_cell = points.shape[0]
        if self.Q.dofmap.dof_layout.num_dofs != self.n_points_per_cell:
            raise RuntimeError("quadrature space and basix rule disagree on the number of points "
                               f"({self.Q.dofmap.dof_layout.num_dofs} vs {self.n_points_per_cell})")
        self.n_cells = msh.topology.index_map(2).size_local
        self.n_points = self.n_cells * self.n_points_per_cell
        self._cells = np.arange(self.n_cells, dtype=np.int32)
        qdofs = self.Q.dofmap.list.array.reshape(-1, self.n_points_per_cell)[:self.n_cells].ravel()
        # For owned cells DOLFINx 0.5.2 numbers quadrature dofs cell-major (checked);
        # keep an index map for the case it ever does not.
        self._qdofs = None if np.array_equal(qdofs, np.arange(self.n_points)) else qdofs

        self._points = points
        self._strain_expr = None
        nodes = self.V.dofmap.list.array.reshape(-1, self.V.dofmap.dof_layout.num_dofs)[:self.n_cells]
        self._point_strains = PointStrains(nodes, self.V.tabulate_dof_coordinates()[:, :2][nodes],
                                           cell_name, points, L1, L2)

        detJ = fem.Expression(abs(ufl.JacobianDeterminant(msh)), points).eval(self._cells)
        self.quadrature_weights_detJ = (detJ * weights[np.newaxis, :]).ravel()

        self.n_owned_nodes = self.V.dofmap.index_map.size_local
        self.n_owned_dofs = 3 * self.n_owned_nodes

        self.live = fem.Function(fem.FunctionSpace(msh, ("DG", 0)), name="live")
        self.live.x.array[:] = 1.0
        self._live_dofs = self.live.function_space.dofmap.list.array[:self.n_cells]
        self.terms: list[MembraneTerm] = [YarnTerm()]
        self._form = None
        self._form_key = None
        self._per_cell_terms: list[MembraneTerm] = []
        self._energy_forms: dict[int, object] = {}
        self._b = None
        self._h_min = None
        self._velocity = None
        self.dt = fem.Constant(msh, PETSc.ScalarType(0.0))
        self._diss_form = None
        self._diss_key = None
        self._diss_b = None

    # ---------------------------------------------------------------- the term context
    @property
    def velocity(self) -> fem.Function:
        """The lagged velocity v^{n-1/2} (m/s) as a Function on ``V``, for terms whose residual
        depends on the rate (a viscous term); the integrator keeps it current once it exists."""
        if self._velocity is None:
            self._velocity = fem.Function(self.V, name="velocity")
        return self._velocity

    def set_term_context(self, velocity: np.ndarray, dt: float) -> None:
        """Bring the term context up to date before an assembly: the owned velocity dofs
        (m/s) into :attr:`velocity` (only if a term asked for it; collective then) and the step
        ``dt`` (s) into :attr:`dt`."""
        self.dt.value = dt
        if self._velocity is not None:
            self._velocity.x.array[:velocity.size] = velocity
            self._velocity.x.scatter_forward()

    # ---------------------------------------------------------------- the physics in UFL
    def stress_tensor(self):
        """First Piola-Kirchhoff stress P = P1 l1 (x) L1 + P2 l2 (x) L2 (Eq. 2-5), N/m."""
        l1 = self.a1 / self.lambda1
        l2 = self.a2 / self.lambda2
        return self.P1 * ufl.outer(l1, self.L1) + self.P2 * ufl.outer(l2, self.L2)

    def weak_form(self):
        """Residual R(u; v) = sum over :attr:`terms` of int live r_term(u; v) dA: the internal
        virtual work of the referential balance of momentum (Eq. 2-4), the yarn stress of
        Eq. 2-5 first, every term switched off in removed cells by the live-cell mask. The UFL
        terms only: :meth:`internal_force` adds the forces of the ``per_cell`` ones."""
        return sum(self.live * term.integrand(self) * term.measure(self) for term in self.terms
                   if not term.per_cell)

    def add_term(self, term: MembraneTerm) -> MembraneTerm:
        """Add a weak-form term (e.g. ``IsotropicShear(G)``); returns it."""
        if not isinstance(term, MembraneTerm):
            raise TypeError(f"term must be a fabric_fenicsx.fem.terms.MembraneTerm, got {term!r}")
        self.terms.append(term)
        return term

    def terms_wave_modulus(self) -> float:
        """Sum of the terms' own wave moduli (N/m), added to the material's for the stable time
        step (the yarn term's stiffness is the material's and adds nothing here)."""
        return float(sum(term.wave_modulus() for term in self.terms))

    def terms_viscosity(self) -> float:
        """Sum of the terms' viscosities eta (N s/m): their damping's share of the stable time
        step (:func:`fabric_fenicsx.fem.timestep.stable_dt`)."""
        return float(sum(term.viscosity() for term in self.terms))

    def term_energies(self) -> dict[str, float]:
        """Stored energy (J, all ranks) of every term that books its own, over the live cells."""
        energies = {}
        for term in self.terms:
            term.prepare(self)
            if term.per_cell:
                local = term.cell_energy(self)
                energies[term.name] = energies.get(term.name, 0.0) + self.comm.allreduce(local, op=MPI.SUM)
                continue
            if id(term) not in self._energy_forms:
                density = term.energy_density(self)
                self._energy_forms[id(term)] = (None if density is None else
                                                fem.form(self.live * density * term.measure(self)))
            form = self._energy_forms[id(term)]
            if form is not None:
                local = fem.assemble_scalar(form)
                energies[term.name] = energies.get(term.name, 0.0) + self.comm.allreduce(local, op=MPI.SUM)
        return energies

    def remove_cells(self, cells: np.ndarray, share: bool = True) -> None:
        """Switch the owned cells ``cells`` off for every term (live-cell mask 0). With
        ``share`` the mask is sent to the ranks that hold these cells as ghosts at once, which
        is collective: every rank must call it. A caller on which only some ranks remove cells
        passes ``share=False`` and calls :meth:`share_live_cells` on every rank afterwards."""
        self.live.x.array[self._live_dofs[np.asarray(cells, dtype=np.int64)]] = 0.0
        if share:
            self.share_live_cells()

    def share_live_cells(self) -> None:
        """The owners' live-cell mask onto the ghost cells (collective)."""
        self.live.x.scatter_forward()

    # ---------------------------------------------------------------- point data (numpy)
    def yarn_strains(self) -> tuple[np.ndarray, np.ndarray]:
        """Yarn Lagrangian strains E1, E2 = (lambda_i^2 - 1) / 2 (Eq. 2-3) at the owned
        quadrature points (cell-major), from the current displacement (ghosts must be current),
        by the compiled point loop of :class:`~fabric_fenicsx.fem.point_strains.PointStrains`."""
        return self._point_strains(self.u.x.array)

    def yarn_strains_expression(self) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`yarn_strains` evaluated by DOLFINx from the UFL expression of E_i (compiled
        on first use): the reference the compiled point loop is tested against."""
        if self._strain_expr is None:
            E = ufl.as_vector([0.5 * (ufl.dot(self.a1, self.a1) - 1.0),
                               0.5 * (ufl.dot(self.a2, self.a2) - 1.0)])
            self._strain_expr = fem.Expression(E, self._points, jit_params=dict(self.jit_params))
        vals = self._strain_expr.eval(self._cells, np.zeros((self.n_cells, 2 * self.n_points_per_cell)))
        vals = vals.reshape(self.n_cells, self.n_points_per_cell, 2)
        return vals[:, :, 0].ravel(), vals[:, :, 1].ravel()

    def set_stress(self, P1: np.ndarray, P2: np.ndarray) -> None:
        """Write the yarn stresses P1, P2 (N/m, Eq. 2-5) at the owned quadrature points."""
        for name, P, f in (("P1", P1, self.P1), ("P2", P2, self.P2)):
            P = np.asarray(P)
            if P.shape != (self.n_points,):
                raise ValueError(f"{name} must have shape ({self.n_points},) (owned quadrature "
                                 f"points), got {P.shape}")
            if self._qdofs is None:
                f.x.array[:self.n_points] = P
            else:
                f.x.array[self._qdofs] = P
            if self.parallel:
                f.x.scatter_forward()

    def integrate(self, density: np.ndarray) -> float:
        """Global integral over the reference area of a point field (e.g. an energy density
        in J/m^2), summed over all ranks."""
        density = np.asarray(density)
        if density.shape != (self.n_points,):
            raise ValueError(f"density must have shape ({self.n_points},), got {density.shape}")
        return self.comm.allreduce(float(self.quadrature_weights_detJ @ density), op=MPI.SUM)

    def cell_average(self, q_values: np.ndarray, name: str = "cell_average") -> fem.Function:
        """DG0 Function holding the area-weighted cell average of a point field (for XDMF
        output, which cannot write quadrature functions)."""
        q_values = np.asarray(q_values, dtype=float)
        if q_values.shape != (self.n_points,):
            raise ValueError(f"q_values must have shape ({self.n_points},), got {q_values.shape}")
        W = fem.FunctionSpace(self.msh, ("DG", 0))
        f = fem.Function(W, name=name)
        w = self.quadrature_weights_detJ.reshape(self.n_cells, -1)
        avg = (w * q_values.reshape(self.n_cells, -1)).sum(axis=1) / w.sum(axis=1)
        f.x.array[W.dofmap.list.array[:self.n_cells]] = avg
        f.x.scatter_forward()
        return f

    # ---------------------------------------------------------------- dof data (numpy)
    def internal_force(self, out: np.ndarray | None = None) -> np.ndarray:
        """Owned part of f_int = assemble(weak_form()) plus the ``per_cell`` terms' forces (N)
        for the current u, P1, P2; ghost contributions are summed onto their owners
        (ADD/REVERSE). Written into ``out`` (owned dofs) if given, else into a new array."""
        for term in self.terms:
            term.prepare(self)
        key = tuple(map(id, self.terms))
        if self._form is None or key != self._form_key:
            self._form = [fem.form(part, jit_params=dict(self.jit_params)) for part in self._weak_form_parts()]
            self._packers = [CoefficientPacker(form) for form in self._form]
            self._form_key = key
            self._per_cell_terms = [term for term in self.terms if term.per_cell]
            self._b = la.create_petsc_vector(self.V.dofmap.index_map, self.V.dofmap.index_map_bs)
        self._assemble(self._b, self._form, self._packers, self._per_cell_terms)
        return _owned(self._b, out)

    def dissipative_force(self, out: np.ndarray | None = None) -> np.ndarray | None:
        """Owned part of the forces (N) of the terms that declare their work dissipated
        (:attr:`~fabric_fenicsx.fem.terms.MembraneTerm.dissipative`), at the state of the last
        :meth:`internal_force`; None when no term does. Their work is part of the internal work
        and is booked apart as dissipation (``EnergyRecord.dissipated``). Written into ``out``
        (owned dofs) if given, else into a new array."""
        terms = [t for t in self.terms if t.dissipative]
        if not terms:
            return None
        if any(t.per_cell for t in terms):
            raise NotImplementedError("a per_cell term cannot declare its work dissipated: give it "
                                      "a UFL integrand")
        key = tuple(id(t) for t in terms)
        if self._diss_form is None or key != self._diss_key:
            parts: dict = {}
            for term in terms:
                dx = term.measure(self)
                rule = tuple(sorted(dx.metadata().items()))
                parts[rule] = parts.get(rule, 0) + self.live * term.integrand(self) * dx
            self._diss_form = [fem.form(part, jit_params=dict(self.jit_params)) for part in parts.values()]
            self._diss_packers = [CoefficientPacker(form) for form in self._diss_form]
            self._diss_key = key
            self._diss_b = la.create_petsc_vector(self.V.dofmap.index_map, self.V.dofmap.index_map_bs)
        self._assemble(self._diss_b, self._diss_form, self._diss_packers, ())
        return _owned(self._diss_b, out)

    def _assemble(self, b: PETSc.Vec, forms: list, packers: list, per_cell_terms) -> None:
        """b = the forms assembled by DOLFINx's ``assemble_vector`` (coefficients packed by
        their :class:`~fabric_fenicsx.fem.packing.CoefficientPacker`, constants by DOLFINx)
        plus the forces of ``per_cell_terms``, ghost contributions summed onto their owners
        (ADD/REVERSE). One local form of ``b`` for all of them."""
        with b.localForm() as b_local:
            local = b_local.array_w
            local.fill(0.0)
            for form, packer in zip(forms, packers):
                fem.assemble_vector(local, form, coeffs=packer.pack())     # adds into b
            for term in per_cell_terms:
                term.add_cell_forces(self, local.reshape(-1, 3))
        if self.parallel:
            b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)

    def _weak_form_parts(self) -> list:
        """:meth:`weak_form` split into one form per quadrature rule: DOLFINx 0.5.2 assembles
        only one of two cell integrals with different quadrature degrees in one form (measured:
        a degree-1 yarn term plus a degree-2 hourglass term gave the force of neither)."""
        parts: dict = {}
        for term in self.terms:
            if term.per_cell:
                continue
            dx = term.measure(self)
            rule = tuple(sorted(dx.metadata().items()))
            parts[rule] = parts.get(rule, 0) + self.live * term.integrand(self) * dx
        return list(parts.values())

    def lumped_mass(self, areal_density: float) -> np.ndarray:
        """Row-sum lumped mass (kg) of the owned dofs: int rho_A N_a dA for each node a and each
        of the 3 components, with rho_A the areal density (kg/m^2) of the reference fabric."""
        if not np.isfinite(areal_density) or areal_density <= 0:
            raise ValueError(f"areal_density must be a finite positive number in kg/m^2, "
                             f"got {areal_density!r}")
        form = fem.form(float(areal_density) * (self.v[0] + self.v[1] + self.v[2]) * self.dx)
        b = fem_petsc.assemble_vector(form)
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        mass = b.array_r.copy()
        b.destroy()
        return mass

    def interpolate_owned(self, fn: typing.Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
        """Owned dof values of the nodal interpolant of fn(x) -> array (3, n_points), x of shape
        (3, n_points) in the reference configuration (handy for u, v or f_ext fields)."""
        f = fem.Function(self.V)
        f.interpolate(fn)
        return f.x.array[:self.n_owned_dofs].copy()

    def restart(self) -> None:
        """Back to the reference state for another run on this mesh: zero displacement and every
        cell live again (the cells an earlier run removed are back)."""
        self.set_displacement(np.zeros(self.n_owned_dofs))
        self.live.x.array[:] = 1.0

    def set_displacement(self, owned_values: np.ndarray) -> None:
        """Set the owned displacement dofs (m) and update the ghosts."""
        owned_values = np.asarray(owned_values)
        if owned_values.shape != (self.n_owned_dofs,):
            raise ValueError(f"owned_values must have shape ({self.n_owned_dofs},), "
                             f"got {owned_values.shape}")
        self.u.x.array[:self.n_owned_dofs] = owned_values
        self.u.x.scatter_forward()

    def boundary_dofs(self, marker: typing.Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
        """Local unrolled dof indices (all 3 components, owned and ghost) of the nodes where
        marker(x) is True, x of shape (3, n) in the reference configuration."""
        blocks = fem.locate_dofs_geometrical(self.V, marker)
        return (3 * blocks[:, np.newaxis] + np.arange(3)).ravel().astype(np.int32)

    def global_dot(self, a: np.ndarray, b: np.ndarray) -> float:
        """sum_owned a . b over all ranks (each dof counted once)."""
        return self.comm.allreduce(float(np.dot(a, b)), op=MPI.SUM)

    def min_edge_length(self) -> float:
        """Smallest element edge (m) of the reference mesh, minimum over all ranks."""
        if self._h_min is None:
            x = self.msh.geometry.x[:, :2]
            nv = 4 if self.msh.topology.cell_type.name == "quadrilateral" else 3
            geo = self.msh.geometry.dofmap.array.reshape(-1, nv)[:self.n_cells]
            edges = np.array(_CELL_EDGES[self.msh.topology.cell_type.name])
            lengths = np.linalg.norm(x[geo[:, edges[:, 0]]] - x[geo[:, edges[:, 1]]], axis=-1)
            local = lengths.min() if lengths.size else np.inf
            self._h_min = self.comm.allreduce(float(local), op=MPI.MIN)
        return self._h_min


def _owned(b: PETSc.Vec, out: np.ndarray | None) -> np.ndarray:
    """The owned entries of the assembled vector ``b``, copied into ``out`` if given (no new
    array), else into a new array."""
    if out is None:
        return b.array_r.copy()
    np.copyto(out, b.array_r)
    return out
