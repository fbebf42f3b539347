"""One result per fit, every surface renders it: the JSON payload, the CSV, the screen, the page and the
filter yaml of ``avbench estimate`` give each coefficient the value, the interval and the status of the
fit's :class:`avbench.estimators.results.FitResult`, each in one unit per sensor; no surface reads the
JSON payload, and no module reads an estimator's ``diagnostics_`` (a read-only view built from the result)."""

from __future__ import annotations

import ast
import json
import math
import os
import re
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from avbench import estimators
from avbench.estimators.results import RESULT_ENTRIES, STATUSES, Coefficient, FitResult, build
from avbench.noise_models import AngleRandomWalk, BiasInstability, Gyro, Quantization, RateRandomWalk
from avbench.noise_models.units import COEFFICIENTS, DISPLAY_UNITS, from_si, si_units

ROOT = Path(__file__).resolve().parents[1]
#: the folders installed as subpackages of avbench other than the estimators package
OUTSIDE = ("avbench", "noise_models", "studies", "recordings", "bench")


def _reads_of_diagnostics(path: Path) -> list[int]:
    tree = ast.parse(path.read_text(), str(path))
    return [node.lineno for node in ast.walk(tree) if isinstance(node, ast.Attribute) and node.attr == "diagnostics_"]


def test_no_module_reads_diagnostics():
    """``diagnostics_`` is a view built from the result for callers of the free-form mapping: no module
    of the package reads it (results are assembled from an estimator's typed parts, its own details are
    its ``extras_``)."""
    found = [f"{p.relative_to(ROOT)}:{line}" for folder in (*OUTSIDE, "estimators")
             for p in sorted((ROOT / folder).rglob("*.py")) for line in _reads_of_diagnostics(p)]
    assert not found, "read the fit's result (Estimator.result()) or its parts_, not diagnostics_: " + ", ".join(found)


@pytest.mark.parametrize("body", ["def f(est):\n    d = est.diagnostics_\n    return d['poor_fit']\n",
                                  "def f(est):\n    return FitParts(failure=est.diagnostics_.get('failure'))\n",
                                  "def conf_int(self):\n    return dict(self.diagnostics_)\n"])
def test_the_rule_finds_a_read(tmp_path, body):
    bad = tmp_path / "m.py"
    bad.write_text(body)
    assert _reads_of_diagnostics(bad) == [2]


def _builtin_fits():
    """One fit of every built-in estimator but the slow MLE, on one record with a bias instability."""
    g = Gyro(dt=0.01, terms=[AngleRandomWalk(N=1e-3), BiasInstability(B=5e-5, tau_max=100.0), RateRandomWalk(K=1e-5)])
    x = g.simulate(8192, np.random.default_rng(8)) * 57.3
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return {m: estimators.get(m).fit(x, g.dt) for m in _BUILTIN if m not in _SLOW}


def test_diagnostics_is_a_read_only_view_of_the_result():
    """Every built-in estimator's ``diagnostics_`` says what its FitResult says under each of the result's
    entries (the fit check, parameters, standard errors, failure, unresolved bounds, model choices), adds
    only its ``extras_`` (none of them an entry of the result) and refuses to be written."""
    for m, est in _builtin_fits().items():
        r, d = est.result(), est.diagnostics_
        assert not set(est.extras_) & set(RESULT_ENTRIES), m
        assert set(d) == set(est.extras_) | (set(d) & set(RESULT_ENTRIES)) | set(r.model_choice), m
        assert d.get("poor_fit") == r.fit_check.poor_fit and d.get("failure") == r.failure, m
        assert d.get("params") == r.parameters, m
        assert d["std_err"].equals(est.std_err_), m
        for key, detail in r.model_choice.items():
            assert d[key] == detail, (m, key)
        for c, e in r.coefficients.items():
            if e.status == "not resolved" and e.reason == "record":
                assert d["unresolved"][c][0] == 0.0 and _close(d["unresolved"][c][1], e.upper), (m, c)
            else:
                assert c not in d.get("unresolved", {}), (m, c)
        with pytest.raises(TypeError):
            d["poor_fit"] = True


