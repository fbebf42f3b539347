"""Whittle maximum likelihood: compiled kernel vs reference, recovery, standard errors, selection."""

import math

import numpy as np
import pytest

from avbench import estimators
from conftest import assert_mc_recovery
from avbench.estimators.likelihood._whittle_kernels import whittle_pass, whittle_pass_py
from avbench.estimators.likelihood.crlb import crlb
from avbench.estimators.likelihood.whittle_likelihood import WhittleFit
from avbench.noise_models import AngleRandomWalk, BiasInstability, GaussMarkov, Gyro, Quantization, RateRamp, RateRandomWalk

DT = 0.1


def flicker_gyro(n, ramp=False, K=3e-5):
    terms = [AngleRandomWalk(N=1e-3), BiasInstability(B=2e-4, tau_max=2 * n * DT), RateRandomWalk(K=K)]
    if ramp:
        terms.append(RateRamp(R=1e-6))
    return Gyro(dt=DT, terms=terms)


def test_kernel_matches_reference():
    g = Gyro(dt=DT, terms=[Quantization(Q=2e-5), AngleRandomWalk(N=1e-3), GaussMarkov(sigma=1e-4, tc=30.0),
                           RateRandomWalk(K=1e-5)])
    x = g.simulate(5001, np.random.default_rng(1))
    wf = WhittleFit(x, DT)
    comps = ["Q", "N", "GM", "K"]
    a = np.array([0.3, 1.2, 0.5, 0.01])
    Bm = wf.basis_matrix(comps, 30.0)
    D = wf.basis("GM", 31.0) - wf.basis("GM", 29.0)
    args = (a, Bm, D, 0.5, wf.X2, wf.GX, wf.G2, wf.w, float(wf.n))
    for grad in (False, True):
        for linear in (False, True):
            ref, got = whittle_pass_py(*args, grad, linear), whittle_pass(*args, grad, linear)
            for r, o in zip(ref, got):
                np.testing.assert_allclose(o, r, rtol=1e-10, atol=0)
    # the score and information in the variances themselves are those in their logs scaled by 1/a
    _, _, _, s_log, f_log = whittle_pass(*args, True)
    _, _, _, s_lin, f_lin = whittle_pass(*args, True, True)
    d = np.append(a, 1.0)
    np.testing.assert_allclose(s_lin, s_log / d, rtol=1e-10)
    np.testing.assert_allclose(f_lin, f_log / np.outer(d, d), rtol=1e-10)


def test_trend_regressor_is_the_dft_of_a_line():
    n = 1000
    wf = WhittleFit(np.arange(n, dtype=float) ** 1.5 + 1.0, DT)
    t = np.arange(n, dtype=float)
    np.testing.assert_allclose(wf.G, np.fft.rfft(t)[1:], rtol=1e-9, atol=1e-6)


def test_recovery_within_standard_errors_long_record():
    """4 h at 10 Hz of white + flicker + random walk + ramp, full model: every coefficient within
    4 standard errors (a 1e-4 two-sided normal quantile is 3.9)."""
    n = 144_000
    g = flicker_gyro(n, ramp=True)
    x = g.simulate(n, np.random.default_rng(7))
    est = estimators.get("whittle", terms="NBKR", select=False).fit(x, DT)
    z = (est.coefficients_ - g.coefficients) / est.std_err_
    assert np.all(np.abs(z[["N", "B", "K", "R"]]) < 4), z.to_dict()
    # standard errors are the Cramér-Rao bound at the estimate: close to the bound at the truth
    ratio = est.std_err_[["N", "B", "K"]] / crlb(Gyro(dt=DT, terms=g.terms[:3]), n)[["N", "B", "K"]]
    assert np.all((ratio > 0.7) & (ratio < 1.4)), ratio.to_dict()


