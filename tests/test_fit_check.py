"""The poor-fit check (estimators.fit_check): calibration under the model, power against a missing
term, and its presence in every curve-fitting estimator's diagnostics."""

import numpy as np
import pytest

import estimators
from estimators.fit_check import ALPHA, assess_fit, assess_five_term
from noise_models import AngleRandomWalk, GaussMarkov, Gyro, RateRandomWalk

G = Gyro(dt=0.1, terms=[AngleRandomWalk(N=1e-3), GaussMarkov(sigma=3e-4, tc=20.0), RateRandomWalk(K=3e-6)])


def test_statistic_is_chi2_under_the_true_model(tol):
    # with the true model and no fitted parameter, T ~ chi^2_k: its replicate mean is k
    R = 20
    stats_, dofs = [], set()
    for s in np.random.SeedSequence(7).spawn(R):
        d = assess_fit(G.simulate(50_000, np.random.default_rng(s)), 0.1, G.avar, G, 0)
        stats_.append(d["fit_stat"])
        dofs.add(d["fit_dof"])
    (k,) = dofs
    T = np.array(stats_)
    assert abs(T.mean() - k) < tol(T[:, None])[0]
    # and the chi^2 variance 2k: the sample variance within its chi^2_{R-1} 99.8 % interval
    from scipy import stats

    lo, hi = stats.chi2.ppf([0.001, 0.999], R - 1) / (R - 1)
    assert lo < T.var(ddof=1) / (2 * k) < hi


def test_missing_term_is_flagged_and_correct_model_is_not():
    x = G.simulate(200_000, np.random.default_rng(11))
    right = estimators.get("gmwm", model="WN+GM+RW").fit(x, 0.1).diagnostics_
    wrong = estimators.get("gmwm", model="WN+RW").fit(x, 0.1).diagnostics_
    assert wrong["poor_fit"] and wrong["fit_pvalue"] < 1e-6
    assert right["fit_pvalue"] > ALPHA / 10  # fixed seed; a correct model is flagged with prob. alpha
    # a five-term reading (plateau for the GM bump, no random walk) misses the curve
    d = assess_five_term(x, 0.1, {"N": 1e-3, "B": 3e-4 * 0.9294}, 2)
    assert d["poor_fit"] and np.nanmax(np.abs(d["fit_check"]["z"])) > 3


CURVE_FITTERS = ["ols", "ols_trimmed", "wls", "wls_edf", "slope_lines", "log_fit", "nnls_rel", "gmwm",
                 "gmwm_robust", "gmwm_despiked"]


@pytest.mark.parametrize("name", CURVE_FITTERS)
def test_every_curve_fit_reports_the_check(name):
    x = G.simulate(40_000, np.random.default_rng(3))
    d = estimators.get(name).fit(x, 0.1).diagnostics_
    assert isinstance(d["poor_fit"], bool)
    assert d["fit_dof"] >= 1 and 0.0 <= d["fit_pvalue"] <= 1.0 and d["fit_stat"] >= 0
    chk = d["fit_check"]
    assert len(chk["tau"]) == len(chk["avar"]) == len(chk["model"]) == len(chk["z"]) == d["fit_dof"] + (
        d["fit_check"]["tau"].size - d["fit_dof"])


def test_nonphysical_coefficient_leaves_its_term_out_and_is_flagged():
    # OLS of five terms on white noise + random walk gives a negative element somewhere or not;
    # a model with nothing in it cannot match a curve: p = 0
    x = G.simulate(20_000, np.random.default_rng(5))
    d = assess_five_term(x, 0.1, {"N": np.nan}, 1)
    assert d["poor_fit"] and d["fit_pvalue"] == 0.0
