"""The noise-term interface: what every term of a synthetic gyro answers, and the checks they share.

Every term is sampled at interval ``dt`` (seconds) and produces rate samples in rad/s. Each term
answers the same small questions:

``coefficients()``
    the IEEE coefficient(s) it stands for, in SI (e.g. ``{"N": 1e-4}``);
``avar(m, dt)``
    the exact Allan variance (rad^2/s^2) of the *discrete* generator at cluster sizes ``m``
    (tau = m dt), for the non-overlapping and the overlapping estimator alike (both have that
    expectation);
``psd(f, dt)``
    the one-sided power spectral density (rad^2/s^2/Hz) of the discrete sequence at frequencies
    0 < f <= 1/(2 dt) (the pseudo-spectrum for the random walk; zero for the deterministic ramp);
``autocovariance(lags, dt)``
    the exact autocovariance (rad^2/s^2) of the discrete rate sequence at integer ``lags`` (an array of
    any shape; a lag and its negative give the same value); the exact statistics of the deviation
    family (:mod:`avbench.noise_models.exact_variances`) and the spectral likelihoods read it. A term
    that is not stationary (the random walk) declares ``stationary = False`` and answers with a
    ValueError; its exact statistics come from :meth:`NoiseTerm.phase_gcov`;
``stream(dt, rng)``
    a :class:`TermStream` whose ``next(n)`` returns the next ``n`` samples. The samples do not depend
    on how a record is cut into requests: ``next(a)`` then ``next(b)`` equals ``next(a + b)`` bit for
    bit. Each term of a gyro draws from its own child generator, so terms do not interfere.

A term a latent-model fit offers (GMWM's ``model="WN+GM+RW"``, :mod:`avbench.noise_models.latents`)
also answers the fitting questions, as arch's volatility processes do (``parameter_names``,
``starting_values``, ``bounds``): its code in a model (:attr:`NoiseTerm.latent`), the parameters a fit
estimates in their order (:attr:`NoiseTerm.fit_parameters`: the amplitude, then the shape
parameters), the term at fitted values (:meth:`NoiseTerm.from_fit`), the box of their logarithms
(:meth:`NoiseTerm.fit_bounds`) and the starts read off an AV curve (:meth:`NoiseTerm.fit_starts`).
The fitter loops over the terms of its model and keeps no table of them.
"""

from __future__ import annotations

import abc
import math
from typing import ClassVar, NamedTuple

import numpy as np

from avbench.noise_models.exact_variances import gcov_from_autocovariance

__all__ = ["NoiseTerm", "TermStream", "FitHint", "StateBlock", "PLATEAU"]

#: the flicker plateau of the AV, (2 ln 2 / pi) B^2 (IEEE Std 952-1997, Annex C)
PLATEAU = 2.0 * math.log(2.0) / math.pi


def _check_dt(dt) -> float:
    try:
        dt = float(dt)
    except (TypeError, ValueError):
        raise ValueError(f"dt: expected a positive number of seconds, got {dt!r}") from None
    if not math.isfinite(dt) or dt <= 0:
        raise ValueError(f"dt: expected a positive, finite sample interval in seconds, got {dt!r}")
    return dt


def _positive(name: str, value, allow_zero: bool = False) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected a number, got {value!r}") from None
    if not math.isfinite(v) or v < 0 or (v == 0 and not allow_zero):
        kind = "non-negative" if allow_zero else "positive"
        raise ValueError(f"{name}: expected a finite, {kind} value, got {value!r}")
    return v


def _check_n(n) -> int:
    if isinstance(n, bool) or not isinstance(n, int | np.integer) or n < 0:
        raise ValueError(f"n: expected a non-negative integer number of samples, got {n!r}")
    return int(n)


class TermStream:
    """Chunk-invariant sample source of one term (see the module docstring)."""

    def __init__(self, dt: float, rng: np.random.Generator):
        self.dt = dt
        self.rng = rng

    def next(self, n: int) -> np.ndarray:  # pragma: no cover - abstract
        raise NotImplementedError

def _no_exact_statistic(name: str):
    """The method ``name`` of a term without exact statistics: a ValueError naming the term."""

    def method(self, *args, **kwargs):
        raise ValueError(f"{type(self).__name__}: no exact {name} (the term declares has_exact_avar = False)")

    method.__name__ = name
    return method


