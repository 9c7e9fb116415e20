"""Per-point damage laws in the surrogate (a strength scatter's field): a point with its own
critical stretch behaves like a fabric with that critical stretch, a softening scale like the
crack-band scale, and the table grows to hold the field's laws without changing a tile."""
import numpy as np
import pytest

from fabric_fenicsx.material.fabric import zylon_as
from fabric_fenicsx.material.scatter import DamageRange
from fabric_fenicsx.surrogate.table import Surrogate
from conftest import COARSE

FABRIC = zylon_as()
PATH = np.linspace(0.0, 0.11, 56)    # warp strain through complete failure, fill free of load


def loaded(sur, E2=0.005, **laws):
    """alpha1 and P1 along PATH, each step from the last one's damage."""
    a1, a2, out = 1.0, 1.0, []
    for e in PATH:
        p1, _, a1, a2 = sur.update(np.array([e]), np.array([E2]), np.array([a1]), np.array([a2]), **laws)
        a1, a2 = float(a1[0]), float(a2[0])
        out.append((a1, float(p1[0])))
    return np.array(out)


@pytest.fixture(scope="module")
def wide(surrogate_cache):
    """The coarse table grown to hold critical stretches 1.012 ... 1.04 and scales up to 1.3."""
    rng = DamageRange(np.array([1.012, 1.012]), np.array([1.04 + 1.3 * 0.03, 1.04 + 1.3 * 0.03]))
    return Surrogate(FABRIC, cache_dir=surrogate_cache, damage_range=rng, **COARSE)


def test_a_wider_damage_range_only_adds_tiles(wide, coarse_surrogate):
    assert wide.key == coarse_surrogate.key          # the same tiles, one cache
    assert wide.nE % wide.tile == 0 and wide.nE > coarse_surrogate.nE
    assert wide.E_fail[0] > coarse_surrogate.E_fail[0]
    n = coarse_surrogate.nE
    E = np.linspace(-0.05, coarse_surrogate.E_table[1] - 0.01, 7)
    E1, E2 = np.meshgrid(E, E)
    for a in (1.0, 0.4):
        assert np.array_equal(wide.lookup(E1.ravel(), E2.ravel(), np.full(49, a), np.ones(49)),
                              coarse_surrogate.lookup(E1.ravel(), E2.ravel(), np.full(49, a), np.ones(49)))
    assert n < wide.nE


@pytest.mark.parametrize("mu_crit", [1.015, 1.034])
def test_a_point_with_its_own_critical_stretch_is_a_fabric_with_it(wide, surrogate_cache, mu_crit):
    other = Surrogate(FABRIC.with_yarn("warp", mu_crit=mu_crit), cache_dir=surrogate_cache, **COARSE)
    mine = loaded(wide, critical_stretch=(mu_crit, FABRIC.fill.mu_crit))
    theirs = loaded(other)
    assert mine[:, 0].min() == 0.0 and mine[:, 0].max() == 1.0     # the path breaks the warp
    assert mine == pytest.approx(theirs, rel=1e-9, abs=1e-9)
    default = loaded(wide)
    assert not np.allclose(default[:, 0], mine[:, 0])


def test_a_softening_scale_is_the_crack_band_scale_and_may_exceed_one(wide):
    assert loaded(wide, softening_scale=(0.7, 1.0)) == pytest.approx(loaded(wide, crack_band=(0.7, 1.0)),
                                                                     rel=1e-12, abs=1e-12)
    longer = loaded(wide, softening_scale=(1.3, 1.0))
    broken = PATH[np.argmax(longer[:, 0] == 0.0)]
    assert broken > PATH[np.argmax(loaded(wide)[:, 0] == 0.0)]


def test_a_law_outside_the_tables_damage_range_is_refused(coarse_surrogate, wide):
    one = np.array([0.03])
    for laws in (dict(critical_stretch=(1.005, 1.03)), dict(softening_scale=(2.0, 1.0)),
                 dict(critical_stretch=(1.045, 1.03), softening_scale=(1.2, 1.0))):
        with pytest.raises(ValueError, match="damage range"):
            wide.update(one, one, np.ones(1), np.ones(1), **laws)
    with pytest.raises(ValueError, match="damage_range"):
        coarse_surrogate.update(one, one, np.ones(1), np.ones(1), critical_stretch=(1.02, 1.03))
