import sys, time, tempfile, functools, os, numpy as np
import scipy.sparse.linalg as spla
import fabric_fenicsx.surrogate.table as table
res = float(os.environ.get("SUR_RES", "0.002"))
table.Surrogate = functools.partial(table.Surrogate, resolution=res)
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
free = np.flatnonzero(cd.free[:n])
Mi = 1.0 / np.sqrt(cd.mass[free])
def fint(u):
    m.set_displacement(u)
    E1, E2 = m.yarn_strains()
    P1, P2 = mat.update(E1, E2)
    m.set_stress(P1, P2)
    return m.internal_force()[:n]
def stiffness():
    K = np.empty((free.size, free.size)); h = 1e-9
    for j, d in enumerate(free):
        u = u0.copy(); u[d] += h; fp = fint(u); u[d] -= 2 * h; fm = fint(u)
        K[:, j] = (fp - fm)[free] / (2 * h)
    return Mi[:, None] * K * Mi[None, :]
def unstable(A, label):
    import scipy.linalg as sla
    vals, vecs = sla.eig(A)
    g = np.abs(np.sqrt(vals.astype(complex)).imag)
    ls = np.linalg.eigvalsh(0.5 * (A + A.T))
    print(f"{label}: most negative Re(lambda) {vals.real.min():.3e} (growth {g.max():.3e}/s); sym part: {int((ls < 0).sum())} negative, min {ls.min():.3e}", flush=True)
    return vals, vecs
A = stiffness()
vals, vecs = unstable(A, "all terms")
j = int(np.argmin(vals.real))
phi = np.zeros(n); phi[free] = Mi * np.real(vecs[:, j]); phi /= np.abs(phi).max()
eps = 1e-7
def point_state(u):
    m.set_displacement(u)
    E1, E2 = m.yarn_strains()
    P1, P2 = mat.update(E1, E2)
    return np.array([E1, E2]), np.array([P1, P2])
Ep, Pp = point_state(u0 + eps * phi); Em, Pm = point_state(u0 - eps * phi); E0, P0 = point_state(u0)
dl = (np.sqrt(1 + 2 * Ep) - np.sqrt(1 + 2 * Em)) / (2 * eps)
dP = (Pp - Pm) / (2 * eps)
contrib = mat.w * (dP * dl).sum(axis=0)
geo = None
print("material energy of the mode: total %.3e, negative part %.3e from %d points, positive %.3e" % (contrib.sum(), contrib[contrib < 0].sum(), (contrib < 0).sum(), contrib[contrib > 0].sum()))
sur = sim.surrogate
one = np.ones(E0.shape[1])
Pr = sur.evaluate(np.clip(E0[0], *sur.E_table), np.clip(E0[1], *sur.E_table), one, one, tension_only=False)
V = sur.lookup(np.clip(E0[0], *sur.E_table), np.clip(E0[1], *sur.E_table), one, one, ("V",))[:, 0]
s1, s2 = mat.slack(E0[0], E0[1])
for p in np.argsort(contrib)[:12]:
    print(f"  {contrib[p]:+.3e}: E=({E0[0,p]:+.5f},{E0[1,p]:+.5f}) P_raw=({Pr[0][p]:.0f},{Pr[1][p]:.0f}) P_used=({P0[0,p]:.0f},{P0[1,p]:.0f}) V={V[p]:.3g} slack=({s1[p]},{s2[p]}) dl=({dl[0,p]:+.2e},{dl[1,p]:+.2e}) dP=({dP[0,p]:+.2e},{dP[1,p]:+.2e})")
