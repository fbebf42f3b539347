"""De-biased Whittle likelihood, profile-likelihood intervals and per-term evidence (issue 23)."""

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from scipy import stats

from avbench import estimators
from avbench.estimators.likelihood.whittle import _chibar2_pvalue, _expected_periodogram
from avbench.noise_models import AngleRandomWalk, BiasInstability, Gyro, RateRandomWalk

DT = 0.1


def _toeplitz_expected_periodogram(c, n):
    """E[I_k] = (1/n) sum_{s,t} c(|s-t|) e^{-i w_k (s-t)} by the double sum (the definition)."""
    k = np.arange(1, n // 2 + 1)
    s = np.arange(n)
    lag = np.abs(s[:, None] - s[None, :])
    C = c[lag]
    E = np.exp(-2j * np.pi * np.outer(k, s) / n)
    return np.real(np.einsum("ks,st,kt->k", E, C, np.conj(E))) / n


@pytest.mark.parametrize("n", [64, 65])
@pytest.mark.parametrize("coef", ["Q", "GM", "B"])
def test_expected_periodogram_is_the_double_sum(coef, n):
    from scipy.special import digamma

    tau = np.arange(n, dtype=float)
    if coef == "Q":
        c = np.zeros(n)
        c[0], c[1] = 2 / DT**2, -1 / DT**2
    elif coef == "GM":
        c = np.exp(-tau * DT / 1.7)
    else:  # ideal flicker: -variogram (plus any constant: the Fejer kernel vanishes at k >= 1)
        c = 5.0 - (digamma(tau + 0.5) - digamma(0.5)) / math.pi
    got = _expected_periodogram(coef, n, DT, 1.7 if coef == "GM" else None)
    np.testing.assert_allclose(got, _toeplitz_expected_periodogram(c, n), rtol=1e-10, atol=1e-12 * np.max(np.abs(got)))


def test_expected_periodogram_of_flicker_matches_simulation():
    """The flicker generator's mean periodogram (tau_max >> record) at the lowest ordinates is the
    expected periodogram, not the 1/f spectrum (which is ~20 % low at k = 1). 400 records:
    each ordinate's mean has relative std 1/20; the mean over k = 1..4 of the ratio 1/40."""
    n, R = 512, 400
    g = Gyro(dt=DT, terms=[BiasInstability(B=1.0, tau_max=10 * n * DT)])
    rng = np.random.default_rng(7)
    acc = np.zeros(n // 2)
    for _ in range(R):
        acc += np.abs(np.fft.rfft(g.simulate(n, rng))[1:]) ** 2 / n
    acc /= R
    ratio = acc[:4] / _expected_periodogram("B", n, DT)[:4]
    assert abs(ratio.mean() - 1) < 3.5 / math.sqrt(4 * R)


@given(st.floats(min_value=0.0, max_value=200.0))
@settings(max_examples=50, deadline=None)
def test_chibar2_pvalue_is_half_the_chi2_tail(lr):
    p = _chibar2_pvalue(lr)
    if lr == 0:
        assert p == 1.0
    else:
        assert p == pytest.approx(0.5 * stats.chi2.sf(lr, 1), rel=1e-12, abs=1e-300)
        assert 0 <= p <= 0.5


def _gyro(n, K=True):
    terms = [AngleRandomWalk(N=1e-3), BiasInstability(B=2e-4, tau_max=2 * n * DT)]
    if K:
        terms.append(RateRandomWalk(K=3e-5))
    return Gyro(dt=DT, terms=terms)


def test_every_term_reported_with_its_interval_and_evidence():
    n = 20_000
    g = _gyro(n, K=False)
    e = estimators.get("whittle_debiased").fit(g.simulate(n, np.random.default_rng(3)), DT)
    ev = e.diagnostics_["evidence"]
    ci = e.conf_int()
    assert set(ev.index) == set("QNBKR")
    for c in "QNBKR":
        assert np.isfinite(e.coefficients_[c]) and np.isfinite(ci.loc[c, "upper"])
        assert ci.loc[c, "lower"] <= e.coefficients_[c] <= ci.loc[c, "upper"]
        assert 0 <= ev.loc[c, "p_value"] <= 1
    assert ci.loc["N", "lower"] > 0 and ev.loc["N", "p_value"] < 1e-6 and bool(ev.loc["N", "present"])
    # the profile bounds are the intervals conf_int gives at 95 %; other levels fall back to Wald
    np.testing.assert_allclose(ci.loc[list(ev.index)].to_numpy(), ev[["lower", "upper"]].to_numpy())
    assert not np.allclose(e.conf_int(0.9).loc["N"].to_numpy(), ci.loc["N"].to_numpy())
    # the ramp's evidence: |R| +- z s with s >= its standard error (the random walk's drift at K's
    # upper bound), and its p-value the two-sided chi^2_1 tail of (|R| / s)^2
    r = e.coefficients_["R"] if e.coefficients_["R"] > 0 else math.sqrt(e.diagnostics_["ramp_z2"]) * e.std_err_["R"]
    s = (ev.loc["R", "upper"] - r) / stats.norm.ppf(0.975)
    assert s >= e.std_err_["R"] * (1 - 1e-9)
    assert ev.loc["R", "p_value"] == pytest.approx(stats.chi2.sf((r / s) ** 2, 1), rel=1e-6)


@pytest.mark.parametrize("debiased,signed", [(True, False), (False, False), (True, True)])
def test_profile_bounds_are_where_the_likelihood_ratio_reaches_its_quantile(debiased, signed):
    """At every non-zero bound of every term (a well-resolved N, whose interval is a fraction of a
    per cent, as well as B and K) the profile likelihood ratio is chi^2_1(0.95), to the root's
    tolerance on the signed root (0.01, plus the refit's own); a zero lower bound has LR(0) <= it.
    ``signed``: the maximum and the profiles over the domain of a positive model spectrum."""
    from avbench.estimators.likelihood.whittle import WhittleFit, profile_evidence, whittle_fit

    n = 100_000
    x = _gyro(n).simulate(n, np.random.default_rng(5))
    wf = WhittleFit(x, DT, debiased=debiased)
    full = whittle_fit(wf, ["N", "B", "K"], signed=signed)
    ev, best = profile_evidence(wf, full)
    root_q = math.sqrt(stats.chi2.ppf(0.95, 1))
    for i, c in enumerate(full["comps"]):
        assert ev[c]["upper"] > full["a"][i]
        for bound in ("upper", "lower"):
            if ev[c][bound] == 0.0:
                assert ev[c]["lr"] <= stats.chi2.ppf(0.95, 1)
                continue
            a = full["a"].copy()
            a[i] = ev[c][bound]
            r = wf.fit(full["comps"], a, None, np.full(3, -np.inf), fixed=i, tol=1e-10, signed=signed)
            assert abs(math.sqrt(max(2 * (best - r[2]), 0.0)) - root_q) < 0.03, (c, bound)


@pytest.mark.parametrize("settings_", [{}, dict(interval_domain="switch"), dict(calibration="bartlett", n_boot=10)])
def test_answer_does_not_depend_on_the_unit(settings_):
    n = 20_000
    x = _gyro(n).simulate(n, np.random.default_rng(11))
    a = estimators.get("whittle_debiased", **settings_).fit(x, DT)
    b = estimators.get("whittle_debiased", **settings_).fit(x * (180 / math.pi), DT)
    for c in "NBK":
        assert b.coefficients_[c] == pytest.approx(a.coefficients_[c] * 180 / math.pi, rel=1e-4, abs=1e-12)
        assert b.conf_int().loc[c, "upper"] == pytest.approx(a.conf_int().loc[c, "upper"] * 180 / math.pi, rel=2e-3)


def _signed_fits(g, R, n, seed, comps):
    """Variances (SI) of the maxima over the positive-spectrum domain and over a >= 0, and each
    signed fit's minimum expected periodogram relative to its largest."""
    from avbench.estimators.likelihood.whittle import WhittleFit, whittle_fit

    out = []
    for s in np.random.SeedSequence(seed).spawn(R):
        wf = WhittleFit(g.simulate(n, np.random.default_rng(s)), DT, debiased=True)
        sf = whittle_fit(wf, comps, signed=True)
        nf = whittle_fit(wf, comps)
        S = sf["a"] @ wf._matrix(sf["comps"], None)
        assert sf["loglik"] >= nf["loglik"] - 1e-9 * abs(nf["loglik"])
        assert set(sf["absent"]) == {c for c, v in zip(sf["comps"], sf["a"]) if v <= 0}
        out.append(np.concatenate([sf["a"] * wf.scale**2, nf["a"] * wf.scale**2, [S.min() / S.max()]]))
    return np.array(out)


def test_signed_domain_keeps_the_spectrum_positive_and_is_unbiased_beside_an_absent_term():
    """Candidates N, B, K on a gyro without K: the signed maximum takes K below 0 in some records
    (the domain is used) with the expected periodogram positive at every ordinate, never has a lower
    likelihood than the non-negative one, and its variance of B is unbiased: the mean over R records
    within 3.5 standard errors of the truth (the non-negative maximum pushes B down whenever K
    would go below 0)."""
    _check_signed_unbiased(R=40, seed=232)


def _check_signed_unbiased(R, seed, n=7_200):
    g = _gyro(n, K=False)
    v = _signed_fits(g, R, n, seed=seed, comps=["N", "B", "K"])
    assert np.all(v[:, -1] > 0)
    assert np.sum(v[:, 2] < 0) >= stats.binom.ppf(0.001, R, 0.25)  # K's variance is below 0 in about half the records
    for j, c in ((0, "N"), (1, "B")):
        err = v[:, j] - g.coefficients[c] ** 2
        assert abs(err.mean()) < 3.5 * err.std(ddof=1) / math.sqrt(R), c
    return v


@pytest.mark.slow
def test_signed_domain_unbiased_slow():
    """The same at 400 records (the bias of B's variance resolved to ~0.05 of its spread)."""
    _check_signed_unbiased(R=400, seed=234)


def test_signed_domain_reports_no_negative_coefficient():
    """A variance below 0 is reported as the coefficient 0 with an interval [0, upper] and no
    evidence (LR 0, p 1); every reported coefficient and bound is >= 0."""
    n = 7_200
    g = _gyro(n, K=False)
    seen = False
    for s in np.random.SeedSequence(233).spawn(6):
        e = estimators.get("whittle_debiased").fit(g.simulate(n, np.random.default_rng(s)), DT)
        ci, ev = e.conf_int(), e.diagnostics_["evidence"]
        assert np.all(e.coefficients_[list("QNBKR")] >= 0) and np.all(ci.loc[list("QNBKR")].to_numpy() >= 0)
        for c in "QK":
            if e.coefficients_[c] == 0:
                seen = True
                assert ci.loc[c, "lower"] == 0 < ci.loc[c, "upper"]
                assert ev.loc[c, "p_value"] == 1.0
    assert seen


@pytest.mark.parametrize("bad", [dict(spectrum="tapered"), dict(intervals="bayes"), dict(domain="real"),
                                 dict(interval_domain="both"), dict(calibration="bca"), dict(n_boot=5)])
def test_bad_settings_are_clear_errors(bad):
    with pytest.raises(ValueError, match=next(iter(bad))):
        estimators.get("whittle_debiased", **bad).fit(np.random.default_rng(0).standard_normal(1000), DT)


def _coverage(R, n, seed):
    """Per replicate, at the defaults (candidates QNBKR): does the 95 % interval hold N, B, K
    (present) and 0 for Q and for the ramp R (absent; R beside a random walk whose drift it must
    not be read as)?"""
    g = _gyro(n)
    truth = g.coefficients
    hits = []
    for s in np.random.SeedSequence(seed).spawn(R):
        e = estimators.get("whittle_debiased").fit(g.simulate(n, np.random.default_rng(s)), DT)
        ci = e.conf_int()
        row = [ci.loc[c, "lower"] <= truth[c] <= ci.loc[c, "upper"] for c in "NBK"]
        row += [ci.loc[c, "lower"] == 0.0 for c in "QR"]
        hits.append(row)
    return np.array(hits)


def _check_coverage(hits):
    """Each column's misses are Binomial(R, <= 0.05): fail past the 99.9 % point of that law."""
    R = hits.shape[0]
    limit = stats.binom.ppf(0.999, R, 0.05)
    misses = R - hits.sum(axis=0)
    assert np.all(misses <= limit), (misses, limit)


def test_coverage_without_the_true_terms_small():
    _check_coverage(_coverage(R=12, n=7_200, seed=230))


@pytest.mark.slow
def test_coverage_without_the_true_terms_slow():
    hits = _coverage(R=400, n=72_000, seed=231)
    _check_coverage(hits)
    # and not wildly conservative: at least 90 % - 3 binomial std
    assert np.all(hits[:, :3].mean(axis=0) >= 0.95 - 3 * math.sqrt(0.05 * 0.95 / 400))


def _fit_check_rates(g, R, n, seed, spectrum="debiased"):
    p = []
    for s in np.random.SeedSequence(seed).spawn(R):
        e = estimators.get("whittle", select=False, spectrum=spectrum).fit(g.simulate(n, np.random.default_rng(s)), DT)
        assert e.diagnostics_["poor_fit"] == (e.diagnostics_["fit_pvalue"] < 0.01)
        p.append(e.diagnostics_["fit_pvalue"])
    return np.array(p)


def _check_false_alarms(p):
    """With the right model the p-values are ~uniform: flags at 1 % and 5 % within their binomial 99.9 % points."""
    R = p.size
    assert np.sum(p < 0.01) <= stats.binom.ppf(0.999, R, 0.01)
    assert np.sum(p < 0.05) <= stats.binom.ppf(0.999, R, 0.05)


def test_fit_check_false_alarms_and_power_small():
    n = 20_000
    _check_false_alarms(_fit_check_rates(_gyro(n), R=20, n=n, seed=71))
    # a Gauss-Markov bias read as flicker: flagged at 1 % in about half the records of 20 000 samples
    from avbench.noise_models import GaussMarkov

    wrong = Gyro(dt=DT, terms=[AngleRandomWalk(N=1e-3), GaussMarkov(sigma=1e-3, tc=20.0)])
    p = _fit_check_rates(wrong, R=20, n=n, seed=72)
    assert np.sum(p < 0.01) > stats.binom.ppf(0.999, 20, 0.01)


@pytest.mark.slow
@pytest.mark.parametrize("spectrum", ["debiased", "plain"])
def test_fit_check_false_alarms_slow(spectrum):
    n = 72_000
    _check_false_alarms(_fit_check_rates(_gyro(n), R=300, n=n, seed=73, spectrum=spectrum))


def test_profile_fit_raises_a_term_from_its_floor_without_crawling():
    """A profile fit whose terms must rise from their floors (20 min of the ADIS16405_X preset, B
    held near its lower profile bound) reaches the likelihood of the log-scale scoring of the point
    fits in a few steps, where that scoring crawls for hundreds (the huge log step of a floored
    term, once the step vector is capped, stalls every parameter): the profile fits score in the
    variances themselves (``hold_floor``)."""
    from avbench.estimators.likelihood.whittle import _FLOOR, WhittleFit, whittle_fit
    from avbench.noise_models import presets

    g = presets.get("ADIS16405_X")
    x = g.simulate(120_000, np.random.default_rng(100))
    wf = WhittleFit(x, g.dt, debiased=True)
    comps = ["Q", "N", "B", "K"]
    full = whittle_fit(wf, comps)
    _, top = wf.start(comps)
    lo = np.log(_FLOOR * top)
    lo[2] = -np.inf
    a0 = 10 * _FLOOR * top  # every other term starts near its floor, B near its lower profile bound
    a0[2] = (9.83e-5 / wf.scale) ** 2
    lin = wf.fit(comps, a0, None, lo, fixed=2, tol=1e-10)
    log = wf.fit(comps, a0, None, lo, fixed=2, tol=1e-10, hold_floor=False, max_iter=200)
    assert lin[4] and lin[3] < 60
    assert not log[4] and lin[2] > log[2]  # 200 log-scale steps: still short of the optimum


def test_ramp_variance_with_a_variance_below_zero():
    """A record whose signed maximum takes B (and Q) below 0 (20 min of the 50 Hz ADIS preset,
    replicate 121 of coverage_defaults): the slope's variance counts those terms as absent in the
    record's covariance, so the ramp's z-statistic and interval stay finite (they divided by 0)."""
    from avbench.studies.config import load_config
    from avbench.studies.runner import replicate_rng

    cfg = load_config(Path(__file__).resolve().parents[1] / "studies" / "coverage_defaults.toml")
    gs = next(g for g in cfg.gyros if g.label == "ADIS16405_X_50HZ")
    x = gs.gyro.simulate(gs.n_samples, replicate_rng(cfg.seed, cfg.gyros.index(gs), 121))
    e = estimators.get("whittle_debiased").fit(x, gs.gyro.dt)
    assert e.coefficients_["B"] == 0.0 and np.isfinite(e.diagnostics_["ramp_z2"])
    assert np.all(np.isfinite(e.conf_int().loc[list("QNBKR")].to_numpy()))


@pytest.mark.parametrize("n", [64, 65])
def test_sandwich_ratio_is_the_explicit_matrix_product(n):
    """WhittleFit.godambe_ratio (closed-form DFT covariances, FFT Toeplitz products) equals
    diag(H^-1 J H^-1) / diag(H^-1) with J built from the explicit covariance of the detrended DFT
    ordinates M x, M = F - G c^T, of a record whose covariance is the model's dense matrix."""
    from avbench.estimators.likelihood.whittle import WhittleFit, _autocovariance

    dt, m = 0.1, 10
    wf = WhittleFit(np.random.default_rng(0).standard_normal(n), dt, debiased=True)
    comps, a = ["Q", "N", "B", "K"], np.array([0.3, 1.0, 2.0, 0.5])
    idx = np.arange(n)
    lag = np.abs(np.subtract.outer(idx, idx))
    sigma = sum(a[j] * (dt * (np.minimum.outer(idx, idx) + 1.0) if c == "K" else _autocovariance(c, n, dt)[lag])
                for j, c in enumerate(comps))
    F = np.exp(-2j * np.pi * np.outer(np.arange(1, m + 1), idx) / n)
    M = F - np.outer(wf.G[:m], wf.trend_weights(comps, a))
    EY, PY = M @ sigma @ M.conj().T, M @ sigma @ M.T
    Bm = wf._matrix(comps, None)
    S = a @ Bm
    cov = (np.abs(EY) ** 2 + np.abs(PY) ** 2) / n**2 - np.diag(S[:m] ** 2)
    H = (Bm * (wf.w / S**2)) @ Bm.T
    b = Bm[:, :m] * (wf.w[:m] / S[:m] ** 2)
    Hi = np.linalg.inv(H)
    want = np.diag(Hi @ (H + b @ cov @ b.T) @ Hi) / np.diag(Hi)
    np.testing.assert_allclose(wf.godambe_ratio(comps, a, m=m), want, rtol=1e-9)


def test_white_noise_ordinates_are_independent():
    """A circulant covariance (white noise) leaves the DFT ordinates uncorrelated: A diagonal, P = 0."""
    from avbench.estimators.likelihood.whittle import _low_dft_covariance

    c = np.zeros(50)
    c[0] = 2.0
    A, P = _low_dft_covariance(c, 12)
    np.testing.assert_allclose(A, np.diag(np.full(12, 100.0)), atol=1e-12)
    np.testing.assert_allclose(P, 0.0, atol=1e-12)


def _whittle_world_record(gyro, n, rng):
    """A record of n samples whose DFT ordinates k = 1..n/2 are independent complex Gaussians with
    the model's expected periodogram (the Whittle likelihood's own world: its approximation exact)."""
    from avbench.estimators.likelihood.whittle import _expected_periodogram

    S = sum(gyro.coefficients[c] ** 2 * _expected_periodogram(c, n, gyro.dt) for c in "NBK"
            if np.isfinite(gyro.coefficients[c]))
    X = np.sqrt(n * S / 2) * (rng.standard_normal(S.size) + 1j * rng.standard_normal(S.size))
    if n % 2 == 0:
        X[-1] = math.sqrt(n * S[-1]) * rng.standard_normal()  # the Nyquist ordinate is real
    return np.fft.irfft(np.concatenate([[0.0], X]), n)


def _adis_like(dt=1.0):
    """ADIS16405_X's N, B, K (a B its 20 min record resolves to ~50 %, a K it barely sees) at a
    lower rate: the ratio of flicker and random walk to white noise at a frequency does not depend
    on dt, so the lowest ordinates, where B and K trade, are as on the preset at 100 Hz."""
    from avbench.noise_models import presets

    tr = presets.get("ADIS16405_X").coefficients
    return Gyro(dt=dt, terms=[AngleRandomWalk(N=tr["N"]), BiasInstability(B=tr["B"], tau_max=36_000.0),
                              RateRandomWalk(K=tr["K"])])


def _whittle_world_coverage_of_b(R, seed, interval_domain="union", n=1_200):
    g = _adis_like()
    hits = []
    for s in np.random.SeedSequence(seed).spawn(R):
        x = _whittle_world_record(g, n, np.random.default_rng(s))
        ci = estimators.get("whittle_debiased", terms="NBK", interval_domain=interval_domain).fit(x, g.dt).conf_int()
        hits.append(ci.loc["B", "lower"] <= g.coefficients["B"] <= ci.loc["B", "upper"])
    return np.array(hits)


def _check_b_coverage(hits):
    """B's misses are Binomial(R, 0.05) for a 95 % interval: fail past the 99.9 % point of that law
    (too narrow), and fail below its 0.1 % point (too wide to be the 95 % interval)."""
    R = hits.size
    misses = int(R - hits.sum())
    assert stats.binom.ppf(0.001, R, 0.05) <= misses <= stats.binom.ppf(0.999, R, 0.05), (misses, R)


def test_union_b_interval_holds_when_the_random_walk_is_barely_resolved_small():
    """The small version of the test below (60 records): a check that the path runs and is not
    grossly off; the slow one is the one that tells 0.92 from 0.95."""
    hits = _whittle_world_coverage_of_b(R=60, seed=235)
    assert hits.size - hits.sum() <= stats.binom.ppf(0.999, hits.size, 0.05)


@pytest.mark.slow
def test_union_b_interval_holds_when_the_random_walk_is_barely_resolved_slow():
    """ADIS16405_X's N, B, K, 20 min, in the Whittle likelihood's own world (independent
    exponential ordinates with the true expected periodogram), candidates N, B, K, with
    ``interval_domain="union"``: B's 95 % interval holds the truth at the binomial tolerance of 95 %
    in 1500 records. Intervals over the signed domain alone (the default ``"fit"``) fail it: 115
    misses of 1500 (coverage 0.923) against the limit 101 (seed 4242, measured issue 23's fifth
    session; the union: 60, 0.960). The random walk, estimated below -2 K^2 in ~40 % of such records, is the nuisance that inflates
    the signed domain's profile statistic (``_union_evidence``)."""
    _check_b_coverage(_whittle_world_coverage_of_b(R=1500, seed=236))


def test_union_interval_holds_both_domains_intervals():
    """``interval_domain="union"``: each term's interval is the union of the signed domain's
    (the default ``interval_domain="fit"``) and the non-negative domain's
    (``domain="nonnegative"``) profile intervals, its likelihood ratio the smaller of theirs; the
    estimates are the signed domain's."""
    g = _adis_like()
    x = _whittle_world_record(g, 1_200, np.random.default_rng(7))
    settings = {"union": dict(interval_domain="union"), "fit": dict(interval_domain="fit"),
                "nonneg": dict(domain="nonnegative")}
    fits = {k: estimators.get("whittle_debiased", terms="NBK", **s).fit(x, g.dt) for k, s in settings.items()}
    ev = {k: f.diagnostics_["evidence"] for k, f in fits.items()}
    for c in "NBK":
        pair = [ev[k].loc[c] for k in ("fit", "nonneg")]
        assert ev["union"].loc[c, "lower"] == pytest.approx(min(e["lower"] for e in pair), rel=1e-12)
        assert ev["union"].loc[c, "upper"] == pytest.approx(max(e["upper"] for e in pair), rel=1e-12)
        assert ev["union"].loc[c, "lr"] == pytest.approx(min(e["lr"] for e in pair), rel=1e-12, abs=1e-300)
    assert fits["union"].coefficients_.equals(fits["fit"].coefficients_)


def test_redrawn_periodogram_is_exponential_with_the_model_mean():
    """``WhittleFit.redrawn``: periodogram ordinates |X_k|^2 / n independent exponentials with mean the
    model's expected periodogram: the normalised ordinates have mean 1 and variance 1 (exponential),
    within 4 standard errors of their sample means over 10 000 ordinates."""
    from avbench.estimators.likelihood.whittle import WhittleFit, whittle_fit

    n = 20_002
    g = _gyro(n)
    wf = WhittleFit(g.simulate(n, np.random.default_rng(2)), DT, debiased=True)
    full = whittle_fit(wf, ["N", "B", "K"], 1, signed=True)
    ws = wf.redrawn(full["comps"], full["a"], None, np.random.default_rng(3))
    S = full["a"] @ wf._matrix(full["comps"], None)
    r = (ws.X2 / n / S)[:-1]  # the Nyquist ordinate is chi^2_1 / 2, not exponential
    se_mean = 1 / math.sqrt(r.size)
    assert abs(r.mean() - 1) < 4 * se_mean
    assert abs(r.var() - 1) < 4 * math.sqrt(8 / r.size)  # Var((r - 1)^2) = E(r - 1)^4 - 1 = 9 - 1
    assert ws.X2 is not wf.X2 and ws.scale == wf.scale and ws._basis is wf._basis


def test_bootstrap_bartlett_factor_is_one_for_a_regular_model():
    """White noise alone (one variance, far from its boundary, 2 000 ordinates): the likelihood-ratio
    statistic is chi^2_1 to O(1/n), so the bootstrap's critical value is chi^2_1(0.95) times a mean of
    ``n_boot`` chi^2_1 draws: within 4 of that mean's standard errors (sqrt(2 / n_boot))."""
    from avbench.estimators.likelihood.whittle import WhittleFit, bootstrap_critical_values, whittle_fit

    n_boot = 200
    wf = WhittleFit(np.random.default_rng(4).standard_normal(4_000), 1.0, debiased=True)
    full = whittle_fit(wf, ["N"], 1, signed=True)
    crit = bootstrap_critical_values(wf, full, 0.95, n_boot)
    q = stats.chi2.ppf(0.95, 1)
    assert abs(crit["N"] / q - 1) < 4 * math.sqrt(2 / n_boot)


def test_calibrated_bounds_are_where_the_likelihood_ratio_reaches_the_bootstrap_value():
    """``calibration="bartlett"``: each non-zero bound is where the profile likelihood ratio reaches that
    term's bootstrap critical value (not chi^2_1(0.95)), to the root's tolerance; estimates and
    evidence are those of the default (chi^2_1) calibration."""
    from avbench.estimators.likelihood.whittle import (WhittleFit, bootstrap_critical_values, profile_evidence,
                                                       whittle_fit)

    n = 6_000
    x = _gyro(n).simulate(n, np.random.default_rng(5))
    wf = WhittleFit(x, DT, debiased=True)
    full = whittle_fit(wf, ["N", "B", "K"], 1, signed=True)
    crit = bootstrap_critical_values(wf, full, 0.95, 20)
    assert set(crit) == {c for i, c in enumerate(full["comps"]) if full["a"][i] > 0}
    ev, best = profile_evidence(wf, full, crit=crit)
    ev0, _ = profile_evidence(wf, full)
    for i, c in enumerate(full["comps"]):
        assert ev[c]["lr"] == ev0[c]["lr"]
        q = crit.get(c, stats.chi2.ppf(0.95, 1))
        for bound in ("upper", "lower"):
            if ev[c][bound] == 0.0:
                continue
            a = full["a"].copy()
            a[i] = ev[c][bound]
            r = wf.fit(full["comps"], a, None, np.full(3, -np.inf), fixed=i, tol=1e-10, signed=True)
            assert abs(math.sqrt(max(2 * (best - r[2]), 0.0)) - math.sqrt(q)) < 0.03, (c, bound)
    a = estimators.get("whittle_debiased", terms="NBK").fit(x, DT)
    b = estimators.get("whittle_debiased", terms="NBK", calibration="bartlett", n_boot=20).fit(x, DT)
    assert a.coefficients_.equals(b.coefficients_)


def test_negative_neighbours_are_the_adjacent_terms_of_a_variance_below_its_noise():
    """``_negative_neighbours``: a term switches to the non-negative domain's interval exactly when an
    adjacent term (order Q N B K of the fit) has a variance below -1.96 of its Wald standard errors."""
    from avbench.estimators.likelihood.whittle import NEGATIVE_Z, _negative_neighbours

    comps = ["Q", "N", "B", "K"]
    info = np.diag([1.0, 4.0, 1.0, 0.25])  # Wald std 1, 0.5, 1, 2
    for aK, expected in [(-2 * NEGATIVE_Z * 1.01, {"B"}), (-2 * NEGATIVE_Z * 0.99, set()), (1.0, set())]:
        full = dict(comps=comps, a=np.array([0.5, 1.0, 1.0, aK]), detail={"info": info})
        assert _negative_neighbours(full) == expected
    full = dict(comps=comps, a=np.array([-1.0 * NEGATIVE_Z * 1.01, 1.0, -1.01 * NEGATIVE_Z, 1.0]),
                detail={"info": info})
    assert _negative_neighbours(full) == {"N", "K"}  # Q's neighbour N; B's neighbours N and K
    # interval_domain="switch_steeper": only the next term in Q N B K (the steeper spectrum) counts: N
    # switches beside the negative B, K (B is its shallower neighbour) does not, nor does anything beside Q
    assert _negative_neighbours(full, sides="steeper") == {"N"}
    for aK, expected in [(-2 * NEGATIVE_Z * 1.01, {"B"}), (1.0, set())]:
        full = dict(comps=comps, a=np.array([-NEGATIVE_Z * 1.01, 1.0, 1.0, aK]), detail={"info": info})
        assert _negative_neighbours(full, sides="steeper") == expected  # Q below 0 switches nothing


def _whittle_world_coverage(R, seed, interval_domain, drop_k=False, n=1_200):
    """B's 95 % intervals on ADIS16405_X's N, B, K (or without K) at 1 Hz, 20 min, in the Whittle world,
    candidates N, B, K."""
    g = _adis_like()
    if drop_k:
        g = Gyro(dt=g.dt, terms=[t for t in g.terms if not isinstance(t, RateRandomWalk)])
    hits = []
    for s in np.random.SeedSequence(seed).spawn(R):
        x = _whittle_world_record(g, n, np.random.default_rng(s))
        ci = estimators.get("whittle_debiased", terms="NBK", interval_domain=interval_domain).fit(x, g.dt).conf_int()
        hits.append(ci.loc["B", "lower"] <= g.coefficients["B"] <= ci.loc["B", "upper"])
    return np.array(hits)


def test_switch_b_interval_small():
    """The small version of the slow test below (40 records each, K present and absent): the path runs
    and is not grossly off."""
    for drop_k in (False, True):
        hits = _whittle_world_coverage(40, 237 + drop_k, "switch", drop_k)
        assert hits.size - hits.sum() <= stats.binom.ppf(0.999, hits.size, 0.05)


@pytest.mark.slow
@pytest.mark.parametrize("drop_k", [False, True])
def test_switch_b_interval_holds_beside_a_random_walk_present_or_absent_slow(drop_k):
    """``interval_domain="switch"`` on ADIS16405_X's N, B with K (barely resolved) and without K, in the
    Whittle world (the likelihood's approximation exact), candidates N, B, K: B's 95 % interval holds
    the truth at the binomial tolerance of 95 % in 1000 records each. Measured with the signed domain
    alone (issue 23, sixth session; cand3 script, seeds 9913/9914): 0.916 (K present) and 0.928 (K
    absent, 628 records) -- the inflation is there beside an absent random walk too, and sits in the
    records whose K^2 the signed fit puts below -2 Wald std (B covers 0.83 / 0.88 there); switched:
    0.951, 0.959."""
    _check_b_coverage(_whittle_world_coverage(1000, 238 + drop_k, "switch", drop_k))


def test_switch_steeper_acts_through_the_steeper_neighbour_only():
    """``interval_domain="switch_steeper"`` on ADIS16405_X's N, B, K (Whittle world, candidates Q N B K,
    so the absent Q goes below 0 in about half the records): B's interval is ``"switch"``'s (its
    steeper neighbour K is the one that goes below 0), N's is the signed domain's (``"fit"``: its
    steeper neighbour B never does) wherever ``"switch"`` moved it beside Q; estimates unchanged."""
    g = _adis_like()
    moved_n = 0
    for i, s in enumerate(np.random.SeedSequence(239).spawn(60)):  # Q below 0 beyond its noise in ~5 %
        if moved_n and i >= 12:
            break
        x = _whittle_world_record(g, 1_200, np.random.default_rng(s))
        ci = {d: estimators.get("whittle_debiased", terms="QNBK", interval_domain=d).fit(x, g.dt)
              for d in ("fit", "switch", "switch_steeper")}
        assert ci["switch_steeper"].coefficients_.equals(ci["fit"].coefficients_)
        c = {d: f.conf_int() for d, f in ci.items()}
        assert c["switch_steeper"].loc["B"].equals(c["switch"].loc["B"])
        assert c["switch_steeper"].loc["N"].equals(c["fit"].loc["N"])
        moved_n += not c["switch"].loc["N"].equals(c["fit"].loc["N"])
    assert moved_n > 0  # the records do exercise the difference between the two switches
