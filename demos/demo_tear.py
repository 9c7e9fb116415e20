"""The tear test (fabric_fenicsx.studies.tear): does a tear follow the yarns or the cells?

A 60 x 60 mm panel of Zylon AS, warp along x, with a 10 mm slit from its bottom edge across the
warp, is pulled along the warp at 5 m/s until the tear runs. The same panel is meshed with
2 mm squares along the yarns (aligned) and with 2 mm squares turned 30 degrees from them
(structured30), and torn with two failure rules. A tear in a fabric runs along the fill yarns,
straight across the load (90 degrees from x). With the thesis's rule (every point damages by
Eq. 2-25 on its own strains) the tear on the turned mesh follows the rows of cells instead, at
another load: the mesh bias that the ballistic limit inherits. With the yarn crack
(fabric_fenicsx.fem.yarn_crack: a broken warp tears along the fill, with one yarn segment's
energy per yarn cut) it runs along the fill on both meshes (docs/tear_test.md). About a minute.

Run:  python3 demos/demo_tear.py [output_dir]      (default output_dir: out/tear)
Writes ``tear.png`` (the four panels, cells coloured by the warp's alpha) and prints, per rule
and mesh, the tear load (N), the work per unit length of tear (J/m) and the path's angle from
the warp.
"""
import sys
from pathlib import Path

from fabric_fenicsx.material.fabric import zylon_as
from fabric_fenicsx.studies.tear import TearSetup, TearTest
from fabric_fenicsx.studies.tear_report import plot_paths
from fabric_fenicsx.surrogate.table import Surrogate

out_dir = Path(sys.argv[1]) if len(sys.argv) > 1 else Path("out/tear")
out_dir.mkdir(parents=True, exist_ok=True)
fabric = zylon_as()
cells = {}
for failure in ("thesis", "yarn_crack"):
    for family in ("aligned", "structured30"):
        test = TearTest(fabric, family, 0.002, TearSetup(failure=failure))
        surrogate = Surrogate(fabric, progress=False, workers=1, damage_range=test.damage_range())
        result = test.pull(surrogate)
        cells[(f"{failure} {family}", 0.002)] = result["cells"]
        print(f"{failure:>10} {family:>13}: tear load {result['tear_load']:7.1f} N, work "
              f"{result['work_per_length']:6.2f} J/m, path {result['path_angle']:5.1f} deg from the warp "
              f"({result['end']})")
plot_paths(cells, out_dir / "tear.png", "2 mm cells along the yarns and turned 30 degrees: thesis's rule, yarn crack")
print(f"picture: {out_dir / 'tear.png'}")
