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
    return Gyro(dt=DT, terms=[FilteredWhiteNoise(N=N, tc=TF), GaussMarkov(sigma=5e-4, tc=30.0), RateRandomWalk(K=K)])


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
    B (the AV's minimum read as a plateau); a slow GM is not flagged (the rule can fail)."""
    import warnings

    from avbench.estimators.base import IdentifiabilityWarning
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
        flag = coefficient_flags(MethodFit("gmwm", e, 1.0, 0.0))["B"]
        assert flag == ("not resolved" if expect else "ok")
        if gyro is fast_fl:
            lo, hi = unresolved["B"]
            assert lo == 0 and flicker.B <= hi


def test_a_term_at_zero_is_reported_with_its_interval():
    """No bare 0: a term the fit puts at its floor (K on a gyro without rate random walk) is flagged
    not resolved with [0, upper], upper the largest K whose AV stays under the record's AV limits."""
    import warnings

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
    assert coefficient_flags(MethodFit("gmwm_filtered", e, 1.0, 0.0))["K"] == "not resolved"
