"""The compiled passes of YarnStress.update (fabric_fenicsx.surrogate.kernels.yarn_stress) against
the numpy expressions they replace, bit for bit over random inputs: the table's clip, the strains
as given where the tension field leaves them, the live points' gathers and peak strains, the
scatter of the tension field's strains, the yarn stresses with their viscous part, and the yarn
tensions."""
import numpy as np
import pytest

from fabric_fenicsx.surrogate.kernels import yarn_stress as kernel

LO, HI = -0.062, 0.176


def same(x, y):
    x, y = np.asarray(x), np.asarray(y)
    return x.dtype == y.dtype and x.shape == y.shape and x.tobytes() == y.tobytes()


def strains(rng, n):
    """Strains inside and beyond the table, with zeros of both signs, NaN and the table's ends."""
    E = rng.uniform(-0.1, 0.25, n)
    for value, share in ((0.0, 0.05), (-0.0, 0.05), (np.nan, 0.02), (LO, 0.02), (HI, 0.02)):
        E[rng.random(n) < share] = value
    return E


def test_clip_and_keep_given_equal_numpy():
    rng = np.random.default_rng(1)
    for n in (0, 1, 7, 1000):
        E1, E2 = strains(rng, n), strains(rng, n)
        c1, c2 = np.empty(n), np.empty(n)
        kernel.clip(E1, E2, LO, HI, c1, c2)
        C1, C2 = (np.minimum(np.maximum(E, LO), HI) for E in (E1, E2))
        assert same(c1, C1) and same(c2, C2)
        # the tension field moves some clipped strains, others stay (exactly) as clipped
        r1, r2 = C1.copy(), C2.copy()
        moved1, moved2 = rng.random(n) < 0.4, rng.random(n) < 0.4
        r1[moved1] = rng.uniform(-0.05, 0.01, int(moved1.sum()))
        r2[moved2] = 0.0   # also where the clipped strain is a zero of either sign
        expected = np.where(r1 != C1, r1, E1), np.where(r2 != C2, r2, E2)
        kernel.keep_given(r1, r2, E1, E2, LO, HI)
        assert same(r1, expected[0]) and same(r2, expected[1])


@pytest.mark.parametrize("removed", [0.0, 0.3])
def test_live_inputs_and_put_live_equal_numpy(removed):
    rng = np.random.default_rng(2)
    for n in (0, 1, 9, 800):
        E1, E2 = strains(rng, n), strains(rng, n)
        a1, a2 = rng.random(n), rng.random(n)
        relaxed = rng.uniform(-0.05, 0.05, (2, n))
        peak = np.stack([strains(rng, n), strains(rng, n)])
        peak[:, rng.random(n) < 0.2] = -0.0   # ties of opposite zeros: numpy keeps the second
        peak[:, rng.random(n) < 0.2] = 0.0
        idx = np.flatnonzero(rng.random(n) >= removed)
        expected_peak = peak.copy()
        for row, E in zip(expected_peak, (E1, E2)):
            row[idx] = np.maximum(row[idx], E[idx])
        m = idx.size
        e1, e2, h1, h2, guess = np.empty(m), np.empty(m), np.empty(m), np.empty(m), np.empty((2, m))
        kernel.live_inputs(idx, E1, E2, a1, a2, relaxed, peak, e1, e2, h1, h2, guess)
        assert same(peak, expected_peak)
        assert all(same(x, y[idx]) for x, y in ((e1, E1), (e2, E2), (h1, a1), (h2, a2)))
        assert same(guess, relaxed[:, idx])
        r1, r2 = rng.random(m), rng.random(m)
        expected = relaxed.copy()
        expected[0, idx], expected[1, idx] = r1, r2
        kernel.put_live(idx, r1, r2, relaxed)
        assert same(relaxed, expected)


def numpy_stresses(E1, E2, live, p1, p2, ref, E_lo, beta_over_dt, w, lam_prev, P_v_prev):
    """The yarn stresses in numpy: slack rule, viscous stress, stretches, and the viscous work
    summed point after point (as the kernel sums)."""
    idx = np.flatnonzero(live)
    slack1 = (E1 < E_lo) | ((E1 < 0.0) & (E2 <= 0.0))
    slack2 = (E2 < E_lo) | ((E2 < 0.0) & (E1 <= 0.0))
    P_el, P_v = np.zeros((2, E1.size)), np.zeros((2, E1.size))
    P_el[0, idx] = np.where(slack1[idx], 0.0, p1)
    P_el[1, idx] = np.where(slack2[idx], 0.0, p2)
    if beta_over_dt > 0.0:
        q = P_el[:, idx]
        P_v[:, idx] = np.maximum(q + beta_over_dt * (q - ref[:, idx]), 0.0) - q
    lam = np.sqrt(1.0 + 2.0 * np.stack((E1, E2)))
    terms = w * (0.5 * (P_v[0] + P_v_prev[0]) * (lam[0] - lam_prev[0])
                 + 0.5 * (P_v[1] + P_v_prev[1]) * (lam[1] - lam_prev[1]))
    work = 0.0
    for t in terms:
        work += t
    below = int(np.count_nonzero(((E1 < E_lo) | (E2 < E_lo))[idx]))
    slack_tension = int(np.count_nonzero(((slack1[idx]) & (p1 > 0.0)) | ((slack2[idx]) & (p2 > 0.0))))
    return P_el, P_v, lam, P_el + P_v, (below, slack_tension, work)


@pytest.mark.parametrize("beta_over_dt", [0.0, 37.5])
def test_stresses_equal_numpy(beta_over_dt):
    rng = np.random.default_rng(3)
    for n in (0, 1, 6, 700):
        E1, E2 = rng.uniform(-0.08, 0.1, (2, n))
        live = rng.random(n) < 0.8
        m = int(live.sum())
        p1, p2 = rng.uniform(-1e3, 5e4, (2, m))
        ref, P_v_prev = rng.uniform(0.0, 5e4, (2, 2, n))
        lam_prev = np.sqrt(1.0 + 2.0 * rng.uniform(-0.08, 0.1, (2, n)))
        w = rng.uniform(1e-6, 2e-6, n)
        out = [np.empty((2, n)) for _ in range(4)]
        counts = kernel.stresses(E1, E2, live, p1, p2, ref, LO, beta_over_dt, w, lam_prev, P_v_prev,
                                 *out)
        *expected, expected_counts = numpy_stresses(E1, E2, live, p1, p2, ref, LO, beta_over_dt, w,
                                                    lam_prev, P_v_prev)
        assert all(same(x, y) for x, y in zip(out, expected))
        assert counts[:2] == expected_counts[:2] and same(counts[2], expected_counts[2])


def test_tension_equals_numpy():
    rng = np.random.default_rng(4)
    for n in (0, 1, 5, 900):
        P_el = rng.uniform(-1e3, 5e4, (2, n))
        lam = rng.uniform(0.5, 1.5, (2, n))
        for value, share in ((0.0, 0.05), (-0.0, 0.05), (np.nan, 0.03), (np.inf, 0.01)):
            P_el[rng.random((2, n)) < share] = value
        for value, share in ((0.0, 0.05), (-0.0, 0.05), (np.nan, 0.03), (-0.2, 0.03),
                             (np.inf, 0.01), (1e-310, 0.02)):
            lam[rng.random((2, n)) < share] = value
        T = np.full((2, n), 7.0)
        kernel.tension(P_el, lam, T)
        with np.errstate(over="ignore", invalid="ignore"):   # 1e-310 and inf divide too
            expected = np.divide(P_el, lam, out=np.zeros_like(P_el), where=lam > 0.0)
        assert same(T, expected)
