"""The stability study (fabric_fenicsx.studies.stability, docs/stability.md): its fabric variants, outcome
parsing and verdicts, and its fast cases run short on the coarse Y90 mesh.

Each run asserts an outcome that could be false: a completed run has finite fields and an
energy error below 5 %; a stopped run raised ImpactError with a message naming step, time,
place and cause. The cases use the built-in fabric only, on the session's coarse table
(conftest's ``coarse_tables_in_runs``: these tests are about the study and the runs, not the
table's accuracy, and the default table's damaged tiles take minutes to solve from an empty
cache); the fabric variants, whose tables take a minute each to solve, are checked here through
their geometry and run in the study.
"""

import math
from types import SimpleNamespace

import numpy as np
import pytest

from fabric_fenicsx.material.fabric import zylon_as
from fabric_fenicsx.studies.stability import (BASE_OVERRIDES, CASES, EDGE_Y, ENERGY_LIMIT, Case, assess,
                                      make_fabric, parse_stop_message, run_case, scaled_stiffness,
                                      with_crimp)

SHORT = tuple(o for o in BASE_OVERRIDES if not o.startswith("run.t_end")) + ("run.t_end=0.00015",)
"""The study's coarse mesh (1039 cells), 0.15 ms: contact and the first stress waves."""

pytestmark = pytest.mark.usefixtures("coarse_tables_in_runs")


def by_name(name):
    return next(c for c in CASES if c.name == name)


# ============================================================================ fabrics
@pytest.mark.parametrize("crimp", [0.0, 0.031, 0.10])
def test_with_crimp_sets_both_yarns_crimp_and_keeps_the_yarn_spacing(crimp):
    base = zylon_as()
    fab = with_crimp(base, crimp)
    for new, old in zip(fab.yarns, base.yarns):
        assert new.crimp == pytest.approx(crimp, abs=1e-9)
        assert new.w == pytest.approx(old.w, rel=1e-9)
        assert (new.A0, new.B0, new.mu_crit) == (old.A0, old.B0, old.mu_crit)
    if crimp == 0.0:
        assert fab.warp.Phi_L == 0.0 and fab.warp.H == 0.0


def test_with_crimp_rejects_impossible_crimp():
    with pytest.raises(ValueError, match="crimp must lie in"):
        with_crimp(zylon_as(), 5.0)
    with pytest.raises(ValueError, match="crimp must be"):
        with_crimp(zylon_as(), -0.1)


def test_scaled_stiffness_scales_only_A0_and_B0():
    base = zylon_as()
    fab = scaled_stiffness(base, stretch=10.0, bending=0.1)
    for new, old in zip(fab.yarns, base.yarns):
        assert new.A0 == pytest.approx(10 * old.A0) and new.B0 == pytest.approx(0.1 * old.B0)
        assert (new.L, new.Phi_L, new.mu_crit) == (old.L, old.Phi_L, old.mu_crit)
    with pytest.raises(ValueError, match="positive"):
        scaled_stiffness(base, stretch=0.0)
    with pytest.raises(ValueError, match="unknown fabric change"):
        make_fabric(("shear", 2.0))


def test_every_case_named_in_the_issue_is_in_the_study():
    names = {c.name for c in CASES}
    assert {"bending-x10", "bending-div10", "stretch-x10", "crimp-0", "crimp-10", "v300", "v1000",
            "friction-0", "friction-2", "fillet-0", "angle-30", "edge-20mm", "refined-4x",
            "beyond-table", "large-damage"} <= names
    assert len(names) == len(CASES)
    assert -0.27305 / 2 - EDGE_Y == pytest.approx(-0.020)   # 20 mm from the clamped bottom edge


# ============================================================================ verdicts
TROUBLE = ("impact run stopped at step 1222, t = 2.469569e-04 s: blow-up: kinetic energy 1.851e+04 J; "
           "largest displacement [ 0.005 0.02 -0.27] m at reference (x, y) = [-0.0022 -0.0121] m on "
           "rank 0; dt = 2.014e-07 s, projectile at z = -2.4634e-01 m moving 997.497 m/s. Likely fixes: ...")


def test_stop_message_parsing():
    parsed = parse_stop_message(TROUBLE)
    assert parsed["step"] == 1222 and parsed["time"] == pytest.approx(2.469569e-4)
    assert parsed["cause"].startswith("blow-up") and "reference (x, y)" in parsed["place"]
    assert parse_stop_message("surrogate damage iteration did not converge") is None


def _record(status, energy_error=0.001, finite=True, message=None, error_type=None):
    summary = ({"residual_velocity": 50.0, "energy_error": energy_error, "end_time": 6e-4}
               if status == "completed" else None)
    return {"status": status, "summary": summary, "message": message, "error_type": error_type,
            "history": {"rows": 10, "finite": finite, "max_kinetic_over_KE0": 1.0}}


