"""The screen's notes on a likelihood fit's own model choices: the bias spectrum, the terms kept by
selection and the models its estimates were averaged over, in words, from the fit's result."""

import numpy as np
import pytest

from avbench import estimators
from avbench.noise_models import AngleRandomWalk, BiasInstability, Gyro, Quantization
from avbench.recordings.report import model_choice_notes

DT = 0.1


@pytest.fixture(scope="module")
def record():
    g = Gyro(dt=DT, terms=[AngleRandomWalk(N=4e-7), BiasInstability(B=3e-6, tau_max=1e5)])
    return g.simulate(20_000, np.random.default_rng(11))


def test_averaged_estimates_name_their_models_and_weights(record):
    r = estimators.get("whittle_debiased", averaging="bic_kept").fit(record, DT).result()
    weights = r.model_choice["term_weights"]["models"]
    notes = model_choice_notes(r.model_choice, "gyro")
    averaged = [n for n in notes if n.startswith("estimates averaged over the models with the terms ")]
    assert len(averaged) == 1
    listed = averaged[0].removeprefix("estimates averaged over the models with the terms ").split(" (weights")[0]
    shown = dict(item.split(" ") for item in listed.split(", "))
    assert shown == {m: f"{w:.2f}" for m, w in sorted(weights.items(), key=lambda kv: -kv[1]) if w >= 0.01}
    assert list(shown) == sorted(shown, key=lambda m: -weights[m])  # heaviest first
    assert "bias instability modelled as flicker (1/f) noise" in notes
    assert not any(n.startswith(("term weights:", "selection:", "bias model:")) for n in notes)


def test_selection_says_the_terms_kept_of_the_models_tried(record):
    r = estimators.get("whittle", terms="QNBK").fit(record, DT).result()
    tried = r.model_choice["selection"]
    assert len(tried) > 1
    kept = min(tried, key=tried.get)
    assert f"terms kept: {kept} (the lowest criterion of {len(tried)} models tried)" in \
        model_choice_notes(r.model_choice, "gyro")


def test_one_model_fitted_gives_no_selection_note():
    notes = model_choice_notes({"selection": {"QNBK": 1.0}, "bias_model": {"chosen": "gauss_markov"}}, "gyro")
    assert notes == ["bias instability modelled as Gauss-Markov noise"]


@pytest.mark.parametrize("preferred", ["GM", "FL"])
@pytest.mark.parametrize("decisive", [True, False])
def test_bias_evidence_note_says_when_the_intervals_hold_both_models(preferred, decisive):
    """GMWM's bias-model evidence in words: 'clearly favours' or 'does not clearly favour', and where the
    intervals hold both fits (unless the evidence clearly favours the fitted model) the note says so."""
    ev = {"preferred": preferred, "fitted": "GM", "decisive": decisive, "weight": 0.97 if decisive else 0.6,
          "GM": {"coefficients": {"B": 1e-5, "K": 1e-7}}, "FL": {"coefficients": {"B": 2e-5, "K": 0.0}}}
    units = {"B": "deg/h", "K": "deg/h^1.5"}
    notes = [n for n in model_choice_notes({"bias_evidence": ev}, "gyro", units) if n.startswith("bias instability")]
    assert len(notes) == 1
    note = notes[0]
    assert ("clearly favours" in note) is decisive and ("does not clearly favour" in note) is (not decisive)
    assert note.endswith("; the intervals hold both") is (not decisive or preferred != "GM")
    assert "not clearly favours" not in note
