"""The AV covariance's caches (avbench.estimators.allan.covariance): the weighted sum of kept per-shape
integrals equals the direct midpoint sum of the squared total spectrum to round-off, for every term
kind, on first and later calls, and for coefficients the cache has not seen; a kept covariance and kept
Haar gains give the values computed afresh bit for bit, within their budgets."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from avbench.estimators.allan import covariance
from avbench.estimators.allan.covariance import av_covariance
from avbench.noise_models import (AngleRandomWalk, BiasInstability, GaussMarkov, Gyro, Quantization, RateRamp,
                                  RateRandomWalk, SecondOrderGaussMarkov)


def direct(gyro, m, n_samples, grid_per_cycle=8, max_grid=1 << 21):
    """The covariance without the cache: one midpoint sum of |H_j|^2 |H_k|^2 S^2."""
    m = np.asarray(m, dtype=float)
    n_grid = int(min(max(grid_per_cycle * m.max(), 4096), max_grid))
    w = (np.arange(n_grid) + 0.5) * (np.pi / n_grid)
    S = gyro.psd(w / (2 * np.pi * gyro.dt)) / (2 * gyro.dt)
    G = 4.0 * np.sin(0.5 * m[:, None] * w[None, :]) ** 4 / (m[:, None] ** 2 * np.sin(w / 2)[None, :] ** 2)
    out = (G * S**2) @ G.T / n_grid
    M = n_samples - 2 * m + 1
    return out / (2.0 * np.sqrt(np.outer(M, M)))


def close(a, b, rtol=1e-11):
    """Equal to round-off relative to each entry's scale sqrt(b_ii b_jj)."""
    d = np.sqrt(np.outer(np.diag(b), np.diag(b)))
    return np.all(np.abs(a - b) <= rtol * d)


def gyro_of(q, n, b, k, tc, dt):
    terms = [Quantization(Q=q), AngleRandomWalk(N=n), BiasInstability(B=b, tau_max=3000 * dt), RateRandomWalk(K=k),
             RateRamp(R=1e-7)]
    if tc is not None:
        terms[2] = GaussMarkov(sigma=b, tc=tc)
    return Gyro(dt=dt, terms=terms)


M = 2 ** np.arange(0, 10)


@settings(max_examples=15, deadline=None)
@given(q=st.floats(1e-7, 1e-4), n=st.floats(1e-5, 1e-2), b=st.floats(1e-6, 1e-3), k=st.floats(1e-7, 1e-4),
       tc=st.one_of(st.none(), st.floats(0.05, 500.0)), dt=st.sampled_from([0.01, 0.1]))
def test_cached_covariance_equals_the_direct_sum(q, n, b, k, tc, dt):
    g = gyro_of(q, n, b, k, tc, dt)
    first = av_covariance(g, M, 20_000)
    covariance._RESULTS.clear()  # not the kept covariance: its pairs
    again = av_covariance(g, M, 20_000)  # every pair from the cache
    ref = direct(g, M, 20_000)
    assert close(first, ref) and close(again, ref)
    assert close(av_covariance(g, M, 20_000, reuse=False), ref)


def test_a_term_without_psd_factor_is_integrated_every_time():
    """SecondOrderGaussMarkov keeps the default factor (1, self): right, never shared by equality."""
    assert not covariance._factor(SecondOrderGaussMarkov(R=1e-6, w0=0.05))[2]
    g1 = Gyro(dt=0.01, terms=[AngleRandomWalk(N=1e-3), SecondOrderGaussMarkov(R=1e-6, w0=0.05)])
    g2 = Gyro(dt=0.01, terms=[AngleRandomWalk(N=1e-3), SecondOrderGaussMarkov(R=3e-6, w0=0.05)])
    for g in (g1, g2, g1):
        assert close(av_covariance(g, M, 50_000), direct(g, M, 50_000))


def test_shapes_are_shared_across_coefficients_and_the_cache_is_bounded(monkeypatch):
    monkeypatch.setattr(covariance, "CACHE_SIZE", 6)
    covariance._PAIRS.clear()
    calls = []
    real = covariance._pair_integrals
    monkeypatch.setattr(covariance, "_pair_integrals", lambda *a: calls.append(list(a[1])) or real(*a))
    for g in (gyro_of(1e-6, 1e-3, 1e-4, 1e-6, None, 0.1), gyro_of(3e-6, 2e-3, 5e-4, 4e-6, None, 0.1)):
        assert close(av_covariance(g, M, 10_000), direct(g, M, 10_000))
        assert len(covariance._PAIRS) <= 6
    assert len(calls[0]) == 10 and len(calls[1]) == 4  # 4 random shapes: 10 pairs, 6 of them kept
    monkeypatch.setattr(covariance, "CACHE_SIZE", 512)
    av_covariance(gyro_of(1e-6, 1e-3, 1e-4, 1e-6, None, 0.1), M, 10_000)
    av_covariance(gyro_of(3e-6, 2e-3, 5e-4, 4e-6, None, 0.1), M, 20_000)  # other coefficients and length
    assert len(calls) == 3


