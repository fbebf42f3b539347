"""MLE: the block-mean state-space model is exact; recovery within the estimator's own standard errors."""

import math

import numpy as np
import pytest
from scipy.linalg import solve_discrete_lyapunov

from avbench import estimators
from conftest import check_monte_carlo_recovery
from avbench.estimators.likelihood.mle import BlockMeanModel, block_means
from avbench.noise_models import AngleRandomWalk, GaussMarkov, Gyro, Quantization, RateRamp, RateRandomWalk


@pytest.mark.parametrize("m, tc", [(1, 0.5), (7, 0.5), (20, 50.0), (64, 0.05)])
def test_gm_block_means_have_the_exact_autocovariance(m, tc):
    # stationary autocovariance of the block mean from (T, Q) against the double sum of the AR(1)
    # autocovariance sigma^2 phi^|k| over the two blocks
    dt, sigma = 0.01, 2.0
    T, Q = GaussMarkov.block_mean_block((sigma, tc), m, dt)[:2]
    P = solve_discrete_lyapunov(T, Q)
    z = np.array([0.0, 1.0])
    phi = math.exp(-dt / tc)
    i = np.arange(m)
    for h in range(4):
        lags = np.abs(h * m + i[:, None] - i[None, :])
        exact = sigma**2 * np.mean(phi**lags)
        model = z @ np.linalg.matrix_power(T, h) @ P @ z
        assert model == pytest.approx(exact, rel=1e-10)


@pytest.mark.parametrize("m", [1, 5, 100])
def test_random_walk_block_means_have_the_exact_allan_variance(m):
    # E[(Lbar_{j+1} - Lbar_j)^2] / 2 is the AV of the sampled walk at cluster size m: (2m^2+1) q/(6m)
    q, dt = 3.0, 0.1
    Q = RateRandomWalk.block_mean_block((math.sqrt(q / dt),), m, dt).level
    # Lbar_{j+1} - Lbar_j = e_L(j) + u(j+1) - u(j), with Cov(e_L(j), u(j)) = Q[0, 1]
    var_diff = Q[0, 0] + 2 * Q[1, 1] - 2 * Q[0, 1]
    assert var_diff / 2 == pytest.approx((2 * m * m + 1) * q / (6 * m), rel=1e-12)
    assert RateRandomWalk(K=math.sqrt(q / dt)).avar([m], dt)[0] == pytest.approx(var_diff / 2, rel=1e-12)


def test_likelihood_prefers_the_truth():
    # E[loglike(truth) - loglike(other)] is the Kullback-Leibler divergence, > 0. With the GM at the
    # white noise's level (sigma N-equivalent ~ N) and sigma halved or doubled it is tens of units
    # per 40,000-sample record while its spread is ~10: every record must prefer the truth.
    g = Gyro(dt=0.01, terms=[AngleRandomWalk(N=1e-3), GaussMarkov(sigma=1e-3, tc=2.0)])
    p_true = np.log([1e-3, 1e-3, 2.0])
    for s in np.random.SeedSequence(5).spawn(3):
        y = block_means(g.simulate(40_000, np.random.default_rng(s)), 4)
        mod = BlockMeanModel(y, ("WN", "GM"), 4, 0.01)
        for sigma in (0.5e-3, 2e-3):
            assert mod.loglike(p_true) > mod.loglike(np.log([1e-3, sigma, 2.0]))


def test_scaling_does_not_change_the_likelihood_differences():
    g = Gyro(dt=0.01, terms=[AngleRandomWalk(N=1e-3), GaussMarkov(sigma=3e-4, tc=2.0)])
    y = block_means(g.simulate(20_000, np.random.default_rng(1)), 4)
    a, b = np.log([1e-3, 3e-4, 2.0]), np.log([1.1e-3, 2e-4, 3.0])
    d = [BlockMeanModel(y, ("WN", "GM"), 4, 0.01, scale=s) for s in (1e3, 1e5)]
    assert d[0].loglike(a) - d[0].loglike(b) == pytest.approx(d[1].loglike(a) - d[1].loglike(b), rel=1e-6)


_CASES = [  # latents, block size, dt, terms (in the order of the log-parameters)
    (("WN", "GM", "RW"), 4, 0.01, [AngleRandomWalk(N=1e-3), GaussMarkov(sigma=3e-4, tc=2.0), RateRandomWalk(K=1e-5)]),
    (("WN", "RW", "DR"), 5, 0.1, [AngleRandomWalk(N=1e-3), RateRandomWalk(K=1e-6), RateRamp(R=2e-7)]),
    (("QN", "WN", "RW"), 3, 0.1, [Quantization(Q=3e-5), AngleRandomWalk(N=2e-4), RateRandomWalk(K=1e-6)]),
    (("QN", "WN", "GM", "RW", "DR"), 1, 0.1, [Quantization(Q=3e-5), AngleRandomWalk(N=2e-4),
                                              GaussMarkov(sigma=1e-4, tc=5.0), RateRandomWalk(K=1e-6)]),
]


def _log_truth(terms):
    out = []
    for t in terms:
        out += [t.sigma, t.tc] if isinstance(t, GaussMarkov) else list(t.coefficients().values())
    return np.log(out)


