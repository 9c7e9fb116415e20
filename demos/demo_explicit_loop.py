"""The explicit loop of an impact, written out from the library's parts.

For the researcher who wants to change the time loop itself. `fabric-fenicsx impact` runs the
same loop with more bookkeeping (fabric_fenicsx/impact/simulation.py: damage, cell removal,
time-step re-checks, output); here it is in one screen:

    mesh (fem.mesh)  ->  membrane with its weak-form terms (fem.membrane, fem.terms)
    material at the quadrature points: the unit-cell surrogate (surrogate, fem.yarn_stress)
    central difference with a lumped mass (fem.explicit)
    rigid projectile and penalty contact with friction (fem.projectile)

Each step: contact forces at t_n from positions x^n and velocities v^(n-1/2); the membrane's
step (yarn strains -> material -> internal force -> acceleration -> v^(n+1/2), u^(n+1)); the
projectile's step with the contact force summed over all ranks; the energy balance
KE_fabric + KE_projectile + W_internal - W_contact = KE_0 (trapezoidal works).

A light projectile hits a small clamped square of Zylon at 20 m/s, damage off, with a small
isotropic shear term. Prints the projectile's velocity and the energy-balance error as it goes,
and writes explicit_loop.csv. Runs under MPI too: mpirun -n 2 python3 demos/demo_explicit_loop.py

Run:  python3 demos/demo_explicit_loop.py [output_dir]      (default output_dir: out/explicit_loop)
"""
import csv
import sys
from pathlib import Path

import numpy as np
from mpi4py import MPI

from fabric_fenicsx.fem.explicit import CentralDifference
from fabric_fenicsx.fem.membrane import Membrane
from fabric_fenicsx.fem.mesh import BOTTOM, LEFT, RIGHT, TOP, edge_dofs, min_cell_size, uniform_square
from fabric_fenicsx.fem.projectile import PenaltyContact, Projectile, ProjectileState, advance
from fabric_fenicsx.fem.terms import IsotropicShear
from fabric_fenicsx.fem.yarn_stress import WAVE_MODULUS_MARGIN, YarnStress, straight_yarn_modulus
from fabric_fenicsx.fem.timestep import stable_dt
from fabric_fenicsx.material import zylon_as
from fabric_fenicsx.surrogate import Surrogate

comm = MPI.COMM_WORLD
out_dir = Path(sys.argv[1]) if len(sys.argv) > 1 else Path("out/explicit_loop")
SIDE, N, T_END, SAFETY = 0.08, 16, 3e-4, 0.8          # m, cells per side, s, Courant safety

# -- the fabric: mesh, membrane, terms, material at its quadrature points
msh, _, facet_tags = uniform_square(N, SIDE, comm)
membrane = Membrane(msh, angle=0.0)                    # warp along x
membrane.add_term(IsotropicShear(5.0e4))               # N/m, about 1 % of the yarns' modulus
fabric = zylon_as()
surrogate = Surrogate(fabric, workers=1 if comm.size > 1 else None)
material = YarnStress(surrogate, membrane.quadrature_weights_detJ, damage=False)

# -- integrator with the four edges clamped
clamped = edge_dofs(membrane.V, facet_tags, [LEFT, RIGHT, BOTTOM, TOP])
cd = CentralDifference(membrane, material, fabric.areal_density, clamped)
X = membrane.V.tabulate_dof_coordinates()[:membrane.n_owned_nodes].copy()
X[:, 2] = 0.0
node_mass = cd.mass[0::3]

# -- projectile and contact
projectile = Projectile(diameter=0.02, length=0.0093, fillet=0.0, mass=0.005, velocity=20.0,
                        friction=0.5, axis_xy=(0.0, 0.0), z0=0.2e-3)
contact = PenaltyContact(projectile, damping_ratio=1.0, penalty_fraction=0.5)
state = ProjectileState.initial(projectile)
KE0 = state.kinetic_energy


def contact_forces(dt):
    """Nodal contact forces (owned dofs) and the projectile's z force on this rank."""
    x = X + cd.u.reshape(-1, 3)
    near = np.flatnonzero(projectile.candidates(x, state.z))
    f_ext = np.zeros(membrane.n_owned_dofs)
    if near.size == 0:
        return f_ext, 0.0
    f_nodes, f_p, _ = contact.forces(x[near], cd.v.reshape(-1, 3)[near], node_mass[near], dt, state)
    f_ext.reshape(-1, 3)[near] = f_nodes
    return f_ext, f_p[2]


def write_row(writer, row):
    if comm.rank == 0:
        writer.writerow([f"{v:.8g}" for v in row])


# One fixed step for the whole run, from the stiffest state a yarn can reach (straight, intact:
# the crimped reference state is much softer) plus the shear term's modulus; the impact command
# instead re-checks the material's wave modulus every few steps.
modulus = WAVE_MODULUS_MARGIN * straight_yarn_modulus(fabric) + membrane.terms_wave_modulus()
dt = stable_dt(modulus, fabric.areal_density, min_cell_size(msh, "area_over_diagonal"), 0.0, SAFETY)
dt_prev, fz_prev, z_prev, W_projectile, worst = 0.0, 0.0, state.z, 0.0, 0.0
if comm.rank == 0:
    out_dir.mkdir(parents=True, exist_ok=True)
    csv_file = open(out_dir / "explicit_loop.csv", "w", newline="")
    writer = csv.writer(csv_file)
    writer.writerow(["time", "projectile_velocity", "contact_force", "energy_error"])
else:
    writer = None
step = 0
while cd.time < T_END:
    f_ext, fz_local = contact_forces(dt)                 # contact at t_n
    energy = cd.step(dt, f_ext)                          # membrane t_n -> t_n+1, energies at t_n
    fz = comm.allreduce(fz_local, op=MPI.SUM)            # force on the projectile, all ranks
    vz_full = state.vz + 0.5 * dt_prev * fz / state.mass
    W_projectile += 0.5 * (fz_prev + fz) * (state.z - z_prev)
    KE_p = 0.5 * state.mass * vz_full ** 2
    W_contact = energy.external + W_projectile
    error = abs(energy.kinetic + KE_p + energy.internal - W_contact - energy.support - KE0) / KE0
    worst = max(worst, error)
    z_prev, fz_prev = state.z, fz
    state = advance(state, fz, dt)                       # projectile t_n -> t_n+1
    if step % 50 == 0:
        write_row(writer, [energy.time, -vz_full, fz, error])
    if step % 200 == 0 and comm.rank == 0:
        print(f"t = {energy.time * 1e6:7.2f} us  v = {-vz_full:8.4f} m/s  F = {fz:8.2f} N  "
              f"energy error {error:.2e}", flush=True)
    dt_prev = dt
    step += 1

if comm.rank == 0:
    csv_file.close()
    print(f"{step} steps of {dt:.3e} s: projectile at {-state.vz:.4f} m/s (from 20 m/s), "
          f"largest energy-balance error {worst:.2e}; wrote {out_dir / 'explicit_loop.csv'}")
