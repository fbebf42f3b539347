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
      ``dict`` of method-specific details (AV used, residuals, trajectories, divergence reports...);
  ``std_err_``
      ``pandas.Series`` like ``coefficients_``: standard errors (SI) where the method gives them
      (``diagnostics_["std_err"]``), NaN elsewhere; ``bootstrap(...)`` fills them for any method.
      ``conf_int(level=0.95, conservative=False)`` gives intervals (:mod:`estimators.uncertainty`).

Subclasses implement ``_fit(rate, dt)`` returning ``(coefficients: dict, nonphysical: dict,
diagnostics: dict)``; the base class does the input checks and packs the results. A subclass whose
settings can be validated without data may also define ``check_settings()`` (raise ``ValueError``
naming the bad setting): study configs then call it instead of trial fits on simulated records.

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
    "DEFAULT_METHODS",
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
    "data_scale_exponent",
    "DT_RANGE",
    "SAFE_SPREAD",
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
    "gmwm_despiked": "estimators.robust:GMWMDespiked",
    "gmwm_robust": "estimators.robust:GMWMRobust",
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
    "whittle": "estimators.whittle:Whittle",
}

#: The methods to run on a user's recording when none are named (``avbench estimate``): methods
#: whose default settings give physically plausible coefficients on all six ADIS16405 runs x 3 axes
#: and the MTi-G (results/real/README.md). Left out on purpose: Lv et al.'s ``ols``,
#: ``ols_trimmed`` and ``wls``, faithful to the paper and unconstrained (negative elements of beta,
#: i.e. missing B/K, and rate ramps from nothing on real records), ``gmwm_robust`` (all octaves,
#: as the papers: on a sensor that low-pass filters its output its Gauss-Markov term fits the
#: filter), the slow ``mle`` and the online filters. ``gmwm_despiked`` equals ``gmwm`` on a clean
#: record and guards against spikes (the MTi-G); ``nnls_rel`` gives the five IEEE coefficients.
DEFAULT_METHODS = ("gmwm", "gmwm_despiked", "nnls_rel")


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


#: classes loaded from an import path or an entry point, by the name they were asked for
_PLUGINS: dict[str, type["Estimator"]] = {}


def names() -> list[str]:
    """Names of all registered estimators (built-in, see :data:`BUILTIN`, and user-registered) and of
    those installed packages declare, sorted.

    Installed packages declare estimators in the entry-point group ``avbench.estimators``
    (:mod:`noise_models.plugins`); they are listed here without being imported.
    """
    from noise_models.plugins import ESTIMATOR_GROUP, entry_point_names

    return sorted(set(_REGISTRY) | set(BUILTIN) | set(entry_point_names(ESTIMATOR_GROUP)))


def estimator_class(name: str, search=None) -> type["Estimator"]:
    """The estimator class called ``name``; a clear error naming the known ones otherwise.

    ``name`` is a registry name (``"wls"``), the name of an entry point of the group
    ``avbench.estimators`` declared by an installed package, or an import path
    ``"package.module:Class"``. ``search``: a folder to look in for a plugin module that is not
    importable otherwise (see :func:`noise_models.plugins.import_module`). A plugin that cannot
    be imported is a :class:`noise_models.plugins.PluginError` (a ``ValueError``) naming the module.
    """
    from noise_models import plugins

    if not isinstance(name, str):
        raise ValueError(f"estimator name: expected a string, got {name!r}")
    if name not in _REGISTRY and name in BUILTIN:  # a built-in: its module registers it on import
        import importlib

        importlib.import_module(BUILTIN[name].partition(":")[0])
    cls = _REGISTRY.get(name) or _PLUGINS.get(name)
    if cls is not None:
        return cls
    if plugins.is_import_path(name):
        target = name
    else:
        target = plugins.entry_point_target(plugins.ESTIMATOR_GROUP, name)
        if target is None:
            raise ValueError(
                f"unknown estimator {name!r}: expected one of {', '.join(names())}, "
                "or an import path 'package.module:Class'"
            )
    cls = plugins.load_object(target, search)
    if not (isinstance(cls, type) and issubclass(cls, Estimator)):
        raise plugins.PluginError(
            f"estimator {name!r}: {target} is {cls!r}, expected a subclass of estimators.Estimator"
        )
    if "name" not in cls.__dict__:  # not registered under a name of its own
        cls.name = name
    _PLUGINS[name] = cls
    return cls


