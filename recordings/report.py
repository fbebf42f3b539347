"""Step 5a: what the fits mean, per sensor, axis and method -- the JSON payload, the CSV and the screen.

Every surface renders one object per fit, the method's :class:`avbench.estimators.results.FitResult`
(:attr:`avbench.recordings.fit.MethodFit.result`): the JSON payload (:func:`payload`) carries each
coefficient's value, its interval and its status, and the CSV (:func:`tables`) and the screen
(:func:`screen`) are drawn from the payload, so that they cannot disagree. Each coefficient has a
``flag``, its status:

* ``"ok"`` -- a value, with ``interval_si`` (the method's interval at ``level``) and ``std_err_si``
  where the method gives them;
* ``"not resolved"`` -- the record does not determine it: ``value`` is null, ``interval_si`` is
  ``[0, upper]`` (the bound the record allows; absent where none is known), ``reason`` says which rule
  decided (the estimator's bound, the term's evidence, or an estimate of exactly 0), and the fit's own
  number is in ``fitted_si`` with the method's interval about it in ``fitted_interval_si``;
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
import textwrap

import numpy as np
import pandas as pd

from avbench.estimators.results import REASONS
from avbench.estimators.results import jsonable as _jsonable
from avbench.noise_models.units import COEFFICIENTS, DISPLAY_UNITS, TERM_NAMES, from_si, si_units

__all__ = ["coefficient_flags", "poor_fit", "payload", "method_entry", "tables", "screen", "screen_tables",
           "shown_value", "shown_interval", "wrap", "term_evidence", "model_choice_notes", "SCHEMA", "SCREEN_WIDTH"]

SCHEMA = "avbench-estimate/2"
#: the width of every line :func:`screen` prints
SCREEN_WIDTH = 100


def _num(v):
    return float(v) if v is not None and math.isfinite(v) else None


def coefficient_flags(fit) -> dict[str, str]:
    """Each coefficient's status (``ok`` / ``not resolved`` / ``not modelled`` / ``non-physical`` /
    ``failed``) in a fit (:class:`avbench.recordings.fit.MethodFit`)."""
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


def term_evidence(fit, sensor) -> dict[str, dict]:
    """Each term's evidence where the method reports it (e.g. ``whittle_debiased``): the likelihood ratio
    of dropping the term, its boundary-corrected p-value, whether it is present, the interval's bounds
    (display units) and a one-line reading ("present, p < 1e-6" / "not resolved (p = 0.4), upper 95 %
    bound 0.31 deg/h"). Empty where the method reports none."""
    units = DISPLAY_UNITS[sensor]
    out = {}
    for c, e in fit.result.coefficients.items():
        ev = e.evidence
        if ev is None:
            continue
        up = _num(from_si(c, ev.upper, units[c], sensor))
        low = _num(from_si(c, ev.lower, units[c], sensor))
        p = _num(ev.p_value)
        if ev.present:
            reading = f"present, {_pvalue_text(p)}"
        else:
            bound = "?" if up is None else f"{up:.3g}"
            reading = f"not resolved ({_pvalue_text(p)}), upper {100 * ev.level:g} % bound {bound} {units[c]}"
        out[c] = {"lr": _num(ev.lr), "p_value": p, "present": ev.present, "lower": low, "upper": up,
                  "level": ev.level, "reading": reading}
    return out


def method_entry(fit, sensor, n_samples):
    """The JSON object of one method on one axis (``fit``: :class:`avbench.recordings.fit.MethodFit`)."""
    units = DISPLAY_UNITS[sensor]
    si = si_units(sensor)
    r = fit.result
    entry = {}
    for c, e in r.coefficients.items():
        d = {"value": _num(from_si(c, e.value, units[c], sensor)), "unit": units[c], "si": _num(e.value),
             "si_unit": si[c], "flag": e.status}
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
        entry[c] = d
    for c, ev in term_evidence(fit, sensor).items():
        entry[c]["evidence"] = ev
    check = r.fit_check
    out = {"coefficients": entry, "poor_fit": check.poor_fit, "failure": r.failure, "warnings": list(r.warnings),
           "seconds": round(float(fit.seconds), 3),
           "fitted_on": ("whole record" if fit.run is None else
                         f"longest gap-free run: samples {fit.run[0]}..{fit.run[0] + fit.run[1] - 1} "
                         f"({fit.run[1]} of {n_samples}); this method cannot skip gaps")}
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


def model_choice_notes(md: dict, sensor: str) -> list[str]:
    """Notes on the model a method chose (``md``: a method of the JSON payload): the sensor filter it
    modelled or held, a spectral line or resonance it added, and which bias-instability model the
    record favours, with the weight and the other model's B and K."""
    notes = []
    choice = md.get("model_choice") or {}
    ft = choice.get("filter_test") or {}  # nnls_rel_filtered: the sensor's filter entered on evidence
    if ft.get("included") and ft.get("tf") is not None:
        notes.append(f"sensor filter modelled (first-order, tf = {1e3 * ft['tf']:.3g} ms)")
    held = choice.get("filter_held") or {}  # GMWM's filter_tf: the sensor's filter given, not fitted
    if held.get("tf") is not None:
        notes.append(f"sensor filter held at tf = {1e3 * held['tf']:.3g} ms (filter_tf, not fitted)")
    ln = choice.get("line_test") or {}
    if ln.get("included") and ln.get("f0") is not None and "filter_test" in choice:
        notes.append(f"spectral line at {ln['f0']:.3g} Hz modelled")
    rs = choice.get("resonance_test") or {}
    if rs.get("included") and rs.get("f0") is not None:
        notes.append(f"resonance at {rs['f0']:.3g} Hz modelled")
    ev = choice.get("bias_evidence") or {}
    if ev.get("preferred") in ("GM", "FL"):
        name = {"GM": "Gauss-Markov", "FL": "flicker"}
        fitted = ev["fitted"]
        other = "FL" if fitted == "GM" else "GM"
        values = ev[other]["coefficients"]
        shown = ", ".join(f"{c} {from_si(c, values[c], DISPLAY_UNITS[sensor][c], sensor):.3g} {DISPLAY_UNITS[sensor][c]}"
                          for c in ("B", "K") if values.get(c) is not None)
        favoured = f"{name[ev['preferred']]} favoured (weight {ev['weight']:.2f}"
        if ev.get("decisive"):
            notes.append(f"B model: {favoured}, decisive); values from the {name[fitted]} fit; the {name[other]} fit: "
                         f"{shown or '?'}")
        else:
            notes.append(f"B model: {favoured}, not decisive); values from the {name[fitted]} fit, intervals "
                         f"hold the {name[other]} fit's too ({shown or '?'})")
    return notes


def payload(sources, timing, sensors, fits, extra=None) -> dict:
    """The JSON object of ``avbench estimate``.

    ``sensors``: list of :class:`~avbench.recordings.sensors.SensorRecord`; ``fits``:
    ``{sensor: {axis: {method: MethodFit}}}``.
    """
    out = {"schema": SCHEMA, "sources": [str(s) for s in sources], "timing": _jsonable(timing.to_dict()),
           "sensors": {}}
    for s in sensors:
        axes = {}
        for axis, x in s.axes.items():
            axes[axis] = {"channel": s.names.get(axis, axis), "n_samples": int(x.size),
                          "methods": {m: method_entry(f, s.sensor, x.size) for m, f in fits[s.sensor][axis].items()}}
        out["sensors"][s.sensor] = {"units_in": s.unit_in, "si_unit": s.si_unit, "terms": TERM_NAMES[s.sensor],
                                    "axes": axes}
    if extra:
        out.update(_jsonable(extra))
    return out


def _g(v) -> str:
    return f"{v:.3g}"


def shown_interval(e: dict, coefficient: str, sensor: str) -> tuple[float, float] | None:
    """The interval of one coefficient (``e``: a coefficient of the JSON payload, :func:`method_entry`)
    in its display unit: ``[0, upper]`` where the record does not resolve it, the method's interval of
    a value, None where there is none."""
    iv = e.get("interval_si")
    if iv is None or iv[0] is None or iv[1] is None:
        return None
    return (_num(from_si(coefficient, iv[0], e["unit"], sensor)), _num(from_si(coefficient, iv[1], e["unit"], sensor)))


def shown_value(e: dict, coefficient: str, sensor: str) -> str:
    """One coefficient as a user should read it, in its display unit (``e``: a coefficient of the JSON
    payload): ``value [low, high]`` with its interval; ``< upper`` where the record does not resolve it;
    ``value (+- se)`` where the method gives only a standard error; the bare value with ``(no
    interval)`` where it gives neither; ``-`` for a term the method does not model, and the status
    itself for "non-physical" / "failed" (and "not resolved" without a bound)."""
    flag = e["flag"]
    if flag == "not modelled":
        return "-"
    if flag in ("non-physical", "failed"):
        return flag
    iv = shown_interval(e, coefficient, sensor)
    if flag == "not resolved":
        return f"< {_g(iv[1])}" if iv is not None else "not resolved"
    v = e["value"]
    if iv is not None:
        return f"{_g(v)} [{_g(iv[0])}, {_g(iv[1])}]"
    se = e.get("std_err_si")
    if se is not None:
        return f"{_g(v)} (+- {_g(_num(from_si(coefficient, se, e['unit'], sensor)))})"
    return f"{_g(v)} (no interval)"


def _notes(md: dict, sensor: str) -> list[str]:
    """Every note on one method's fit of one axis, in the order a reader needs them."""
    notes = []
    if md["failure"]:
        notes.append(f"failed: {md['failure']}")
    if md["poor_fit"]:
        notes.append("POOR FIT: the model misses the AV curve beyond its intervals" +
                     (f" ({md['fit_reading']})" if md.get("fit_reading") else ""))
    elif "NOT STATIONARY" in (md.get("fit_reading") or ""):
        notes.append("fits, " + md["fit_reading"])
    for c in COEFFICIENTS:  # a bound is in its cell ("< x"); what a cell cannot say is here
        if md["coefficients"][c]["flag"] == "non-physical":
            notes.append(f"{c}: non-physical (the fit's value has no physical meaning)")
    notes.extend(model_choice_notes(md, sensor))
    if md["fitted_on"] != "whole record":
        notes.append(f"fitted on the {md['fitted_on']}")
    notes.extend(md.get("warnings") or [])
    return notes


def tables(data: dict) -> dict[str, pd.DataFrame]:
    """One long table per sensor (the CSV of ``avbench estimate``): rows (axis, method, coefficient),
    columns the value, the interval and the status as the JSON gives them (display units), the unit,
    the fit's own number and the fit's verdicts."""
    out = {}
    for sensor, sd in data["sensors"].items():
        rows, index = [], []
        for axis, ad in sd["axes"].items():
            for method, md in ad["methods"].items():
                for c in COEFFICIENTS:
                    e = md["coefficients"][c]
                    iv = shown_interval(e, c, sensor) or (None, None)
                    fitted = e.get("fitted_si", e["si"])
                    rows.append({"value": e["value"], "lower": iv[0], "upper": iv[1], "status": e["flag"],
                                 "unit": e["unit"], "shown": shown_value(e, c, sensor),
                                 "fitted": None if fitted is None else _num(from_si(c, fitted, e["unit"], sensor)),
                                 "poor_fit": md["poor_fit"], "failure": md["failure"]})
                    index.append((axis, method, c))
        out[sensor] = pd.DataFrame(rows, index=pd.MultiIndex.from_tuples(index, names=["axis", "method", "coefficient"]))
    return out


def screen_tables(data: dict) -> dict[str, tuple[pd.DataFrame, list[str]]]:
    """Per sensor, the table :func:`screen` prints -- rows (axis, method), a column per coefficient some
    method models (:func:`shown_value`, the unit in the column name) and ``notes``, the numbers of the
    footnotes of that row -- and the footnotes in order (each text once, whichever rows it applies to):
    a failure, a poor fit, a non-physical value, the model choices, a fit on the longest gap-free run
    only, and the warnings. Bounds are in their cells ("< x")."""
    out = {}
    for sensor, sd in data["sensors"].items():
        modelled = [c for c in COEFFICIENTS if any(md["coefficients"][c]["flag"] != "not modelled"
                                                   for ad in sd["axes"].values() for md in ad["methods"].values())]
        rows, index, footnotes = [], [], []
        for axis, ad in sd["axes"].items():
            for method, md in ad["methods"].items():
                row = {}
                for c in modelled:
                    e = md["coefficients"][c]
                    row[f"{c} ({e['unit']})"] = shown_value(e, c, sensor)
                marks = []
                for note in _notes(md, sensor):  # a note shared by several rows is printed once
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


def screen(data: dict) -> str:
    """The coefficient tables of ``avbench estimate`` as printed: per sensor a header, the table
    (:func:`screen_tables`, columns wrapped into blocks so that no line exceeds :data:`SCREEN_WIDTH`)
    and its numbered footnotes, wrapped at words."""
    lines = wrap("# each coefficient: value [95 % interval]; '< x': not resolved by this record, x its upper "
                  "95 % bound; '(+- s)': a standard error only; '-': not in the method's model; notes: the "
                  "footnotes below each table", "# ")
    for sensor, (table, footnotes) in screen_tables(data).items():
        sd = data["sensors"][sensor]
        lines.append("")
        lines += wrap(f"## {sensor} (samples in {sd['units_in']}): "
                       + ", ".join(f"{c} = {n}" for c, n in sd["terms"].items()), "#  ")
        lines += table.to_string(line_width=SCREEN_WIDTH).splitlines()
        for k, note in enumerate(footnotes, 1):
            lines += wrap(f"[{k}] {note}", " " * (len(str(k)) + 3))
    return "\n".join(lines)
