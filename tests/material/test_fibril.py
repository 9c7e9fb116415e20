"""Tests of the fibril scale (thesis section 2.3, Eq. 2-22 to 2-25, A.12)."""
import math

import numpy as np
import pytest

from fabric_fenicsx.material.fibril import (
    BundleDamage,
    ExponentialDamage,
    FibrilBundle,
    damage_law_from_dict,
    damage_update,
    fit_beta,
)

MU_CRIT = 1.025  # warp, Table 1


def _laws():
    return [ExponentialDamage(), ExponentialDamage(beta=20.0, width=0.05),
            BundleDamage.for_width(0.03, MU_CRIT, n=2000, seed=1)]


# ------------------------------------------------------------------ shared law properties
@pytest.mark.parametrize("law", _laws(), ids=lambda l: l.to_dict()["law"])
def test_alpha_one_below_crit_zero_beyond_complete(law):
    mu_below = np.linspace(0.5, MU_CRIT, 50)
    assert np.all(law.alpha(mu_below[:-1], MU_CRIT) == 1.0)
    mu_c = law.mu_complete(MU_CRIT)
    mu_beyond = np.linspace(mu_c, mu_c + 0.5, 50)
    assert np.all(law.alpha(mu_beyond, MU_CRIT) == 0.0)
    # and something happens in between
    mid = law.alpha(0.5 * (MU_CRIT + mu_c), MU_CRIT)
    assert 0.0 < mid < 1.0


@pytest.mark.parametrize("law", _laws(), ids=lambda l: l.to_dict()["law"])
def test_alpha_monotone_non_increasing(law):
    mu = np.sort(np.random.default_rng(3).uniform(0.9, law.mu_complete(MU_CRIT) + 0.01, 4000))
    a = law.alpha(mu, MU_CRIT)
    assert np.all(np.diff(a) <= 0.0)
    assert np.all((a >= 0.0) & (a <= 1.0))


@pytest.mark.parametrize("law", _laws(), ids=lambda l: l.to_dict()["law"])
def test_to_dict_round_trip(law):
    rebuilt = damage_law_from_dict(law.to_dict())
    assert rebuilt.to_dict() == law.to_dict()
    mu = np.linspace(1.0, 1.1, 301)
    assert np.array_equal(rebuilt.alpha(mu, MU_CRIT), law.alpha(mu, MU_CRIT))


# ------------------------------------------------------------------ exponential law
def test_exponential_matches_eq_2_25_and_is_continuous():
    law = ExponentialDamage(beta=124.0, width=0.03)
    s = np.linspace(1e-4, 0.03 - 1e-4, 97)
    ref = (np.exp(-124.0 * s) - np.exp(-0.03 * 124.0)) / (1.0 - np.exp(-0.03 * 124.0))
    np.testing.assert_allclose(law.alpha(MU_CRIT + s, MU_CRIT), ref, rtol=1e-12, atol=1e-15)
    eps = 1e-10
    assert law.alpha(MU_CRIT + eps, MU_CRIT) == pytest.approx(1.0, abs=1e-7)
    assert law.alpha(MU_CRIT + 0.03 - eps, MU_CRIT) == pytest.approx(0.0, abs=1e-7)
    assert law.mu_complete(MU_CRIT) == MU_CRIT + 0.03


def test_exponential_small_beta_tends_to_linear():
    law = ExponentialDamage(beta=1e-9, width=0.03)
    s = np.linspace(0.001, 0.029, 29)
    np.testing.assert_allclose(law.alpha(MU_CRIT + s, MU_CRIT), 1.0 - s / 0.03, rtol=1e-7)


def test_exponential_large_beta_finite():
    a = ExponentialDamage(beta=1e5).alpha(MU_CRIT + np.linspace(0, 0.03, 31), MU_CRIT)
    assert np.all(np.isfinite(a)) and a[0] == 1.0 and a[-1] == 0.0


@pytest.mark.parametrize("beta", [10.0, 124.0, 400.0])
def test_dalpha_dmu_against_finite_difference(beta):
    law = ExponentialDamage(beta=beta)
    mu = MU_CRIT + np.linspace(0.001, 0.029, 57)
    h = 1e-7
    fd = (law.alpha(mu + h, MU_CRIT) - law.alpha(mu - h, MU_CRIT)) / (2 * h)
    np.testing.assert_allclose(law.dalpha_dmu(mu, MU_CRIT), fd, rtol=1e-6)
    outside = np.array([0.9, MU_CRIT - 1e-3, MU_CRIT + 0.031, 2.0])
    assert np.all(law.dalpha_dmu(outside, MU_CRIT) == 0.0)


