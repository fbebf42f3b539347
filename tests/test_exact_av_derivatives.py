"""Derivatives of the terms' exact AV (``NoiseTerm.avar_shape_derivative``), GMWM's analytic Jacobian,
and the kept Haar gains of the AV covariance (GMWM's cost)."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from avbench.estimators.allan import covariance
from avbench.estimators.likelihood.gmwm import _LatentAV, build_gyro
from avbench.noise_models import FilteredWhiteNoise, GaussMarkov, Sinusoidal
from avbench.noise_models.terms import _gm_shape_kernel, _gm_shape_py

M = np.unique(np.geomspace(1, 2e6, 120).astype(np.int64))


def _richardson(term, m, dt, h=1e-3):
    """d avar / d ln p by Richardson-extrapolated central differences of the reference ``avar``
    (truncation O(h^4) ~ 1e-12, round-off ~ 1e-16 / h of the AV)."""
    name, params = term.shape_parameter, term._params()

    def central(step):
        up = type(term)(**{**params, name: params[name] * math.exp(step)}).avar(m, dt)
        down = type(term)(**{**params, name: params[name] * math.exp(-step)}).avar(m, dt)
        return (up - down) / (2 * step)

    return (4 * central(h / 2) - central(h)) / 3


@settings(max_examples=60, deadline=None)
@given(log_a=st.floats(math.log(1e-9), math.log(30.0)))
def test_gauss_markov_derivative_matches_the_reference_curve(log_a):
    """The compiled value equals the NumPy reference ``avar`` to round-off; d/d ln Tc agrees with
    extrapolated differences of it to 1e-7 of the AV (the differences' own error is below 1e-10)."""
    a = math.exp(log_a)
    term = GaussMarkov(sigma=1.3, tc=1.0 / a)
    av, dav = term.avar_shape_derivative(M, 1.0)
    ref = term.avar(M, 1.0)
    np.testing.assert_allclose(av, ref, rtol=1e-13, atol=0)
    assert np.all(np.abs(dav - _richardson(term, M, 1.0)) <= 1e-7 * ref)


def test_gauss_markov_kernel_equals_its_numpy_reference():
    mf = M.astype(float)
    for a in (1e-7, 3e-4, 0.05, 2.0):
        g1, d1, g2, d2 = (np.empty_like(mf) for _ in range(4))
        _gm_shape_kernel(mf, a, g1, d1)
        _gm_shape_py(mf, a, g2, d2)
        np.testing.assert_allclose(g1, g2, rtol=1e-14)
        np.testing.assert_allclose(d1, d2, rtol=1e-12, atol=1e-14 * np.abs(g2).max())


@pytest.mark.parametrize("term", [FilteredWhiteNoise(N=1e-3, tf=0.07), Sinusoidal(A=2e-4, f0=0.8)])
def test_shape_derivative_agrees_with_extrapolated_differences(term):
    m = np.arange(1, 40)
    av, dav = term.avar_shape_derivative(m, 0.01)
    np.testing.assert_array_equal(av, term.avar(m, 0.01))
    scale = np.abs(av).max()
    assert np.all(np.abs(dav - _richardson(term, m, 0.01)) <= 1e-6 * scale)


def test_sinusoid_derivative_at_the_nyquist_frequency_is_the_backward_limit():
    """A sinusoid at the Nyquist frequency (GMWM's upper bound for f0), where no step above f0 is a term:
    the analytic derivative is finite and agrees with Richardson-extrapolated backward differences (error
    O(h^2) ~ 1e-8 of the AV's scale) to 1e-6 of it."""
    term = Sinusoidal(A=1.0, f0=50.0)
    m = np.arange(1, 9)
    av, dav = term.avar_shape_derivative(m, 0.01)

    def backward(h):
        return (av - Sinusoidal(A=1.0, f0=50.0 * math.exp(-h)).avar(m, 0.01)) / h

    assert np.all(np.isfinite(dav))
    assert np.all(np.abs(dav - (2 * backward(1e-4) - backward(2e-4))) <= 1e-6 * np.abs(av).max())


def test_a_term_without_shape_parameter_says_so():
    from avbench.noise_models import AngleRandomWalk

    with pytest.raises(ValueError, match="no shape parameter"):
        AngleRandomWalk(N=1e-3).avar_shape_derivative([1, 2], 0.01)


@pytest.mark.parametrize("latents", [("WN", "GM", "RW"), ("QN", "WN", "GM", "RW", "DR"), ("FW", "GM", "RW", "SN"),
                                     ("WN", "FL", "RW"), ("FW", "GM", "RW", "RS")])
def test_latent_model_value_and_jacobian(latents):
    """GMWM's model: the value equals the latent gyro's exact AV to round-off, the Jacobian agrees
    with central differences of it (to 1e-6 of the AV; 1e-5 where a term's shape derivative is
    itself a central difference, the sinusoid's and the filter's: its truncation error is
    ~(1e-4 * 2 pi f0 tau)^2 / 6 of the term's own AV)."""
    dt, tau_fl = 0.01, 2000.0
    tau = dt * 2.0 ** np.arange(0, 14)
    values = {"QN": [3e-6], "WN": [2e-3], "GM": [1e-4, 12.0], "FL": [5e-5], "RW": [3e-5], "DR": [1e-7],
              "FW": [2e-3, 0.02], "SN": [4e-4, 0.5], "RS": [5e-3, 20.0, 0.3]}
    v = np.array([x for lat in latents for x in values[lat]])
    u = np.log(v)
    model = _LatentAV(latents, tau, dt, tau_fl)
    exact = build_gyro(latents, v, dt, tau_fl).avar(tau)
    np.testing.assert_allclose(model(u), exact, rtol=1e-12)
    jac = model.jacobian(u)
    h = 1e-5
    for j in range(u.size):
        e = np.zeros_like(u)
        e[j] = h
        fd = (model(u + e) - model(u - e)) / (2 * h)
        tol = 1e-5 if {"SN", "FW", "RS"} & set(latents) else 1e-6
        assert np.all(np.abs(jac[:, j] - fd) <= tol * exact), (latents, j)


def test_kept_gains_give_the_same_covariance():
    """The Haar gains kept between calls (runs of consecutive cluster sizes as views) give the
    covariance of gains computed afresh, bit for bit."""
    gyro = build_gyro(("WN", "GM", "RW"), [1e-3, 1e-4, 30.0, 1e-6], 0.1)
    m = 2.0 ** np.arange(0, 12)
    covariance._GAINS.clear()
    fresh = [covariance.av_covariance(gyro, m[i:], 100_000, reuse=False) for i in range(3)]
    covariance._GAINS.clear()
    covariance.av_covariance(gyro, m, 100_000, reuse=False)  # keeps the gains of all sizes
    kept = [covariance.av_covariance(gyro, m[i:], 100_000, reuse=False) for i in range(3)]
    for a, b in zip(fresh, kept):
        np.testing.assert_array_equal(a, b)


def test_gains_too_large_to_keep_come_block_by_block(monkeypatch):
    """Past the budget nothing is kept and the gains are made per block (bounded work arrays), with
    the same covariance."""
    gyro = build_gyro(("WN", "RW"), [1e-3, 1e-6], 0.1)
    m = 2.0 ** np.arange(0, 15)
    covariance._GAINS.clear()
    kept = covariance.av_covariance(gyro, m, 400_000, reuse=False)
    covariance._GAINS.clear()
    monkeypatch.setattr(covariance, "GAIN_CACHE_BYTES", 1024)
    monkeypatch.setattr(covariance, "CHUNK", 1 << 12)
    blocks = covariance._gains(m, covariance._grid_size(m, 8, 1 << 21))
    assert not isinstance(blocks, list) and not covariance._GAINS
    assert next(iter(blocks))[1].shape == (m.size, 1 << 12)
    monkeypatch.setattr(covariance, "CHUNK", 1 << 17)
    np.testing.assert_allclose(covariance.av_covariance(gyro, m, 400_000, reuse=False), kept, rtol=1e-12)
    assert not covariance._GAINS