def test_an_extra_the_result_holds_is_refused():
    """An estimator's ``_fit`` that hands back an entry of the result among its extras (here the
    failure, which belongs in its FitParts) is refused, naming the entry."""

    class Twice(estimators.Estimator):
        def _fit(self, rate, dt):
            return {"N": 1.0}, {}, {"failure": "no", "own": 1}

    with pytest.raises(TypeError, match="failure"):
        Twice().fit(np.random.default_rng(0).normal(size=256), 0.01)


# -- no surface reads another's output ---------------------------------------------------------------------
#: the keys only the JSON payload has (:func:`avbench.recordings.report.payload`)
_JSON_KEYS = {"interval_si", "std_err_si", "fitted_si", "fitted_interval_si", "si", "si_unit", "methods"}
#: the functions that write the JSON payload: the only ones that may use its keys
_JSON_WRITERS = {("recordings/report.py", "payload"), ("recordings/report.py", "_method_entry")}


def _reads_of_the_payload(path: Path, rel: str) -> list[str]:
    """Where ``path`` calls ``payload(...)`` (but in the command that writes the JSON) or subscripts a
    key only the JSON payload has, outside the functions that write it."""
    tree = ast.parse(path.read_text(), str(path))
    found = []

    def visit(node, function):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            function = node.name
        if isinstance(node, ast.Subscript) and isinstance(node.slice, ast.Constant) and node.slice.value in _JSON_KEYS \
                and (rel, function) not in _JSON_WRITERS:
            found.append(f"{rel}:{node.lineno} [{node.slice.value!r}]")
        if isinstance(node, ast.Call):
            f = node.func
            name = f.attr if isinstance(f, ast.Attribute) else getattr(f, "id", None)
            if name in ("payload", "method_entry") and (rel, function) != ("recordings/estimate.py", "run"):
                found.append(f"{rel}:{node.lineno} {name}()")
        for child in ast.iter_child_nodes(node):
            visit(child, function)

    visit(tree, None)
    return found


def test_every_surface_renders_the_fit_result_not_the_json():
    """The screen, the CSV, the yaml, the exports, the page and the studies' rows read the fits'
    FitResults; only the JSON renderer uses the JSON's keys, and only the command that writes the JSON
    calls it."""
    found = [hit for folder in OUTSIDE for p in sorted((ROOT / folder).rglob("*.py"))
             for hit in _reads_of_the_payload(p, str(p.relative_to(ROOT)))]
    assert not found, "render the FitResult (recordings.report.Estimate), not the JSON payload: " + ", ".join(found)


def test_the_payload_rule_finds_a_read(tmp_path):
    bad = tmp_path / "m.py"
    bad.write_text("def yaml(data):\n    e = data['sensors']['gyro']\n    return e['interval_si'], payload(data)\n")
    assert _reads_of_the_payload(bad, "recordings/m.py") == ["recordings/m.py:3 ['interval_si']",
                                                             "recordings/m.py:3 payload()"]


# -- the surfaces ---------------------------------------------------------------------------------------
def _record(seed, unit, n, quantized):
    rng = np.random.default_rng(seed)
    terms = [AngleRandomWalk(N=float(rng.uniform(1e-4, 1e-2))),
             BiasInstability(B=float(rng.uniform(1e-6, 1e-4)), tau_max=n * 0.01),
             RateRandomWalk(K=float(rng.uniform(1e-7, 1e-5)))]
    if quantized:
        terms.append(Quantization(Q=float(rng.uniform(1e-6, 1e-5))))
    g = Gyro(dt=0.01, terms=terms)
    return {a: g.simulate(n, rng) * unit for a in ("x", "y")}, {"x": 0.05 * g.simulate(n, rng) * unit}


