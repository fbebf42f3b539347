"""The model choices the selection components make, each as the typed
:class:`~avbench.estimators.results.ModelChoice` a fit reports: its key, what was chosen and why, and
which parts carry the record's unit (so that a result in another unit converts them with its
coefficients: :data:`UNITS`).

>>> c = line_test({"f0": 5.0, "amplitude": 2e-3, "p_value": 1e-9, "included": True})
>>> c.key, c.converted(lambda v, p: v * 10.0 ** p).detail["amplitude"]
('line_test', 0.02)
"""

from __future__ import annotations

from avbench.estimators.results import ModelChoice

__all__ = ["UNITS", "line_test", "filter_test", "filter_held", "resonance_test", "bias_evidence", "first_scale",
           "term_weights", "bias_model", "criteria"]

_BIAS_FIT = {"B": 1, "coefficients": 1, "std_err": 1}

#: the parts in the record's unit of each choice, by key (power of the unit, or a nested spec)
UNITS = {"line_test": {"amplitude": 1}, "resonance_test": {"sigma": 1},
         "bias_evidence": {"GM": _BIAS_FIT, "FL": _BIAS_FIT}}


def _choice(key, detail) -> ModelChoice:
    return ModelChoice(key, detail, UNITS.get(key, 0))


def line_test(report: dict) -> ModelChoice:
    """The spectral-line test (:mod:`avbench.estimators.selection.lines`): the strongest line's frequency,
    amplitude (the record's unit), prominence, p-value, and whether the sinusoid entered the model."""
    return _choice("line_test", report)


def filter_test(report: dict) -> ModelChoice:
    """The sensor filter entered on evidence: the fit check's p-values without and with it, its time constant."""
    return _choice("filter_test", report)


def filter_held(tf: float) -> ModelChoice:
    """The sensor filter held at a given time constant ``tf`` (s)."""
    return _choice("filter_held", {"tf": float(tf)})


def resonance_test(report: dict) -> ModelChoice:
    """The resonance test (:mod:`avbench.estimators.selection.resonance`): the band found, its ``sigma``
    (the record's unit), the cut-offs tried, and whether the band-pass term entered."""
    return _choice("resonance_test", report)


def bias_evidence(report: dict) -> ModelChoice:
    """The evidence between a Gauss-Markov and a flicker bias instability
    (:mod:`avbench.estimators.selection.bias_model`): each model's fit (B, coefficients and standard
    errors in the record's unit), Akaike weights, the preferred model and whether the record decides."""
    return _choice("bias_evidence", report)


def first_scale(min_m: int) -> ModelChoice:
    """The first AV scale fitted, as its cluster size (:mod:`avbench.estimators.selection.scales`)."""
    return _choice("min_m", int(min_m))


def term_weights(report: dict) -> ModelChoice:
    """The Akaike weights of the models averaged over (:mod:`avbench.estimators.selection.averaging`)."""
    return _choice("term_weights", report)


def bias_model(chosen: str, criteria: dict | None = None, weights: dict | None = None) -> ModelChoice:
    """The bias-instability model fitted (``"flicker"`` or ``"gauss_markov"``, say), with each candidate's
    criterion and weight where several were weighed."""
    detail = {"chosen": chosen}
    if criteria is not None:
        detail["criteria"] = criteria
    if weights is not None:
        detail["weights"] = weights
    return _choice("bias_model", detail)


def criteria(values: dict) -> ModelChoice:
    """Each candidate model's selection criterion (its name -> value; the smallest chosen,
    :mod:`avbench.estimators.selection.elimination`)."""
    return _choice("selection", values)
