"""Step 5a: what the fits mean, per sensor, axis and method -- the JSON payload and the screen tables.

Each coefficient carries a ``flag`` instead of an overloaded NaN:

* ``"ok"`` -- a value (with ``std_err_si`` and ``conf_int_si`` where the method gives them);
* ``"not resolved"`` -- the record does not determine it (the estimator says so, with an interval:
  ``interval_si``; ``value`` is null and the fitted value is in ``fitted_si``), e.g. GMWM's B when its
  Gauss-Markov term sits at the sensor's filter;
* ``"not modelled"`` -- the method's model has no such term;
* ``"non-physical"`` -- the fit gave a value without physical meaning (e.g. a negative AV-model
  weight); ``value`` is null;
* ``"failed"`` -- the method failed on this record (``failure`` says why).

Each method also says whether its model misses the AV curve (``poor_fit``, from the estimator's
``diagnostics_["poor_fit"]`` when it provides one; null when it does not check), whether it was fitted
on the longest gap-free run only (``fitted_on``), and the warnings it raised.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from avbench.noise_models.units import COEFFICIENTS, DISPLAY_UNITS, TERM_NAMES, from_si, si_units

__all__ = ["coefficient_flags", "poor_fit", "payload", "method_entry", "tables", "screen_tables", "shown_value",
           "shown_interval", "term_evidence",
           "zero_notes", "SCHEMA"]

SCHEMA = "avbench-estimate/1"


def _num(v):
    return float(v) if v is not None and math.isfinite(v) else None


def _jsonable(v):
    if isinstance(v, dict):
        return {str(k): _jsonable(x) for k, x in v.items()}
    if isinstance(v, list | tuple):
        return [_jsonable(x) for x in v]
    if isinstance(v, np.ndarray):
        return _jsonable(v.tolist())
    if isinstance(v, bool | np.bool_):
        return bool(v)
    if isinstance(v, int | np.integer):
        return int(v)
    if isinstance(v, float | np.floating):
        return _num(float(v))
    if v is None or isinstance(v, str):
        return v
    return str(v)


#: what an estimator reports about the model it chose (GMWM's ``diagnostics_``: the spectral line test, the
#: resonance it added or not, the evidence between a Gauss-Markov and a flicker bias instability), copied
#: into the JSON's ``model_choice`` and read in one screen note each (:func:`model_choice_notes`)
MODEL_CHOICE_KEYS = ("line_test", "resonance_test", "bias_evidence", "filter_test", "filter_held")


def model_choice_notes(md: dict, sensor: str) -> list[str]:
    """Screen notes for the model a method chose (``md``: a method of the JSON payload): a resonance
    it modelled, and which bias-instability model the record favours, with the weight and the other
    model's B."""
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


def poor_fit(fit):
    """(flag, detail): flag True/False from ``diagnostics_["poor_fit"]``, None if the method does not check."""
    est = fit.estimator
    if est is None:
        return None, None
    pf = est.diagnostics_.get("poor_fit")
    if pf is None:
        return None, None
    if isinstance(pf, dict):
        flag = pf.get("poor_fit", pf.get("flag"))
        return (bool(flag) if flag is not None else None), _jsonable(pf)
    try:
        return bool(pf), None
    except (TypeError, ValueError):
        return None, _jsonable(pf)


def coefficient_flags(fit) -> dict[str, str]:
    """``ok`` / ``not resolved`` / ``not modelled`` / ``non-physical`` / ``failed`` for each of Q, N, B, K, R
    (``not resolved``: the estimator says, in ``diagnostics_["unresolved"]``, that the record does not
    determine it, with an interval)."""
    if fit.estimator is None:
        return {c: "failed" for c in COEFFICIENTS}
    est = fit.estimator
    coefs = est.coefficients_
    nonphys = getattr(est, "nonphysical_", None)
    failed = bool(est.diagnostics_.get("failure"))
    unresolved = est.diagnostics_.get("unresolved") or {}
    out = {}
    for c in COEFFICIENTS:
        if c in unresolved:
            out[c] = "not resolved"
        elif math.isfinite(float(coefs[c])):
            out[c] = "ok"
        elif nonphys is not None and bool(nonphys.get(c, False)):
            out[c] = "non-physical"
        elif failed:
            out[c] = "failed"
        else:
            out[c] = "not modelled"
    return out


def _pvalue_text(p):
    if p is None or not math.isfinite(p):
        return "p = ?"
    if p < 1e-6:
        return "p < 1e-6"
    return f"p = {p:.2g}"


