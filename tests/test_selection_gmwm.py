"""GMWM's model-choice components (avbench.estimators.selection: scales, lines, resonance, bias_model, bounds)
and the fitting interface of the noise terms they and GMWM loop over (NoiseTerm.fit_parameters, fit_bounds,
fit_starts; noise_models.latents), each on its own: known records, hand-computed limits, stub fits."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from scipy.stats import chi2

from avbench.estimators.allan.variance import allan_variance
from avbench.estimators.base import IdentifiabilityWarning
from avbench.estimators.likelihood.gmwm import GMWM
from avbench.estimators.selection import bias_model, bounds, lines, resonance, scales
from avbench.noise_models import AngleRandomWalk, FilteredWhiteNoise, GaussMarkov, Gyro, RateRandomWalk, Resonance
from avbench.noise_models.latents import LATENT_TERMS, LATENTS, build_gyro, param_index, parse_model, white_latent
from avbench.noise_models.term_base import PLATEAU, FitHint

DT = 0.01
M = 2 ** np.arange(10)  # ten octaves
ALL = np.ones(M.size, bool)


def _stub(J_by_m0):
    """A fit_on whose fit of the scales ``m >= m0`` has Hansen's J ``J_by_m0[m0]`` (8.0 where not given)."""
    calls = []

    def fit_on(keep):
        m0 = int(M[keep][0])
        calls.append(m0)
        return {"J_stat": J_by_m0.get(m0, 8.0), "m0": m0}

    return fit_on, calls


# -- scales ----------------------------------------------------------------------------------------------------

def test_cutoffs_leave_enough_scales_for_the_parameters():
    assert scales.cutoffs("auto", M, ALL, 3) == [1, 2, 4, 8, 16, 32, 64]  # each leaves >= 4 scales
    assert scales.cutoffs("adequate", M, M >= 4, 3) == [1, 2, 4, 8, 16, 32, 64]
    assert scales.cutoffs(4, M, ALL, 3) == [4]


def test_auto_drops_a_bent_first_octave_and_stops_where_the_next_agrees():
    # the first octave bent (J falls by 391 when it is dropped, above chi2_1's 0.999 point 10.83), the second not
    fit_on, calls = _stub({1: 400.0, 2: 9.0, 4: 8.5})
    c = scales.choose_scales(fit_on, scales.cutoffs("auto", M, ALL, 3), M, ALL, 3, "auto")
    assert c.fit["m0"] == 2 and c.fit["k"] == 9
    assert [t[0] for t in c.tried] == [1, 2, 4] and calls == [1, 2, 4]
    assert c.tried[1] == (2, 9.0, 9)
    # a drop of J just below the test's critical value keeps the shorter scale
    crit = chi2.ppf(1 - scales.SCALE_TEST_LEVEL, 1)
    fit_on, _ = _stub({1: 9.0 + 0.99 * crit, 2: 9.0})
    assert scales.choose_scales(fit_on, [1, 2, 4], M, ALL, 3, "auto").fit["m0"] == 1
    fit_on, _ = _stub({1: 9.0 + 1.01 * crit, 2: 9.0})
    assert scales.choose_scales(fit_on, [1, 2, 4], M, ALL, 3, "auto").fit["m0"] == 2


def test_adequate_takes_the_shortest_cut_off_hansens_j_accepts():
    # dropping one scale at a time changes J too little for the difference test (auto keeps m0 = 1), but the
    # fits from m0 = 4 on are adequate by their own J (chi2 with k - 3 dof)
    J = {1: 60.0, 2: 52.0, 4: 6.0}
    fit_on, _ = _stub(J)
    auto = scales.choose_scales(fit_on, [1, 2, 4, 8], M, ALL, 3, "auto")
    assert auto.fit["m0"] == 1
    fit_on, _ = _stub(J)
    adequate = scales.choose_scales(fit_on, [1, 2, 4, 8], M, ALL, 3, "adequate")
    assert adequate.fit["m0"] == 4 and "Hansen" in adequate.reason
    assert scales.adequate(6.0, 8, 3) and not scales.adequate(52.0, 9, 3)