# ------------------------------------------------------------------ history (Eq. 2-25 / A.12)
@pytest.mark.parametrize("law", _laws()[::2], ids=lambda l: l.to_dict()["law"])
def test_damage_update_load_unload_reload(law):
    # load to 1.04, unload to 1.0, reload to 1.05: mu_max is the history maximum
    path = np.concatenate([np.linspace(1.0, 1.04, 41), np.linspace(1.04, 1.0, 41),
                           np.linspace(1.0, 1.05, 51)])
    mu_max = np.maximum.accumulate(path)
    alpha = 1.0
    history = []
    for m in mu_max:
        alpha = damage_update(alpha, m, law, MU_CRIT)
        history.append(float(alpha))
    history = np.array(history)
    assert np.all(np.diff(history) <= 0.0)
    # unloading keeps the damage reached at 1.04
    unload = slice(41, 82)
    assert np.all(history[unload] == law.alpha(1.04, MU_CRIT))
    # damage depends on the path only through mu_max
    np.testing.assert_array_equal(history, law.alpha(mu_max, MU_CRIT))


def test_damage_update_respects_history_and_broadcasts():
    law = ExponentialDamage()
    alpha_hist = np.array([1.0, 0.2, 0.9, 0.0])
    mu_max = np.array([1.0, 1.03, 1.03, 1.03])
    out = damage_update(alpha_hist, mu_max, law, MU_CRIT)
    expected = np.minimum(alpha_hist, law.alpha(mu_max, MU_CRIT))
    np.testing.assert_array_equal(out, expected)
    assert out[1] == 0.2 and out[3] == 0.0  # history smaller than the law wins
    assert np.all(out <= alpha_hist)
    assert damage_update(np.full((3, 4), 0.5), mu_max, law, MU_CRIT).shape == (3, 4)


# ------------------------------------------------------------------ statistical bundle
def _brute_force(d0_over_h0, n, seed, mu, U_crit):
    """(m, n) evaluation of Eq. 2-22 / 2-23 in draw order."""
    x = np.random.default_rng(seed).random(n) * d0_over_h0
    U = np.sqrt(mu[:, None] ** 2 + x[None, :] ** 2) / np.sqrt(1.0 + x[None, :] ** 2)
    rho = U < U_crit
    alpha = rho.mean(axis=1)
    e_ratio = (rho / (1.0 + x[None, :] ** 2) ** 1.5).sum(axis=1) / n
    return alpha, e_ratio


@pytest.mark.parametrize("U_crit", [1.025, 1.0297, 1.03])
def test_bundle_matches_brute_force(U_crit):
    bundle = FibrilBundle(0.9, n=300, seed=7)
    mu = np.random.default_rng(11).uniform(0.95, bundle.mu_complete(U_crit) + 0.01, 500)
    alpha_bf, e_bf = _brute_force(0.9, 300, 7, mu, U_crit)
    # one fibril is a step of 1/300, far above the rounding tolerance
    np.testing.assert_allclose(bundle.alpha(mu, U_crit), alpha_bf, rtol=0, atol=1e-14)
    np.testing.assert_allclose(bundle.effective_modulus_ratio(mu, U_crit), e_bf,
                               rtol=1e-12, atol=1e-15)
    assert np.unique(alpha_bf).size > 50  # the comparison covers many rupture states


def test_rupture_stretch_breaks_fibril():
    U_crit = 1.03
    bundle = FibrilBundle(1.2, n=50, seed=2)
    x = bundle.x_sorted
    mu_star = bundle.rupture_stretch(U_crit)
    U = np.sqrt(mu_star ** 2 + x ** 2) / np.sqrt(1 + x ** 2)  # Eq. 2-22 at mu_j*
    np.testing.assert_allclose(U, U_crit, rtol=1e-14)
    assert np.all(np.diff(mu_star) >= 0.0)


@pytest.mark.parametrize("U_crit", [1.025, 1.0297, 1.03])
def test_for_width_reaches_zero_at_mu_complete(U_crit):
    bundle = FibrilBundle.for_width(0.03, U_crit, n=5000, seed=0)
    assert bundle.mu_complete(U_crit) == pytest.approx(U_crit + 0.03, rel=1e-14)
    assert bundle.alpha(bundle.mu_complete(U_crit), U_crit) == 0.0
    # the sample's last rupture lies within the range, and close to its end
    last = bundle.rupture_stretch(U_crit)[-1]
    assert U_crit < last <= U_crit + 0.03
    assert bundle.alpha(last - 1e-12, U_crit) == pytest.approx(1.0 / 5000)
    assert bundle.alpha(U_crit, U_crit) == 1.0


def test_bundle_converges_to_sqrt_onset_limit():
    U_crit = 1.025
    bundle = FibrilBundle.for_width(0.03, U_crit, n=20000, seed=0)
    mu = np.linspace(U_crit, U_crit + 0.03, 301)
    dev = np.abs(bundle.alpha(mu, U_crit) - bundle.alpha_limit(mu, U_crit)).max()
    assert dev < 4.0 / math.sqrt(bundle.n)  # Kolmogorov-Smirnov scale, far above the typical 1/sqrt(n)


