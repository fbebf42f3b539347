"""The typed result of one fit: what every surface (screen, JSON, CSV, filter yaml, study rows, figures) renders.

:meth:`avbench.estimators.Estimator.result` builds a :class:`FitResult` from a fitted estimator's
coefficients and the typed parts its fit reported (:class:`FitParts`); an estimator's ``diagnostics_``
is a read-only view built from the result (:func:`diagnostics_view`) that no module reads (a test walks
them all), so the screen, the files and the studies cannot disagree about a coefficient.

Each coefficient (:class:`Coefficient`) has one **status**:

``"ok"``
    resolved: ``value`` is the estimate, and the method tested it against zero at ``level``: its
    ``interval`` at ``level`` lies above zero, or its evidence (a likelihood-ratio test) shows the term
    present (``interval`` None where it has no finite upper end);
``"no interval"``
    estimated, not tested: ``value`` is the estimate of a method that gives neither an interval nor
    evidence for it (the Allan-variance curve fits, the online filters), so nothing says whether the
    record resolves it; ``interval`` is None (``std_err`` may be finite);
``"not resolved"``
    the record does not determine it: ``value`` is NaN, ``interval`` is ``(0, upper)``, the upper
    bound the record allows (None where no bound is known), ``fitted`` keeps the fit's number and
    ``reason`` says which rule decided (:data:`REASONS`). A coefficient is not resolved when the
    estimator says so (``"record"``: the floor rule of
    :meth:`~avbench.estimators.Estimator._mark_unseen_terms`, GMWM's bounds of a term at the filter),
    when its evidence says the term is not present (``"evidence"``: likelihood-ratio test,
    ``whittle_debiased``), when it was estimated as exactly 0 (``"zero"``), or when the method's
    interval at ``level`` reaches zero (``"interval"``: its lower end is 0 or below, whatever
    estimator gave it);
``"not modelled"``
    the method's model has no such term;
``"non-physical"``
    the fit gave a value without physical meaning (a negative AV-model weight, Lv et al. 2015 eq. 7);
``"failed"``
    the fit failed (``FitResult.failure`` says why).

The status is decided in one place, :func:`build`, from what every estimator reports the same way
(its bounds, evidence, value and ``conf_int``), so that a term whose interval reaches zero reads
the same whichever estimator produced it: every surface shows and exports such a term as its
upper bound (``< upper`` on the screen and the page, the upper end in the filter files, the fit's
own number only as ``fitted``), never as an estimate (:meth:`Coefficient.estimate_or_bound`).

``estimate_interval`` is the method's own interval about ``fitted`` whatever the status (the
estimator's ``conf_int(level)`` as it gives it, an end possibly infinite): the Monte Carlo studies
score its coverage of the true value.

Units: SI (of the record as handed to ``fit``); :meth:`FitResult.rescaled` divides every quantity
that carries the record's unit by a factor, the one place where a result changes unit.

>>> import numpy as np
>>> from avbench import estimators
>>> rate = np.random.default_rng(1).normal(0.0, 1e-3, 4096)
>>> r = estimators.get("whittle_debiased", terms="NB").fit(rate, 0.01).result()
>>> r.coefficients["N"].status, r.coefficients["K"].status
('ok', 'not modelled')
>>> bool(r.coefficients["N"].interval[0] < r.coefficients["N"].value < r.coefficients["N"].interval[1])
True
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from types import MappingProxyType
from typing import Any

import numpy as np

from avbench.noise_models.units import COEFFICIENTS

__all__ = ["STATUSES", "VALUE_STATUSES", "REASONS", "BOUND_REASONS", "unresolved_reason", "jsonable", "Coefficient",
           "Evidence", "FitCheck", "ModelChoice", "Alternative", "FitParts", "FitResult", "RESULT_ENTRIES", "build",
           "diagnostics_view", "extras_of", "failed"]

#: the statuses of a coefficient (module docstring)
STATUSES = ("ok", "no interval", "not resolved", "not modelled", "non-physical", "failed")

#: the statuses whose ``value`` is the method's estimate (resolved, or given without an interval)
VALUE_STATUSES = ("ok", "no interval")

#: why a coefficient is "not resolved": the estimator's bound for what the record cannot see, the
#: term's evidence (its likelihood-ratio test does not show it), an estimate of exactly 0, or the
#: method's interval reaching zero
REASONS = {"record": "the record does not resolve it", "evidence": "its evidence does not show the term",
           "zero": "estimated as 0", "interval": "its interval reaches zero"}

#: why a filter file takes a bound and not the estimate (:meth:`Coefficient.estimate_or_bound`): the
#: :data:`REASONS` a coefficient is not resolved, or a poor fit
BOUND_REASONS = (*REASONS, "poor fit")

def _f(v) -> float:
    try:
        v = float(v)
    except (TypeError, ValueError):
        return math.nan
    return v


def _finite(v) -> bool:
    return v is not None and math.isfinite(v)


@dataclass(frozen=True)
class Evidence:
    """A term's evidence: the likelihood ratio of the model without it (``lr``), its boundary-corrected
    p-value, whether the term is present at ``1 - level``, and the term's interval ``(lower, upper)`` at
    ``level`` (SI)."""

    lr: float
    p_value: float
    present: bool
    lower: float
    upper: float
    level: float


@dataclass(frozen=True)
class Coefficient:
    """One of Q, N, B, K, R as a fit gives it (module docstring for ``status``); values in SI."""

    name: str
    status: str
    value: float = math.nan
    fitted: float = math.nan
    std_err: float = math.nan
    interval: tuple[float, float] | None = None
    estimate_interval: tuple[float, float] | None = None
    evidence: Evidence | None = None
    reason: str | None = None  # why "not resolved": a key of :data:`REASONS`

    def __post_init__(self):
        if self.name not in COEFFICIENTS:
            raise ValueError(f"coefficient: expected one of {', '.join(COEFFICIENTS)}, got {self.name!r}")
        if self.status not in STATUSES:
            raise ValueError(f"status: expected one of {', '.join(STATUSES)}, got {self.status!r}")
        if self.status == "ok" and self.interval is not None and unresolved_reason(self.value, None, self.interval):
            raise ValueError(f"{self.name}: an interval {self.interval} reaching zero is not resolved; expected "
                             "status 'not resolved' with reason 'interval' (results.build)")
        if self.status == "no interval" and self.interval is not None:
            raise ValueError(f"{self.name}: a coefficient with an interval {self.interval} is tested; expected "
                             "status 'ok' or 'not resolved' (results.build)")
        if self.status == "not resolved" and self.reason not in REASONS:
            raise ValueError(f"{self.name}: reason of a coefficient not resolved: expected one of "
                             f"{', '.join(REASONS)}, got {self.reason!r}")

    @property
    def upper(self) -> float | None:
        """The upper end of ``interval`` (None where there is none)."""
        return None if self.interval is None or not _finite(self.interval[1]) else float(self.interval[1])

    def estimate_or_bound(self, poor_fit: bool | None = False) -> tuple[float | None, str | None]:
        """What a filter file takes for this coefficient: ``(value, None)`` for an estimate (resolved, or
        "no interval": the filter files then fall back on nothing better than the method's value), and
        ``(upper end of the interval or None, why)`` otherwise, ``why`` a code of :data:`BOUND_REASONS`
        (or the status where there is no value). A value is not taken as it is where the coefficient is
        not resolved (``why``: its ``reason``; an interval reaching zero is one, :func:`build`), or where
        the fit check flags the fit (``poor_fit``, ``"poor fit"``) -- except for the noise density N,
        read at the shortest scales where hours of samples pin it (the filter yaml's module docstring,
        :mod:`avbench.recordings.filter_yaml`).

        >>> Coefficient("K", "ok", value=2.0, interval=(1.0, 3.0)).estimate_or_bound()
        (2.0, None)
        >>> Coefficient("K", "ok", value=2.0, interval=(1.0, 3.0)).estimate_or_bound(poor_fit=True)
        (3.0, 'poor fit')
        >>> Coefficient("N", "ok", value=2.0, interval=(1.0, 3.0)).estimate_or_bound(poor_fit=True)
        (2.0, None)
        >>> Coefficient("K", "not resolved", interval=(0.0, 4.0), reason="record").estimate_or_bound()
        (4.0, 'record')
        """
        if self.status == "not resolved":
            return self.upper, self.reason
        if not _finite(self.value):
            return None, self.status
        if poor_fit and self.name != "N":
            return self.upper, "poor fit"
        return float(self.value), None


@dataclass(frozen=True)
class FitCheck:
    """Whether the fitted model misses the record's statistic (:mod:`avbench.estimators.allan.fit_check`):
    ``poor_fit`` (None where the method makes no check), the chi^2-type statistic with its degrees of
    freedom and p-value, the reference distribution's name, the per-scale residuals ``(tau, z)``
    where the check is made per AV scale (None otherwise) and the check in words (``reading``)."""

    poor_fit: bool | None
    stat: float = math.nan
    dof: int | None = None
    pvalue: float = math.nan
    reference: str | None = None
    residuals: tuple[np.ndarray, np.ndarray] | None = None
    detail: dict | None = None
    reading: str | None = None  #: the check in words (:func:`avbench.estimators.allan.fit_check.reading`)


def _times(unit: float):
    """The conversion of a value of unit power ``p`` from the standardised record to the caller's unit:
    multiplied by ``unit ** p`` (the product :meth:`avbench.estimators.Estimator.fit` applies to its
    diagnostics, so that a part and its diagnostics entry hold the same number)."""
    def op(v, p):
        with np.errstate(over="ignore", invalid="ignore"):
            return v * float(np.float64(unit) ** p)
    return op


def _divided(factor: float):
    """The conversion of :meth:`FitResult.rescaled`: a value of unit power ``p`` divided by ``factor ** p``."""
    def op(v, p):
        return v / factor if p == 1 else v / factor ** p
    return op


@dataclass(frozen=True)
class ModelChoice:
    """One model choice a fit made, as the selection component that made it reports it: ``key`` names
    the choice (``"line_test"``, ``"bias_evidence"``, ...), ``detail`` is what was chosen and why (a
    JSON-able mapping, or a number), and ``units`` says which parts of ``detail`` carry the record's
    unit (part -> power of the unit, or a nested spec of the same form; 0: none), so that a result
    converts its choices with its coefficients."""

    key: str
    detail: Any
    units: Any = 0

    def __post_init__(self):
        object.__setattr__(self, "detail", jsonable(self.detail))

    def converted(self, op) -> "ModelChoice":
        """The same choice with each part named in ``units`` converted by ``op(value, power)``."""
        return replace(self, detail=_scale_parts(self.detail, self.units, op))


@dataclass(frozen=True)
class Alternative:
    """Another model the record cannot tell from the reported one: its coefficients and their standard
    errors (SI, by coefficient). The reported intervals hold each alternative's too
    (:meth:`avbench.estimators.Estimator.conf_int`)."""

    coefficients: dict[str, float]
    std_err: dict[str, float]

    def converted(self, op) -> "Alternative":
        return Alternative({c: op(v, 1) for c, v in self.coefficients.items()},
                           {c: op(v, 1) for c, v in self.std_err.items()})


@dataclass(frozen=True)
class FitParts:
    """What a fit reports besides its coefficients, typed: what an estimator's ``_fit`` returns after
    ``(coefficients, nonphysical, diagnostics)``, and from which :func:`build` assembles the
    :class:`FitResult` (with the coefficients, standard errors and intervals).

    ``fit_check`` (:class:`FitCheck`), ``evidence`` (coefficient -> :class:`Evidence`), ``unresolved``
    (coefficient -> the upper bound the record allows a term it does not resolve; NaN: none known),
    ``choices`` (:class:`ModelChoice`, in the order made), ``parameters`` (the fitted latent model's
    parameters by name), ``trajectory`` (an online filter's estimates, a DataFrame with a column per
    coefficient), ``failure`` (why the fit failed), ``alternatives`` (:class:`Alternative`: models the
    record cannot tell from the reported one, whose intervals the reported ones hold), ``zero_bounds``
    (the upper bounds an estimator gives its coefficients estimated as 0 itself: a Series of bounds (SI)
    at z = 1 and a Series of the powers of z they scale with, :func:`avbench.estimators.uncertainty.interval`),
    ``std_err`` (coefficient -> standard error, SI, where the method gives them; the estimator's
    ``std_err_``), and the optimiser's record in statsmodels' names:
    ``llf`` (the maximised log-likelihood, of the standardised record the estimator fits: the same in
    every unit of the record), ``aic``, ``bic``, ``converged`` and ``n_iter`` (None / NaN where the
    method has none)."""

    fit_check: FitCheck = field(default_factory=lambda: FitCheck(None))
    evidence: dict[str, Evidence] = field(default_factory=dict)
    unresolved: dict[str, float] = field(default_factory=dict)
    choices: tuple[ModelChoice, ...] = ()
    parameters: dict[str, float] | None = None
    trajectory: Any = None
    failure: str | None = None
    alternatives: tuple[Alternative, ...] = ()
    zero_bounds: tuple[Any, Any] | None = None
    std_err: Any = None
    llf: float = math.nan
    aic: float = math.nan
    bic: float = math.nan
    converged: bool | None = None
    n_iter: int | None = None

    def converted(self, op) -> "FitParts":
        """The parts with every quantity in the record's unit converted by ``op(value, power)``."""
        ev = {c: replace(e, lower=op(e.lower, 1), upper=op(e.upper, 1)) for c, e in self.evidence.items()}
        params = None if self.parameters is None else {
            k: (op(v, parameter_power(k)) if parameter_power(k) else v) for k, v in self.parameters.items()}
        traj = self.trajectory
        if traj is not None:
            traj = traj.copy()
            for c in COEFFICIENTS:
                if c in traj:
                    traj[c] = op(traj[c], 1)
        zb = None if self.zero_bounds is None else (op(self.zero_bounds[0], 1), self.zero_bounds[1])
        se = self.std_err
        if se is not None:
            se = op(se, 1) if hasattr(se, "index") else {c: op(v, 1) for c, v in dict(se).items()}
        return replace(self, evidence=ev, std_err=se, unresolved={c: op(v, 1) for c, v in self.unresolved.items()}, zero_bounds=zb,
                       choices=tuple(ch.converted(op) for ch in self.choices), parameters=params, trajectory=traj,
                       alternatives=tuple(a.converted(op) for a in self.alternatives))

    def times(self, unit: float) -> "FitParts":
        """The parts of a fit of the record divided by ``unit``, in the record's own unit."""
        return self if unit == 1.0 else self.converted(_times(unit))


@dataclass(frozen=True)
class FitResult:
    """One fit of one method to one record: per coefficient its :class:`Coefficient`, the fit check,
    the model choices made (:class:`ModelChoice`, each with its units), the fitted model's parameters
    by name (latent models), the optimiser's record (``llf``, ``aic``, ``bic``, ``converged``,
    ``n_iter``: :class:`FitParts`), the failure and warnings (``interval_error``: why ``conf_int``
    gave no intervals, if it raised), and ``extras``: the method's other details (the estimator's
    ``extras_``, in the unit of the record it was fitted to; documented by each estimator)."""

    method: str
    coefficients: dict[str, Coefficient]
    level: float = 0.95
    fit_check: FitCheck = field(default_factory=lambda: FitCheck(None))
    choices: tuple[ModelChoice, ...] = ()
    parameters: dict[str, float] | None = None
    trajectory: Any = None
    failure: str | None = None
    warnings: tuple[str, ...] = ()
    interval_error: str | None = None
    llf: float = math.nan
    aic: float = math.nan
    bic: float = math.nan
    converged: bool | None = None
    n_iter: int | None = None
    extras: dict = field(default_factory=dict, repr=False, compare=False)
    scale: float = 1.0
    _model: Any = field(default=None, repr=False, compare=False)

    @property
    def failed(self) -> bool:
        return self.failure is not None

    @property
    def model_choice(self) -> dict[str, Any]:
        """The model choices by key: each choice's JSON-able ``detail``."""
        return {c.key: c.detail for c in self.choices}

    def value(self, name: str) -> float:
        """The estimate of coefficient ``name`` (NaN unless its status is one of :data:`VALUE_STATUSES`)."""
        return self.coefficients[name].value

    def model_avar(self, tau) -> np.ndarray:
        """The AV of the fitted model at ``tau`` (s), in this result's unit (squared)."""
        with np.errstate(over="ignore", under="ignore"):
            return self.fitted_model_avar(tau) / np.float64(self.scale) / np.float64(self.scale)

    def fitted_model_avar(self, tau) -> np.ndarray:
        """The AV of the fitted model at ``tau`` (s) in the unit of the record as it was fitted (before
        :meth:`rescaled`: ``scale`` times this result's unit), free of the rescaling's over- and underflow."""
        if self._model is None:
            raise ValueError(f"{self.method}: no fitted model ({self.failure or 'the fit failed'})")
        return np.asarray(self._model(np.asarray(tau, dtype=float)), dtype=float)

    def rescaled(self, factor: float) -> "FitResult":
        """The same result for the record divided by ``factor`` (every quantity in the record's unit
        divided by it, AV-like ones by its square); ``factor == 1`` returns ``self``."""
        factor = float(factor)
        if factor == 1.0:
            return self

        def d(v):
            return v / factor if v is not None else None

        def iv(t):
            return None if t is None else (t[0] / factor, t[1] / factor)

        coefs = {}
        for c, e in self.coefficients.items():
            ev = e.evidence
            if ev is not None:
                ev = replace(ev, lower=ev.lower / factor, upper=ev.upper / factor)
            coefs[c] = replace(e, value=e.value / factor, fitted=e.fitted / factor, std_err=e.std_err / factor,
                               interval=iv(e.interval), estimate_interval=iv(e.estimate_interval), evidence=ev)
        parts = FitParts(choices=self.choices, parameters=self.parameters,
                         trajectory=self.trajectory).converted(_divided(factor))
        return replace(self, coefficients=coefs, parameters=parts.parameters, trajectory=parts.trajectory,
                       choices=parts.choices, scale=self.scale * factor)

    def with_warnings(self, messages) -> "FitResult":
        """The same result with ``messages`` (the warnings its fit raised) added to its own."""
        return replace(self, warnings=tuple(self.warnings) + tuple(m for m in messages if m not in self.warnings))


def parameter_power(key) -> int:
    """A latent model's parameter by its name (``"GM.sigma"``, ``"tc"``, ``"FW.tf"``): times and
    frequencies (``tc``, ``tf``, ``f0``, ``omega0``, ``T``) do not carry the rate's unit (power 0), the
    other parameters (scales: N, sigma, K, Q, B, R, A) carry it once (power 1)."""
    return 0 if str(key).rsplit(".", 1)[-1] in ("tc", "tf", "f0", "omega0", "T") else 1


def _scale_parts(value, spec, op):
    """``value`` (JSON-able) with its parts named in ``spec`` (a power of the unit, or a nested spec)
    converted by ``op(value, power)``; integers (counts) and non-numbers keep their value."""
    if spec == 0 or value is None:
        return value
    if isinstance(spec, dict):
        if not isinstance(value, dict):
            return value
        return {k: (_scale_parts(v, spec[k], op) if k in spec else v) for k, v in value.items()}
    if isinstance(value, dict):
        return {k: _scale_parts(v, spec, op) for k, v in value.items()}
    if not isinstance(value, float):
        return value
    return jsonable(op(value, spec))


def jsonable(v):
    """Plain Python (dict, list, float, int, bool, str, None) for a diagnostics entry; non-finite floats as None."""
    if isinstance(v, dict):
        return {str(k): jsonable(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [jsonable(x) for x in v]
    if isinstance(v, np.ndarray):
        return jsonable(v.tolist())
    if isinstance(v, (bool, np.bool_)):
        return bool(v)
    if isinstance(v, (int, np.integer)):
        return int(v)
    if isinstance(v, (float, np.floating)):
        return float(v) if math.isfinite(v) else None
    if v is None or isinstance(v, str):
        return v
    return str(v)


def _intervals(est, level) -> tuple[dict, str | None]:
    """``{coefficient: (lower, upper)}`` of the estimator's ``conf_int(level)`` as it gives them (a pair
    with neither end finite left out) and the error that prevented it, if any (an interval that cannot
    be computed is missing, not a failed fit)."""
    try:
        ci = est.conf_int(level)
    except Exception as e:  # noqa: BLE001 - an optional extra; never let it cost the coefficients
        return {}, f"no intervals: {type(e).__name__}: {e}"
    out = {}
    for c in ci.index:
        lo, hi = _f(ci.loc[c].iloc[0]), _f(ci.loc[c].iloc[1])
        if math.isfinite(lo) or math.isfinite(hi):
            out[c] = (lo, hi)
    return out, None


def _finite_pair(pair):
    return pair if pair is not None and math.isfinite(pair[0]) and math.isfinite(pair[1]) else None


def unresolved_reason(fitted: float, evidence: Evidence | None, interval) -> str | None:
    """Why a finite estimate ``fitted`` is not resolved -- a key of :data:`REASONS`, the first that
    holds of: its ``evidence`` says the term is not present (``"evidence"``), it is exactly 0
    (``"zero"``), its ``interval`` ``(lower, upper)`` at the result's level reaches zero, its lower end
    0 or below (``"interval"``) -- or None: resolved where the evidence or the interval tested it ("ok"),
    else estimated untested ("no interval"). The one rule every estimator's result obeys
    (:func:`build`): a term whose interval holds 0 is not told apart from its absence at that level,
    whatever the method.

    >>> unresolved_reason(2.0, None, (0.0, 5.0)), unresolved_reason(2.0, None, (1.0, 5.0))
    ('interval', None)
    >>> unresolved_reason(2.0, None, None) is None  # no interval: nothing says it reaches zero
    True
    """
    if evidence is not None and not evidence.present:
        return "evidence"
    if fitted == 0.0:
        return "zero"
    if interval is not None and _finite(interval[0]) and interval[0] <= 0.0:
        return "interval"
    return None


def _not_resolved(reason: str, upper: float, common: dict) -> Coefficient:
    """A "not resolved" coefficient: its interval ``(0, upper)`` (None where ``upper`` is not finite)."""
    return Coefficient(status="not resolved", interval=(0.0, upper) if _finite(upper) else None, reason=reason,
                       **common)


def build(est, level: float = 0.95) -> FitResult:
    """The :class:`FitResult` of the fitted estimator ``est`` at interval level ``level``: its
    ``coefficients_``, ``nonphysical_``, ``std_err_``, ``conf_int(level)`` and the typed parts its fit
    reported (``parts_``, :class:`FitParts`)."""
    est._check_fitted()
    parts: FitParts = getattr(est, "parts_", None) or FitParts()  # an estimator storing its fit without _set_results
    failure = parts.failure or None
    coefs, nonphys, se = est.coefficients_, est.nonphysical_, est.std_err_
    unresolved, evidence = parts.unresolved, parts.evidence
    intervals, interval_error = _intervals(est, level)
    out = {}
    for c in COEFFICIENTS:
        fitted = _f(coefs[c])
        s = _f(se[c]) if se is not None else math.nan
        ev = evidence.get(c)
        raw = intervals.get(c)
        ci = _finite_pair(raw)
        common = dict(name=c, fitted=fitted, std_err=s, estimate_interval=raw, evidence=ev)
        if c in unresolved:
            out[c] = _not_resolved("record", _f(unresolved[c]), common)
        elif math.isfinite(fitted):
            why = unresolved_reason(fitted, ev, raw)
            if why is None:
                tested = ev is not None or (raw is not None and _finite(raw[0]))
                out[c] = Coefficient(status="ok" if tested else "no interval", value=fitted,
                                     interval=ci if tested else None, **common)
            else:
                up = ev.upper if why == "evidence" and math.isfinite(ev.upper) else (
                    raw[1] if raw is not None else math.nan)
                out[c] = _not_resolved(why, up, common)
        elif bool(nonphys.get(c, False)):
            out[c] = Coefficient(status="non-physical", **common)
        elif failure:
            out[c] = Coefficient(status="failed", **common)
        else:
            out[c] = Coefficient(status="not modelled", **common)
    params = None if parts.parameters is None else {str(k): _f(v) for k, v in parts.parameters.items()}
    warnings = (interval_error,) if interval_error else ()
    return FitResult(interval_error=interval_error, method=getattr(est, "name", type(est).__name__), coefficients=out,
                     level=float(level), fit_check=parts.fit_check, choices=parts.choices, parameters=params,
                     trajectory=parts.trajectory, failure=str(failure) if failure else None, warnings=warnings,
                     llf=_f(parts.llf), aic=_f(parts.aic), bic=_f(parts.bic), converged=parts.converged,
                     n_iter=parts.n_iter, extras=dict(est.extras_), _model=est.model_avar)


#: the entries of an estimator's ``diagnostics_`` that its :class:`FitResult` provides
#: (:func:`diagnostics_view`); neither these nor the keys of its model choices are in its ``extras_``
RESULT_ENTRIES = ("poor_fit", "fit_stat", "fit_dof", "fit_pvalue", "fit_reference", "fit_reading", "evidence",
                  "unresolved", "params", "std_err", "failure", "trajectory", "llf", "aic", "bic", "converged",
                  "n_iter")


def extras_of(details: dict, parts: FitParts) -> dict:
    """The entries of a fit's working ``details`` that are its own (an estimator's ``extras``): those its
    result does not provide (:data:`RESULT_ENTRIES`, the keys of ``parts.choices``)."""
    held = {*RESULT_ENTRIES, *(c.key for c in parts.choices)}
    return {k: v for k, v in details.items() if k not in held}


def diagnostics_view(result: FitResult, extras: dict) -> Mapping:
    """The read-only ``diagnostics_`` of a fit, for callers of the free-form mapping: the estimator's
    own details ``extras`` (its ``extras_``) and what its ``result`` holds under the names of
    :data:`RESULT_ENTRIES`: the fit check (``poor_fit``, ``fit_stat``, ``fit_dof``, ``fit_pvalue``,
    ``fit_reference``, ``fit_reading``; where the method makes one), ``evidence`` (a DataFrame by
    coefficient: ``lr``, ``p_value``, ``lower``, ``upper``, ``present``), ``unresolved`` (coefficient ->
    ``(0, upper)``, where the record decided), ``params``, ``std_err`` (a Series by coefficient),
    ``failure`` and ``trajectory`` (where there is one), the optimiser's record (``llf``, ``aic``, ``bic``, ``converged``,
    ``n_iter``, where known) and each model choice's detail under its key. Nothing in avbench reads it:
    code reads the :class:`FitResult` (a test walks every module for it).

    >>> import numpy as np
    >>> from avbench import estimators
    >>> est = estimators.get("wls", terms="NK").fit(np.random.default_rng(2).normal(0, 1e-3, 4096), 0.01)
    >>> d = est.diagnostics_
    >>> d["poor_fit"] == est.result().fit_check.poor_fit, "allan" in d
    (True, True)
    >>> d["poor_fit"] = True
    Traceback (most recent call last):
    ...
    TypeError: 'mappingproxy' object does not support item assignment
    """
    import pandas as pd

    out = dict(extras)
    check = result.fit_check
    if check.poor_fit is not None or math.isfinite(check.stat) or check.reference is not None:
        out.update(poor_fit=check.poor_fit, fit_stat=check.stat, fit_dof=check.dof, fit_pvalue=check.pvalue,
                   fit_reference=check.reference)
        if check.reading is not None:
            out["fit_reading"] = check.reading
    coefs = result.coefficients
    evidence = {c: e.evidence for c, e in coefs.items() if e.evidence is not None}
    if evidence:
        out["evidence"] = pd.DataFrame.from_dict(
            {c: dict(lr=ev.lr, p_value=ev.p_value, lower=ev.lower, upper=ev.upper, present=ev.present)
             for c, ev in evidence.items()}, orient="index")
    unresolved = {c: (0.0, e.upper if e.upper is not None else math.nan)
                  for c, e in coefs.items() if e.status == "not resolved" and e.reason == "record"}
    if unresolved:
        out["unresolved"] = unresolved
    if result.parameters is not None:
        out["params"] = dict(result.parameters)
    out["std_err"] = pd.Series({c: e.std_err for c, e in coefs.items()}, dtype=float)
    if result.failure is not None:
        out["failure"] = result.failure
    if result.trajectory is not None:
        out["trajectory"] = result.trajectory
    for key in ("llf", "aic", "bic"):
        if math.isfinite(getattr(result, key)):
            out[key] = getattr(result, key)
    for key in ("converged", "n_iter"):
        if getattr(result, key) is not None:
            out[key] = getattr(result, key)
    out.update(result.model_choice)
    return MappingProxyType(out)


def failed(method: str, message: str, modelled=COEFFICIENTS, level: float = 0.95) -> FitResult:
    """The result of a fit that raised: every coefficient "failed" (those in ``modelled``; the others
    "not modelled"), ``failure`` the message."""
    coefs = {c: Coefficient(name=c, status="failed" if c in modelled else "not modelled") for c in COEFFICIENTS}
    return FitResult(method=method, coefficients=coefs, level=float(level), failure=str(message))
