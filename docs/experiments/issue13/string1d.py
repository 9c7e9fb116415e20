"""1-D twin test: a clamped tension-only cable (per unit width, Y90's warp numbers) hit by a
bonded rigid plug; does a 1e-12 perturbation grow exponentially, at a rate set by the cell?
usage: string1d.py h [D_factor] [E0]"""
import sys, numpy as np
from fabric_fenicsx.material.fabric import zylon_as
from fabric_fenicsx.fem.yarn_stress import straight_yarn_modulus
from fabric_fenicsx.studies.divergence import relative_difference, growth_rate, crossing_times
f = zylon_as()
rhoA = f.areal_density; k = straight_yarn_modulus(f)
Dbend = float(sys.argv[2]) if len(sys.argv) > 2 else 0.0
D = Dbend * f.warp.B0 * f.yarns_per_metre           # N m (per unit width)
E0 = float(sys.argv[3]) if len(sys.argv) > 3 else 0.0
L, R, Mp = 0.27305, 0.0127, 0.0371 / 0.0254         # span, plug half-width, projectile mass per width
h = float(sys.argv[1]); N = int(round(L / h)); h = L / N
X = np.linspace(0, L, N + 1)
plug = np.abs(X - L / 2) < R
free = ~plug; free[0] = free[-1] = False
m = rhoA * h * np.ones(N + 1)
cL = np.sqrt(k / rhoA)
dt = 0.4 * min(h / cL, h * h / (2 * np.sqrt(D / rhoA) * 2) if D > 0 else 1.0)
def force(x, z):
    dx, dz = np.diff(x), np.diff(z)
    lam = np.hypot(dx, dz) / h
    P = k * np.maximum(0.5 * (lam ** 2 - 1) - E0, 0.0)
    tx, tz = P * dx / (lam * h), P * dz / (lam * h)
    fx = np.zeros(N + 1); fz = np.zeros(N + 1)
    fx[:-1] += tx; fx[1:] -= tx; fz[:-1] += tz; fz[1:] -= tz
    if D > 0:
        c = (z[2:] - 2 * z[1:-1] + z[:-2]) * D / h ** 3
        fz[2:] -= c; fz[1:-1] += 2 * c; fz[:-2] -= c
    return fx, fz
def run(v0, T=8e-4):
    x, z = X.copy(), np.zeros(N + 1); vx, vz = np.zeros(N + 1), np.zeros(N + 1)
    vz[plug] = -v0; vp = -v0
    ts, ke = [], []
    t = 0.0
    while t < T:
        fx, fz = force(x, z)
        Fp = fz[plug].sum()
        vx[free] += dt * fx[free] / m[free]; vz[free] += dt * fz[free] / m[free]
        vp += dt * Fp / (Mp + m[plug].sum()); vz[plug] = vp
        x += dt * vx; z += dt * vz; t += dt
        ts.append(t); ke.append(0.5 * (m[free] * (vx[free] ** 2 + vz[free] ** 2)).sum())
    return np.array(ts), np.array(ke), vp
t, a, va = run(57.3); _, b, vb = run(57.3 * (1 + 1e-12))
d = relative_difference(a, b)
r = growth_rate(t, d, lo=1e-9, hi=1e-4)
print(f"h {h*1e3:.2f} mm D {D:.2e} E0 {E0}: e-fold {1e6/r if r else float('nan'):.1f} us, crossings 1e-8/1e-6/1e-4 "
      + "/".join('%.0f' % (c * 1e6) if c else '-' for c in crossing_times(t, d, (1e-8, 1e-6, 1e-4)))
      + f", d end {d[-1]:.1e}, v_proj {-va:.2f} m/s")
