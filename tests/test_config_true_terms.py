"""``terms = "true"`` in a study's settings: each gyro fitted with its own term set, checked before any work."""

from __future__ import annotations

import re

import pytest

from avbench.noise_models import AngleRandomWalk, BiasInstability, GaussMarkov, Gyro, Quantization, RateRandomWalk
from avbench.studies.config import ConfigError, parse_config


@pytest.mark.parametrize("terms, expected", [
    ([AngleRandomWalk(N=1e-5)], "N"),
    ([RateRandomWalk(K=1e-7), AngleRandomWalk(N=1e-5), Quantization(Q=1e-6)], "QNK"),
    ([AngleRandomWalk(N=1e-5), BiasInstability(B=1e-6, tau_max=600.0)], "NB"),
    ([AngleRandomWalk(N=1e-5), GaussMarkov(sigma=1e-5, tc=100.0)], "NB"),
])
def test_a_gyro_names_its_term_set_in_coefficient_order(terms, expected):
    assert Gyro(dt=0.1, terms=terms).term_set == expected


def _raw(estimator: dict) -> dict:
    return {
        "study": {"name": "t", "seed": 1, "replicates": 2, "n_samples": 2000},
        "gyros": [
            {"name": "nk", "dt": 0.1, "terms": [{"type": "RateRandomWalk", "K": 1e-7},
                                                {"type": "AngleRandomWalk", "N": 1e-5}]},
            {"name": "qnbk", "dt": 0.1, "terms": [{"type": "Quantization", "Q": 1e-6},
                                                  {"type": "AngleRandomWalk", "N": 1e-5},
                                                  {"type": "BiasInstability", "B": 1e-6, "tau_max": 600.0},
                                                  {"type": "RateRandomWalk", "K": 1e-7}]},
            {"preset": "SRS2000"},
        ],
        "estimators": [estimator],
    }


def test_true_terms_are_resolved_per_gyro_before_the_estimator_is_built():
    cfg = parse_config(_raw({"name": "whittle_debiased", "settings": {"terms": "true"}}))
    (spec,) = cfg.estimators
    # SRS2000 is a quantization + white noise + bias instability preset (Lv et al. 2015: Q, N, B)
    assert {g.label: spec.make(g).get_params()["terms"] for g in cfg.gyros} == \
        {"nk": "NK", "qnbk": "QNBK", "SRS2000": "QNB"}


def test_gyro_settings_override_true_terms_for_their_gyro():
    cfg = parse_config(_raw({"name": "whittle_debiased", "settings": {"terms": "true"},
                             "gyro_settings": {"nk": {"terms": "QNBK"}}}))
    (spec,) = cfg.estimators
    assert [spec.make(g).get_params()["terms"] for g in cfg.gyros] == ["QNBK", "QNBK", "QNB"]


@pytest.mark.parametrize("estimator, message", [
    # the resolved set is checked against what the estimator supports, under the key that asked for it
    ({"name": "arma_em", "settings": {"terms": "true"}},
     r"estimators[0].settings: (gyro qnbk) estimator 'arma_em': terms='QNBK': expected 'NK', 'NB' or 'NBK'"),
    # an estimator without a terms setting is told so
    ({"name": "gmwm", "settings": {"terms": "true"}},
     r"estimators[0].settings: (gyro nk) estimator 'gmwm': unknown setting(s) terms"),
])
def test_a_true_term_set_the_estimator_cannot_fit_is_refused_before_any_work(estimator, message):
    with pytest.raises(ConfigError, match=re.escape(message)):
        parse_config(_raw(estimator), where="study.toml")
