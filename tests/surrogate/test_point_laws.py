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
    three = np.full(3, 0.03)   # the first point outside is named, a NaN law among them
    with pytest.raises(ValueError, match="point 2, fill: critical stretch nan"):
        wide.update(three, three, np.ones(3), np.ones(3),
                    critical_stretch=(np.full(3, 1.03), np.array([1.03, 1.03, np.nan])))


def _kernel_update(sur, E1, E2, hist, mu_crit, band, skips=True):
    """damage_kernel.update of the points straight (tiles built by ``sur.update`` first): with the
    table's cell-level skips (its safe map, and each cell's top stretch against the point's own
    mu_crit), or, ``skips`` False, the full path where every point forms its target at the
    history and iterates where that target lies below it. Returns (P, alpha, status, counts)."""
    from fabric_fenicsx.surrogate.kernels import damage as damage_kernel
    from fabric_fenicsx.material.unitcell import ALPHA_BROKEN
    from fabric_fenicsx.surrogate.table import MU_MARGIN
    table = list(sur._table())
    top = (sur._mu_top["intact"], sur._mu_top["damaged"])
    if not skips:
        table[4], table[5] = np.zeros_like(table[4]), np.zeros_like(table[5])
        top = None
    n = E1.size
    P, alpha, residual, status = np.empty((n, 2)), np.empty((n, 2)), np.empty((n, 2)), np.empty(n, np.int8)
    counts = damage_kernel.update(E1, E2, hist[:, 0].copy(), hist[:, 1].copy(), tuple(table),
                                  sur._spec(("P1", "P2")), sur._spec(("mu1", "mu2")), sur._law,
                                  mu_crit, band, 2 * ALPHA_BROKEN, 1e-10, P, alpha, residual, status,
                                  top, MU_MARGIN)
    assert counts[1] == 0       # every tile was there
    return P, alpha, status, counts


def test_points_skipped_where_nothing_can_change_get_the_bits_of_the_full_path(wide):
    """Eq. 2-25 (alpha_i = min(alpha_i^hist, alpha(mu_i(E, alpha)))) is not iterated where the
    table cell cannot reach the point's own mu_crit, nor where the target at the history is the
    history (unloading, or the strains the history was made at). Over random states, each point
    with its own critical stretch and softening scale per yarn (a strength scatter), the skipped
    path must give the bits of the full path: intact and damaged histories (r = alpha_min /
    alpha_max below 1 couples the yarns' stretches), broken yarns, growing damage, unloading,
    and states at exactly the strains their history was made at."""
    rng = np.random.default_rng(43)
    n = 1500
    E1 = rng.uniform(-0.02, 0.075, n)
    E2 = rng.uniform(-0.02, 0.06, n)
    mu_crit = rng.uniform(1.012, 1.04, (n, 2))
    scale = rng.uniform(0.7, 1.3, (n, 2))
    kind = rng.integers(0, 5, n)   # intact, random damage, one yarn broken, equal damage, one yarn only
    hist = np.ones((n, 2))
    hist[kind == 1] = rng.uniform(0.02, 1.0, (np.count_nonzero(kind == 1), 2))
    hist[kind == 2, rng.integers(0, 2)] = 0.0
    hist[kind == 3] = rng.uniform(0.1, 1.0, (np.count_nonzero(kind == 3), 1))
    hist[kind == 4, 0] = rng.uniform(0.05, 1.0, np.count_nonzero(kind == 4))
    laws = dict(critical_stretch=tuple(mu_crit.T), softening_scale=tuple(scale.T))
    # histories made by the loading itself: at 1.1 x the strains (then unloaded to E) and at E
    made = np.stack(wide.update(1.1 * E1, 1.1 * E2, hist[:, 0], hist[:, 1], **laws)[2:], axis=1)
    again = np.stack(wide.update(E1, E2, hist[:, 0], hist[:, 1], **laws)[2:], axis=1)
    E1s, E2s = np.tile(E1, 3), np.tile(E2, 3)
    states = np.concatenate((hist, made, again))
    mu_crits, scales = np.tile(mu_crit, (3, 1)), np.tile(scale, (3, 1))
    wide.update(E1s, E2s, states[:, 0], states[:, 1], critical_stretch=tuple(mu_crits.T),
                softening_scale=tuple(scales.T))   # every tile the kernel needs
    band = scales.copy()
    skipped = _kernel_update(wide, E1s, E2s, states, mu_crits, band)
    full = _kernel_update(wide, E1s, E2s, states, mu_crits, band, skips=False)
    for a, b in zip(skipped[:3], full[:3]):
        np.testing.assert_array_equal(a, b)
    assert skipped[3][0] == full[3][0] > 100            # damage grew at many points
    alpha = skipped[1]
    unchanged = np.all(alpha == states, axis=1)
    assert np.count_nonzero(unchanged[n:] & np.any(states[n:] < 1.0, axis=1)) > 100  # unloaded, at E
    assert np.count_nonzero(~unchanged) > 100
    # the skip matters: many points are in cells that cannot reach their mu_crit
    flag = wide._values(E1s, E2s, states[:, 0], states[:, 1], ("P1",))[1]
    assert 0.2 < flag.mean() < 0.9