def test_gauss_markov_bias_reports_b_equiv():
    n = 100_000
    g = Gyro(dt=DT, terms=[AngleRandomWalk(N=1e-3), GaussMarkov(sigma=3e-4, tc=60.0)])
    x = g.simulate(n, np.random.default_rng(3))
    est = estimators.get("whittle", terms="NB", bias="gauss_markov", select=False).fit(x, DT)
    z = (est.coefficients_ - g.coefficients) / est.std_err_
    assert abs(z["B"]) < 4 and abs(z["N"]) < 4, z.to_dict()
    assert abs(math.log(est.diagnostics_["tc"] / 60.0)) < 0.5


@pytest.mark.parametrize("criterion", ["bic", "lr"])
def test_selection_finds_the_true_terms_on_a_long_record(criterion):
    n = 144_000
    g = flicker_gyro(n)  # N, B, K present; Q and R absent
    x = g.simulate(n, np.random.default_rng(11))
    est = estimators.get("whittle", criterion=criterion).fit(x, DT)
    assert est.diagnostics_["terms"] == "NBK", est.diagnostics_["selection"]
    assert est.coefficients_["Q"] == 0 and est.coefficients_["R"] == 0
    ci = est.conf_int()
    assert ci.loc["Q", "lower"] == 0 and np.isfinite(ci.loc["Q", "upper"])


@pytest.mark.parametrize("bad", [dict(terms="X"), dict(bias="pink"), dict(select="yes"), dict(n_starts=0),
                                 dict(terms="R"), dict(criterion="aic"), dict(reml=1)])
def test_bad_settings_are_clear_errors(bad):
    x = np.random.default_rng(0).standard_normal(1000)
    with pytest.raises(ValueError):
        estimators.get("whittle", **bad).fit(x, DT)


def _monte_carlo(R, n, seed):
    g = flicker_gyro(n)
    est, se = [], []
    for s in np.random.SeedSequence(seed).spawn(R):
        e = estimators.get("whittle", terms="NBK", select=False).fit(g.simulate(n, np.random.default_rng(s)), DT)
        est.append(e.coefficients_[["N", "B", "K"]].to_numpy())
        se.append(e.std_err_[["N", "B", "K"]].to_numpy())
    return g, np.array(est), np.array(se)


def _check_monte_carlo(g, est, se):
    assert_mc_recovery(g.coefficients[["N", "B", "K"]].to_numpy(), est, se)


def test_monte_carlo_standard_errors_small():
    _check_monte_carlo(*_monte_carlo(R=16, n=72_000, seed=2024))


@pytest.mark.slow
def test_monte_carlo_standard_errors_slow():
    _check_monte_carlo(*_monte_carlo(R=200, n=144_000, seed=2025))


@pytest.mark.parametrize("seed", [41, 115])
def test_a_poor_start_is_retried_until_scoring_converges(seed):
    """20 min of SRS2000 (quantization-dominated): on these records the relative-residual NNLS start
    reads white noise as quantization and Fisher scoring crawls without converging (N off by 20-90 %).
    The fit must converge, and to a likelihood no lower than scoring started at the truth reaches."""
    from avbench.noise_models import presets

    g = presets.get("SRS2000")
    x = g.simulate(12_000, np.random.default_rng(seed))
    est = estimators.get("whittle", terms="QNBKR", select=False).fit(x, g.dt)
    d = est.diagnostics_
    assert d["converged"], d.get("failure")
    wf = WhittleFit(x, g.dt)
    comps = ["Q", "N", "B", "K"]
    k_tiny = 1e-6 * g.coefficients["N"] ** 2 * g.dt**2  # no random walk: a variance at its floor
    truth = np.array([g.coefficients[c] ** 2 for c in "QNB"] + [k_tiny]) / wf.scale**2
    _, top = wf.start(comps)
    a, _, ll_truth, _, conv, _ = wf.fit(comps, truth, None, np.log(1e-6 * top))
    assert conv
    assert est.result().llf >= ll_truth - 1e-6
    assert abs(est.coefficients_["N"] / g.coefficients["N"] - 1) < 5 * est.std_err_["N"] / g.coefficients["N"]


