"""Static material-point scenes from Python: uniaxial strain and equibiaxial strain (thesis 3.3).

One material point of the Zylon AS fabric (Table 1) is stretched along the warp with E2 = 0
(scenario 1, Fig. 3-1) and equally in both directions (scenario 3, Fig. 3-3) until its yarns
have failed completely; the unit cell gives the membrane stresses P1, P2 and the damage
alpha1, alpha2 at each step. The demo prints the key points next to the thesis's values and
saves, per scene, the CSV, the key points (JSON) and a plot in the style of the thesis's
figure. The command line does the same: ``fabric-fenicsx static --scenario NAME --out DIR``.

Run:  python3 demos/demo_static.py [output_dir]      (default output_dir: out/static_demo)
"""
import sys
from pathlib import Path

from fabric_fenicsx.material.fabric import zylon_as
from fabric_fenicsx.studies.static import format_key_points, plot_scenario, run_scenario, write_key_points

STEP = 0.001  # coarser than the CLI's default 0.0005: a quick look (the thesis's points differ by < 1 step)
THESIS = {
    "uniaxial-strain": "thesis: P1 peak at E1 ~ 0.049, warp failure complete at ~ 0.066, fill undamaged",
    "equibiaxial": "thesis: fill damage 0.029 -> 0.0325, warp failure complete at ~ 0.091",
}

out_dir = Path(sys.argv[1]) if len(sys.argv) > 1 else Path("out/static_demo")
out_dir.mkdir(parents=True, exist_ok=True)
fabric = zylon_as("max")
print(fabric.describe())

for name in ("uniaxial-strain", "equibiaxial"):
    result = run_scenario(name, fabric=fabric, step=STEP, progress=False,
                          csv_path=out_dir / f"{name}.csv")
    write_key_points(result, out_dir / f"{name}.json")
    plot_scenario(result, out_dir / f"{name}.png")
    print()
    print(format_key_points(result))
    print(f"  ({THESIS[name]})")
    print(f"  wrote {out_dir / (name + '.png')}")