def test_adequate_keeps_the_longer_half_of_the_scales():
    # nothing adequate before the cut-off that keeps fewer than half the scales (m0 = 64: 4 of 10): the "auto"
    # choice; half of them (m0 = 32: 5 of 10) is enough
    J = {m0: 100.0 for m0 in (1, 2, 4, 8, 16, 32)} | {64: 1.0}
    fit_on, calls = _stub(J)
    c = scales.choose_scales(fit_on, [1, 2, 4, 8, 16, 32, 64], M, ALL, 3, "adequate")
    assert c.fit["m0"] == 1 and calls[-1] == 64 and "as 'auto'" in c.reason
    fit_on, calls = _stub(J | {32: 1.0})
    assert scales.choose_scales(fit_on, [1, 2, 4, 8, 16, 32, 64], M, ALL, 3, "adequate").fit["m0"] == 32


def test_a_fixed_cut_off_is_fitted_once():
    fit_on, calls = _stub({})
    c = scales.choose_scales(fit_on, scales.cutoffs(8, M, ALL, 3), M, ALL, 3, 8)
    assert calls == [8] and c.fit["k"] == 7 and "fixed" in c.reason


def test_shorter_adequate_looks_below_and_asks_accept():
    fit_on, calls = _stub({1: 100.0, 2: 5.0, 4: 5.0})
    seen = []
    c = scales.shorter_adequate(fit_on, [1, 2, 4, 8], M, ALL, 3, below=8, max_tau=np.inf, dt=DT,
                                accept=lambda fit: seen.append(fit["m0"]) or fit["m0"] >= 4)
    assert c.fit["m0"] == 4 and seen == [2, 4] and calls == [1, 2, 4]
    fit_on, calls = _stub({})
    c = scales.shorter_adequate(fit_on, [1, 2, 4, 8], M, ALL, 3, below=8, max_tau=1.5 * DT, dt=DT)
    assert c.fit["m0"] == 1 and calls == [1]
    fit_on, calls = _stub({})
    none = scales.shorter_adequate(fit_on, [1, 2, 4, 8], M, ALL, 3, below=1, max_tau=np.inf, dt=DT)
    assert none.fit is None and none.tried == [] and calls == []


