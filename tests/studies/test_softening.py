"""The work of a warp loaded through its damage softening (fabric_fenicsx.studies.softening):
the thesis's onset and failure strains, and the two measured facts that rule out a crack band
of one unit cell on the impact meshes (docs/mesh_independence.md)."""
import pytest

from fabric_fenicsx.studies.softening import softening_work


@pytest.fixture(scope="module")
def work(coarse_surrogate):
    return {s: softening_work(coarse_surrogate, s) for s in (1.0, 0.8, 0.5)}


def test_onset_and_failure_of_the_warp_in_uniaxial_strain_as_the_thesis(work):
    """Scenario 1 of chapter 3: warp damage starts at E1 ~ 0.049, failure complete at ~0.066."""
    w = work[1.0]
    assert w.E_onset == pytest.approx(0.049, abs=1e-3)
    assert w.E_failure == pytest.approx(0.066, abs=1.5e-3)      # coarse table: 0.0653


def test_the_work_before_damage_dominates_and_a_short_branch_snaps_back(work):
    """Measured on the coarse table: W_pre = 2748 J/m^2, W_soft = 727 J/m^2 (the default table:
    2749 and 719). A crack band of width l needs h (W_pre + W_soft(s)) = l (W_pre + W_soft(1)),
    impossible for h > 1.26 l whatever s. And W_soft(s) falls faster than s: 0.53 of the full
    branch at s = 0.8, nothing at s = 0.5, where the unit cell breaks in one step at onset."""
    full, short, half = work[1.0], work[0.8], work[0.5]
    assert full.pre > 3.0 * full.soft > 0.0
    assert short.soft < 0.7 * 0.8 * full.soft
    assert half.soft < 0.01 * full.soft and half.E_failure == half.E_onset
    assert short.pre == full.pre                   # the same path up to onset


def test_bad_scale_is_refused(coarse_surrogate):
    with pytest.raises(ValueError, match=r"scale must lie in \(0, 1\]"):
        softening_work(coarse_surrogate, 0.0)
