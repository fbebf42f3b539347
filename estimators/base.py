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
  ``parts_``
      what the fit reports besides its coefficients, typed (:class:`avbench.estimators.results.FitParts`);
  ``extras_``
      ``dict`` of the method's own details, none of them held by its result (AV used, residuals,
      internal states...);
  ``diagnostics_``
      a read-only mapping for callers of the free-form details: ``extras_`` and what the result holds
      under the names of :data:`avbench.estimators.results.RESULT_ENTRIES`
      (:func:`avbench.estimators.results.diagnostics_view`);
  ``std_err_``
      ``pandas.Series`` like ``coefficients_``: standard errors (SI) where the method gives them
      (``parts_.std_err``), NaN elsewhere; ``bootstrap(...)`` fills them for any method.
      ``conf_int(level=0.95, conservative=False)`` gives intervals (:mod:`avbench.estimators.uncertainty`).

``result(level=0.95)`` gives all of it as one typed :class:`avbench.estimators.results.FitResult`
(per coefficient its value, standard error, interval and status), the object every surface renders;
no code in avbench reads ``diagnostics_``.

Subclasses implement ``_fit(rate, dt)`` returning ``(coefficients: dict, nonphysical: dict,
extras: dict, parts: FitParts)`` (:class:`avbench.estimators.results.FitParts`: the fit check,
term evidence, model choices, standard errors, optimiser record, in the standardised record's unit;
``extras`` the method's own details, none of them an entry the result provides,
:data:`avbench.estimators.results.RESULT_ENTRIES`; an estimator with nothing typed to report may
return the first three); the base class does the input checks, packs
the results and keeps the parts as ``parts_``, from which ``result()`` is built. Each subclass
declares what its settings accept in ``parameter_constraints`` (:mod:`avbench.estimators.settings`),
relations between settings included, checked by ``get``, ``fit`` and study configs alike: no trial fits.

Register a subclass with the decorator ``@register("name")``; ``estimators.get(name, **settings)``
returns a new configured instance.
"""

from __future__ import annotations

import inspect
import math
import warnings
from typing import Any, ClassVar

import numpy as np

from avbench.estimators.validation import check_dt, check_not_constant, check_record
from avbench.noise_models.units import COEFFICIENTS

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
    "coefficient_series",
    "data_scale",
    "noise_level",
    "STANDARD_LEVEL",
    "DIAGNOSTIC_UNITS",
    "rescale_diagnostics",
    "UNSEEN_SHARE",
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
    "arma_em": "avbench.estimators.online.arma_em:ArmaEM",
    "gmwm": "avbench.estimators.likelihood.gmwm:GMWM",
    "gmwm_despiked": "avbench.estimators.robust.gmwm:GMWMDespiked",
    "gmwm_filtered": "avbench.estimators.likelihood.gmwm:GMWMFiltered",
    "gmwm_robust": "avbench.estimators.robust.gmwm:GMWMRobust",
    "log_fit": "avbench.estimators.curve_fits.practitioners:LogFit",
    "mle": "avbench.estimators.likelihood.mle:MLE",
    "nekf": "avbench.estimators.online.nekf:Nekf",
    "nekf_multitau": "avbench.estimators.online.nekf:NekfMultitau",
    "nnls_rel": "avbench.estimators.curve_fits.practitioners:NNLSRel",
    "nnls_rel_filtered": "avbench.estimators.curve_fits.practitioners:NNLSRelFiltered",
    "ols": "avbench.estimators.curve_fits.least_squares:OLS",
    "ols_trimmed": "avbench.estimators.curve_fits.least_squares:TrimmedOLS",
    "shakf": "avbench.estimators.online.shakf:Shakf",
    "shakf_multitau": "avbench.estimators.online.shakf:ShakfMultitau",
    "slope_lines": "avbench.estimators.curve_fits.practitioners:SlopeLines",
    "wls": "avbench.estimators.curve_fits.least_squares:WLS",
    "wls_edf": "avbench.estimators.curve_fits.least_squares:EDFWeightedLS",
    "wls_edf_hadamard": "avbench.estimators.curve_fits.hadamard:HadamardEDFWeightedLS",
    "whittle": "avbench.estimators.likelihood.whittle:Whittle",
    "whittle_debiased": "avbench.estimators.likelihood.whittle:WhittleDebiased",
}

#: The methods run on a user's recording when none are named (``avbench estimate``): methods whose
#: default settings give physically plausible coefficients on the six ADIS16405 runs and the MTi-G
#: and whose model passes the fit check on most real axes (results/real/README.md).
#: ``gmwm_filtered`` (GMWM with the sensor's low-pass filter modelled, FW+GM+RW, a spectral line and a
#: resonance entering on evidence) is first (it fills the filter yaml): its fit check (with the record's own
#: AV variances) passes on 16 of the 18 ADIS gyro axes and 16 of the 18 accelerometer axes.
#: ``gmwm_despiked`` is the same model with spikes found and left out (equal to it on a clean record).
#: Not defaults: Lv et al.'s ``ols``, ``ols_trimmed`` and ``wls`` (faithful to the paper and unconstrained:
#: negative elements of beta and rate ramps from nothing on real records); ``gmwm_robust`` (all octaves: on a
#: sensor that low-pass filters its output its Gauss-Markov term fits the filter); ``nnls_rel`` (its five-term model has
#: neither the filter nor the line: it fails the fit check on 18 of 18 gyro and 17 of 18 accelerometer
#: axes) and ``nnls_rel_filtered`` (5 of 18 pass); the slow ``mle`` and the online filters. Each is one
#: ``--method NAME`` away.
DEFAULT_METHODS = ("gmwm_filtered", "gmwm_despiked")


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
    (:mod:`avbench.noise_models.plugins`); they are listed here without being imported.
    """
    from avbench.noise_models.plugins import ESTIMATOR_GROUP, entry_point_names

    return sorted(set(_REGISTRY) | set(BUILTIN) | set(entry_point_names(ESTIMATOR_GROUP)))


