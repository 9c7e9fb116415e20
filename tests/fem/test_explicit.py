"""Tests of the explicit central-difference membrane dynamics (thesis Eq. 2-4 with Eq. 2-5).

Run as a script (`mpirun -n 2 python tests/fem/test_explicit.py`) it prints the energy history of a
short free vibration as JSON; `test_mpi_matches_serial` uses that.
"""
import json
import os
import pathlib
import shutil
import subprocess
import sys
from types import SimpleNamespace

import numpy as np
import pytest
from dolfinx import mesh
from mpi4py import MPI

from fabric_fenicsx.fem.explicit import CentralDifference, LinearYarnMaterial
from fabric_fenicsx.fem.membrane import Membrane

A = 0.05        # half side of the square fabric (m)
K = 1.0e4       # yarn stiffness dP/dlambda (N/m)
RHO_A = 0.158   # areal density (kg/m^2)
PRESTRETCH = 1.02


def prestretched_drum(n, angle=0.0, damping=0.0, bump="mode"):
    """Square membrane, equibiaxially prestretched by PRESTRETCH, all edges clamped, started with
    a transverse velocity: the fundamental mode shape or a Gaussian bump (m/s)."""
    msh = mesh.create_rectangle(MPI.COMM_WORLD, [[-A, -A], [A, A]], [n, n],
                                mesh.CellType.quadrilateral)
    m = Membrane(msh, angle=angle)
    clamped = m.boundary_dofs(lambda x: np.isclose(np.abs(x[0]), A) | np.isclose(np.abs(x[1]), A))
    s = PRESTRETCH - 1.0
    m.set_displacement(m.interpolate_owned(lambda x: np.vstack([s * x[0], s * x[1], 0 * x[0]])))
    cd = CentralDifference(m, LinearYarnMaterial(K, K), RHO_A, clamped, damping=damping)
    if bump == "mode":
        shape = lambda x: np.cos(np.pi * x[0] / (2 * A)) * np.cos(np.pi * x[1] / (2 * A))
    else:
        shape = lambda x: np.exp(-((x[0] - 0.2 * A) ** 2 + (x[1] + 0.1 * A) ** 2) / (0.3 * A) ** 2)
    cd.v[:] = m.interpolate_owned(lambda x: np.vstack([0 * x[0], 0 * x[0], shape(x)]))
    cd.v[cd.clamped] = 0.0
    return cd


def fundamental_frequency():
    """omega = sqrt(T / rho_A) pi sqrt(2) / side for the string-like membrane; with reference
    quantities the tension is T = P / lambda (P per reference length, rho_A per reference area)."""
    T = K * (PRESTRETCH - 1.0) / PRESTRETCH
    return np.sqrt(T / RHO_A) * np.pi * np.sqrt(2.0) / (2 * A)


def modal_amplitude(cd):
    """Mass-weighted projection of the transverse displacement on the fundamental mode."""
    m = cd.membrane
    mode = lambda x: np.cos(np.pi * x[0] / (2 * A)) * np.cos(np.pi * x[1] / (2 * A))
    phi = m.interpolate_owned(lambda x: np.vstack([0 * x[0], 0 * x[0], mode(x)]))
    return lambda: m.global_dot(cd.mass * phi, cd.u)


def measured_frequency(cd, n_periods=2.2):
    """Angular frequency from the zero crossings of the modal amplitude (linear interpolation)."""
    q = modal_amplitude(cd)
    dt = cd.stable_dt()
    n_steps = int(n_periods * 2 * np.pi / fundamental_frequency() / dt)
    t, y, totals = [0.0], [q()], []
    for _ in range(n_steps):
        totals.append(cd.step(dt).total)
        t.append(cd.time)
        y.append(q())
    t, y = np.array(t), np.array(y)
    i = np.nonzero((y[1:-1] > 0) != (y[2:] > 0))[0] + 1   # crossings after the start
    crossings = t[i] - y[i] * (t[i + 1] - t[i]) / (y[i + 1] - y[i])
    half_period = np.diff(np.concatenate([[0.0], crossings])).mean()
    return np.pi / half_period, t, y, np.array(totals)


def energy_history(n=8, n_steps=40, angle=np.deg2rad(30), bump="gauss"):
    cd = prestretched_drum(n, angle=angle, bump=bump)
    dt = cd.stable_dt()
    records = [cd.step(dt) for _ in range(n_steps)]
    return [[r.time, r.kinetic, r.internal, r.external, r.support, r.damping] for r in records]


def test_linear_yarn_material_is_tension_only():
    mat = LinearYarnMaterial(2.0, 3.0)
    lam = np.array([0.9, 1.0, 1.1])
    E = 0.5 * (lam**2 - 1)
    P1, P2 = mat.update(E, E)
    assert np.allclose(P1, [0.0, 0.0, 0.2]) and np.allclose(P2, [0.0, 0.0, 0.3])
    assert np.all(mat.state.alpha1 == 1.0) and not mat.state.removed.any()
    assert mat.max_wave_modulus() == 3.0
    mat.remove([2])                        # a removed point carries nothing from then on
    P1, P2 = mat.update(E, E)
    assert P1[2] == 0.0 and P2[2] == 0.0 and P1[:2].sum() == 0.0
    with pytest.raises(ValueError, match="k2"):
        LinearYarnMaterial(1.0, -1.0)


