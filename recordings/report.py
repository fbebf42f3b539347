"""Step 5a: what the fits mean, per sensor, axis and method -- the screen, the CSV and the JSON payload.

Every surface renders one object per fit, the method's :class:`avbench.estimators.results.FitResult`
(:attr:`avbench.recordings.fit.MethodFit.result`), gathered with the record's facts in an
:class:`Estimate`: the screen (:func:`screen`, :func:`screen_tables`), the CSV (:func:`tables`), the
JSON payload (:func:`payload`), the filter yaml and the exports (:mod:`avbench.recordings.filter_yaml`,
:mod:`avbench.recordings.exports`), the page (:mod:`avbench.recordings.html`) -- none reads another's
output, so that they cannot disagree. Each surface shows a sensor's coefficients in the units of
:meth:`Estimate.units`, chosen once per sensor: the display units, or SI where one of the sensor's
numbers (a value, an interval's end, a standard error, an evidence bound) would overflow them (a
record of 1e306 rad/s in deg/h), so that a value and its bounds are always in one unit.

Each coefficient has a ``flag`` in the JSON, its status:

* ``"ok"`` -- resolved: a value, with ``interval_si`` (the method's interval at ``level``, above zero)
  and ``std_err_si``, or the term's evidence showing it present;
* ``"no interval"`` -- a value from a method that gives no interval and no evidence for it (the AV
  curve fits, the online filters): an estimate nothing tested against zero, ``std_err_si`` where given;
* ``"not resolved"`` -- the record does not determine it: ``value`` is null, ``interval_si`` is
  ``[0, upper]`` (the bound the record allows; absent where none is known), ``reason`` says which rule
  decided (the estimator's bound, the term's evidence, an estimate of exactly 0, or the method's
  interval reaching zero -- the same for every method,
  :func:`avbench.estimators.results.unresolved_reason`), and the fit's own number is in ``fitted_si``
  with the method's interval about it in ``fitted_interval_si``;
* ``"not modelled"`` -- the method's model has no such term;
* ``"non-physical"`` -- the fit gave a value without physical meaning (e.g. a negative AV-model
  weight); ``value`` is null;
* ``"failed"`` -- the method failed on this record (``failure`` says why).

Each method also says whether its model misses the AV curve (``poor_fit``; null when the method makes
no check), whether it was fitted on the longest gap-free run only (``fitted_on``), the model choices it
made (``model_choice``) and the warnings it raised.
"""

from __future__ import annotations

import math
import re
import textwrap
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import pandas as pd

from avbench.estimators.results import REASONS, Coefficient
from avbench.estimators.results import jsonable as _jsonable
from avbench.noise_models.units import COEFFICIENTS, DISPLAY_UNITS, TERM_NAMES, from_si, si_units

__all__ = ["Estimate", "display_units", "coefficient_flags", "poor_fit", "payload", "tables", "screen",
           "screen_tables", "shown_value", "shown_interval", "wrap", "term_evidence", "model_choice_notes",
           "fitted_on", "in_unit", "level_text", "warning_text", "SCHEMA", "SCREEN_WIDTH"]

SCHEMA = "avbench-estimate/2"
#: the width of every line :func:`screen` prints
SCREEN_WIDTH = 100


def _num(v):
    return float(v) if v is not None and math.isfinite(v) else None


def _quantities(e: Coefficient):
    """Every number of one coefficient that carries the record's unit (SI)."""
    yield from (e.value, e.fitted, e.std_err)
    for pair in (e.interval, e.estimate_interval):
        if pair is not None:
            yield from pair
    if e.evidence is not None:
        yield from (e.evidence.lower, e.evidence.upper)


def display_units(sensor: str, results) -> dict[str, str]:
    """The unit of each coefficient of ``sensor`` in which every surface shows ``results`` (FitResults
    of that sensor): the display units (:data:`~avbench.noise_models.units.DISPLAY_UNITS`), or SI for
    all of them where a number finite in SI is not finite in its display unit."""
    units = DISPLAY_UNITS[sensor]
    with np.errstate(over="ignore"):
        for r in results:
            for c, e in r.coefficients.items():
                for v in _quantities(e):
                    if v is not None and math.isfinite(v) and not math.isfinite(from_si(c, v, units[c], sensor)):
                        return dict(si_units(sensor))
    return dict(units)