def estimator_class(name: str, search=None) -> type["Estimator"]:
    """The estimator class called ``name``; a clear error naming the known ones otherwise.

    ``name`` is a registry name (``"wls"``), the name of an entry point of the group
    ``avbench.estimators`` declared by an installed package, or an import path
    ``"package.module:Class"``. ``search``: a folder to look in for a plugin module that is not
    importable otherwise (see :func:`avbench.noise_models.plugins.import_module`). A plugin that cannot
    be imported is a :class:`avbench.noise_models.plugins.PluginError` (a ``ValueError``) naming the module.
    """
    from avbench.noise_models import plugins

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
            f"estimator {name!r}: {target} is {cls!r}, expected a subclass of avbench.estimators.Estimator"
        )
    if "name" not in cls.__dict__:  # not registered under a name of its own
        cls.name = name
    _PLUGINS[name] = cls
    return cls


def get(name, **settings) -> "Estimator":
    """A new estimator ``name`` (see :func:`estimator_class`; or a class), configured with ``settings``,
    checked against its declaration (:func:`avbench.estimators.settings.validate_settings`: an unknown
    setting is an error naming the accepted ones)."""
    from avbench.estimators.settings import validate_settings

    cls = name if isinstance(name, type) and issubclass(name, Estimator) else estimator_class(name)
    validate_settings(cls, settings)
    return cls(**settings)


def coefficient_series(values: dict[str, float] | None = None, dtype=float, fill=math.nan) -> pd.Series:
    """A Series indexed Q, N, B, K, R, filled from ``values`` (missing keys get ``fill``)."""
    import pandas as pd

    values = values or {}
    bad = set(values) - set(COEFFICIENTS)
    if bad:
        raise ValueError(f"unknown coefficient(s) {sorted(bad)}: expected {COEFFICIENTS}")
    return pd.Series([values.get(c, fill) for c in COEFFICIENTS], index=list(COEFFICIENTS), dtype=dtype)


