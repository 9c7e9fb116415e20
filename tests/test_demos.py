"""Every ``demos/demo_*.py`` runs to completion as a script, serially, from any directory.

Each demo gets an output directory as argv[1] and must write something there; the demos are
started in the background when the session begins (tests/conftest.py, BackgroundDemos). A
demo that is meant for ``mpirun`` must still run serially; none is skipped. What a demo computes is then checked against expectations found independently of the code
under test (CHECKS: the thesis's numbers, closed forms, a stored converged run, balances).
"""

from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DEMOS = sorted((ROOT / "demos").glob("demo_*.py"))


def test_there_are_demos():
    assert DEMOS, f"no demos/demo_*.py under {ROOT}"


@pytest.mark.parametrize("demo", DEMOS, ids=[d.stem for d in DEMOS])
def test_demo_runs(demo, background_demos):
    """The demo was started when the session began (tests/conftest.py, BackgroundDemos), in a
    folder of its own, with an output directory as argv[1]."""
    returncode, stdout, stderr, out = background_demos.result(demo)
    assert returncode == 0, (
        f"{demo.name} exited with {returncode}\n--- stdout\n{stdout[-3000:]}\n--- stderr\n{stderr[-3000:]}")
    written = [p for p in out.rglob("*") if p.is_file()] if out.exists() else []
    assert written, f"{demo.name} wrote nothing into its output directory {out}"
    assert demo.stem in CHECKS, f"{demo.name} has no check of what it computes in CHECKS"
    CHECKS[demo.stem](out, stdout)


def _csv(path):
    import csv
    with open(path) as f:
        return list(csv.DictReader(f))


def check_weak_form(out, stdout):
    """Both shear terms store energy, shorten the time step and keep the balance within 1 %."""
    rows = {r["term"]: r for r in _csv(out / "weak_form_demo.csv")}
    assert set(rows) == {"none", "IsotropicShear", "TrellisShear"}
    assert float(rows["none"]["term_energy_J"]) == 0.0
    for name in ("IsotropicShear", "TrellisShear"):
        assert float(rows[name]["term_energy_J"]) > 0.0
        assert float(rows[name]["dt"]) < float(rows["none"]["dt"])
        assert float(rows[name]["velocity_at_end"]) < float(rows["none"]["velocity_at_end"])
    assert all(float(r["energy_error"]) < 0.01 for r in rows.values())


def check_explicit_loop(out, stdout):
    """The hand-written loop slows the projectile and keeps the energy balance within 1 %."""
    rows = _csv(out / "explicit_loop.csv")
    assert max(float(r["energy_error"]) for r in rows) < 0.01
    assert 0.0 < float(rows[-1]["projectile_velocity"]) < 0.9 * 20.0


def _png(path):
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", path


def check_ballistic_limit(out, stdout):
    """The stand-in's 40 shots (V50 = 38 m/s, sigma = 6.5 m/s, Lambert-Jonas 0.95, 2, 30 m/s):
    every 95 % interval of the report covers its true value (a fixed seed: this draw), V10 and
    V90 lie 1.2816 sigma either side of V50, the design went through its three phases, and the
    binned fractions rise from none to most."""
    import json
    rep = json.loads((out / "v50.json").read_text())
    p, lj = rep["probit"], rep["lambert_jonas"]
    for name, true in (("v50", 38.0), ("sigma", 6.5), ("v10", 38.0 - 1.2816 * 6.5), ("v90", 38.0 + 1.2816 * 6.5)):
        lo, hi = p[f"{name}_ci"]
        assert lo < true < hi, (name, lo, true, hi)
    assert p["v90"] - p["v50"] == pytest.approx(1.2815515655446004 * p["sigma"])
    for name, true in (("a", 0.95), ("p", 2.0), ("vbl", 30.0)):
        lo, hi = lj[f"{name}_ci"]
        assert lo <= true <= hi, (name, lo, true, hi)
    assert rep["runs"] == 40 and rep["answer"] == "v50" and rep["monotone"]
    assert rep["bins"][0]["fraction"] < 0.2 and rep["bins"][-1]["fraction"] > 0.8
    assert "d-optimal" in stdout and "V50" in stdout
    _png(out / "v50.png")


