import sys, tempfile, numpy as np
from fabric_fenicsx.impact.scene import load_scene
from fabric_fenicsx.impact.simulation import ImpactSimulation
T = float(sys.argv[1]); x0, y0 = float(sys.argv[2]) * 1e-3, float(sys.argv[3]) * 1e-3
ov = ["projectile.velocity=57.3", "output.xdmf_interval=0", "output.png=false", "material.damage=false",
      f"run.t_end={T}", "mesh.h_centre=0.004"]
sim = ImpactSimulation(load_scene("/work/main/demos/scenes/y90.toml", ov), tempfile.mkdtemp(), verbose=False)
sim.run()
m, mat, sur = sim.membrane, sim.material, sim.surrogate
cells = m.V.dofmap.list.array.reshape(-1, 4)[:m.n_cells]
X = m.V.tabulate_dof_coordinates()[:, :2]
cen = X[cells].mean(axis=1)
near = np.argsort(np.hypot(cen[:, 0] - x0, cen[:, 1] - y0))[:6]
E1, E2 = mat.E1, mat.E2
one = np.ones(E1.size)
P = sur.evaluate(np.clip(E1, *sur.E_table), np.clip(E2, *sur.E_table), one, one, tension_only=False)
t11, t12, t21, t22 = sur.tangent(np.clip(E1, *sur.E_table), np.clip(E2, *sur.E_table), one, one)
s1, s2 = mat.slack(E1, E2)
u = sim.cd.u.reshape(-1, 3)
for c in near:
    p = c  # one point per cell (reduced)
    print(f"cell at ({cen[c,0]*1e3:.1f},{cen[c,1]*1e3:.1f}) mm: E1={E1[p]:+.5f} E2={E2[p]:+.5f} P_raw=({P[0][p]:.0f},{P[1][p]:.0f}) P_used=({mat.P_el[0,p]:.0f},{mat.P_el[1,p]:.0f}) slack=({s1[p]},{s2[p]}) t=({t11[p]:.2e},{t12[p]:.2e},{t21[p]:.2e},{t22[p]:.2e}) uz={u[cells[c],2].mean()*1e3:.2f} mm")
