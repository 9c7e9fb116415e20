"""The strip test of the strength scatter (fabric_fenicsx.studies.strip, ``study strip``): the
deterministic strip breaks at the material point's uniaxial strength, the scattered strips
are weaker (weakest link), the table is written as the pulls end and an interrupted study
resumes; the statistics on synthetic samples."""
import json
import subprocess
import sys

import numpy as np
import pytest
from scipy.optimize import brentq

from fabric_fenicsx.studies.strip import compare, paired, read_table, weibull_fit
from conftest import mpi_env


def test_weibull_fit_and_two_sample_comparison_on_known_samples():
    rng = np.random.default_rng(3)
    x = 1000.0 * rng.weibull(12.0, 4000)
    m, scale = weibull_fit(x)
    assert m == pytest.approx(12.0, rel=0.05) and scale == pytest.approx(1000.0, rel=0.01)
    same = compare(x[:2000], x[2000:])
    assert abs(same["difference"]) < same["difference_ci95"] and same["welch_p"] > 0.05
    shifted = compare(x[:2000] * 1.05, x[2000:])
    assert shifted["difference"] > shifted["difference_ci95"] and shifted["ks_p"] < 1e-3


def test_two_studies_are_paired_fabric_by_fabric_over_the_seeds_both_pulled():
    rng = np.random.default_rng(5)
    strength = 1000.0 * rng.weibull(12.0, 60)
    a = {s: {"peak_force": float(x)} for s, x in enumerate(strength)}
    b = {s: {"peak_force": float(x) + 5.0 + rng.normal(0.0, 1.0)} for s, x in enumerate(strength[:50])}
    a[-1] = b[-1] = {"peak_force": 1500.0}          # the strip without scatter is no fabric of the pairs
    c = paired(a, b)
    assert c["n"] == 50 and c["correlation"] > 0.99
    assert abs(c["mean_difference"] + 5.0) < c["difference_ci95"] < 1.0     # the offset, resolved by the pairs
    assert c["unpaired"]["difference_ci95"] > 10 * c["difference_ci95"]     # and lost in the fabrics' scatter
    with pytest.raises(ValueError, match="at least 3"):
        paired(a, {0: b[0], 1: b[1]})


def uniaxial_strength(width: float) -> float:
    """The material point's strength (N) across ``width``: P1 at damage onset (mu1 = mu_crit) with
    the fill free of load (P2 = 0), from the default table."""
    from fabric_fenicsx.material.fabric import zylon_as
    from fabric_fenicsx.surrogate.table import Surrogate

    fabric = zylon_as()
    sur = Surrogate(fabric, progress=False)

    def at(E1):
        P2 = lambda e: float(sur.evaluate(E1, e, 1.0, 1.0, tension_only=False)[1])
        E2 = brentq(P2, -0.059, 0.05)
        return sur.evaluate(E1, E2, 1.0, 1.0, tension_only=False)

    E1 = brentq(lambda e: float(at(e)[2]) - fabric.warp.mu_crit, 0.05, 0.065)
    return float(at(E1)[0]) * width


