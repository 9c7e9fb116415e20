"""The ballistic limit as ballistic testing estimates it (fabric_fenicsx.studies: neyer, probit,
lambert_jonas), on a stand-in: shots drawn from a known probability of perforation instead of
impact runs, so that the estimate can be checked against the truth in a few seconds.

The stand-in fabric perforates at v with probability Phi((v - 38) / 6.5) (V50 = 38 m/s,
sigma = 6.5 m/s, what `fabric-fenicsx v50` measured for Y90 on the make-demo mesh) and a
perforating shot leaves at the Lambert-Jonas velocity 0.95 (v^2 - 30^2)^(1/2) with 3 m/s of
scatter. Forty shots, two at a time, chosen by Neyer's D-optimal design from the bracket 20-60
m/s; then the probit fit with profile-likelihood intervals, the fraction perforated per bin and
the Lambert-Jonas fit, as the command reports them for impact runs. No DOLFINx, no impact run.

Run:  python3 demos/demo_ballistic_limit.py [output_dir]      (default output_dir: out/ballistic_limit)
Writes ``v50.png`` (the command's plot) and ``v50.json`` (its report), and prints the report
with the true values beside it.
"""
import json
import sys
from pathlib import Path

import numpy as np
from scipy.stats import norm

from fabric_fenicsx.studies import v50
from fabric_fenicsx.studies.lambert_jonas import residual_velocity
from fabric_fenicsx.studies.neyer import NeyerDesign, Shot

TRUE_V50, TRUE_SIGMA, TRUE_LJ = 38.0, 6.5, (0.95, 2.0, 30.0)

out_dir = Path(sys.argv[1]) if len(sys.argv) > 1 else Path("out/ballistic_limit")
out_dir.mkdir(parents=True, exist_ok=True)
rng = np.random.default_rng(2024)
design, rows = NeyerDesign(20.0, 60.0), []
while len(rows) < 40:
    shots = [Shot(r["velocity"], r["outcome"] == "perforated") for r in rows]
    phase = design.phase(shots)
    for v in design.next(shots, 2):
        through = rng.random() < norm.cdf((v - TRUE_V50) / TRUE_SIGMA)
        vr = max(float(residual_velocity(v, *TRUE_LJ)) + rng.normal(0.0, 3.0), 0.1) if through else -0.01
        rows.append({"run": len(rows), "velocity": v, "outcome": "perforated" if through else "held",
                     "residual_velocity": vr, "phase": phase, "wall_time_s": 0.0})

rep = v50.report(rows, "40 shots", "stand-in")
(out_dir / "v50.json").write_text(json.dumps(rep, indent=1))
v50.plot(rep, rows, out_dir / "v50.png", title="stand-in: V50 = 38 m/s, sigma = 6.5 m/s, 40 shots")
print(v50.format_report(rep))
print(f"true: V50 {TRUE_V50} m/s, sigma {TRUE_SIGMA} m/s, V10 {TRUE_V50 - 1.2816 * TRUE_SIGMA:.2f} m/s, "
      f"V90 {TRUE_V50 + 1.2816 * TRUE_SIGMA:.2f} m/s; Lambert-Jonas a {TRUE_LJ[0]}, p {TRUE_LJ[1]}, "
      f"Vbl {TRUE_LJ[2]} m/s")
print("phases: " + ", ".join(f"{p} {sum(r['phase'] == p for r in rows)}" for p in ("bracket", "overlap", "d-optimal")))
