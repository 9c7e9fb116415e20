"""The yarn-crack failure rule (fabric_fenicsx.fem.yarn_crack): its laws carry one segment's
energy over each cell's extent along the yarn, and a new damage is kept on a crack's line, taken
back beside it, and starts a crack of its own only far from any and at the segment's strength;
with a tip that reads its yarn (fabric_fenicsx.fem.yarn_tip), a cell on a crack's line joins it
only when the median strain of the other cells on its yarn reaches the segment's law."""

import math

import numpy as np
import pytest

from fabric_fenicsx.fem.yarn_crack import GIVEN, ROOT, TIP, UNCRACKED, YarnCrack, cell_extents
from fabric_fenicsx.fem.yarn_tip import YarnTip, grouped_median
from fabric_fenicsx.material.crack_energy import breaking_work, softening_moments
from fabric_fenicsx.material.fabric import zylon_as

X, Y = np.array([1.0, 0.0]), np.array([0.0, 1.0])


def _grid(n: int, h: float) -> np.ndarray:
    """Corners (n*n, 4, 2) of n x n squares of side h from the origin; cell i * n + j at column i, row j."""
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    i, j = i.ravel(), j.ravel()
    return np.stack([np.column_stack(((i + a) * h, (j + b) * h)) for a, b in ((0, 0), (1, 0), (1, 1), (0, 1))],
                    axis=1).astype(float)


def _rule(corners, fabric=None):
    return YarnCrack.on_cells(corners, (X, Y), fabric or zylon_as())


class ThresholdSurrogate:
    """A stand-in for the surrogate's damage update: a yarn whose strain passes its critical
    strain (mu_crit - 1) loses half its fibrils."""

    def update(self, E1, E2, a1, a2, critical_stretch, softening_scale):
        b1 = np.where(E1 > critical_stretch[0] - 1.0, 0.5 * a1, a1)
        b2 = np.where(E2 > critical_stretch[1] - 1.0, 0.5 * a2, a2)
        return np.zeros_like(E1), np.zeros_like(E1), b1, b2


def test_the_extent_along_a_yarn_of_a_turned_square():
    t = math.radians(30)
    square = np.array([[[0, 0], [1, 0], [1, 1], [0, 1]]], float) @ np.array([[math.cos(t), math.sin(t)],
                                                                             [-math.sin(t), math.cos(t)]])
    lo, hi = cell_extents(square, X)
    assert hi[0] - lo[0] == pytest.approx(math.cos(t) + math.sin(t))


@pytest.mark.parametrize("side", [0.726e-3, 2e-3, 4e-3])
def test_a_crack_tip_cell_breaks_with_one_segments_work(side):
    fabric = zylon_as()
    rule = _rule(_grid(3, side), fabric)
    h0 = 2 * fabric.warp.w
    I0, I1, _ = softening_moments(fabric.damage, fabric.warp.mu_crit)
    m0 = fabric.warp.mu_crit - 1.0
    work = breaking_work(rule.tip[0][0] - 1.0, rule.tip[1][0], I0, I1)
    assert np.allclose(work * side, breaking_work(m0, 1.0, I0, I1) * min(h0, side), rtol=1e-9)
    assert np.all(rule.base[0][0] == fabric.warp.mu_crit)          # a root keeps the segment's law


