"""The strength scatter's random field (fabric_fenicsx.material.scatter): keyed per segment,
the thesis's fibril statistics per segment, the Weibull model's median and modulus, and how a
cell reads the segments it covers."""
import math

import numpy as np
import pytest
from scipy import stats

from fabric_fenicsx.material.fabric import zylon_as
from fabric_fenicsx.material.fibril import ExponentialDamage, FibrilBundle, fit_beta
from fabric_fenicsx.material.scatter import (WEIBULL_MODULUS, StrengthScatter, cell_laws,
                                             fibril_draws, misalignment_for_beta, segment_index,
                                             segment_uniform)

FABRIC = zylon_as()


def square_cells(x0, y0, h, n):
    """n x n square cells of side h from (x0, y0), corners in perimeter order."""
    xs, ys = np.meshgrid(x0 + h * np.arange(n), y0 + h * np.arange(n), indexing="ij")
    lower_left = np.stack([xs.ravel(), ys.ravel()], 1)
    steps = np.array([[0, 0], [h, 0], [h, h], [0, h]])
    return lower_left[:, None, :] + steps[None]


def test_the_default_fabric_damage_law_is_eq_2_25_with_beta_124():
    """zylon_as() damages by Eq. 2-25 with the thesis's beta = 124 and width 0.03, written out
    here at stretches across the damage range of both yarns."""
    law = FABRIC.damage
    for yarn in FABRIC.yarns:
        mu_c = yarn.mu_crit
        mu = mu_c + np.array([-0.01, 0.0, 0.001, 0.005, 0.01, 0.02, 0.029, 0.03, 0.05])
        s = np.clip(mu - mu_c, 0.0, None)
        eq_2_25 = np.clip((np.exp(-124.0 * s) - np.exp(-0.03 * 124.0)) / (1 - np.exp(-0.03 * 124.0)), 0, 1)
        assert law.alpha(mu, mu_c) == pytest.approx(eq_2_25, abs=1e-14)


def test_keyed_uniforms_repeat_differ_per_key_and_are_uniform():
    yarn, seg = np.arange(-500, 500), np.arange(1000) * 7 - 3000
    u = segment_uniform(5, 0, yarn, seg)
    assert np.array_equal(u, segment_uniform(5, 0, yarn, seg))          # the same everywhere
    assert np.all((u > 0) & (u < 1))
    # any change of the key gives other numbers, uncorrelated with these
    for other in (segment_uniform(6, 0, yarn, seg), segment_uniform(5, 1, yarn, seg),
                  segment_uniform(5, 0, yarn + 1, seg), segment_uniform(5, 0, yarn, seg + 1),
                  segment_uniform(5, 0, yarn, seg, draw=1)):
        assert not np.any(other == u)
        assert abs(np.corrcoef(u, other)[0, 1]) < 0.12     # 1000 pairs: 3.8 sd of r
    big = segment_uniform(11, 1, np.repeat(np.arange(300), 300), np.tile(np.arange(300), 300))
    assert stats.kstest(big, "uniform").pvalue > 1e-3


def test_segment_indices_follow_the_yarn_spacing_and_the_material_angle():
    spacing = (2 * FABRIC.warp.w, 2 * FABRIC.fill.w)
    p = np.array([[0.5 * spacing[0], 1.5 * spacing[1]], [-0.5 * spacing[0], 0.2 * spacing[1]]])
    (a1, b1), (a2, b2) = segment_index(p, 0.0, spacing)
    assert list(a1) == [1, 0] and list(b1) == [0, -1]     # warp: yarn across d2, segment along d1
    assert list(a2) == [0, -1] and list(b2) == [1, 0]
    (c1, d1), _ = segment_index(p @ np.array([[0, 1], [-1, 0]]), 90.0, spacing)   # rotated by 90 deg
    assert list(c1) == list(a1) and list(d1) == list(b1)


def test_weibull_segments_have_the_thesis_median_and_the_stated_modulus():
    n = 40000
    mu, s = StrengthScatter("weibull", seed=2).segment_laws(FABRIC, 0, np.arange(n), np.zeros(n, int))
    strain = mu - 1.0
    median_sd = 1.2533 * strain.std() / math.sqrt(n)
    assert np.median(strain) == pytest.approx(FABRIC.warp.mu_crit - 1.0, abs=4 * median_sd)
    m, _, _ = stats.weibull_min.fit(strain, floc=0.0)
    assert m == pytest.approx(WEIBULL_MODULUS, rel=0.03)           # sd of the fit ~ 0.4 %
    assert np.all(s == 1.0)


