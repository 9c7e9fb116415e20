"""Tests of the woven-fabric membrane kinematics and internal force (thesis Eq. 2-1 to 2-6)."""
import numpy as np
import pytest
import ufl
from dolfinx import fem, mesh
from mpi4py import MPI

from fabric_fenicsx.fem.explicit import LinearYarnMaterial
from fabric_fenicsx.fem.terms import IsotropicShear
from fabric_fenicsx.fem.membrane import Membrane, yarn_directions

A = 0.05  # half side of the square test fabric (m)


def square(n, distort=0.0, seed=0):
    """Square [-A, A]^2 of n x n quadrilaterals; interior nodes moved randomly by up to
    distort * h in each direction (serial meshes only need it)."""
    msh = mesh.create_rectangle(MPI.COMM_WORLD, [[-A, -A], [A, A]], [n, n],
                                mesh.CellType.quadrilateral)
    if distort:
        x = msh.geometry.x
        interior = (np.abs(x[:, 0]) < A - 1e-12) & (np.abs(x[:, 1]) < A - 1e-12)
        rng = np.random.default_rng(seed)
        x[interior, :2] += distort * (2 * A / n) * rng.uniform(-1, 1, (interior.sum(), 2))
    return msh


def homogeneous(m, F):
    """Owned dofs of u = (F - I_32) X for a constant 3 x 2 deformation gradient F."""
    G = np.asarray(F) - np.eye(3, 2)
    return m.interpolate_owned(lambda x: G @ x[:2])


def stretch_gradient(lam1, lam2, angle, rotation=np.eye(3)):
    """3 x 2 F that stretches the yarn directions of `angle` by lam1, lam2, then rotates rigidly."""
    L1, L2 = yarn_directions(angle)
    F2 = lam1 * np.outer(L1, L1) + lam2 * np.outer(L2, L2)
    return rotation @ np.vstack([F2, np.zeros(2)])


def rigid_rotation(axis, phi):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(phi) * K + (1 - np.cos(phi)) * K @ K


def stress_and_force(m, material):
    E1, E2 = m.yarn_strains()
    P1, P2 = material.update(E1, E2)
    m.set_stress(P1, P2)
    return m.internal_force()


def boundary_mask(m):
    mask = np.zeros(m.u.x.array.size, dtype=bool)
    mask[m.boundary_dofs(lambda x: np.isclose(np.abs(x[0]), A)
                         | np.isclose(np.abs(x[1]), A))] = True
    return mask[:m.n_owned_dofs]


@pytest.mark.parametrize("angle", [0.0, np.pi / 6])
@pytest.mark.parametrize("rotation", [np.eye(3), rigid_rotation([1, 2, 3], 0.7)])
def test_homogeneous_stretch_patch(angle, rotation):
    lam1, lam2 = 1.07, 1.03
    msh = square(8, distort=0.2 if MPI.COMM_WORLD.size == 1 else 0.0)
    m = Membrane(msh, angle=angle)
    F = stretch_gradient(lam1, lam2, angle, rotation)
    m.set_displacement(homogeneous(m, F))

    E1, E2 = m.yarn_strains()
    assert E1.shape == (m.n_points,) == E2.shape
    assert np.max(np.abs(E1 - 0.5 * (lam1**2 - 1))) < 1e-12
    assert np.max(np.abs(E2 - 0.5 * (lam2**2 - 1))) < 1e-12

    k1, k2 = 2.0e4, 1.0e4
    f = stress_and_force(m, LinearYarnMaterial(k1, k2))
    on_boundary = boundary_mask(m)
    f_boundary = MPI.COMM_WORLD.allreduce(np.abs(f[on_boundary]).max(initial=0), op=MPI.MAX)
    f_interior = MPI.COMM_WORLD.allreduce(np.abs(f[~on_boundary]).max(initial=0), op=MPI.MAX)
    assert f_boundary > 1.0
    assert f_interior < 1e-12 * f_boundary

    # Virtual work of the homogeneous stress on any linear field u = H X: f . u_H = area P : H,
    # with P = P1 l1 (x) L1 + P2 l2 (x) L2 (Eq. 2-5) computed by hand.
    L1, L2 = yarn_directions(angle)
    P = (k1 * (lam1 - 1) * np.outer(F @ L1 / lam1, L1)
         + k2 * (lam2 - 1) * np.outer(F @ L2 / lam2, L2))
    H = np.random.default_rng(1).normal(size=(3, 2))
    work = m.global_dot(f, m.interpolate_owned(lambda x: H @ x[:2]))
    assert abs(work - (2 * A) ** 2 * np.sum(P * H)) < 1e-10 * np.abs(P).sum() * (2 * A) ** 2


def test_compressed_yarns_carry_no_force():
    m = Membrane(square(4), angle=0.3)
    m.set_displacement(homogeneous(m, stretch_gradient(0.95, 0.9, 0.3)))
    f = stress_and_force(m, LinearYarnMaterial(1e4, 1e4))
    assert np.all(f == 0.0)


@pytest.mark.parametrize("angle", [0.0, np.deg2rad(30)])
def test_internal_force_is_energy_gradient(angle):
    """f_int . d equals the directional derivative of the stored energy
    Pi(u) = int 0.5 k_i (lambda_i - 1)^2 dA (central finite difference)."""
    material = LinearYarnMaterial(3.0e4, 1.0e4)
    m = Membrane(square(6), angle=angle)
    rng = np.random.default_rng(7)
    u0 = homogeneous(m, stretch_gradient(1.05, 1.04, angle))
    u0 = u0 + 2e-4 * rng.uniform(-1, 1, u0.size)
    d = rng.uniform(-1, 1, u0.size)

    def energy(u):
        m.set_displacement(u)
        return m.integrate(material.energy_density(*m.yarn_strains()))

    m.set_displacement(u0)
    f = stress_and_force(m, material)
    eps = 1e-7
    fd = (energy(u0 + eps * d) - energy(u0 - eps * d)) / (2 * eps)
    exact = m.global_dot(f, d)
    assert abs(fd - exact) < 1e-6 * abs(exact)


