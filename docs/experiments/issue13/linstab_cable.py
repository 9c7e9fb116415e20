import numpy as np
import fabric_fenicsx.fem.yarn_stress as ys
def _intact(self, E1, E2):
    k = self.k_straight
    return k * np.maximum(E1, 0.0), k * np.maximum(E2, 0.0)
ys.YarnStress._intact = _intact
exec(open("/work/main/docs/experiments/issue13/linstab.py").read())
