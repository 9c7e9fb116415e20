import numpy as np
from fabric_fenicsx.material.fabric import zylon_as
from fabric_fenicsx.material.unitcell import UnitCell
from fabric_fenicsx.surrogate.table import Surrogate
fab = zylon_as("max")
c = UnitCell(fab)
sur = Surrogate(fab, progress=False)
lam = lambda E: np.sqrt(1 + 2 * E)
Eof = lambda l: 0.5 * (l * l - 1)
for E1, E2 in [(0.00898, -0.00619), (-0.00333, 0.00139), (0.00092, 0.00008), (0.00651, -0.00762), (0.003, -0.0016)]:
    r = c.solve(E1, E2)
    h = 1e-6
    l1, l2 = lam(E1), lam(E2)
    fd = np.array([[(c.solve(Eof(l1 + h), E2).P1 - c.solve(Eof(l1 - h), E2).P1) / (2 * h), (c.solve(E1, Eof(l2 + h)).P1 - c.solve(E1, Eof(l2 - h)).P1) / (2 * h)],
                   [(c.solve(Eof(l1 + h), E2).P2 - c.solve(Eof(l1 - h), E2).P2) / (2 * h), (c.solve(E1, Eof(l2 + h)).P2 - c.solve(E1, Eof(l2 - h)).P2) / (2 * h)]])
    t = sur.tangent(E1, E2, 1.0, 1.0)
    P = sur.evaluate(E1, E2, 1.0, 1.0, tension_only=False)
    print(f"E=({E1},{E2}) unit cell P=({r.P1:.0f},{r.P2:.0f}) contact={r.in_contact} V={r.V:.3g}; tangent uc FD {fd.ravel().round(-3)}; surrogate P=({float(P[0]):.0f},{float(P[1]):.0f}) t={np.array([float(x) for x in t]).round(-3)}")
