"""1D relaxed responses: P1_rel(E1) = unit cell with the fill force-free (P2 = 0), and
P2_rel(E2) = the same with warp and fill swapped. Saves /work/ens/relaxed.npz."""
import dataclasses, numpy as np
from fabric_fenicsx.material.fabric import zylon_as
from fabric_fenicsx.material.unitcell import UnitCell
fab = zylon_as("max")
swapped = fab.replace(warp=dataclasses.replace(fab.fill, name="warp"), fill=dataclasses.replace(fab.warp, name="fill"))
E = np.arange(-0.06, 0.1001, 0.0005)
out = {}
for key, f in (("P1rel", fab), ("P2rel", swapped)):
    c = UnitCell(f)
    vals, E2free = [], []
    for e in E:
        r = c.solve(e, None)
        vals.append(r.P1); E2free.append(r.E2)
    out[key] = np.array(vals); out[key + "_other"] = np.array(E2free)
np.savez("/work/ens/relaxed.npz", E=E, **out)
i = np.searchsorted(E, 0.009)
print("P1rel at 0.009:", out["P1rel"][i], "free fill strain", out["P1rel_other"][i])
print("monotone P1rel for E>0:", bool(np.all(np.diff(out["P1rel"][E >= 0]) > 0)), " P2rel:", bool(np.all(np.diff(out["P2rel"][E >= 0]) > 0)))