def _surfaces(method, seed, unit, quantized, n=8192):
    from avbench.recordings import filter_yaml, report
    from avbench.recordings.fit import fit_axis
    from avbench.recordings.html import recording_page
    from avbench.recordings.sensors import SensorRecord
    from avbench.recordings.timing import Timing

    gyro, accel = _record(seed, unit, n, quantized)
    sensors = [SensorRecord("gyro", "rad/s", gyro, {}), SensorRecord("accel", "m/s^2", accel, {})]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with np.errstate(all="ignore"):
            fits = {s.sensor: {a: fit_axis(x, 0.01, np.zeros(0, dtype=np.int64), [method]) for a, x in s.axes.items()}
                    for s in sensors}
    est = report.Estimate(["sim"], Timing(0.01, "--fs", n), sensors, fits)
    data = json.loads(json.dumps(report.payload(est)))  # as the file holds it
    try:
        yaml = filter_yaml.filter_choices(est.results(), method)
    except ValueError:  # the method does not give N and K on every axis
        yaml = None
    return (est, data, report.tables(est), report.screen_tables(est), report.screen(est), yaml,
            _page_cells(recording_page(est, {})))


def _page_cells(page: str) -> dict:
    """(sensor, axis, method, coefficient) -> the text of the page's cell, and "header" -> its tables'
    column labels."""
    import html as html_

    cells = {}
    for attrs, text in re.findall(r"<td ([^>]*data-coef[^>]*)>(.*?)</td>", page):
        a = dict(re.findall(r'([\w-]+)="([^"]*)"', attrs))
        cells[tuple(html_.unescape(a[k]) for k in ("data-sensor", "data-axis", "data-method", "data-coef"))] = \
            html_.unescape(text)
    cells["header"] = [html_.unescape(h) for h in re.findall(r"<th>(.*?)</th>", page)]
    return cells


def _close(a, b):
    if a is None or b is None:
        return a is None and b is None
    if not (math.isfinite(a) and math.isfinite(b)):
        return a == b or (math.isnan(a) and math.isnan(b))
    return math.isclose(a, b, rel_tol=1e-12, abs_tol=0.0)


def _in(c, v, unit, sensor):
    """SI ``v`` in ``unit``, None where it is not a finite number there."""
    if v is None or not math.isfinite(v):
        return None
    with np.errstate(over="ignore"):
        out = from_si(c, v, unit, sensor)
    return out if math.isfinite(out) else None


def _expected_cell(e: Coefficient, c, sensor, u) -> str:
    """The screen's text of one coefficient, from the FitResult alone, in unit ``u``."""

    def d(v):
        return f"{from_si(c, v, u, sensor):.3g}"

    if e.status == "not modelled":
        return "-"
    if e.status in ("non-physical", "failed"):
        return e.status
    if e.status == "not resolved":
        return f"< {d(e.interval[1])}" if e.interval is not None else "not resolved"
    if e.interval is not None:
        return f"{d(e.value)} [{d(e.interval[0])}, {d(e.interval[1])}]"
    return f"{d(e.value)} (+- {d(e.std_err)})" if math.isfinite(e.std_err) else f"{d(e.value)} (no interval)"


def _expected_yaml(fits, sensor, c):
    """The filter yaml's value for one sensor's coefficient, from the FitResults alone: per axis the
    coefficient's estimate or its bound (:meth:`Coefficient.estimate_or_bound`), the largest over the axes."""
    best = None
    for per_method in fits[sensor].values():
        (fit,) = per_method.values()
        v, _ = fit.result.coefficients[c].estimate_or_bound(fit.result.fit_check.poor_fit)
        if v is None:
            return None
        best = v if best is None else max(best, v)
    return best


#: estimators whose fit of a record costs seconds: one example each (the others: three)
_SLOW = ("mle",)
_UNITS = st.sampled_from([1.0, 180 / math.pi, 2.0**-30, 1e6])
_BUILTIN = [m for m in estimators.names() if m in estimators.base.BUILTIN]


