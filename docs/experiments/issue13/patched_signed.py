import sys, numpy as np
import fabric_fenicsx.fem.yarn_stress as ys
def _intact(self, E1, E2):
    one = np.ones(E1.size)
    vals = self.sur.lookup(self._clip(E1), self._clip(E2), one, one, ("P1", "P2"))
    return vals[:, 0].copy(), vals[:, 1].copy()
ys.YarnStress._intact = _intact
from fabric_fenicsx.cli import main
sys.exit(main(sys.argv[1:]))
