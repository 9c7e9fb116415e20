"""The shear-lag tip (fabric_fenicsx.fem.shear_lag): Hedgepeth's concentration beside n broken
yarns, the broken yarns counted in yarn spacings whatever the cells, and a tip that breaks when its
yarn's concentrated stretch reaches the segment's law, not when its own strain does."""

import numpy as np
import pytest

from fabric_fenicsx.fem.crack_rules import crack_rule_on_cells
from fabric_fenicsx.fem.shear_lag import SLIP_CONCENTRATION, ShearLag, hedgepeth_concentration, touching_pieces
from fabric_fenicsx.fem.yarn_crack import TIP, UNCRACKED
from fabric_fenicsx.material.fabric import zylon_as

X, Y = np.array([1.0, 0.0]), np.array([0.0, 1.0])
N = 15


def _grid(n: int, h: float) -> np.ndarray:
    """Corners (n*n, 4, 2) of n x n squares of side h from the origin; cell i * n + j at column i, row j."""
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    i, j = i.ravel(), j.ravel()
    return np.stack([np.column_stack(((i + a) * h, (j + b) * h)) for a, b in ((0, 0), (1, 0), (1, 1), (0, 1))],
                    axis=1).astype(float)


def cell(i: int, j: int) -> int:
    return i * N + j


def test_hedgepeths_factors_and_their_crack_like_growth():
    """K_1 = 4/3, K_2 = 8/5, K_3 = 64/35 (Hedgepeth 1961, Table 1); for many broken yarns the
    product grows as sqrt(pi (n + 1) / 4), the square root of a crack's length."""
    assert hedgepeth_concentration([0, 1, 2, 3]) == pytest.approx([1.0, 4 / 3, 8 / 5, 64 / 35], rel=1e-14)
    K = hedgepeth_concentration(np.array([100, 400]))
    assert K / np.sqrt(np.pi * np.array([101, 401]) / 4) == pytest.approx([1.0, 1.0], abs=2e-3)
    with pytest.raises(ValueError, match="integer >= 0"):
        hedgepeth_concentration([-1])
    with pytest.raises(ValueError, match="integer >= 0"):
        hedgepeth_concentration([1.5])


def test_a_tip_counts_the_broken_piece_it_ends_or_the_two_it_bridges():
    lo, hi = np.array([0.0, 1.0, 2.0, 5.0]), np.array([1.0, 2.0, 3.0, 6.0])    # pieces [0, 3], [5, 6]
    weights = np.array([[1.0], [2.0], [3.0], [10.0]])
    span, sums, reach = touching_pieces(lo, hi, lo, hi, weights, np.array([3.0, 4.0, 3.0, 7.5]),
                                        np.array([4.0, 5.0, 5.0, 8.5]), 1e-9)
    assert span == pytest.approx([3.0, 1.0, 4.0, 0.0])
    assert sums[:, 0] == pytest.approx([6.0, 10.0, 16.0, 0.0])
    # the span across of the cut yarns each candidate's pieces hold: [0, 3], [5, 6], both, none
    assert np.allclose(reach[:, :3], [[0.0, 5.0, 0.0], [3.0, 6.0, 6.0]]) and np.isnan(reach[:, 3]).all()


def test_the_broken_yarns_are_counted_in_yarn_spacings_whatever_the_cells():
    """A 6 mm slit is 8 yarns at Zylon's 0.726 mm spacing, cut as three 2 mm cells or as six 1 mm
    cells."""
    counts = []
    for h, k in ((2e-3, 3), (1e-3, 6)):
        rule = ShearLag.on_cells(_grid(N, h), (X, Y), zylon_as())
        rule.add_crack([i * N + 0 + j for i in (7,) for j in range(k)], 0, 7.5 * h)
        counts.append(rule._broken_yarns(0, np.array([7 * N + k]), np.array([7.5 * h]))[0][0])
    spacing = 2 * zylon_as().fill.w
    assert counts == [round(6e-3 / spacing)] * 2


