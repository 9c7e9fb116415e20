"""Where the removed cells of a member lie: reference (x, y) of the removed cells at the end.
usage: removed.py K [SECTION.KEY=VALUE ...]"""
import sys, tempfile, numpy as np
from fabric_fenicsx.impact.scene import load_scene
from fabric_fenicsx.impact.simulation import ImpactSimulation
k = int(sys.argv[1]); extra = sys.argv[2:] or ["mesh.h_centre=0.004"]
ov = [f"projectile.velocity={57.3 * (1 + k * 1e-12)!r}", "output.xdmf_interval=0", "output.png=false", *extra]
sim = ImpactSimulation(load_scene("/work/main/demos/scenes/y90.toml", ov), tempfile.mkdtemp(), verbose=False)
s = sim.run()
m = sim.membrane
nodes = m.V.dofmap.list.array.reshape(-1, 4)[:m.n_cells]
C = m.V.tabulate_dof_coordinates()[nodes].mean(axis=1)[:, :2] * 1e3
gone = ~np.asarray(sim.live_cells)[:m.n_cells]
r = np.hypot(C[gone, 0], C[gone, 1])
print(f"k={k}: v_res {s['residual_velocity']:.2f} m/s, onset r {s['damage_onset_radius']*1e3:.1f} mm, removed {gone.sum()}: "
      f"radius quartiles {np.percentile(r, [0, 25, 50, 75, 100]).round(1)} mm; beyond 20 mm: {(r > 20).sum()}, |y| > 20 mm: {(np.abs(C[gone,1]) > 20).sum()}, |x| > 20 mm: {(np.abs(C[gone,0]) > 20).sum()}")
print("  removed (x, y) mm:", " ".join(f"({x:.0f},{y:.0f})" for x, y in C[gone][np.argsort(-np.hypot(*C[gone].T))][:12]))
