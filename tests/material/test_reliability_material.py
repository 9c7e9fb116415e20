"""Reliability of the material point (docs/reliability.md, its items 3, 4 and 9).

* item 3: the unit cell solves the lower bending bound at the table nodes where Newton with a
  line search on the intact yarn's scale stalled (``UnitCell._solve``, path 3);
* item 4: the damage iteration always returns: a coupled point whose yarn-by-yarn steps run
  out of rounds is finished by the guaranteed bracketing (``damage_solver._bracket``), and a
  point with no root is reported by the surrogate, not raised;
* item 9: a yarn below ALPHA_BROKEN is broken in the surrogate's look-up as in the unit cell.

Each test fails on the code before the fix (see docs/reliability.md for how that was checked).
"""

import warnings

import numpy as np
import pytest

from fabric_fenicsx.material import damage_solver
from fabric_fenicsx.material.damage_solver import (BRACKETED, CONVERGED, UNCONVERGED, FallbackLog,
                                                    solve_damage, solve_point)
from fabric_fenicsx.material.fabric import zylon_as
from fabric_fenicsx.material.unitcell import ALPHA_BROKEN, UnitCell, UnitCellError
from fabric_fenicsx.surrogate.table import Surrogate
from conftest import COARSE

MIN = zylon_as("min")
MAX = zylon_as("max")


# ------------------------------------------------------------------------------- item 3
@pytest.mark.parametrize("E2", [0.064, 0.068, 0.072])
def test_lower_bending_bound_solves_the_nodes_where_newton_stalled(E2):
    """The three nodes of the lower-bound table (r = 0 node: alpha = (1, R_LIMIT)) that Newton
    and continuation did not solve (scaled residual stuck at 2e-9): solved now, out of contact,
    with the warp's force that of the isolated warp (solved at a neighbouring E2 by path 1)
    and the weak fill's force continuous in E2."""
    cell = UnitCell(MIN)
    near = cell.solve(-0.034, E2 - 0.004, alpha=(1.0, 1e-4))
    cell.forget()
    r = cell.solve(-0.034, E2, alpha=(1.0, 1e-4))
    assert not r.in_contact and r.V == 0.0
    assert np.all(np.isfinite(r.tangent)) and np.isfinite(r.Psi)
    # Out of contact the warp is an isolated elastica: its force depends on E1 only.
    assert r.P1 == pytest.approx(near.P1, rel=1e-8)
    assert r.P1 < 0.0                              # the compressed warp
    # The weak fill (alpha = 1e-4) is pulled nearly straight: its force grows with E2.
    assert 0.0 < near.P2 < r.P2 < 1.2 * near.P2


def test_lower_bending_bound_solve_is_a_path_independent_equilibrium():
    """The stalled state reached from the reference state and along a path agree."""
    a = UnitCell(MIN).solve(-0.034, 0.064, alpha=(1.0, 1e-4))
    cell = UnitCell(MIN)
    for E1 in np.linspace(0.0, -0.034, 5):
        b = cell.solve(float(E1), 0.064, alpha=(1.0, 1e-4))
    assert b.P1 == pytest.approx(a.P1, rel=1e-8) and b.P2 == pytest.approx(a.P2, rel=1e-6)


def test_unit_cell_failure_names_the_unit_cell_and_its_state_only():
    """A solve that fails on every path says it is the unit cell and which state; it does not
    send the user to settings of the run."""
    with pytest.raises(UnitCellError) as err:
        UnitCell(MAX, max_iter=1).solve(0.04, 0.0, alpha=(0.5, 1.0))
    text = str(err.value)
    assert text.startswith("unit cell: ")
    assert "E1=0.04" in text and "alpha=(0.5, 1.0)" in text and "residual" in text
    assert "dt_safety" not in text and "damping" not in text


# ------------------------------------------------------------------------------- item 4
def _linear_target(J, root, hist):
    """target(alpha) = min(hist, alpha - J (alpha - root)): a coupled two-yarn point with the
    single root ``root``; J[0, 1] > 0 as in the unit cell, where a weaker fill lets the warp
    straighten with less stretch (its target rises as alpha2 falls)."""
    J = np.asarray(J, float)

    def evaluate(rows, alpha):
        return np.minimum(alpha - (alpha - root) @ J.T, hist[rows])
    return evaluate


@pytest.mark.parametrize("J", [[[1.0, 0.9], [0.5, 0.5]], [[1.0, 0.6], [0.05, 0.05]],
                               [[1.0, 0.3], [0.2, 0.2]]])
def test_coupled_point_is_solved_where_the_yarn_by_yarn_steps_run_out(J):
    """Before: DamageIterationError after MAX_ROUNDS rounds (residual 1e-7 to 2e-3 left). Now:
    the guaranteed bracketing ends at the root."""
    root = np.array([0.6, 0.3])
    hist = np.array([[0.95, 0.9]])
    evaluate = _linear_target(J, root, hist)
    alpha = solve_damage(hist, evaluate(np.array([0]), hist), evaluate, floor=2e-6, tol=1e-10)
    np.testing.assert_allclose(alpha[0], root, atol=1e-8)
    g = alpha - evaluate(np.array([0]), alpha)
    assert np.all(np.abs(g) <= 1e-9)


