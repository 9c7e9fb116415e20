"""Material (d): uncoupled linear cables, P_i = k (E_i - E0), no unit cell at all.
CABLE_E0: the slack strain (crimp) before the cable takes load (default 0);
CABLE_SIGNED=1: keep compression (a linear orthotropic membrane without shear)."""
import os, sys, numpy as np
import fabric_fenicsx.fem.yarn_stress as ys
E0 = float(os.environ.get("CABLE_E0", "0"))
SIGNED = os.environ.get("CABLE_SIGNED") == "1"
def _intact(self, E1, E2):
    k = self.k_straight
    if SIGNED:
        return k * (E1 - E0), k * (E2 - E0)
    return k * np.maximum(E1 - E0, 0.0), k * np.maximum(E2 - E0, 0.0)
ys.YarnStress._intact = _intact
if SIGNED:
    ys.YarnStress.slack = lambda self, E1, E2: (np.zeros(E1.size, bool), np.zeros(E1.size, bool))
from fabric_fenicsx.cli import main
sys.exit(main(sys.argv[1:]))
