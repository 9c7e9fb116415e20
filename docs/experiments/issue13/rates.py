import csv, sys, numpy as np
sys.path.insert(0, "/work/main")
from fabric_fenicsx.studies.divergence import relative_difference, growth_rate, crossing_times
def load(p):
    r = list(csv.DictReader(open(p)))
    return {k: np.array([float(x[k]) for x in r]) for k in r[0]}
for name in sys.argv[1:]:
    try:
        a, b = load(f"d_{name}_k0/history.csv"), load(f"d_{name}_k1/history.csv")
    except FileNotFoundError:
        continue
    n = min(len(a["time"]), len(b["time"]))
    t = a["time"][:n]
    out = []
    for c in ("fabric_kinetic", "projectile_velocity"):
        d = relative_difference(a[c][:n], b[c][:n])
        r = growth_rate(t, d, lo=1e-9, hi=1e-4)
        ct = crossing_times(t, d, (1e-8, 1e-6, 1e-4))
        out.append(f"{c[:8]} e-fold {1e6/r if r else float('nan'):6.1f} us, 1e-8/1e-6/1e-4 at " + "/".join("%.0f" % (x*1e6) if x else "-" for x in ct) + f", end {d[-1]:.1e}")
    print(f"{name:8s}", " | ".join(out))
