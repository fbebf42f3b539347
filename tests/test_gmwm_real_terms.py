"""GMWM's latents for real sensors: the sensor's filter (FW) and sinusoidal noise (SN).

Recovery on simulated gyros: the replicate mean within 3 replicate standard errors of the truth
(slow), and in the default run one record where the right model passes the poor-fit check and the
model without the term is flagged (the check's own calibration is tested in test_fit_check.py).
"""

import math

import numpy as np
import pytest

from avbench import estimators
from avbench.estimators.likelihood.gmwm import parse_model
from avbench.noise_models import AngleRandomWalk, FilteredWhiteNoise, GaussMarkov, Gyro, RateRandomWalk, Sinusoidal

DT = 0.01
N, TF, K = 1e-3, 0.02, 2e-6
A, F0 = 4e-3, 0.55


def _filtered():
    return Gyro(dt=DT, terms=[FilteredWhiteNoise(N=N, tf=TF), GaussMarkov(sigma=5e-4, tc=30.0), RateRandomWalk(K=K)])


def _sine():
    return Gyro(dt=DT, terms=[AngleRandomWalk(N=1e-4), Sinusoidal(A, F0), RateRandomWalk(K=K)])


def test_filter_latent_fits_what_white_noise_cannot():
    x = _filtered().simulate(300_000, np.random.default_rng(1))
    fw = estimators.get("gmwm", model="FW+GM+RW", min_m=1).fit(x, DT)
    wn = estimators.get("gmwm", model="WN+GM+RW", min_m=1).fit(x, DT)
    assert not fw.diagnostics_["poor_fit"] and wn.diagnostics_["poor_fit"]
    se = fw.diagnostics_["std_err"]["N"]
    assert abs(fw.coefficients_["N"] - N) < 4 * se, (fw.coefficients_["N"], se)
    assert fw.diagnostics_["params"]["FW.tf"] == pytest.approx(TF, rel=0.3)


def test_sinusoid_latent_finds_the_line():
    x = _sine().simulate(300_000, np.random.default_rng(2))
    sn = estimators.get("gmwm", model="WN+RW+SN", min_m=1).fit(x, DT)
    plain = estimators.get("gmwm", model="WN+RW", min_m=1).fit(x, DT)
    assert not sn.diagnostics_["poor_fit"] and plain.diagnostics_["poor_fit"]
    p = sn.diagnostics_["params"]
    assert p["SN.f0"] == pytest.approx(F0, rel=0.05) and p["SN.A"] == pytest.approx(A, rel=0.1)
    assert "SN" not in sn.coefficients_.index and math.isfinite(sn.coefficients_["N"])


def test_model_names():
    assert parse_model("SN+FW+RW") == ("FW", "RW", "SN")
    with pytest.raises(ValueError, match="not both WN and FW"):
        parse_model("WN+FW")


@pytest.mark.slow
@pytest.mark.parametrize("which", ["filtered", "sine"])
def test_recovery_over_replicates(which):
    """20 replicates: the mean of each parameter within 3 replicate SE of the truth."""
    gyro, model, truth = {
        "filtered": (_filtered(), "FW+GM+RW", {"FW.N": N, "FW.tf": TF, "RW.K": K}),
        "sine": (_sine(), "WN+RW+SN", {"SN.A": A, "SN.f0": F0, "RW.K": K}),
    }[which]
    vals = {k: [] for k in truth}
    for s in np.random.SeedSequence(24).spawn(20):
        e = estimators.get("gmwm", model=model, min_m=1).fit(gyro.simulate(300_000, np.random.default_rng(s)), DT)
        for k in truth:
            vals[k].append(e.diagnostics_["params"][k])
    for k, t in truth.items():
        v = np.array(vals[k])
        assert abs(v.mean() - t) <= 3 * v.std(ddof=1) / math.sqrt(len(v)), (k, v.mean(), t)


