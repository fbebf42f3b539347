"""One contract test, parametrised over every registered estimator (scikit-learn style)."""

import pickle

import numpy as np
import pandas as pd
import pytest

import estimators
from noise_models import AngleRandomWalk, GaussMarkov, Gyro, RateRandomWalk

COEFS = ["Q", "N", "B", "K", "R"]


@pytest.fixture(scope="module")
def record():
    g = Gyro(
        dt=0.01,
        terms=[AngleRandomWalk(N=1e-3), GaussMarkov(sigma=2e-4, tc=5.0), RateRandomWalk(K=1e-6)],
    )
    return g.simulate(30_000, np.random.default_rng(0)), g.dt


@pytest.mark.parametrize("name", estimators.names())
def test_contract(name, record):
    x, dt = record
    est = estimators.get(name)
    params = est.get_params()
    # __init__ stores its arguments unchanged; clone gives an equal, unfitted estimator
    clone = est.clone()
    assert type(clone) is type(est) and clone.get_params().keys() == params.keys()
    assert not hasattr(clone, "coefficients_")
    pickle.loads(pickle.dumps(est))
    with np.errstate(all="ignore"):
        import warnings

        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            out = est.fit(x, dt)
            assert out is est
            c1 = est.coefficients_.copy()
            est2 = estimators.get(name).fit(x, dt)
    assert isinstance(est.coefficients_, pd.Series) and list(est.coefficients_.index) == COEFS
    assert est.coefficients_.dtype == float
    assert list(est.nonphysical_.index) == COEFS and est.nonphysical_.dtype == bool
    assert isinstance(est.diagnostics_, dict)
    # refitting on the same data gives the same answer
    pd.testing.assert_series_equal(c1, est2.coefficients_)
    # flagged coefficients are NaN; estimates are non-negative
    assert np.all(np.isnan(est.coefficients_[est.nonphysical_]))
    finite = est.coefficients_.dropna()
    assert np.all(finite >= 0)


@pytest.mark.parametrize("name", estimators.names())
def test_unknown_setting_is_a_clear_error(name):
    with pytest.raises(ValueError, match="unknown setting"):
        estimators.get(name, no_such_setting=1)


def test_unknown_name_lists_known():
    with pytest.raises(ValueError, match="expected one of"):
        estimators.get("kalman_magic")


@pytest.mark.parametrize("name", estimators.names())
def test_bad_records_rejected(name):
    est = estimators.get(name)
    with pytest.raises(ValueError, match="non-finite"):
        est.fit(np.r_[np.zeros(100), np.nan], 0.01)
    with pytest.raises(ValueError, match="dt"):
        est.fit(np.zeros(100), -1.0)