@dataclass
class Estimate:
    """What ``avbench estimate`` found: the record (``sources``, its :class:`~avbench.recordings.timing.Timing`,
    its SI ``sensors``: :class:`~avbench.recordings.sensors.SensorRecord`), every fit (``fits``:
    ``{sensor: {axis: {method: MethodFit}}}``) and the record's other facts (``extra``: the reader's
    format, topic, time source and notes, the static check, the between-run checks, each JSON-able).
    Every surface renders it."""

    sources: list
    timing: object
    sensors: list
    fits: dict
    extra: dict = field(default_factory=dict)

    def results(self, method: str | None = None) -> dict:
        """``{sensor: {axis: {method: FitResult}}}`` (only ``method`` where given)."""
        return {s: {a: {m: f.result for m, f in per.items() if method is None or m == method}
                    for a, per in axes.items()} for s, axes in self.fits.items()}

    @cached_property
    def _units(self) -> dict:
        return {s: display_units(s, [f.result for per in axes.values() for f in per.values()])
                for s, axes in self.fits.items()}

    def units(self, sensor: str) -> dict[str, str]:
        """The unit of each coefficient of ``sensor`` on every surface (:func:`display_units`)."""
        return self._units[sensor]

    @property
    def notes(self) -> list[str]:
        """The reader's notes, then one per sensor shown in SI because its numbers overflow the display units."""
        notes = list(self.extra.get("notes") or [])
        for s in self.fits:
            if self.units(s) != DISPLAY_UNITS[s]:
                notes.append(f"{s}: coefficients shown in SI units, as their values overflow the usual display units")
        return notes

    def record(self, sensor: str):
        """The :class:`~avbench.recordings.sensors.SensorRecord` of ``sensor``."""
        return next(s for s in self.sensors if s.sensor == sensor)


def coefficient_flags(fit) -> dict[str, str]:
    """Each coefficient's status (``ok`` / ``no interval`` / ``not resolved`` / ``not modelled`` /
    ``non-physical`` / ``failed``) in a fit (:class:`avbench.recordings.fit.MethodFit`)."""
    return {c: e.status for c, e in fit.result.coefficients.items()}


def poor_fit(fit):
    """(flag, detail): the fit check's verdict (None where the method makes no check) and its details."""
    check = fit.result.fit_check
    return check.poor_fit, check.detail


def _pvalue_text(p):
    if p is None or not math.isfinite(p):
        return "p = ?"
    if p < 1e-6:
        return "p < 1e-6"
    return f"p = {p:.2g}"


def in_unit(c: str, v, unit: str, sensor: str):
    """SI ``v`` of coefficient ``c`` in ``unit`` (None where it is not a finite number)."""
    if v is None:
        return None
    with np.errstate(over="ignore"):
        return _num(from_si(c, v, unit, sensor))


def term_evidence(e: Coefficient, unit: str, sensor: str) -> dict | None:
    """One term's evidence where the method reports it (e.g. ``whittle_debiased``), in ``unit``: the
    likelihood ratio of dropping the term, its boundary-corrected p-value, whether it is present, the
    interval's bounds and a one-line reading ("present, p < 1e-6" / "not resolved (p = 0.4), upper 95 %
    bound 0.31 deg/h"). None where the method reports none."""
    ev = e.evidence
    if ev is None:
        return None
    up, low, p = in_unit(e.name, ev.upper, unit, sensor), in_unit(e.name, ev.lower, unit, sensor), _num(ev.p_value)
    if ev.present:
        reading = f"present, {_pvalue_text(p)}"
    else:
        bound = "?" if up is None else f"{up:.3g}"
        reading = f"not resolved ({_pvalue_text(p)}), upper {100 * ev.level:g} % bound {bound} {unit}"
    return {"lr": _num(ev.lr), "p_value": p, "present": ev.present, "lower": low, "upper": up, "level": ev.level,
            "reading": reading}