def test_gm_at_the_first_octaves_does_not_resolve_b():
    """A Gauss-Markov term peaking within three octaves of the shortest tau is the filter's shape, not
    bias instability: B is flagged not resolved with an upper bound that holds for the record's flicker
    B (the AV's minimum read as a plateau), and so is K, which the model without a bias instability reads
    from the curve's middle (its bound holds the true K); a slow GM is not flagged (the rule can fail)."""
    import warnings

    from avbench.estimators.base import IdentifiabilityWarning
    from avbench.estimators.results import build
    from avbench.recordings.fit import MethodFit
    from avbench.recordings.report import coefficient_flags

    from avbench.noise_models import BiasInstability, SecondOrderGaussMarkov

    flicker = BiasInstability(B=1e-4, tau_max=4000.0)
    # the filter-like fast correlated term as a second-order GM (it reports R, not B): the GM latent takes it
    fast = Gyro(dt=DT, terms=[AngleRandomWalk(N=1e-4), GaussMarkov(sigma=3e-3, tc=0.015), RateRandomWalk(K=K)])
    fast_fl = Gyro(dt=DT, terms=[AngleRandomWalk(N=1e-4), SecondOrderGaussMarkov(R=0.03, w0=60.0), flicker,
                                 RateRandomWalk(K=K)])
    slow = Gyro(dt=DT, terms=[AngleRandomWalk(N=1e-4), GaussMarkov(sigma=3e-4, tc=20.0), RateRandomWalk(K=K)])
    for gyro, expect in ((fast, True), (fast_fl, True), (slow, False)):
        x = gyro.simulate(200_000, np.random.default_rng(7))
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            e = estimators.get("gmwm", min_m=1).fit(x, DT)
        unresolved = e.diagnostics_.get("unresolved", {})
        assert ("B" in unresolved) is expect
        assert any(issubclass(w.category, IdentifiabilityWarning) for w in caught) is expect
        flags = coefficient_flags(MethodFit("gmwm", build(e), 1.0, 0.0))
        assert flags["B"] == ("not resolved" if expect else "ok")
        if expect:
            assert flags["K"] == "not resolved"
            lo, hi = unresolved["K"]
            assert lo == 0 and K <= hi
            # the bound is the data's, not the fit's: the largest K whose AV stays under the record's AV limits
            assert hi < math.sqrt(3 * e.diagnostics_["avar"].max() / e.diagnostics_["tau"].min())
        if gyro is fast_fl:
            lo, hi = unresolved["B"]
            assert lo == 0 and flicker.B <= hi


def test_a_term_at_zero_is_reported_with_its_interval():
    """No bare 0: a term the fit puts at its floor (K on a gyro without rate random walk) is flagged
    not resolved with [0, upper], upper the largest K whose AV stays under the record's AV limits."""
    import warnings

    from avbench.estimators.results import build
    from avbench.recordings.fit import MethodFit
    from avbench.recordings.report import coefficient_flags

    g = Gyro(dt=DT, terms=[AngleRandomWalk(N=1e-3), GaussMarkov(sigma=2e-4, tc=5.0)])
    x = g.simulate(200_000, np.random.default_rng(1))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        e = estimators.get("gmwm_filtered").fit(x, DT)
    assert e.coefficients_["K"] == 0
    lo, hi = e.diagnostics_["unresolved"]["K"]
    av = e.diagnostics_["avar"]
    assert lo == 0 and 0 < hi < math.sqrt(3 * av.max() / e.diagnostics_["tau"].min())
    assert coefficient_flags(MethodFit("gmwm_filtered", build(e), 1.0, 0.0))["K"] == "not resolved"


# -- a resonance (band-pass Gauss-Markov, RS): the ADIS16405 gyro z's 17-21 Hz band ---------------------

RS_F0, RS_TC = 20.0, 0.3


def _resonant():
    """Like the ADIS16405's gyro z (results/real): the filtered white noise, a slow Gauss-Markov bias, a
    random walk, and a resonance near 20 Hz holding half the white noise's variance."""
    from avbench.noise_models import Resonance

    return Gyro(dt=DT, terms=[FilteredWhiteNoise(N=7e-4, tf=0.006), GaussMarkov(sigma=1.7e-4, tc=40.0),
                              RateRandomWalk(K=1e-5), Resonance(sigma=5e-3, f0=RS_F0, tc=RS_TC)])