def get(name, **settings) -> "Estimator":
    """A new estimator ``name`` (see :func:`estimator_class`; or a class), configured with ``settings``.

    Unknown settings are an error naming the accepted ones.
    """
    cls = name if isinstance(name, type) and issubclass(name, Estimator) else estimator_class(name)
    accepted = cls._param_names()
    unknown = sorted(set(settings) - set(accepted))
    if unknown:
        raise ValueError(
            f"estimator {cls.name!r}: unknown setting(s) {', '.join(unknown)}; "
            f"accepted: {', '.join(accepted) or '(none)'}"
        )
    try:
        check_common_settings(settings)
    except ValueError as e:
        raise ValueError(f"estimator {cls.name!r}: {e}") from None
    return cls(**settings)


def check_common_settings(params: dict) -> None:
    """Validate the settings several estimators share, wherever they appear.

    ``terms``: a non-empty subset of QNBKR; ``taus``: "octave", "decade", "all" or a list of
    positive seconds; ``overlapping``: a bool (a string such as "maybe" is refused, not read as true).
    """
    from estimators.allan import check_taus
    from estimators.av_model import check_terms

    if "terms" in params:
        check_terms(params["terms"])
    if "taus" in params:
        check_taus(params["taus"])
    if "overlapping" in params and not isinstance(params["overlapping"], bool | np.bool_):
        raise ValueError(f"overlapping: expected true or false, got {params['overlapping']!r}")


def coefficient_series(values: dict[str, float] | None = None, dtype=float, fill=math.nan) -> pd.Series:
    """A Series indexed Q, N, B, K, R, filled from ``values`` (missing keys get ``fill``)."""
    import pandas as pd

    values = values or {}
    bad = set(values) - set(COEFFICIENTS)
    if bad:
        raise ValueError(f"unknown coefficient(s) {sorted(bad)}: expected {COEFFICIENTS}")
    return pd.Series([values.get(c, fill) for c in COEFFICIENTS], index=list(COEFFICIENTS), dtype=dtype)


#: sample intervals an estimator accepts (1 ns .. ~11.6 days): beyond them tau**2 and tau**-2 in the
#: Allan-variance model leave float64's comfortable range
DT_RANGE = (1e-9, 1e6)


