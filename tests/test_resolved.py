"""One meaning of "resolved" for every method: a coefficient whose interval at the result's level
reaches zero (its lower end 0 or below) is "not resolved", whatever estimator gave the interval, and
every surface shows and writes its upper bound, never the fit's number as an estimate
(:func:`avbench.estimators.results.build`, :func:`~avbench.estimators.results.unresolved_reason`).

The slow Monte Carlo tests measure what that rule gives on records without a term: the share of records
on which a method calls the absent term resolved, against the level of its intervals (at most 5 % at
95 %, judged by the share's Clopper-Pearson interval), and on records with the term at a moderate level,
the share on which it is resolved (power)."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.stats import beta

from avbench import estimators
from avbench.estimators.base import Estimator, data_scale
from avbench.estimators.results import REASONS, Coefficient, build, unresolved_reason
from avbench.noise_models import Gyro, presets
from avbench.noise_models.units import COEFFICIENTS


class _GivenInterval(Estimator):
    """N from the variance of the rate, and a B whose value and interval are the settings: an
    estimator that hands ``build`` any interval, as a Wald interval (ends below zero), a clipped one
    (lower end 0) or a log-scale one (above zero) would be."""

    def __init__(self, *, b=2e-5, lower=0.0, upper=6e-5):
        self.b = b
        self.lower = lower
        self.upper = upper

    def _fit(self, rate, dt):
        return {"N": float(np.sqrt(np.var(rate) * dt)), "B": self.b}, {}, {}

    def conf_int(self, level=0.95, conservative=False):
        ci = pd.DataFrame({"lower": np.nan, "upper": np.nan}, index=list(COEFFICIENTS))
        ci.loc["B"] = (self.lower, self.upper)
        return ci


def _rate():
    """White noise at the level estimators fit in (:func:`avbench.estimators.base.data_scale` 1): the
    settings' B is the fit's as it is."""
    x = np.random.default_rng(3).normal(0.0, 1.0, 2048)
    x = x / data_scale(x)
    assert data_scale(x) == 1.0
    return x


def _fitted(**settings_):
    return _GivenInterval(**settings_).fit(_rate(), 0.01)


@settings(max_examples=60, deadline=None, derandomize=True)
@given(b=st.floats(1e-6, 1e-3), below=st.floats(0.0, 2e-3), above=st.floats(0.0, 1e-3))
def test_a_term_is_resolved_exactly_when_its_interval_stays_above_zero(b, below, above):
    lower, upper = b - below, b + above  # an interval about the estimate, reaching below zero or not
    r = build(_fitted(b=b, lower=lower, upper=upper))
    e = r.coefficients["B"]
    assert e.fitted == b and e.estimate_interval == (lower, upper)  # the method's own numbers are kept
    if lower > 0.0:
        assert e.status == "ok" and e.value == b and e.interval == (lower, upper)
        assert e.estimate_or_bound() == (b, None)
    else:
        assert e.status == "not resolved" and e.reason == "interval" and math.isnan(e.value)
        assert e.interval == (0.0, upper)
        assert e.estimate_or_bound() == (upper, "interval")  # the bound, never the fit's number


def test_an_estimate_without_interval_or_evidence_is_not_called_resolved():
    """A method that gives no interval: its estimate is "no interval", shown and written as an estimate
    with that said, never "ok"."""
    from avbench.recordings import report

    est = _fitted(b=2e-5, lower=np.nan, upper=np.nan)
    r = build(est)
    e = r.coefficients["B"]
    assert e.status == "no interval" and e.value == 2e-5 and e.interval is None
    assert e.estimate_or_bound() == (2e-5, None)
    assert report.shown_value(e, "rad/s", "gyro") == "2e-05 (no interval)"
    with pytest.raises(ValueError, match="tested"):
        Coefficient("B", "no interval", value=2e-5, interval=(1e-5, 3e-5))


def test_the_rule_reads_evidence_and_zero_before_the_interval():
    from avbench.estimators.results import Evidence

    absent = Evidence(lr=0.1, p_value=0.4, present=False, lower=0.0, upper=5.0, level=0.95)
    present = Evidence(lr=30.0, p_value=1e-7, present=True, lower=1.0, upper=5.0, level=0.95)
    assert unresolved_reason(2.0, absent, (1.0, 5.0)) == "evidence"
    assert unresolved_reason(0.0, None, (1.0, 5.0)) == "zero"
    assert unresolved_reason(2.0, present, (0.0, 5.0)) == "interval"
    assert unresolved_reason(2.0, present, (1.0, 5.0)) is None
    assert unresolved_reason(2.0, None, (-math.inf, 5.0)) is None  # no finite lower end: nothing reaches zero
    assert set(REASONS) >= {"record", "evidence", "zero", "interval"}


def test_a_coefficient_refuses_a_resolved_status_with_an_interval_reaching_zero():
    with pytest.raises(ValueError, match="reaching zero"):
        Coefficient("B", "ok", value=2e-5, interval=(0.0, 6e-5))
    with pytest.raises(ValueError, match="reason"):
        Coefficient("B", "not resolved", interval=(0.0, 6e-5), reason="because")
    Coefficient("B", "not resolved", fitted=2e-5, interval=(0.0, 6e-5), reason="interval")


def test_every_surface_shows_an_interval_reaching_zero_as_its_bound():
    """The screen's cell, the page's, the CSV row, the JSON entry and the filter files' value of a B whose
    interval reaches zero: the upper end, said to be a bound; the fit's number only as ``fitted``."""
    from avbench.recordings import filter_yaml, report
    from avbench.recordings.fit import MethodFit
    from avbench.recordings.html import recording_page
    from avbench.recordings.sensors import SensorRecord
    from avbench.recordings.timing import Timing

    est = _fitted(b=2e-5, lower=0.0, upper=6e-5)
    r = build(est)
    x = _rate()
    fits = {"gyro": {"x": {"m": MethodFit("m", r, 1.0, 0.0)}}}
    estimate = report.Estimate(["sim"], Timing(0.01, "--fs", x.size), [SensorRecord("gyro", "rad/s", {"x": x}, {})],
                               fits)
    unit = estimate.units("gyro")["B"]
    bound = report.shown_value(r.coefficients["B"], unit, "gyro")
    assert bound.startswith("< ") and float(bound[2:]) > 0
    table, _ = report.screen_tables(estimate)["gyro"]
    assert table.loc[("x", "m"), f"B ({unit})"] == bound and bound in report.screen(estimate)
    assert f">{bound.replace('<', '&lt;')}</td>" in recording_page(estimate, {})
    row = report.tables(estimate)["gyro"].loc[("x", "m", "B")]
    assert row["status"] == "not resolved" and row["shown"] == bound and row["lower"] == 0.0
    entry = report.payload(estimate)["sensors"]["gyro"]["axes"]["x"]["methods"]["m"]["coefficients"]["B"]
    assert entry["flag"] == "not resolved" and entry["value"] is None and entry["interval_si"] == [0.0, 6e-5]
    assert entry["reason"] == REASONS["interval"] and entry["fitted_si"] == 2e-5
    v, why = filter_yaml.axis_value(r, "B")  # the value of the yaml and of every export (their one rule)
    assert v == 6e-5 and "reaches zero" in why