def _dense_covariance(comp, n, dt, tc=None):
    """Time-domain covariance of one unit-variance term (normalised units, as WhittleFit uses)."""
    from scipy.linalg import toeplitz

    lag = np.arange(n)
    if comp == "N":
        return np.eye(n) / dt
    if comp == "Q":
        r = np.zeros(n)
        r[0], r[1] = 2 / dt**2, -1 / dt**2
        return toeplitz(r)
    if comp == "GM":
        return toeplitz(np.exp(-lag * dt / tc))
    if comp == "B":  # a filter memory far beyond the record: the ideal 1/f up to ~1e-5
        return toeplitz(BiasInstability(B=1.0, tau_max=1e6 * dt).autocovariance(np.arange(n), dt))
    if comp == "K":  # random walk of increments with variance dt
        s = np.minimum.outer(lag, lag) + 1.0
        return s * dt
    raise AssertionError(comp)


@pytest.mark.parametrize("comp", ["N", "Q", "GM", "B", "K"])
@pytest.mark.parametrize("n", [300, 301])
def test_trend_variance_is_the_exact_quadratic_form(comp, n):
    """WhittleFit.trend_weights reproduce the profiled slope, and trend_variance equals c^T Sigma c with
    each term's dense covariance (the random walk's includes its end-point drift)."""
    rng = np.random.default_rng(n)
    x = rng.standard_normal(n).cumsum() * 0.1 + rng.standard_normal(n)
    wf = WhittleFit(x, DT)
    comps, a, tc = ["N", "B", "K"], np.array([1.0, 0.3, 0.01]), None
    beta = wf.evaluate(comps, a)[1]
    c = wf.trend_weights(comps, a)
    assert abs(c @ (x / wf.scale) - beta) < 1e-10 * abs(beta)
    assert abs(c.sum()) < 1e-12 * np.abs(c).sum()
    one_tc = 40 * DT if comp == "GM" else None
    both = ["N"] + ([comp] if comp != "N" else [])  # white noise keeps the spectrum positive
    got = wf.trend_variance(both, np.ones(len(both)), one_tc)
    cc = wf.trend_weights(both, np.ones(len(both)), one_tc)
    want = cc @ sum(_dense_covariance(x, n, DT, one_tc) for x in both) @ cc
    assert got == pytest.approx(want, rel=1e-4 if comp == "B" else 1e-9)


def test_trend_variance_holds_a_random_walk_the_model_dropped():
    """``a_walk`` (the full model's random walk, given to the ramp test) enters the slope's variance also
    when the reported model has no random walk: c^T (Sigma_N + Sigma_B + a_walk Sigma_K) c with the
    reported model's weights c. A random walk too weak to be kept still drifts."""
    n = 300
    rng = np.random.default_rng(5)
    x = rng.standard_normal(n).cumsum() * 0.1 + rng.standard_normal(n)
    wf = WhittleFit(x, DT)
    comps, a, a_walk = ["N", "B"], np.array([1.0, 0.3]), 0.01
    c = wf.trend_weights(comps, a)
    sigma = sum(v * _dense_covariance(comp, n, DT) for comp, v in zip(comps, a))
    want = c @ (sigma + a_walk * _dense_covariance("K", n, DT)) @ c
    assert wf.trend_variance(comps, a, a_walk=a_walk) == pytest.approx(want, rel=1e-4)
    assert wf.trend_variance(comps, a, a_walk=a_walk) > 1.01 * wf.trend_variance(comps, a)


def _ramp_z2(R, seed):
    """Squared z-statistics of the slope on R records of 20 min of SRS2000 (Q + N + flicker, no ramp),
    with the slope's variance from the true spectrum and from the fitted one."""
    from avbench.noise_models import presets

    g = presets.get("SRS2000")
    truth, fitted = [], []
    for s in np.random.SeedSequence(seed).spawn(R):
        x = g.simulate(12_000, np.random.default_rng(s))
        wf = WhittleFit(x, g.dt)
        a = np.array([g.coefficients[c] ** 2 for c in "QNB"]) / wf.scale**2
        beta = wf.trend_weights(list("QNB"), a) @ (x / wf.scale)
        truth.append(beta**2 / wf.trend_variance(list("QNB"), a))
        e = estimators.get("whittle", terms="QNBR", select=False).fit(x, g.dt)
        fitted.append((e.coefficients_["R"] / e.std_err_["R"]) ** 2)
    return np.array(truth), np.array(fitted)


