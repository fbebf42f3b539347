"""GMWM with a flicker latent ("FL"): the exact discrete flicker AV as the latent's theoretical AV."""


import numpy as np
import pytest

from avbench import estimators
from conftest import assert_mc_recovery
from avbench.estimators.likelihood.gmwm import parse_model
from avbench.noise_models import AngleRandomWalk, BiasInstability, Gyro, RateRandomWalk

DT = 0.1


def test_parse_rejects_two_models_of_b():
    assert parse_model("WN+FL+RW") == ("WN", "FL", "RW")
    with pytest.raises(ValueError, match="not both GM and FL"):
        parse_model("WN+GM+FL")


def test_mle_keeps_its_gauss_markov_reading():
    with pytest.raises(ValueError, match="MLE supports"):
        estimators.get("mle", model="WN+FL").fit(np.random.default_rng(0).standard_normal(4096), DT)


def _replicates(R, n, seed):
    g = Gyro(dt=DT, terms=[AngleRandomWalk(N=1e-3), BiasInstability(B=2e-4, tau_max=2 * n * DT),
                           RateRandomWalk(K=3e-5)])
    est, se = [], []
    for s in np.random.SeedSequence(seed).spawn(R):
        e = estimators.get("gmwm", model="WN+FL+RW").fit(g.simulate(n, np.random.default_rng(s)), DT)
        est.append(e.coefficients_[["N", "B", "K"]].to_numpy())
        se.append(e.std_err_[["N", "B", "K"]].to_numpy())
    return g.coefficients[["N", "B", "K"]].to_numpy(), np.array(est), np.array(se)


def _check(truth, est, se):
    # N and B (the model is the true one; K's information is weak at these lengths)
    assert_mc_recovery(truth[:2], est[:, :2], se[:, :2])


def test_flicker_latent_recovers_b_small():
    _check(*_replicates(R=10, n=72_000, seed=31))


@pytest.mark.slow
def test_flicker_latent_recovers_b_slow():
    _check(*_replicates(R=100, n=144_000, seed=32))
