"""The Allan-variance engine against allantools, its own references, and statistics."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import stats

from avbench.estimators import RecursiveAllan, StreamingAllan, allan_variance
from avbench.estimators.allan.variance import (
    _avar_sums_numpy,
    _interval,
    _oavar_sums_numpy,
    cluster_sizes,
    edf_overlapping,
    recursive_avar,
)
from avbench.estimators.allan import _kernels as kernels
from avbench.noise_models import AngleRandomWalk, Gyro, presets

allantools = pytest.importorskip("allantools")


@pytest.fixture(scope="module")
def record():
    return presets.get("CRG20").simulate(20_000, np.random.default_rng(3)) + 0.01


@pytest.mark.parametrize("taus", ["octave", "decade", "all"])
def test_matches_allantools_oadev(record, taus):
    rate = 10.0
    t, ad, _, _ = allantools.oadev(record, rate=rate, data_type="freq", taus=taus)
    av = allan_variance(record, 1 / rate, taus=t, overlapping=True)
    np.testing.assert_allclose(av.tau, t)
    np.testing.assert_allclose(av.avar, ad**2, rtol=1e-10)


def test_matches_allantools_adev_nonoverlapping(record):
    t, ad, _, _ = allantools.adev(record, rate=10.0, data_type="freq", taus="octave")
    av = allan_variance(record, 0.1, taus=t, overlapping=False)
    np.testing.assert_allclose(av.avar, ad**2, rtol=1e-10)


def test_kernels_match_numpy_references(record):
    S = np.concatenate(([0.0], np.cumsum(record - record.mean())))
    m = cluster_sizes("all", record.size, 0.1)[::37]
    np.testing.assert_allclose(kernels.oavar_sums(S, m), _oavar_sums_numpy(S, m), rtol=1e-11)
    np.testing.assert_allclose(kernels.avar_sums(S, m), _avar_sums_numpy(S, m), rtol=1e-11)


def test_nonoverlapping_is_lv_eq2_as_written():
    x = np.random.default_rng(0).standard_normal(1001)
    for m in (1, 3, 10, 500):
        J = x.size // m
        w = [x[k * m : (k + 1) * m].mean() for k in range(J)]
        ref = sum((w[k + 1] - w[k]) ** 2 for k in range(J - 1)) / (2 * (J - 1))
        av = allan_variance(x, 1.0, taus=[float(m)], overlapping=False)
        assert av.avar[0] == pytest.approx(ref, rel=1e-12)
        assert av.J[0] == J
        assert av.rel_error[0] == pytest.approx(1 / np.sqrt(2 * (J - 1)))


def test_grids():
    n, dt = 1000, 0.5
    assert list(cluster_sizes("octave", n, dt)) == [1, 2, 4, 8, 16, 32, 64, 128, 256]
    assert cluster_sizes("all", n, dt)[-1] == n // 2
    dec = cluster_sizes("decade", n, dt, points_per_decade=5)
    assert dec[0] == 1 and dec[-1] <= n // 2 and np.all(np.diff(dec) > 0)


@pytest.mark.parametrize(
    "kwargs, msg",
    [
        (dict(taus=[1000.0]), "exceed half the record"),
        (dict(taus=[0.15]), "multiples of dt"),
        (dict(taus="weekly"), "taus"),
        (dict(dt=0.0), "dt"),
        (dict(dt=float("nan")), "dt"),
    ],
)
def test_bad_input(kwargs, msg):
    x = np.zeros(100)
    args = dict(rate=x, dt=0.1)
    args.update(kwargs)
    with pytest.raises(ValueError, match=msg):
        allan_variance(**args)


def test_bad_records():
    with pytest.raises(ValueError, match="non-finite"):
        allan_variance(np.array([0.0] * 20 + [np.nan]), 0.1)
    with pytest.raises(ValueError, match="1-D"):
        allan_variance(np.zeros((20, 2)), 0.1)
    with pytest.raises(ValueError, match="at least 16"):
        allan_variance(np.zeros(3), 0.1)
    with pytest.raises(ValueError, match="numeric"):
        allan_variance(np.array(["a"] * 20), 0.1)


def test_streaming_equals_batch(record):
    one = allan_variance(record, 0.1, "octave", overlapping=False)
    for parts in (1, 3, 1000):
        acc = StreamingAllan(dt=0.1)
        for c in np.array_split(record, parts):
            acc.update(c)
        res = acc.result()
        np.testing.assert_array_equal(res.m, one.m)
        np.testing.assert_allclose(res.avar, one.avar, rtol=1e-9)


def test_recursive_avar_is_miao_eq_3_4_as_written():
    """Per-sample recursion of Miao et al. 2014, eqs 3.3-3.4, against the vectorised form."""
    x = np.random.default_rng(2).standard_normal(600)
    for m in (1, 4):
        ref = []
        delta2, prev, k = 0.0, None, 0
        for j in range(x.size // m):
            wbar = 0.0
            for i in range(1, m + 1):  # eq. 3.3
                wbar = (i - 1) / i * wbar + x[j * m + i - 1] / i
            k += 1
            if k >= 2:  # eq. 3.4
                delta2 = (k - 2) / (k - 1) * delta2 + (wbar - prev) ** 2 / (2 * (k - 1))
                ref.append(delta2)
            prev = wbar
        np.testing.assert_allclose(recursive_avar(x, m), ref, rtol=1e-12)
        ra = RecursiveAllan(m)
        got = np.concatenate([ra.update(c) for c in np.array_split(x, 7)])
        np.testing.assert_allclose(got, ref, rtol=1e-12)


def test_edf_predicts_the_spread_of_overlapping_av():
    """Var over replicates of the overlapping AV of white FM ~ 2 AV^2 / edf (NIST SP 1065 Table 5).

    The sample variance of R replicates is tested against the predicted variance with a chi^2
    interval (level 1e-4), at cluster sizes where the prediction is meant to hold.
    """
    g = Gyro(dt=1.0, terms=[AngleRandomWalk(N=1.0)])
    R, n = 400, 2048
    m = np.array([1, 4, 16, 64])
    vals = np.array(
        [
            allan_variance(g.simulate(n, np.random.default_rng(s)), 1.0, taus=m.astype(float)).avar
            for s in np.random.SeedSequence(9).spawn(R)
        ]
    )
    predicted = 2 * (1.0 / m) ** 2 / edf_overlapping(m, n, "white_fm")
    ratio = vals.var(axis=0, ddof=1) / predicted
    lo, hi = stats.chi2.ppf([5e-5, 1 - 5e-5], R - 1) / (R - 1)
    assert np.all((ratio > lo) & (ratio < hi)), ratio


def test_confidence_interval_contains_truth_at_nominal_rate():
    g = Gyro(dt=1.0, terms=[AngleRandomWalk(N=1.0)])
    hits = []
    for s in np.random.SeedSequence(10).spawn(300):
        av = allan_variance(g.simulate(4096, np.random.default_rng(s)), 1.0, taus=[4.0, 32.0], noise="white_fm")
        truth = 1.0 / av.tau
        hits.append((av.ci_low <= truth) & (truth <= av.ci_high))
    rate = np.mean(hits, axis=0)
    # binomial 1e-4 two-sided band around the nominal 68.3 %
    lo, hi = stats.binom.ppf([5e-5, 1 - 5e-5], 300, 0.683) / 300
    assert np.all((rate >= lo) & (rate <= hi)), rate


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_fused_finiteness_check_names_the_first_bad_sample(bad):
    # the finiteness test rides on the mean's compiled sum: one bad sample anywhere is still caught
    x = np.random.default_rng(0).standard_normal(1000)
    x[[321, 700]] = bad
    with pytest.raises(ValueError, match="2 non-finite sample.*index 321"):
        allan_variance(x, 0.1)


def test_reused_cumsum_buffer_leaves_earlier_results_intact():
    rng = np.random.default_rng(1)
    a, b = rng.standard_normal(5000), rng.standard_normal(5000)
    ra = allan_variance(a, 1.0)
    first = ra.avar.copy()
    allan_variance(b, 1.0)
    np.testing.assert_array_equal(ra.avar, first)
    np.testing.assert_array_equal(allan_variance(a, 1.0).avar, first)


def _noise_from_slope_reference(tau, avar, J):
    """The noise-type rule in NumPy: np.gradient of the logarithms where J >= 16, rounded, clipped; the
    longest trusted type beyond; white FM where the slope is not finite or fewer than two taus are trusted."""
    out = np.array(["white_fm"] * len(tau), dtype=object)
    g = np.flatnonzero(J >= 16)
    if len(g) < 2:
        return out
    with np.errstate(invalid="ignore", divide="ignore"):
        slope = np.gradient(np.log(np.maximum(avar[g], np.finfo(float).tiny)), np.log(tau[g]))
    slope = np.where(np.isfinite(slope), slope, -1.0)
    names = {-2: "white_pm", -1: "white_fm", 0: "flicker_fm", 1: "rw_fm"}
    kinds = [names[int(v)] for v in np.clip(np.rint(slope), -2, 1)]
    out[g] = kinds
    out[g[-1] + 1 :] = kinds[-1]
    return out


@settings(max_examples=200, deadline=None)
@given(n=st.integers(2, 24), octave=st.booleans(), seed=st.integers(0, 2**31), special=st.sampled_from(["none", "zero", "inf", "nan"]))
def test_compiled_noise_rule_is_numpys_gradient_rule(n, octave, seed, special):
    """``_noise_codes_from_slope`` (the slope in a compiled pass) gives the types of the NumPy rule, on octave
    taus (equal log spacing: NumPy's uniform form) and on irregular ones, with zero, infinite and NaN AVs."""
    from avbench.estimators.allan.variance import NOISE_NAMES, _noise_codes_from_slope

    rng = np.random.default_rng(seed)
    m = 2.0 ** np.arange(n) if octave else np.unique(np.rint(np.cumsum(rng.uniform(1, 30, n))))
    tau = m * 0.01
    # slopes near the rounding boundaries as well as anywhere
    avar = np.exp(np.cumsum(rng.choice([-2.5, -1.5, -0.5, 0.5, 1.5], m.size) * np.log(2) + rng.normal(0, 0.3, m.size)))
    if special != "none":
        avar[rng.integers(m.size)] = {"zero": 0.0, "inf": np.inf, "nan": np.nan}[special]
    J = (4096 // m).astype(np.int64)
    np.testing.assert_array_equal(NOISE_NAMES[_noise_codes_from_slope(tau, avar, J)],
                                  _noise_from_slope_reference(tau, avar, J))


@settings(max_examples=200, deadline=None)
@given(edf=st.one_of(st.floats(0.05, 1e7), st.sampled_from([0.0, -1.0, np.inf, np.nan])),
       confidence=st.sampled_from([0.683, 0.9, 0.95, 0.99]))
def test_interval_is_scipy_stats_chi2_bit_for_bit(edf, confidence):
    """The AV's chi^2 interval, computed without importing scipy.stats, equals scipy.stats.chi2's bit for
    bit (nan where scipy.stats gives nan)."""
    lo, hi = _interval(np.array([2.5e-7]), np.array([edf]), confidence)
    a = (1 - confidence) / 2
    with np.errstate(all="ignore"):
        want_lo = edf * 2.5e-7 / stats.chi2.ppf(1 - a, edf)
        want_hi = edf * 2.5e-7 / stats.chi2.ppf(a, edf)
    np.testing.assert_array_equal(lo, [want_lo])
    np.testing.assert_array_equal(hi, [want_hi])