def test_effective_modulus_ratio_undamaged_then_decreasing():
    U_crit = 1.025
    bundle = FibrilBundle.for_width(0.03, U_crit, n=20000, seed=4)
    undamaged = np.mean((1.0 + bundle.x_sorted ** 2) ** -1.5)
    below = np.linspace(0.98, U_crit - 1e-9, 20)
    np.testing.assert_allclose(bundle.effective_modulus_ratio(below, U_crit), undamaged, rtol=1e-13)
    # infinite-bundle closed form: integral_0^1 (1 + x0^2 r^2)^{-3/2} dr = 1 / sqrt(1 + x0^2)
    assert undamaged == pytest.approx(1.0 / math.sqrt(1.0 + bundle.d0_over_h0 ** 2), abs=5e-3)
    mu = np.linspace(U_crit, U_crit + 0.03, 200)
    e = bundle.effective_modulus_ratio(mu, U_crit)
    assert np.all(np.diff(e) <= 0.0)
    assert e[100] < undamaged and e[-1] == 0.0
    # the aligned (stiffest) fibrils break first, so stiffness drops faster than alpha
    assert np.all(e / undamaged <= bundle.alpha(mu, U_crit) + 1e-12)


def test_aligned_bundle_breaks_all_at_once():
    bundle = FibrilBundle(0.0, n=10, seed=0)
    assert bundle.alpha(1.0299, 1.03) == 1.0 and bundle.alpha(1.03, 1.03) == 0.0


def test_bundle_damage_uses_mu_crit_as_fibril_crit():
    law = BundleDamage.for_width(0.03, 1.0297, n=1000, seed=3)
    mu = np.linspace(1.0, 1.07, 71)
    np.testing.assert_array_equal(law.alpha(mu, 1.0297), law.bundle.alpha(mu, 1.0297))
    with pytest.raises(NotImplementedError):
        law.dalpha_dmu(mu, 1.0297)


# ------------------------------------------------------------------ fit of beta
@pytest.mark.parametrize("beta", [80.0, 124.0])
def test_fit_beta_recovers_known_beta(beta):
    law = ExponentialDamage(beta=beta)
    mu = np.linspace(MU_CRIT - 0.01, MU_CRIT + 0.04, 200)  # samples outside the range are ignored
    fitted, rms = fit_beta(mu, law.alpha(mu, MU_CRIT), MU_CRIT)
    assert fitted == pytest.approx(beta, rel=1e-6)
    assert rms < 1e-10


def test_fit_beta_of_bundle_is_positive_and_imperfect():
    U_crit = 1.03
    bundle = FibrilBundle.for_width(0.03, U_crit, n=20000, seed=0)
    mu = np.linspace(U_crit, U_crit + 0.03, 301)
    beta, rms = fit_beta(mu, bundle.alpha(mu, U_crit), U_crit)
    assert beta > 0.0
    # the sqrt onset cannot be matched by an exponential: the residual is far above sampling noise
    assert rms > 3.0 / math.sqrt(bundle.n)
    # and the fit is a true minimum: perturbing beta raises the residual
    a = bundle.alpha(mu, U_crit)
    for b in (0.9 * beta, 1.1 * beta):
        assert np.sqrt(np.mean((ExponentialDamage(b).alpha(mu, U_crit) - a) ** 2)) > rms