def _check_ramp_z2(truth, fitted):
    """chi^2_1 under the model: mean 1 with standard error sqrt(2/R), 3 SE either side."""
    R = truth.size
    tol = 3 * math.sqrt(2 / R)
    assert abs(truth.mean() - 1) < tol, truth.mean()
    assert abs(fitted.mean() - 1) < tol, fitted.mean()  # the plug-in (the frequency-domain GLS variance gives ~6)


def test_ramp_standard_error_matches_the_spread_small():
    _check_ramp_z2(*_ramp_z2(R=60, seed=31))


@pytest.mark.slow
def test_ramp_standard_error_matches_the_spread_slow():
    _check_ramp_z2(*_ramp_z2(R=400, seed=32))


@pytest.mark.parametrize("shape", ["gauss_markov", "flicker"])
def test_bias_select_tells_gauss_markov_from_flicker(shape):
    """30 min at 100 Hz of a gyro whose bias instability is a Gauss-Markov process (Tc 11 s, well
    inside the band) or flicker of the same level: bias="select" keeps the true spectrum, by a margin
    of the penalised likelihood far beyond its noise (29-90 on 3 seeds each), and B follows it."""
    bias = (GaussMarkov(sigma=(9.55, "deg/h"), tc=11.26) if shape == "gauss_markov"
            else BiasInstability(B=(9.55, "deg/h"), tau_max=7200))
    g = Gyro(dt=0.01, terms=[AngleRandomWalk(N=(0.1217, "deg/sqrt(h)")), bias])
    est = estimators.get("whittle", bias="select").fit(g.simulate(180_000, np.random.default_rng(0)), g.dt)
    d = est.diagnostics_
    other = "flicker" if shape == "gauss_markov" else "gauss_markov"
    assert est.result().model_choice["bias_model"]["chosen"] == shape
    assert d["bias_models"][other] - d["bias_models"][shape] > 10
    assert abs(est.coefficients_["B"] / g.coefficients["B"] - 1) < 4 * est.std_err_["B"] / g.coefficients["B"]


def test_bias_select_without_a_bias_term_fits_once():
    g = Gyro(dt=DT, terms=[AngleRandomWalk(N=1e-3), RateRandomWalk(K=1e-5)])
    est = estimators.get("whittle", terms="NK", bias="select").fit(g.simulate(50_000, np.random.default_rng(1)), DT)
    assert list(est.diagnostics_["bias_models"]) == ["flicker"]


@pytest.mark.parametrize("comps, tc", [(["N", "B", "K"], None), (["Q", "N", "GM", "K"], 30.0)])
def test_reml_score_is_the_derivative_of_the_restricted_likelihood(comps, tc):
    x = flicker_gyro(30_000).simulate(30_000, np.random.default_rng(0))
    wf = WhittleFit(x, DT, reml=True)
    a, _ = wf.start(comps, tc)
    ll, _, sgg, score, _ = wf.evaluate(comps, a, tc, grad=True)
    assert ll == pytest.approx(WhittleFit(x, DT).loglik(comps, a, tc) - 0.5 * math.log(sgg), rel=1e-13)
    h = 1e-4
    for j in range(score.size):
        up, dn = np.array(a), np.array(a)
        tu = td = tc
        if j < len(a):
            up[j] *= math.exp(h)
            dn[j] *= math.exp(-h)
        else:
            tu, td = tc * math.exp(h), tc * math.exp(-h)
        num = (wf.loglik(comps, up, tu) - wf.loglik(comps, dn, td)) / (2 * h)
        assert num == pytest.approx(score[j], rel=1e-3, abs=1e-5 * abs(score).max())


