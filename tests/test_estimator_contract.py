"""The estimator contract (``avbench.estimators.contract.check_estimator``, ``avbench check-estimator``):
every built-in estimator passes it, and deliberately broken estimators fail it with a clear reason."""

import math
import random
import warnings

import numpy as np
import pandas as pd
import pytest

from avbench import estimators
from avbench.estimators import Estimator
from avbench.estimators.contract import ContractError, check_estimator
from avbench.estimators.validation import check_record
from avbench.cli import main

#: settings that keep the default run fast; the slow run checks every estimator at its defaults
FAST = {"mle": {"model": "WN+RW", "max_blocks": 4096}, "gmwm_filtered": {"n_starts": 2}}


@pytest.mark.parametrize("name", estimators.names())
def test_builtin_estimators_keep_the_contract(name):
    if not estimators.estimator_class(name).__module__.startswith("avbench.estimators."):
        pytest.skip(f"{name} is an installed plugin, not a built-in")
    report = check_estimator(name, settings=FAST.get(name), raise_on_failure=False)
    assert report.ok, str(report)
    assert [r.check for r in report.results] == [
        "init", "params", "pickle", "fit", "attributes", "uncertainty", "model", "determinism", "bad input",
        "equivariance", "recovery",
    ]


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(FAST))
def test_builtin_estimators_keep_the_contract_at_their_defaults(name):
    check_estimator(name)


def test_unknown_name_lists_known():
    with pytest.raises(ValueError, match="expected one of"):
        estimators.get("kalman_magic")


# -- deliberately broken estimators ------------------------------------------------------------


class _WhiteN(Estimator):
    """A correct minimal estimator: N from the variance of the rate (white noise only)."""

    def __init__(self, *, scale=1.0):
        self.scale = scale

    def _fit(self, rate, dt):
        return {"N": float(np.sqrt(np.var(rate) * dt)) * self.scale}, {}, {}


class ValidatesInInit(_WhiteN):
    def __init__(self, *, scale=1.0):
        self.scale = float(scale)


class CopiesDefault(_WhiteN):
    def __init__(self, *, taus=(1, 2)):
        self.taus = list(taus)


class FitReturnsNone(_WhiteN):
    def fit(self, rate, dt):
        super().fit(rate, dt)


class DegreesPerHour(_WhiteN):
    """N in deg/sqrt(h) where SI (rad/sqrt(s)) is expected."""

    def _fit(self, rate, dt):
        coefs, nonphys, diag = super()._fit(rate, dt)
        return {"N": coefs["N"] * 180 / math.pi * 60}, nonphys, diag


class BiasTimes66(estimators.estimator_class("ols")):
    """OLS with B in a wrong unit (66 times too large): the first record has no bias instability."""

    def _fit(self, rate, dt):
        coefs, nonphys, diag, *parts = super()._fit(rate, dt)
        return {**coefs, "B": coefs["B"] * 66}, nonphys, diag, *parts


class WrongIndex(_WhiteN):
    def fit(self, rate, dt):
        super().fit(rate, dt)
        self.coefficients_ = self.coefficients_[["N", "K"]]
        return self


class Unseeded(_WhiteN):
    def _fit(self, rate, dt):
        coefs, nonphys, diag = super()._fit(rate, dt)
        return {"N": coefs["N"] * (1 + 1e-3 * random.random())}, nonphys, diag


class RemembersFirstRecord(_WhiteN):
    def _fit(self, rate, dt):
        if not hasattr(self, "_first"):
            self._first = float(np.var(rate))
        return {"N": float(np.sqrt(self._first * dt))}, {}, {}


class AbsoluteFloor(_WhiteN):
    """Fits the record as handed (its own fit, no standardisation) with an absolute floor on N: its
    answer depends on the unit of the record."""

    def _fit(self, rate, dt):
        return {"N": max(float(np.sqrt(np.var(rate) * dt)), 1e-6)}, {}, {}

    def fit(self, rate, dt):
        rate, dt = check_record(rate, dt)
        self._set_results(*self._fit(rate, dt))
        return self


class AcceptsAnything(_WhiteN):
    def fit(self, rate, dt):
        rate = np.asarray(rate, dtype=float).ravel()
        self._set_results(*self._fit(rate, abs(float(dt)) if dt == dt else 0.1))
        return self


class IndexErrorOnShort(_WhiteN):
    def fit(self, rate, dt):
        if np.size(rate) < 16:
            return np.asarray(rate)[99]
        return super().fit(rate, dt)


class Unpicklable(_WhiteN):
    def __init__(self, *, scale=1.0):
        self.scale = scale
        self.hook = lambda x: x


class BadStdErr(_WhiteN):
    def fit(self, rate, dt):
        super().fit(rate, dt)
        self.std_err_ = self.coefficients_ * np.nan
        self.std_err_["N"] = -1e-5  # a negative standard error
        return self


class BadConfInt(_WhiteN):
    def conf_int(self):
        c = self.coefficients_
        return pd.DataFrame({"lower": 2 * c, "upper": 3 * c})


class VarArgs(_WhiteN):
    def __init__(self, scale=1.0, **extra):
        self.scale = scale