def _record_without(term: str | None, n: int, seed: int, b_factor: float = 1.0) -> np.ndarray:
    """A 100 Hz record of ``n`` samples of the ADIS16405 X gyro's model (white noise, flicker bias
    instability, rate random walk; no quantization) without ``term``, its B times ``b_factor``."""
    coefs = presets.get("ADIS16405_X").coefficients.to_dict()
    coefs["B"] *= b_factor
    if term is not None:
        coefs.pop(term)
    return Gyro.from_coefficients(coefs, 0.01).simulate(n, np.random.SeedSequence([55, seed]))


@pytest.mark.parametrize("method", estimators.names())
def test_no_method_calls_a_term_resolved_whose_interval_reaches_zero(method):
    """Every registered method on a short record without bias instability: each coefficient it calls
    resolved has an interval above zero or none, and each it does not resolve is written as its bound."""
    x = _record_without("B", 8192, 0)
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore")
        r = estimators.get(method).fit(x, 0.01).result()
    for c, e in r.coefficients.items():
        raw = e.estimate_interval
        if e.status == "ok":  # tested against zero: an interval above it, or evidence of the term
            assert (raw is not None and raw[0] > 0.0) or (e.evidence is not None and e.evidence.present), (c, e)
        if e.status == "no interval":  # an estimate nothing tested
            assert e.interval is None and e.evidence is None and math.isfinite(e.value), (c, e)
            assert raw is None or not math.isfinite(raw[0]), (c, e)
        if e.status == "not resolved":
            assert math.isnan(e.value) and e.estimate_or_bound()[0] == e.upper


def _share_interval(k: int, n: int, level: float = 0.99) -> tuple[float, float]:
    """The two-sided Clopper-Pearson interval at ``level`` of a share of ``k`` in ``n``."""
    a = (1 - level) / 2
    return (0.0 if k == 0 else float(beta.ppf(a, k, n - k + 1)),
            1.0 if k == n else float(beta.ppf(1 - a, k + 1, n - k)))


