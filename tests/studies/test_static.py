"""Static material-point scenes (thesis chapter 3) on the unit cell, and their command line.

The thesis's numbers (section 3.3) are checked with the tolerances of the project's issue;
nothing in the model is tuned to them.
"""

import csv
import json
import sys
from types import SimpleNamespace

import numpy as np
import pytest

from fabric_fenicsx.studies import static
from fabric_fenicsx.cli import main
from fabric_fenicsx.material.fabric import zylon_as
from fabric_fenicsx.studies.static import SCENARIOS, run_scenario
from fabric_fenicsx.material.unitcell import UnitCell

STEP = 0.0005


@pytest.fixture(scope="module")
def s1():
    return run_scenario("uniaxial-strain", progress=False)


@pytest.fixture(scope="module")
def s2():
    return run_scenario("load-unload", progress=False)


@pytest.fixture(scope="module")
def s3():
    return run_scenario("equibiaxial", progress=False)


@pytest.fixture(scope="module")
def bending():
    return run_scenario("bending", progress=False)


def _upper(bending):
    """Scenario 4 proper: the bending scene's run with B2 at the upper bound (Fig. 3-5)."""
    return bending.select("B2", bending.key_points["B2_upper"]["B2"])


# ----------------------------------------------------------------------------- scenario 1
def test_scenario1_peak_and_complete_warp_failure(s1):
    kp = s1.key_points
    assert kp["peak_P1"]["E1"] == pytest.approx(0.049, abs=0.002)
    assert kp["complete_failure"]["warp"] == pytest.approx(0.066, abs=0.003)
    # The peak of P1 marks the onset of warp damage (section 3.3.1).
    assert abs(kp["damage_onset"]["warp"] - kp["peak_P1"]["E1"]) <= STEP + 1e-12
    # The fill is never damaged, but P2 peaks with P1 (coupling through V).
    assert np.all(s1.data["alpha2"] == 1.0)
    assert kp["damage_onset"]["fill"] is None
    assert abs(kp["peak_P2"]["E1"] - kp["peak_P1"]["E1"]) <= STEP + 1e-12
    assert not kp["cap_reached"]


def test_scenario1_grid_and_tail(s1):
    E1 = s1.data["E1"]
    np.testing.assert_allclose(E1, STEP * np.arange(E1.size), rtol=0, atol=1e-15)
    broken = np.flatnonzero(s1.data["alpha1"] == 0.0)
    assert broken.size == static.EXTRA_STEPS + 1 and broken[-1] == E1.size - 1
    assert np.all(s1.data["P1"][broken] == 0.0) and np.all(s1.data["V"][broken] == 0.0)
    assert np.all(np.diff(s1.data["alpha1"]) <= 0.0)  # damage never heals


# ----------------------------------------------------------------------------- scenario 2
def test_scenario2_unloads_to_origin_and_reload_rejoins(s2, s1):
    """Tolerance 1e-6 of the peak P1 (~0.15 N/m): the unit cell is solved to a scaled residual of
    1e-12 and alpha to 1e-10, and at zero strain the discrete reference state is exactly
    stress-free, so the only differences left come from solver tolerances."""
    kp = s2.key_points
    tol = 1e-6 * kp["peak_P1"]["P1"]
    assert 0.0 < kp["unload_at"]["alpha1"] < 1.0  # partial damage at the unloading point
    assert abs(kp["residual_P1_at_zero_strain"]) < tol
    assert abs(kp["residual_P2_at_zero_strain"]) < tol
    assert kp["reload_max_deviation_P1"] < tol
    assert kp["reload_retrace_max_deviation_P1"] < tol  # reloading retraces the unloading path
    # The first loading and the monotone reference are the same path; the envelope of
    # load + reload has scenario 1's key points.
    assert kp["peak_P1"] == pytest.approx(s1.key_points["peak_P1"], rel=1e-9)
    assert kp["complete_failure"] == s1.key_points["complete_failure"]


def test_scenario2_legs(s2):
    load, unload, reload = (s2.select("leg", leg) for leg in static.LEGS)
    assert load["E1"][-1] == pytest.approx(static.UNLOAD_E1) and unload["E1"][-1] == 0.0
    a_u = load["alpha1"][-1]
    assert np.all(unload["alpha1"] == a_u)  # no damage while unloading
    below = reload["E1"] <= static.UNLOAD_E1 + 1e-12
    assert np.all(reload["alpha1"][below] == a_u)  # none either before the previous maximum
    assert reload["alpha1"][-1] == 0.0
    # The unloading path lies below the first loading path (damaged, softer yarn).
    inner = (unload["E1"] > 0.0) & (unload["E1"] < 0.045)
    P_first = np.interp(unload["E1"][inner], load["E1"], load["P1"])
    assert np.all(unload["P1"][inner] < P_first)