@pytest.mark.parametrize("method", [m for m in _BUILTIN if m not in _SLOW])
@settings(max_examples=3, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**31), unit=_UNITS, quantized=st.booleans())
def test_screen_json_csv_yaml_and_page_render_the_same_result(method, seed, unit, quantized):
    _check_surfaces(method, seed, unit, quantized)


@pytest.mark.parametrize("method", _SLOW)
@settings(max_examples=1, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**31), unit=_UNITS, quantized=st.booleans())
def test_slow_estimators_render_the_same_result(method, seed, unit, quantized):
    _check_surfaces(method, seed, unit, quantized)


@pytest.mark.parametrize("unit", [1e306, 1e-300])
@pytest.mark.parametrize("method", [m for m in _BUILTIN if m not in _SLOW])
def test_a_record_at_the_ends_of_float64_renders_in_one_unit(method, unit):
    """A record of 1e306 or 1e-300 times a gyro's rad/s: on every surface each coefficient's value,
    interval, bound and evidence are in one unit, each number finite there."""
    _check_surfaces(method, 12345, unit, False, n=4096)


def _check_surfaces(method, seed, unit, quantized, n=8192):
    est, data, csv, screen_tables, screen, yaml, page = _surfaces(method, seed, unit, quantized, n)
    assert max(len(line) for line in screen.splitlines()) <= 100
    for sensor, per_axis in est.fits.items():
        table, footnotes = screen_tables[sensor]
        for note in footnotes:  # in a user's words: no Python class or attribute names
            assert not re.search(r"\b[A-Z]\w*Warning\b|\w_\[|\bdiagnostics_", note), note
        units = est.units(sensor)
        assert units in (DISPLAY_UNITS[sensor], si_units(sensor))  # one choice for the sensor
        for axis, per_method in per_axis.items():
            r = per_method[method].result
            assert isinstance(r, FitResult)
            md = data["sensors"][sensor]["axes"][axis]["methods"][method]
            assert md["poor_fit"] == r.fit_check.poor_fit
            assert set(md.get("model_choice") or {}) == set(r.model_choice)  # every choice the fit made
            for c in COEFFICIENTS:
                e = r.coefficients[c]
                u = units[c]
                assert e.status in STATUSES
                # every number of the coefficient finite in SI is finite in the unit shown
                for v in (e.value, e.std_err, *(e.interval or ()), *((e.evidence.lower, e.evidence.upper)
                                                                      if e.evidence is not None else ())):
                    assert not math.isfinite(v) or _in(c, v, u, sensor) is not None, (c, v, u)
                j = md["coefficients"][c]
                # JSON: the status, the value and the interval of the result, value and evidence in the unit
                assert j["flag"] == e.status and j["unit"] == u
                assert _close(j["si"], e.value if math.isfinite(e.value) else None)
                assert _close(j["value"], _in(c, e.value, u, sensor))
                iv = j.get("interval_si")
                assert (iv is None) == (e.interval is None)
                if iv is not None:
                    assert _close(iv[0], e.interval[0]) and _close(iv[1], e.interval[1])
                if e.status == "not resolved":
                    assert e.interval is None or e.interval[0] == 0.0
                    assert j["value"] is None and not math.isfinite(e.value)
                if e.status == "ok":  # resolved: an interval, where there is one, above zero
                    assert e.interval is None or e.interval[0] > 0.0
                if e.evidence is not None:
                    ev = j["evidence"]
                    assert _close(ev["upper"], _in(c, e.evidence.upper, u, sensor))
                    assert _close(ev["lower"], _in(c, e.evidence.lower, u, sensor))
                    assert ev["present"] or ev["reading"].endswith(f" {u}")
                # CSV: the same, in the unit
                row = csv[sensor].loc[(axis, method, c)]
                assert row["status"] == e.status and row["unit"] == u
                value = None if row["value"] is None or (isinstance(row["value"], float) and math.isnan(row["value"])) \
                    else float(row["value"])
                assert _close(value, _in(c, e.value, u, sensor))
                if e.interval is not None:
                    assert _close(float(row["lower"]), _in(c, e.interval[0], u, sensor))
                    assert _close(float(row["upper"]), _in(c, e.interval[1], u, sensor))
                # screen and page: the cell rendered from the result alone, in the column of the unit
                expected = _expected_cell(e, c, sensor, u)
                col = f"{c} ({u})"
                if col in table.columns:
                    assert table.loc[(axis, method), col] == expected
                    assert expected in screen
                    assert page[(sensor, axis, method, c)] == expected and col in page["header"]
                else:
                    assert e.status == "not modelled"
    if yaml is not None:
        from avbench.recordings.filter_yaml import KEYS

        for (sensor, c), key in KEYS.items():
            want = _expected_yaml(est.fits, sensor, c)
            assert want is not None and _close(yaml[key][0], want), (key, yaml[key], want)


