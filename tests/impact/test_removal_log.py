"""Where removal happens and why (fabric_fenicsx.impact.removal_log): the chord of a cell along a
yarn against analytic cells, the family states, and a tiny damaged run whose removed_cells.csv
agrees with its summary and with the cells CellRemoval took out."""

import csv
import json
import math

import numpy as np
import pytest

from fabric_fenicsx.impact.removal_log import (BROKEN_BELOW, FAMILY_STATES, REMOVED_CELL_COLUMNS, RULES,
                                              chords_through_centroid, corner_extents, family_states,
                                              polygon_centroids, removal_statistics)
from fabric_fenicsx.impact.scene import build_scene
from fabric_fenicsx.impact.simulation import ImpactSimulation

DAMAGED = {
    "description": "tiny damaged scene",
    "material": {"angle": 90.0, "damage": True},
    "mesh": {"kind": "uniform", "side": 0.08, "n": 16, "element": "full"},   # 5 mm squares
    "projectile": {"diameter": 0.02, "velocity": 200.0, "mass": 0.005},
    "boundary": {"clamped": ["left", "right", "bottom", "top"]},
    "run": {"t_end": 3e-4},
    "output": {"xdmf_interval": 0.0, "png": False, "progress_interval": 0.0},
}
"""The 8 cm fabric clamped all round, hit at 200 m/s: cells deleted and eroded, a perforation."""


def rotated_square(theta: float, centre=(0.3, -0.2), side=1.0, clockwise=False) -> np.ndarray:
    """A square of ``side`` turned by ``theta`` (rad) about ``centre``, corners in perimeter
    order, shape (1, 4, 2)."""
    sq = side * (np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=float) - 0.5)
    if clockwise:
        sq = sq[::-1]
    c, s = math.cos(theta), math.sin(theta)
    return (sq @ np.array([[c, -s], [s, c]]).T + np.array(centre))[None]


@pytest.mark.parametrize("clockwise", [False, True])
def test_the_chord_of_a_unit_square_turned_by_30_degrees(clockwise):
    """Along x, the line through the centre of a unit square turned by 30 degrees crosses two
    opposite sides at 30 degrees to their normal: chord 1 / cos 30 = 1.1547; along the square's
    own side: 1; at 45 degrees to it: the diagonal sqrt(2). The corners' extent along x is
    cos 30 + sin 30 = 1.366."""
    theta = math.radians(30.0)
    cell = rotated_square(theta, clockwise=clockwise)
    assert polygon_centroids(cell)[0] == pytest.approx([0.3, -0.2], abs=1e-15)
    x = np.array([1.0, 0.0])
    assert chords_through_centroid(cell, x)[0] == pytest.approx(1.0 / math.cos(theta), rel=1e-14)
    assert chords_through_centroid(cell, np.array([0.0, 1.0]))[0] == pytest.approx(1.0 / math.cos(theta), rel=1e-14)
    side = np.array([math.cos(theta), math.sin(theta)])
    assert chords_through_centroid(cell, side)[0] == pytest.approx(1.0, rel=1e-14)
    diagonal = np.array([math.cos(theta + math.pi / 4), math.sin(theta + math.pi / 4)])
    assert chords_through_centroid(cell, diagonal)[0] == pytest.approx(math.sqrt(2.0), rel=1e-14)
    assert corner_extents(cell, x)[0] == pytest.approx(math.cos(theta) + math.sin(theta), rel=1e-14)


def test_chords_are_vectorised_and_depend_on_the_point_and_the_cell_shape():
    """Several cells at once; a 2 x 0.5 rectangle along x: chords 2 and 0.5, through any inner
    point; a right trapezoid (heights 1 and 3 over a base of 2): its area centroid is at
    x = h (a + 2 b) / (3 (a + b)) = 7/6, where the vertical chord is 1 + 7/6."""
    rect = np.array([[[0, 0], [2, 0], [2, 0.5], [0, 0.5]]], dtype=float)
    trap = np.array([[[0, 0], [2, 0], [2, 3], [0, 1]]], dtype=float)
    cells = np.concatenate([rect, trap, rotated_square(0.4, side=0.002)])
    along_y = chords_through_centroid(cells, np.array([0.0, 1.0]))
    assert along_y[:2] == pytest.approx([0.5, 1.0 + 7.0 / 6.0], rel=1e-14)
    assert polygon_centroids(trap)[0, 0] == pytest.approx(7.0 / 6.0, rel=1e-14)
    assert chords_through_centroid(rect, np.array([1.0, 0.0]), np.array([[1.7, 0.1]]))[0] == pytest.approx(2.0)
    assert along_y[2] == pytest.approx(0.002 / math.cos(0.4), rel=1e-12)