class NoiseTerm(abc.ABC):
    """Abstract base of the noise terms: every term declares its parameters (:meth:`_params`), its exact
    AV (:meth:`avar`), spectrum (:meth:`psd`), autocovariance (:meth:`autocovariance`) and generator
    (:meth:`stream`), each with the signature below (the module docstring)."""

    #: the IEEE coefficient the term reports (None if it reports none)
    coefficient: ClassVar[str | None] = None
    #: False for a term without an exact Allan variance (a user's term may declare so): then
    #: ``Gyro.avar`` is an error and study tables and figures say the truth curve is unavailable
    has_exact_avar: ClassVar[bool] = True

    #: False for a term whose rate is not a stationary sequence (the random walk): it has no
    #: :meth:`autocovariance`, and its spectrum (:meth:`psd`) is a pseudo-spectrum
    stationary: ClassVar[bool] = True
    #: True for a term without a random part (the ramp: a mean, no covariance); a spectral likelihood
    #: models it as a trend, not a spectrum
    deterministic: ClassVar[bool] = False

    #: the exact statistics a term declares unless it says it has none (``has_exact_avar = False``)
    _EXACT_STATISTICS: ClassVar[tuple[str, ...]] = ("avar", "psd", "autocovariance")

    def __init_subclass__(cls, **kwargs):
        """A term that declares no exact Allan variance (``has_exact_avar = False``: a user's term whose truth
        is not derived) is not asked for its exact statistics: each left out answers with an error naming
        the term, so that the abstract base does not refuse to make it. Every other term must declare them."""
        super().__init_subclass__(**kwargs)
        if cls.has_exact_avar:
            return
        for name in cls._EXACT_STATISTICS:
            if getattr(getattr(cls, name, None), "__isabstractmethod__", False):
                setattr(cls, name, _no_exact_statistic(name))

    def coefficients(self) -> dict[str, float]:
        """The IEEE coefficient(s) the term stands for, in SI (none by default)."""
        return {}

    @abc.abstractmethod
    def avar(self, m, dt) -> np.ndarray:
        """The exact Allan variance (rad^2/s^2) of the discrete generator at cluster sizes ``m``."""

    @abc.abstractmethod
    def psd(self, f, dt) -> np.ndarray:
        """The one-sided power spectral density (rad^2/s^2/Hz) at frequencies 0 < f <= 1/(2 dt)."""

    @abc.abstractmethod
    def autocovariance(self, lags, dt) -> np.ndarray:
        """The exact autocovariance r(k) = Cov(w_j, w_{j+k}) (rad^2/s^2) of the discrete rate sequence
        at the integer ``lags`` (any shape; r(-k) = r(k)); a ValueError for a term that is not
        :attr:`stationary`."""

    def psd_autocovariance(self, lags, dt) -> np.ndarray:
        """The autocovariance whose transform is :meth:`psd`, at integer ``lags``, up to an additive
        constant: the generator's own (:meth:`autocovariance`) by default; a term whose :meth:`psd` is an
        ideal spectrum beside its generator's (the flicker term's 1/f, whose variance is infinite)
        overrides it. The spectral likelihoods' expected periodograms and time-domain covariances read
        it (a constant changes no Fourier ordinate k >= 1 and no contrast whose weights sum to 0)."""
        return self.autocovariance(lags, dt)

    def _not_stationary(self):
        """The error :meth:`autocovariance` raises for a term that is not stationary."""
        return ValueError(f"{type(self).__name__} is not stationary: it has no autocovariance (its exact "
                          "statistics come from phase_gcov)")

    def psd_factor(self) -> tuple[float, "NoiseTerm"]:
        """``(c, unit)`` with ``self.psd(f, dt) == c * unit.psd(f, dt)`` for every f and dt: the
        spectrum's amplitude and a term of the same spectral shape (``c = 0``: no random part). Spectral
        integrals that are quadratic in the spectrum (the AV covariance,
        :mod:`avbench.estimators.allan.covariance`) are then computed once per shape and weighted.
        Default ``(1.0, self)`` (always right; a term whose spectrum scales with a coefficient
        overrides it so that fits with different coefficients share the integrals)."""
        return 1.0, self

    #: the parameter (a key of ``_params()``) that sets the shape of the term's AV curve beside its
    #: amplitude (a correlation time, a frequency), or None: :meth:`avar_shape_derivative`
    shape_parameter: ClassVar[str | None] = None

    def avar_shape_derivative(self, m, dt) -> tuple[np.ndarray, np.ndarray]:
        """``(avar, d avar / d ln p)`` at cluster sizes ``m`` for p the :attr:`shape_parameter`: the
        Jacobian column a fit in log-parameters needs (GMWM, :mod:`avbench.estimators.likelihood.gmwm`).

        Default: a central difference in ln p (relative step ``1e-4``: truncation ~1e-9 relative for
        curves smooth in ln p) of :meth:`avar`, one-sided where a step leaves the values the term
        accepts (a sinusoid at the Nyquist frequency; truncation ~1e-4 there); a term overrides it with
        the analytic derivative (:class:`GaussMarkov`). A ValueError if the term has no shape parameter."""
        name = self.shape_parameter
        if name is None:
            raise ValueError(f"{type(self).__name__}: no shape parameter (its AV is its amplitude squared "
                             "times a fixed curve)")
        params = self._params()
        h = 1e-4
        value = self.avar(m, dt)

        def at(step):
            try:
                return type(self)(**{**params, name: params[name] * math.exp(step)}).avar(m, dt), step
            except ValueError:  # outside the values the term accepts: the other side only
                return value, 0.0

        (up, a), (down, b) = at(h), at(-h)
        return value, (up - down) / (a - b)

    @classmethod
    def shape_parameters(cls) -> tuple[str, ...]:
        """Every parameter beside the amplitude that shapes the AV curve: ``(shape_parameter,)`` or ``()``
        by default; a term with two (:class:`Resonance`: frequency and damping time) overrides it."""
        return () if cls.shape_parameter is None else (cls.shape_parameter,)

    def avar_shape_gradient(self, m, dt) -> tuple[np.ndarray, list[np.ndarray]]:
        """``(avar, [d avar / d ln p for p in shape_parameters()])``: :meth:`avar_shape_derivative` for a
        term with one shape parameter; central differences in ln p (as there) for more."""
        names = self.shape_parameters()
        if len(names) == 1:
            value, d = self.avar_shape_derivative(m, dt)
            return value, [d]
        params, h = self._params(), 1e-4
        value = self.avar(m, dt)
        out = []
        for name in names:
            up = type(self)(**{**params, name: params[name] * math.exp(h)}).avar(m, dt)
            down = type(self)(**{**params, name: params[name] * math.exp(-h)}).avar(m, dt)
            out.append((up - down) / (2 * h))
        return value, out

    def spectral_lines(self, dt) -> list[tuple[float, float]]:
        """Spectral lines [(frequency Hz, variance)] beside :meth:`psd` (none but for sinusoids)."""
        return []

    @abc.abstractmethod
    def stream(self, dt, rng: np.random.Generator) -> TermStream:
        """The term's chunk-invariant sample source at interval ``dt`` (the module docstring)."""

    def phase_gcov(self, lags, dt) -> np.ndarray:
        """Generalized covariance G(d) of the phase at integer lags (see ``noise_models.exact_variances``).

        Default: from :meth:`autocovariance` at lags 0..max|lags| (a stationary term), G = -D/2; a term
        that is not stationary overrides it.
        """
        lags = np.abs(np.asarray(lags, dtype=np.int64))
        L = int(lags.max()) if lags.size else 0
        return gcov_from_autocovariance(self.autocovariance(np.arange(L + 1), dt), lags, dt)

    def simulate(self, n: int, dt, rng: np.random.Generator) -> np.ndarray:
        """``n`` samples (rad/s) of this term alone."""
        return self.stream(_check_dt(dt), rng).next(_check_n(n))

    def __repr__(self) -> str:
        args = ", ".join(f"{k}={v!r}" for k, v in self._params().items())
        return f"{type(self).__name__}({args})"

    @abc.abstractmethod
    def _params(self) -> dict:
        """The term's parameters by constructor keyword, SI: ``type(self)(**self._params()) == self``."""

    def __eq__(self, other) -> bool:
        return type(self) is type(other) and self._params() == other._params()

    def __hash__(self):
        return hash((type(self).__name__, tuple(self._params().items())))

    # -- as a latent of a fitted model (:mod:`avbench.noise_models.latents`) ---------------------------------
    #: the term's code in a latent model (``"WN"`` in ``"WN+GM+RW"``), or None where the fits do not offer it
    latent: ClassVar[str | None] = None
    #: the parameters a fit estimates, in their order in the parameter vector: the amplitude first (the AV
    #: is its square times a curve set by the others), then the shape parameters; named as the fits report
    #: them (``"GM.tc"``, ``"SN.f0"``)
    fit_parameters: ClassVar[tuple[str, ...]] = ()
    #: the reported :attr:`coefficient` per unit amplitude (B_equiv / sigma for a Gauss-Markov term)
    coefficient_per_amplitude: ClassVar[float] = 1.0

    @classmethod
    def from_fit(cls, values, *, tau_max=None) -> "NoiseTerm":
        """The term at the values of its :attr:`fit_parameters` (SI, in their order); ``tau_max``: the filter
        memory of a flicker term (which the fit does not estimate)."""
        raise NotImplementedError(f"{cls.__name__}: not a latent of the fits")

    @classmethod
    def fit_amplitude_top(cls, tau, avar) -> float:
        """The amplitude at which the term alone reaches the AV curve ``avar`` (at ``tau``, s) where it rises
        highest above the term's shape: the scale of the box of :meth:`fit_bounds`."""
        raise NotImplementedError(f"{cls.__name__}: not a latent of the fits")

    @classmethod
    def fit_shape_bounds(cls, tau, dt, T, hint=None) -> tuple[list[float], list[float]]:
        """``(lower, upper)``: the box of the logarithms of the shape parameters, for a fit at the taus
        ``tau`` of a record of ``T`` seconds sampled every ``dt``; ``hint``: a :class:`FitHint` or None.
        None by default (no shape parameter)."""
        return [], []

    @classmethod
    def fit_bounds(cls, tau, avar, dt, T, hint=None) -> tuple[list[float], list[float]]:
        """``(lower, upper)``: the box of the logarithms of the :attr:`fit_parameters` for a fit of the AV
        curve ``avar`` at ``tau``: the amplitude from 1e-8 to 10 times :meth:`fit_amplitude_top`, the shape
        parameters as :meth:`fit_shape_bounds`."""
        top = cls.fit_amplitude_top(tau, avar)
        lo, hi = cls.fit_shape_bounds(tau, dt, T, hint)
        return [math.log(top * 1e-8), *lo], [math.log(top * 10), *hi]

    @classmethod
    def fit_starts(cls, tau, avar, lo, hi, *, n_starts=1, hint=None) -> list[tuple[float, ...]]:
        """Starting values (SI, one tuple per start, in the order of :attr:`fit_parameters`) read off the AV
        curve ``avar`` at ``tau``; ``lo``, ``hi``: the term's box (:meth:`fit_bounds`, logarithms);
        ``n_starts``: how many values of a shape parameter to try; ``hint``: a :class:`FitHint` or None. A
        fitter starts from every combination of its terms' starts."""
        raise NotImplementedError(f"{cls.__name__}: not a latent of the fits")

    # -- in the exact block-mean state-space likelihood (:mod:`avbench.estimators.likelihood.mle`) ------------
    #: how many states of its own the term adds to the block-mean state space (0: it acts on the observation
    #: or on the shared level only), or None where that likelihood does not model it. A deterministic term's
    #: states are diffuse (unknown constants), the others' start from their stationary distribution
    block_mean_states: ClassVar[int | None] = None

    @classmethod
    def block_mean_block(cls, values, m: int, dt: float) -> "StateBlock":
        """The term's part of the state space of the means of blocks of ``m`` samples (a
        :class:`StateBlock`), at the values of its stochastic :attr:`fit_parameters` (the amplitude in the
        unit of the data the filter runs on, the others SI; none for a deterministic term)."""
        raise NotImplementedError(f"{cls.__name__}: not a term of the block-mean likelihood")

    @classmethod
    def block_mean_derivatives(cls, values, m: int, dt: float, block: "StateBlock") -> list["StateBlock"]:
        """The derivatives of :meth:`block_mean_block` (``block``, at ``values``) in the logarithm of each fit
        parameter, in their order (the observation row depends on m and dt only: its derivative is zero).
        Default: the amplitude only, every covariance of the term being its square times a matrix set by the
        others (twice itself; the transition does not move); a term with shape parameters overrides it."""
        return [StateBlock(np.zeros_like(block.T), 2.0 * block.Q, np.zeros_like(block.Z), 2.0 * block.P0, 2.0 * block.H,
                           None if block.level is None else 2.0 * block.level,
                           None if block.level_input is None else np.zeros_like(block.level_input))]

    @classmethod
    def likelihood_start(cls, values, tau, avar) -> tuple[float, ...]:
        """Where the block-mean likelihood starts the term: from ``values``, its :attr:`fit_parameters` as a
        fit of the AV curve ``avar`` at ``tau`` found them (SI). Default: those values."""
        return tuple(values)

    @classmethod
    def block_mean_memory(cls, values) -> float | None:
        """The time (s) the block means must resolve for the term at ``values`` (its correlation time), or
        None (default: no time scale of its own)."""
        return None