def fitted_on(fit, n_samples: int) -> str:
    """Where ``fit`` (a :class:`~avbench.recordings.fit.MethodFit`) was fitted: the whole record, or its
    longest gap-free run."""
    if fit.run is None:
        return "whole record"
    return (f"longest gap-free run: samples {fit.run[0]}..{fit.run[0] + fit.run[1] - 1} ({fit.run[1]} of "
            f"{n_samples}); this method cannot skip gaps")


def _method_entry(fit, sensor, n_samples, units):
    """The JSON object of one method on one axis (``fit``: :class:`avbench.recordings.fit.MethodFit`)."""
    si = si_units(sensor)
    r = fit.result
    entry = {}
    for c, e in r.coefficients.items():
        d = {"value": in_unit(c, e.value, units[c], sensor), "unit": units[c], "si": _num(e.value), "si_unit": si[c],
             "flag": e.status}
        if math.isfinite(e.std_err):
            d["std_err_si"] = e.std_err
        if e.interval is not None:
            d["interval_si"] = [_num(v) for v in e.interval]
            d["level"] = r.level
        if e.status == "not resolved":
            d["reason"] = REASONS[e.reason]
            d["fitted_si"] = _num(e.fitted)
            if e.estimate_interval is not None:
                d["fitted_interval_si"] = [_num(v) for v in e.estimate_interval]
        ev = term_evidence(e, units[c], sensor)
        if ev is not None:
            d["evidence"] = ev
        entry[c] = d
    check = r.fit_check
    out = {"coefficients": entry, "poor_fit": check.poor_fit, "failure": r.failure, "warnings": list(r.warnings),
           "seconds": round(float(fit.seconds), 3), "fitted_on": fitted_on(fit, n_samples)}
    if check.detail is not None:
        out["poor_fit_detail"] = check.detail
    if check.poor_fit is not None:  # the chi^2-type check behind poor_fit
        out.update(fit_stat=_num(check.stat), fit_dof=check.dof, fit_pvalue=_num(check.pvalue),
                   fit_reference=check.reference)
        if check.reading:
            out["fit_reading"] = check.reading
    if r.model_choice:
        out["model_choice"] = _jsonable(r.model_choice)
    return out


_BIAS_MODELS = {"GM": "Gauss-Markov", "FL": "flicker"}
#: the model choices with notes of their own words below; ``min_m`` (the first AV scale fitted) is drawn
#: in the figure, where each model curve starts
_WORDED = ("filter_test", "filter_held", "line_test", "resonance_test", "bias_evidence", "min_m", "term_weights",
           "selection", "bias_model")
#: the bias-instability spectra a likelihood fits, by the name its ``bias_model`` choice gives
_BIAS_SPECTRA = {"flicker": "flicker (1/f)", "gauss_markov": "Gauss-Markov"}
#: the smallest model weight an averaging note names
_SHOWN_WEIGHT = 0.01


def _plain(v) -> str | None:
    """A scalar as a note shows it (numbers to 3 digits), None for what is not a scalar."""
    if isinstance(v, bool) or isinstance(v, str):
        return str(v)
    if isinstance(v, (int, float, np.integer, np.floating)):
        return f"{float(v):.3g}" if math.isfinite(v) else None
    return None


def _choice_note(key: str, value) -> str | None:
    """A model choice without words of its own: its name in words and its scalar parts (up to six)."""
    shown = _plain(value)
    if shown is None and isinstance(value, dict):
        parts = [(k, _plain(v)) for k, v in value.items()]
        parts = [f"{str(k).replace('_', ' ')} {v}" for k, v in parts if v is not None][:6]
        shown = ", ".join(parts) if parts else None
    return None if shown is None else f"{key.replace('_', ' ')}: {shown}"


