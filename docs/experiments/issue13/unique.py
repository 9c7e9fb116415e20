import numpy as np
from fabric_fenicsx.material.fabric import zylon_as
from fabric_fenicsx.material.unitcell import UnitCell
fab = zylon_as("max")
d = np.load("/work/ens/branch.npz")
E1g, E2g = d["E1"], d["E2"]
contact = d["V"] > 0
bad = (~contact) & (d["Vc"] >= 0)
idx = np.argwhere(bad)
print("non-unique candidates:", len(idx), " E1 range", E1g[idx[:, 0]].min(), E1g[idx[:, 0]].max(), " E2 range", E2g[idx[:, 1]].min(), E2g[idx[:, 1]].max())
c = UnitCell(fab)
lam = lambda E: np.sqrt(1 + 2 * E)
for i, j in idx[::max(1, len(idx) // 8)][:8]:
    e1, e2 = E1g[i], E2g[j]
    c.forget(); r = c.solve(e1, e2)
    base = c._last[2]; st = base.copy(); st.contact = True
    st2, its = c._newton(st, np.array([lam(e1), lam(e2)]), np.ones(2))
    rc = c._result(st2, np.array([lam(e1), lam(e2)]), np.ones(2), its)
    print(f"E=({e1:+.3f},{e2:+.3f}): fresh solve contact={r.in_contact} P=({r.P1:.0f},{r.P2:.0f}) Psi={r.Psi:.4g} gap?; bilateral V={rc.V:.3g} P=({rc.P1:.0f},{rc.P2:.0f}) Psi={rc.Psi:.4g}")
