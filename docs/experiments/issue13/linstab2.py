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
    vals, vecs = spla.eigs(A, k=6, sigma=-2e10, which="LM")
    g = np.abs(np.sqrt(vals.astype(complex)).imag)
    ls = np.linalg.eigvalsh(0.5 * (A + A.T))
    print(f"{label}: most negative Re(lambda) {vals.real.min():.3e} (growth {g.max():.3e}/s); sym part: {int((ls < 0).sum())} negative, min {ls.min():.3e}", flush=True)
    return vals, vecs
A = stiffness()
vals, vecs = unstable(A, "all terms")
terms = list(m.terms)
m.terms[:] = [t for t in terms if t.name == "yarns"]
A2 = stiffness()
unstable(A2, "yarn term only")
m.terms[:] = terms
# the mode: which points carry its negative energy?
phi = np.real(vecs[:, np.argmin(vals.real)])
X = m.V.tabulate_dof_coordinates()[: n // 3]
v = np.abs(phi); k = np.argmax(v)
print("mode peak at x=%.1f y=%.1f mm comp %d" % (X[free[k] // 3, 0] * 1e3, X[free[k] // 3, 1] * 1e3, free[k] % 3))
