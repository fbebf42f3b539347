"""nnls_rel with the sensor's filter and a spectral line: ``filter="auto"``, ``lines="auto"``
(``nnls_rel_filtered``). The terms enter on evidence, the fit check stays calibrated, ``model_avar`` is the
curve fitted, and the defaults of ``nnls_rel`` are the five-term fit."""

from __future__ import annotations

import math

import numpy as np
import pytest

from avbench import estimators
from avbench.estimators.curve_fits.practitioners import shaped_design
from avbench.noise_models import (AngleRandomWalk, BiasInstability, FilteredWhiteNoise, Gyro, RateRandomWalk,
                                  Sinusoidal)


def _filtered_gyro(line=True):
    terms = [FilteredWhiteNoise(N=7e-4, tf=0.005), BiasInstability(B=1.8e-4), RateRandomWalk(K=1.2e-5)]
    if line:
        # 2 Hz: on 30 minutes the line test searches from 1.4 Hz (avbench.estimators.selection.lines)
        terms.append(Sinusoidal(A=2e-3, f0=2.0))
    return Gyro(dt=0.01, terms=terms)


def test_design_columns_are_the_exact_discrete_avs():
    dt = 0.01
    tau = dt * 2.0 ** np.arange(12)
    m = np.rint(tau / dt).astype(np.int64)
    X = shaped_design(tau, dt, "NBK", tf=0.004, f0=0.7)
    assert X.shape == (tau.size, 4)
    assert np.allclose(X[:, 0], FilteredWhiteNoise(N=1.0, tf=0.004).avar(m, dt), rtol=1e-14, atol=0)
    assert np.allclose(X[:, 3], Sinusoidal(A=1.0, f0=0.7).avar(m, dt), rtol=1e-14, atol=0)
    # a filter far faster than dt is white noise: N's five-term column N^2 / tau
    assert np.allclose(shaped_design(tau, dt, "N", tf=dt / 1000)[:, 0], 1 / tau, rtol=1e-9)


def test_defaults_are_the_five_term_fit():
    g = _filtered_gyro()
    x = g.simulate(60_000, np.random.default_rng(3))
    plain = estimators.get("nnls_rel").fit(x, g.dt)
    assert plain.get_params()["filter"] == "none" and plain.get_params()["lines"] == "none"
    d = plain.diagnostics_
    assert "filter_test" not in d and "line_test" not in d and "params" not in d
    # model_avar is the five-term curve of the coefficients
    from avbench.estimators.allan.model import model_avar

    tau = d["tau"]
    c = {k: float(v) for k, v in plain.coefficients_.items() if np.isfinite(v)}
    assert np.allclose(plain.model_avar(tau), model_avar(c, tau), rtol=1e-12)


def test_filter_and_line_enter_on_evidence_and_the_fit_holds():
    # a record with the ADIS16405 gyro's filter (tf = dt / 2) and a line: the five-term fit is flagged,
    # the filtered one models both and passes; its curve is model_avar's
    g = _filtered_gyro()
    x = g.simulate(180_000, np.random.default_rng(11))
    plain = estimators.get("nnls_rel", terms="NBK").fit(x, g.dt)
    assert plain.diagnostics_["poor_fit"]
    e = estimators.get("nnls_rel_filtered", terms="NBK").fit(x, g.dt)
    d = e.diagnostics_
    assert d["line_test"]["included"] and d["line_test"]["p_value"] < 1e-3
    assert d["filter_test"]["included"] and d["filter_test"]["p_without"] < 0.01
    assert abs(d["params"]["SN.f0"] / 2.0 - 1) <= 0.05 + 1e-12
    assert not d["poor_fit"], d["fit_pvalue"]
    assert d["fit_reference"] == "weighted chi2"
    assert d["fit_dof"] == d["fit_check"]["tau"].size - (3 + 1 + 2)
    assert np.allclose(e.model_avar(d["tau"]), d["fitted_avar"], rtol=1e-10)
    assert np.allclose(e.model_avar(d["fit_check"]["tau"]), d["fit_check"]["model"], rtol=1e-10)
    # N: the white noise before the filter, within 4 standard errors of its estimate from the flat part of
    # the curve (tau 0.16-0.64 s: relative SE of an AV value ~ sqrt(1 / edf), here below 1 %, times 1/2)
    assert abs(e.coefficients_["N"] / 7e-4 - 1) < 0.05
    assert 0.0025 < d["params"]["FW.tf"] < 0.01