class RedWhite(AngleRandomWalk):
    """A user's subclass that changes the spectrum but not psd_factor: never shared, never mis-scaled."""

    def psd(self, f, dt):
        return super().psd(f, dt) * (1.0 + np.asarray(f, float) * dt)


def test_a_subclass_changing_psd_is_not_taken_for_its_base():
    assert not covariance._factor(RedWhite(N=1e-3))[2]
    for n in (1e-3, 2e-3):
        g = Gyro(dt=0.1, terms=[RedWhite(N=n), Quantization(Q=1e-6)])
        assert close(av_covariance(g, M, 10_000), direct(g, M, 10_000))


@pytest.mark.parametrize("terms", [[RateRamp(R=1e-6)], [RateRamp(R=1e-6), AngleRandomWalk(N=1e-3)]])
def test_deterministic_terms_add_nothing(terms):
    g = Gyro(dt=0.1, terms=terms)
    np.testing.assert_allclose(av_covariance(g, M, 10_000), direct(g, M, 10_000), rtol=1e-11, atol=0)


# -- the fit check's tail: a poor fit does not pay for Imhof's integral --------------------------------
from scipy import stats  # noqa: E402

from avbench.estimators.allan import fit_check  # noqa: E402


@settings(max_examples=40, deadline=None)
@given(k=st.integers(1, 20), x=st.floats(0.1, 400.0))
def test_chernoff_bound_holds_for_chi2(k, x):
    assert fit_check.chernoff_bound(x, np.ones(k)) >= stats.chi2.sf(x, k) * (1 - 1e-9)


@settings(max_examples=15, deadline=None)
@given(w=st.lists(st.floats(0.05, 3.0), min_size=2, max_size=12), q=st.floats(1.5, 60.0))
def test_skipping_the_integral_changes_nothing(w, q):
    """Where the bound sends a poor fit past the integral, the answer is what integrating gave."""
    w = np.array(w)
    x = q * w.sum()
    fast = fit_check.weighted_chi2_sf(x, w)
    bound = fit_check.chernoff_bound(x, w)
    assert fast <= bound * (1 + 1e-9) + 1e-14
    real = fit_check.chernoff_bound
    try:
        fit_check.chernoff_bound = lambda *a: 1.0  # force the integral
        slow = fit_check.weighted_chi2_sf(x, w)
    finally:
        fit_check.chernoff_bound = real
    assert fast == slow  # skipped (bound below the floor) or the same path


def test_a_sinusoid_adds_its_cross_term_with_the_noise():
    """A sinusoid in white noise: the AV's variance over replicates is the covariance's diagonal with the
    line's cross term (covariance._line_cross); without it the model is 2-11 times too small where the
    sinusoid shapes the curve (m = 32, 64 here). Tolerance: 4 standard errors of the replicates' variance
    (from their fourth moment)."""
    from avbench.estimators.allan.variance import allan_variance
    from avbench.noise_models import Sinusoidal

    dt, n, reps = 0.01, 20_000, 300
    g = Gyro(dt=dt, terms=[AngleRandomWalk(N=1e-3), Sinusoidal(3e-3, 0.6)])
    rng = np.random.default_rng(11)
    av = np.array([allan_variance(g.simulate(n, rng), dt, taus="octave", overlapping=True).avar
                   for _ in range(reps)])
    m = 2 ** np.arange(0, 8)
    av = av[:, : m.size]
    dev = av - av.mean(axis=0)
    var = (dev**2).sum(axis=0) / (reps - 1)
    se_var = np.sqrt(((dev**2 - var) ** 2).mean(axis=0) / reps)
    model = np.diag(av_covariance(g, m, n))
    assert np.all(np.abs(var - model) < 4 * se_var), (var / model, se_var / model)
    M_ = n - 2 * m + 1
    without = model - np.diag(covariance._line_cross(g, m.astype(float))) / (2.0 * M_)
    assert np.any(np.abs(var - without) > 8 * se_var)  # the check can fail: the cross term matters here
    assert close(av_covariance(g, m, n, reuse=False), av_covariance(g, m, n), rtol=1e-9)


