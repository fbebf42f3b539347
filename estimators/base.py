"""The common estimator interface and the registry of estimators by config name.

Every estimator, batch or online, follows the scikit-learn contract:

* ``__init__`` only stores its keyword arguments, unchanged (no validation, no data);
* ``get_params()`` / ``set_params(**p)`` / ``clone()`` read the settings from the signature, so one
  configured estimator can be cloned for each Monte Carlo replicate and pickled to any worker;
* ``fit(rate, dt)`` validates the record, fits, and returns ``self``; what was learned ends with an
  underscore:

  ``coefficients_``
      ``pandas.Series`` indexed ``Q, N, B, K, R`` in SI units (NaN where not modelled or where the
      fit gave no physical value);
  ``nonphysical_``
      ``pandas.Series`` of bools, same index: True where the fit produced a value without physical
      meaning (e.g. a negative element of beta in Lv et al. 2015, eq. 7); the coefficient is NaN there;
  ``diagnostics_``
      ``dict`` of method-specific details (AV used, residuals, trajectories, divergence reports...).

Subclasses implement ``_fit(rate, dt)`` returning ``(coefficients: dict, nonphysical: dict,
diagnostics: dict)``; the base class does the input checks and packs the results.

Register a subclass with the decorator ``@register("name")``; ``estimators.get(name, **settings)``
returns a new configured instance.
"""

from __future__ import annotations

import inspect
import math
import warnings
from typing import Any, ClassVar

import numpy as np

from noise_models.terms import _check_dt as check_dt
from noise_models.units import COEFFICIENTS

__all__ = [
    "Estimator",
    "register",
    "get",
    "names",
    "estimator_class",
    "AvbenchWarning",
    "DivergenceWarning",
    "IdentifiabilityWarning",
    "check_record",
    "coefficient_series",
]


class AvbenchWarning(UserWarning):
    """Base class of the warnings avbench emits."""


class DivergenceWarning(AvbenchWarning):
    """An online filter diverged (NaN, negative variance, non-positive-definite covariance)."""


class IdentifiabilityWarning(AvbenchWarning):
    """The data cannot determine the requested coefficients (e.g. one scalar measurement for many)."""


_REGISTRY: dict[str, type["Estimator"]] = {}

#: the estimators shipped with avbench: registry name -> "module:Class". Their modules are imported
#: on first use, so ``import estimators`` does not pay for scipy.optimize, statsmodels or the
#: compiled filters (a test checks that importing each module registers exactly these names).
BUILTIN: dict[str, str] = {
    "arma_em": "estimators.arma_em:ArmaEM",
    "gmwm": "estimators.gmwm:GMWM",
    "log_fit": "estimators.practitioners:LogFit",
    "mle": "estimators.mle:MLE",
    "nekf": "estimators.nekf:Nekf",
    "nekf_multitau": "estimators.nekf:NekfMultitau",
    "nnls_rel": "estimators.practitioners:NNLSRel",
    "ols": "estimators.least_squares:OLS",
    "ols_trimmed": "estimators.least_squares:TrimmedOLS",
    "shakf": "estimators.shakf:Shakf",
    "shakf_multitau": "estimators.shakf:ShakfMultitau",
    "slope_lines": "estimators.practitioners:SlopeLines",
    "wls": "estimators.least_squares:WLS",
    "wls_edf": "estimators.least_squares:EDFWeightedLS",
}


def register(name: str):
    """Class decorator: register an :class:`Estimator` subclass under ``name``."""

    def deco(cls):
        if name in _REGISTRY and _REGISTRY[name] is not cls:
            raise ValueError(f"estimator name {name!r} is already registered by {_REGISTRY[name]!r}")
        if name not in _REGISTRY and name in BUILTIN and BUILTIN[name] != f"{cls.__module__}:{cls.__qualname__}":
            raise ValueError(f"estimator name {name!r} is already registered by {BUILTIN[name]}")
        cls.name = name
        _REGISTRY[name] = cls
        return cls

    return deco


def names() -> list[str]:
    """Names of all registered estimators (built-in and user-registered), sorted."""
    return sorted(set(_REGISTRY) | set(BUILTIN))


def estimator_class(name: str) -> type["Estimator"]:
    """The class registered under ``name`` (importing its module on first use); a clear error otherwise."""
    if name not in _REGISTRY and name in BUILTIN:
        import importlib

        importlib.import_module(BUILTIN[name].partition(":")[0])  # registers it
    try:
        return _REGISTRY[name]
    except KeyError:
        raise ValueError(f"unknown estimator {name!r}: expected one of {', '.join(names())}") from None