def test_without_filter_or_line_nothing_enters():
    g = Gyro(dt=0.01, terms=[AngleRandomWalk(N=1e-3), BiasInstability(B=1e-4)])
    x = g.simulate(60_000, np.random.default_rng(5))
    e = estimators.get("nnls_rel_filtered", terms="NB").fit(x, g.dt)
    p = estimators.get("nnls_rel", terms="NB").fit(x, g.dt)
    d = e.diagnostics_
    assert not d["filter_test"]["included"] and not d["line_test"]["included"]
    assert d["params"] == {}
    np.testing.assert_array_equal(e.coefficients_.to_numpy(), p.coefficients_.to_numpy())
    assert math.isclose(d["fit_pvalue"], p.diagnostics_["fit_pvalue"], rel_tol=1e-9)  # the same check, other round-off


def test_unit_equivariance_with_the_new_terms():
    g = _filtered_gyro()
    x = g.simulate(60_000, np.random.default_rng(8))
    a = estimators.get("nnls_rel_filtered", terms="NBK").fit(x, g.dt)
    b = estimators.get("nnls_rel_filtered", terms="NBK").fit(x * (180 / math.pi), g.dt)
    assert a.diagnostics_["filter_test"]["included"] == b.diagnostics_["filter_test"]["included"]
    ca, cb = a.coefficients_.to_numpy(), b.coefficients_.to_numpy() * (math.pi / 180)
    assert np.allclose(ca, cb, rtol=1e-6, atol=1e-12 * np.nanmax(ca), equal_nan=True)
    pa, pb = a.diagnostics_["params"], b.diagnostics_["params"]
    assert pa.keys() == pb.keys()
    for k in pa:
        scale = math.pi / 180 if k == "SN.A" else 1.0
        assert math.isclose(pa[k], pb[k] * scale, rel_tol=1e-6)


@pytest.mark.parametrize("setting", [{"filter": "yes"}, {"lines": True}, {"filter": "auto", "terms": "BK"},
                                     {"filter": "fit", "terms": "QB"}])
def test_bad_settings_are_refused(setting):
    x = np.random.default_rng(0).standard_normal(4096)
    with pytest.raises(ValueError, match="filter|lines"):
        estimators.get("nnls_rel", **setting).fit(x, 0.01)


@pytest.mark.slow
def test_fit_check_calibrated_with_the_filter_and_line():
    # records that HAVE the filter and the line, fitted with both terms (filter="fit": on 65,536 samples
    # the five-term fit is seldom rejected, so "auto" would mostly leave the filter out): the flag at
    # p < 0.01 fires as binomial(R, 0.01) (99.9 % bound), and the line enters on every record
    from scipy import stats

    from avbench.studies.fit_check_calibration import flag_rates

    R = 60
    r = flag_rates("filtered+line", "nnls_rel", R, seed=2024, settings={"filter": "fit", "lines": "auto"})
    assert r["flagged"] <= stats.binom.ppf(0.999, R, 0.01), r
    assert r["included"]["line"] == R, r["included"]

def test_report_says_what_the_curve_fit_assumed():
    # avbench estimate's screen notes (recordings/report.py): the filter and the line the fit modelled, from
    # the fit's model_choice; nothing when they did not enter
    from avbench.recordings.report import model_choice_notes

    md = {"filter_test": {"included": True, "tf": 0.005, "p_without": 1e-9, "p_with": 0.2},
          "line_test": {"included": True, "f0": 0.56, "p_value": 1e-30}}
    notes = model_choice_notes(md, "gyro")
    assert "sensor filter modelled (first-order, tf = 5 ms)" in notes
    assert "spectral line at 0.56 Hz modelled" in notes
    md = {"filter_test": {"included": False, "tf": float("nan")}, "line_test": {"included": False, "f0": 3.0}}
    assert model_choice_notes(md, "gyro") == []


def test_every_other_model_choice_reaches_the_notes_in_words():
    """A choice without words of its own (a plugin's, say) is still a note: its name in words and its
    scalar parts; the first AV scale fitted is the figure's."""
    from avbench.recordings.report import model_choice_notes

    notes = model_choice_notes({"lag_window": "parzen", "band_choice": {"low": 2567.34, "high": 2558.33},
                                "min_m": 4}, "gyro")
    assert notes == ["lag window: parzen", "band choice: low 2.57e+03, high 2.56e+03"]