def test_strip_study_strengths_and_resume(tmp_path):
    out = tmp_path / "strip"
    cmd = [sys.executable, "-m", "fabric_fenicsx.cli", "study", "strip", "--seeds", "3", "--sizes", "0.005",
           "--families", "aligned,free", "--jobs", "2", "--out", str(out)]
    proc = subprocess.run(cmd, env=mpi_env(), capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stderr[-3000:]
    report = json.loads((out / "strip.json").read_text())
    strength = uniaxial_strength(0.01)
    for family in ("aligned", "free"):
        rows = read_table(out / f"strip-{family}-5mm.csv")
        assert sorted(rows) == [-1, 0, 1, 2]
        entry = report["meshes"][f"{family} 5 mm"]
        # the clamped ends hold the fill at E2 = 0 where the material point lets it contract: a few %
        assert entry["deterministic"] == pytest.approx(strength, rel=0.05)
        assert entry["n"] == 3 and entry["mean"] < entry["deterministic"]     # weakest link
        assert all(r["damage_dissipation"] > 0 for r in rows.values())
    assert (out / "strip.png").stat().st_size > 0
    before = {p.name: p.read_text() for p in out.glob("*.csv")}
    again = subprocess.run(cmd, env=mpi_env(), capture_output=True, text=True, timeout=900)
    assert again.returncode == 0, again.stderr[-3000:]
    assert {p.name: p.read_text() for p in out.glob("*.csv")} == before     # nothing pulled again
    # the same fabrics torn by the del zone's rule, paired with these: the same strengths
    other = tmp_path / "del_zone"
    proc = subprocess.run([*cmd[:-1], str(other), "--families", "aligned", "--failure", "del_zone_budget",
                           "--against", str(out)], env=mpi_env(), capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stderr[-3000:]
    pair = json.loads((other / "strip.json").read_text())["against"]
    assert pair["label"] == "failure thesis" and list(pair["meshes"]) == ["aligned 5 mm"]
    c = pair["meshes"]["aligned 5 mm"]
    assert c["n"] == 3 and abs(c["mean_difference"]) < 0.01 * report["meshes"]["aligned 5 mm"]["mean"]
    assert "this - failure thesis, 3 fabrics: paired" in proc.stdout


def test_bad_strip_options_stop_before_any_work(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "fabric_fenicsx.cli", "study", "strip", "--sizes", "0.02",
                           "--scatter", "none", "--out", str(tmp_path / "s")],
                          env=mpi_env(), capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2
    assert "--scatter" in proc.stderr and "--sizes" in proc.stderr
    assert not (tmp_path / "s").exists()


def test_the_crack_band_variant_shortens_every_cells_softening_to_one_segments():
    from fabric_fenicsx.material.fabric import zylon_as
    from fabric_fenicsx.material.scatter import StrengthScatter
    from fabric_fenicsx.studies.strip import StripSetup, StripTest

    fabric, scatter = zylon_as(), StrengthScatter("weibull", seed=2)
    plain = StripTest(fabric, "aligned", 0.005).laws(scatter)
    band = StripTest(fabric, "aligned", 0.005, StripSetup(crack_band=True)).laws(scatter)
    assert np.array_equal(band[0], plain[0])
    assert band[1] == pytest.approx(plain[1] * 2 * fabric.warp.w / 0.005, rel=1e-12)


def test_a_crack_rule_breaks_the_strip_at_its_weakest_segment_as_the_thesiss_rule_does():
    """A strip breaks at its weakest segment whichever rule tears it afterwards: the del zone's
    rule (``failure``) leaves the peak force where the thesis's rule puts it, and it is the rule
    that tears the strip: its cells break through with one segment's work per yarn, so the
    strip dissipates less than under each point's own softening."""
    from fabric_fenicsx.material.fabric import zylon_as
    from fabric_fenicsx.material.scatter import DamageRange, StrengthScatter
    from fabric_fenicsx.studies.strip import StripSetup, StripTest
    from fabric_fenicsx.surrogate.table import Surrogate

    fabric, scatter = zylon_as(), StrengthScatter("weibull", seed=1)
    thesis = StripTest(fabric, "aligned", 0.005)
    del_zone = StripTest(fabric, "aligned", 0.005, StripSetup(failure="del_zone_budget"))
    laws = thesis.laws(scatter)
    assert np.array_equal(del_zone.laws(scatter)[0], laws[0])
    assert thesis.crack_rule(laws) is None and thesis.damage_range(scatter, None) is None
    surrogate = Surrogate(fabric, progress=False, workers=1,
                          damage_range=DamageRange.union(thesis.damage_range(scatter, laws),
                                                         del_zone.damage_range(scatter, laws)))
    a, b = thesis.pull(surrogate, laws), del_zone.pull(surrogate, laws)
    assert b["peak_force"] == pytest.approx(a["peak_force"], rel=0.01)
    assert b["strain_at_peak"] == pytest.approx(a["strain_at_peak"], rel=0.02)
    assert b["damage_dissipation"] < 0.7 * a["damage_dissipation"]
    with pytest.raises(ValueError, match="yarn_average"):
        StripSetup(failure="yarn_average")


def test_a_strip_study_into_a_folder_of_other_options_is_refused(tmp_path):
    out = tmp_path / "s"
    out.mkdir()
    from dataclasses import asdict

    from fabric_fenicsx.studies.strip import StripSetup

    kept = {"scatter": "weibull", **asdict(StripSetup())}
    (out / "strip-setup.json").write_text(json.dumps(kept))
    cmd = [sys.executable, "-m", "fabric_fenicsx.cli", "study", "strip", "--out", str(out)]
    proc = subprocess.run(cmd + ["--failure", "del_zone_budget"], env=mpi_env(), capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 2
    assert "failure 'thesis' -> 'del_zone_budget'" in proc.stderr and "another --out" in proc.stderr
    assert sorted(p.name for p in out.iterdir()) == ["strip-setup.json"]
    bad = subprocess.run(cmd + ["--failure", "yarn_average"], env=mpi_env(), capture_output=True, text=True,
                         timeout=120)
    assert bad.returncode == 2 and "--failure must be thesis or one of" in bad.stderr
    empty = tmp_path / "empty"
    empty.mkdir()
    lonely = subprocess.run(cmd + ["--against", str(empty)], env=mpi_env(), capture_output=True, text=True,
                            timeout=120)
    assert lonely.returncode == 2 and "holds no strip table of these meshes" in lonely.stderr
