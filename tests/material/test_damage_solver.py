"""The damage iteration (fabric_fenicsx.material.damage_solver) on manufactured targets."""

import numpy as np
import pytest

from fabric_fenicsx.material.damage_solver import DamageIterationError, solve_damage


def jump_target(jump: float, at: float = 0.3):
    """target(alpha) for yarn 1 with no exact fixed point: alpha - target = -jump below `at`
    and +jump above (a root hidden in a jump, as an interpolated, nearly singular target
    can have)."""
    def evaluate(rows, alpha):
        t = np.ones_like(alpha)   # yarn 2 below its critical stretch: target = its history, 1
        t[:, 0] = np.where(alpha[:, 0] < at, alpha[:, 0] + jump, alpha[:, 0] - jump)
        return np.minimum(t, np.array([[0.5, 1.0]]))
    return evaluate


def test_a_root_hidden_in_a_tiny_jump_is_accepted_at_the_jump():
    hist = np.array([[0.5, 1.0]])
    evaluate = jump_target(2e-9)
    alpha = solve_damage(hist, evaluate(None, hist), evaluate, floor=2e-6, tol=1e-10)
    assert alpha[0, 0] == pytest.approx(0.3, abs=1e-6)   # the highest sign change below hist
    assert alpha[0, 1] == 1.0


def test_a_large_jump_is_not_accepted():
    hist = np.array([[0.5, 1.0]])
    evaluate = jump_target(1e-3)
    with pytest.raises(DamageIterationError, match="did not converge.*alpha - target") as err:
        solve_damage(hist, evaluate(None, hist), evaluate, floor=2e-6, tol=1e-10)
    assert list(err.value.rows) == [0] and abs(err.value.residual[0, 0]) > 1e-7


def test_a_contraction_converges_to_tol():
    hist = np.array([[1.0, 1.0], [0.8, 0.9]])

    def evaluate(rows, alpha):   # target = 0.5 alpha + 0.2 (yarn 1): fixed point 0.4
        t = hist[rows].copy()
        t[:, 0] = 0.5 * alpha[:, 0] + 0.2
        return np.minimum(t, hist[rows])

    alpha = solve_damage(hist, evaluate(np.arange(2), hist), evaluate, floor=2e-6, tol=1e-12)
    assert np.allclose(alpha[:, 0], 0.4, atol=1e-11) and np.all(alpha[:, 1] == hist[:, 1])
