"""Linear stability of the semi-discrete membrane at the state of a run at time T."""
import sys, time, tempfile, numpy as np, scipy.linalg as sla
from fabric_fenicsx.impact.scene import load_scene
from fabric_fenicsx.impact.simulation import ImpactSimulation
from fabric_fenicsx.fem.yarn_stress import YarnStress
T = float(sys.argv[1]); extra = sys.argv[2:]
ov = ["projectile.velocity=57.3", "output.xdmf_interval=0", "output.png=false", "material.damage=false",
      f"run.t_end={T}", *(extra or ["mesh.h_centre=0.004"])]
sim = ImpactSimulation(load_scene("/work/main/demos/scenes/y90.toml", ov), tempfile.mkdtemp(), verbose=False)
sim.run()
m, cd = sim.membrane, sim.cd
mat = YarnStress(sim.surrogate, m.quadrature_weights_detJ, False, 0.0)
for term in m.terms:
    if hasattr(term, "follow"):
        term.follow(lambda: mat.state, mat.tension)
n = m.n_owned_dofs
u0 = cd.u.copy()
def fint(u):
    m.set_displacement(u)
    E1, E2 = m.yarn_strains()
    P1, P2 = mat.update(E1, E2)
    m.set_stress(P1, P2)
    return m.internal_force()[:n]
f0 = fint(u0)
free = np.flatnonzero(cd.free[:n])
h = 1e-9
t0 = time.time()
K = np.empty((free.size, free.size))
for j, d in enumerate(free):
    u = u0.copy(); u[d] += h
    fp = fint(u)
    u[d] -= 2 * h
    fm = fint(u)
    K[:, j] = (fp - fm)[free] / (2 * h)
print("K built in %.0f s, %d free dofs" % (time.time() - t0, free.size))
Mi = 1.0 / np.sqrt(cd.mass[free])
A = Mi[:, None] * K * Mi[None, :]
asym = np.abs(A - A.T).max() / np.abs(A).max()
print("relative asymmetry of M^-1/2 K M^-1/2: %.2e" % asym)
lam, vec = sla.eig(A)
omega = np.sqrt(lam.astype(complex))
growth = np.abs(omega.imag)
k = np.argsort(growth)[::-1][:8]
print("largest growth rates (1/s):", growth[k], "\n eigenvalues:", lam[k])
ls = np.linalg.eigvalsh(0.5 * (A + A.T))
print("symmetric part: %d negative eigenvalues, min %.3e (growth %.3e /s)" % ((ls < 0).sum(), ls.min(), np.sqrt(max(-ls.min(), 0))))
X = m.V.tabulate_dof_coordinates()[: n // 3]
v = np.abs(vec[:, k[0]])
node = free[np.argmax(v)] // 3; comp = free[np.argmax(v)] % 3
print("most unstable mode peaks at node x=%.1f y=%.1f mm, component %d" % (X[node, 0] * 1e3, X[node, 1] * 1e3, comp))
share = [float((v[(free % 3) == c] ** 2).sum() / (v ** 2).sum()) for c in range(3)]
print("mode energy share x/y/z:", np.round(share, 3))
np.savez("/work/ens/linstab.npz", lam=lam, growth=growth, free=free, X=X, vec0=vec[:, k[0]])
