"""Model averaging of the Whittle estimates (``averaging="akaike"`` and ``"bic"``): the weights and
the averaged variances from first principles, the intervals untouched, and the efficiency it buys
where a candidate term is absent."""

import math

import numpy as np
import pytest

from avbench.estimators.likelihood.whittle import WhittleDebiased
from avbench.estimators.likelihood.whittle_likelihood import WhittleFit, whittle_fit
from avbench.estimators.selection import averaging
from avbench.noise_models import AngleRandomWalk, BiasInstability, Gyro, Quantization, RateRandomWalk

DT = 0.1


def _record(terms, n, seed):
    return Gyro(dt=DT, terms=terms).simulate(n, np.random.default_rng(seed))


WHITE_WALK = [AngleRandomWalk(N=4e-7), RateRandomWalk(K=2e-8)]


@pytest.mark.parametrize("how, penalty, own", [("akaike", lambda n: 2.0, False), ("bic", math.log, False),
                                               ("akaike_kept", lambda n: 2.0, True), ("bic_kept", math.log, True)])
def test_weights_and_estimates_are_the_criterion_average_of_the_submodels(how, penalty, own):
    """Refit every submodel the estimator averaged over, by hand: its weights are exp(-AIC/2) (or
    exp(-BIC/2)) normalised and each reported coefficient is the square root of the weighted mean of the
    variances: over every model, 0 where dropped, or (``_kept``) over the models holding its term, their
    weights renormalised."""
    x = _record([Quantization(Q=1e-8), *WHITE_WALK], 36_000, 5)
    est = WhittleDebiased(terms="QNBK", averaging=how).fit(x, DT)
    pen = penalty(x.size)
    assert est.result().model_choice["term_weights"]["penalty"] == pytest.approx(pen, rel=1e-15)
    weights = est.diagnostics_["term_weights"]["models"]
    assert len(weights) > 1 and math.isclose(sum(weights.values()), 1.0, rel_tol=1e-12)
    wf = WhittleFit(x, DT, debiased=True)
    full = whittle_fit(wf, list("QNBK"), signed=True)
    fits = {m: (full if m == "QNBK" else whittle_fit(wf, list(m), signed=True,
                                                    warm={c: full["a"][full["comps"].index(c)] for c in m} | {"tc": None}))
            for m in weights}
    aic = {m: -2 * f["loglik"] + pen * len(f["comps"]) for m, f in fits.items()}
    raw = {m: math.exp(-(v - min(aic.values())) / 2) for m, v in aic.items()}
    for m, f in fits.items():
        assert weights[m] == pytest.approx(raw[m] / sum(raw.values()), rel=1e-6, abs=1e-9)
    for c in "QNBK":
        held = {m: w for m, w in weights.items() if c in fits[m]["comps"] or not own}
        a = sum(w * (fits[m]["a"][fits[m]["comps"].index(c)] if c in fits[m]["comps"] else 0.0)
                for m, w in held.items()) / sum(held.values())
        assert est.coefficients_[c] == pytest.approx(math.sqrt(max(a, 0.0)) * wf.scale, rel=1e-5, abs=1e-12 * wf.scale)


def test_averaging_leaves_intervals_evidence_and_the_full_model_alone():
    x = _record([*WHITE_WALK, BiasInstability(B=2e-7, tau_max=1e5)], 36_000, 6)
    plain = WhittleDebiased(averaging="none").fit(x, DT)
    avg = WhittleDebiased(averaging="akaike").fit(x, DT)
    np.testing.assert_array_equal(avg.conf_int().to_numpy(), plain.conf_int().to_numpy())
    np.testing.assert_array_equal(avg.diagnostics_["full_coefficients"].to_numpy(),
                                  plain.diagnostics_["full_coefficients"].to_numpy())
    assert "term_weights" not in plain.diagnostics_
    assert avg.result().model_choice["term_weights"]["penalty"] == averaging.PENALTY


def test_a_term_far_above_its_noise_is_never_dropped():
    """The white noise of any such record has a Wald z^2 in the thousands: no averaged model lacks it."""
    x = _record(WHITE_WALK, 18_000, 7)
    est = WhittleDebiased(terms="QNBK", averaging="akaike").fit(x, DT)
    assert all("N" in m for m in est.diagnostics_["term_weights"]["models"])


def test_submodels_and_droppable():
    assert averaging.submodels(list("QNK"), ["Q", "K"]) == [list("QNK"), list("NK"), list("QN"), ["N"]]
    assert averaging.submodels(list("QN"), ["Q", "N"], admissible=lambda s: "N" in s) == [list("QN"), ["N"]]
    assert averaging.droppable(list("QNK"), [0.3, 1e4, math.nan]) == ["Q", "K"]
    assert averaging.NEGLIGIBLE_Z2 == pytest.approx(2 + 2 * math.log(1e6))
    assert averaging.droppable(list("QNK"), [30.0, 1e4, 40.0], penalty=math.log(72_000)) == ["Q"]


@pytest.mark.slow
def test_averaging_lowers_white_noise_error_where_quantization_is_absent():
    """White noise + random walk, Q, B, K all candidates (Q and B absent): the averaged N's squared error
    is below the full model's, the paired mean difference more than 3 of its standard errors above 0
    (the full model's N carries the absent Q's noise: ~1.8 x the bound against ~1.4 x)."""
    d = []
    for seed in range(60):
        x = _record(WHITE_WALK, 18_000, 1000 + seed)
        full = WhittleDebiased(averaging="none").fit(x, DT).coefficients_["N"]
        avg = WhittleDebiased(averaging="akaike").fit(x, DT).coefficients_["N"]
        d.append((full / 4e-7 - 1) ** 2 - (avg / 4e-7 - 1) ** 2)
    d = np.asarray(d)
    assert d.mean() > 3 * d.std(ddof=1) / math.sqrt(d.size), (d.mean(), d.std(ddof=1))
