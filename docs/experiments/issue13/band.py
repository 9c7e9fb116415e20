import numpy as np
from fabric_fenicsx.material.fabric import zylon_as
from fabric_fenicsx.surrogate.table import Surrogate
sur = Surrogate(zylon_as("max"), resolution=0.004, r_nodes=6, tile=8, progress=False)
E1 = np.linspace(0.0, 0.075, 3001)
for s in (1.0, 0.95, 0.9, 0.85, 0.8, 0.7, 0.6):
    a1 = a2 = 1.0
    P = []; A = []
    for e in E1:
        p1, p2, a1, a2 = sur.update(e, 0.0, a1, a2, crack_band=(s, 1.0))
        P.append(float(p1)); A.append(float(a1))
    P, A = np.array(P), np.array(A)
    lam = np.sqrt(1 + 2 * E1)
    k = np.argmax(A < 1.0)          # first damaged step
    W_pre = np.trapz(P[:k], lam[:k]); W_soft = np.trapz(P[k - 1:], lam[k - 1:])
    print(f"s={s}: onset E1={E1[k]:.4f}, failure E1={E1[np.argmax(A == 0)]:.4f}, W_pre={W_pre:.1f} J/m2, W_soft={W_soft:.1f}, W_soft/s={W_soft/s:.1f}")