def model_choice_notes(choice: dict, sensor: str, units: dict | None = None) -> list[str]:
    """Notes, in a user's words, on the model a method chose (``choice``: its
    :attr:`~avbench.estimators.results.FitResult.model_choice`; ``units``: the coefficients' units,
    default the display units): the sensor filter it modelled or held, a spectral line or resonance
    it added, and which bias-instability model the record favours, with its weight and the other
    model's B and K."""
    units = units or DISPLAY_UNITS[sensor]
    notes = []
    ft = choice.get("filter_test") or {}  # nnls_rel_filtered: the sensor's filter entered on evidence
    if ft.get("included") and ft.get("tf") is not None:
        notes.append(f"sensor filter modelled (first-order, tf = {1e3 * ft['tf']:.3g} ms)")
    held = choice.get("filter_held") or {}  # GMWM's filter_tf: the sensor's filter given, not fitted
    if held.get("tf") is not None:
        notes.append(f"sensor filter held at tf = {1e3 * held['tf']:.3g} ms (the filter_tf setting, not fitted)")
    ln = choice.get("line_test") or {}
    if ln.get("included") and ln.get("f0") is not None and "filter_test" in choice:
        notes.append(f"spectral line at {ln['f0']:.3g} Hz modelled")
    rs = choice.get("resonance_test") or {}
    if rs.get("included") and rs.get("f0") is not None:
        notes.append(f"resonance at {rs['f0']:.3g} Hz modelled")
    ev = choice.get("bias_evidence") or {}
    if ev.get("preferred") in _BIAS_MODELS:
        from avbench.estimators.selection.bias_model import held_alternative

        fitted, preferred = ev["fitted"], ev["preferred"]
        other = "FL" if fitted == "GM" else "GM"
        values = ev[other]["coefficients"]
        shown = ", ".join(f"{c} {_g(in_unit(c, values[c], units[c], sensor))} {units[c]}"
                          for c in ("B", "K") if values.get(c) is not None) or "?"
        favours = "clearly favours" if ev.get("decisive") else "does not clearly favour"
        both = "; the intervals hold both" if held_alternative(ev) is not None else ""
        if preferred == fitted:
            notes.append(f"bias instability: the record {favours} the {_BIAS_MODELS[fitted]} model these "
                         f"values come from (weight {ev['weight']:.2f}); the {_BIAS_MODELS[other]} model gives "
                         f"{shown}{both}")
        else:
            notes.append(f"bias instability: the record {favours} a {_BIAS_MODELS[preferred]} model (weight "
                         f"{ev['weight']:.2f}) over the {_BIAS_MODELS[fitted]} model these values come from; the "
                         f"{_BIAS_MODELS[preferred]} model gives {shown}{both}")
    bm = choice.get("bias_model") or {}
    bm = bm if isinstance(bm, dict) else {"chosen": bm}
    if bm.get("chosen") in _BIAS_SPECTRA:
        picked = " (the lower criterion of the two)" if len(bm.get("criteria") or {}) > 1 else ""
        notes.append(f"bias instability modelled as {_BIAS_SPECTRA[bm['chosen']]} noise{picked}")
    sel = choice.get("selection") or {}
    if isinstance(sel, dict) and len(sel) > 1:
        best = min(sel, key=sel.get)
        notes.append(f"terms kept: {best or '-'} (the lowest criterion of {len(sel)} models tried)")
    tw = choice.get("term_weights") or {}
    if tw.get("models"):
        ranked = sorted(tw["models"].items(), key=lambda kv: -kv[1])
        shown = ", ".join(f"{m} {w:.2f}" for m, w in ranked if w >= _SHOWN_WEIGHT)
        notes.append(f"estimates averaged over the models with the terms {shown} (weights; penalty "
                     f"{tw['penalty']:.3g} per parameter; intervals from the full model)")
    for key, value in choice.items():  # every other choice the method made, as it reports it
        if key not in _WORDED:
            note = _choice_note(key, value)
            if note is not None:
                notes.append(note)
    return notes


def payload(est: Estimate) -> dict:
    """The JSON object of ``avbench estimate``: the record's facts and, per sensor, axis and method, each
    coefficient as the fit's result gives it, in the units of :meth:`Estimate.units`."""
    out = {"schema": SCHEMA, "sources": [str(s) for s in est.sources], "timing": _jsonable(est.timing.to_dict()),
           "sensors": {}}
    for s in est.sensors:
        units = est.units(s.sensor)
        axes = {}
        for axis, x in s.axes.items():
            axes[axis] = {"channel": s.names.get(axis, axis), "n_samples": int(x.size),
                          "methods": {m: _method_entry(f, s.sensor, x.size, units)
                                      for m, f in est.fits[s.sensor][axis].items()}}
        out["sensors"][s.sensor] = {"units_in": s.unit_in, "si_unit": s.si_unit, "terms": TERM_NAMES[s.sensor],
                                    "axes": axes}
    if est.extra:
        out.update(_jsonable(est.extra))
    out["notes"] = est.notes
    return out