class Estimator:
    """Base class of all coefficient estimators (see the module docstring for the contract)."""

    name: ClassVar[str] = "?"
    #: True for estimators that can also consume a record chunk by chunk (``partial_fit``).
    online: ClassVar[bool] = False
    #: True for estimators that see the record only through ``allan_variance`` of the engine: on a
    #: record with gaps they are fitted to all of it, the clusters straddling a gap left out
    #: (``avbench.estimators.allan.variance.skip_gaps``); False: fitted to the longest gap-free run.
    uses_allan_variance: ClassVar[bool] = False
    #: True for estimators whose answer is an iterative optimiser's (or a nonlinear filter's) end
    #: point, where BLAS/LAPACK and the CPU's vector width change the last bits of each step and the
    #: iteration carries them beyond 1e-8 relative: a study's rows of such an estimator regenerate on
    #: another machine only to a small share of their replicate spread (tests/test_regeneration.py).
    round_off_amplified: ClassVar[bool] = False
    #: the diagnostics of this class that carry the rate's unit beyond :data:`DIAGNOSTIC_UNITS`
    #: (same form: key -> power of the unit, or a nested mapping); ``fit`` rescales them
    diagnostic_units: ClassVar[dict] = {}

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
        """Change settings, checked as ``get`` checks them (:func:`avbench.estimators.settings.validate_settings`)."""
        from avbench.estimators.settings import validate_settings

        validate_settings(type(self), {**self.get_params(), **params})
        for k, v in params.items():
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

        **Unit equivariance** (the contract every estimator keeps, checked by ``check-estimator``):
        the record is standardised before ``_fit`` sees it, divided by ``data_scale = s / STANDARD_LEVEL``
        where ``s`` is its noise level (:func:`noise_level`, the RMS of its first differences over
        sqrt 2, a statistic that scales exactly with the data). A record in deg/s and the same record
        in rad/s are therefore the same numbers, to rounding, when the estimator works on them:
        absolute tolerances, floors and starting values inside an estimator cannot make its answer
        depend on the unit it was handed. The results are scaled back to the caller's unit:
        coefficients (linear in the rate), ``std_err_``, ``conf_int``, ``model_avar``, the typed parts
        and the extras that carry the rate's unit (:data:`DIAGNOSTIC_UNITS` and the class's own
        :attr:`diagnostic_units`). The extras not listed
        there (an online filter's internal states, ``extras_["model"]``,
        the fitted :class:`~avbench.noise_models.Gyro`) are those of the standardised record, whose
        unit is ``data_scale`` (in the caller's unit). It is exactly 1 for a record already
        standardised (an estimator fitting another inside its ``_fit``) and for a constant one.
        """
        from avbench.estimators.settings import validate_settings

        validate_settings(type(self), self.get_params())
        rate, dt = check_record(rate, dt)
        check_not_constant(rate)
        # an online estimator is handed the record as it is (fit must equal partial_fit over chunks,
        # and the noise level that standardises a record is known only at its end: the online filters
        # work relative to their starting coefficients, ARMA-EM in its own offset and scale), unless
        # its magnitude would over- or underflow float64 arithmetic (_extreme_unit: a power of two)
        unit = _extreme_unit(rate) if self.online else data_scale(rate)
        if unit == 1.0:
            coefs, nonphys, extras, parts = _with_parts(self._fit(rate, dt))
            extras = {**(extras or {}), "data_scale": 1.0}
        else:
            given = {name: getattr(self, name) for name in self._rate_settings() if getattr(self, name) is not None}
            scaled = _standardised(rate, unit)
            # settings holding rates are handed to _fit in the standardised unit, on a copy: fit changes no setting
            worker = self
            if given:
                import copy

                worker = copy.copy(self)
                for name, value in given.items():
                    setattr(worker, name, _scale_coefficients(name, value, 1.0 / unit))
            with _same_gaps(rate, scaled):
                coefs, nonphys, extras, parts = _with_parts(worker._fit(scaled, dt))
            if worker is not self:  # what the fit learned (its state, not its settings) is this estimator's
                settings = set(self._param_names())
                self.__dict__.update({k: v for k, v in worker.__dict__.items() if k not in settings})
            coefs = {c: float(v) * unit for c, v in coefs.items()}
            extras = rescale_diagnostics(extras or {}, unit, {**DIAGNOSTIC_UNITS, **self.diagnostic_units})
            extras["data_scale"] = unit
            parts = parts.times(unit)
        self._set_results(coefs, nonphys, extras, parts)
        self._mark_unseen_terms(rate.size, dt)
        return self

    def _mark_unseen_terms(self, n: int, dt: float) -> None:
        """Report a term the record cannot see as not resolved, with its bound (the contract's floor rule).

        A coefficient whose term contributes less than :data:`UNSEEN_SHARE` of the fitted
        model's AV (:meth:`model_avar`) at every octave tau of the record with at least 8 clusters is
        below anything the record resolves: its value is where the fit's floor or round-off left it
        (GMWM's Gauss-Markov sigma a few decades under the curve, say), and such values differ
        between fits of the same record in two units by orders of magnitude while meaning the same.
        It goes into ``parts_.unresolved`` with ``upper``, the upper bound any such term
        obeys: its AV is at most the AV's 97.5 % chi^2 upper limit at every tau (J - 1 degrees of
        freedom, J = floor(n / m) clusters, the non-overlapping AV's, fewer than the overlapping
        AV's), ``upper = min_tau sqrt(AV_97.5%(tau) / (beta_scale tau^p))``, with the fitted model
        as the AV. It replaces an estimator's own entry for such a term (whose bound may come from
        another rule that the floor's round-off switches on or off: GMWM's for a Gauss-Markov term
        peaking early), so that the term reads the same in every unit. The coefficient keeps its value.
        A coefficient of exactly 0 (a term at the fit's lower bound: GMWM, nnls_rel) is such a term
        too, so that a floor reached in one unit and missed by a hair in another reads the same,
        unless the estimator bounds its zeros itself (``parts_.zero_bounds``: whittle).
        """
        from dataclasses import replace

        from avbench.estimators.allan.model import BETA_SCALE, TAU_POWER

        c = self.coefficients_
        own = None if self.parts_.zero_bounds is None else self.parts_.zero_bounds[0]  # whittle bounds its zeros
        own = set() if own is None else {k for k in getattr(own, "index", own) if math.isfinite(float(own[k]))}
        shares = self.term_shares(n, dt)
        judged = [k for k, s in shares.items() if s < UNSEEN_SHARE and (float(c[k]) > 0.0 or k not in own)]
        if not judged:
            return
        from scipy.special import gammaincinv  # scipy.stats.chi2.ppf(q, k) is 2 gammaincinv(k / 2, q) (no scipy.stats import)

        tau, model = self._octave_model(n, dt)
        m = tau / dt
        dof = np.floor(n / m) - 1
        upper_av = model * dof / (2 * gammaincinv(dof / 2, 0.025))
        unresolved = dict(self.parts_.unresolved)
        for k in judged:
            unresolved[k] = float(np.sqrt(np.min(upper_av / (BETA_SCALE[k] * tau ** TAU_POWER[k]))))
        self.parts_ = replace(self.parts_, unresolved=unresolved)

    def _octave_model(self, n: int, dt: float):
        """``(tau, model AV)`` at the octave taus of a record of ``n`` samples with at least 8 clusters,
        or None when the fitted model cannot be evaluated there (finite and positive)."""
        if n < 16:
            return None
        tau = 2.0 ** np.arange(int(math.log2(n // 8)) + 1) * dt
        try:
            model = np.asarray(self.model_avar(tau), dtype=float)
        except Exception:  # a model that cannot be evaluated is the model check's business
            return None
        if model.shape != tau.shape or not np.all(np.isfinite(model) & (model > 0)):
            return None
        return tau, model

    def term_shares(self, n: int, dt: float) -> dict[str, float]:
        """The statistic the floor rule (:meth:`_mark_unseen_terms`) decides on: for each finite
        coefficient, the largest share of the fitted model's AV (:meth:`model_avar`) its five-term AV
        takes at an octave tau of a record of ``n`` samples with at least 8 clusters (0 for a
        coefficient of 0; empty when the model cannot be evaluated). Dimensionless: the same in every
        unit, to the fit's own round-off (``check-estimator``'s equivariance check compares it where a
        term's label differs between units, :func:`avbench.estimators.contract.equivariance`)."""
        from avbench.estimators.allan.model import BETA_SCALE, TAU_POWER

        self._check_fitted()
        at = self._octave_model(n, dt)
        if at is None:
            return {}
        tau, model = at
        c = self.coefficients_
        return {k: float(np.max(BETA_SCALE[k] * float(c[k]) ** 2 * tau ** TAU_POWER[k] / model))
                for k in c.index if math.isfinite(float(c[k]))}

    @classmethod
    def _rate_settings(cls) -> list[str]:
        """Settings holding coefficient values (a mapping coefficient -> SI value), which scale with the data."""
        return [n for n in cls._param_names() if n == "x0"]

    def _fit(self, rate: np.ndarray, dt: float):  # pragma: no cover - abstract
        raise NotImplementedError

    def _set_results(self, coefs: dict, nonphys: dict | None, extras: dict | None, parts=None) -> None:
        """Store a fit: coefficients, non-physical flags, the method's own details (``extras_``) and the
        typed parts (:class:`avbench.estimators.results.FitParts`; none given: nothing typed to report).
        An extra that the result provides (:data:`~avbench.estimators.results.RESULT_ENTRIES`, a model
        choice's key) is refused: the result is its one source."""
        from avbench.estimators.results import RESULT_ENTRIES, FitParts

        parts = FitParts() if parts is None else parts
        extras = dict(extras or {})
        twice = sorted(set(extras) & {*RESULT_ENTRIES, *(c.key for c in parts.choices)})
        if twice:
            raise TypeError(f"{type(self).__name__}._fit: the extras {', '.join(twice)} are the result's "
                            "(report them in its FitParts)")
        self.parts_ = parts
        c = coefficient_series(coefs)
        flags = coefficient_series(nonphys or {}, dtype=bool, fill=False)
        if flags.to_numpy().any():  # (an ndarray key, and only when needed: a boolean Series key costs pandas ~0.3 ms)
            c[flags.to_numpy()] = math.nan
        self.coefficients_ = c
        self.nonphysical_ = flags
        self.extras_ = extras
        se = parts.std_err
        se = coefficient_series({} if se is None else {k: float(v) for k, v in dict(se).items()})
        unset = ~np.isfinite(c.to_numpy())
        if unset.any():
            se[unset] = math.nan
        self.std_err_ = se

    # -- the fitted model ---------------------------------------------------------------------
    def model_avar(self, tau) -> np.ndarray:
        """The Allan variance (SI, of the record as handed to ``fit``) at ``tau`` (s) of the model this
        estimator fitted: what a figure draws over the record's AV and what its residuals are taken from.

        An estimator whose model is a sum of noise terms other than the five-term curve (a Gauss-Markov
        bias instability, a flicker with its filter memory, ...) keeps that model as a
        :class:`avbench.noise_models.Gyro` in ``extras_["model"]`` (in the units it was fitted in,
        see ``data_scale``): its exact discrete AV is returned. Otherwise the five-term curve of
        ``coefficients_`` (IEEE 952 / Lv et al. 2015, :func:`avbench.estimators.allan.model.model_avar`;
        terms without a finite value left out). A subclass may override this method.
        """
        from avbench.estimators.allan.model import model_avar

        self._check_fitted()
        tau = np.asarray(tau, dtype=float)
        gyro = self.extras_.get("model")
        if gyro is not None:
            return gyro.avar(tau) * float(self.extras_.get("data_scale", 1.0)) ** 2
        c = self.coefficients_
        return model_avar({k: float(v) for k, v in c.items() if np.isfinite(v)}, tau)

    @property
    def diagnostics_(self):
        """The fit's details as one read-only mapping, for callers of the free-form form: ``extras_`` and
        what :meth:`result` holds under the names of :data:`~avbench.estimators.results.RESULT_ENTRIES`
        (:func:`avbench.estimators.results.diagnostics_view`).
        Built from the result on each read; code in avbench reads the result instead."""
        from avbench.estimators.results import diagnostics_view

        extras = self.extras_  # AttributeError before a fit, as for every fitted attribute
        return diagnostics_view(self.result(), extras)

    def result(self, level: float = 0.95):
        """The fit as one typed :class:`avbench.estimators.results.FitResult` with intervals at ``level``
        (after :meth:`bootstrap`, its standard errors); what every surface renders."""
        from avbench.estimators.results import build

        return build(self, level)

    # -- uncertainty (avbench.estimators.uncertainty) ------------------------------------------------------
    def _check_fitted(self):
        if not hasattr(self, "coefficients_"):
            raise ValueError(f"{type(self).__name__}: not fitted yet; call fit(rate, dt) first")

    def conf_int(self, level=0.95, conservative=False) -> pd.DataFrame:
        """Intervals for the coefficients (SI): DataFrame indexed Q..R, columns ``lower``, ``upper``.

        Log-scale normal intervals from ``std_err_`` (NaN where there is none); with
        ``conservative=True`` one-sided upper bounds holding jointly with probability ``level``
        (an overbound; lower = 0). See :mod:`avbench.estimators.uncertainty`.

        Where the fit reports models the record cannot tell from this one (``parts_.alternatives``:
        GMWM's other bias-instability model when the evidence is not decisive, its longer cut-offs within
        the white reach that Hansen's J accepts), each interval is widened to hold the same coefficient's
        interval (and value) under each of them: the reported value stays this model's, the interval is
        the union of the models' intervals (model uncertainty kept in the interval, as model-averaged
        intervals do, Buckland, Burnham & Augustin 1997, but conservative: it holds the coefficient under
        each model).
        """
        import pandas as pd

        from avbench.estimators.uncertainty import interval, zero_quantile

        self._check_fitted()
        upper0 = None
        if self.parts_.zero_bounds is not None and len(self.parts_.zero_bounds[0]):  # whittle: its zeros' bounds
            zu, power = self.parts_.zero_bounds
            z = zero_quantile(level, conservative, self.std_err_, self.coefficients_)
            upper0 = zu * z ** power
        ci = interval(self.coefficients_, self.std_err_, level, conservative, upper_if_zero=upper0)
        for alt in self.parts_.alternatives:
            coefs = pd.Series(alt.coefficients, dtype=float)
            other = interval(coefs, pd.Series(alt.std_err, dtype=float).reindex(coefs.index), level, conservative)
            for c in coefs.index:
                own = self.coefficients_.get(c, math.nan)
                v = coefs[c]
                if not (np.isfinite(own) and np.isfinite(v)):
                    continue
                lo = np.nanmin([ci.at[c, "lower"], other.at[c, "lower"], v])
                hi = np.nanmax([ci.at[c, "upper"], other.at[c, "upper"], v])
                ci.loc[c] = (lo, hi)
        return ci

    def bootstrap(self, n_samples: int, dt, n_draws: int = 20, seed=0) -> "Estimator":
        """Replace ``std_err_`` by a parametric bootstrap: ``n_draws`` records of ``n_samples``
        samples simulated from the fitted coefficients with the exact generators, refitted by
        clones of this estimator (:func:`avbench.estimators.uncertainty.parametric_bootstrap`). Costs
        ``n_draws`` fits. Returns ``self``."""
        from avbench.estimators.uncertainty import parametric_bootstrap

        self._check_fitted()
        se = parametric_bootstrap(self, int(n_samples), check_dt(dt), n_draws, seed)
        se[~np.isfinite(self.coefficients_)] = math.nan
        self.std_err_ = se
        self.extras_["std_err_method"] = f"parametric bootstrap, {n_draws} draws"
        return self

    # -- presentation --------------------------------------------------------------------------
    def summary(self, units: dict[str, str] | None = None, level: float = 0.95) -> pd.DataFrame:
        """The fit's :class:`~avbench.estimators.results.FitResult` (:meth:`result` at ``level``) as a table:
        per coefficient the fitted value in SI and in ``units`` (default: the papers' units), its status
        and its interval in ``units`` (NaN where there is none)."""
        import pandas as pd

        from avbench.noise_models.units import PAPER_UNITS, SI_UNITS, from_si

        units = units or PAPER_UNITS
        r = self.result(level)
        rows = {}
        for c in COEFFICIENTS:
            e = r.coefficients[c]
            lo, hi = e.interval if e.interval is not None else (math.nan, math.nan)
            rows[c] = {"SI": e.fitted, "SI unit": SI_UNITS[c], "value": from_si(c, e.fitted, units[c]), "unit": units[c],
                       "status": e.status, "lower": from_si(c, lo, units[c]), "upper": from_si(c, hi, units[c]),
                       "nonphysical": e.status == "non-physical"}
        return pd.DataFrame.from_dict(rows, orient="index")


#: the noise level (:func:`noise_level`) every record is standardised to before an estimator fits it:
#: near that of the studies' simulated gyros in rad/s (1e-7..1e-2), so that what remained
#: unit-dependent inside an estimator (its tolerances and floors were tuned on such records) sees
#: data of the magnitude it was tuned on
STANDARD_LEVEL = 2.0**-10

#: a term whose share of the fitted model's AV stays below this at every tau of the record is not
#: seen by it (:meth:`Estimator._mark_unseen_terms`): no record resolves an AV to a part in a million
UNSEEN_SHARE = 1e-6

#: a record whose unit would differ from 1 by less than this is fitted as it is (a record already
#: standardised, as an estimator fitting another inside its ``_fit`` hands it on)
_UNIT_TOLERANCE = 1e-9


def noise_level(rate: np.ndarray) -> float:
    """The RMS of the record's first differences over sqrt 2 (the white-noise level of one sample;
    0 for a constant record). It scales exactly with the data (``noise_level(2**k * x) == 2**k *
    noise_level(x)``) and to rounding with any factor; computed relative to the largest difference,
    so that neither 1e300 nor 1e-300 over- or underflows."""
    rate = np.asarray(rate, dtype=float)
    if rate.size < 2:
        return 0.0
    top = max(float(np.max(rate)), -float(np.min(rate)))
    if top > 2.0**1000:  # differences of values near the float64 limit would overflow
        e = math.frexp(top)[1]
        return math.ldexp(noise_level(np.ldexp(rate, -e)), e)
    d = np.diff(rate)
    big = float(np.max(np.abs(d)))
    if big == 0.0:
        return 0.0
    d /= big
    return big * math.sqrt(float(np.dot(d, d)) / (2.0 * d.size))


def _extreme_unit(rate: np.ndarray) -> float:
    """1 for a record whose spread (max - min) lies in [2^-60, 2^60] (or is 0); else the power of two
    near its spread, an exact unit for estimators that keep the record's own unit otherwise."""
    lo, hi = float(rate.min()), float(rate.max())
    spread = hi - lo
    if not math.isfinite(spread):  # max - min overflowed (values near the float64 limit)
        spread = max(abs(lo), abs(hi))
    if spread == 0.0 or 2.0**-60 <= spread <= 2.0**60:
        return 1.0
    return math.ldexp(1.0, math.frexp(spread)[1])


def data_scale(rate: np.ndarray) -> float:
    """The unit (in the record's own unit) an estimator fits the record in: ``noise_level(rate) /
    STANDARD_LEVEL``, so that ``rate / data_scale(rate)`` has the noise level :data:`STANDARD_LEVEL`;
    exactly 1 for a constant record and for one already standardised (within 1e-9)."""
    s = noise_level(rate)
    if s == 0.0:
        return 1.0
    unit = s / STANDARD_LEVEL
    if not (math.isfinite(unit) and unit > 0.0):  # noise levels within 2^10 of the float64 limits
        return math.ldexp(1.0, math.frexp(s)[1] + 10)
    return 1.0 if abs(unit - 1.0) < _UNIT_TOLERANCE else unit





#: How the extras every estimator may hold scale with the unit of the record: key -> power p
#: of the unit (the value, a number, array, Series, DataFrame, tuple, list or a mapping of such, is
#: multiplied by ``data_scale ** p``), or a mapping for entries with parts of different powers (keys
#: of a dict, columns of a DataFrame, attributes of a dataclass such as ``AllanResult``; parts not
#: named keep their value), or a function of the key for mappings keyed by names. A class adds
#: its own in :attr:`Estimator.diagnostic_units`; the typed parts convert themselves
#: (:meth:`avbench.estimators.results.FitParts.times`).
_ALLAN = {"avar": 2}  # AllanResult: adev, ci_low, ci_high follow from avar and edf
DIAGNOSTIC_UNITS: dict = {
    # coefficient-like (each entry is a coefficient in SI)
    "full_coefficients": 1, "full_std_err": 1, "start": 1, "x0": 1, "last_good": 1,
    # Allan-variance-like (rad^2/s^2)
    "avar": 2, "fitted_avar": 2, "fitted_hvar": 2, "residuals": 2, "beta": 2,
    "fit_check": {"avar": 2, "model": 2},
    "allan": _ALLAN, "hadamard": _ALLAN,
}


def rescale_diagnostics(diag: dict, unit: float, units: dict) -> dict:
    """``diag`` with each entry named in ``units`` (see :data:`DIAGNOSTIC_UNITS`) multiplied by
    ``unit ** power``; the other entries unchanged (a new dict; values are not modified in place)."""
    return {k: _rescale(v, units.get(k, 0), unit) for k, v in diag.items()}


def _rescale(value, power, unit):
    import dataclasses

    import pandas as pd

    if value is None or isinstance(value, (str, bool)):
        return value
    if callable(power):  # a mapping keyed by parameter names
        if isinstance(value, dict):
            return {k: _rescale(v, power(k), unit) for k, v in value.items()}
        if isinstance(value, pd.Series):
            return pd.Series([_rescale(v, power(k), unit) for k, v in value.items()], index=value.index,
                             dtype=value.dtype, name=value.name)
        return value
    if isinstance(power, dict):
        if isinstance(value, dict):
            return {k: (_rescale(v, power[k], unit) if k in power else v) for k, v in value.items()}
        if isinstance(value, pd.DataFrame):
            out = value.copy()
            for c, p in power.items():
                if c in out.columns:
                    out[c] = _rescale(out[c], p, unit)
            return out
        if dataclasses.is_dataclass(value):
            return dataclasses.replace(value, **{f: _rescale(getattr(value, f), p, unit)
                                                 for f, p in power.items() if hasattr(value, f)})
        return value
    if power == 0:
        return value
    with np.errstate(over="ignore"):
        f = float(np.float64(unit) ** power)  # inf for a power of a unit near the float64 limit
    if isinstance(value, dict):
        return {k: _rescale(v, power, unit) for k, v in value.items()}
    if isinstance(value, (tuple, list)):
        return type(value)(_rescale(v, power, unit) for v in value)
    with np.errstate(over="ignore", invalid="ignore"):
        if isinstance(value, pd.DataFrame):
            return value * f
        if isinstance(value, (pd.Series, np.ndarray)):
            return value * f if value.dtype.kind in "fc" else value
        if isinstance(value, (float, np.floating)):
            return type(value)(np.float64(value) * f)
    return value  # ints (counts), objects: not a measured value in the rate's unit


def _with_parts(fitted):
    """``(coefficients, nonphysical, diagnostics, parts)`` of what ``_fit`` returned: the four, or the
    first three of an estimator with nothing typed to report (empty :class:`~avbench.estimators.results.FitParts`)."""
    from avbench.estimators.results import FitParts

    if len(fitted) == 4:
        return fitted
    coefs, nonphys, diag = fitted
    return coefs, nonphys, diag, FitParts()


def _standardised(rate, unit):
    """``rate / unit``; within the engine's ``memoize_allan`` (a study's replicate) one copy per record,
    shared by the estimators fitted to it (and so their Allan variances too)."""
    import sys

    engine = sys.modules.get("avbench.estimators.allan.variance")
    if engine is None:
        return rate / unit
    return engine.memoized(rate, ("standardised", unit), lambda: rate / unit)


def _same_gaps(rate, scaled):
    """A context in which ``scaled`` (the standardised copy of ``rate``) has the gaps
    :func:`avbench.estimators.allan.variance.skip_gaps` registered for ``rate``, if any (the engine is
    looked up, not imported: no gaps can be registered before it is loaded)."""
    import contextlib
    import sys

    engine = sys.modules.get("avbench.estimators.allan.variance")
    starts = None if engine is None else engine.gap_starts(rate)
    return contextlib.nullcontext() if starts is None else engine.skip_gaps(scaled, starts)


def _scale_coefficients(name: str, value, factor: float):
    """A coefficient mapping (SI floats or (value, unit) pairs) multiplied by ``factor``, in SI."""
    from avbench.noise_models.units import as_si

    if not isinstance(value, dict):
        return value  # the estimator's own validation reports what is wrong with it
    return {c: as_si(c, v) * factor for c, v in value.items()}


def warn(category, message: str) -> None:
    warnings.warn(message, category, stacklevel=3)