# ----------------------------------------------------------------------------- scenario 3
def test_scenario3_fill_then_warp_failure(s3):
    kp = s3.key_points
    assert kp["damage_onset"]["fill"] == pytest.approx(0.029, abs=0.002)
    assert kp["complete_failure"]["fill"] == pytest.approx(0.0325, abs=0.002)
    assert kp["complete_failure"]["warp"] == pytest.approx(0.091, abs=0.003)
    # Two peaks of P1, one of P2; the first P1 peak is the P2 peak (fill damage onset), the
    # second marks warp damage onset (section 3.3.3).
    assert len(kp["peaks_P1"]) == 2 and len(kp["peaks_P2"]) == 1
    assert abs(kp["peaks_P1"][0]["E1"] - kp["peaks_P2"][0]["E1"]) <= STEP + 1e-12
    assert abs(kp["peaks_P1"][1]["E1"] - kp["damage_onset"]["warp"]) <= STEP + 1e-12
    np.testing.assert_allclose(s3.data["E2"], s3.data["E1"], rtol=0, atol=1e-14)


# ----------------------------------------------------------------------------- scenario 4
def test_scenario4_contracts_then_expands_back(bending):
    d = _upper(bending)
    E1, E2, a1 = d["E1"], d["E2"], d["alpha1"]
    peak = np.max(np.abs(d["P1"]))
    assert np.max(np.abs(d["P2"])) < 1e-9 * peak  # the fill is free
    intact = (E1 > 0) & (a1 == 1.0)
    assert np.all(E2[intact] < 0.0)
    assert np.all(np.diff(E2[a1 == 1.0]) < 0.0)  # contracting while the warp is intact
    alive = a1 > 0.0
    j = int(np.argmin(np.where(alive, E2, np.inf)))
    onset = E1[np.flatnonzero(a1 < 1.0)[0]]
    assert abs(E1[j] - onset) <= 2 * STEP + 1e-12  # turns where warp damage starts ...
    last = np.flatnonzero(alive)[-1]
    assert np.all(np.diff(E2[j:last + 1]) > 0.0)  # ... and expands back from there
    assert E2[last] - E2[j] > 0.2 * abs(E2[j])


def test_bending_lower_bound_softer_early_then_converges(bending):
    up, lo = bending.select("B2", bending.key_points["B2_upper"]["B2"]), \
        bending.select("B2", bending.key_points["B2_lower"]["B2"])
    assert bending.key_points["B2_lower"]["B2"] == pytest.approx(zylon_as("min").fill.B0)
    early = (up["E1"] > 0.0) & (up["E1"] <= 0.03)
    P_lo = np.interp(up["E1"][early], lo["E1"], lo["P1"])
    assert np.all(P_lo < up["P1"][early])
    cmp = bending.key_points["P1_lower_over_upper"]
    gap_early = 1.0 - cmp["E1_0.01"]["ratio"]
    gap_peak = abs(1.0 - cmp["upper_peak"]["ratio"])
    assert gap_early > 0.2
    assert gap_peak < 0.05 and gap_peak < 0.1 * gap_early


# ----------------------------------------------------------------------------- any backend
class _ExplicitE2Only:
    """The unit cell without free-fill support: scenes must root-find P2 = 0 themselves."""

    def __init__(self, fabric):
        self.cell = UnitCell(fabric)

    def respond(self, E1, E2, alpha_hist):
        if E2 is None:
            raise AssertionError("E2=None used on a material point that does not support it")
        return self.cell.respond(E1, E2, alpha_hist=alpha_hist)


def test_free_fill_root_find_matches_native():
    """The generic P2 = 0 root find follows the same branch as the unit cell's own free-fill
    solve, through warp damage and the jump to complete failure."""
    step = 0.002
    native = run_scenario("uniaxial-stress", step=step, progress=False)
    generic = run_scenario("uniaxial-stress", step=step, backend=_ExplicitE2Only, progress=False)
    assert len(native) == len(generic)
    peak = native.key_points["peak_P1"]["P1"]
    np.testing.assert_allclose(generic.data["E2"], native.data["E2"], rtol=0, atol=1e-9)
    np.testing.assert_allclose(generic.data["P1"], native.data["P1"], rtol=0, atol=1e-6 * peak)
    assert np.max(np.abs(generic.data["P2"])) < 1e-6 * peak
    assert generic.key_points["complete_failure"] == native.key_points["complete_failure"]


