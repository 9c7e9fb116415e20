"""Proof of concept: branch-aware intact surrogate (contact branch continued bilaterally, separated
branch), selection by the sign of the continued contact force V. Builds /work/ens/branch.npz."""
import time, numpy as np
from fabric_fenicsx.material.fabric import zylon_as
from fabric_fenicsx.material.unitcell import UnitCell, UnitCellError
c = UnitCell(zylon_as("max"))
h = 0.002
E1g = np.arange(-0.06, 0.0701, h); E2g = np.arange(-0.12, 0.0501, h)
lam = lambda E: np.sqrt(1 + 2 * E)
alpha = np.ones(2)
out = {k: np.full((E1g.size, E2g.size), np.nan) for k in ("P1c", "P2c", "Vc", "P1s", "P2s", "P1", "P2", "V")}
t0 = time.time(); fails = 0
for i, e1 in enumerate(E1g):
    for j, e2 in enumerate(E2g):
        try:
            r = c.solve(e1, e2)
        except UnitCellError:
            fails += 1; continue
        out["P1"][i, j], out["P2"][i, j], out["V"][i, j] = r.P1, r.P2, r.V
        base = c._last[2]
        L = np.array([lam(e1), lam(e2)])
        for branch, key in ((True, "c"), (False, "s")):
            if base.contact == branch:
                out["P1" + key][i, j], out["P2" + key][i, j] = r.P1, r.P2
                if branch: out["Vc"][i, j] = r.V
                continue
            st = base.copy(); st.contact = branch
            if not branch: st.V = 0.0
            try:
                st2, its = c._newton(st, L, alpha)
                rr = c._result(st2, L, alpha, its)
                out["P1" + key][i, j], out["P2" + key][i, j] = rr.P1, rr.P2
                if branch: out["Vc"][i, j] = rr.V
            except UnitCellError:
                fails += 1
print("solved in %.0f s, %d failures; NaN counts:" % (time.time() - t0, fails), {k: int(np.isnan(v).sum()) for k, v in out.items()})
np.savez("/work/ens/branch.npz", E1=E1g, E2=E2g, **out)