def get(name: str, **settings) -> "Estimator":
    """A new estimator registered under ``name``, configured with ``settings``.

    Unknown settings are an error naming the accepted ones.
    """
    cls = estimator_class(name)
    accepted = cls._param_names()
    unknown = sorted(set(settings) - set(accepted))
    if unknown:
        raise ValueError(
            f"estimator {name!r}: unknown setting(s) {', '.join(unknown)}; "
            f"accepted: {', '.join(accepted) or '(none)'}"
        )
    return cls(**settings)


def coefficient_series(values: dict[str, float] | None = None, dtype=float, fill=math.nan) -> pd.Series:
    """A Series indexed Q, N, B, K, R, filled from ``values`` (missing keys get ``fill``)."""
    import pandas as pd

    values = values or {}
    bad = set(values) - set(COEFFICIENTS)
    if bad:
        raise ValueError(f"unknown coefficient(s) {sorted(bad)}: expected {COEFFICIENTS}")
    return pd.Series([values.get(c, fill) for c in COEFFICIENTS], index=list(COEFFICIENTS), dtype=dtype)


def check_record(rate, dt) -> tuple[np.ndarray, float]:
    """Validate a gyro record: 1-D, finite, at least 16 samples; ``dt`` finite and > 0."""
    dt = check_dt(dt)
    arr = np.asarray(rate)
    if arr.dtype.kind not in "iuf":
        raise ValueError(f"rate: expected numeric samples, got dtype {arr.dtype}")
    if arr.ndim != 1:
        raise ValueError(f"rate: expected a 1-D array of rate samples, got shape {arr.shape}")
    if arr.size < 16:
        raise ValueError(f"rate: expected at least 16 samples, got {arr.size}")
    arr = arr.astype(np.float64, copy=False)
    bad = ~np.isfinite(arr)
    if bad.any():
        first = int(np.flatnonzero(bad)[0])
        raise ValueError(f"rate: {int(bad.sum())} non-finite sample(s) (NaN/inf), the first at index {first}")
    return arr, dt


class Estimator:
    """Base class of all coefficient estimators (see the module docstring for the contract)."""

    name: ClassVar[str] = "?"
    #: True for estimators that can also consume a record chunk by chunk (``partial_fit``).
    online: ClassVar[bool] = False

    # -- parameters (scikit-learn style) -------------------------------------------------------
    @classmethod
    def _param_names(cls) -> list[str]:
        sig = inspect.signature(cls.__init__)
        return [
            p.name
            for p in sig.parameters.values()
            if p.name != "self" and p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)
        ]

    def get_params(self) -> dict[str, Any]:
        return {k: getattr(self, k) for k in self._param_names()}

    def set_params(self, **params) -> "Estimator":
        accepted = self._param_names()
        for k, v in params.items():
            if k not in accepted:
                raise ValueError(f"{type(self).__name__}: unknown setting {k!r}; accepted: {accepted}")
            setattr(self, k, v)
        return self

    def clone(self) -> "Estimator":
        """A new unfitted estimator with the same settings."""
        import copy

        return type(self)(**copy.deepcopy(self.get_params()))

    def __repr__(self) -> str:
        args = ", ".join(f"{k}={v!r}" for k, v in self.get_params().items())
        return f"{type(self).__name__}({args})"

    # -- fitting -------------------------------------------------------------------------------
    def fit(self, rate, dt) -> "Estimator":
        """Fit the coefficients to a gyro record ``rate`` (rad/s) sampled every ``dt`` seconds."""
        rate, dt = check_record(rate, dt)
        coefs, nonphys, diag = self._fit(rate, dt)
        self._set_results(coefs, nonphys, diag)
        return self

    def _fit(self, rate: np.ndarray, dt: float):  # pragma: no cover - abstract
        raise NotImplementedError

    def _set_results(self, coefs: dict, nonphys: dict | None, diag: dict | None) -> None:
        c = coefficient_series(coefs)
        flags = coefficient_series(nonphys or {}, dtype=bool, fill=False)
        c[flags] = math.nan
        self.coefficients_ = c
        self.nonphysical_ = flags
        self.diagnostics_ = dict(diag or {})

    # -- presentation --------------------------------------------------------------------------
    def summary(self, units: dict[str, str] | None = None) -> pd.DataFrame:
        """The fitted coefficients in SI and in ``units`` (default: the papers' units)."""
        import pandas as pd

        from noise_models.units import PAPER_UNITS, SI_UNITS, from_si

        units = units or PAPER_UNITS
        c = self.coefficients_
        return pd.DataFrame(
            {
                "SI": c,
                "SI unit": pd.Series(SI_UNITS),
                "value": pd.Series({k: from_si(k, c[k], units[k]) for k in c.index}),
                "unit": pd.Series(units),
                "nonphysical": self.nonphysical_,
            }
        ).loc[list(COEFFICIENTS)]


def warn(category, message: str) -> None:
    warnings.warn(message, category, stacklevel=3)
