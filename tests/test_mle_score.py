"""MLE: the analytic score (each Kalman filter's derivative recursions) is the derivative of the
likelihood the filter computes, and the observed information from it is stable."""

import numpy as np
import pytest

from avbench.estimators.likelihood._mle_kernels import BlockMeanSystem
from avbench.estimators.likelihood.mle import block_means, observed_cov
from avbench.noise_models import AngleRandomWalk, GaussMarkov, Gyro, Quantization, RateRamp, RateRandomWalk

_TRUTH = {"log_Q": 3e-5, "log_N": 1e-3, "log_sigma": 3e-4, "log_tc": 2.0, "log_K": 1e-5}
_CASES = [  # latents, block size, dt
    (("WN", "GM", "RW"), 4, 0.01),
    (("QN", "WN", "GM", "RW"), 1, 0.01),
    (("WN", "RW", "DR"), 5, 0.01),
    (("QN", "WN", "GM", "RW", "DR"), 3, 0.01),
    (("GM",), 2, 0.01),
]


def _record(n, seed=1):
    g = Gyro(dt=0.01, terms=[Quantization(Q=3e-5), AngleRandomWalk(N=1e-3), GaussMarkov(sigma=3e-4, tc=2.0),
                             RateRandomWalk(K=1e-5), RateRamp(R=1e-7)])
    return g.simulate(n, np.random.default_rng(seed))


def _richardson(f, p, h):
    """Central differences at steps h and h/2 combined (error O(h^4))."""
    out = np.empty(p.size)
    for i in range(p.size):
        e = np.zeros(p.size)
        e[i] = 1.0
        d1 = (f(p + h * e) - f(p - h * e)) / (2 * h)
        d2 = (f(p + h / 2 * e) - f(p - h / 2 * e)) / h
        out[i] = (4 * d2 - d1) / 3
    return out


@pytest.mark.parametrize("latents, m, dt", _CASES)
def test_system_derivatives_are_those_of_the_matrices(latents, m, dt):
    s = BlockMeanSystem(latents, m, dt)
    rng = np.random.default_rng(4)
    for _ in range(3):
        p = np.log([_TRUTH[name] for name in s.names]) + rng.uniform(-1, 1, len(s.names))
        d = s.derivatives(p, 7.0)
        for which in range(4):
            f = lambda q, w=which: np.atleast_1d(s.matrices(q, 7.0)[w]).ravel()  # noqa: E731
            for i in range(p.size):
                e = np.zeros(p.size)
                e[i] = 1e-3
                num = (4 * (f(p + e / 2) - f(p - e / 2)) / 1e-3 - (f(p + e) - f(p - e)) / 2e-3) / 3
                ana = np.atleast_1d(d[which][i]).ravel()
                scale = np.max(np.abs(f(p))) or 1.0
                np.testing.assert_allclose(ana, num, rtol=1e-7, atol=1e-9 * scale)


@pytest.mark.parametrize("latents, m, dt", _CASES)
def test_score_is_the_derivative_of_the_likelihood(latents, m, dt):
    # a record short enough that the covariance never freezes at its steady state (the likelihood
    # is then smooth in the parameters): the analytic score equals Richardson-extrapolated central
    # differences of the same likelihood, whose error (h^4 terms, round-off ~eps |ll| / h) is
    # orders below the tolerance; the likelihood is the exact initial filter's, to the bit
    s = BlockMeanSystem(latents, m, dt)
    y = block_means(_record(1_500 * m), m)
    scale = 1.0 / np.std(y)
    rng = np.random.default_rng(5)
    for _ in range(2):
        p = np.log([_TRUTH[name] for name in s.names]) + rng.uniform(-0.5, 0.5, len(s.names))
        for method in ("exact_initial", "augmented") if s.drift else ("exact_initial",):
            ll, grad = s.score(y, p, scale, method=method)
            assert np.isfinite(ll) and np.all(np.isfinite(grad))
            assert ll == s.loglike(y, p, scale, method=method)
            num = _richardson(lambda q: s.loglike(y, q, scale, method=method), p, 1e-3)
            np.testing.assert_allclose(grad, num, rtol=1e-6, atol=1e-9 * abs(ll))


@pytest.mark.parametrize("latents", [("WN", "GM", "RW"), ("QN", "WN", "GM", "RW", "DR")])
def test_score_after_the_steady_state(latents):
    # a long record: the covariance freezes (steady state; with a drift the augmented filter's
    # diffuse columns settle too) and the score stays the derivative; central differences here
    # also see the freezing step move (jumps of ~1e-10 relative in the likelihood, i.e. ~1e-5
    # absolute over steps of 1e-3), so the tolerance is that resolution
    s = BlockMeanSystem(latents, 4, 0.01)
    y = block_means(_record(400_000), 4)
    scale = 1.0 / np.std(y)
    p = np.log([_TRUTH[name] for name in s.names]) + 0.2
    ll, grad = s.score(y, p, scale)
    assert np.isfinite(ll) and np.all(np.isfinite(grad))
    assert ll == s.loglike(y, p, scale)
    num = _richardson(lambda q: s.loglike(y, q, scale), p, 1e-3)
    np.testing.assert_allclose(grad, num, rtol=1e-5, atol=1e-10 * abs(ll) / 1e-3)


def test_observed_information_from_the_score_does_not_depend_on_the_step():
    # the Hessian from central differences of the analytic score errs by O(h^2) + (the score's
    # own resolution) / h: halving or doubling the step moves the standard errors and the
    # correlations by < 1e-3 (a thousandth of a standard error's width: far below what any
    # coverage study resolves). The nested central differences of the likelihood (statsmodels'
    # approx) are round-off dominated here: at the same point one of those steps gives a
    # non-positive variance.
    from avbench.estimators.likelihood import mle

    s = BlockMeanSystem(("WN", "GM", "RW"), 4, 0.01)
    y = block_means(_record(200_000, seed=3), 4)
    scale = 1.0 / np.std(y)
    p = np.log([_TRUTH[name] for name in s.names])

    def score(q):
        return s.score(y, q, scale)[1]

    def normalised(cov):
        assert np.all(np.isfinite(cov)) and np.all(np.diag(cov) > 0)
        d = np.sqrt(np.diag(cov))
        return cov / np.outer(d, d), d

    step = mle._EPS_GRAD
    covs = []
    try:
        for factor in (1.0, 0.5, 2.0):
            mle._EPS_GRAD = step * factor
            covs.append(normalised(observed_cov(None, p, score)))
    finally:
        mle._EPS_GRAD = step
    (corr, se), others = covs[0], covs[1:]
    for c, d in others:
        np.testing.assert_allclose(d, se, rtol=1e-3)
        np.testing.assert_allclose(c, corr, rtol=0, atol=1e-3)