def _gmwm_scale_choice(x, model, rule):
    """The scale rule over GMWM's own fits of ``model`` on the record ``x``."""
    est = GMWM(model=model)
    latents = parse_model(model)
    wv = est._wavelet_variance(x, DT)
    usable = (x.size // wv.m >= est.min_clusters) & (wv.avar > 0)

    def fit_on(keep):
        return est._fit_scales(latents, wv.tau[keep], wv.avar[keep], wv.m[keep], wv.edf[keep], x.size, DT, 1.0)

    n_free = est._n_free(latents)
    return scales.choose_scales(fit_on, scales.cutoffs(rule, wv.m, usable, n_free), wv.m, usable, n_free, rule)


def test_auto_on_a_record_with_a_flat_first_octave():
    """White noise through a 2-sample average: AV(m=1) lies at half the white line (a flat first octave),
    AV(m) = N^2/tau (1 - 3/(4m)) beyond. A white-noise model drops the first octave(s); on the white record
    itself it keeps every scale (trying only m=2)."""
    e = np.random.default_rng(5).standard_normal(2**17)
    flat = np.convolve(e, [0.5, 0.5], mode="valid")
    av = allan_variance(flat, DT, taus="octave", overlapping=True)
    assert av.avar[0] < 0.55 * av.avar[1] * 2  # the first octave below the white line through the second
    c = _gmwm_scale_choice(flat, "WN", "auto")
    assert int(c.fit["diag"]["m"][0]) >= 2
    assert c.tried[0][1] > 100 * c.fit["J_stat"]
    white = _gmwm_scale_choice(e, "WN", "auto")
    assert int(white.fit["diag"]["m"][0]) == 1 and [t[0] for t in white.tried] == [1, 2]


def test_white_reach_is_the_end_of_the_first_white_stretch():
    """The longest cut-off that keeps the white noise in the fit: the last octave of the first stretch of at
    least two octaves whose AV slope lies within 1/4 of -1; a lone white octave (a resonance's flank) is
    passed over; none on a curve without white noise."""
    tau = DT * M
    white = 1e-4 / tau
    # a filter (AV below the white line at the first two octaves), four white octaves, then a flat plateau
    curve = np.r_[0.4 * white[:1], 0.8 * white[1:2], white[2:6], np.full(4, 3 * white[5])]
    assert scales.white_reach(tau, curve, 10**7, M, ALL) == 16
    assert scales.white_reach(tau, curve, 10**7, M, M <= 8) == 8  # only usable octaves count
    # a hump at the second octave (one falling octave), then a long white stretch
    hump = np.r_[white[0], 3 * white[1], white[2:]]
    assert scales.white_reach(tau, hump, 10**7, M, ALL) == 512
    assert scales.white_reach(tau, np.full(10, 1e-3), 10**7, M, ALL) is None  # flat: no white noise
    # octaves with fewer than 16 clusters do not count
    assert scales.white_reach(tau, white, 64 * 16, M, ALL) == 64
    assert scales.cutoffs("adequate", M, ALL, 3, reach=8) == [1, 2, 4, 8]
    assert scales.cutoffs(32, M, ALL, 3, reach=8) == [32]  # a fixed cut-off is the user's


def test_adequate_within_the_white_reach_takes_the_least_rejected_fit():
    """Cut off at the white reach with no adequate cut-off: the fit with the largest p-value of Hansen's J, not the
    sequential test's choice (which stops where J did not fall, here at m0 = 1, the worst fit); without the reach
    the rule is as before."""
    fit_on, _ = _stub({1: 1658.0, 2: 1684.0, 4: 408.0, 8: 42.5})
    c = scales.choose_scales(fit_on, [1, 2, 4, 8], M, ALL, 3, "adequate", reached=True)
    assert c.fit["m0"] == 8 and "rejects least" in c.reason
    fit_on, _ = _stub({1: 1658.0, 2: 1684.0, 4: 408.0, 8: 42.5})
    assert scales.choose_scales(fit_on, [1, 2, 4, 8], M, ALL, 3, "adequate").fit["m0"] == 1
    fit_on, _ = _stub({1: 1658.0, 2: 5.0})  # an adequate cut-off within the reach is taken as always
    c = scales.choose_scales(fit_on, [1, 2, 4, 8], M, ALL, 3, "adequate", reached=True)
    assert c.fit["m0"] == 2 and c.reason.startswith("the shortest cut-off")


# -- lines -----------------------------------------------------------------------------------------------------

def test_line_test_finds_a_sinusoid_of_known_frequency():
    n, f0, amp = 2**17, 7.3, 0.1
    t = np.arange(n) * DT
    x = np.random.default_rng(11).standard_normal(n) + amp * np.sin(2 * np.pi * f0 * t + 0.4)
    found = lines.strongest_line(x, DT)
    assert abs(found.f0 - f0) <= 1.0 / (n * DT) and found.p_value < 1e-6
    assert found.amplitude == pytest.approx(amp, rel=0.1)
    choice = lines.choose_line(("WN",), x, DT, DT * M, auto=True)
    assert choice.latents == ("WN", "SN") and choice.line["significant"] and choice.line["included"]
    kept = lines.choose_line(("WN",), x, DT, DT * M, auto=False)
    assert kept.latents == ("WN",) and not kept.line["included"]
    hint = lines.sinusoid_hint(choice.line)
    assert hint.window == (choice.line["f0"] / 1.05, choice.line["f0"] * 1.05)
    assert hint.starts == ((choice.line["amplitude"], choice.line["f0"]),)
    assert lines.frequency_at_bound(choice.line["f0"] * 1.05, choice.line)
    assert not lines.frequency_at_bound(choice.line["f0"] * 1.04, choice.line)


def test_line_test_finds_none_in_white_noise():
    p = [lines.strongest_line(np.random.default_rng(100 + i).standard_normal(2**15), DT).p_value for i in range(20)]
    assert sum(v < lines.LINE_TEST_LEVEL for v in p) == 0 and np.median(p) > 0.1
    choice = lines.choose_line(("WN",), np.random.default_rng(3).standard_normal(2**15), DT, DT * M, auto=True)
    assert choice.latents == ("WN",) and not choice.line["significant"]
    assert lines.sinusoid_hint(choice.line) is None
    assert lines.choose_line(("WN",), np.zeros(100), DT, DT * M, auto=True).line is None  # too short to search


def test_line_test_background_spans_the_same_band_on_short_records():
    """A block of the background spans BLOCK_HZ (32 bins of 10,000 s, fewer on shorter records, at least 2), so a
    0.5 Hz line is searched and found on 10- and 30-minute records as on hours (with fewer bins in its background
    the evidence is weaker: on 10 minutes a prominence of ~150 gives p ~ 3e-3, so the line here is one of 400
    times the background); on white noise of those lengths nothing passes the level."""
    assert lines.block_bins(1_000_000, DT) == 32 and lines.block_bins(2_000_000, DT) == 32
    assert lines.block_bins(180_000, DT) == 5 and lines.block_bins(60_000, DT) == 2 and lines.block_bins(1000, DT) == 2
    for n in (60_000, 180_000):
        t = np.arange(n) * DT
        x = np.random.default_rng(n).standard_normal(n) + 0.2 * np.sin(2 * np.pi * 0.5 * t + 0.3)
        found = lines.strongest_line(x, DT)
        assert found.band[0] < 0.3 and abs(found.f0 - 0.5) <= 2.0 / (n * DT) and found.p_value < 1e-6
        p = [lines.strongest_line(np.random.default_rng(n + i).standard_normal(n), DT).p_value for i in range(10)]
        assert min(p) >= lines.LINE_TEST_LEVEL


# -- resonance -------------------------------------------------------------------------------------------------

def _resonant(n, seed):
    g = Gyro(dt=DT, terms=[AngleRandomWalk(N=1e-3), Resonance(sigma=5e-3, f0=20.0, tc=0.3)])
    return g.simulate(n, np.random.default_rng(seed))


def test_band_test_finds_a_resonance_and_not_white_noise():
    band = resonance.band_seen(_resonant(2**17, 4), DT, DT * M)
    assert band.f0 == pytest.approx(20.0, rel=0.05) and band.prominence > 5 and band.p_value < 1e-6
    assert all(s[1] == band.f0 for s in band.starts) and band.starts[1][2] == pytest.approx(10 * band.starts[0][2])
    white = resonance.band_seen(np.random.default_rng(4).standard_normal(2**17) * 1e-2, DT, DT * M)
    assert not (white.prominence >= resonance.RESONANCE_MIN_PROMINENCE
                and white.p_value < resonance.RESONANCE_TEST_LEVEL)
    # a line the model holds is excluded from the search, with its neighbourhood
    held = {"included": True, "significant": True, "f0": 20.0}
    away = resonance.band_seen(_resonant(2**17, 4), DT, DT * M, held)
    assert not 20.0 / 1.5 <= away.f0 <= 20.0 * 1.5
    hint = resonance.resonance_hint(band)
    assert hint.window == (band.f0 / 1.5, band.f0 * 1.5) and resonance.resonance_hint(None) is None


def _best(m0, J=50.0):
    return {"J_stat": J, "diag": {"m": np.array([m0]), "values": np.array([1.0, 2.0])}}


def test_resonance_choice_says_why_it_adds_nothing():
    def refit(*a, **k):  # never reached in these cases
        raise AssertionError("refit called")

    keeps_all = resonance.choose_resonance(("WN",), _best(1), [(1, 50.0, 10)], M, ALL, lambda: None, refit)
    assert not keeps_all.report["included"] and "every scale" in keeps_all.report["reason"]
    dull = resonance.ResonanceBand(20.0, 1.0, 1.5, 0.5, [(1.0, 20.0, 0.1)])
    no_band = resonance.choose_resonance(("WN",), _best(4), [], M, ALL, lambda: dull, refit)
    assert not no_band.report["included"] and no_band.latents == ("WN",) and no_band.report["prominence"] == 1.5


def test_resonance_choice_adds_rs_where_the_refit_keeps_shorter_scales():
    band = resonance.ResonanceBand(20.0, 1.0, 10.0, 1e-9, [(1.0, 20.0, 0.1)])
    asked = {}

    def refit(latents, found, below, accept, max_tau, seed):
        import pandas as pd

        asked.update(latents=latents, below=below, max_tau=max_tau)
        fit = {"J_stat": 7.0, "coefs": {"N": 1e-3},
               "diag": {"m": np.array([1]), "tau": np.array([DT]), "std_err": pd.Series({"N": 1e-4}),
                        "params": {"RS.sigma": 1.0, "RS.f0": 20.0, "RS.tc": 0.1}}}
        assert accept(fit)  # seen: 0.01 s x 20 Hz <= 0.75; N resolved; no fit check
        traded = {**fit, "diag": {**fit["diag"], "std_err": pd.Series({"N": 6e-4})}}
        assert not accept(traded)  # N's 95 % interval reaches zero: the resonance trades with the white noise
        return scales.ScaleChoice(fit, [(1, 7.0, 10)], "stub")

    c = resonance.choose_resonance(("WN", "GM"), _best(4), [(1, 80.0, 10), (2, 60.0, 9), (4, 50.0, 8)], M, ALL,
                                   lambda: band, refit)
    assert c.latents == ("WN", "GM", "RS") and c.report["included"] and c.report["min_m_with"] == 1
    assert asked == {"latents": ("WN", "GM", "RS"), "below": 4, "max_tau": 0.75 * 1.5 / 20.0}
    assert c.report["J_without_same_scales"] == 80.0 and c.report["p_value"] == pytest.approx(chi2.sf(73.0, 3))


# -- bias model ------------------------------------------------------------------------------------------------

def _fit(J, B):
    import pandas as pd

    return {"J_stat": J, "coefs": {"N": 1.0, "B": B}, "diag": {"std_err": pd.Series({"N": 0.1, "B": 0.2})}}


def test_bias_models_weighed_by_hand_computed_akaike_weights():
    assert bias_model.exchanged(("WN", "GM", "RW")) == ("WN", "FL", "RW")
    assert bias_model.exchanged(("FW", "FL", "SN")) == ("FW", "GM", "SN")
    n_free = {("WN", "GM", "RW"): 4, ("WN", "FL", "RW"): 3}.__getitem__
    # AIC: GM 4 + 8 = 12, FL 12 + 6 = 18: the GM weight 1 / (1 + e^-3) = 0.9526 >= 0.95, decisive
    ev = bias_model.weigh_bias_models(("WN", "GM", "RW"), _fit(4.0, 2.0), ("WN", "FL", "RW"), _fit(12.0, 3.0),
                                      n_free, 2)
    assert ev.preferred == "GM" and ev.decisive and ev.weight == pytest.approx(1 / (1 + math.exp(-3)))
    assert ev.report["FL"]["aic"] == 18.0 and ev.report["fitted"] == "GM" and ev.report["min_m"] == 2
    assert bias_model.held_alternative(ev.report) is None
    # FL J 11: AIC 17, the GM weight 1 / (1 + e^-2.5) = 0.924: not decisive, the FL fit is the alternative
    ev = bias_model.weigh_bias_models(("WN", "GM", "RW"), _fit(4.0, 2.0), ("WN", "FL", "RW"), _fit(11.0, 3.0),
                                      n_free, 2)
    assert not ev.decisive and ev.weight == pytest.approx(1 / (1 + math.exp(-2.5)))
    alt = bias_model.held_alternative(ev.report)
    assert alt["B"] == 3.0 and alt["coefficients"] == {"N": 1.0, "B": 3.0} and alt["std_err"]["B"] == 0.2
    # FL J 0: AIC 6 against GM's 12, the FL weight 1 / (1 + e^-3) >= 0.95: decisive for the model not fitted,
    # whose fit the intervals then hold too
    ev = bias_model.weigh_bias_models(("WN", "GM", "RW"), _fit(4.0, 2.0), ("WN", "FL", "RW"), _fit(0.0, 3.0),
                                      n_free, 2)
    assert ev.decisive and ev.preferred == "FL" and ev.report["fitted"] == "GM"
    assert bias_model.held_alternative(ev.report)["B"] == 3.0
    assert bias_model.held_alternative(None) is None


# -- bounds ----------------------------------------------------------------------------------------------------

TAU = DT * M[:6]
AVAR = np.array([4e-6, 2e-6, 1.1e-6, 7e-7, 6e-7, 8e-7])
EDF = np.array([900.0, 400.0, 200.0, 90.0, 40.0, 0.0])


def test_av_upper_limits_are_the_chi2_limits():
    usable = np.array([True, True, True, True, True, True])
    tau, up = bounds.av_upper_limits(TAU, AVAR, EDF, usable)
    assert np.array_equal(tau, TAU[:5])  # no edf at the last: left out
    hand = [AVAR[i] * EDF[i] / chi2.ppf(0.025, EDF[i]) for i in range(5)]
    np.testing.assert_allclose(up, hand, rtol=1e-14)
    assert up[0] == pytest.approx(4e-6 * 900 / 818.7, rel=1e-4)  # chi2_900's 2.5 % point ~ 818.7


def test_a_term_at_zero_gets_the_data_bound():
    tau, up = bounds.av_upper_limits(TAU, AVAR, EDF, np.ones(6, bool))
    # K: the rate random walk's exact AV at K = 1 is (2 m^2 + 1) dt / (6 m)
    m = tau / DT
    hand = math.sqrt(np.min(up / ((2 * m * m + 1) * DT / (6 * m))))
    assert bounds.data_upper("RW", tau, up, DT, 100.0) == pytest.approx(hand, rel=1e-12)
    out = bounds.terms_at_zero(("WN", "GM", "RW"), {"N": 1e-3, "B": 1e-4, "K": 0.0}, tau, up, DT, 100.0)
    assert out == {"K": (0.0, pytest.approx(hand, rel=1e-12))}
    assert bounds.terms_at_zero(("WN", "RW"), {"N": 1e-3, "K": 0.0}, tau, up, DT, 100.0, known={"K": (0, 1)}) == {}
    assert bounds.terms_at_zero(("WN", "RW"), {"N": 1e-3, "K": 2e-6}, tau, up, DT, 100.0) == {}
    assert bounds.terms_at_zero(("WN", "RW"), {"K": 0.0}, tau[:0], up[:0], DT, 100.0) == {}


def test_a_gauss_markov_term_at_the_first_octaves_leaves_b_unresolved():
    tau, up = bounds.av_upper_limits(TAU, AVAR, EDF, np.ones(6, bool))
    latents = ("WN", "GM", "RW")
    fast = np.array([1e-3, 5e-4, 0.02, 1e-6])  # N, sigma, Tc = 0.02 s: peak 0.038 s < 8 x 0.01 s
    with pytest.warns(IdentifiabilityWarning, match="B not resolved"):
        out = bounds.gm_unresolved(latents, fast, DT, tau, up, DT, 100.0)
    assert list(out) == ["B", "K"]
    assert out["B"] == (0.0, pytest.approx(math.sqrt(np.min(up) / PLATEAU), rel=1e-14))
    assert out["K"][1] == pytest.approx(bounds.data_upper("RW", tau, up, DT, 100.0))
    slow = np.array([1e-3, 5e-4, 2.0, 1e-6])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert bounds.gm_unresolved(latents, slow, DT, tau, up, DT, 100.0) is None


# -- the terms' fitting interface ------------------------------------------------------------------------------

def test_the_latent_catalogue_is_read_from_the_terms():
    assert list(LATENT_TERMS) == ["QN", "WN", "FW", "GM", "FL", "RW", "DR", "SN", "RS"]
    for code, cls in LATENT_TERMS.items():
        assert cls.latent == code and LATENTS[code] == (cls.fit_parameters, cls.coefficient)
        assert len(cls.fit_parameters) == 1 + len(cls.shape_parameters()), code
    assert parse_model("rw+GM + wn") == ("WN", "GM", "RW")
    for bad in ("WN+GM+FL", "WN+FW", "WN+WN", "WN+XX", "", 5):
        with pytest.raises(ValueError, match="model: expected latent names"):
            parse_model(bad)
    assert param_index(("WN", "GM", "RW"), "RW") == 3 and white_latent(("FW", "GM")) == "FW"
    g = build_gyro(("FW", "GM", "SN", "RS"), [1e-3, 0.02, 2e-4, 5.0, 1e-3, 3.0, 4e-3, 20.0, 0.3], DT)
    fw, gm, sn, rs = g.terms
    assert (fw.N, fw.tf, gm.sigma, gm.tc) == (1e-3, 0.02, 2e-4, 5.0)
    assert (sn.A, sn.f0, rs.sigma, rs.f0, rs.tc) == (1e-3, 3.0, 4e-3, 20.0, 0.3)
    fl = build_gyro(("QN", "FL", "DR"), [1e-5, 1e-4, 1e-8], DT, flicker_tau_max=100.0).terms
    assert [type(t).__name__ for t in fl] == ["Quantization", "BiasInstability", "RateRamp"]
    assert (fl[1].B, fl[1].tau_max) == (1e-4, 100.0)


def test_each_terms_starts_lie_in_its_box():
    g = Gyro(dt=DT, terms=[FilteredWhiteNoise(N=1e-3, tf=0.02), GaussMarkov(sigma=2e-4, tc=5.0),
                           RateRandomWalk(K=2e-6)])
    tau = DT * 2.0 ** np.arange(12)
    avar = g.avar(tau)
    T = 2**15 * DT
    for code, cls in LATENT_TERMS.items():
        hint = FitHint(window=(2.0, 3.0), starts=((1e-3, 2.5),) if code == "SN" else ((1e-3, 2.5, 0.1),))
        lo, hi = cls.fit_bounds(tau, avar, DT, T, hint)
        assert len(lo) == len(hi) == len(cls.fit_parameters) and all(a < b for a, b in zip(lo, hi)), code
        starts = cls.fit_starts(tau, avar, np.array(lo), np.array(hi), n_starts=4, hint=hint)
        assert starts and all(len(s) == len(lo) for s in starts), code
        if code != "GM":  # GM's starts are read off the curve unclipped
            for s in starts:
                assert all(a <= math.log(v) <= b for a, v, b in zip(lo, s, hi)), (code, s)
    # the documented boxes: GM's Tc from the shortest tau (>= dt) to 10 T; a line's window holds SN's f0
    lo, hi = LATENT_TERMS["GM"].fit_bounds(tau, avar, DT, T)
    assert (lo[1], hi[1]) == (math.log(DT), math.log(10 * T)) and len(LATENT_TERMS["GM"].fit_starts(
        tau, avar, np.array(lo), np.array(hi), n_starts=4)) == 4
    lo, hi = LATENT_TERMS["SN"].fit_bounds(tau, avar, DT, T, FitHint(window=(2.0, 3.0)))
    assert (lo[1], hi[1]) == (math.log(2.0), math.log(3.0))
    assert LATENT_TERMS["RS"].fit_starts(tau, avar, np.array(lo + [0.0]), np.array(hi + [1.0])) == []


# -- choices shared between the methods of one axis -------------------------------------------------------------

def _fits_equal(a, b):
    """Two fitted estimators report the same numbers, bit for bit (coefficients, standard errors, J, the
    scale choice, the fit check)."""
    assert a.coefficients_.equals(b.coefficients_)
    assert a.diagnostics_["std_err"].equals(b.diagnostics_["std_err"])
    for k in ("J_stat", "min_m", "scale_choice", "fit_pvalue", "params", "outlier_fraction"):
        assert a.diagnostics_.get(k) == b.diagnostics_.get(k), k


def test_a_second_method_takes_the_first_ones_choices_only_on_the_same_values():
    """gmwm_despiked on a record where it finds no spike matches the classical AV, the values gmwm_filtered
    matches: within one axis's scope it takes gmwm_filtered's outcome (computed once, shared once) and reports
    exactly what it reports fitted on its own; with a spike it matches other values and fits them itself; a
    setting that shapes the choices, or no scope, shares nothing."""
    from avbench import estimators
    from avbench.estimators.selection.shared import AxisChoices, shared_choices

    g = Gyro(DT, [FilteredWhiteNoise(N=2e-4, tf=0.008), GaussMarkov(sigma=3e-5, tc=20.0), RateRandomWalk(K=2e-6)])
    x = g.simulate(1 << 15, np.random.default_rng(5))
    spiky = x.copy()
    spiky[::4000] += 40 * np.std(x)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        alone = {(name, i): estimators.get(name).fit(rec, DT) for name in ("gmwm_filtered", "gmwm_despiked")
                 for i, rec in enumerate((x, spiky))}
        assert alone["gmwm_despiked", 0].diagnostics_["outlier_fraction"] == 0.0
        assert alone["gmwm_despiked", 1].diagnostics_["outlier_fraction"] > 0.0
        for i, rec in enumerate((x, spiky)):
            with shared_choices() as kept:
                first = estimators.get("gmwm_filtered").fit(rec, DT)
                second = estimators.get("gmwm_despiked").fit(rec, DT)
                other = estimators.get("gmwm_despiked", n_starts=2).fit(rec, DT)
            assert (kept.computed, kept.shared) == ((2, 1) if i == 0 else (3, 0))
            _fits_equal(first, alone["gmwm_filtered", i])
            _fits_equal(second, alone["gmwm_despiked", i])
            assert "outlier_fraction" not in first.diagnostics_  # the outcome kept holds no entry of the AV's
        assert isinstance(kept, AxisChoices)


def test_fit_axis_shares_the_choices_of_its_methods(monkeypatch):
    """recordings.fit.fit_axis opens one scope per axis: its two default methods fit a spike-free record's curve
    once, and report what each reports fitted alone."""
    from avbench import estimators
    from avbench.estimators.selection import shared
    from avbench.recordings.fit import fit_axis

    g = Gyro(DT, [FilteredWhiteNoise(N=2e-4, tf=0.008), RateRandomWalk(K=2e-6)])
    x = g.simulate(1 << 14, np.random.default_rng(6))
    scopes = []
    real = shared.AxisChoices.outcome

    def counting(self, key, compute):
        scopes.append(id(self))
        return real(self, key, compute)

    monkeypatch.setattr(shared.AxisChoices, "outcome", counting)
    fits = fit_axis(x, DT, [], ["gmwm_filtered", "gmwm_despiked"])
    assert len(scopes) == 2 and len(set(scopes)) == 1
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for name, fit in fits.items():
            alone = estimators.get(name).fit(x, DT).result(0.95)
            assert repr(fit.result.coefficients) == repr(alone.coefficients), name  # NaN where not modelled