def test_a_result_rescaled_divides_every_quantity_in_the_records_unit():
    rng = np.random.default_rng(5)
    x = Gyro(dt=0.01, terms=[AngleRandomWalk(N=1e-3), RateRandomWalk(K=1e-5)]).simulate(20_000, rng)
    est = estimators.get("whittle_debiased", terms="NBK").fit(x, 0.01)
    r = build(est)
    half = r.rescaled(2.0)
    for c in COEFFICIENTS:
        a, b = r.coefficients[c], half.coefficients[c]
        assert a.status == b.status
        assert _close(a.fitted / 2.0, b.fitted) and _close(a.std_err / 2.0, b.std_err)
        if a.interval is not None:
            assert _close(a.interval[1] / 2.0, b.interval[1])
        if a.evidence is not None:
            assert _close(a.evidence.upper / 2.0, b.evidence.upper)
    tau = np.array([0.01, 1.0, 10.0])
    assert np.allclose(half.model_avar(tau), r.model_avar(tau) / 4.0, rtol=1e-14)


def test_a_coefficient_refuses_an_unknown_status():
    with pytest.raises(ValueError, match="status"):
        Coefficient(name="N", status="fine")
    with pytest.raises(ValueError, match="coefficient"):
        Coefficient(name="X", status="ok")


_REAL = os.environ.get("AVBENCH_REAL_DATA")


@pytest.mark.skipif(not _REAL, reason="AVBENCH_REAL_DATA is not set: the real ADIS runs are optional")
def test_real_record_surfaces_agree():
    """The same agreement on 10 minutes of a real ADIS16405 run, the default methods, six axes."""
    from avbench.estimators.base import DEFAULT_METHODS
    from avbench.recordings import filter_yaml, report
    from avbench.recordings.fit import fit_axis
    from avbench.studies.real_runs import _records

    path = Path(_REAL)
    if not (path / "adis16405-calgary").exists():
        pytest.skip("the ADIS16405 runs are not under AVBENCH_REAL_DATA")
    from avbench.recordings.sensors import SensorRecord
    from avbench.recordings.timing import Timing

    axes: dict = {}
    for rec, sensor, axis, x, timing in _records(path):
        if rec.endswith("imu1"):
            axes.setdefault(sensor, {})[axis] = np.asarray(x[:60_000])
    sensors = [SensorRecord(s, "SI", a, {}) for s, a in axes.items()]
    fits = {s.sensor: {a: fit_axis(x, 0.01, np.zeros(0, dtype=np.int64), DEFAULT_METHODS) for a, x in s.axes.items()}
            for s in sensors}
    est = report.Estimate(["adis"], Timing(0.01, "--fs", 60_000), sensors, fits)
    screen = report.screen(est)
    assert max(len(line) for line in screen.splitlines()) <= 100
    tables = report.screen_tables(est)
    data = report.payload(est)
    for s in sensors:
        for axis in s.axes:
            for m in DEFAULT_METHODS:
                r = fits[s.sensor][axis][m].result
                for c in ("N", "B", "K"):
                    e = r.coefficients[c]
                    u = est.units(s.sensor)[c]
                    assert data["sensors"][s.sensor]["axes"][axis]["methods"][m]["coefficients"][c]["flag"] == e.status
                    assert tables[s.sensor][0].loc[(axis, m), f"{c} ({u})"] == _expected_cell(e, c, s.sensor, u)
    ch = filter_yaml.filter_choices(est.results(), DEFAULT_METHODS[0])
    from avbench.recordings.filter_yaml import KEYS

    sub = {s: {a: {DEFAULT_METHODS[0]: f[DEFAULT_METHODS[0]]} for a, f in per.items()} for s, per in fits.items()}
    for (sensor, c), key in KEYS.items():
        want = _expected_yaml(sub, sensor, c)
        if want is not None:
            assert _close(ch[key][0], want)