def test_stable_dt_formula():
    cd = prestretched_drum(8)
    h = 2 * A / 8
    assert cd.stable_dt(0.9) == pytest.approx(0.9 * h / np.sqrt(K / RHO_A), rel=1e-12)
    damped = prestretched_drum(8, damping=1e-5)
    assert damped.stable_dt() < cd.stable_dt()
    with pytest.raises(ValueError, match="dt"):
        cd.step(-1.0)


@pytest.mark.parametrize("angle", [0.0, np.deg2rad(30)])
def test_free_vibration_conserves_energy_and_blows_up_beyond_stable_dt(angle):
    cd = prestretched_drum(8, angle=angle, bump="gauss")
    u_clamped = cd.u[cd.clamped].copy()
    dt = cd.stable_dt()
    records = [cd.step(dt) for _ in range(300)]
    e0 = records[0].total
    assert e0 == pytest.approx(records[0].kinetic)
    assert max(abs(r.total - e0) for r in records) < 0.01 * e0
    # Energy sloshes between kinetic and stored, and nothing else works on the fabric.
    assert min(r.kinetic for r in records) < 0.5 * e0
    assert max(r.internal for r in records) > 0.5 * e0
    assert all(r.external == 0.0 and r.support == 0.0 for r in records)
    assert np.array_equal(cd.u[cd.clamped], u_clamped)

    unstable = prestretched_drum(8, angle=angle, bump="gauss")
    dt = 2.5 * unstable.stable_dt()
    e0 = unstable.step(dt).total
    for _ in range(300):
        e = unstable.step(dt)
        if e.kinetic + e.internal > 1e3 * e0:
            break
    assert e.kinetic + e.internal > 1e3 * e0, "no blow-up at 2.5 x stable_dt"


def test_fundamental_frequency_converges_to_membrane_value():
    exact = fundamental_frequency()
    errors = []
    for n in (8, 16):
        omega, _, _, _ = measured_frequency(prestretched_drum(n))
        errors.append(abs(omega - exact) / exact)
    assert errors[0] < 0.03
    assert errors[1] < 0.5 * errors[0]


def test_rayleigh_damping_decay_rate_and_energy_balance():
    """Modal damping ratio of stiffness-proportional damping is zeta = beta omega / 2: the mode
    amplitude decays like exp(-zeta omega t); the dissipated energy closes the balance."""
    omega = fundamental_frequency()
    zeta = 0.03
    cd = prestretched_drum(12, damping=2 * zeta / omega)
    _, t, y, totals = measured_frequency(cd, n_periods=3.2)
    peaks = np.nonzero((y[1:-1] > y[:-2]) & (y[1:-1] >= y[2:]) & (y[1:-1] > 0))[0] + 1
    rate = -np.polyfit(t[peaks], np.log(y[peaks]), 1)[0]
    assert rate == pytest.approx(zeta * omega, rel=0.1)
    assert cd.energy.damping > 0.3 * totals[0]
    assert np.abs(totals - totals[0]).max() < 0.01 * totals[0]


def test_energy_balance_with_load_and_moving_support():
    """A transverse pressure and an edge pulled at constant velocity feed energy in; the work
    they do is booked as external and support work and closes the balance."""
    cd = prestretched_drum(8, bump="gauss")
    m = cd.membrane
    cd.v[:] = 0.0
    right = np.zeros(m.u.x.array.size, dtype=bool)
    right[m.boundary_dofs(lambda x: np.isclose(x[0], A))] = True
    pulled = np.nonzero(right[:m.n_owned_dofs])[0]
    pulled = pulled[pulled % 3 == 0]
    cd.v[pulled] = 0.05                                   # m/s along x
    pressure = 20.0                                       # N/m^2
    f_ext = np.zeros(m.n_owned_dofs)
    f_ext[2::3] = pressure * cd.mass[2::3] / RHO_A        # lumped nodal areas times pressure
    dt = cd.stable_dt()
    records = [cd.step(dt, f_ext) for _ in range(300)]
    fed_in = max(abs(r.external) + abs(r.support) for r in records)
    assert records[-1].external > 0 and records[-1].support > 0
    assert max(abs(r.total - records[0].total) for r in records) < 0.01 * fed_in
    assert np.allclose(cd.v[pulled], 0.05)