def test_family_states_and_statistics_of_rows():
    """alpha below BROKEN_BELOW is broken: the four states, counted per rule, the first removal
    of each state and the median chords."""
    assert BROKEN_BELOW == 0.5
    a1 = np.array([0.0, 0.9, 0.0, 1.0, 0.49])
    a2 = np.array([1.0, 0.1, 0.0, 0.5, 0.2])
    assert [FAMILY_STATES[i] for i in family_states(a1, a2)] == ["warp_only", "fill_only", "both",
                                                                 "neither", "both"]
    col = {c: i for i, c in enumerate(REMOVED_CELL_COLUMNS)}
    rows = np.zeros((5, len(REMOVED_CELL_COLUMNS)))
    rows[:, col["time_s"]] = [3e-4, 1e-4, 2e-4, 4e-4, 5e-4]
    rows[:, col["rule"]] = [1, 1, 0, 1, 0]
    rows[:, col["alpha1_warp"]], rows[:, col["alpha2_fill"]] = a1, a2
    rows[:, col["chord1_warp_m"]] = [1, 2, 3, 4, 100]
    rows[:, col["chord2_fill_m"]] = [5, 5, 6, 6, 6]
    s = removal_statistics(rows)
    assert s["by_rule"] == {"deletion": 2, "erosion": 3} and s["cells"] == 5
    assert s["by_family_state"] == {"warp_only": 1, "fill_only": 1, "both": 2, "neither": 1}
    assert s["by_rule_and_family_state"]["deletion"] == {"warp_only": 0, "fill_only": 0, "both": 2, "neither": 0}
    assert s["first_removal_time_s"] == {"warp_only": 3e-4, "fill_only": 1e-4, "both": 2e-4, "neither": 4e-4}
    assert s["median_chord_m"] == {"warp": 3.0, "fill": 6.0}
    assert s["median_chord_by_rule_m"]["deletion"] == {"warp": 51.5, "fill": 6.0}
    empty = removal_statistics(np.zeros((0, len(REMOVED_CELL_COLUMNS))))
    assert empty["cells"] == 0 and empty["median_chord_m"] == {"warp": None, "fill": None}
    assert removal_statistics(rows, broken_below=0.0)["by_family_state"]["neither"] == 5


@pytest.fixture(scope="module")
def damaged_run(tmp_path_factory, coarse_surrogate):
    """The tiny damaged scene run serially on the session's coarse table: (simulation, summary,
    rows of removed_cells.csv)."""
    out = tmp_path_factory.mktemp("removal") / "run"
    sim = ImpactSimulation(build_scene(DAMAGED, [], "tiny.toml"), out, verbose=False,
                           surrogate=coarse_surrogate)
    try:
        summary = sim.run()
    finally:
        sim.output.close()
    with open(out / "removed_cells.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert json.loads((out / "summary.json").read_text())["removal"] == summary["removal"]
    return sim, summary, rows


def test_removed_cells_csv_agrees_with_the_summary_and_the_removed_cells(damaged_run):
    sim, s, rows = damaged_run
    assert s["deleted_cells"] > 0 and s["eroded_cells"] > 0
    assert list(rows[0]) == list(REMOVED_CELL_COLUMNS)
    assert len(rows) == s["deleted_cells"] + s["eroded_cells"] == s["removal"]["cells"]
    removal = s["removal"]
    assert removal["by_rule"] == {"deletion": s["deleted_cells"], "erosion": s["eroded_cells"]}
    # the rule of each row is the one CellRemoval applied to that cell (one rank: global = local)
    for rule, mask in (("deletion", sim.removal.deleted_cells), ("erosion", sim.removal.eroded_cells)):
        cells = sorted(int(r["cell"]) for r in rows if r["rule"] == rule)
        assert cells == list(np.flatnonzero(mask)), rule
    assert {r["rule"] for r in rows} <= set(RULES)
    # the family states recounted from the CSV's alphas
    a1 = np.array([float(r["alpha1_warp"]) for r in rows])
    a2 = np.array([float(r["alpha2_fill"]) for r in rows])
    states = family_states(a1, a2, removal["broken_below_alpha"])
    assert removal["by_family_state"] == {k: int(np.count_nonzero(states == i)) for i, k in enumerate(FAMILY_STATES)}
    assert sum(removal["by_family_state"].values()) == len(rows)
    # recorded before the material forgot them: a deleted cell has both yarns broken, an eroded
    # one a yarn strain beyond the erosion strain (stretch sqrt(1 + 2 E))
    for r in rows:
        E = max(float(r["E1_max_warp"]), float(r["E2_max_fill"]))
        if r["rule"] == "deletion":
            assert float(r["alpha1_warp"]) == float(r["alpha2_fill"]) == 0.0
        else:
            assert E > 1.0
        assert float(r["mu1_max_warp"]) == pytest.approx(math.sqrt(1 + 2 * float(r["E1_max_warp"])), rel=1e-9)
        # 5 mm squares along the yarns (angle 90: warp along y)
        assert float(r["chord1_warp_m"]) == pytest.approx(0.005, rel=1e-9)
        assert float(r["chord2_fill_m"]) == pytest.approx(0.005, rel=1e-9)
        assert abs(float(r["x_m"])) < 0.04 and abs(float(r["y_m"])) < 0.04
    assert removal["median_chord_m"]["warp"] == pytest.approx(0.005, rel=1e-9)
    # rows in the order of removal, at times of the run, after each family's damage onset
    t = np.array([float(r["time_s"]) for r in rows])
    assert np.all(np.diff(t) >= 0) and 0 < t[0] and t[-1] <= s["end_time"]
    onset = removal["damage_onset_time_s"]
    assert min(onset["warp"], onset["fill"]) == pytest.approx(s["damage_onset_time"], rel=1e-15)
    assert t[0] >= min(onset.values())
    broken = removal["broken_time_s"]
    assert all(broken[y] is not None and broken[y] >= onset[y] for y in ("warp", "fill"))
    assert min(removal["first_removal_time_s"][k] for k in FAMILY_STATES
               if removal["first_removal_time_s"][k] is not None) == pytest.approx(t[0], rel=1e-9)
