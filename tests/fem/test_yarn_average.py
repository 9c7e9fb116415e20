"""The yarn-average failure rule (fabric_fenicsx.fem.yarn_average): its neighbourhoods lie along
each yarn, one cell wide; it averages live cells only; shorter than a cell it is the thesis's
rule to the bit."""

import numpy as np
import pytest

from fabric_fenicsx.fem.yarn_average import YarnAverage, yarn_neighbourhoods

X, Y = (np.array([1.0, 0.0]), np.array([0.0, 1.0]))


def _grid(n: int, h: float):
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    return np.column_stack(((i.ravel() + 0.5) * h, (j.ravel() + 0.5) * h)), np.full(n * n, h * h)


def test_the_neighbourhoods_run_along_each_yarn_one_cell_wide():
    centres, areas = _grid(9, 1.0)
    W1, W2 = yarn_neighbourhoods(centres, areas, (X, Y), 4.0)
    c = 4 * 9 + 4                                   # the middle cell
    along_x = centres[W1[c].indices]
    along_y = centres[W2[c].indices]
    assert np.allclose(along_x[:, 1], centres[c, 1]) and sorted(along_x[:, 0]) == [2.5, 3.5, 4.5, 5.5, 6.5]
    assert np.allclose(along_y[:, 0], centres[c, 0]) and sorted(along_y[:, 1]) == [2.5, 3.5, 4.5, 5.5, 6.5]


def test_the_average_takes_live_cells_only():
    centres, areas = _grid(5, 1.0)
    rule = YarnAverage(centres, areas, (X, Y), 2.0)
    E1 = centres[:, 0].copy()                       # a strain rising along x
    live = np.ones(25, dtype=bool)
    Ebar1, _ = rule(E1, np.zeros(25), live)
    c = 2 * 5 + 2
    assert Ebar1[c] == pytest.approx(2.5)           # (1.5 + 2.5 + 3.5) / 3
    live[3 * 5 + 2] = False                         # the cell at x = 3.5 removed
    Ebar1, _ = rule(E1, np.zeros(25), live)
    assert Ebar1[c] == pytest.approx(2.0)           # (1.5 + 2.5) / 2


def test_shorter_than_a_cell_it_is_the_thesis_rule():
    from fabric_fenicsx.fem.yarn_stress import YarnStress
    from fabric_fenicsx.material.fabric import zylon_as
    from fabric_fenicsx.surrogate.table import Surrogate

    fabric = zylon_as()
    sur = Surrogate(fabric, progress=False, workers=1)
    centres, areas = _grid(6, 1e-3)
    rng = np.random.default_rng(3)
    thesis = YarnStress(sur, areas, True)
    local = YarnStress(sur, areas, True)
    local.damage_drive = YarnAverage(centres, areas, (X, Y), 0.5e-3)
    for E in np.linspace(0.0, 0.06, 13):
        E1 = E * (1 + 0.2 * rng.random(36))
        E2 = 0.3 * E * rng.random(36)
        P = thesis.update(E1, E2)
        Q = local.update(E1, E2)
        assert np.array_equal(thesis.alpha1, local.alpha1) and np.array_equal(thesis.alpha2, local.alpha2)
        assert np.allclose(P, Q, rtol=1e-12, atol=1e-9)
    assert thesis.alpha1.min() < 0.5                # the path went through damage


def test_a_longer_average_delays_damage_where_the_strain_peaks():
    from fabric_fenicsx.fem.yarn_stress import YarnStress
    from fabric_fenicsx.material.fabric import zylon_as
    from fabric_fenicsx.surrogate.table import Surrogate

    fabric = zylon_as()
    sur = Surrogate(fabric, progress=False, workers=1)
    centres, areas = _grid(7, 1e-3)
    peak = np.exp(-((centres[:, 0] - 3.5e-3) / 1e-3) ** 2)     # warp strain peaked at one column
    thesis, averaged = YarnStress(sur, areas, True), YarnStress(sur, areas, True)
    averaged.damage_drive = YarnAverage(centres, areas, (X, Y), 5e-3)
    for E in np.linspace(0.0, 0.05, 11):
        thesis.update(E * peak, np.zeros(49))
        averaged.update(E * peak, np.zeros(49))
    assert thesis.alpha1.min() < averaged.alpha1.min()


def test_more_than_one_rank_is_refused():
    class Two:
        size = 2

    with pytest.raises(ValueError, match="one rank"):
        YarnAverage(np.zeros((1, 2)), np.ones(1), (X, Y), 1.0, Two())
