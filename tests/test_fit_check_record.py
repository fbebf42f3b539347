"""The poor-fit check with the record's own variances (fit_check.record_variance_factor, GMWM's
``fit_covariance="record"``): the same check where the record shows no excess, still flagging a wrong
model, and tolerant only of the variability the record itself shows."""

import numpy as np
import pytest
from scipy import stats

from avbench import estimators
from avbench.estimators.allan.covariance import av_covariance
from avbench.estimators.allan.fit_check import (MIN_CLUSTERS, PINNED_LEVERAGE, RECORD_BATCHES, RECORD_LEVEL,
                                                record_reference_weights, record_residual_sd, record_variance_factor)
from avbench.noise_models import AngleRandomWalk, GaussMarkov, Gyro, RateRandomWalk

G = Gyro(dt=0.1, terms=[AngleRandomWalk(N=1e-3), GaussMarkov(sigma=3e-4, tc=50.0), RateRandomWalk(K=1e-6)])


def test_reference_weights_without_excess_are_the_chi2_of_gmm():
    # all factors 1: the model-weighted fit is efficient, T is chi^2_{k-p}: k - p ones and p zeros
    rng = np.random.default_rng(1)
    k, p = 9, 3
    a = rng.standard_normal((k, k))
    omega = a @ a.T + k * np.eye(k)
    lam = np.sort(record_reference_weights(omega, np.ones(k), rng.standard_normal((k, p))))
    assert np.allclose(lam, np.r_[np.zeros(p), np.ones(k - p)], atol=1e-9)
    # a factor above 1 on one scale: the statistic with the record's covariance is no longer chi^2_{k-p}
    f = np.ones(k)
    f[2] = 20.0
    lam2 = record_reference_weights(omega, f, rng.standard_normal((k, p)))
    assert not np.allclose(np.sort(lam2), np.r_[np.zeros(p), np.ones(k - p)], atol=1e-3)


