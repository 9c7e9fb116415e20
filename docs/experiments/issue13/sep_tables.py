"""Exact separated branch: per yarn P_i^sep(E_i) and its gap contribution D_i(E_i) (the unit cell
with contact switched off: the yarns are independent). Saves /work/ens/sep.npz."""
import numpy as np
from fabric_fenicsx.material.fabric import zylon_as
from fabric_fenicsx.material.unitcell import UnitCell
c = UnitCell(zylon_as("max"))
E = np.arange(-0.06, 0.1001, 0.0005)
P1, P2, D1, D2, ok = (np.full(E.size, np.nan) for _ in range(5))
state = c._reference.copy(); state.contact = False; state.V = 0.0
order = np.argsort(np.abs(E))          # march outwards from E = 0
for k in order:
    e = E[k]
    lam = np.sqrt(1 + 2 * e)
    # warm start from the nearest solved neighbour toward 0
    st = c._reference.copy(); st.contact = False; st.V = 0.0
    nb = k - 1 if e > 0 else k + 1
    if 0 <= nb < E.size and not np.isnan(P1[nb]):
        st = prev[nb].copy()
    st2, its = c._newton(st, np.array([lam, lam]), np.ones(2))
    r = c._result(st2, np.array([lam, lam]), np.ones(2), its)
    P1[k], P2[k] = r.P1, r.P2
    for i, (y, phi, F) in enumerate(zip(c.yarns, (st2.phi1, st2.phi2), (st2.F1, st2.F2))):
        cc, s, N, Q, mu = y.fields(phi, F, 0.0, c.A0[i])
        (D1, D2)[i][k] = float(np.sum(y.wq * mu * s)) - y.sinPhi_int
    if "prev" not in dir(): prev = {}
    prev[k] = st2
np.savez("/work/ens/sep.npz", E=E, P1=P1, P2=P2, D1=D1, D2=D2)
i = np.searchsorted(E, 0.009); j = np.searchsorted(E, -0.0062)
print("P1sep(0.009)", P1[i], "D1(0.009)", D1[i], "D2(-0.0062)", D2[j], "sum", D1[i] + D2[j])
print("D at 0:", D1[np.searchsorted(E, 0.0)], D2[np.searchsorted(E, 0.0)])
