#!/bin/bash
# usage: [RUNNER=...] pair.sh NAME [--set ...]: damage off to 0.8 ms, k=0 and k=1, then growth
# report. RUNNER (default .venv/bin/fabric-fenicsx) runs the twins with a patched material, e.g.
# RUNNER=".venv/bin/python /work/ens/patched_branch_relaxed.py" for material (c).
name=$1; shift
RUNNER=${RUNNER:-.venv/bin/fabric-fenicsx}
for k in 0 1; do
v=$(python3 -c "print(repr(57.3*(1+$k*1e-12)))")
(cd /work/main && $RUNNER impact demos/scenes/y90.toml --out /work/ens/d_${name}_k$k --set projectile.velocity=$v --set output.xdmf_interval=0 --set output.png=false --quiet --set material.damage=false --set run.t_end=0.0008 --set mesh.h_centre=0.004 "$@" > /work/ens/d_${name}_k$k.log 2>&1) &
done
wait
python3 - $name <<'PY'
import csv, sys, numpy as np
name=sys.argv[1]
def load(p):
    r=list(csv.DictReader(open(p)))
    return {k: np.array([float(x[k]) for x in r]) for k in r[0]}
a=load(f"/work/ens/d_{name}_k0/history.csv"); b=load(f"/work/ens/d_{name}_k1/history.csv")
n=min(len(a["time"]),len(b["time"]))
out=[name]
for key in ["fabric_kinetic","projectile_velocity"]:
    d=np.abs(a[key][:n]-b[key][:n]); s=np.abs(a[key][:n]).max()
    ts=[]
    for thr in [1e-12,1e-10,1e-8,1e-6,1e-4]:
        i=np.argmax(d>thr*s); ts.append("%.0f"%(a["time"][i]*1e6) if d[i]>thr*s else "-")
    out.append(key[:8]+" "+"/".join(ts)+" final rel %.1e"%(d[-1]/s))
print(" | ".join(out))
PY