def term_evidence(fit, sensor) -> dict[str, dict]:
    """Each term's evidence where the estimator reports it (``diagnostics_["evidence"]``, e.g.
    ``whittle_debiased``): the likelihood ratio of dropping the term, its boundary-corrected p-value,
    whether it is resolved at 5 %, the interval's bounds (display units) and a one-line reading
    ("present, p < 1e-6" / "not resolved, upper 95 % bound 0.31 deg/h"). Empty otherwise."""
    est = fit.estimator
    ev = None if est is None else est.diagnostics_.get("evidence")
    if ev is None:
        return {}
    units = DISPLAY_UNITS[sensor]
    level = float(est.diagnostics_.get("evidence_level", 0.95))
    out = {}
    for c in ev.index:
        p = _num(float(ev.loc[c, "p_value"]))
        up = _num(from_si(c, float(ev.loc[c, "upper"]), units[c], sensor))
        low = _num(from_si(c, float(ev.loc[c, "lower"]), units[c], sensor))
        present = bool(ev.loc[c, "present"])
        if present:
            reading = f"present, {_pvalue_text(p)}"
        else:
            bound = "?" if up is None else f"{up:.3g}"
            reading = f"not resolved ({_pvalue_text(p)}), upper {100 * level:g} % bound {bound} {units[c]}"
        out[c] = {"lr": _num(float(ev.loc[c, "lr"])), "p_value": p, "present": present, "lower": low,
                  "upper": up, "level": level, "reading": reading}
    return out


def zero_notes(md: dict, sensor: str) -> list[str]:
    """Screen notes for a method's coefficients: every term that is not clearly present (reported
    as 0, or not resolved by its evidence) with its upper bound and evidence, so that no coefficient
    is shown as 0 without them."""
    notes = []
    for c in COEFFICIENTS:
        e = md["coefficients"][c]
        ev = e.get("evidence")
        if ev is not None and not ev["present"]:
            notes.append(f"{c}: {ev['reading']}")
        elif e["flag"] == "ok" and e["value"] == 0.0:
            ci = e.get("conf_int_si")
            up = None if ci is None or ci[1] is None else _num(from_si(c, ci[1], e["unit"], sensor))
            notes.append(f"{c}: 0, upper 95 % bound {up:.3g} {e['unit']} (no evidence reported)" if up is not None
                         else f"{c}: 0 with no interval (no evidence reported)")
    return notes


def method_entry(fit, sensor, n_samples):
    units = DISPLAY_UNITS[sensor]
    si = si_units(sensor)
    coefs = fit.coefficients()
    flags = coefficient_flags(fit)
    se = fit.std_errors() or {}
    ci = fit.intervals() or {}
    entry = {}
    for c in COEFFICIENTS:
        v = coefs[c] if flags[c] == "ok" else math.nan
        e = {"value": _num(from_si(c, v, units[c], sensor)), "unit": units[c], "si": _num(v), "si_unit": si[c],
             "flag": flags[c]}
        if c in se:
            e["std_err_si"] = se[c]
        if c in ci:
            e["conf_int_si"] = list(ci[c])
        if flags[c] == "not resolved":  # the interval the record allows, and the fitted value beside it
            e["interval_si"] = [float(v) / fit.scale for v in fit.estimator.diagnostics_["unresolved"][c]]
            e["fitted_si"] = _num(coefs[c])
        entry[c] = e
    for c, ev in term_evidence(fit, sensor).items():
        entry[c]["evidence"] = ev
    flag, detail = poor_fit(fit)
    failure = fit.error or (fit.estimator.diagnostics_.get("failure") if fit.estimator is not None else None)
    out = {"coefficients": entry, "poor_fit": flag, "failure": failure or None, "warnings": fit.warnings,
           "fitted_on": ("whole record" if fit.run is None else
                         f"longest gap-free run: samples {fit.run[0]}..{fit.run[0] + fit.run[1] - 1} "
                         f"({fit.run[1]} of {n_samples}); this method cannot skip gaps")}
    if detail is not None:
        out["poor_fit_detail"] = detail
    if fit.estimator is not None:  # the chi^2-type check behind poor_fit, where the estimator reports it
        for key in ("fit_stat", "fit_dof", "fit_pvalue", "fit_reference"):
            if key in fit.estimator.diagnostics_:
                out[key] = _jsonable(fit.estimator.diagnostics_[key])
        choice = {k: _jsonable(fit.estimator.diagnostics_[k]) for k in MODEL_CHOICE_KEYS
                  if k in fit.estimator.diagnostics_}
        for key, part, name in (("bias_evidence", "GM", "B"), ("bias_evidence", "FL", "B"),
                                ("resonance_test", None, "sigma"), ("line_test", None, "amplitude")):
            d = (choice.get(key) or {}) if part is None else (choice.get(key) or {}).get(part) or {}
            if d.get(name) is not None:  # in the unit of the record as fitted: to SI
                d[name] = _num(float(d[name]) / fit.scale)
            for table in ("coefficients", "std_err"):  # a bias model's coefficients: to SI too
                if isinstance(d.get(table), dict):
                    d[table] = {c: None if v is None else _num(float(v) / fit.scale) for c, v in d[table].items()}
        if choice:
            out["model_choice"] = choice
    return out


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