class StateBlock(NamedTuple):
    """A term's part of the block-mean state space (:meth:`NoiseTerm.block_mean_block`): over its own s
    states the transition ``T`` (s x s), disturbance covariance ``Q``, observation row ``Z`` (s,) and
    covariance ``P0`` of the first state (zero for diffuse states); ``H`` the variance it adds to the
    observation; ``level`` the disturbance covariance (2 x 2) it adds to the shared level and block-mean
    level ``(L, Lbar)``, or None; ``level_input`` (2 x s) how its states enter ``(L, Lbar)``, or None."""

    T: np.ndarray
    Q: np.ndarray
    Z: np.ndarray
    P0: np.ndarray
    H: float = 0.0
    level: np.ndarray | None = None
    level_input: np.ndarray | None = None


class FitHint(NamedTuple):
    """What a fitter knows about a term beyond the AV curve: ``window`` (Hz), the range its frequency is held
    in (a spectral line or band found in the record), or None; ``starts``, parameter tuples (SI, in the
    order of :attr:`NoiseTerm.fit_parameters`) to start the fit at instead of values read off the curve."""

    window: tuple[float, float] | None = None
    starts: tuple = ()


class FrequencyGrid(np.ndarray):
    """Frequencies (Hz) at which spectra are asked for again and again (the AV covariance's midpoint grid:
    every fit's weights and fit check): an array that keeps, per sample interval, what the terms' spectra
    compute from the frequencies alone -- 2 pi f dt (:func:`_omega_dt`) and its sine, cosine and complex
    exponentials (:func:`_grid_value`) -- computed once by the same expressions, so a spectrum on the grid
    is bit for bit the spectrum on the plain array. Arithmetic on it, and a slice of it, give arrays that
    keep nothing."""

    def __new__(cls, f):
        obj = np.asarray(f, dtype=float).view(cls)
        obj._kept = {}
        return obj

    def __array_finalize__(self, obj):
        self._kept = None

    def __array_wrap__(self, arr, context=None, return_scalar=False):
        arr = arr.view(np.ndarray)
        return arr[()] if return_scalar else arr