def check_impact(out, stdout):
    """Y90 at 123.69 m/s on the coarse 4 mm mesh: a perforation (0 < v_res < V0); the absorbed
    energy is the projectile's loss of kinetic energy (37.1 g); the projectile's momentum loss
    is the impulse of the contact force in history.csv (within 3 %: sampled every microsecond);
    the energy balance holds within 1 %; what the demo prints is what summary.json holds.
    Not checked: the value of v_res against a converged run. The tearing phase is not yet
    mesh-converged (the mesh-independence study, docs/mesh_independence.md); the reduced element moved this coarse
    run from 116 m/s (2 x 2 points) to 98 m/s."""
    import json
    s = json.loads((out / "summary.json").read_text())
    v0, v = s["v0"], s["residual_velocity"]
    assert v0 == 123.69 and s["perforated"] and s["end_reason"] == "perforated"
    assert 0.0 < v < v0, v
    assert s["absorbed_energy"] == pytest.approx(0.5 * 0.0371 * (v0 ** 2 - v ** 2), rel=1e-9)
    assert s["energy_error"] < 0.01
    assert s["deleted_cells"] + s["eroded_cells"] > 0
    rows = _csv(out / "history.csv")
    t = [float(r["time"]) for r in rows]
    f = [float(r["contact_force"]) for r in rows]
    impulse = sum(0.5 * (f[k] + f[k + 1]) * (t[k + 1] - t[k]) for k in range(len(t) - 1))
    assert impulse == pytest.approx(0.0371 * (v0 - v), rel=0.03)
    assert f"residual velocity {v:7.2f} m/s" in stdout
    assert (out / "impact.xdmf").stat().st_size > 0          # its format: tests/impact/test_output.py
    _png(out / "velocity_history.png")
    _png(out / "damage_map.png")


def check_static(out, stdout):
    """The thesis's key points (Sec. 3.3) within one strain step of the demo (0.001) plus the
    issue's tolerance, and the strain paths the scenarios prescribe."""
    import json
    uni = json.loads((out / "uniaxial-strain.json").read_text())
    assert uni["peak_P1"]["E1"] == pytest.approx(0.049, abs=0.003)
    assert uni["peak_P1"]["P1"] == pytest.approx(148e3, rel=0.01)
    assert uni["complete_failure"]["warp"] == pytest.approx(0.066, abs=0.004)
    assert uni["damage_onset"]["fill"] is None
    equi = json.loads((out / "equibiaxial.json").read_text())
    assert equi["damage_onset"]["fill"] == pytest.approx(0.029, abs=0.003)
    assert equi["complete_failure"]["fill"] == pytest.approx(0.0325, abs=0.003)
    assert equi["complete_failure"]["warp"] == pytest.approx(0.091, abs=0.004)
    for name, e2_over_e1 in (("uniaxial-strain", 0.0), ("equibiaxial", 1.0)):
        rows = _csv(out / f"{name}.csv")
        E1 = [float(r["E1"]) for r in rows]
        assert all(abs(b - a - 0.001) < 1e-12 for a, b in zip(E1, E1[1:]))
        assert all(float(r["E2"]) == pytest.approx(e2_over_e1 * float(r["E1"]), abs=1e-12) for r in rows)
        _png(out / f"{name}.png")
    assert "peak of P1" in stdout


def check_fibril(out, stdout):
    """d0/h0 of each yarn is the closed form that puts the most misaligned fibril's rupture at
    mu_crit + 0.03 (Eq. 2-22 at r = 1); the printed fitted beta is the least-squares beta
    found here independently (scipy's bounded scalar minimiser on a brute-force bundle of the
    same draws, Eq. 2-22/2-23), and its fit beats the thesis's beta = 124."""
    import numpy as np
    from scipy.optimize import minimize_scalar
    rows = {}
    for line in stdout.splitlines():
        parts = line.split()
        if len(parts) == 6 and parts[0] in ("warp", "fill", "virgin"):
            rows[parts[0]] = [float(x) for x in parts[1:]]
    assert set(rows) == {"warp", "fill", "virgin"}
    for name, (mu_crit, d0, beta, rms, rms_124) in rows.items():
        top = mu_crit + 0.03
        assert d0 == pytest.approx(np.sqrt((top ** 2 - mu_crit ** 2) / (mu_crit ** 2 - 1)), abs=1e-4)
        x = np.random.default_rng(0).random(20000) * np.sqrt((top ** 2 - mu_crit ** 2) / (mu_crit ** 2 - 1))
        rupture = np.sqrt(mu_crit ** 2 + x ** 2 * (mu_crit ** 2 - 1))   # U_j = mu_crit (Eq. 2-22)
        mu = np.linspace(mu_crit, top, 601)
        alpha = (mu[:, None] < rupture).mean(axis=1)
        s = mu - mu_crit

        def rms_of(b):
            law = (np.exp(-b * s) - np.exp(-b * 0.03)) / (1 - np.exp(-b * 0.03))
            return np.sqrt(np.mean((law - alpha) ** 2))

        best = minimize_scalar(rms_of, bounds=(1.0, 1000.0), method="bounded", options={"xatol": 1e-6})
        assert beta == pytest.approx(best.x, abs=0.02), name
        assert rms == pytest.approx(best.fun, abs=1e-4) and rms_124 == pytest.approx(rms_of(124.0), abs=1e-4)
        assert rms < rms_124
    _png(out / "fibril_damage.png")