def test_lumped_mass_sums_to_three_times_fabric_mass():
    rho_A = 0.158
    m = Membrane(square(8, distort=0.2 if MPI.COMM_WORLD.size == 1 else 0.0))
    M = m.lumped_mass(rho_A)
    assert M.shape == (m.n_owned_dofs,)
    assert np.all(M > 0)
    total = MPI.COMM_WORLD.allreduce(M.sum(), op=MPI.SUM)
    assert total == pytest.approx(3 * rho_A * (2 * A) ** 2, rel=1e-13)
    # The three components of a node carry the same mass.
    assert np.array_equal(M[0::3], M[1::3]) and np.array_equal(M[0::3], M[2::3])


def test_quadrature_layout_weights_and_cell_average():
    """The numpy point arrays, the basix rule and the quadrature space agree point by point."""
    m = Membrane(square(5, distort=0.25 if MPI.COMM_WORLD.size == 1 else 0.0), quadrature_degree=2)
    area = MPI.COMM_WORLD.allreduce(m.quadrature_weights_detJ.sum())
    assert area == pytest.approx((2 * A) ** 2, rel=1e-13)

    # Write the x coordinate of every point into P1; int P1 x^3 dA must equal int x^4 dA under
    # the same rule only if the points coincide.
    import basix
    pts, _ = basix.make_quadrature(basix.CellType.quadrilateral, 2)
    x = ufl.SpatialCoordinate(m.msh)
    xq = fem.Expression(x[0], pts).eval(np.arange(m.n_cells, dtype=np.int32)).ravel()
    m.set_stress(xq, np.zeros_like(xq))
    lhs = fem.assemble_scalar(fem.form(m.P1 * x[0] ** 3 * m.dx))
    rhs = fem.assemble_scalar(fem.form(x[0] ** 4 * m.dx))
    assert MPI.COMM_WORLD.allreduce(lhs) == pytest.approx(MPI.COMM_WORLD.allreduce(rhs), rel=1e-12)
    assert m.integrate(xq ** 4) == pytest.approx(MPI.COMM_WORLD.allreduce(rhs), rel=1e-12)

    avg = m.cell_average(np.full(m.n_points, 2.5))
    assert np.allclose(avg.x.array, 2.5)
    # The dA-weighted average of x over a cell is its centroid: integrating it back gives int x dA.
    avg_x = m.cell_average(xq)
    total = fem.assemble_scalar(fem.form(avg_x * ufl.dx(domain=m.msh)))
    assert abs(MPI.COMM_WORLD.allreduce(total)) < 1e-15


def test_shear_term_changes_response():
    """A pure trellis shear leaves both yarns unstretched, so the thesis membrane offers no
    resistance; an isotropic shear term added with `Membrane.add_term` does, with the force equal
    to the derivative of its energy G dev(E) : dev(E)."""
    phi, G = 0.1, 500.0
    F = np.array([[np.cos(phi), np.sin(phi)], [np.sin(phi), np.cos(phi)], [0.0, 0.0]])
    m = Membrane(square(6), angle=0.0)
    m.set_displacement(homogeneous(m, F))
    material = LinearYarnMaterial(1e4, 1e4)
    E1, E2 = m.yarn_strains()
    assert np.allclose(E1, 0.0, atol=1e-14) and np.allclose(E2, 0.0, atol=1e-14)
    # the yarns see round-off strains only (|E| ~ 1e-16): forces of round-off size
    assert np.abs(stress_and_force(m, material)).max(initial=0) < 1e-9

    shear = m.add_term(IsotropicShear(G))
    f = stress_and_force(m, material)
    assert MPI.COMM_WORLD.allreduce(np.abs(f).max(initial=0), op=MPI.MAX) > 1.0

    def psi(Fh):
        E = 0.5 * (Fh.T @ Fh - np.eye(2))
        dev = E - 0.5 * np.trace(E) * np.eye(2)
        return G * np.sum(dev * dev)

    dpsi = np.zeros((3, 2))
    for i in range(3):
        for j in range(2):
            e = np.zeros((3, 2))
            e[i, j] = 1e-6
            dpsi[i, j] = (psi(F + e) - psi(F - e)) / 2e-6
    H = np.random.default_rng(3).normal(size=(3, 2))
    work = m.global_dot(f, m.interpolate_owned(lambda x: H @ x[:2]))
    assert work == pytest.approx((2 * A) ** 2 * np.sum(dpsi * H), rel=1e-7)

    m.terms.remove(shear)
    assert np.abs(stress_and_force(m, material)).max(initial=0) < 1e-9


def test_min_edge_length():
    assert Membrane(square(8)).min_edge_length() == pytest.approx(2 * A / 8, rel=1e-12)


@pytest.mark.parametrize("kwargs, field", [({"angle": float("nan")}, "angle"),
                                           ({"quadrature_degree": 0}, "quadrature_degree")])
def test_bad_input_raises(kwargs, field):
    with pytest.raises(ValueError, match=field):
        Membrane(square(2), **kwargs)


def test_bad_stress_and_density_raise():
    m = Membrane(square(2))
    with pytest.raises(ValueError, match="P1"):
        m.set_stress(np.zeros(m.n_points + 1), np.zeros(m.n_points))
    with pytest.raises(ValueError, match="areal_density"):
        m.lumped_mass(-1.0)