def tables(data: dict) -> dict[str, pd.DataFrame]:
    """One table per sensor: rows (axis, method), the coefficients in display units, and the flags."""
    out = {}
    for sensor, sd in data["sensors"].items():
        rows, index = [], []
        for axis, ad in sd["axes"].items():
            for method, md in ad["methods"].items():
                row = {}
                notes = []
                for c in COEFFICIENTS:
                    e = md["coefficients"][c]
                    row[f"{c} ({e['unit']})"] = e["value"] if e["value"] is not None else np.nan
                    if e["flag"] == "non-physical":
                        notes.append(f"{c} non-physical")
                    elif e["flag"] == "not resolved":
                        hi = from_si(c, e["interval_si"][1], e["unit"], sensor)
                        notes.append(f"{c} not resolved (<= {hi:.3g})")
                notes.extend(zero_notes(md, sensor))
                notes.extend(model_choice_notes(md, sensor))
                if md["failure"]:
                    notes.append("failed")
                if md["poor_fit"]:
                    notes.append("POOR FIT")
                if md["fitted_on"] != "whole record":
                    notes.append("longest run only")
                row["flags"] = "; ".join(notes)
                rows.append(row)
                index.append((axis, method))
        out[sensor] = pd.DataFrame(rows, index=pd.MultiIndex.from_tuples(index, names=["axis", "method"]))
    return out


def _g(v) -> str:
    return f"{v:.3g}"


def shown_interval(e: dict, coefficient: str, sensor: str) -> tuple[float, float] | None:
    """The interval a user reads for one coefficient (``e``: a coefficient of the JSON payload,
    :func:`method_entry`), ``(low, high)`` in its display unit, as :func:`shown_value` prints it: ``(0,
    upper)`` where the record does not resolve it (flag "not resolved", evidence that the term is not
    present, or a zero with an interval), the method's interval of a value, and None where none is shown
    (a term not modelled, a non-physical or failed fit, a value with no interval)."""
    def d(v):
        return None if v is None else _num(from_si(coefficient, v, e["unit"], sensor))

    flag = e["flag"]
    if flag == "not resolved":
        hi = d(e["interval_si"][1])
        return None if hi is None else (0.0, hi)
    if flag in ("not modelled", "non-physical", "failed"):
        return None
    ci = e.get("conf_int_si")
    lo, hi = (d(ci[0]), d(ci[1])) if ci is not None else (None, None)
    ev = e.get("evidence")
    if ev is not None and not ev["present"]:
        up = ev.get("upper") if ev.get("upper") is not None else hi
        return None if up is None else (0.0, up)
    if e["value"] == 0.0:
        return None if hi is None else (0.0, hi)
    return (lo, hi) if lo is not None and hi is not None else None


def shown_value(e: dict, coefficient: str, sensor: str, level: float = 0.95) -> str:
    """One coefficient as a user should read it, in its display unit (``e``: a coefficient of the JSON
    payload): ``value [low, high]`` with its ``level`` interval; ``< upper`` where the record does not
    resolve it (flag "not resolved", or evidence that the term is not present, or a zero with an
    interval); ``value (+- se)`` where the method gives only a standard error; the bare value with
    ``(no interval)`` where it gives neither; ``-`` for a term the method does not model, and the flag
    itself for "non-physical" / "failed". The bounds are :func:`shown_interval`'s."""
    flag = e["flag"]
    if flag == "not modelled":
        return "-"
    if flag in ("non-physical", "failed"):
        return flag
    iv = shown_interval(e, coefficient, sensor)
    if flag == "not resolved":
        return f"< {_g(iv[1])}" if iv is not None else "not resolved"
    v = e["value"]
    ev = e.get("evidence")
    absent = ev is not None and not ev["present"]
    if absent or v == 0.0:
        if iv is not None:
            return f"< {_g(iv[1])}"
        return f"{_g(v)} (not resolved)" if absent else "0 (no interval)"
    if iv is not None:
        return f"{_g(v)} [{_g(iv[0])}, {_g(iv[1])}]"
    se = e.get("std_err_si")
    if se is not None:
        return f"{_g(v)} (+- {_g(_num(from_si(coefficient, se, e['unit'], sensor)))})"
    return f"{_g(v)} (no interval)"


def screen_tables(data: dict) -> dict[str, pd.DataFrame]:
    """The tables printed by ``avbench estimate``: like :func:`tables`, each coefficient as text with
    its 95 % interval or its upper bound (:func:`shown_value`), the unit in the column name."""
    out = {}
    for sensor, table in tables(data).items():
        cells = table.copy().astype(object)
        for (axis, method) in table.index:
            md = data["sensors"][sensor]["axes"][axis]["methods"][method]
            for c in COEFFICIENTS:
                e = md["coefficients"][c]
                cells.loc[(axis, method), f"{c} ({e['unit']})"] = shown_value(e, c, sensor)
        out[sensor] = cells
    return out