def test_solve_point_reports_the_bracketed_path_and_keeps_damage_below_history():
    root = np.array([0.6, 0.3])
    hist = np.array([0.95, 0.9])
    evaluate = _linear_target([[1.0, 0.9], [0.5, 0.5]], root, hist[None])

    def point(data, a1, a2):
        t = evaluate(np.array([0]), np.array([[a1, a2]]))[0]
        return t[0], t[1]

    alpha, residual = np.empty(2), np.empty(2)
    status = solve_point((point, None), hist, np.array(point(None, *hist)), 2e-6, 1e-10,
                         damage_solver.FAST_ITERATIONS, damage_solver.SCAN_POINTS,
                         damage_solver.MAX_ROUNDS, damage_solver.ACCEPT, alpha, residual)
    assert status == BRACKETED
    assert np.all(alpha <= hist) and np.all(np.abs(residual) <= 1e-9)


def test_a_jump_without_root_ends_at_a_narrow_bracket_below_history():
    """Yarn 1's residual jumps from -1e-3 to +1e-3 at 0.3 (no root): the point ends with
    status UNCONVERGED at the jump's upper side, within tol, never above its history."""
    hist = np.array([0.5, 1.0])

    def point(data, a1, a2):
        return (min(a1 + 1e-3, 0.5) if a1 < 0.3 else a1 - 1e-3), 1.0

    alpha, residual = np.empty(2), np.empty(2)
    status = solve_point((point, None), hist, np.array(point(None, *hist)), 2e-6, 1e-10,
                         damage_solver.FAST_ITERATIONS, damage_solver.SCAN_POINTS,
                         damage_solver.MAX_ROUNDS, damage_solver.ACCEPT, alpha, residual)
    assert status == UNCONVERGED
    assert 0.3 <= alpha[0] <= 0.3 + 1e-9 and alpha[1] == 1.0
    assert residual[0] == pytest.approx(1e-3)


def test_surrogate_update_reports_a_point_without_root_and_goes_on(monkeypatch):
    """Before: one such point raised SurrogateError and ended the run. Now the update returns
    (alpha within [0, alpha_hist], finite stresses), counts the point and names it once in a
    warning."""
    sur = Surrogate(MAX, cache_dir=False, progress=False)
    n = 3

    def fake_update_points(E1, E2, a1, a2, tol, band, mu_crit, mu_top=None):
        P = np.full((n, 2), 1000.0)
        alpha = np.stack((a1, a2), axis=1) * np.array([0.5, 1.0])
        residual = np.zeros((n, 2))
        residual[1] = (1e-3, 0.0)
        status = np.array([CONVERGED, UNCONVERGED, BRACKETED], np.int8)
        return P, alpha, residual, status, 2

    monkeypatch.setattr(sur, "_update_points", fake_update_points)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        P1, P2, a1, a2 = sur.update(np.full(n, 0.05), np.full(n, 0.01), np.ones(n), np.ones(n))
    assert np.all(np.isfinite(P1)) and np.all(a1 <= 1.0)
    log = sur.damage_fallbacks
    assert isinstance(log, FallbackLog) and (log.unconverged, log.bracketed) == (1, 1)
    bad = [s for s in log.states if s["status"] == "unconverged"][0]
    assert bad["E1"] == 0.05 and bad["alpha_hist"] == (1.0, 1.0) and bad["residual"][0] == 1e-3
    assert len(caught) == 1 and "E1 = 0.05" in str(caught[0].message)
    with warnings.catch_warnings(record=True) as caught:   # named once, counted always
        warnings.simplefilter("always")
        sur.update(np.full(n, 0.05), np.full(n, 0.01), np.ones(n), np.ones(n))
    assert not caught and log.unconverged == 2


# ------------------------------------------------------------------------------- item 9
def test_a_yarn_below_alpha_broken_is_broken_in_the_lookup_as_in_the_unit_cell():
    """Before: alpha1 = 1e-300 read the r = 0 node (solved at R_LIMIT) and gave the warp the
    force of alpha1 = 1e-4 (~20 N/m); the unit cell takes the yarn out (P1 = 0). (An instance
    of the coarse table of its own: the session's shared one must not get damaged tiles.)"""
    sur = Surrogate(MAX, **COARSE)
    cell = UnitCell(MAX, n_elements=sur.n_elements)
    mu_complete = sur.fabric.damage.mu_complete(sur.mu_crit[0])
    for E1, E2 in [(0.02, 0.02), (0.04, 0.02), (0.01, 0.03)]:
        for a1 in (1e-300, 1e-9, 0.5 * ALPHA_BROKEN):
            P1, P2, mu1, mu2 = sur.evaluate(E1, E2, a1, 1.0, tension_only=False)
            r = cell.solve(E1, E2, (a1, 1.0))
            assert float(P1) == r.P1 == 0.0
            assert float(mu1) == pytest.approx(mu_complete) and r.mu1_max == pytest.approx(mu_complete)
            assert float(P2) == pytest.approx(r.P2, rel=5e-3)
        # the same for the fill, and in the derivative look-up (the time-step check)
        P1, P2, _, _ = sur.evaluate(E1, E2, 1.0, 1e-300, tension_only=False)
        assert float(P2) == 0.0
        t = sur.tangent(E1, E2, 1e-300, 1.0)
        assert t[0] == 0.0 and t[1] == 0.0
    # just above the threshold the yarn is in the cell: its force is small but not zero
    assert float(sur.evaluate(0.02, 0.02, 2 * ALPHA_BROKEN, 1.0)[0]) > 0.0