def test_new_damage_is_kept_on_the_line_taken_back_beside_it_and_starts_a_crack_only_far_away():
    h = 2e-3
    n = 15
    corners = _grid(n, h)
    rule = _rule(corners)
    cell = lambda i, j: i * n + j                                     # noqa: E731
    rule.add_crack([cell(7, 0), cell(7, 1), cell(7, 2)], 0, 7.5 * h)  # a slit across the warp, column 7
    points = np.arange(n * n)
    tip_strain = rule.tip[0][0, 0] - 1.0
    full_strain = rule.base[0][0, 0] - 1.0
    E1 = np.zeros(n * n)
    on_line, beside, far_strong, far_weak = cell(7, 3), cell(6, 3), cell(1, 12), cell(13, 12)
    beside_strong = cell(9, 1)                                            # 2 cells beside the slit
    E1[[on_line, beside, far_weak]] = 0.5 * (tip_strain + full_strain)   # past the tip's law only
    E1[[far_strong, beside_strong]] = full_strain + 0.001                 # past the segment's law
    rule.time = 1.5e-3
    a_old = np.ones((2, n * n))
    surrogate = ThresholdSurrogate()
    b_new = np.stack(surrogate.update(E1, np.zeros(n * n), a_old[0], a_old[1], *rule.laws(points).values())[2:])
    b, redo = rule.admit(surrogate, points, E1, np.zeros(n * n), a_old, b_new)
    assert b[0, on_line] == 0.5 and rule.kind[0, on_line] == TIP and rule.line[0, on_line] == 7.5 * h
    assert b[0, beside] == 1.0 and rule.kind[0, beside] == UNCRACKED
    assert b[0, far_strong] == 0.5 and rule.kind[0, far_strong] == ROOT
    assert rule.line[0, far_strong] == pytest.approx(1.5 * h)       # its own line, through its centre
    assert rule.mu_crit[0, far_strong] == rule.base[0][0, far_strong]
    assert b[0, far_weak] == 1.0 and rule.kind[0, far_weak] == UNCRACKED
    assert b[0, beside_strong] == 1.0 and rule.kind[0, beside_strong] == UNCRACKED   # beside: held
    assert rule.kind[0, cell(7, 0)] == GIVEN and np.all(rule.kind[1] == UNCRACKED)
    assert set(redo) == {beside, far_strong, far_weak, beside_strong}
    # cracks.csv's rows: the slit's three cells at t = 0, then the tip and the root at 1.5 ms
    rows = rule.new_cracks()
    assert rows.shape == (5, 7) and rule.new_cracks().shape == (0, 7)
    assert rows[:3, 0].tolist() == [0.0] * 3 and np.all(rows[:3, 2] == GIVEN)
    joined = {int(r[3]): r for r in rows[3:]}
    assert set(joined) == {on_line, far_strong} and np.all(rows[3:, 0] == 1.5e-3)
    assert joined[on_line][2] == TIP and joined[on_line][6] == pytest.approx(7.5 * h)
    assert joined[far_strong][2] == ROOT and joined[far_strong][4:6] == pytest.approx([1.5 * h, 12.5 * h])


def test_cells_starting_cracks_in_one_step_keep_apart():
    h = 2e-3
    n = 15
    rule = _rule(_grid(n, h))
    points = np.arange(n * n)
    E1 = np.zeros(n * n)
    E1[[7 * n + 7, 8 * n + 7]] = rule.base[0][0, 0] - 1.0 + 0.001   # two neighbours across the warp
    a_old = np.ones((2, n * n))
    surrogate = ThresholdSurrogate()
    b_new = np.stack(surrogate.update(E1, np.zeros(n * n), a_old[0], a_old[1], *rule.laws(points).values())[2:])
    b, _ = rule.admit(surrogate, points, E1, np.zeros(n * n), a_old, b_new)
    assert rule.kind[0, 7 * n + 7] == ROOT and rule.kind[0, 8 * n + 7] == UNCRACKED
    assert b[0, 8 * n + 7] == 1.0


def test_the_rule_refuses_more_than_one_rank():
    class TwoRanks:
        size = 2

    with pytest.raises(ValueError, match="one rank"):
        YarnCrack(_grid(2, 1e-3), (X, Y), zylon_as(), np.full((2, 4), 1.03), np.ones((2, 4)), comm=TwoRanks())


