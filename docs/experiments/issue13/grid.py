import numpy as np
from fabric_fenicsx.material.fabric import Fabric
from fabric_fenicsx.surrogate.table import Surrogate
from fabric_fenicsx.impact.setup import build_fabric
from fabric_fenicsx.impact.scene import load_scene
fab = build_fabric(load_scene("/work/main/demos/scenes/y90.toml", []))
sur = Surrogate(fab, progress=False)
E1, E2 = np.meshgrid(np.linspace(-0.02, 0.05, 71), np.linspace(-0.03, 0.03, 61), indexing="ij")
E1, E2 = E1.ravel(), E2.ravel()
one = np.ones(E1.size)
P1, P2, _, _ = sur.evaluate(E1, E2, one, one, tension_only=False)
t11, t12, t21, t22 = sur.tangent(E1, E2, one, one)
both = (P1 > 0) & (P2 > 0)
sym = 0.5 * (t12 + t21)
lmin = 0.5 * (t11 + t22) - np.sqrt(0.25 * (t11 - t22) ** 2 + sym ** 2)
asym = np.abs(t12 - t21) / np.maximum(np.maximum(np.abs(t12), np.abs(t21)), 1.0)
print("both taut:", both.sum(), "negative lmin:", (both & (lmin < 0)).sum(), "min %.3e" % lmin[both].min())
print("asymmetry > 10 %:", (both & (asym > 0.1)).sum(), "median asym %.3e" % np.median(asym[both]))
print("det t (unsymmetrised) < 0:", (both & (t11 * t22 - t12 * t21 < 0)).sum())
for k in np.flatnonzero(both & (lmin < 0))[:12]:
    print("E1 %.3f E2 %.3f P %.0f %.0f  t11 %.2e t12 %.2e t21 %.2e t22 %.2e" % (E1[k], E2[k], P1[k], P2[k], t11[k], t12[k], t21[k], t22[k]))
# one yarn cut (P2<0) with warp taut: coupling
cut = (P1 > 0) & (P2 <= 0) & (E1 > 0)
print("warp taut, fill would push:", cut.sum(), "median |t12|/t11 %.2f" % np.median(np.abs(t12[cut]) / np.maximum(t11[cut], 1)))
