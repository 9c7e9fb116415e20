import sys, numpy as np, tempfile
from fabric_fenicsx.impact.scene import load_scene
from fabric_fenicsx.impact.simulation import ImpactSimulation
t_end = float(sys.argv[1]); extra = sys.argv[2:]
res = []
for k in (0, 1):
    ov = [f"projectile.velocity={57.3*(1+k*1e-12)!r}", "output.xdmf_interval=0", "output.png=false",
          "material.damage=false", f"run.t_end={t_end}", *(extra or ["mesh.h_centre=0.004"])]
    sc = load_scene("/work/main/demos/scenes/y90.toml", ov)
    sim = ImpactSimulation(sc, tempfile.mkdtemp(), verbose=False)
    sim.run()
    n = sim.n_nodes
    u = np.array(sim.cd.u).reshape(-1, 3)[:n].copy()
    v = np.array(sim.cd.v).reshape(-1, 3)[:n].copy() if hasattr(sim.cd, "v") else None
    E1, E2 = sim.material.E1.copy(), sim.material.E2.copy()
    res.append((u, v, E1, E2))
    X = sim.X
    npc = sim.npc
(u0, v0, a1, a2), (u1, v1, b1, b2) = res
d = np.linalg.norm(u1 - u0, axis=1)
r = np.hypot(X[:, 0], X[:, 1])
print("max |du| %.2e at x=%.1f y=%.1f mm (r=%.1f), uz there %.2f mm" % (d.max(), *(X[d.argmax(), :2]*1e3), r[d.argmax()]*1e3, u0[d.argmax(), 2]*1e3))
for lo, hi in [(0, 12.7), (12.7, 20), (20, 40), (40, 80), (80, 200)]:
    m = (r*1e3 >= lo) & (r*1e3 < hi)
    print(f"r in [{lo},{hi}) mm: max |du| {d[m].max():.2e}, nodes {m.sum()}")
dv = np.linalg.norm(v1 - v0, axis=1) if v0 is not None else None
if dv is not None: print("max |dv| %.2e at r=%.1f mm" % (dv.max(), r[dv.argmax()]*1e3))
# strains at points: compressed?
dE = np.abs(b1 - a1) + np.abs(b2 - a2)
k = dE.argmax()
print("max |dE| %.2e at point with E1=%.4f E2=%.4f" % (dE[k], a1[k], a2[k]))
slack = (a1 < 0) | (a2 < 0)
print("points with a compressed yarn: %d of %d; max |dE| there %.2e, elsewhere %.2e" % (slack.sum(), a1.size, dE[slack].max() if slack.any() else 0, dE[~slack].max()))
