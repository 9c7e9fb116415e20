"""Extending the membrane's weak form: an in-plane shear stiffness added in a few lines.

The thesis's membrane carries stress only along the yarns (Eq. 2-5, shear neglected, Sec. 2.1),
so a trellis shear of the fabric costs nothing. `Membrane.weak_form()` is the one place where the
residual is built: the yarn term plus every UFL form in `Membrane.extra_terms`. This demo writes
an isotropic shear energy G dev(E) : dev(E) (E = (F^T F - I) / 2, Eq. 2-2) in UFL here, appends
its variation to the membrane of an impact run, and runs a small impact (damage off) with and
without it. It prints the residual velocity, the central deflection and the energy-balance error
of both runs (the internal work includes the new term, so the balance still closes) and writes
weak_form_demo.csv.

Run:  python3 demos/demo_weak_form.py [output_dir]      (default output_dir: out/weak_form_demo)
"""
import csv
import sys
from pathlib import Path

import ufl

from fabric_fenicsx.impact.simulation import ImpactSimulation
from fabric_fenicsx.impact.scene import build_scene

SCENE = {  # a small square patch hit at 20 m/s; damage off keeps it elastic
    "material": {"angle": 0.0, "damage": False},
    "mesh": {"kind": "uniform", "side": 0.08, "n": 16},
    "projectile": {"diameter": 0.02, "velocity": 20.0, "mass": 0.005},
    "boundary": {"clamped": ["left", "right", "bottom", "top"]},
    "run": {"t_end": 3e-4},
    "output": {"xdmf_interval": 0.0, "png": False, "progress_interval": 0.0},
}
G = 5.0e4  # N/m: about 1 % of the straight yarn's modulus, so the stable time step hardly moves


def shear_term(m, G):
    """The variation of int G dev(E) : dev(E) dA: the whole extension, in UFL."""
    E = 0.5 * (m.F.T * m.F - ufl.Identity(2))
    devE = E - 0.5 * ufl.tr(E) * ufl.Identity(2)
    return ufl.derivative(G * ufl.inner(devE, devE) * m.dx, m.u, m.v)


out_dir = Path(sys.argv[1]) if len(sys.argv) > 1 else Path("out/weak_form_demo")
rows = []
for shear in (0.0, G):
    sim = ImpactSimulation(build_scene(SCENE, [], "weak_form_demo"), out_dir / f"G{shear:g}", verbose=False)
    if shear > 0:
        sim.membrane.extra_terms.append(shear_term(sim.membrane, shear))
    try:
        s = sim.run()
    finally:
        sim.output.close()
    deflection = max(float(r[list(sim.output.columns).index("central_deflection")])
                     for r in sim.output.history_rows) if sim.output.history_rows else float("nan")
    rows.append({"G_N_per_m": shear, "residual_velocity": s["residual_velocity"],
                 "max_central_deflection_mm": 1e3 * deflection, "energy_error": s["energy_error"],
                 "n_steps": s["n_steps"], "dt": s["dt"]})

if rows and sim.comm.rank == 0:
    out_dir.mkdir(parents=True, exist_ok=True)
    with open(out_dir / "weak_form_demo.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    print(f"{'G (N/m)':>10} {'v at 0.3 ms (m/s)':>18} {'max deflection (mm)':>20} {'energy error':>13} {'steps':>6}")
    for r in rows:
        print(f"{r['G_N_per_m']:10.3g} {r['residual_velocity']:18.4f} {r['max_central_deflection_mm']:20.4f} "
              f"{r['energy_error']:13.2e} {r['n_steps']:6d}")
    print(f"wrote {out_dir / 'weak_form_demo.csv'}")