def test_assess_flags_what_the_issue_forbids():
    assert assess(_record("completed"))["verdict"] == "ok"
    bad = assess(_record("completed", energy_error=1.5 * ENERGY_LIMIT))
    assert bad["verdict"] == "finding" and "did not stop" in bad["problems"][0]
    assert assess(_record("completed", finite=False))["verdict"] == "finding"
    assert assess(_record("stopped", message=TROUBLE, error_type="ImpactError"))["verdict"] == "ok"
    vague = assess(_record("stopped", message="stopped", error_type="ImpactError"))
    assert vague["verdict"] == "finding"
    other = assess(_record("failed", message="no convergence", error_type="SurrogateError"))
    assert other["verdict"] == "finding" and "outside the impact guards" in other["problems"][0]


# ============================================================================ runs
def assert_sound(rec):
    """Completed with finite output and energy error < 5 %, or stopped naming step/time/place."""
    assert rec["status"] in ("completed", "stopped"), rec.get("message")
    assert rec["history"]["rows"] > 0 and rec["history"]["finite"]
    if rec["status"] == "completed":
        s = rec["summary"]
        assert all(math.isfinite(s[k]) for k in ("residual_velocity", "energy_error", "end_time"))
        assert s["energy_error"] < ENERGY_LIMIT
        assert rec["history"]["max_kinetic_over_KE0"] <= 1.2
    else:
        stop = parse_stop_message(rec["message"])
        assert stop is not None, rec["message"]
        assert stop["step"] > 0 and stop["time"] > 0


CONTACT_CASES = ("friction-0", "friction-2", "angle-30", "edge-20mm")


@pytest.fixture(scope="module")
def contact_runs(tmp_path_factory, coarse_tables_in_runs):
    """The four contact cases run short by the study's own `run_case` (outcome record and
    verdict), each with its simulation kept for a look at the fields at the end."""
    from fabric_fenicsx.studies import stability

    kept = {}
    original = stability.run_simulation

    def keeping(scene, folder, keep):
        try:
            kept["summary"] = original(scene, folder, keep)
            return kept["summary"]
        finally:
            kept["sim"] = keep.get("sim")

    runs = {}
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(stability, "run_simulation", keeping)
        for name in CONTACT_CASES:
            rec = run_case(by_name(name), tmp_path_factory.mktemp(name), base_overrides=SHORT)
            runs[name] = SimpleNamespace(rec=rec, sim=kept.pop("sim"), summary=kept.pop("summary", None))
    return runs


def point_coordinates(sim):
    """Reference (x, y) of the owned quadrature points, in the membrane's point order."""
    import ufl
    from dolfinx import fem

    from fabric_fenicsx.fem.membrane import _BASIX_CELL
    import basix

    m = sim.membrane
    pts, _ = basix.make_quadrature(_BASIX_CELL[m.msh.topology.cell_type.name], m.quadrature_degree)
    xq = fem.Expression(ufl.SpatialCoordinate(m.msh), pts).eval(np.arange(m.n_cells, dtype=np.int32))
    return xq.reshape(-1, 2)


def strained_band(sim):
    """Direction (degrees in [0, 180)) and centre of the band of quadrature points whose warp
    strain E1 exceeds half its largest value: the principal axis of the points' area-weighted
    second moment about the impact point, and their area-weighted mean position."""
    mat, w = sim.material, sim.membrane.quadrature_weights_detJ
    sel = mat.E1 > 0.5 * mat.E1.max()
    d = point_coordinates(sim)[sel] - sim.axis_xy
    moment = np.einsum("k,ki,kj->ij", w[sel], d, d)
    _, vectors = np.linalg.eigh(moment)
    axis = vectors[:, 1]
    return float(np.degrees(np.arctan2(axis[1], axis[0])) % 180.0), sim.axis_xy + np.average(d, axis=0, weights=w[sel])


def sliding_under_the_face(sim):
    """Mean in-plane displacement (m) of the nodes under the projectile's face (r < 0.8 R)."""
    u = sim.cd.u.reshape(-1, 3)
    r = np.hypot(sim.X[:, 0] - sim.axis_xy[0], sim.X[:, 1] - sim.axis_xy[1])
    face = r < 0.8 * sim.projectile.radius
    return float(np.hypot(u[face, 0], u[face, 1]).mean())


@pytest.mark.parametrize("name", CONTACT_CASES)
def test_contact_cases_complete_with_a_small_energy_error(contact_runs, name):
    rec = contact_runs[name].rec
    assert_sound(rec)
    s = rec["summary"]
    assert rec["status"] == "completed" and s["end_reason"] == "time_limit"
    assert rec["assessment"]["verdict"] == "ok" and rec["fragments"]["free_fragments"] == 0
    assert s["residual_velocity"] < 57.3          # the fabric took energy
    assert s["energy_error"] < 0.001              # measured 4.9e-4 (at the first contact)


