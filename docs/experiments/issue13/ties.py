"""Near-ties at damage onset: the twins (V0 and V0 (1 + 1e-12)) run damage off to T; at each
point mu_i / mu_crit,i (the damage criterion, Eq. 2-22/2-25); how many points are within the
twins' own difference of the largest, and whether the twins rank the same point first.
usage: ties.py T [SECTION.KEY=VALUE ...]"""
import sys, tempfile, numpy as np
from fabric_fenicsx.impact.scene import load_scene
from fabric_fenicsx.impact.simulation import ImpactSimulation
T = float(sys.argv[1]); extra = sys.argv[2:] or ["mesh.h_centre=0.004"]
out = []
for k in (0, 1):
    ov = [f"projectile.velocity={57.3 * (1 + k * 1e-12)!r}", "output.xdmf_interval=0", "output.png=false",
          "material.damage=false", f"run.t_end={T}", *extra]
    sim = ImpactSimulation(load_scene("/work/main/demos/scenes/y90.toml", ov), tempfile.mkdtemp(), verbose=False)
    sim.run()
    mat, sur = sim.material, sim.surrogate
    E1, E2 = np.clip(mat.E1, *sur.E_table), np.clip(mat.E2, *sur.E_table)
    one = np.ones(E1.size)
    mu = sur.lookup(E1, E2, one, one, ("mu1", "mu2"))
    fab = sur.fabric
    r = np.stack([(mu[:, 0] - 1) / (fab.warp.mu_crit - 1), (mu[:, 1] - 1) / (fab.fill.mu_crit - 1)])
    out.append(r)
a, b = out
d = np.abs(a - b).max()
for name, r in (("a", a), ("b", b)):
    top = r.max(); i = np.unravel_index(r.argmax(), r.shape)
    print(f"twin {name}: largest (mu-1)/(mu_crit-1) {top:.6f} at yarn {i[0]+1} point {i[1]}")
print(f"largest twin difference of the criterion over all points: {d:.2e}")
top = max(a.max(), b.max())
for tol in (d, 1e-3, 1e-2, 3e-2):
    print(f"points within {tol:.1e} of the largest: a {(a >= a.max() - tol).sum()}, b {(b >= b.max() - tol).sum()}")
m = sim.membrane
nodes = m.V.dofmap.list.array.reshape(-1, 4)[:m.n_cells]
C = m.V.tabulate_dof_coordinates()[nodes].mean(axis=1)[:, :2] * 1e3
C = np.repeat(C, m.n_points_per_cell, axis=0)
for name, r in (("a", a), ("b", b)):
    o = np.argsort(r[0])[::-1][:8]
    print(name, "top warp points (x, y mm: criterion):", "; ".join(f"({C[p,0]:.1f}, {C[p,1]:.1f}): {r[0,p]:.3f}" for p in o))
dd = np.abs(a - b)[0]; o = np.argsort(dd)[::-1][:5]
print("largest twin differences at", "; ".join(f"({C[p,0]:.1f}, {C[p,1]:.1f}): {a[0,p]:.3f} vs {b[0,p]:.3f}" for p in o))
print("profile along the principal warp (|x| < 12.7 mm), criterion per 10 mm bin of y: max / mean, twin a | twin b")
sel = np.abs(C[:, 0]) < 12.7
for lo in range(-130, 130, 20):
    s = sel & (C[:, 1] >= lo) & (C[:, 1] < lo + 20)
    if s.any():
        print(f"  y in [{lo:4d},{lo+20:4d}) mm ({s.sum():3d} points): {a[0,s].max():.3f} / {a[0,s].mean():.3f} | {b[0,s].max():.3f} / {b[0,s].mean():.3f}")
for x0 in (0.0, 6.0):
    print(f"strip |x - {x0}| < 2 mm: y (mm): criterion a / b")
    s = np.flatnonzero(np.abs(C[:, 0] - x0) < 2.0)
    s = s[np.argsort(C[s, 1])]
    print("  " + "; ".join(f"{C[p,1]:.0f}: {a[0,p]:.2f}/{b[0,p]:.2f}" for p in s))
