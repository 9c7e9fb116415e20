"""Linear stability of the semi-discrete membrane at the state of a Y90 run at time T (damage
off): K by central differences of the internal force over the free dofs, the eigenvalues of
M^-1/2 K M^-1/2 and of its symmetric part, and the most unstable mode's material energy split
over the points. Merges the four scripts that ran (the first printed the dense spectrum, the
second also the yarn term alone, the third and fourth the energy split, by ARPACK and dense).

usage: linstab.py T [--arpack] [--yarn-only] [SECTION.KEY=VALUE ...]
Material (b) or (c): python -c "import branch_patch; ..." before it (see README.md)."""
import sys, tempfile, numpy as np, scipy.linalg as sla, scipy.sparse.linalg as spla
from fabric_fenicsx.impact.scene import load_scene
from fabric_fenicsx.impact.simulation import ImpactSimulation
from fabric_fenicsx.fem.yarn_stress import YarnStress
T = float(sys.argv[1]); flags = {a for a in sys.argv[2:] if a.startswith("--")}
extra = [a for a in sys.argv[2:] if not a.startswith("--")]
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
    if "--arpack" in flags:   # did not converge in 17 min on material (b): use the dense solve
        vals, vecs = spla.eigs(A, k=6, sigma=-2e10, which="LM")
    else:
        vals, vecs = sla.eig(A)
    g = np.abs(np.sqrt(vals.astype(complex)).imag)
    ls = np.linalg.eigvalsh(0.5 * (A + A.T))
    print(f"{label}: most negative Re(lambda) {vals.real.min():.3e} (growth {g.max():.3e}/s); sym part: {int((ls < 0).sum())} negative, min {ls.min():.3e}", flush=True)
    return vals, vecs
A = stiffness()
vals, vecs = unstable(A, "all terms")
if "--yarn-only" in flags:               # the yarn term alone, without the hourglass control
    terms = list(m.terms)
    m.terms[:] = [t for t in terms if t.name == "yarns"]
    unstable(stiffness(), "yarn term only")
    m.terms[:] = terms
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
print("material energy of the mode: total %.3e, negative part %.3e from %d points, positive %.3e" % (contrib.sum(), contrib[contrib < 0].sum(), (contrib < 0).sum(), contrib[contrib > 0].sum()))
sur = sim.surrogate
one = np.ones(E0.shape[1])
Pr = sur.evaluate(np.clip(E0[0], *sur.E_table), np.clip(E0[1], *sur.E_table), one, one, tension_only=False)
V = sur.lookup(np.clip(E0[0], *sur.E_table), np.clip(E0[1], *sur.E_table), one, one, ("V",))[:, 0]
s1, s2 = mat.slack(E0[0], E0[1])
for p in np.argsort(contrib)[:12]:
    print(f"  {contrib[p]:+.3e}: E=({E0[0,p]:+.5f},{E0[1,p]:+.5f}) P_raw=({Pr[0][p]:.0f},{Pr[1][p]:.0f}) P_used=({P0[0,p]:.0f},{P0[1,p]:.0f}) V={V[p]:.3g} slack=({s1[p]},{s2[p]}) dl=({dl[0,p]:+.2e},{dl[1,p]:+.2e}) dP=({dP[0,p]:+.2e},{dP[1,p]:+.2e})")