def test_estimate_on_a_six_axis_record_prints_within_100_columns(tmp_path, capsys):
    """``avbench estimate`` with its default methods on a 6-axis record: every printed line, the
    tables and their footnotes included, fits a 100-column terminal; the JSON it writes beside them
    says the same statuses as the table."""
    import json

    from avbench.cli import main

    rng = np.random.default_rng(11)
    g = Gyro(dt=0.01, terms=[AngleRandomWalk(N=2e-3), BiasInstability(B=5e-5, tau_max=600.0), RateRandomWalk(K=2e-5)])
    gyro = np.column_stack([g.simulate(36_000, rng) for _ in range(3)]) * 180 / math.pi  # deg/s
    accel = np.column_stack([0.02 * g.simulate(36_000, rng) for _ in range(3)]) + [0.0, 0.0, 9.80665]
    np.savez(tmp_path / "imu.npz", gyro=gyro, accel=accel)
    assert main(["estimate", str(tmp_path / "imu.npz"), "--fs", "100", "--units", "deg/s", "--accel-units", "m/s^2",
                 "--out", str(tmp_path / "o"), "--no-progress"]) == 0
    out = capsys.readouterr().out
    assert "## gyro" in out and "## accel" in out and "[1]" in out
    width = max(len(line) for line in out.splitlines())
    assert width <= 100, f"{width} columns:\n{out}"
    data = json.loads((tmp_path / "o" / "imu_coefficients.json").read_text())
    for sensor, sd in data["sensors"].items():
        assert len(sd["axes"]) == 3
        for axis, ad in sd["axes"].items():
            for method, md in ad["methods"].items():
                for c, e in md["coefficients"].items():
                    if e["flag"] == "not resolved" and e.get("interval_si"):
                        assert e["value"] is None


def test_every_model_choice_reaches_the_result_in_its_units():
    """The choices an estimator makes reach its FitResult as typed ModelChoices (Whittle's bias model and
    criteria, GMWM's line test among them), and a rescaled result converts exactly the parts each choice
    declares in the record's unit (the line's amplitude, not its frequency)."""
    g = Gyro(dt=0.01, terms=[AngleRandomWalk(N=1e-3), RateRandomWalk(K=1e-5)])
    x = g.simulate(8192, np.random.default_rng(4))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        whittle = estimators.get("whittle", bias="select").fit(x, g.dt).result()
        gmwm = estimators.get("gmwm_filtered").fit(x, g.dt).result()
    assert {"bias_model", "selection"} <= set(whittle.model_choice)
    assert set(whittle.model_choice["bias_model"]["criteria"]) == {"flicker", "gauss_markov"}
    assert {"line_test", "min_m"} <= set(gmwm.model_choice)
    line = gmwm.model_choice["line_test"]
    moved = gmwm.rescaled(1e3).model_choice["line_test"]
    assert moved["amplitude"] == pytest.approx(line["amplitude"] / 1e3, rel=1e-15)
    assert moved["f0"] == line["f0"] and moved["p_value"] == line["p_value"]
    assert whittle.rescaled(1e3).model_choice == whittle.model_choice  # no part in the record's unit
