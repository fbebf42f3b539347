"""std_err_ and conf_int on every registered estimator; intervals; bootstrap; coverage."""

import math
import warnings

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from avbench import estimators
from avbench.estimators.uncertainty import interval
from avbench.noise_models import AngleRandomWalk, BiasInstability, GaussMarkov, Gyro, RateRandomWalk

COEFS = ["Q", "N", "B", "K", "R"]


@pytest.fixture(scope="module")
def record():
    g = Gyro(dt=0.01, terms=[AngleRandomWalk(N=1e-3), GaussMarkov(sigma=2e-4, tc=5.0), RateRandomWalk(K=1e-6)])
    return g.simulate(30_000, np.random.default_rng(0)), g.dt


def _fit(name, x, dt):
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore")
        return estimators.get(name).fit(x, dt)


# the package's estimators (not the test-only ones other test modules register)
PACKAGE_ESTIMATORS = [n for n in estimators.names() if not n.startswith("test_")]


@pytest.mark.parametrize("name", PACKAGE_ESTIMATORS)
def test_std_err_and_conf_int_shapes_and_units(name, record):
    x, dt = record
    est = _fit(name, x, dt)
    se = est.std_err_
    assert isinstance(se, pd.Series) and list(se.index) == COEFS and se.dtype == float
    # NaN wherever the coefficient is NaN; never negative
    assert np.all(np.isnan(se[est.coefficients_.isna()]))
    assert np.all(se.dropna() >= 0)
    ci = est.conf_int()
    assert list(ci.index) == COEFS and list(ci.columns) == ["lower", "upper"]
    both = ci.dropna()
    assert np.all(both["lower"] >= 0) and np.all(both["lower"] <= both["upper"])
    # units: the interval brackets the estimate (SI, the same scale as coefficients_)
    c = est.coefficients_
    ok = c.notna() & (c > 0) & ci["lower"].notna()
    assert np.all(ci["lower"][ok] <= c[ok]) and np.all(c[ok] <= ci["upper"][ok])
    # a wider level gives a wider interval; the overbound is one-sided
    wide = est.conf_int(level=0.99)
    assert np.all(wide["upper"][ok] >= ci["upper"][ok])
    over = est.conf_int(conservative=True)
    assert np.all(over["lower"][over["upper"].notna()] == 0)


def test_not_fitted_and_bad_level_are_clear_errors(record):
    with pytest.raises(ValueError, match="not fitted"):
        estimators.get("whittle").conf_int()
    est = _fit("whittle", *record)
    with pytest.raises(ValueError, match="level"):
        est.conf_int(level=1.5)


def test_interval_is_the_log_scale_delta_interval():
    c = pd.Series({"N": 2.0, "B": 1.0})
    se = pd.Series({"N": 0.2, "B": 0.5})
    ci = interval(c, se, 0.9)
    z = stats.norm.ppf(0.95)
    np.testing.assert_allclose(ci.loc["N"], [2 * math.exp(-z * 0.1), 2 * math.exp(z * 0.1)])
    np.testing.assert_allclose(ci.loc["B"], [math.exp(-z * 0.5), math.exp(z * 0.5)])
    # overbound: Bonferroni over the two coefficients, one-sided
    over = interval(c, se, 0.9, conservative=True)
    z2 = stats.norm.ppf(1 - 0.1 / 2)
    np.testing.assert_allclose(over.loc["N"], [0.0, 2 * math.exp(z2 * 0.1)])
    assert ci.loc[["Q", "K", "R"]].isna().all().all()
    # a relative standard error above 0.5: the plain interval, clipped at 0
    wide = interval(pd.Series({"K": 1.0}), pd.Series({"K": 2.0}), 0.9)
    np.testing.assert_allclose(wide.loc["K"], [0.0, 1 + z * 2.0])


def test_bootstrap_agrees_with_the_analytic_standard_errors():
    """Whittle on white + flicker: bootstrap se (12 draws) vs the information se; ratio of variances
    within the chi^2_{11} 99.8 % interval."""
    n, dt = 20_000, 0.1
    g = Gyro(dt=dt, terms=[AngleRandomWalk(N=1e-3), BiasInstability(B=3e-4, tau_max=2 * n * dt)])
    est = estimators.get("whittle", terms="NB", select=False).fit(g.simulate(n, np.random.default_rng(5)), dt)
    analytic = est.std_err_.copy()
    est.bootstrap(n, dt, n_draws=12, seed=1)
    ratio = (est.std_err_ / analytic)[["N", "B"]] ** 2
    lo, hi = stats.chi2.ppf([0.001, 0.999], 11) / 11
    assert np.all((ratio > lo) & (ratio < hi)), ratio.to_dict()
    assert "bootstrap" in est.diagnostics_["std_err_method"]


def _coverage(name, settings, R, n, seed, coefs):
    dt = 0.1
    g = Gyro(dt=dt, terms=[AngleRandomWalk(N=1e-3), BiasInstability(B=3e-4, tau_max=2 * n * dt),
                           RateRandomWalk(K=3e-5)])
    truth = g.coefficients[coefs]
    hits, over = [], []
    for s in np.random.SeedSequence(seed).spawn(R):
        e = estimators.get(name, **settings).fit(g.simulate(n, np.random.default_rng(s)), dt)
        ci = e.conf_int(0.95)
        hits.append(((ci.loc[coefs, "lower"] <= truth) & (truth <= ci.loc[coefs, "upper"])).to_numpy())
        ob = e.conf_int(0.95, conservative=True)
        over.append(bool(np.all(truth <= ob.loc[coefs, "upper"])))
    return np.array(hits), np.array(over)


def _check_coverage(hits, over):
    R = hits.shape[0]
    # each coefficient's coverage is consistent with 95 % (binomial, two-sided 1e-3)
    lo, hi = stats.binom.ppf([5e-4, 1 - 5e-4], R, 0.95)
    k = hits.sum(axis=0)
    assert np.all((k >= lo) & (k <= hi)), (k, lo, hi)
    # the joint overbound holds at least 95 % of the time (one-sided 1e-3)
    assert over.sum() >= stats.binom.ppf(1e-3, R, 0.95)


def test_whittle_coverage_small():
    _check_coverage(*_coverage("whittle", dict(terms="NBK", select=False), R=30, n=36_000, seed=77,
                               coefs=["N", "B", "K"]))


@pytest.mark.slow
def test_whittle_coverage_slow():
    _check_coverage(*_coverage("whittle", dict(terms="NBK", select=False), R=400, n=72_000, seed=78,
                               coefs=["N", "B", "K"]))