class _Linear:
    """An undamageable linear material point: P1 = k (E1 + nu E2), P2 = k (E2 + nu E1)."""

    def __init__(self, nu=0.3, k=1e5, fail_after=None):
        self.nu, self.k, self.calls, self.fail_after = nu, k, 0, fail_after

    def respond(self, E1, E2, alpha_hist):
        self.calls += 1
        if self.fail_after is not None and self.calls > self.fail_after:
            raise KeyboardInterrupt
        return SimpleNamespace(E2=E2, P1=self.k * (E1 + self.nu * E2), P2=self.k * (E2 + self.nu * E1),
                               V=0.0, alpha1=alpha_hist[0], alpha2=alpha_hist[1])


def test_free_fill_root_find_analytic():
    r = static.respond_free_fill(_Linear(nu=0.3), 0.04, (1.0, 1.0), E2_guess=0.0)
    assert r.E2 == pytest.approx(-0.3 * 0.04, abs=1e-12)


def test_cap_is_reported_when_nothing_fails():
    res = run_scenario("uniaxial-stress", step=0.01, backend=_Linear(), progress=False)
    assert res.key_points["cap_reached"]
    assert res.data["E1"][-1] == pytest.approx(static.E1_CAP)
    np.testing.assert_allclose(res.data["E2"], -0.3 * res.data["E1"], atol=1e-12)
    assert "cap" in static.format_key_points(res)


def test_interrupted_run_keeps_its_rows(tmp_path):
    path = tmp_path / "s.csv"
    with pytest.raises(KeyboardInterrupt):
        run_scenario("uniaxial-strain", step=0.001, backend=_Linear(fail_after=7), progress=False,
                     csv_path=path)
    rows = list(csv.DictReader(path.open()))
    assert len(rows) == 7 and float(rows[-1]["E1"]) == pytest.approx(0.006)


@pytest.mark.parametrize("kwargs, word", [
    ({"name": "uniaxial"}, "uniaxial-strain"),
    ({"name": "bending", "backend": _Linear()}, "factory"),
    ({"name": "equibiaxial", "step": 0.0}, "step"),
    ({"name": "equibiaxial", "step": float("nan")}, "step"),
    ({"name": "equibiaxial", "backend": "abaqus"}, "backend"),
])
def test_bad_input_raises(kwargs, word):
    with pytest.raises(ValueError, match=word):
        run_scenario(progress=False, **kwargs)


# ----------------------------------------------------------------------------- command line
def test_cli_writes_csv_png_json(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["static", "--scenario", "uniaxial-strain", "--out", str(out), "--quiet"]) == 0
    with (out / "uniaxial-strain.csv").open() as f:
        reader = csv.DictReader(f)
        assert set(static.COLUMNS) <= set(reader.fieldnames)
        rows = [{k: float(v) for k, v in r.items()} for r in reader]
    E1 = np.array([r["E1"] for r in rows])
    assert np.all(np.abs(np.diff(E1) - STEP) < 1e-12)
    assert all(r["E2"] == 0.0 for r in rows)
    assert (out / "uniaxial-strain.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    kp = json.loads((out / "uniaxial-strain.json").read_text())
    assert kp["peak_P1"]["E1"] == pytest.approx(0.049, abs=0.002)
    printed = capsys.readouterr().out
    assert "peak of P1" in printed and "complete failure" in printed


def test_cli_fabric_file_and_leg_column(tmp_path):
    fabric_file = tmp_path / "fabric.toml"
    zylon_as("min").save(fabric_file)
    out = tmp_path / "o"
    assert main(["static", "--scenario", "load-unload", "--fabric", str(fabric_file), "--step",
                 "0.002", "--out", str(out), "--quiet"]) == 0
    with (out / "load-unload.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert {r["leg"] for r in rows} == set(static.LEGS)
    assert json.loads((out / "load-unload.json").read_text())["fabric"] == zylon_as("min").name


def test_cli_bad_scenario_lists_valid_names(tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["static", "--scenario", "uniaxial", "--out", str(tmp_path)])
    assert exc.value.code != 0
    err = capsys.readouterr().err
    assert all(name in err for name in SCENARIOS)


@pytest.mark.parametrize("step", ["0", "-0.001", "abc"])
def test_cli_bad_step(tmp_path, capsys, step):
    with pytest.raises(SystemExit):
        main(["static", "--scenario", "equibiaxial", "--step", step, "--out", str(tmp_path)])
    assert "--step" in capsys.readouterr().err


def test_static_never_imports_dolfinx():
    import subprocess

    code = ("import sys, fabric_fenicsx.studies.static as s; s.run_scenario('equibiaxial', step=0.005, "
            "progress=False); assert 'dolfinx' not in sys.modules, 'dolfinx imported'")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]
