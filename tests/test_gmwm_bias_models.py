"""GMWM's intervals when the record does not clearly favour the bias-instability model fitted (``bias_evidence``
not decisive, or decisive for the other model): each interval holds the coefficient under either model (the
union of the Gauss-Markov and the flicker fits' intervals); the value stays the fitted model's; with evidence
decisive for the fitted model nothing changes.

The slow test measures what it is for: on gyros whose bias instability is flicker (outside the reported
Gauss-Markov model), 30-minute records at 100 Hz, the coverage of K's 95 % interval."""

import math
import warnings

import numpy as np
import pytest
from scipy.stats import binom

from avbench.estimators import get
from avbench.noise_models import (AngleRandomWalk, BiasInstability, FilteredWhiteNoise, GaussMarkov, Gyro,
                                  RateRandomWalk)

DT = 0.01
D2R = math.pi / 180
#: an ADIS16405-like gyro (results/real: N 2.45 deg/sqrt(h), B 38 deg/h, K 150 deg/h^1.5, its 5 ms filter) whose
#: bias instability is flicker, with a memory of 2 h
FLICKER = Gyro(dt=DT, terms=[FilteredWhiteNoise(N=2.45 * D2R / 60, tf=0.005),
                             BiasInstability(B=38 * D2R / 3600, tau_max=7200.0),
                             RateRandomWalk(K=150 * D2R / 216_000)])
TRUTH = {"N": 2.45 * D2R / 60, "B": 38 * D2R / 3600, "K": 150 * D2R / 216_000}


def _fit(x, **settings):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return get("gmwm_filtered", **settings).fit(x, DT)


def _own_conf_int(est, **kw):
    """The fitted model's own intervals: ``conf_int`` with no alternative model to hold."""
    import copy
    import dataclasses

    own = copy.copy(est)
    own.parts_ = dataclasses.replace(est.parts_, alternatives=())
    return own.conf_int(**kw)


def _alternative(est):
    ev = est.diagnostics_["bias_evidence"]
    return ev["FL" if ev["fitted"] == "GM" else "GM"]


def test_undecided_record_intervals_hold_both_models():
    x = FLICKER.simulate(60_000, np.random.default_rng(0))
    est = _fit(x)
    ev = est.diagnostics_["bias_evidence"]
    assert not ev["decisive"] and ev["fitted"] == "GM"
    alt = _alternative(est)
    base, union = _own_conf_int(est), est.conf_int()
    alt_ci = pd_interval(alt)
    widened = 0
    for c in ("N", "B", "K"):
        lo, hi = union.loc[c]
        assert lo <= base.at[c, "lower"] and hi >= base.at[c, "upper"]  # the fitted model's interval
        assert lo <= alt["coefficients"][c] <= hi  # the other model's value
        if np.isfinite(alt_ci.at[c, "lower"]):
            assert lo <= alt_ci.at[c, "lower"] and hi >= alt_ci.at[c, "upper"]  # and its interval
        widened += (lo, hi) != tuple(base.loc[c])
        assert lo <= est.coefficients_[c] <= hi
    assert widened >= 1
    # the value is the fitted model's, untouched; Q and R (in neither model) have no interval
    assert est.coefficients_["B"] == pytest.approx(ev["GM"]["coefficients"]["B"], rel=1e-12)
    assert union.loc[["Q", "R"]].isna().all().all()
    # other levels and the conservative bounds are widened the same way
    for kw in ({"level": 0.683}, {"conservative": True}):
        b, u = _own_conf_int(est, **kw), est.conf_int(**kw)
        assert (u["lower"].fillna(0) <= b["lower"].fillna(0)).all() and (u["upper"].fillna(0) >= b["upper"].fillna(0)).all()
    # the unit of the record changes nothing but the unit of the intervals
    milli = _fit(1000.0 * x)
    np.testing.assert_allclose(milli.conf_int().loc[["N", "B", "K"]].to_numpy(),
                               1000.0 * union.loc[["N", "B", "K"]].to_numpy(), rtol=1e-6)
    ev2 = milli.diagnostics_["bias_evidence"]
    for m in ("GM", "FL"):
        for c in ("N", "B", "K"):
            assert ev2[m]["coefficients"][c] == pytest.approx(1000 * ev[m]["coefficients"][c], rel=1e-6)


def pd_interval(model):
    import pandas as pd

    from avbench.estimators.uncertainty import interval

    return interval(pd.Series(model["coefficients"], dtype=float), pd.Series(model["std_err"], dtype=float))