# ------------------------------------------------------------------ bad input
# Each bad input raises a ValueError whose message names the argument and what is valid (the
# pattern), not an error of Python or numpy on the way (e.g. float("abc")).
@pytest.mark.parametrize("make, message", [
    (lambda: ExponentialDamage(beta=0.0), r"beta must be finite and > 0, got 0\.0"),
    (lambda: ExponentialDamage(beta=-1.0), r"beta must be finite and > 0, got -1\.0"),
    (lambda: ExponentialDamage(beta=float("inf")), r"beta must be finite and > 0, got inf"),
    (lambda: ExponentialDamage(width=0.0), r"width must be finite and > 0, got 0\.0"),
    (lambda: ExponentialDamage(width=float("nan")), r"width must be finite and > 0, got nan"),
    (lambda: ExponentialDamage(beta="abc"), r"beta must be a real number, got 'abc'"),
    (lambda: FibrilBundle(-0.1), r"d0_over_h0 must be finite and >= 0, got -0\.1"),
    (lambda: FibrilBundle(float("nan")), r"d0_over_h0 must be finite and >= 0, got nan"),
    (lambda: FibrilBundle("abc"), r"d0_over_h0 must be a real number, got 'abc'"),
    (lambda: FibrilBundle(1.0, n=0), r"n must be an integer >= 1, got 0"),
    (lambda: FibrilBundle(1.0, n=2.5), r"n must be an integer >= 1, got 2\.5"),
    (lambda: FibrilBundle(1.0, seed=-1), r"seed must be an integer >= 0, got -1"),
    (lambda: FibrilBundle.for_width(width=-0.03), r"width must be finite and > 0, got -0\.03"),
    (lambda: FibrilBundle.for_width(U_crit=1.0), r"U_crit must be a finite critical stretch > 1, got 1\.0"),
    (lambda: BundleDamage(1.0, n=0), r"n must be an integer >= 1, got 0"),
    (lambda: ExponentialDamage().alpha(1.03, 0.99), r"mu_crit must be a finite critical stretch > 1, got 0\.99"),
    (lambda: ExponentialDamage().alpha(1.03, "x"), r"mu_crit must be a real number, got 'x'"),
    (lambda: ExponentialDamage().alpha([1.03, np.nan], 1.025), r"mu contains non-finite values \(e\.g\. nan\)"),
    (lambda: ExponentialDamage().alpha(0.0, 1.025), r"mu must be a stretch > 0, got minimum 0\.0"),
    (lambda: ExponentialDamage().alpha("abc", 1.025), r"mu must be a real number or an array of them, got 'abc'"),
    (lambda: FibrilBundle(1.0, n=10).alpha(1.03, 1.0), r"U_crit must be a finite critical stretch > 1, got 1\.0"),
    (lambda: FibrilBundle(1.0, n=10).alpha(np.nan, 1.03), r"mu contains non-finite values \(e\.g\. nan\)"),
    (lambda: FibrilBundle(1.0, n=10).effective_modulus_ratio(np.inf, 1.03),
     r"mu contains non-finite values \(e\.g\. inf\)"),
    (lambda: damage_law_from_dict({"law": "weibull"}), r"law must be one of \['bundle', 'exponential'\], got 'weibull'"),
    (lambda: damage_law_from_dict({"law": "exponential", "gamma": 1.0}),
     r"unknown parameter\(s\) \['gamma'\] for law 'exponential'; valid: \['beta', 'width'\]"),
    (lambda: damage_law_from_dict({"law": "bundle"}), r"law 'bundle' needs d0_over_h0"),
    (lambda: damage_law_from_dict("exponential"), r"damage law description must be a dict, got 'exponential'"),
    (lambda: fit_beta([1.03, 1.04], [1.0], 1.025), r"mu and alpha must be 1-D of equal length, got shapes \(2,\) and \(1,\)"),
    (lambda: fit_beta([1.03, 1.04], [0.5, np.nan], 1.025), r"fit_beta: mu or alpha contains non-finite values"),
    (lambda: fit_beta([1.03, 1.04], [0.5, 1.5], 1.025), r"fit_beta: alpha must lie in \[0, 1\], got range \[0\.5, 1\.5\]"),
    (lambda: fit_beta([1.0, 1.03, 1.1], [1.0, 0.5, 0.0], 1.025),   # one sample in the range
     r"fit_beta: need >= 2 samples with mu in \(1\.025, 1\.055\), got 1"),
    (lambda: fit_beta("ab", [1.0], 1.025), r"fit_beta: mu must be a real number or an array of them, got 'ab'"),
])
def test_bad_input_raises_value_error(make, message):
    with pytest.raises(ValueError, match=message):
        make()


@pytest.mark.parametrize("alpha_hist, mu_max, message", [
    (np.nan, 1.03, r"damage_update: alpha_hist contains NaN"),
    (np.array([1.0, np.nan]), 1.0, r"damage_update: alpha_hist contains NaN"),
    (1.5, 1.0, r"damage_update: alpha_hist must lie in \[0, 1\], got range \[1\.5, 1\.5\]"),
    (-0.1, 1.0, r"damage_update: alpha_hist must lie in \[0, 1\]"),
    ("a", 1.0, r"damage_update: alpha_hist must be a real number or an array of them, got 'a'"),
    (1.0, np.nan, r"mu contains non-finite values \(e\.g\. nan\)"),
    (1.0, -1.0, r"mu must be a stretch > 0, got minimum -1\.0"),
    (1.0, np.inf, r"mu contains non-finite values \(e\.g\. inf\)"),
])
def test_damage_update_rejects_bad_input(alpha_hist, mu_max, message):
    with pytest.raises(ValueError, match=message):
        damage_update(alpha_hist, mu_max, ExponentialDamage(), MU_CRIT)


def test_error_messages_name_field_and_value():
    with pytest.raises(ValueError, match=r"beta.*-3"):
        ExponentialDamage(beta=-3.0)
    with pytest.raises(ValueError, match=r"law.*bundle.*exponential.*weibull"):
        damage_law_from_dict({"law": "weibull"})