def test_a_stationary_record_shows_no_excess_at_the_nominal_rate():
    # 40 stationary records of the model itself: a scale's factor exceeds 1 with probability RECORD_LEVEL;
    # the count over the scales the batches resolve is at most its binomial 99.9 % point
    n = 200_000
    m = 2 ** np.arange(15)
    m = m[n // m >= MIN_CLUSTERS]
    var = np.diag(av_covariance(G, m, n))
    seen = (n // RECORD_BATCHES) // m >= MIN_CLUSTERS
    hits = 0
    R = 40
    for s in range(R):
        f = record_variance_factor(G.simulate(n, np.random.default_rng(500 + s)), m, var, n)
        assert np.all(f >= 1.0)
        hits += int(np.count_nonzero(f[seen] > 1.0))
    assert hits <= stats.binom.ppf(0.999, R * int(seen.sum()), RECORD_LEVEL), hits


def test_a_record_whose_noise_moves_shows_it():
    # white noise whose level moves by +-40 % between the record's eighths: the short scales' AVs vary
    # between batches far beyond the stationary model's variance, and the factor says so
    n, dt = 200_000, 0.1
    rng = np.random.default_rng(7)
    level = np.repeat(1.0 + 0.4 * np.array([1, -1, 1, -1, -1, 1, -1, 1]), n // 8)
    x = 1e-3 / np.sqrt(dt) * level * rng.standard_normal(n)
    m = 2 ** np.arange(8)
    white = Gyro(dt=dt, terms=[AngleRandomWalk(N=1e-3 * float(np.sqrt(np.mean(level**2))))])
    f = record_variance_factor(x, m, np.diag(av_covariance(white, m, n)), n)
    assert np.all(f[:4] > 10.0), f


@pytest.mark.parametrize("seed", [11, 12, 13])
def test_the_record_check_still_flags_a_missing_term(seed):
    # a Gauss-Markov bump fitted without a bias term: flagged with the record's variances as with the model's
    x = G.simulate(200_000, np.random.default_rng(seed))
    wrong = estimators.get("gmwm", model="WN+RW", min_m=1, fit_covariance="record").fit(x, 0.1).diagnostics_
    assert wrong["poor_fit"] and wrong["fit_pvalue"] < 1e-6, wrong["fit_pvalue"]


def test_the_record_check_on_a_correct_model_is_the_model_check_where_nothing_moves():
    # stationary records of the model: same flags as the model check on most records (the two differ only
    # where a scale's batches show an excess, ~1 % per scale), and at most the binomial 99.9 % count of flags
    R, flags, same = 12, 0, 0
    for s in range(R):
        x = G.simulate(200_000, np.random.default_rng(900 + s))
        rec = estimators.get("gmwm", model="WN+GM+RW", min_m=1, fit_covariance="record").fit(x, 0.1)
        mod = estimators.get("gmwm", model="WN+GM+RW", min_m=1).fit(x, 0.1)
        flags += bool(rec.diagnostics_["poor_fit"])
        same += bool(np.isclose(rec.diagnostics_["fit_pvalue"], mod.diagnostics_["fit_pvalue"], rtol=1e-9))
        # the record's standard errors: the model's, times the Birge ratio sqrt(T / dof) where the misfit exceeds
        # its mean (diagnostics_["dispersion"]), and a record factor above 1 only widens
        d = rec.diagnostics_
        ratio = d.get("dispersion", 1.0)
        assert (ratio > 1.0) == (d["fit_stat"] > d["fit_dof"]) or "weights" in d["fit_check"]
        if "record_se_factor" not in d:
            assert np.allclose(rec.std_err_.fillna(0), mod.std_err_.fillna(0) * ratio)
        else:
            assert np.all(rec.std_err_.fillna(0) >= mod.std_err_.fillna(0) * ratio * (1 - 1e-12))
    assert flags <= stats.binom.ppf(0.999, R, 0.01), flags
    assert same >= R // 2, same


@pytest.mark.parametrize("fit_covariance", ["model", "record"])
def test_a_missing_random_walk_is_flagged_with_either_variance(fit_covariance):
    # a stationary record whose rate random walk the model lacks: the check flags it whichever variances it uses,
    # and its reading names the reference it was read against in words, not in degrees of freedom alone
    x = Gyro(dt=0.1, terms=[AngleRandomWalk(N=1e-3), RateRandomWalk(K=2e-6)]).simulate(200_000, np.random.default_rng(21))
    d = estimators.get("gmwm", model="WN", min_m=1, fit_covariance=fit_covariance).fit(x, 0.1).diagnostics_
    assert d["poor_fit"], d["fit_reading"]
    assert "where a record the fitted model describes gives about" in d["fit_reading"]


def test_a_missing_term_on_a_record_whose_noise_moves_is_still_flagged_and_the_move_said():
    # the white noise's level moves by +-40 % between eighths (the record's variances are used at the short
    # scales) and the model lacks the random walk: the flag stays, and the reading says the record moves
    n, dt = 200_000, 0.1
    rng = np.random.default_rng(8)
    level = np.repeat(1.0 + 0.4 * np.array([1, -1, 1, -1, -1, 1, -1, 1]), n // 8)
    x = 1e-3 / np.sqrt(dt) * level * rng.standard_normal(n)
    x += Gyro(dt=dt, terms=[RateRandomWalk(K=3e-6)]).simulate(n, rng)
    est = estimators.get("gmwm", model="WN", min_m=1, fit_covariance="record").fit(x, dt)
    d = est.diagnostics_
    assert np.any(d["fit_check"]["record_factor"] > 1.0)
    assert d["poor_fit"], d["fit_reading"]
    assert "NOT STATIONARY" in d["fit_reading"] and "largest residual" in d["fit_reading"]
    assert isinstance(d["fit_dof"], int) and est.result().fit_check.reading == d["fit_reading"]
    z, lim = np.asarray(d["fit_check"]["z"]), d["fit_check"]["residual_limit"]
    # the verdict agrees with the residuals the figure draws: a residual beyond its limit, or the whole misfit
    assert np.any(np.abs(z) > lim) or d["fit_pvalue"] < 0.005


def test_a_scale_the_fit_pins_is_judged_against_a_share_of_its_own_variance():
    # a parameter that moves only the first scale (a filter's time constant at the shortest tau), independent
    # values: the linearised residual variance there is 0, and the per-scale reading takes 1 - PINNED_LEVERAGE of
    # the value's variance; elsewhere the linearised standard deviation stands
    rng = np.random.default_rng(3)
    k = 8
    omega = np.diag(rng.uniform(1.0, 5.0, k))
    G = np.c_[np.eye(k)[:, 0], rng.standard_normal(k)]
    factor = np.ones(k)
    linear = record_residual_sd(omega, factor, G, pinned=1.0)
    assert linear[0] < 1e-6 * np.sqrt(omega[0, 0])
    sd = record_residual_sd(omega, factor, G)
    assert np.isclose(sd[0], np.sqrt((1 - PINNED_LEVERAGE) * omega[0, 0]))
    others = linear[1:] ** 2 >= (1 - PINNED_LEVERAGE) * np.diag(omega)[1:]
    assert np.allclose(sd[1:][others], linear[1:][others])


def test_the_per_scale_reading_holds_its_level_where_the_filter_pins_the_first_octave():
    # white noise through a first-order filter far faster than the sampling (tf = dt / 6: the MTi-G's), a
    # Gauss-Markov bias, 2e5 samples: gmwm_filtered keeps the first octave, which N and tf pin; the per-scale
    # reading made on the fit's scales (as assess_fit makes it where the record shows an excess) flags none of
    # 6 records at its level (alpha / 2 = 0.005: P(>= 1 of 6) = 3 %), while the linearised residual alone put that
    # octave's residual hundreds of its standard deviations out on every record
    from avbench.estimators.allan import fit_check as F
    from avbench.estimators.allan.variance import allan_variance
    from avbench.estimators.likelihood import gmwm as gmwm_module
    from avbench.noise_models import FilteredWhiteNoise

    dt, n = 0.01, 200_000
    g = Gyro(dt=dt, terms=[FilteredWhiteNoise(N=1e-3, tf=dt / 6), GaussMarkov(sigma=4e-4, tc=3.0)])
    captured = []
    orig = gmwm_module.assess_fit

    def spy(*args, **kw):
        if kw.get("record_covariance") and kw.get("jacobian") is not None:
            captured.append((args, kw))
        return orig(*args, **kw)

    flagged, pinned_out = 0, 0
    for s in range(6):
        captured.clear()
        gmwm_module.assess_fit = spy
        try:
            estimators.get("gmwm_filtered", model="FW+GM", lines="model", resonance="model",
                           bias_evidence=False).fit(g.simulate(n, np.random.default_rng(40 + s)) * 1e3, dt)
        finally:
            gmwm_module.assess_fit = orig
        (rate, _, model_avar, cov_gyro, *_), kw = captured[-1]
        tau_j, jac = kw["jacobian"]
        av = allan_variance(rate, dt, taus="octave")
        keep = (n // av.m >= MIN_CLUSTERS) & (av.tau >= tau_j[0] * (1 - 1e-9)) & (av.tau <= tau_j[-1] * (1 + 1e-9))
        assert av.m[keep][0] == 1
        args = (rate, av.m[keep], av.avar[keep], model_avar(av.tau[keep]), av_covariance(cov_gyro, av.m[keep], n),
                jac[np.searchsorted(tau_j, av.tau[keep])], n, F.ALPHA / 2)
        z, lim = F.scale_residuals(*args)
        flagged += bool(np.any(np.abs(z) > lim))
        z1, lim1 = F.scale_residuals(*args, pinned=1.0)
        pinned_out += bool(abs(z1[0]) > 100 * lim1[0])
    assert flagged == 0
    assert pinned_out == 6


def test_a_misfit_widens_the_intervals_by_its_birge_ratio():
    # the Gauss-Markov bump fitted without a bias term: the misfit T far above its reference's mean, so every
    # standard error is the record check's times sqrt(T / mean), and each interval holds the model covariance's
    x = G.simulate(200_000, np.random.default_rng(31))
    rec = estimators.get("gmwm", model="WN+RW", min_m=1, fit_covariance="record").fit(x, 0.1)
    mod = estimators.get("gmwm", model="WN+RW", min_m=1).fit(x, 0.1)
    d = rec.diagnostics_
    weights = d["fit_check"].get("weights")
    mean = float(np.sum(weights)) if weights is not None else d["fit_dof"]
    assert d["fit_stat"] > mean and np.isclose(d["dispersion"], np.sqrt(d["fit_stat"] / mean))
    se_r, se_m = rec.std_err_[["N", "K"]], mod.std_err_[["N", "K"]]
    assert np.all(se_r >= se_m * d["dispersion"] * (1 - 1e-12)), (se_r, se_m)
    ci_r, ci_m = rec.conf_int().loc[["N", "K"]], mod.conf_int().loc[["N", "K"]]
    assert np.all(ci_r["lower"] <= ci_m["lower"]) and np.all(ci_r["upper"] >= ci_m["upper"])


def test_the_bounds_read_the_av_with_the_edf_the_record_shows():
    # edf over the batches' factor (interpolated in log tau between the check's scales, held beyond) and over the
    # misfit's Birge ratio squared; the engine's where neither shows an excess
    from avbench.estimators.likelihood.gmwm import GMWM, WaveletVariance

    tau = np.array([0.1, 0.2, 0.4, 0.8, 1.6])
    wv = WaveletVariance(tau, np.ones(5), np.arange(1, 6), np.full(5, 100.0))
    check = {"fit_check": {"tau": tau[1:4]}}
    assert np.array_equal(GMWM._bound_edf(wv, check, np.ones(3)), wv.edf)
    edf = GMWM._bound_edf(wv, check, np.array([2.0, 4.0, 8.0]), dispersion=2.0)
    assert np.allclose(edf, 100.0 / 4.0 / np.array([2.0, 2.0, 4.0, 8.0, 8.0]))
