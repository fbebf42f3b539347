"""MLE: the augmented Kalman filter (used with a drift) equals the exact initial one and its NumPy twin,
and the fit through it reaches the optimum of the fit through the exact initial filter."""

import numpy as np
import pytest

from avbench import estimators
from avbench.estimators.likelihood._mle_kernels import BlockMeanSystem, augmented_loglike, augmented_loglike_py
from avbench.estimators.likelihood.mle import block_means
from test_mle import _log_truth as _stochastic_log_truth
from avbench.noise_models import AngleRandomWalk, GaussMarkov, Gyro, Quantization, RateRamp, RateRandomWalk, presets

_DRIFT_CASES = [  # latents, block size, dt, terms (the stochastic ones in log-parameter order, then the ramp)
    (("WN", "RW", "DR"), 5, 0.1, [AngleRandomWalk(N=1e-3), RateRandomWalk(K=1e-6), RateRamp(R=2e-7)]),
    (("WN", "GM", "RW", "DR"), 4, 0.01, [AngleRandomWalk(N=1e-3), GaussMarkov(sigma=3e-4, tc=2.0),
                                         RateRandomWalk(K=1e-5), RateRamp(R=1e-6)]),
    (("QN", "WN", "GM", "RW", "DR"), 3, 0.1, [Quantization(Q=3e-5), AngleRandomWalk(N=2e-4),
                                              GaussMarkov(sigma=1e-4, tc=5.0), RateRandomWalk(K=1e-6),
                                              RateRamp(R=1e-7)]),
]


def _log_truth(terms):
    return _stochastic_log_truth([t for t in terms if not isinstance(t, RateRamp)])


@pytest.mark.parametrize("latents, m, dt, terms", _DRIFT_CASES)
def test_augmented_filter_equals_exact_initial_filter(latents, m, dt, terms):
    # two exact diffuse likelihoods (Durbin & Koopman 2012, Sec. 5.2 and 5.7) of the same model, at
    # the truth and away from it; with a drift the exact initial filter never reaches its steady
    # state, the augmented one does (its switch is exact to round-off): they agree to round-off,
    # and so do the last filtered state (whose slope is the reported R) and its covariance
    g = Gyro(dt=dt, terms=terms)
    y = block_means(g.simulate(40_000, np.random.default_rng(11)), m)
    system = BlockMeanSystem(latents, m, dt)
    scale = 1.0 / np.std(y)
    truth = _log_truth(terms)
    k = system.k
    for shift in (0.0, 0.5, -0.8):
        p = truth + shift * np.linspace(-1, 1, truth.size)
        fa, fe = (np.empty(k), np.empty((k, k))), (np.empty(k), np.empty((k, k)))
        la = system.loglike(y, p, scale, fa, method="augmented")
        le = system.loglike(y, p, scale, fe, method="exact_initial")
        assert la == pytest.approx(le, rel=1e-12, abs=0)
        np.testing.assert_allclose(fa[0], fe[0], rtol=1e-7, atol=1e-12 * np.max(np.abs(fe[0])))
        np.testing.assert_allclose(fa[1], fe[1], rtol=1e-6, atol=1e-9 * np.max(np.abs(fe[1])))


@pytest.mark.parametrize("latents, m, dt, terms", _DRIFT_CASES[:2])
def test_compiled_augmented_filter_equals_its_numpy_twin(latents, m, dt, terms):
    g = Gyro(dt=dt, terms=terms)
    y = block_means(g.simulate(6_000, np.random.default_rng(12)), m)
    system = BlockMeanSystem(latents, m, dt)
    scale = 1.0 / np.std(y)
    p = _log_truth(terms) + 0.3
    T, Qc, H, P0, _ = system.matrices(p, scale)
    a, P = np.empty(system.k), np.empty((system.k, system.k))
    ll = augmented_loglike(y, scale, T, Qc, system.Z, H, P0, system.lev, a, P)
    ref, a_ref, P_ref = augmented_loglike_py(y, scale, T, Qc, system.Z, H, P0, system.lev)
    assert ll == pytest.approx(ref, rel=1e-12, abs=0)
    np.testing.assert_allclose(a, a_ref, rtol=1e-8, atol=1e-12 * np.max(np.abs(a_ref)))
    np.testing.assert_allclose(P, P_ref, rtol=1e-7, atol=1e-10 * np.max(np.abs(P_ref)))