BROKEN = [
    (ValidatesInInit, "init", "does more than store its settings"),
    (CopiesDefault, "init", "default of 'taus' stored as [1, 2]"),
    (VarArgs, "init", "__init__ takes *extra"),
    (FitReturnsNone, "fit", "fit() returned None, expected self"),
    (DegreesPerHour, "recovery", "off by"),
    (BiasTimes66, "recovery", "on the recovery_all record: off by"),
    (AbsoluteFloor, "equivariance", "coefficient N moves by"),
    (WrongIndex, "attributes", "coefficients_ index ['N', 'K'], expected ['Q', 'N', 'B', 'K', 'R']"),
    (Unseeded, "determinism", "a fresh copy fitted on the same record gave other coefficients"),
    (RemembersFirstRecord, "determinism", "refitting a fitted estimator on another record differs from a fresh fit"),
    (AcceptsAnything, "bad input", "a NaN sample: accepted, expected a ValueError"),
    (IndexErrorOnShort, "bad input", "8 samples: raised IndexError"),
    (Unpicklable, "pickle", "Can't pickle"),
    (BadStdErr, "uncertainty", "std_err_ of ['N'] is negative"),
    (BadConfInt, "uncertainty", "conf_int() does not contain the estimate for ['N']"),
]


def test_a_correct_minimal_estimator_passes():
    report = check_estimator(_WhiteN)
    assert report.ok and "N recovered" in str(report)
    assert "std_err_ and conf_int: not provided" in str(report)  # never "checked" for what it lacks


def test_every_coefficient_an_estimator_returns_is_recovered():
    report = check_estimator("ols", raise_on_failure=False)
    recovery = next(r for r in report.results if r.check == "recovery")
    assert recovery.passed and "B" in recovery.reason.split("recovered")[0], str(report)


@pytest.mark.parametrize("cls, check, reason", BROKEN, ids=[b[0].__name__ for b in BROKEN])
def test_broken_estimators_fail_with_a_clear_reason(cls, check, reason):
    report = check_estimator(cls, raise_on_failure=False)
    failed = {r.check: r.reason for r in report.failures}
    assert check in failed, str(report)
    assert reason in failed[check], str(report)
    with pytest.raises(ContractError, match="FAIL"):
        check_estimator(cls)


BROKEN_FILE = '''
import numpy as np
from avbench.estimators import Estimator


class NoSelf(Estimator):
    """fit forgets to return self."""

    def __init__(self, *, scale=1.0):
        self.scale = scale

    def _fit(self, rate, dt):
        return {"N": float(np.sqrt(np.var(rate) * dt))}, {}, {}

    def fit(self, rate, dt):
        super().fit(rate, dt)
'''


def test_cli_check_estimator(tmp_path, capsys):
    assert main(["check-estimator", "ols"]) == 0
    assert "all 11 checks passed" in capsys.readouterr().out
    f = tmp_path / "my_broken_estimator.py"
    f.write_text(BROKEN_FILE)
    assert main(["check-estimator", f"{f}:NoSelf"]) == 1
    out = capsys.readouterr().out
    assert "FAIL  fit: fit() returned None, expected self" in out and "checks failed" in out
    assert main(["check-estimator", str(f)]) == 1  # every estimator defined in the file
    assert main(["check-estimator", f"{tmp_path / 'missing.py'}:X"]) == 2
    assert "no such file" in capsys.readouterr().err
    assert main(["check-estimator", "ols", "--settings", "[1]"]) == 2


@pytest.mark.parametrize("level", [0.0, 0.01, -3.5e-7, 1e300])
@pytest.mark.parametrize("name", estimators.names())
def test_every_estimator_refuses_a_constant_record_naming_it(name, level, capfd):
    """A constant record (20,000 samples, long enough for every estimator) has no noise: every estimator
    of the registry refuses it with one line naming "constant", and nothing else is said (no LAPACK
    message on stderr, no warning)."""
    est = estimators.get(name)
    with pytest.raises(ValueError) as e:
        est.fit(np.full(20_000, level), 0.01)
    assert "constant" in str(e.value) and "\n" not in str(e.value), str(e.value)
    out, err = capfd.readouterr()
    assert out == "" and err == ""


_N_DEGENERATE = 20_000


def _degenerate(kind):
    t = np.arange(_N_DEGENERATE) / _N_DEGENERATE
    return {"ramp": 1e-3 * t,
            "ramp with 1e-12 noise": 1e-3 * t + 1e-12 * np.random.default_rng(3).standard_normal(t.size),
            "alternating": np.where(np.arange(t.size) % 2 == 0, 1.0, -1.0)}[kind]


BUILTINS = [n for n in estimators.names() if estimators.estimator_class(n).__module__.startswith("avbench.estimators.")]


@pytest.mark.parametrize("kind", ["ramp", "ramp with 1e-12 noise", "alternating"])
@pytest.mark.parametrize("name", BUILTINS)
def test_every_estimator_answers_a_degenerate_record_with_a_fit_or_its_own_refusal(name, kind):
    """A straight line (with no or float64-tiny noise) or a +1, -1, ... record of 20,000 samples (long
    enough for every estimator, as the constant record's test holds): each estimator gives a fit or
    refuses with its own one-line error about the record (starting ``rate:``), never an error of its
    arithmetic (NaN in a solver) and never "too short" / "a longer record" for a record that is not."""
    est = estimators.get(name)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            est.fit(_degenerate(kind), 0.01)
        except ValueError as e:
            msg = str(e)
            assert msg.startswith("rate:") and "\n" not in msg, msg
            assert "too short" not in msg and "longer record" not in msg, msg


@pytest.mark.parametrize("name", BUILTINS)
def test_no_estimator_calls_a_long_periodic_record_too_short(name):
    """+1, -1, ... over 20,000 samples: its Allan variance is 0 at every even cluster size, so an
    estimator on octave taus sees one positive value. A refusal names that (the Allan variance is 0
    there), never "too short" / "a longer record": a longer one would be no better."""
    est = estimators.get(name)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            est.fit(_degenerate("alternating"), 0.01)
        except ValueError as e:
            msg = str(e)
            assert "too short" not in msg and "longer record" not in msg, msg