def test_the_stored_classification_is_what_classifying_again_gives_as_cracks_grow():
    """A cell's state is kept from step to step until a crack is added near it: over a run of
    random strains on a turned grid, where tips and roots are added by the rule itself, every
    step's stored states equal a fresh classification of every cell."""
    h, n = 1e-3, 24
    t = math.radians(30)
    turn = np.array([[math.cos(t), math.sin(t)], [-math.sin(t), math.cos(t)]])
    corners = _grid(n, h) @ turn
    rule = _rule(corners)
    centres = corners.mean(axis=1)
    rule.add_crack(np.flatnonzero(np.abs(centres[:, 0] - centres[:, 0].mean()) < 0.6 * h)[:4], 0, centres[:, 0].mean())
    rng = np.random.default_rng(3)
    points, cells = np.arange(n * n), np.arange(n * n)
    tip, full = rule.tip[0][0].min() - 1.0, rule.base[0][0, 0] - 1.0
    a = np.ones((2, n * n))
    surrogate = ThresholdSurrogate()
    added = 0
    for step in range(40):
        E1 = rng.uniform(0.0, tip + 1.2 * (full - tip), n * n) * (rng.random(n * n) < 0.05)
        E2 = np.zeros(n * n)
        b_new = np.stack(surrogate.update(E1, E2, a[0], a[1], *rule.laws(points).values())[2:])
        before = np.count_nonzero(rule.kind[0])
        a, _ = rule.admit(surrogate, points, E1, E2, a, b_new)
        added += np.count_nonzero(rule.kind[0]) - before
        stored, fresh = rule._classified(0, cells), rule._classify(0, cells)
        assert np.array_equal(stored[0], fresh[0]), step
        assert np.array_equal(stored[1], fresh[1]), step
    assert added > 5       # cracks did grow (tips and roots) while the states were reused


H, N = 2e-3, 15


def cell(i: int, j: int) -> int:
    return i * N + j


def test_grouped_median_is_each_groups_median_and_nan_where_empty():
    rng = np.random.default_rng(3)
    values, group = rng.normal(size=200), rng.integers(0, 7, size=200)
    group[group == 4] = 5                                  # group 4 empty
    median, count = grouped_median(values, group, 8)
    for g in range(8):
        mine = values[group == g]
        assert count[g] == mine.size
        assert (np.isnan(median[g]) if mine.size == 0 else median[g] == pytest.approx(np.median(mine)))


def _slit_rule(kind=YarnTip):
    rule = kind.on_cells(_grid(N, H), (X, Y), zylon_as())
    rule.add_crack([cell(7, 0), cell(7, 1), cell(7, 2)], 0, 7.5 * H)   # a slit across the warp, column 7
    return rule