def test_augmented_filter_falls_back_on_a_noiseless_first_observation():
    # RW alone: the first block mean is its diffuse level exactly (F = 0); the augmented filter
    # cannot take it and the exact initial filter answers
    y = np.cumsum(np.random.default_rng(3).standard_normal(500))
    system = BlockMeanSystem(("RW", "DR"), 1, 1.0)
    p = np.log([1.0])
    assert system.loglike(y, p, method="augmented") == system.loglike(y, p, method="exact_initial")
    with pytest.raises(ValueError, match="method"):
        system.loglike(y, p, method="fast")


def _fit_both(x, dt, **settings):
    fits = []
    for method in ("exact_initial", "auto"):
        est = estimators.get("mle", **settings)
        est._loglike_method = method
        fits.append(est.fit(x, dt))
    return fits


def _same_optimum(old, new):
    """Same log-likelihood to round-off; estimates within 1e-3 relative and 1e-3 standard errors.

    L-BFGS on two likelihoods equal to ~1e-14 stops at points that differ by the optimiser's
    tolerance: ~1e-4 relative along the likelihood's flat directions (K against Tc, a term near
    zero), i.e. ~1e-4 standard errors.
    """
    assert new.result().llf == pytest.approx(old.result().llf, rel=1e-12, abs=0)
    c0, c1 = old.coefficients_.to_numpy(), new.coefficients_.to_numpy()
    np.testing.assert_allclose(c1, c0, rtol=1e-3)
    se = old.diagnostics_["std_err"].to_numpy()
    ok = np.isfinite(se) & np.isfinite(c0)
    assert np.all(np.abs(c1 - c0)[ok] < 1e-3 * se[ok]), (c0, c1, se)


@pytest.mark.parametrize("latents, m, dt, terms", [
    (("WN", "RW", "DR"), 5, 0.1, [AngleRandomWalk(N=1e-3), RateRandomWalk(K=1e-5), RateRamp(R=2e-6)]),
    _DRIFT_CASES[1],
])
def test_fit_through_the_augmented_filter_equals_the_fit_through_the_exact_initial_one(latents, m, dt, terms):
    # the same optimiser on two filters of the same likelihood reaches the same optimum
    g = Gyro(dt=dt, terms=terms)
    x = g.simulate(60_000, np.random.default_rng(13))
    old, new = _fit_both(x, dt, model="+".join(latents), block=m)
    _same_optimum(old, new)


@pytest.mark.parametrize("latents, m, dt, terms", [_DRIFT_CASES[1]])
def test_both_filters_give_the_same_observed_information(latents, m, dt, terms):
    # the observed information from central differences of each filter's analytic score: the two
    # filters (likelihoods equal to ~1e-14) give the same covariance of the log-parameters (nested
    # central differences of the likelihood would not: round-off along the flat directions makes them
    # 10-50 % apart at the same point on one machine, 1 % on another)
    from avbench.estimators.likelihood.mle import observed_cov

    x = Gyro(dt=dt, terms=terms).simulate(60_000, np.random.default_rng(13))
    old, _ = _fit_both(x, dt, model="+".join(latents), block=m)
    system = BlockMeanSystem(latents, m, dt)
    y = block_means(x, m)
    scale = 1.0 / float(np.std(y))
    p = np.log([old.diagnostics_["params"][name[4:]] for name in system.names])
    cov_old, cov_new = (observed_cov(None, p, lambda q, k=k: system.score(y, q, scale, method=k)[1])
                        for k in ("exact_initial", "auto"))
    np.testing.assert_allclose(cov_new, cov_old, rtol=1e-3, atol=1e-3 * np.max(np.abs(np.diag(cov_old))))


@pytest.mark.slow
def test_fit_of_a_preset_through_the_augmented_filter_equals_the_fit_through_the_exact_initial_one():
    # ADIS16405 with the full latent model: its quantization term sits at ~0, a flat direction of
    # the likelihood whose Hessian entry is below the finite differences' resolution in either
    # path, so only the estimates (not the standard errors) are compared
    g = presets.get("ADIS16405_X")
    x = g.simulate(100_000, np.random.default_rng(1))
    _same_optimum(*_fit_both(x, g.dt, model="QN+WN+GM+RW+DR"))
