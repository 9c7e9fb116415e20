"""Material (b): exact separated branch, contact branch continued across the line (importing
it replaces YarnStress._intact; patched_branch.py runs the command line with it)."""
import sys, numpy as np
from scipy.interpolate import RectBivariateSpline
from scipy.ndimage import distance_transform_edt
import fabric_fenicsx.fem.yarn_stress as ys
s = np.load("/work/ens/sep.npz"); b = np.load("/work/ens/branch.npz")
E, P1s, P2s, D1, D2 = s["E"], s["P1"], s["P2"], s["D1"], s["D2"]
E1g, E2g = b["E1"], b["E2"]
Dg = np.interp(E1g, E, D1)[:, None] + np.interp(E2g, E, D2)[None, :]
contact_region = Dg < 0
fails = np.isnan(b["P1c"])
near = distance_transform_edt(~contact_region) <= 2
print("bilateral failures within 2 cells of the contact region:", int((fails & near).sum()), file=sys.stderr)
_, (ii, jj) = distance_transform_edt(fails, return_indices=True)
spl = [RectBivariateSpline(E1g, E2g, b[k][ii, jj], kx=3, ky=3) for k in ("P1c", "P2c")]
def _intact(self, E1, E2):
    self.beyond_table += int(np.count_nonzero((E1 > self.E_hi) | (E2 > self.E_hi)))
    e1 = np.clip(E1, E1g[0], E1g[-1]); e2 = np.clip(E2, E2g[0], E2g[-1])
    sep = (np.interp(E1, E, D1) + np.interp(E2, E, D2)) >= 0.0
    p1 = np.where(sep, np.interp(E1, E, P1s), spl[0].ev(e1, e2))
    p2 = np.where(sep, np.interp(E2, E, P2s), spl[1].ev(e1, e2))
    return np.maximum(p1, 0.0), np.maximum(p2, 0.0)
ys.YarnStress._intact = _intact