def test_a_kept_covariance_is_the_one_computed_afresh_and_a_copy():
    """A covariance asked again (same model, sizes, length, path) is the kept one: equal bit for bit to a
    fresh computation, returned as a copy (the caller may scale it in place); another length, another
    path or other coefficients are computed."""
    from avbench.noise_models import FilteredWhiteNoise

    g = Gyro(dt=0.01, terms=[AngleRandomWalk(N=1e-3), GaussMarkov(sigma=1e-4, tc=20.0), RateRandomWalk(K=1e-6)])
    for reuse in (True, False):
        covariance._RESULTS.clear()
        first = av_covariance(g, M, 50_000, reuse=reuse)
        first *= 2.0  # the caller's copy
        covariance._PAIRS.clear()
        covariance._GAINS.clear()
        covariance._RESULTS.clear()
        fresh = av_covariance(g, M, 50_000, reuse=reuse)
        kept = av_covariance(g, M, 50_000, reuse=reuse)
        np.testing.assert_array_equal(kept, fresh)
        np.testing.assert_array_equal(first, 2.0 * fresh)
        assert kept is not av_covariance(g, M, 50_000, reuse=reuse)
    assert not np.array_equal(av_covariance(g, M, 60_000), fresh)
    other = Gyro(dt=0.01, terms=[AngleRandomWalk(N=1e-3), GaussMarkov(sigma=1e-4, tc=21.0), RateRandomWalk(K=1e-6)])
    assert not np.array_equal(av_covariance(other, M, 50_000), av_covariance(g, M, 50_000))
    # a FIR filter's taps are a parameter of the key; a term with an array parameter is not kept (no key)
    taps = Gyro(dt=0.01, terms=[FilteredWhiteNoise(N=1e-3, taps=[0.25, 0.5, 0.25])])
    assert close(av_covariance(taps, M, 50_000), direct(taps, M, 50_000))
    odd = Gyro(dt=0.01, terms=[ArrayParameter(N=1e-3)])
    assert covariance._result_key(odd, np.asarray(M, float), 50_000, 4096, True) is None
    assert close(av_covariance(odd, M, 50_000), direct(odd, M, 50_000))


class ArrayParameter(AngleRandomWalk):
    """A user's term with an array among its parameters (unhashable)."""

    def _params(self):
        return {**super()._params(), "weights": np.ones(2)}


def test_the_kept_covariances_are_bounded(monkeypatch):
    monkeypatch.setattr(covariance, "RESULT_CACHE_SIZE", 3)
    covariance._RESULTS.clear()
    for n in range(10_000, 10_005):
        av_covariance(Gyro(dt=0.1, terms=[AngleRandomWalk(N=1e-3)]), M, n)
    assert len(covariance._RESULTS) == 3


def test_kept_gains_stay_within_their_budget_and_give_the_same_covariance(monkeypatch):
    """Gains up to the whole budget are kept, the least recently used dropped first so that what is held
    never exceeds it; gains beyond it come block by block; every covariance equals the fresh one."""
    g = Gyro(dt=0.1, terms=[AngleRandomWalk(N=1e-3), GaussMarkov(sigma=1e-4, tc=30.0)])
    m_small, m_big = 2.0 ** np.arange(0, 8), 2.0 ** np.arange(0, 10)
    fresh = {}
    for m in (m_small, m_big):
        covariance._GAINS.clear()
        covariance._RESULTS.clear()
        fresh[m.size] = av_covariance(g, m, 100_000, reuse=False)
    big = m_big.size * covariance._grid_size(m_big, 8, 1 << 21) * 8
    monkeypatch.setattr(covariance, "GAIN_CACHE_BYTES", big)  # room for the big set alone
    covariance._GAINS.clear()
    for m in (m_small, m_big, m_small):
        covariance._RESULTS.clear()
        np.testing.assert_array_equal(av_covariance(g, m, 100_000, reuse=False), fresh[m.size])
        held = sum(v[0].size * k[0] * 8 for k, v in covariance._GAINS.items())
        assert 0 < held <= big
    monkeypatch.setattr(covariance, "GAIN_CACHE_BYTES", big - 1)  # the big set no longer fits: not kept
    covariance._GAINS.clear()
    covariance._RESULTS.clear()
    np.testing.assert_array_equal(av_covariance(g, m_big, 100_000, reuse=False), fresh[m_big.size])
    assert not covariance._GAINS


def test_fitted_shapes_take_the_direct_sum(monkeypatch):
    """A model with two or more pairs of a fitted shape (Gauss-Markov tc, a filter's tc) not kept takes the
    direct midpoint sum (one product, not one per pair) and nothing is integrated per pair; a five-term
    model keeps its pairs. Both equal the direct sum to round-off."""
    from avbench.noise_models import FilteredWhiteNoise

    calls = []
    real = covariance._pair_integrals
    monkeypatch.setattr(covariance, "_pair_integrals", lambda *a: calls.append(list(a[1])) or real(*a))
    covariance._RESULTS.clear()
    fitted = Gyro(dt=0.01, terms=[FilteredWhiteNoise(N=1e-3, tf=0.02), GaussMarkov(sigma=1e-4, tc=17.0),
                                  RateRandomWalk(K=1e-6)])
    assert close(av_covariance(fitted, M, 50_000), direct(fitted, M, 50_000)) and not calls
    five = gyro_of(1e-6, 1e-3, 1e-4, 1e-6, None, 0.01)
    covariance._PAIRS.clear()
    assert close(av_covariance(five, M, 50_000), direct(five, M, 50_000)) and len(calls) == 1