class HalvingSurrogate:
    """A stand-in for the surrogate's damage update: a yarn whose strain passes its critical
    strain (mu_crit - 1) keeps ``keep`` of its fibrils."""

    def __init__(self, keep: float = 0.5):
        self.keep = keep

    def update(self, E1, E2, a1, a2, critical_stretch, softening_scale):
        b1 = np.where(E1 > critical_stretch[0] - 1.0, self.keep * a1, a1)
        b2 = np.where(E2 > critical_stretch[1] - 1.0, self.keep * a2, a2)
        return np.zeros_like(E1), np.zeros_like(E1), b1, b2

    def evaluate(self, E1, E2, a1, a2):
        """The yarns' stretches: 1 + E."""
        return np.zeros_like(E1), np.zeros_like(E1), 1.0 + E1, 1.0 + E2


def _slit_rule(h=2e-3, name="shear_lag"):
    rule = crack_rule_on_cells(name, _grid(N, h), (X, Y), zylon_as())
    rule.add_crack([cell(7, 0), cell(7, 1), cell(7, 2)], 0, 7.5 * h)   # 6 mm across the warp: n = 8
    return rule


def _step(rule, row: float, tip: float, surrogate=None, a_old=None):
    """One damage update with the warp strain of row 3 (the tip's yarn, and the rows beside it
    that the rule's band reads) at ``row`` and of the tip cell (7, 3) at ``tip`` (fractions of
    the segment's critical strain), the rest at half."""
    surrogate = surrogate or HalvingSurrogate()
    points = np.arange(N * N)
    full = rule.base[0][0, 0] - 1.0
    E1 = np.full(N * N, 0.5 * full)
    beside = int(rule.band // 2)
    E1[[cell(i, j) for i in range(N) for j in range(3 - beside, 4 + beside)]] = row * full
    E1[cell(7, 3)] = tip * full
    a_old = np.ones((2, N * N)) if a_old is None else a_old
    b_new = np.stack(surrogate.update(E1, np.zeros(N * N), a_old[0], a_old[1], *rule.laws(points).values())[2:])
    return rule.admit(surrogate, points, E1, np.zeros(N * N), a_old, b_new)


def test_the_tip_breaks_when_its_yarns_concentrated_stretch_reaches_the_segments_law():
    """Beside 8 broken yarns K = 2.70: a yarn at 0.45 of the segment's critical strain breaks the
    tip though the tip cell's own strain is below its law; at 0.35 it does not, though the tip
    cell's own strain (the cells' concentration) is past it."""
    assert hedgepeth_concentration(8) == pytest.approx(2.6958, abs=1e-4)
    rule = _slit_rule()
    b, redo = _step(rule, 0.45, 0.45)
    assert rule.kind[0, cell(7, 3)] == TIP and b[0, cell(7, 3)] == 0.5 and cell(7, 3) in redo
    assert rule.summary()["warp"]["concentration_joined"] == 1
    assert rule.summary()["warp"]["largest_broken_yarns"] == 8
    rule = _slit_rule()
    b, redo = _step(rule, 0.35, 1.25)
    assert rule.kind[0, cell(7, 3)] == UNCRACKED and b[0, cell(7, 3)] == 1.0 and cell(7, 3) in redo


def test_a_joined_tip_lengthens_the_crack_only_once_it_has_broken():
    """The next cell on the line waits while the tip it would follow keeps more than half its
    fibrils, and is counted beside 8 + 3 broken yarns once that tip has broken."""
    rule = _slit_rule()
    a = np.ones((2, N * N))
    b, _ = _step(rule, 0.45, 0.45, HalvingSurrogate(0.8), a)
    assert rule.kind[0, cell(7, 3)] == TIP and b[0, cell(7, 3)] == pytest.approx(0.8)
    n = rule._broken_yarns(0, np.array([cell(7, 4)]), np.array([7.5 * 2e-3]))[0][0]
    assert n == 0                                          # (7, 3) joined, not broken: (7, 4) touches nothing broken
    a[0, cell(7, 3)] = 0.4
    _step(rule, 0.45, 0.45, HalvingSurrogate(0.8), a)      # the step sees (7, 3) broken
    n, given, shed, _ = (x[..., 0] for x in rule._broken_yarns(0, np.array([cell(7, 4)]),
                                                                    np.array([7.5 * 2e-3])))
    assert given == pytest.approx(0.75) and shed == pytest.approx(0.45 * (rule.base[0][0, 0] - 1.0))
    assert n == round(8e-3 / (2 * zylon_as().fill.w))


def test_broken_yarns_that_carried_nothing_shed_nothing():
    """Hedgepeth's factor holds for yarns that all carried the tip's load; a crack whose yarns
    broke slack (carried stretch 0) adds nothing to the tip's (K - 1) x their mean, so the tip at
    0.45 of its strength holds where the same crack as a slit (its yarns counted as loaded like
    the tip's) breaks it."""
    rule = ShearLag.on_cells(_grid(N, 2e-3), (X, Y), zylon_as())
    slack = [cell(7, 0), cell(7, 1), cell(7, 2)]
    rule.kind[0, slack], rule.line[0, slack], rule.carried[0, slack] = TIP, 7.5 * 2e-3, 0.0
    rule._cracks_added(0, np.array(slack))
    rule.broken[0, slack] = True
    a = np.ones((2, N * N))
    a[0, slack] = 0.0
    _step(rule, 0.45, 0.45, a_old=a)
    assert rule.kind[0, cell(7, 3)] == UNCRACKED
    rule.carried[0, slack] = 0.8 * (rule.base[0][0, 0] - 1.0)   # loaded nearly like the tip's
    _step(rule, 0.45, 0.45, a_old=a)
    assert rule.kind[0, cell(7, 3)] == TIP


def test_the_del_zone_caps_the_factor_at_two_from_four_broken_yarns_on():
    """Where the crossings slip the yarn beside the crack carries at most twice a broken yarn's
    load: Hedgepeth's K_n up to n = 3 (1.83), 2 from n = 4 (K_4 = 2.03) on."""
    rule = _slit_rule(name="del_zone")
    assert SLIP_CONCENTRATION == 2.0
    n = np.array([0, 1, 3, 4, 8, 400])
    assert rule.concentration(n) == pytest.approx(np.minimum(hedgepeth_concentration(n), 2.0), rel=1e-14)
    assert rule.concentration(n)[:3] == pytest.approx(hedgepeth_concentration(n[:3]), rel=1e-14)
    assert _slit_rule().concentration(n)[-1] > 11.0         # the uncapped rule's factor grows on
    with pytest.raises(ValueError, match="at least 1"):
        ShearLag.on_cells(_grid(N, 2e-3), (X, Y), zylon_as(), concentration_cap=0.5)


def test_beside_eight_broken_yarns_the_del_zones_tip_needs_half_the_strength():
    """The slit of 8 yarns: Hedgepeth's K_8 = 2.70 breaks the tip at 0.45 of the segment's
    critical strain; capped at 2 the same tip holds there and breaks at 0.55, on its yarn's
    stretch: the tip cell's own strain at 0.3."""
    rule = _slit_rule(name="del_zone")
    _step(rule, 0.45, 0.3)
    assert rule.kind[0, cell(7, 3)] == UNCRACKED
    _step(rule, 0.55, 0.3)
    assert rule.kind[0, cell(7, 3)] == TIP
    shear_lag = _slit_rule()
    _step(shear_lag, 0.45, 0.3)
    assert shear_lag.kind[0, cell(7, 3)] == TIP


def test_a_cell_that_joins_the_del_zones_crack_breaks_in_that_step():
    """Its yarn has passed the segment's peak: the del zone's joined tip is at alpha 1/2 at once,
    where the shear-lag tip keeps what its yarn's raised stretch left it (0.8 here) until that
    stretch rises further."""
    slip = _slit_rule(name="del_zone")
    b, redo = _step(slip, 0.55, 0.3, HalvingSurrogate(0.8))
    assert slip.kind[0, cell(7, 3)] == TIP and b[0, cell(7, 3)] == 0.5 and cell(7, 3) in redo
    lag = _slit_rule()
    b, _ = _step(lag, 0.55, 0.3, HalvingSurrogate(0.8))
    assert lag.kind[0, cell(7, 3)] == TIP and b[0, cell(7, 3)] == pytest.approx(0.8)
    assert b[0, cell(7, 4)] == 1.0                          # the next cell waits for the broken one


def test_the_del_zone_reads_its_tips_yarn_over_the_uncut_yarns_only():
    """Beside a slit of 8 broken warp yarns (column 7, rows 0-2) the tip (7, 3) reads its warp over
    the rows 2-4 of its band, columns 3-11: row 2 on cut yarns (slack, 0.0 here; 8 cells besides
    the slit's), the tip's row 1.0 (8 cells besides the tip), row 4 2.0 (9 cells). The band's
    median is 1.0, pulled down by the cut yarns; over the uncut yarns only (the span of the cut
    yarns left out, as ``del_zone`` reads) it is 2.0."""
    h = 2e-3
    corners = _grid(N, h)
    row = corners.mean(axis=1)[:, 1] // h
    strain = np.select([row == 2, row == 3, row == 4], [0.0, 1.0, 2.0], 5.0)
    live = np.ones(N * N, dtype=bool)
    reads = {}
    for uncut in (False, True):
        rule = ShearLag.on_cells(corners, (X, Y), zylon_as(), band=3.0, read_uncut=uncut)
        rule.add_crack([cell(7, j) for j in range(3)], 0, 7.5 * h)
        tip = np.array([cell(7, 3)])
        cut = rule._broken_yarns(0, tip, np.array([7.5 * h]))[3]
        assert cut[:, 0] == pytest.approx([0.0, 3 * h])            # rows 0-2 cut
        reads[uncut] = rule.yarn_strain(0, tip, strain, live, skip=cut if uncut else None)[0]
    assert reads[False] == pytest.approx(1.0) and reads[True] == pytest.approx(2.0)
    assert crack_rule_on_cells("del_zone", corners, (X, Y), zylon_as()).read_uncut


def _flat(kept):
    """The arrays of a kept crack reading (ShearLag._raised_laws), nested tuples flattened."""
    out = []
    for x in kept:
        out.extend(_flat(x) if isinstance(x, tuple) else [np.asarray(x)])
    return out


def test_the_del_zones_kept_crack_reading_is_what_reading_the_cracks_anew_gives():
    """The tips' cells, their bands and raised laws are kept while the cracks and the live cells
    stay as they are (``ShearLag._raised_laws``): asked again they are the same object; after a
    tip joins, and after it breaks, the reading equals one made anew, and the broken tip brings
    the next cell on the line in (a key that missed the broken cells would keep the old one)."""
    rule = _slit_rule(name="del_zone")
    points = np.arange(N * N)
    live = np.ones(N * N, dtype=bool)

    def read(anew=False):
        if anew:
            rule._raised_key[0] = None
        return rule._raised_laws(0, points, points, live)

    first = read()
    assert read() is first and list(first[0]) == [cell(7, 3)]
    a = np.ones((2, N * N))
    _step(rule, 0.55, 0.3, HalvingSurrogate(0.8), a)               # (7, 3) joins
    joined = read()
    assert rule.kind[0, cell(7, 3)] == TIP
    for kept, fresh in zip(_flat(joined), _flat(read(anew=True))):
        np.testing.assert_array_equal(kept, fresh)
    a[0, cell(7, 3)] = 0.4                                         # and has broken
    _step(rule, 0.55, 0.3, HalvingSurrogate(0.8), a)
    broke = read()
    assert cell(7, 4) in broke[0] and cell(7, 4) not in joined[0]
    for kept, fresh in zip(_flat(broke), _flat(read(anew=True))):
        np.testing.assert_array_equal(kept, fresh)
