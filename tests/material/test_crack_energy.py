"""The breaking work of a yarn segment and the cell law of equal energy
(fabric_fenicsx.material.crack_energy): against a direct integration of the force of Eq. 2-25's
yarn, and the energy each law of a longer cell takes."""

import numpy as np
import pytest

from fabric_fenicsx.material.crack_energy import S_MIN, breaking_work, equal_energy_law, softening_moments
from fabric_fenicsx.material.fibril import ExponentialDamage

LAW = ExponentialDamage()


def _work_by_integration(mu_onset: float, scale: float, n: int = 200001) -> float:
    """int F / A dmu of F = alpha (mu - 1) A, damage starting at mu_onset with the softening
    profile of Eq. 2-25 stretched by ``scale`` (the definition of breaking_work)."""
    span = scale * LAW.width
    mu = np.linspace(1.0, mu_onset + span, n)
    u = np.clip((mu - mu_onset) / scale, 0.0, LAW.width)
    alpha = LAW.alpha(1.5 + u, 1.5)               # the profile, independent of where it starts
    return float(np.trapz(alpha * (mu - 1.0), mu))


@pytest.mark.parametrize("mu_onset, scale", [(1.025, 1.0), (1.0297, 1.0), (1.02, 0.1), (1.025, 0.4)])
def test_the_breaking_work_is_the_integral_of_the_yarn_force(mu_onset, scale):
    I0, I1, span = softening_moments(LAW, 1.025)
    assert span == pytest.approx(LAW.width)
    assert breaking_work(mu_onset - 1.0, scale, I0, I1) == pytest.approx(_work_by_integration(mu_onset, scale),
                                                                          rel=1e-6)


def test_a_cell_of_the_segments_length_keeps_the_segments_law():
    I0, I1, _ = softening_moments(LAW, 1.025)
    m, s = equal_energy_law(np.array([0.025, 0.03]), np.array([1.0, 0.7]), np.array([1.0, 3.0]), I0, I1)
    assert np.allclose(m, [0.025, 0.03]) and np.allclose(s, [1.0, 0.7])


def test_a_longer_cell_takes_the_segments_energy_first_by_its_softening_then_by_its_strength():
    I0, I1, _ = softening_moments(LAW, 1.025)
    m0 = 0.025
    ratio = np.linspace(0.05, 1.0, 400)
    m, s = equal_energy_law(np.full(ratio.size, m0), np.ones(ratio.size), ratio, I0, I1)
    work = breaking_work(m, s, I0, I1)
    assert np.allclose(work, ratio * breaking_work(m0, 1.0, I0, I1), rtol=1e-12)
    softening_only = m == m0
    # the long cells lose strength, the short ones only softening; never both beyond the switch
    assert softening_only[-1] and not softening_only[0]
    assert np.all(s[~softening_only] == S_MIN) and np.all((s[softening_only] >= S_MIN) & (s[softening_only] <= 1))
    assert np.all(np.diff(m) >= 0) and np.all(np.diff(s) >= 0)
    # continuous where the branches meet
    k = np.flatnonzero(softening_only)[0]
    assert abs(m[k] - m[k - 1]) < 1e-4 and abs(s[k] - s[k - 1]) < 0.01


def test_a_ratio_that_is_not_positive_is_refused():
    I0, I1, _ = softening_moments(LAW, 1.025)
    with pytest.raises(ValueError, match="h0 / c"):
        equal_energy_law(0.025, 1.0, 0.0, I0, I1)
