#!/bin/bash
# usage: ens.sh NAME K [--set ...]   runs y90 at 57.3*(1+K*1e-12), writes /work/ens/NAME_kK
name=$1; k=$2; shift 2
v=$(python3 -c "print(repr(57.3*(1+$k*1e-12)))")
out=/work/ens/${name}_k$k
cd /work/main && .venv/bin/fabric-fenicsx impact demos/scenes/${SCENE:-y90}.toml --out $out --set projectile.velocity=$v --set output.xdmf_interval=0 --set output.png=false --quiet "$@" > $out.log 2>&1
python3 - $out <<'PY'
import json,sys
s=json.load(open(sys.argv[1]+"/summary.json"))
e=s["energies"]
print(sys.argv[1].split("/")[-1], "v_res %.4f abs %.2f visc %.2f onset %.1f del %s ero %s %s wall %.0f" % (s["residual_velocity"], s["absorbed_energy"], e["viscous_dissipation"], 1e3*s["damage_onset_deflection"], s.get("deleted_cells"), s.get("eroded_cells"), s["end_reason"], s.get("wall_time_s", 0)))
PY