@pytest.mark.parametrize("latents, m, dt, terms", _CASES)
def test_compiled_likelihood_equals_statsmodels(latents, m, dt, terms):
    # the compiled diffuse Kalman filter against statsmodels' on the same system matrices, at the
    # truth and away from it; the two freeze the covariance at slightly different steps once the
    # filter is in steady state (|dP|^2 < 1e-19), which moves the likelihood by ~1e-10 relative
    g = Gyro(dt=dt, terms=terms)
    y = block_means(g.simulate(30_000, np.random.default_rng(7)), m)
    mod = BlockMeanModel(y, latents, m, dt)
    truth = _log_truth([t for t in terms if not isinstance(t, RateRamp)])
    assert truth.size == len(mod.param_names)
    k = mod.system.k
    for shift in (0.0, 0.4, -0.7):
        p = truth + shift * np.linspace(-1, 1, truth.size)
        final = np.empty(k), np.empty((k, k))
        ours = mod.system.loglike(y, p, mod.scale, final)
        ref = mod.filter(p, cov_type="none")
        assert ours == pytest.approx(ref.llf, rel=1e-9, abs=0)
        np.testing.assert_allclose(final[0], ref.filtered_state[:, -1], rtol=1e-6, atol=1e-8)


def test_fit_equals_statsmodels_optimum():
    # same data, same start: the compiled fit and statsmodels' fit of the same model, both run to a
    # tight tolerance, reach the same optimum: log-likelihoods within 1e-3 (a parameter error of
    # ~0.05 standard errors costs 1e-3) and estimates within 0.05 standard errors. (statsmodels'
    # default pgtol = 1e-5 stops ~0.3 log-likelihood units short here.)
    from avbench.estimators.likelihood.mle import maximize_loglike

    # (a model whose likelihood is curved in every direction here: with RW added, 2000 s of data
    # leave Tc and K nearly exchangeable and the observed information indefinite, in both fits)
    g = Gyro(dt=0.01, terms=[AngleRandomWalk(N=1e-3), GaussMarkov(sigma=3e-4, tc=2.0)])
    y = block_means(g.simulate(200_000, np.random.default_rng(8)), 4)
    mod = BlockMeanModel(y, ("WN", "GM"), 4, 0.01)
    x0 = np.log([1.3e-3, 2e-4, 1.0])
    ours = maximize_loglike(mod.system, y, mod.scale, x0, 200)
    ref = mod.fit(start_params=x0, method="lbfgs", maxiter=500, disp=False, optim_complex_step=False, cov_type="none",
                  pgtol=1e-10, factr=10.0)
    assert ours["converged"]
    assert ours["loglike"] == pytest.approx(ref.llf, abs=1e-3)
    se = np.sqrt(np.diag(ours["cov"]))
    assert np.all(np.abs(ours["params"] - ref.params) < 0.05 * se), (ours["params"], ref.params, se)


def _within(est, g, coefs, k=4.0):
    se = est.diagnostics_["std_err"]
    for c in coefs:
        assert abs(est.coefficients_[c] - g.coefficients[c]) < k * se[c], (c, est.coefficients_[c], se[c])


def test_recovers_white_plus_gauss_markov():
    g = Gyro(dt=0.01, terms=[AngleRandomWalk(N=1e-3), GaussMarkov(sigma=3e-4, tc=2.0)])
    x = g.simulate(40_000, np.random.default_rng(21))
    est = estimators.get("mle", model="WN+GM", block=2).fit(x, 0.01)
    _within(est, g, "NB")
    assert est.diagnostics_["block"] == 2 and est.diagnostics_["converged"]
    assert list(est.diagnostics_["std_err"].index) == ["Q", "N", "B", "K", "R"]


def test_recovers_white_random_walk_and_drift():
    g = Gyro(dt=0.1, terms=[AngleRandomWalk(N=1e-3), RateRandomWalk(K=1e-6), RateRamp(R=2e-7)])
    x = g.simulate(50_000, np.random.default_rng(22))
    est = estimators.get("mle", model="WN+RW+DR", block=5).fit(x, 0.1)
    _within(est, g, "NKR")
    # the ramp is well determined here (se ~ K / sqrt(T) << R), so the check above is informative
    assert est.diagnostics_["std_err"]["R"] < g.coefficients["R"] / 3


def test_recovers_quantization_through_block_means():
    # the quantization block (theta_j, theta_{j-1}) is exact for any block size
    g = Gyro(dt=0.1, terms=[Quantization(Q=3e-5), AngleRandomWalk(N=2e-4), RateRandomWalk(K=1e-6)])
    x = g.simulate(20_000, np.random.default_rng(23))
    for m in (1, 3):
        est = estimators.get("mle", model="QN+WN+RW", block=m).fit(x, 0.1)
        _within(est, g, "QN")


@pytest.mark.slow
def test_monte_carlo_white_gm_rw_hours():
    check_monte_carlo_recovery("mle", seed=2016, R=6)


@pytest.mark.parametrize(
    "settings, match",
    [({"model": "WN+XX"}, "model"), ({"model": "DR"}, "stochastic"), ({"block": 0}, "block"),
     ({"block": "big"}, "block"), ({"max_blocks": 0}, "max_blocks"), ({"maxiter": 2.5}, "maxiter")],
)
def test_bad_settings(settings, match):
    x = np.random.default_rng(0).standard_normal(5000)
    with pytest.raises(ValueError, match=match):
        estimators.get("mle", **settings).fit(x, 0.01)


def test_block_too_large():
    x = np.random.default_rng(0).standard_normal(5000)
    with pytest.raises(ValueError, match="block means"):
        estimators.get("mle", model="WN", block=1000).fit(x, 0.01)