def test_the_bundle_behind_beta_124_and_the_mean_of_1000_fibril_segments():
    """misalignment_for_beta runs the thesis's fit backwards; 1000 segments of n = 326 fibrils,
    each drawn by its key, have a mean alpha(mu) within the fit's own residual of Eq. 2-25
    (beta = 124) - the fit of the infinite bundle - and the spread between segments is stated."""
    U, law = FABRIC.warp.mu_crit, FABRIC.damage
    d = misalignment_for_beta(124.0, 0.03, U)
    mu = np.linspace(U, U + 0.03, 601)
    limit = FibrilBundle(d, n=1).alpha_limit(mu, U)
    beta, fit_rms = fit_beta(mu, limit, U, 0.03)
    assert beta == pytest.approx(124.0, rel=1e-9)
    n_fibrils, segments = 326, 1000
    alpha = np.zeros_like(mu)
    half, offsets = [], []
    for b in range(segments):
        r = fibril_draws(0, 0, 3, b, n_fibrils)          # the segment's own fibrils, as the field draws them
        rupture = np.sort(np.sqrt(U * U + (r * d) ** 2 * (U * U - 1)))
        a = 1.0 - np.searchsorted(rupture, mu, side="right") / n_fibrils
        alpha += a / segments
        half.append(rupture[n_fibrils // 2])
        offsets.append(np.mean(rupture - U))
    mean_vs_eq_2_25 = np.sqrt(np.mean((alpha - law.alpha(mu, U)) ** 2))
    assert mean_vs_eq_2_25 <= fit_rms
    # the spread of the stretch at half damage between segments: the median r of 326 fibrils has
    # sd 0.5 / sqrt(326) = 0.028, and mu* - U grows about as r^2: about 11 % of the offset
    assert 0.07 < np.std(half) / (np.mean(half) - U) < 0.15
    # the field's softening scale of each segment is its mean rupture offset over the bundle's
    _, scale = StrengthScatter("fibrils", seed=0).segment_laws(FABRIC, 0, np.full(segments, 3), np.arange(segments))
    ratio = scale / np.array(offsets)
    assert np.ptp(ratio) < 1e-12 * ratio.mean()


def test_fibril_segments_keep_the_critical_stretch_and_scale_the_softening():
    n = 5000
    mu, s = StrengthScatter("fibrils", seed=1).segment_laws(FABRIC, 1, np.arange(n), np.ones(n, int))
    assert np.all(mu == FABRIC.fill.mu_crit)
    assert abs(s.mean() - 1.0) < 4 * s.std() / math.sqrt(n)      # the bundle's mean
    assert 0.03 < s.std() < 0.08                                # ~ sd(g(r)) / sqrt(326)


def test_the_patch_rule_reads_the_weakest_segment_of_each_yarn_and_averages_over_yarns():
    sc = StrengthScatter("weibull", seed=4)
    w1, w2 = 2 * FABRIC.warp.w, 2 * FABRIC.fill.w
    # a cell of 2 x 2 unit cells exactly: warp yarns a = 0, 1, segments b = 0, 1
    corners = np.array([[[0, 0], [2 * w1, 0], [2 * w1, 2 * w2], [0, 2 * w2]]], float)
    seg = {(a, b): sc.segment_laws(FABRIC, 0, [a], [b])[0][0] for a in (0, 1) for b in (0, 1)}
    weakest = (min(seg[0, 0], seg[0, 1]), min(seg[1, 0], seg[1, 1]))
    for samples in (4, 40):
        mu, s = cell_laws(sc, FABRIC, 0.0, corners, samples_per_segment=samples, rule="patch")
        # each yarn weighs its share of the cell's sample grid: half, to within a grid line
        k = math.ceil(samples * math.hypot(2 * w1, 2 * w2) / min(w1, w2)) + 1
        assert mu[0, 0] == pytest.approx(0.5 * sum(weakest), abs=1.5 / k * abs(weakest[0] - weakest[1]))
        assert min(weakest) < mu[0, 0] < max(weakest)
    # a cell inside one segment reads that segment's law, whatever the mesh around it
    inside = np.array([[[0.1 * w1, 0.1 * w2], [0.4 * w1, 0.1 * w2], [0.5 * w1, 0.6 * w2], [0.1 * w1, 0.3 * w2]]])
    for rule in ("weakest", "patch", "yarn"):
        mu_in, _ = cell_laws(sc, FABRIC, 0.0, inside, rule=rule)
        assert mu_in[0, 0] == seg[0, 0]
    # scatter "none": the fabric's law in every cell
    mu0, s0 = cell_laws(StrengthScatter("none"), FABRIC, 0.0, square_cells(0, 0, 1e-3, 3))
    assert np.all(mu0 == [FABRIC.warp.mu_crit, FABRIC.fill.mu_crit]) and np.all(s0 == 1.0)


def test_the_field_at_fixed_points_is_the_same_on_two_meshes_and_at_two_angles():
    """Small cells around fixed reference points, cut from two different meshes (squares and
    skewed quadrilaterals of other sizes), read the same segment values; rotating the fabric
    rotates the field with it."""
    sc = StrengthScatter("weibull", seed=9)
    rng = np.random.default_rng(0)
    points = rng.uniform(-0.02, 0.02, (50, 2))
    w = min(FABRIC.warp.w, FABRIC.fill.w)
    square = points[:, None, :] + 0.05 * w * np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]])
    skew = points[:, None, :] + 0.03 * w * np.array([[-1, -0.5], [1.2, -1], [0.7, 1], [-0.9, 0.8]])
    for angle in (0.0, 37.0):
        a, _ = cell_laws(sc, FABRIC, angle, square)
        b, _ = cell_laws(sc, FABRIC, angle, skew)
        (ia, ib), (ja, jb) = segment_index(points, angle, (2 * FABRIC.warp.w, 2 * FABRIC.fill.w))
        direct = sc.segment_laws(FABRIC, 0, ia, ib)[0]
        near_edge = np.zeros(len(points), bool)   # a small cell may straddle a segment boundary
        for shift in 0.1 * w * np.array([[1, 0], [-1, 0], [0, 1], [0, -1]]):
            (sa, sb), _ = segment_index(points + shift, angle, (2 * FABRIC.warp.w, 2 * FABRIC.fill.w))
            near_edge |= (sa != ia) | (sb != ib)
        assert near_edge.sum() < 25
        assert np.array_equal(a[~near_edge, 0], direct[~near_edge])
        assert np.array_equal(b[~near_edge, 0], direct[~near_edge])