def test_resonance_is_added_on_evidence_and_keeps_the_short_scales():
    """gmwm_filtered (resonance="auto") adds RS where a band stands out of the spectrum and the model
    without it drops scales: it then fits every octave, finds f0 and tc, and N within 4 of its standard
    errors of the truth; without RS the short octaves are dropped. On a record without a band nothing is
    added (the rule can say no)."""
    import warnings

    x = _resonant().simulate(200_000, np.random.default_rng(24))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        e = estimators.get("gmwm_filtered").fit(x, DT)
        without = estimators.get("gmwm_filtered", resonance="model").fit(x, DT)
    test = e.diagnostics_["resonance_test"]
    assert test["included"] and test["prominence"] > 2 and test["band_p_value"] < 1e-3
    assert e.diagnostics_["min_m"] < without.diagnostics_["min_m"]
    assert e.diagnostics_["min_m"] == 1 and not e.diagnostics_["poor_fit"]
    p = e.diagnostics_["params"]
    assert p["RS.f0"] == pytest.approx(RS_F0, rel=0.02) and p["RS.tc"] == pytest.approx(RS_TC, rel=0.3)
    se = e.std_err_["N"]
    assert abs(e.coefficients_["N"] - 7e-4) < 4 * se, (e.coefficients_["N"], se)
    assert "resonance_test" not in estimators.get("gmwm").fit(x, DT).diagnostics_  # plain gmwm: unchanged
    # the same record in mrad/s: the same choice, the rate-like entries times 1000, the others equal
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        milli = estimators.get("gmwm_filtered").fit(1000.0 * x, DT)
    t2, ev, ev2 = milli.diagnostics_["resonance_test"], e.diagnostics_["bias_evidence"], milli.diagnostics_["bias_evidence"]
    assert t2["included"] and t2["sigma"] == pytest.approx(1000 * test["sigma"], rel=1e-6)
    assert t2["f0"] == pytest.approx(test["f0"], rel=1e-6) and t2["prominence"] == pytest.approx(test["prominence"], rel=1e-9)
    assert ev2["preferred"] == ev["preferred"] and ev2["weight"] == pytest.approx(ev["weight"], rel=1e-6)
    for k in ("GM", "FL"):
        assert ev2[k]["B"] == pytest.approx(1000 * ev[k]["B"], rel=1e-6)
    # a broadband record whose model drops a scale anyway: no band stands out, nothing is added
    g = Gyro(dt=DT, terms=[FilteredWhiteNoise(N=1e-3, length=3), GaussMarkov(sigma=5e-4, tc=2.0)])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        b = estimators.get("gmwm_filtered").fit(g.simulate(200_000, np.random.default_rng(5)), DT)
    assert not b.diagnostics_["resonance_test"]["included"]
    with pytest.raises(ValueError, match="resonance"):
        estimators.get("gmwm", resonance="yes").fit(x, DT)


@pytest.mark.slow
@pytest.mark.timeout(3600)
def test_resonance_fit_check_and_recovery_over_replicates():
    """40 records of the resonant gyro at gmwm_filtered's defaults: the poor-fit check (level 0.01)
    flags at most the binomial 99.9 % limit of 40 x 0.01; RS is left out at most as often as the check
    rejects the right model at one of the two cut-offs that see the band (each at level 0.01: the binomial
    99.9 % limit of 40 x 0.02; measured 1 of 40, where the check's p was 0.005 and 0.008); the means of N
    (all records), f0 and tc (records with RS) lie within 3 replicate standard errors of the truth."""
    import warnings

    from scipy.stats import binom

    reps, flagged, vals = 40, 0, {"N": [], "f0": [], "tc": [], "included": []}
    for s in np.random.SeedSequence(2424).spawn(reps):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            e = estimators.get("gmwm_filtered").fit(_resonant().simulate(200_000, np.random.default_rng(s)), DT)
        flagged += bool(e.diagnostics_["poor_fit"])
        d = e.diagnostics_
        vals["included"].append(d["resonance_test"]["included"])
        vals["N"].append(e.coefficients_["N"])
        vals["f0"].append(d["params"].get("RS.f0", math.nan))
        vals["tc"].append(d["params"].get("RS.tc", math.nan))
    print(f"{flagged}/{reps} flagged; RS on {sum(vals['included'])}/{reps}")
    assert flagged <= binom.ppf(0.999, reps, 0.01)
    assert reps - sum(vals["included"]) <= binom.ppf(0.999, reps, 0.02)
    for k, t in (("N", 7e-4), ("f0", RS_F0), ("tc", RS_TC)):
        v = np.array(vals[k])
        v = v[np.isfinite(v)]
        assert abs(v.mean() - t) <= 3 * v.std(ddof=1) / math.sqrt(v.size), (k, v.mean(), t)


def test_the_first_step_gives_a_flat_first_octave_one_degree_of_freedom():
    """A sensor's low-pass filter holds the first AV point on the level of the second (the engine reads it
    as flicker FM). The engine's edf there is the record's (~0.9 n: SP1065's formula, corrected); GMWM's
    first step counts it as one degree of freedom (``first_step_edf``), and leaves every other scale, and
    every scale of an unfiltered record, at the engine's edf."""
    from avbench.estimators.allan.variance import allan_variance
    from avbench.estimators.likelihood.gmwm import first_step_edf

    for terms, flat in (([FilteredWhiteNoise(N=1e-4, tf=0.02)], True), ([AngleRandomWalk(N=1e-4)], False)):
        g = Gyro(dt=0.01, terms=terms)
        r = allan_variance(g.simulate(1 << 15, np.random.default_rng(1)), g.dt, taus="octave", overlapping=True)
        assert r.edf[0] > 0.5 * r.n_samples
        e = first_step_edf(r.tau, r.avar, r.J, r.edf)
        assert e[0] == (1.0 if flat else r.edf[0])
        np.testing.assert_array_equal(e[1:], r.edf[1:])