def test_intervals_hold_the_other_model_where_the_record_clearly_favours_it():
    """30 minutes of the flicker gyro whose evidence decisively favours flicker (weight >= 0.95) over the
    Gauss-Markov model the values come from: the intervals hold the flicker fit's values and intervals, as where
    the evidence is undecided (a reported interval of the disfavoured model alone would miss what the record
    supports)."""
    est = _fit(FLICKER.simulate(180_000, np.random.default_rng(2)))
    ev = est.diagnostics_["bias_evidence"]
    assert ev["decisive"] and ev["preferred"] == "FL" and ev["fitted"] == "GM"
    alt, union, base = _alternative(est), est.conf_int(), _own_conf_int(est)
    alt_ci = pd_interval(alt)
    for c in ("N", "B", "K"):
        lo, hi = union.loc[c]
        assert lo <= base.at[c, "lower"] and hi >= base.at[c, "upper"]
        assert lo <= alt["coefficients"][c] <= hi
        if np.isfinite(alt_ci.at[c, "lower"]):
            assert lo <= alt_ci.at[c, "lower"] and hi >= alt_ci.at[c, "upper"]


def test_decisive_record_keeps_the_fitted_models_intervals():
    """A record with a clear Gauss-Markov hump: decisive evidence, intervals exactly the fitted model's (the hump
    ends the white region early, so the cut-offs within it the record accepts widen them too: without those, the
    fitted model's alone); and the plain ``gmwm`` (no bias evidence) is untouched."""
    g = Gyro(dt=DT, terms=[AngleRandomWalk(N=1e-3), GaussMarkov(sigma=1e-3, tc=5.0)])
    x = g.simulate(100_000, np.random.default_rng(4))
    est = _fit(x)
    assert est.diagnostics_["bias_evidence"]["decisive"]
    # the alternatives it holds are the accepted longer cut-offs alone: no other bias model
    assert len(est.parts_.alternatives) == len(est.diagnostics_.get("scale_alternatives") or {})
    plain = get("gmwm").fit(x, DT)
    assert "bias_evidence" not in plain.diagnostics_ and not plain.parts_.alternatives
    assert plain.conf_int().equals(_own_conf_int(plain))


#: records of the slow coverage test (30 min at 100 Hz each)
COVERAGE_RECORDS = 40


def _gauss_markov_gyro():
    """The same gyro with a Gauss-Markov bias instability of the same B (tc 50 s): inside the reported model."""
    from avbench.noise_models.terms import B_EQUIV_OVER_SIGMA

    return Gyro(dt=DT, terms=[FilteredWhiteNoise(N=TRUTH["N"], tf=0.005),
                              GaussMarkov(sigma=TRUTH["B"] / B_EQUIV_OVER_SIGMA, tc=50.0),
                              RateRandomWalk(K=TRUTH["K"])])


@pytest.mark.slow
@pytest.mark.timeout(3600)
@pytest.mark.parametrize("which", ["flicker", "gauss_markov"])
def test_k_interval_covers_when_the_bias_model_is_unknown(which):
    """30-minute records at 100 Hz, where the evidence between the two bias models is rarely decisive: K's
    interval that also holds the other model's fit covers the true K at a rate consistent with 95 %
    (binomial, one-sided 1 %), whether B is flicker (outside the reported Gauss-Markov model, which reads K
    high) or Gauss-Markov. Measured on 24 records each (seeds 1000-1023; this test uses others), the fitted
    model's own interval against the union: flicker K 14 -> 22 of 24, B 18 -> 21, N 22 -> 23; Gauss-Markov
    K 19 -> 23, B 24 -> 24; median widths +5-40 % (K on flicker the most). On this test's 40 records each:
    K 18 -> 36 (flicker) and 31 -> 34 (Gauss-Markov), 36 and 37 with K flagged not resolved with its data
    bound where B is."""
    gyro = FLICKER if which == "flicker" else _gauss_markov_gyro()
    held = 0
    for r in range(COVERAGE_RECORDS):
        est = _fit(gyro.simulate(180_000, np.random.default_rng(2000 + r)))
        unresolved = est.diagnostics_.get("unresolved") or {}
        lo, hi = unresolved["K"] if "K" in unresolved else est.conf_int().loc["K"]
        held += bool(lo <= TRUTH["K"] <= hi)
    # P(at most this many | n, 0.95) must not be below 1 %
    assert binom.cdf(held, COVERAGE_RECORDS, 0.95) >= 0.01, (held, COVERAGE_RECORDS)