def test_bad_scatter_settings_are_refused_with_the_key_named():
    for kwargs, key in ((dict(model="gauss"), "material.scatter"), (dict(seed=-1), "material.seed"),
                        (dict(weibull_modulus=0.0), "material.weibull_modulus"),
                        (dict(fibrils=0), "material.fibrils")):
        with pytest.raises(ValueError, match=key):
            StrengthScatter(**kwargs)
    with pytest.raises(ValueError, match="exponential"):
        from fabric_fenicsx.material.fibril import BundleDamage
        StrengthScatter("fibrils").segment_laws(FABRIC.replace(damage=BundleDamage.for_width(n=10)),
                                                0, [0], [0])


def test_the_yarn_and_weakest_rules_read_the_centre_yarn_and_the_weakest_segment():
    sc = StrengthScatter("weibull", seed=4)
    w1, w2 = 2 * FABRIC.warp.w, 2 * FABRIC.fill.w
    # warp yarns 0 and 1 (y < w2 and y > w2), segments 0 and 1; the centre lies on yarn 1
    corners = np.array([[[0.1 * w1, 0.3 * w2], [1.9 * w1, 0.3 * w2], [1.9 * w1, 1.9 * w2], [0.1 * w1, 1.9 * w2]]])
    mu, _ = cell_laws(sc, FABRIC, 0.0, corners, rule="yarn")
    seg = sc.segment_laws(FABRIC, 0, [1, 1], [0, 1])[0]
    assert mu[0, 0] == min(seg)
    weakest, _ = cell_laws(sc, FABRIC, 0.0, corners, rule="weakest")
    every = sc.segment_laws(FABRIC, 0, [0, 0, 1, 1], [0, 1, 0, 1])[0]
    assert weakest[0, 0] == min(every)
    with pytest.raises(ValueError, match="rule"):
        cell_laws(sc, FABRIC, 0.0, corners, rule="centre")