def _reml_bias(R, seed):
    """B^2 of the ADIS 50 Hz preset (N + flicker) on R records of 20 min, fitted with its true terms:
    mean error over its Monte Carlo standard error, profile and restricted likelihood."""
    from avbench.noise_models import presets

    g = presets.get("ADIS16405_X_50HZ")
    b2 = {False: [], True: []}
    for s in np.random.SeedSequence(seed).spawn(R):
        x = g.simulate(60_000, np.random.default_rng(s))
        for reml in (False, True):
            est = estimators.get("whittle", terms="NB", select=False, reml=reml).fit(x, g.dt)
            b2[reml].append(est.coefficients_["B"] ** 2)
    t = g.coefficients["B"] ** 2
    return {k: (np.mean(v) - t) / (np.std(v, ddof=1) / math.sqrt(R)) for k, v in b2.items()}


def test_reml_variance_of_flicker_unbiased_small():
    z = _reml_bias(R=30, seed=41)
    assert abs(z[True]) < 3, z


@pytest.mark.slow
def test_reml_variance_of_flicker_unbiased_slow():
    """400 replicates: the profile likelihood's B^2 is biased low (~ -0.28 CRLB, > 4 SE here), the
    restricted one's not detectably (3 SE)."""
    z = _reml_bias(R=400, seed=42)
    assert abs(z[True]) < 3, z
    assert z[False] < -3, z


def _lr_ramp_rate(R, seed):
    """Share of R records of 20 min of SRS2000 (no ramp) in which the LR criterion keeps a ramp."""
    from avbench.noise_models import presets

    g = presets.get("SRS2000")
    kept = 0
    for s in np.random.SeedSequence(seed).spawn(R):
        e = estimators.get("whittle", criterion="lr").fit(g.simulate(12_000, np.random.default_rng(s)), g.dt)
        kept += e.coefficients_["R"] > 0
    return kept / R


def _check_lr_ramp_rate(rate, R):
    """A test at level 5 % keeps a ramp that is not there in no more than 5 % of records, up to 3
    binomial SE (measured: 3.3 % at 600 records; the model's random walk, fitted though absent, adds
    drift variance, which makes the test a little conservative)."""
    assert rate < 0.05 + 3 * math.sqrt(0.05 * 0.95 / R), rate


@pytest.mark.parametrize("criterion, threshold", [("lr", 3.841458820694124), ("bic", None)])
def test_ramp_is_kept_exactly_when_its_z2_passes_the_criterion(criterion, threshold):
    """The ramp's threshold: the two-sided chi2_1 95 % point for the LR test (its slope's null is not on
    a boundary, unlike a variance's), log n for BIC. Records with a ramp of every strength around it."""
    g = Gyro(dt=DT, terms=[AngleRandomWalk(N=1e-3), BiasInstability(B=3e-4, tau_max=2e4)])
    n = 40_000
    threshold = threshold or math.log(n)
    rng = np.random.default_rng(8)
    seen = []
    for slope in np.linspace(0, 4e-8, 24):
        x = g.simulate(n, rng) + slope * np.arange(n)
        e = estimators.get("whittle", terms="NBR", criterion=criterion).fit(x, DT)
        z2 = e.diagnostics_["ramp_z2"]
        assert (e.coefficients_["R"] > 0) == (z2 > threshold), (z2, e.coefficients_["R"])
        seen.append(z2)
    assert min(seen) < threshold < max(seen)  # both sides were exercised
    if criterion == "lr":  # and the band a boundary-mixture threshold (2.706) would decide otherwise
        assert any(2.706 < z < threshold for z in seen)


def test_lr_ramp_test_has_its_level_small():
    _check_lr_ramp_rate(_lr_ramp_rate(100, 51), 100)


@pytest.mark.slow
def test_lr_ramp_test_has_its_level_slow():
    _check_lr_ramp_rate(_lr_ramp_rate(600, 52), 600)
