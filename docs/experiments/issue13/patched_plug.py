"""Cables (patched_cable) + a bonded plug instead of the contact: the nodes whose reference
radius is below the projectile's are tied to the face's displacement in z by an undamped
bilateral spring (no thresholds, no friction); the rest never touch. PLUG_UNIT=1 keeps the
unit-cell material instead of the cables."""
import os, sys, numpy as np
import fabric_fenicsx.impact.simulation as simmod
from fabric_fenicsx.fem.projectile import stable_penalty
if os.environ.get("PLUG_UNIT") != "1":
    exec(open("/work/ens/patched_cable.py").read().split("from fabric_fenicsx.cli")[0])
def _contact(self, dt):
    s, proj = self.state, self.projectile
    n_dofs = self.membrane.n_owned_dofs
    if not hasattr(self, "_plug"):
        r2 = (self.X[:, 0] - self.axis_xy[0]) ** 2 + (self.X[:, 1] - self.axis_xy[1]) ** 2
        self._plug = np.flatnonzero(r2 < proj.radius ** 2)
    sel = self._plug
    u = self.cd.u.reshape(-1, 3)
    m = self.node_mass[sel]
    k = stable_penalty(m, dt, 0.5, 0.0)
    p = u[sel, 2] - (s.z - proj.z0)          # > 0: node above where the face has moved
    f = np.zeros((sel.size, 3)); f[:, 2] = -k * p
    f_ext = np.zeros(n_dofs); f_ext.reshape(-1, 3)[sel] = f
    info = dict(penalty_energy=float(0.5 * (k * p * p).sum()), friction_work=0.0, damping_work=0.0,
                n_active=int(sel.size), n_attached=int(sel.size), max_penetration=float(np.abs(p).max()),
                normal_force=float(np.abs(f[:, 2]).sum()))
    return f_ext, -f.sum(axis=0), info
simmod.ImpactSimulation._contact = _contact
from fabric_fenicsx.cli import main
sys.exit(main(sys.argv[1:]))
