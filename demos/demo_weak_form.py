"""Extending the membrane's weak form: a new term in one small class.

The thesis's membrane carries stress only along the yarns (Eq. 2-5, shear neglected, Sec. 2.1),
so a trellis shear of the fabric costs nothing. A weak-form term (fabric_fenicsx.fem.terms) gives
its integrand (UFL, linear in the test function), its wave modulus (it enters the stable time
step) and its stored energy (it enters summary.json); the membrane multiplies every term by its
live-cell mask, so a removed cell carries no force from any term.

This demo writes such a term, a trellis shear resistance psi = G/2 gamma^2 with gamma the change
of the angle between warp and fill (sin gamma = l1 . l2), and runs a small impact (damage off)
three times: the thesis's membrane, the shipped `IsotropicShear` switched on by the scene key
`membrane.shear_modulus`, and the term below. It prints the projectile's velocity at the end,
the largest central deflection, the time step, the term's stored energy and the energy-balance
error of each run (the internal work includes the term's, so the balance still closes), and
writes weak_form_demo.csv. The scene's default element (one point per cell, ``mesh.element =
"reduced"``) brings its own term, the hourglass control, whose energy is a column of its own.

Run:  python3 demos/demo_weak_form.py [output_dir]      (default output_dir: out/weak_form_demo)
"""
import csv
import sys
from pathlib import Path

import ufl

from fabric_fenicsx.fem.terms import MembraneTerm
from fabric_fenicsx.impact.scene import build_scene
from fabric_fenicsx.impact.simulation import ImpactSimulation

SCENE = {  # a small square patch hit at 20 m/s; damage off keeps it elastic
    "material": {"angle": 0.0, "damage": False},
    "mesh": {"kind": "uniform", "side": 0.08, "n": 16},
    "projectile": {"diameter": 0.02, "velocity": 20.0, "mass": 0.005},
    "boundary": {"clamped": ["left", "right", "bottom", "top"]},
    "run": {"t_end": 3e-4},
    "output": {"xdmf_interval": 0.0, "png": False, "progress_interval": 0.0},
}
G = 5.0e4  # N/m: about 1 % of the straight yarn's modulus, so the stable time step hardly moves


class TrellisShear(MembraneTerm):
    """psi = G/2 gamma^2, gamma the shear angle between the yarns (sin gamma = l1 . l2)."""

    name = "trellis_shear"

    def __init__(self, G):
        self.G = float(G)

    def energy_density(self, m):
        gamma = ufl.asin(ufl.dot(m.a1, m.a2) / (m.lambda1 * m.lambda2))
        return 0.5 * self.G * gamma ** 2

    def integrand(self, m):
        return ufl.derivative(self.energy_density(m), m.u, m.v)

    def wave_modulus(self):
        return self.G   # small-strain shear modulus: a shear wave runs at sqrt(G / rho_A)


out_dir = Path(sys.argv[1]) if len(sys.argv) > 1 else Path("out/weak_form_demo")
rows = []
for label, overrides, terms in (("none", [], ()),
                                ("IsotropicShear", [f"membrane.shear_modulus={G}"], ()),
                                ("TrellisShear", [], (TrellisShear(G),))):
    sim = ImpactSimulation(build_scene(SCENE, overrides, "weak_form_demo"), out_dir / label,
                           verbose=False, terms=terms)
    try:
        s = sim.run()
    finally:
        sim.output.close()
    col = list(sim.output.columns).index("central_deflection")
    deflection = max((r[col] for r in sim.output.history_rows), default=float("nan"))
    rows.append({"term": label, "velocity_at_end": s["residual_velocity"],
                 "max_central_deflection_mm": 1e3 * deflection, "dt": s["dt_initial"],
                 "term_energy_J": sum(e for name, e in s["energies"]["membrane_terms"].items()
                                      if name != "hourglass"),
                 "hourglass_energy_J": s["energies"]["membrane_terms"].get("hourglass", 0.0),
                 "energy_error": s["energy_error"], "n_steps": s["n_steps"]})

if sim.comm.rank == 0:
    out_dir.mkdir(parents=True, exist_ok=True)
    with open(out_dir / "weak_form_demo.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    print(f"{'term':>15} {'v at end (m/s)':>15} {'max deflection (mm)':>20} {'dt (s)':>10} "
          f"{'term energy (J)':>16} {'hourglass (J)':>14} {'energy error':>13}")
    for r in rows:
        print(f"{r['term']:>15} {r['velocity_at_end']:15.4f} {r['max_central_deflection_mm']:20.4f} "
              f"{r['dt']:10.3e} {r['term_energy_J']:16.4e} {r['hourglass_energy_J']:14.4e} "
              f"{r['energy_error']:13.2e}")
    print(f"wrote {out_dir / 'weak_form_demo.csv'}")