class LinearTable:
    """Stand-in for the surrogate in `YarnStress`: straight linear yarns, P_i = K (lambda_i - 1)
    (signed, as the table gives them), so the highest frequency of a mesh is known."""

    E_table = (-0.06, 0.094)

    def __init__(self, k):
        self.k = k
        self.stats = SimpleNamespace(record=lambda *args: None)

    def lookup(self, E1, E2, a1, a2, quantities, derivative=False):
        assert tuple(quantities) == ("P1", "P2") and not derivative
        return self.k * (np.sqrt(1.0 + 2.0 * np.stack([E1, E2], axis=1)) - 1.0)


def damped_run(n, dt, beta, viscous_in_material, n_steps):
    """Largest kinetic energy (over the initial one) of a prestretched square, yarns along the
    edges, started from a small random velocity (every mode), run at the constant step dt with
    stiffness-proportional damping beta: in the integrator (`CentralDifference`) or, as an
    impact run does it, as the viscous yarn stress of `YarnStress`."""
    from fabric_fenicsx.fem.yarn_stress import YarnStress
    msh = mesh.create_rectangle(MPI.COMM_SELF, [[-A, -A], [A, A]], [n, n], mesh.CellType.quadrilateral)
    m = Membrane(msh, angle=0.0)
    clamped = m.boundary_dofs(lambda x: np.isclose(np.abs(x[0]), A) | np.isclose(np.abs(x[1]), A))
    s = PRESTRETCH - 1.0
    m.set_displacement(m.interpolate_owned(lambda x: np.vstack([s * x[0], s * x[1], 0 * x[0]])))
    if viscous_in_material:
        material = YarnStress(LinearTable(K), m.quadrature_weights_detJ, damage=False, beta=beta,
                              straight_modulus=K)
        cd = CentralDifference(m, material, RHO_A, clamped)
    else:
        material = None
        cd = CentralDifference(m, LinearYarnMaterial(K, K), RHO_A, clamped, damping=beta)
    cd.v[:] = 1e-6 * np.random.default_rng(4).uniform(-1, 1, cd.v.size)
    cd.v[cd.clamped] = 0.0
    ke0 = None
    peak = 0.0
    for _ in range(n_steps):
        e = cd.step(dt)
        ke0 = e.kinetic if ke0 is None else ke0
        peak = max(peak, e.kinetic / ke0)
        if peak > 1e6:
            break
    return peak


@pytest.mark.skipif(MPI.COMM_WORLD.size > 1, reason="serial")
@pytest.mark.parametrize("viscous_in_material", [False, True], ids=["integrator", "yarn_stress"])
def test_damped_stable_time_step_is_the_stability_limit(viscous_in_material):
    """`fabric_fenicsx.impact.timestep.stable_dt` (the damped Courant limit of an impact run):
    with yarns along the edges of a square mesh the highest mesh frequency is omega = 2 c / h
    (the stretch mode alternating along a row of nodes), and with damping ratio xi = 0.5 there
    a run at the damped limit 2 / omega (sqrt(1 + xi^2) - xi) = 0.62 x 2 / omega is stable, one
    4 % above it blows up, and so does one at 0.9 x the undamped limit: the damping lowers the
    limit as the formula says, neither more nor less (for the viscous stress of the impact runs
    as for the integrator's damping force)."""
    from fabric_fenicsx.impact.timestep import stable_dt
    n = 16
    h = 2 * A / n
    omega = 2 * np.sqrt(K / RHO_A) / h
    beta = 2 * 0.5 / omega
    dt = stable_dt(K, RHO_A, h, beta, 1.0)
    assert dt == pytest.approx(2 / omega * (np.sqrt(1.25) - 0.5), rel=1e-12)
    assert damped_run(n, dt, beta, viscous_in_material, 600) < 2.0
    assert damped_run(n, 1.04 * dt, beta, viscous_in_material, 600) > 1e6
    assert damped_run(n, 0.9 * 2 / omega, beta, viscous_in_material, 600) > 1e6


@pytest.mark.skipif(shutil.which("mpirun") is None, reason="mpirun not available")
def test_mpi_matches_serial(tmp_path):
    """The 2-rank history is written to a file (stdout is no channel for results: other
    libraries write to it, e.g. colorama's reset code at exit under mpirun's terminal)."""
    if MPI.COMM_WORLD.size > 1:
        pytest.skip("runs its own 2-rank job")
    serial = np.array(energy_history())
    root = pathlib.Path(__file__).resolve().parents[2]
    env = dict(os.environ, PYTHONPATH=f"{root}{os.pathsep}{os.environ.get('PYTHONPATH', '')}",
               OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    result = tmp_path / "history.json"
    out = subprocess.run(["mpirun", "--oversubscribe", "-n", "2", sys.executable, __file__, str(result)],
                         env=env, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr[-2000:]
    parallel = np.array(json.loads(result.read_text()))
    assert parallel.shape == serial.shape
    scale = np.abs(serial).max(axis=0)
    assert np.all(np.abs(parallel - serial) <= 1e-10 * np.maximum(scale, 1e-300))


if __name__ == "__main__":
    history = energy_history()
    if MPI.COMM_WORLD.rank == 0:
        pathlib.Path(sys.argv[1]).write_text(json.dumps(history))
