"""Stand-in runs for the ballistic-limit study (``study v50``) of the process-pool and the
cluster tests, and what the study must report for them."""
import csv
import json
import random
import sys
from pathlib import Path

from fabric_fenicsx.studies import chapter4
from fabric_fenicsx.studies.probit import fit_probit


def stand_in_limits(run, out):
    """A stand-in for an impact run of the ballistic-limit study: Y90 and XY0 perforate above
    37 + 2 z m/s (z a standard normal number drawn from the run's scene and key: a probit curve
    with V50 37 m/s and sigma 2 m/s), Y0 above 41 m/s exactly, XY45 fails."""
    v = float([o for o in run.overrides if o.startswith("projectile.velocity=")][-1].split("=")[1])
    scene = Path(run.scene).stem.upper()
    if scene == "XY45":
        return [sys.executable, "-c", "import sys; print('stand-in failure'); sys.exit(1)"]
    limit = 41.0 if scene == "Y0" else 37.0 + 2.0 * random.Random(f"{scene} {run.key}").gauss(0.0, 1.0)
    summary = dict(residual_velocity=v - limit, absorbed_energy=1.0, wall_time_s=1.0,
                   end_reason="perforated" if v > limit else "held", perforated=v > limit)
    return [sys.executable, "-c", f"import json; open({str(out / 'summary.json')!r}, 'w').write({json.dumps(summary)!r})"]


def check_stand_in_limits(limits: dict, out, max_runs: int) -> None:
    """What ``study v50`` must report for the stand-in runs of :func:`stand_in_limits`."""
    for scene in ("Y90", "XY0"):
        rep = limits[scene]
        assert 2 <= rep["runs"] == len(rep["rows"]) <= max_runs and rep["counts"]["failed"] == 0
        assert rep["start"] in ([34.5, 39.78], list(chapter4.V50_BRACKET))
        with open(out / "v50" / scene / "v50.csv") as f:
            table = list(csv.DictReader(f))
        assert [int(r["run"]) for r in table] == list(range(rep["runs"]))
        v = [float(r["velocity"]) for r in table]
        assert fit_probit(v, [r["outcome"] == "perforated" for r in table]).v50 == rep["probit"]["v50"]
        assert min(v) < rep["probit"]["v50"] < max(v) and rep["probit"]["width"] > 0
    y0 = limits["Y0"]                      # a sharp limit: no probit fit, the bracket of the outcomes
    assert y0["probit"] is None and y0["bracket"][0] <= 41.0 < y0["bracket"][1]
    xy45 = limits["XY45"]                  # every run failed: stopped after four, none counted
    assert xy45["runs"] == xy45["counts"]["failed"] == 4 and "counted no outcome" in xy45["stop"]
    assert "stand-in failure" in xy45["rows"][0]["error"]