def test_a_cells_yarn_strain_is_the_median_along_its_row_within_the_neighbourhood():
    rule = _slit_rule()
    E1 = np.arange(N * N, dtype=float)                     # every cell its own value
    live = np.ones(N * N, dtype=bool)
    live[cell(5, 3)] = False                               # removed: not read
    reach = int(rule.radius[0] // H)                       # 3 diameters of a 2 mm square: 4 cells
    assert reach == 4
    row = [cell(i, 3) for i in range(7 - reach, 7 + reach + 1) if i not in (5, 7)]
    assert rule.yarn_strain(0, np.array([cell(7, 3)]), E1, live)[0] == pytest.approx(np.median(E1[row]))
    # along the fill (family 1) the band is column 7: the slit's cells, cut in the warp only, are
    # read; a cell whose fill is cracked is not
    rule.add_crack([cell(7, 6)], 1, 6.5 * H)
    column = [cell(7, j) for j in range(0, 3 + reach + 1) if j not in (3, 6)]
    assert rule.yarn_strain(1, np.array([cell(7, 3)]), E1, live)[0] == pytest.approx(np.median(E1[column]))


def test_a_band_three_cells_wide_reads_the_rows_on_both_sides_too():
    """``band = 3``: the cells within 1.5 cell widths of the yarn's line through the cell, the rows
    beside its own (the slit's cells, cut in the warp, left out), within the same reach."""
    wide = YarnTip.on_cells(_grid(N, H), (X, Y), zylon_as(), band=3.0)
    wide.add_crack([cell(7, 0), cell(7, 1), cell(7, 2)], 0, 7.5 * H)
    E1 = np.arange(N * N, dtype=float)
    live = np.ones(N * N, dtype=bool)
    ball = wide.radius[0]
    rows = [cell(i, j) for i in range(N) for j in (2, 3, 4) if (i, j) not in ((7, 3), (7, 2))
            and np.hypot((i - 7) * H, (j - 3) * H) <= ball]
    assert wide.yarn_strain(0, np.array([cell(7, 3)]), E1, live)[0] == pytest.approx(np.median(E1[rows]))
    assert wide.yarn_strain(0, np.array([cell(7, 3)]), E1, live)[0] != _slit_rule().yarn_strain(
        0, np.array([cell(7, 3)]), E1, live)[0]
    with pytest.raises(ValueError, match="positive number of cell widths"):
        YarnTip.on_cells(_grid(N, H), (X, Y), zylon_as(), band=0.0)


def _tip_step(rule, neighbours: float):
    """One damage update with the tip cell (7, 3) strained past the segment's law and its row at
    ``neighbours`` (a fraction of the segment's critical strain)."""
    points = np.arange(N * N)
    full = rule.base[0][0, 0] - 1.0
    E1 = np.full(N * N, 0.5 * full)
    E1[[cell(i, 3) for i in range(N)]] = neighbours * full
    E1[cell(7, 3)] = 1.25 * full                           # the cells' concentration at the tip
    a_old = np.ones((2, N * N))
    surrogate = ThresholdSurrogate()
    b_new = np.stack(surrogate.update(E1, np.zeros(N * N), a_old[0], a_old[1], *rule.laws(points).values())[2:])
    return rule.admit(surrogate, points, E1, np.zeros(N * N), a_old, b_new)


def test_a_tip_whose_yarn_is_short_of_its_strength_waits_where_the_yarn_crack_would_let_it_go():
    waiting = _slit_rule()
    b, redo = _tip_step(waiting, 0.95)
    assert b[0, cell(7, 3)] == 1.0 and waiting.kind[0, cell(7, 3)] == UNCRACKED and cell(7, 3) in redo
    assert waiting.summary()["warp"]["tips_held"] == 1
    crack = _slit_rule(YarnCrack)
    b, _ = _tip_step(crack, 0.95)
    assert b[0, cell(7, 3)] == 0.5 and crack.kind[0, cell(7, 3)] == TIP


def test_a_tip_whose_yarn_reaches_its_strength_joins_the_crack():
    rule = _slit_rule()
    b, _ = _tip_step(rule, 1.02)
    assert b[0, cell(7, 3)] == 0.5 and rule.kind[0, cell(7, 3)] == TIP and rule.line[0, cell(7, 3)] == 7.5 * H
    assert rule.summary()["warp"]["tips_held"] == 0


def _root_step(rule, neighbours: float):
    """One damage update of a fabric without cracks: cell (7, 7) strained past the segment's law,
    its row at ``neighbours`` of the segment's critical strain."""
    points = np.arange(N * N)
    full = rule.base[0][0, 0] - 1.0
    E1 = np.full(N * N, 0.5 * full)
    E1[[cell(i, 7) for i in range(N)]] = neighbours * full
    E1[cell(7, 7)] = 1.25 * full
    a_old = np.ones((2, N * N))
    surrogate = ThresholdSurrogate()
    b_new = np.stack(surrogate.update(E1, np.zeros(N * N), a_old[0], a_old[1], *rule.laws(points).values())[2:])
    return rule.admit(surrogate, points, E1, np.zeros(N * N), a_old, b_new)


def test_a_cracks_start_reads_its_yarn_only_when_the_rule_says_so():
    tip_only = YarnTip.on_cells(_grid(N, H), (X, Y), zylon_as())
    b, _ = _root_step(tip_only, 0.95)
    assert b[0, cell(7, 7)] == 0.5 and tip_only.kind[0, cell(7, 7)] == ROOT
    both = YarnTip.on_cells(_grid(N, H), (X, Y), zylon_as(), roots=True)
    b, _ = _root_step(both, 0.95)                          # its yarn short of the segment's law
    assert b[0, cell(7, 7)] == 1.0 and np.all(both.kind == UNCRACKED) and both.roots_held[0] == 1
    both = YarnTip.on_cells(_grid(N, H), (X, Y), zylon_as(), roots=True)
    _root_step(both, 1.02)                                 # the whole yarn past it: a crack starts on it
    started = np.flatnonzero(both.kind[0] == ROOT)
    assert started.size >= 1 and np.all(started % N == 7) and both.roots_held[0] == 0