#: records per Monte Carlo cell: 30 min at 100 Hz each (a short record, where absent and weak terms
#: are hardest to tell apart); 100 of them tell a share of 5 % from one of 13 % (99 % Clopper-Pearson)
RECORDS, SAMPLES = 100, 180_000
#: methods whose fit of such a record costs seconds (the online filters, the exact MLE): 20 records,
#: which tell 5 % from 30 %
COSTLY, COSTLY_RECORDS = ("mle", "nekf", "nekf_multitau", "shakf", "shakf_multitau", "arma_em"), 20
#: the level of the intervals the results are built at, and of the shares' intervals (one per
#: method and record set: a 99 % interval keeps the chance of a false alarm over the registry small)
LEVEL, SHARE_LEVEL = 0.95, 0.99


def _records(method: str) -> int:
    return COSTLY_RECORDS if method in COSTLY else RECORDS


def _statuses(method: str, absent: str | None, b_factor: float = 1.0) -> dict[str, list[str]]:
    """Per coefficient, the status ``method`` gives it on each of :func:`_records` records (a fit that
    raises gives none: it calls nothing resolved, and counts in the share's denominator)."""
    out: dict[str, list[str]] = {c: [] for c in COEFFICIENTS}
    for seed in range(_records(method)):
        x = _record_without(absent, SAMPLES, seed, b_factor)
        with warnings.catch_warnings(), np.errstate(all="ignore"):
            warnings.simplefilter("ignore")
            try:
                r = estimators.get(method).fit(x, 0.01).result(LEVEL)
            except Exception:  # noqa: BLE001 - a fit that raises calls nothing resolved
                continue
        for c, e in r.coefficients.items():
            out[c].append(e.status)
    return out


#: the cells where a method's intervals of an absent term exclude zero more often than their level:
#: GMWM's log-scale intervals, the exact MLE's and the Hadamard-variance WLS's (the rule reads an
#: interval, it cannot make one hold 0); measured on these records, the share called resolved
MISCALIBRATED = {("mle", "B"): "5 of 20", ("mle", "K"): "16 of 20", ("gmwm", "B"): "21 of 100", ("gmwm", "K"): "58 of 100", ("gmwm_filtered", "K"): "13 of 100",
                 ("gmwm_despiked", "K"): "13 of 100", ("gmwm_robust", "B"): "13 of 100",
                 ("gmwm_robust", "K"): "54 of 100", ("wls_edf_hadamard", "B"): "13 of 100",
                 ("wls_edf_hadamard", "K"): "16 of 100"}


def _cells():
    for method in estimators.names():
        for absent in ("B", "K"):
            known = MISCALIBRATED.get((method, absent))
            marks = [pytest.mark.xfail(strict=True, reason=f"{method}'s interval of an absent {absent} excludes 0 "
                                                            f"on {known} records")] if known else []
            yield pytest.param(method, absent, marks=marks, id=f"{method}-{absent}")


@pytest.mark.slow
@pytest.mark.parametrize("method, absent", list(_cells()))
def test_an_absent_term_is_called_resolved_at_most_at_the_level(method, absent):
    """On records without ``absent`` (and without quantization), the share of records on which the
    method calls the absent term -- or Q -- resolved ("ok") is at most 1 - LEVEL = 5 %: the lower end
    of its Clopper-Pearson interval is at most 5 %. A method without intervals never calls a term
    resolved ("no interval")."""
    statuses = _statuses(method, absent)
    n = _records(method)
    for c in (absent, "Q"):
        k = statuses[c].count("ok")
        lo, hi = _share_interval(k, n, SHARE_LEVEL)
        print(f"{method}: {c} absent, called resolved on {k} of {n} records ({lo:.3f}-{hi:.3f})")
        assert lo <= 1 - LEVEL, f"{method}: {c} absent, called resolved on {k} of {n} records ({lo:.3f}-{hi:.3f})"


@pytest.mark.slow
@pytest.mark.parametrize("method", ["gmwm_filtered", "gmwm_despiked", "whittle_debiased"])
def test_a_bias_instability_present_is_called_resolved_more_often_than_an_absent_one(method):
    """Power: on records with the ADIS16405 X gyro's bias instability, the share of records on which B
    is called resolved is above the share without it (Clopper-Pearson intervals apart)."""
    with_b = _statuses(method, None)["B"].count("ok")
    without = _statuses(method, "B")["B"].count("ok")
    n = _records(method)
    print(f"{method}: B called resolved on {with_b} of {n} records with it, {without} of {n} without")
    assert _share_interval(with_b, n, SHARE_LEVEL)[0] > _share_interval(without, n, SHARE_LEVEL)[1], \
        (method, with_b, without)