def _g(v) -> str:
    return "?" if v is None else f"{v:.3g}"


def shown_interval(e: Coefficient, unit: str, sensor: str) -> tuple[float, float] | None:
    """The interval of one coefficient in ``unit``: ``[0, upper]`` where the record does not resolve it,
    the method's interval of a value, None where there is none."""
    if e.interval is None:
        return None
    lo, hi = (in_unit(e.name, v, unit, sensor) for v in e.interval)
    return None if lo is None or hi is None else (lo, hi)


def shown_value(e: Coefficient, unit: str, sensor: str) -> str:
    """One coefficient as a user should read it, in ``unit``: ``value [low, high]`` with its interval;
    ``< upper`` where the record does not resolve it; ``value (+- se)`` where the method gives only a
    standard error; the bare value with ``(no interval)`` where it gives neither; ``-`` for a term
    the method does not model, and the status itself for "non-physical" / "failed" (and "not
    resolved" without a bound)."""
    if e.status == "not modelled":
        return "-"
    if e.status in ("non-physical", "failed"):
        return e.status
    iv = shown_interval(e, unit, sensor)
    if e.status == "not resolved":
        return f"< {_g(iv[1])}" if iv is not None else "not resolved"
    v = in_unit(e.name, e.value, unit, sensor)
    if iv is not None:
        return f"{_g(v)} [{_g(iv[0])}, {_g(iv[1])}]"
    if math.isfinite(e.std_err):
        return f"{_g(v)} (+- {_g(in_unit(e.name, e.std_err, unit, sensor))})"
    return f"{_g(v)} (no interval)"


def _notes(fit, sensor: str, n_samples: int, units: dict) -> list[str]:
    """Every note on one method's fit of one axis, in the order a reader needs them."""
    r = fit.result
    notes = []
    if r.failure:
        notes.append(f"failed: {r.failure}")
    if r.fit_check.poor_fit:
        notes.append("POOR FIT: the model misses the AV curve beyond its intervals" +
                     (f" ({r.fit_check.reading})" if r.fit_check.reading else ""))
    elif "NOT STATIONARY" in (r.fit_check.reading or ""):
        notes.append("fits, " + r.fit_check.reading)
    for c, e in r.coefficients.items():  # a bound is in its cell ("< x"); what a cell cannot say is here
        if e.status == "non-physical":
            notes.append(f"{c}: non-physical (the fit's value has no physical meaning)")
    notes.extend(model_choice_notes(r.model_choice, sensor, units))
    where = fitted_on(fit, n_samples)
    if where != "whole record":
        notes.append(f"fitted on the {where}")
    notes.extend(warning_text(w) for w in r.warnings)
    return notes


def warning_text(message: str) -> str:
    """A warning a fit raised, as a footnote says it: without the Python class it was raised as
    (``"IdentifiabilityWarning: B not resolved ..."`` -> ``"B not resolved ..."``)."""
    return re.sub(r"^[A-Za-z]*Warning: ", "", message)


def tables(est: Estimate) -> dict[str, pd.DataFrame]:
    """One long table per sensor (the CSV of ``avbench estimate``): rows (axis, method, coefficient),
    columns the value, the interval and the status (in the units of :meth:`Estimate.units`), the unit,
    the fit's own number and the fit's verdicts."""
    out = {}
    for sensor, axes in est.fits.items():
        units = est.units(sensor)
        rows, index = [], []
        for axis, per_method in axes.items():
            for method, fit in per_method.items():
                r = fit.result
                for c in COEFFICIENTS:
                    e = r.coefficients[c]
                    iv = shown_interval(e, units[c], sensor) or (None, None)
                    fitted = e.fitted if e.status == "not resolved" else e.value
                    rows.append({"value": in_unit(c, e.value, units[c], sensor), "lower": iv[0], "upper": iv[1],
                                 "status": e.status, "unit": units[c], "shown": shown_value(e, units[c], sensor),
                                 "fitted": in_unit(c, fitted, units[c], sensor), "poor_fit": r.fit_check.poor_fit,
                                 "failure": r.failure})
                    index.append((axis, method, c))
        out[sensor] = pd.DataFrame(rows, index=pd.MultiIndex.from_tuples(index, names=["axis", "method", "coefficient"]))
    return out


