"""Every built-in estimator declares what each of its settings accepts (``parameter_constraints``,
:mod:`avbench.estimators.settings`): its defaults and every setting a packaged study uses pass, and a
value of the wrong kind is refused with an error naming the estimator and the setting."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from avbench import estimators
from avbench.estimators.base import BUILTIN
from avbench.estimators.settings import (
    Boolean,
    Instance,
    Interval,
    NoneValue,
    Options,
    undeclared,
    validate_settings,
)
from avbench.studies.config import load_config

#: the registered estimators avbench ships (names() also lists plugins and test-only registrations)
NAMES = sorted(n for n in estimators.names() if n in BUILTIN)
STUDIES = sorted((Path(__file__).parents[1] / "studies").glob("*.toml"))


def test_the_built_ins_are_listed():
    assert NAMES == sorted(BUILTIN)


@pytest.mark.parametrize("name", NAMES)
def test_every_setting_is_declared(name):
    cls = estimators.estimator_class(name)
    assert undeclared(cls) == [], f"{name}: settings without a declaration"


@pytest.mark.parametrize("name", NAMES)
def test_defaults_pass(name):
    cls = estimators.estimator_class(name)
    validate_settings(cls, cls().get_params())


# -- values of the wrong kind --------------------------------------------------------------------

#: values every grammar checked by a function (terms, taus, a latent model, a covariance, ...) refuses
_REFUSED_BY_ANY_GRAMMAR = ("maybe", -1, -1.5)


def _refused(constraint, value) -> bool:
    """Whether ``value`` is of a kind or range ``constraint`` refuses, decided from what the constraint
    says it is (its type and bounds), not by asking it."""
    if isinstance(constraint, Interval):
        if isinstance(value, bool) or not isinstance(value, int | float):
            return True
        if constraint.kind is int and not isinstance(value, int):
            return True
        if not math.isfinite(value):
            return True
        lo, hi, closed = constraint.low, constraint.high, constraint.closed
        below = lo is not None and (value < lo or (value == lo and closed in ("right", "neither")))
        above = hi is not None and (value > hi or (value == hi and closed in ("left", "neither")))
        return below or above
    if isinstance(constraint, Boolean):
        return not isinstance(value, bool)
    if isinstance(constraint, NoneValue):
        return value is not None
    if isinstance(constraint, Options):
        return not any(type(value) is type(v) and value == v for v in constraint.values)
    if isinstance(constraint, Instance):
        return not isinstance(value, constraint.types)
    return value in _REFUSED_BY_ANY_GRAMMAR and not isinstance(value, bool)  # a Check (Terms, Taus, ...)


_SIMPLE = (Interval, Boolean, NoneValue, Options, Instance)


def _wrong_values(constraints):
    """Values every one of ``constraints`` refuses: "maybe" for a number or a flag, -1 for a positive
    integer, an unknown option, ... (for a grammar checked by a function: "maybe", -1, -1.5)."""
    known = st.sampled_from(_REFUSED_BY_ANY_GRAMMAR + ("unknown-option", "", True, False, 0, -(2**40), 1e300,
                                                       math.nan, math.inf))
    if all(isinstance(c, _SIMPLE) for c in constraints):
        values = st.one_of(known, st.text(max_size=12), st.integers(-(2**40), 2**40),
                           st.floats(allow_nan=True, allow_infinity=True), st.booleans())
    else:
        values = st.sampled_from(_REFUSED_BY_ANY_GRAMMAR)
    return values.filter(lambda v: all(_refused(c, v) for c in constraints))


def _declared_settings():
    out = []
    for name in NAMES:
        cls = estimators.estimator_class(name)
        declared = getattr(cls, "parameter_constraints", None) or {}
        out += [(name, key) for key in cls._param_names() if key in declared]
    return out


DECLARED = _declared_settings()


@pytest.mark.parametrize("name, key", DECLARED, ids=[f"{n}.{k}" for n, k in DECLARED])
@settings(max_examples=12, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.filter_too_much])
@given(data=st.data())
def test_a_value_of_the_wrong_kind_is_refused_naming_the_setting(name, key, data):
    cls = estimators.estimator_class(name)
    value = data.draw(_wrong_values(cls.parameter_constraints[key]), label="value")
    with pytest.raises(ValueError) as info:
        validate_settings(cls, {**cls().get_params(), key: value})
    message = str(info.value)
    assert message.startswith(f"estimator {name!r}: {key}="), message
    assert "expected" in message
    with pytest.raises(ValueError, match=f"{key}="):  # the registry refuses it too, before any data
        estimators.get(name, **{key: value})


@pytest.mark.parametrize("name, key, value", [
    ("ols", "overlapping", "maybe"), ("ols_trimmed", "max_error_pct", "40"), ("wls_edf", "n_iter", 0),
    ("wls_edf_hadamard", "terms", "QNBKR"), ("slope_lines", "ordered", 1), ("log_fit", "min_clusters", 1),
    ("nnls_rel", "filter", "yes"), ("nnls_rel_filtered", "lines", True),
    ("shakf", "P0", -1.0), ("shakf", "adapt", "qq"), ("shakf", "x0", {"N": [1.0, "furlong"]}),
    ("shakf_multitau", "m", [0, 2]), ("nekf", "seed", 1.5), ("nekf_multitau", "weights_P0", 0.0),
    ("arma_em", "terms", "NBKR"), ("arma_em", "tc0", math.inf), ("mle", "model", "DR"),
    ("mle", "block", "big"), ("gmwm_robust", "eff", 1.5), ("gmwm_robust", "psi", "cauchy"),
    ("gmwm_despiked", "gap_tol", 1.0), ("gmwm_despiked", "half_window", 0),
])
def test_values_refused_at_fit_time_are_refused_by_the_declaration(name, key, value):
    """Values the estimators refused when fitting are refused by the declaration, before any data."""
    with pytest.raises(ValueError, match=f"estimator {name!r}: {key}="):
        validate_settings(estimators.estimator_class(name), {key: value})


@pytest.mark.parametrize("name, params", [
    ("ols", {"taus": [0.1, 0.2], "overlapping": True}), ("ols_trimmed", {"max_error_pct": 30}),
    ("slope_lines", {"terms": ["N", "B"], "min_clusters": 8}), ("nnls_rel", {"filter": "fit", "lines": "auto"}),
    ("shakf", {"terms": "NB", "x0": {"N": (1.5, "deg/sqrt(h)"), "B": 1e-5}, "P0": [0.25, 0.5], "Q0": [[1e-8, 0], [0, 1e-8]],
               "R0": 2, "adapt": "", "b": 1}),
    ("shakf_multitau", {"m": [1, 4, 2], "R0": [1.0, 2.0, 3.0]}), ("nekf", {"seed": 2**40, "weights_Q0": 0}),
    ("arma_em", {"terms": "NK", "x0": {"N": [1.5, "deg/sqrt(h)"], "K": [50.0, "deg/h^1.5"]}, "tc0": 10}),
    ("mle", {"model": ["WN", "RW", "DR"], "block": 1}), ("gmwm_robust", {"psi": "biweight", "eff": 0.95}),
    ("gmwm_despiked", {"gap_tol": None, "threshold": 8}),
])
def test_values_accepted_at_fit_time_pass(name, params):
    validate_settings(estimators.estimator_class(name), params)


# -- the packaged studies ------------------------------------------------------------------------

@pytest.mark.parametrize("path", STUDIES, ids=[p.stem for p in STUDIES])
def test_every_setting_of_the_packaged_studies_passes(path):
    """Each estimator's settings for each gyro of a packaged study (``x0`` from ``x0_truth_scale``
    included) pass its declaration (constraints and relations)."""
    cfg = load_config(path)
    for spec in cfg.estimators:
        for g in cfg.gyros:
            est = spec.make(g)
            validate_settings(type(est), spec.settings_for(g))


# -- one check, one message -----------------------------------------------------------------------

class _UndeclaredColour(estimators.estimator_class("ols")):
    """Test only: OLS with a setting (``colour``) its declaration does not list."""

    def __init__(self, *, terms="QNBKR", taus="all", overlapping=False, colour="red"):
        super().__init__(terms=terms, taus=taus, overlapping=overlapping)
        self.colour = colour


def _message_of(action) -> str:
    with pytest.raises(ValueError) as info:
        action()
    return str(info.value)


def _config_message(tmp_path, name, settings_toml) -> str:
    from conftest import study_toml

    path = tmp_path / "study.toml"
    path.write_text(study_toml(extra_estimators=f'\n[[estimators]]\nname = "{name}"\nsettings = {{ {settings_toml} }}\n'))
    return _message_of(lambda: load_config(path))


@pytest.mark.parametrize("name, given, toml, message", [
    # a setting the estimator does not take
    ("ols", {"colour": "blue"}, 'colour = "blue"',
     "estimator 'ols': unknown setting(s) colour; accepted: terms, taus, overlapping"),
    # a setting it takes but does not declare: refused by get and a config when given, by fit always
    ("test_undeclared_colour", {"colour": "blue"}, 'colour = "blue"',
     "estimator 'test_undeclared_colour': unknown setting(s) colour; accepted: terms, taus, overlapping"),
])
def test_an_undeclared_setting_is_refused_alike_by_get_fit_and_a_study_config(tmp_path, monkeypatch, name, given, toml,
                                                                             message):
    """``estimators.get``, ``Estimator.fit`` and a study config check settings in one place
    (:func:`validate_settings`): an undeclared setting is refused by each with the same message,
    naming the settings the estimator accepts. (The test-only estimator is registered for this test
    only: the registry's other tests see the estimators a user has.)"""
    import numpy as np

    from avbench.estimators import base

    monkeypatch.setitem(base._REGISTRY, "test_undeclared_colour", _UndeclaredColour)
    monkeypatch.setattr(_UndeclaredColour, "name", "test_undeclared_colour")

    assert _message_of(lambda: estimators.get(name, **given)) == message
    assert _config_message(tmp_path, name, toml).endswith(message)
    if name == "test_undeclared_colour":
        est = estimators.estimator_class(name)()  # built without the check: fit refuses it
        assert _message_of(lambda: est.fit(np.random.default_rng(0).normal(size=256), 0.01)) == message


@pytest.mark.parametrize("name, settings, toml, setting", [
    ("gmwm", {"model": "WN+GM+RW", "filter_tf": 0.005}, 'model = "WN+GM+RW", filter_tf = 0.005', "filter_tf"),
    ("shakf", {"terms": "NB", "x0": {"N": 1e-4}}, 'terms = "NB", x0 = { N = 1e-4 }', "x0"),
    ("nnls_rel", {"terms": "QB", "filter": "fit"}, 'terms = "QB", filter = "fit"', "filter"),
])
def test_a_broken_relation_is_refused_alike_by_get_fit_and_a_study_config(tmp_path, name, settings, toml, setting):
    """Relations between settings are declarations too (``setting_relations``), checked in the same place."""
    import numpy as np

    message = _message_of(lambda: estimators.get(name, **settings))
    assert message.startswith(f"estimator {name!r}: {setting}")
    assert _config_message(tmp_path, name, toml).endswith(message)
    est = estimators.estimator_class(name)(**settings)
    assert _message_of(lambda: est.fit(np.random.default_rng(0).normal(size=4096), 0.01)) == message


def test_fit_changes_no_setting(monkeypatch):
    """``fit`` hands a setting holding rates (``x0``) to the fit in the standardised unit on a copy: the
    estimator's own setting is the same object, unchanged, while the fit runs and after it."""
    import warnings

    import numpy as np

    x0 = {"N": 1e-3}
    est = estimators.get("shakf", terms="N", x0=x0)
    fit, during = type(est)._fit, []

    def watched(self, rate, dt):
        during.append((self.x0, est.x0))
        return fit(self, rate, dt)

    monkeypatch.setattr(type(est), "_fit", watched)
    rate = np.random.default_rng(3).normal(0.0, 1e-2, 4096) * 1e30  # an extreme unit: the fit sees x0 rescaled
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        est.fit(rate, 0.01)
    (handed, own), = during
    from avbench.estimators.base import _extreme_unit

    assert handed["N"] == pytest.approx(1e-3 / _extreme_unit(rate), rel=1e-12, abs=0) and own is x0
    assert est.x0 is x0 and x0 == {"N": 1e-3}