def _kept(f, key, compute):
    """``compute()``, kept on ``f`` under ``key`` when ``f`` is a :class:`FrequencyGrid` (its arrays read-only:
    a spectrum that wrote into one would change every later spectrum on the grid)."""
    kept = getattr(f, "_kept", None) if isinstance(f, FrequencyGrid) else None
    if kept is None:
        return compute()
    value = kept.get(key)
    if value is None:
        value = compute()
        for a in value if isinstance(value, tuple) else (value,):
            a.flags.writeable = False
        kept[key] = value
    return value


def _omega_dt(f, dt):
    """``(f, 2 pi f dt)`` as plain arrays, after checking that 0 < f <= 1/(2 dt) (kept on a
    :class:`FrequencyGrid`)."""
    def compute(f=f):
        f = np.asarray(f, dtype=float).view(np.ndarray)
        if np.any(f <= 0) or np.any(f > 0.5 / dt * (1 + 1e-12)):
            raise ValueError(f"f: expected frequencies in (0, 1/(2 dt)] = (0, {0.5 / dt}] Hz")
        return f, 2 * np.pi * f * dt

    return _kept(f, ("w", dt), compute)


#: the functions of w = 2 pi f dt the terms' spectra use, by name (:func:`_grid_value`)
_GRID_FUNCTIONS = {
    "sin(w/2)": lambda w: np.sin(w / 2),
    "cos(w)": np.cos,
    "exp(iw)": lambda w: np.exp(1j * w),
    "exp(-iw)": lambda w: np.exp(-1j * w),
}


def _grid_value(f, dt, name, w):
    """``_GRID_FUNCTIONS[name](w)`` for ``w`` = :func:`_omega_dt` (f, dt), kept on a :class:`FrequencyGrid`
    ``f``."""
    return _kept(f, (name, dt), lambda: _GRID_FUNCTIONS[name](w))
