import sys, numpy as np, tempfile
from fabric_fenicsx.impact.scene import load_scene
from fabric_fenicsx.impact.simulation import ImpactSimulation
t_end = float(sys.argv[1]); extra = sys.argv[2:]
ov = ["projectile.velocity=57.3", "output.xdmf_interval=0", "output.png=false",
      "material.damage=false", f"run.t_end={t_end}", "mesh.h_centre=0.004", *extra]
sim = ImpactSimulation(load_scene("/work/main/demos/scenes/y90.toml", ov), tempfile.mkdtemp(), verbose=False)
sim.run()
mat = sim.material
E1, E2 = mat.E1, mat.E2
P = mat.P_el
s1, s2 = mat.slack(E1, E2)
t11, t12, t21, t22 = sim.surrogate.tangent(np.clip(E1, *sim.surrogate.E_table), np.clip(E2, *sim.surrogate.E_table), np.ones(E1.size), np.ones(E1.size))
on1 = ~s1 & (P[0] > 0); on2 = ~s2 & (P[1] > 0)
T11 = np.where(on1, t11, 0); T22 = np.where(on2, t22, 0); T12 = np.where(on1, t12, 0); T21 = np.where(on2, t21, 0)
sym = 0.5 * (T12 + T21)
lam_min = 0.5 * (T11 + T22) - np.sqrt(0.25 * (T11 - T22) ** 2 + sym ** 2)
print("points", E1.size, "slack1", s1.sum(), "slack2", s2.sum(), "taut1", on1.sum(), "taut2", on2.sum())
print("E1 range %.4f %.4f, E2 range %.4f %.4f" % (E1.min(), E1.max(), E2.min(), E2.max()))
neg = lam_min < 0
print("points with a negative eigenvalue of the symmetric tangent:", neg.sum(), "min %.3e N/m" % lam_min.min())
print("negative T11:", (T11 < 0).sum(), "min %.3e; negative T22:" % T11.min(), (T22 < 0).sum(), "min %.3e" % T22.min())
k = lam_min.argmin(); print("at worst: E1=%.4f E2=%.4f P=%s T=%s" % (E1[k], E2[k], P[:, k], (T11[k], T12[k], T21[k], T22[k])))
# distribution of E2 when compressed and taut
m = on2 & (E2 < 0); print("fill compressed but taut:", m.sum(), "E2 in [%.4f, %.4f]" % (E2[m].min(), E2[m].max()) if m.any() else "")
m = on1 & (E1 < 0); print("warp compressed but taut:", m.sum())
both = on1 & on2
print("both taut:", both.sum(), "max |t12-t21|/max(|t12|,|t21|): %.3e" % (np.abs(t12-t21)[both] / np.maximum(np.abs(t12), np.abs(t21))[both]).max())
print("raw at worst: t21=%.3e t22=%.3e P2raw?" % (t21[k], t22[k]))
# energy pumping potential: points where one yarn cut but coupling from it nonzero
cut = (on1 & ~on2 & (np.abs(t12) > 1e4)) | (on2 & ~on1 & (np.abs(t21) > 1e4))
print("points where a taut yarn's force depends on a cut yarn's stretch (|dPi/dlj| > 1e4 N/m):", cut.sum())