def test_friction_holds_the_fabric_under_the_face(contact_runs):
    """Frictionless contact dissipates nothing by friction and lets the fabric slide under the
    flat face as the cone pulls it in; friction 2 dissipates energy, holds the nodes under the
    face (measured: mean in-plane displacement 4.0e-5 against 8.1e-5 m). Before damage the
    coefficient hardly changes the projectile's speed (56.7139 against 56.7133 m/s at 0.15 ms
    with the reduced element; the fully integrated one gave 56.733 against 56.740 m/s, the
    other way round): within 1e-4 of the impact velocity."""
    run0, run2 = contact_runs["friction-0"], contact_runs["friction-2"]
    e0, e2 = run0.summary["energies"], run2.summary["energies"]
    assert e0["friction_dissipation_estimate"] == 0.0
    assert e2["friction_dissipation_estimate"] > 0.02 * e2["contact_dissipation"]
    assert sliding_under_the_face(run2.sim) < 0.7 * sliding_under_the_face(run0.sim)
    assert abs(run2.summary["residual_velocity"] - run0.summary["residual_velocity"]) < 1e-4 * 57.3


@pytest.mark.parametrize("name, angle", [("friction-0", 90.0), ("angle-30", 30.0)])
def test_the_warp_strain_runs_along_the_material_angle(contact_runs, name, angle):
    """The yarns through the impact zone carry the load: the points of large warp strain E1
    form a band through the impact point along the warp, at the scene's material.angle from
    global X (Y90: 90 degrees; angle-30: 30 degrees; measured 89.6 and 34.0)."""
    direction, _ = strained_band(contact_runs[name].sim)
    assert abs((direction - angle + 90.0) % 180.0 - 90.0) < 5.0, direction


def test_an_impact_near_a_clamped_edge_strains_the_short_yarns_to_it(contact_runs):
    """20 mm from the clamped bottom edge the warp yarns (along Y) between the projectile and
    that edge are short and take the most strain: the points of large E1 gather below the
    impact point (measured 11 mm below it; centred impact: at the impact point), and the
    deepest node is under the projectile there."""
    sim = contact_runs["edge-20mm"].sim
    assert np.allclose(sim.axis_xy, [0.0, EDGE_Y])
    _, centre = strained_band(sim)
    assert -0.27305 / 2 < centre[1] < EDGE_Y - 0.005, centre
    _, centred = strained_band(contact_runs["friction-0"].sim)
    assert np.hypot(*centred) < 0.003, centred
    deepest = sim.X[np.argmin(sim.cd.u[2::3]), :2]
    assert np.hypot(*(deepest - sim.axis_xy)) < sim.projectile.radius


@pytest.fixture(scope="module")
def v1000(tmp_path_factory, coarse_tables_in_runs):
    """The full study case (about 5 s): a plug is punched out at once."""
    return run_case(by_name("v1000"), tmp_path_factory.mktemp("v1000"))


def test_1000_m_per_s_plug_ends_as_a_perforation(v1000):
    """The projectile punches a plug out at once; the plug, cut loose from the clamped edges,
    flies on with it: the run ends as a perforation, not as a blow-up."""
    assert_sound(v1000)
    assert v1000["status"] == "completed" and v1000["summary"]["end_reason"] == "perforated"
    assert v1000["summary"]["energy_error"] < 0.002                  # measured 4.5e-4
    assert v1000["summary"]["deleted_cells"] > 0 and v1000["summary"]["eroded_cells"] > 0
    assert v1000["fragments"]["free_fragments"] >= 1
    assert v1000["assessment"]["verdict"] == "ok"


def test_strains_beyond_the_table_are_counted_and_stay_finite(tmp_path):
    """Damage off at 300 m/s: by 0.3 ms intact yarns pass the table's end (with the reduced
    element not yet at 0.15 ms), are counted, and the run stays finite and balanced."""
    rec = run_case(by_name("beyond-table"), tmp_path / "bt", base_overrides=SHORT[:-1] + ("run.t_end=0.0003",))
    assert_sound(rec)
    assert rec["status"] == "completed" and rec["summary"]["points_beyond_table"] > 0   # measured 109905
    assert rec["assessment"]["verdict"] == "ok"
    assert rec["summary"]["energy_error"] < 0.002                    # measured 5.4e-4


def test_large_damaged_region_removes_cells_within_the_energy_limit(tmp_path):
    """docs/stability.md records an energy error of 0.83 % for this case (default table, 0.6 ms;
    0.82 % measured on this 0.15 ms run with the coarse table): the balance must stay within 1 %,
    not the 5 % guard."""
    rec = run_case(by_name("large-damage"), tmp_path / "ld", base_overrides=SHORT)
    assert_sound(rec)
    s = rec["summary"]
    assert s["eroded_cells"] > 20                                     # measured 36
    assert s["energy_error"] < 0.01


def test_energy_guard_stops_a_damage_on_run_naming_step_time_and_place(tmp_path):
    case = Case("tight", "energy tolerance 1e-9", ("run.energy_tolerance=1e-9", "run.max_steps=400"))
    rec = run_case(case, tmp_path / "tight")
    assert rec["status"] == "stopped"
    stop = parse_stop_message(rec["message"])
    assert stop is not None and "energy balance error" in stop["cause"] and "damage on" in stop["cause"]
    assert rec["assessment"]["verdict"] == "ok"
    assert np.isfinite(rec["history"]["last_energy_error"])