def check_smith(out, stdout):
    """Smith's closed form, written here (V = c sqrt(2 eps sqrt(eps (1 + eps)) - eps^2),
    U = c (sqrt(eps (1 + eps)) - eps), W = c sqrt(eps / (1 + eps))), matches the demo's
    theory columns; the simulation is within the README's 0.6 % on every mesh at Courant
    0.9, and at Courant 1.0 the longitudinal front's dispersion error is smaller."""
    import numpy as np
    from scipy.optimize import brentq
    rows = _csv(out / "smith_convergence.csv")
    assert len(rows) == 8
    c = np.sqrt(5.0e5 / 0.158)
    for r in rows:
        V = float(r["V"])
        eps = brentq(lambda e: c * np.sqrt(2 * e * np.sqrt(e * (1 + e)) - e * e) - V, 1e-9, 0.5, xtol=1e-15)
        assert float(r["c_theory"]) == pytest.approx(c, rel=1e-12)
        assert float(r["strain_theory"]) == pytest.approx(eps, rel=1e-9)
        assert float(r["U_theory"]) == pytest.approx(c * (np.sqrt(eps * (1 + eps)) - eps), rel=1e-9)
        assert float(r["W_theory"]) == pytest.approx(c * np.sqrt(eps / (1 + eps)), rel=1e-9)
        for sim, th in (("strain_sim", "strain_theory"), ("c_sim", "c_theory"), ("U_sim", "U_theory"),
                        ("W_sim", "W_theory")):
            assert abs(float(r[sim]) / float(r[th]) - 1) < 0.006, (V, r["n_elements"], sim)
    for V in ("75.0", "175.0"):
        at = {float(r["dt_safety"]): r for r in rows if r["V"] == V and r["n_elements"] == "1600"}
        assert float(at[1.0]["err_longitudinal_speed"]) < float(at[0.9]["err_longitudinal_speed"])
    for name in ("smith_profiles.png", "smith_convergence.png"):
        _png(out / name)


def check_scatter(out, stdout):
    """The segments' median critical strain is the thesis's (within 3 sampling sd); a square cell
    of size h touches on average (h / s1 + 1)(h / s2 + 1) segments (s1, s2 the segment length
    and the yarn spacing) and takes the weakest, so its mean is the segments' mean x n^(-1/m)
    (the weakest link of n Weibull variables, m = 11.7) within 3 %, and larger cells scatter
    less."""
    import re
    rows = _csv(out / "scatter.csv")
    median = float(re.search(r"median segment strain ([0-9.]+)", stdout).group(1))
    seg = rows[0]
    n, mean0, sd0 = int(seg["cells"]), float(seg["mean_strain"]), float(seg["sd_strain"])
    assert median == pytest.approx(0.025, abs=3 * 1.2533 * sd0 / n ** 0.5)
    from fabric_fenicsx.material.fabric import zylon_as
    s1, s2 = 2e3 * zylon_as().warp.w, 2e3 * zylon_as().fill.w     # segment length, yarn spacing (mm)
    for r in rows[1:]:
        h = float(r["cell_mm"])
        n = (h / s1 + 1.0) * (h / s2 + 1.0)
        assert float(r["mean_strain"]) == pytest.approx(mean0 * n ** (-1 / 11.7), rel=0.03)
    sds = [float(r["sd_strain"]) for r in rows[1:]]
    assert sds == sorted(sds, reverse=True)
    _png(out / "scatter_field.png")


def check_tear(out, stdout):
    """With the thesis's rule, on the grid along the yarns the tear runs straight across the load
    (90 degrees from the warp) and through, on the grid turned 30 degrees it follows the rows of
    cells, 30 degrees off, at another load (docs/tear_test.md); with the yarn crack it runs across
    the load on both."""
    import re
    found = {(m.group(1), m.group(2)): (float(m.group(3)), float(m.group(4))) for m in re.finditer(
        r"^\s*(\w+)\s+(\w+): tear load\s+([0-9.]+) N, work\s+[0-9.na]+ J/m, path\s+([0-9.na]+) deg", stdout,
        re.MULTILINE)}
    assert set(found) == {(r, f) for r in ("thesis", "yarn_crack") for f in ("aligned", "structured30")}, stdout
    assert found[("thesis", "aligned")][1] == pytest.approx(90.0, abs=1.0) and "torn through" in stdout
    assert abs(found[("thesis", "structured30")][1] - 90.0) > 10.0
    assert found[("thesis", "structured30")][0] < found[("thesis", "aligned")][0]
    for family in ("aligned", "structured30"):
        assert found[("yarn_crack", family)][1] == pytest.approx(90.0, abs=5.0)
    _png(out / "tear.png")


CHECKS = {"demo_tear": check_tear, "demo_scatter": check_scatter, "demo_weak_form": check_weak_form, "demo_explicit_loop": check_explicit_loop,
          "demo_impact": check_impact, "demo_static": check_static, "demo_fibril": check_fibril,
          "demo_smith": check_smith, "demo_ballistic_limit": check_ballistic_limit}
