"""Fibril scale: statistical bundle vs. the exponential damage law (thesis section 2.3).

A yarn of n fibrils with uniformly distributed misalignment d_j = r_j d0 (Eq. 2-22) is loaded
monotonically; the fraction of unbroken fibrils alpha(mu) is compared with the exponential law
of Eq. 2-25 at the thesis's beta = 124 and at beta fitted by least squares to the bundle. d0/h0 is
chosen so that the bundle's damage range has the thesis's width 0.03 (``FibrilBundle.for_width``).
The stiffness ratio E*/E_I of Eq. 2-23 is shown as well.

Run:  python3 demos/demo_fibril.py [output_dir]      (default output_dir: out/fibril)
Writes ``fibril_damage.png`` and prints d0/h0, fitted beta and rms residual per yarn.
"""
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from fabric_fenicsx.material.fibril import ExponentialDamage, FibrilBundle, fit_beta  # noqa: E402

WIDTH = 0.03
YARNS = {"warp": 1.025, "fill": 1.0297, "virgin": 1.03}  # mu_crit, Table 1

out_dir = Path(sys.argv[1]) if len(sys.argv) > 1 else Path("out/fibril")
out_dir.mkdir(parents=True, exist_ok=True)

fig, (ax_a, ax_e) = plt.subplots(1, 2, figsize=(11, 4.2))
print(f"{'yarn':7s} {'mu_crit':>8s} {'d0/h0':>8s} {'beta_fit':>9s} {'rms_fit':>8s} {'rms_124':>8s}")
for name, mu_crit in YARNS.items():
    bundle = FibrilBundle.for_width(WIDTH, mu_crit, n=20000, seed=0)
    mu = np.linspace(mu_crit, mu_crit + WIDTH, 601)
    alpha = bundle.alpha(mu, mu_crit)
    beta, rms = fit_beta(mu, alpha, mu_crit, WIDTH)
    rms_124 = np.sqrt(np.mean((ExponentialDamage(124.0, WIDTH).alpha(mu, mu_crit) - alpha) ** 2))
    print(f"{name:7s} {mu_crit:8.4f} {bundle.d0_over_h0:8.4f} {beta:9.2f} {rms:8.4f} {rms_124:8.4f}")
    if name != "warp":
        continue
    mu_plot = np.linspace(mu_crit - 0.005, mu_crit + WIDTH + 0.005, 801)
    ax_a.step(mu_plot, bundle.alpha(mu_plot, mu_crit), where="post", lw=2,
              label=f"bundle, n={bundle.n}, d0/h0={bundle.d0_over_h0:.3f}")
    ax_a.plot(mu_plot, bundle.alpha_limit(mu_plot, mu_crit), "k:", label="bundle, n -> inf")
    ax_a.plot(mu_plot, ExponentialDamage(124.0, WIDTH).alpha(mu_plot, mu_crit), "--",
              label="Eq. 2-25, beta = 124 (thesis)")
    ax_a.plot(mu_plot, ExponentialDamage(beta, WIDTH).alpha(mu_plot, mu_crit), "-.",
              label=f"Eq. 2-25, beta = {beta:.1f} (fit, rms {rms:.3f})")
    ax_a.set(xlabel="yarn stretch mu", ylabel="alpha (unbroken fraction)",
             title=f"warp, mu_crit = {mu_crit}")
    ax_a.legend(fontsize=8)
    e = bundle.effective_modulus_ratio(mu_plot, mu_crit)
    ax_e.plot(mu_plot, e / e[0], label="E*/E*_undamaged (Eq. 2-23)")
    ax_e.plot(mu_plot, bundle.alpha(mu_plot, mu_crit), "--", label="alpha")
    ax_e.set(xlabel="yarn stretch mu", ylabel="ratio", title="stiffness vs. unbroken fraction")
    ax_e.legend(fontsize=8)

fig.tight_layout()
png = out_dir / "fibril_damage.png"
fig.savefig(png, dpi=120)
print(f"wrote {png}")