def check_record(rate, dt) -> tuple[np.ndarray, float]:
    """Validate a gyro record: 1-D, finite, at least 16 samples; ``dt`` finite and in :data:`DT_RANGE`."""
    dt = check_dt(dt)
    if not DT_RANGE[0] <= dt <= DT_RANGE[1]:
        raise ValueError(
            f"dt: expected a sample interval between {DT_RANGE[0]:g} s and {DT_RANGE[1]:g} s "
            f"(a rate between {1 / DT_RANGE[1]:g} Hz and {1 / DT_RANGE[0]:g} Hz), got {dt!r} s"
        )
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
        """Fit the coefficients to a gyro record ``rate`` (rad/s) sampled every ``dt`` seconds.

        Records whose spread lies outside :data:`SAFE_SPREAD` (e.g. data in wrong units scaled by
        1e300 or 1e-200) are fitted in units of a power of two near their spread, and the
        coefficients scaled back (every coefficient is linear in the rate): the scaling is exact, so
        the estimates scale with the data instead of overflowing or underflowing to 0.
        ``diagnostics_["data_scale"]`` then gives the unit (rad/s) the other diagnostics are in.
        """
        check_common_settings(self.get_params())
        rate, dt = check_record(rate, dt)
        k = data_scale_exponent(rate)
        if k == 0:
            coefs, nonphys, diag = self._fit(rate, dt)
        else:
            factor = math.ldexp(1.0, k)
            saved = {name: getattr(self, name) for name in self._rate_settings() if getattr(self, name) is not None}
            try:
                for name, value in saved.items():
                    setattr(self, name, _scale_coefficients(name, value, 1.0 / factor))
                coefs, nonphys, diag = self._fit(np.ldexp(rate, -k), dt)
            finally:
                for name, value in saved.items():
                    setattr(self, name, value)
            coefs = {c: float(v) * factor for c, v in coefs.items()}
            diag = {**(diag or {}), "data_scale": factor}
        self._set_results(coefs, nonphys, diag)
        return self

    @classmethod
    def _rate_settings(cls) -> list[str]:
        """Settings holding coefficient values (a mapping coefficient -> SI value), which scale with the data."""
        return [n for n in cls._param_names() if n == "x0"]

    def _fit(self, rate: np.ndarray, dt: float):  # pragma: no cover - abstract
        raise NotImplementedError

    def _set_results(self, coefs: dict, nonphys: dict | None, diag: dict | None) -> None:
        c = coefficient_series(coefs)
        flags = coefficient_series(nonphys or {}, dtype=bool, fill=False)
        c[flags] = math.nan
        self.coefficients_ = c
        self.nonphysical_ = flags
        self.diagnostics_ = dict(diag or {})
        se = self.diagnostics_.get("std_err")
        se = coefficient_series({} if se is None else {k: float(v) for k, v in dict(se).items()})
        se[~np.isfinite(c)] = math.nan
        self.std_err_ = se

    # -- uncertainty (estimators.uncertainty) ------------------------------------------------------
    def _check_fitted(self):
        if not hasattr(self, "coefficients_"):
            raise ValueError(f"{type(self).__name__}: not fitted yet; call fit(rate, dt) first")

    def conf_int(self, level=0.95, conservative=False) -> pd.DataFrame:
        """Intervals for the coefficients (SI): DataFrame indexed Q..R, columns ``lower``, ``upper``.

        Log-scale normal intervals from ``std_err_`` (NaN where there is none); with
        ``conservative=True`` one-sided upper bounds holding jointly with probability ``level``
        (an overbound; lower = 0). See :mod:`estimators.uncertainty`.
        """
        from estimators.uncertainty import interval, zero_quantile

        self._check_fitted()
        upper0 = None
        zu = self.diagnostics_.get("zero_upper")
        if zu is not None and len(zu):  # e.g. whittle: the bound of a term estimated as 0
            z = zero_quantile(level, conservative, self.std_err_, self.coefficients_)
            upper0 = zu * z ** self.diagnostics_["zero_upper_power"]
        return interval(self.coefficients_, self.std_err_, level, conservative, upper_if_zero=upper0)

    def bootstrap(self, n_samples: int, dt, n_draws: int = 20, seed=0) -> "Estimator":
        """Replace ``std_err_`` by a parametric bootstrap: ``n_draws`` records of ``n_samples``
        samples simulated from the fitted coefficients with the exact generators, refitted by
        clones of this estimator (:func:`estimators.uncertainty.parametric_bootstrap`). Costs
        ``n_draws`` fits. Returns ``self``."""
        from estimators.uncertainty import parametric_bootstrap

        self._check_fitted()
        se = parametric_bootstrap(self, int(n_samples), check_dt(dt), n_draws, seed)
        se[~np.isfinite(self.coefficients_)] = math.nan
        self.std_err_ = se
        self.diagnostics_["std_err_method"] = f"parametric bootstrap, {n_draws} draws"
        return self

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


#: the spread (max - min) of a record that estimators handle in SI as it is; outside it the fit runs
#: in power-of-two scaled units (squares and fourth powers of the rate then stay inside float64)
SAFE_SPREAD = (2.0**-60, 2.0**60)


def data_scale_exponent(rate: np.ndarray) -> int:
    """0 for a record whose spread is inside :data:`SAFE_SPREAD`, else k with spread / 2**k in [0.5, 1)."""
    lo, hi = float(rate.min()), float(rate.max())
    spread = hi - lo
    if not math.isfinite(spread):  # max - min overflowed (values near the float64 limit)
        spread = max(abs(lo), abs(hi))
    if spread == 0.0 or SAFE_SPREAD[0] <= spread <= SAFE_SPREAD[1]:
        return 0
    return math.frexp(spread)[1]


def _scale_coefficients(name: str, value, factor: float):
    """A coefficient mapping (SI floats or (value, unit) pairs) multiplied by ``factor``, in SI."""
    from noise_models.units import as_si

    if not isinstance(value, dict):
        return value  # the estimator's own validation reports what is wrong with it
    return {c: as_si(c, v) * factor for c, v in value.items()}


def warn(category, message: str) -> None:
    warnings.warn(message, category, stacklevel=3)