def screen_tables(est: Estimate) -> dict[str, tuple[pd.DataFrame, list[str]]]:
    """Per sensor, the table :func:`screen` prints -- rows (axis, method), a column per coefficient some
    method models (:func:`shown_value`, the unit in the column name) and ``notes``, the numbers of the
    footnotes of that row -- and the footnotes in order (each text once, whichever rows it applies to):
    a failure, a poor fit, a non-physical value, the model choices, a fit on the longest gap-free run
    only, and the warnings. Bounds are in their cells ("< x")."""
    out = {}
    for sensor, axes in est.fits.items():
        units = est.units(sensor)
        n_samples = {a: int(np.asarray(x).size) for a, x in est.record(sensor).axes.items()}
        modelled = [c for c in COEFFICIENTS if any(f.result.coefficients[c].status != "not modelled"
                                                   for per in axes.values() for f in per.values())]
        rows, index, footnotes = [], [], []
        for axis, per_method in axes.items():
            for method, fit in per_method.items():
                row = {f"{c} ({units[c]})": shown_value(fit.result.coefficients[c], units[c], sensor) for c in modelled}
                marks = []
                for note in _notes(fit, sensor, n_samples[axis], units):  # a note shared by several rows is printed once
                    if note not in footnotes:
                        footnotes.append(note)
                    marks.append(str(footnotes.index(note) + 1))
                row["notes"] = ",".join(marks)
                rows.append(row)
                index.append((axis, method))
        table = pd.DataFrame(rows, index=pd.MultiIndex.from_tuples(index, names=["axis", "method"]))
        out[sensor] = (table, footnotes)
    return out


def wrap(text: str, indent: str = "") -> list[str]:
    """``text`` wrapped to :data:`SCREEN_WIDTH` at spaces (a word longer than a line is not cut)."""
    return textwrap.wrap(text, SCREEN_WIDTH, subsequent_indent=indent, break_long_words=False,
                         break_on_hyphens=False) or [""]


def level_text(est: Estimate) -> str:
    """The interval level of the fits, in per cent ("95"; "90/95" where methods differ)."""
    levels = sorted({r.level for per in est.fits.values() for axis in per.values() for r in
                     (f.result for f in axis.values())}) or [0.95]
    return "/".join(f"{100 * v:g}" for v in levels)


def screen(est: Estimate) -> str:
    """The coefficient tables of ``avbench estimate`` as printed: per sensor a header, the table
    (:func:`screen_tables`, columns wrapped into blocks so that no line exceeds :data:`SCREEN_WIDTH`)
    and its numbered footnotes, wrapped at words."""
    level = level_text(est)
    lines = wrap(f"# each coefficient: value [{level} % interval]; '< x': not resolved by this record, x its upper "
                 f"{level} % bound (its interval reaches zero, or the record does not show the term); '(+- s)': a "
                 "standard error only; '(no interval)': an estimate not tested against zero; '-': not in the "
                 "method's model; notes: the "
                 "footnotes below each table", "# ")
    for sensor, (table, footnotes) in screen_tables(est).items():
        s = est.record(sensor)
        lines.append("")
        lines += wrap(f"## {sensor} (samples in {s.unit_in}): "
                      + ", ".join(f"{c} = {n}" for c, n in TERM_NAMES[sensor].items()), "#  ")
        lines += table.to_string(line_width=SCREEN_WIDTH).splitlines()
        for k, note in enumerate(footnotes, 1):
            lines += wrap(f"[{k}] {note}", " " * (len(str(k)) + 3))
    return "\n".join(lines)
