"""Noise terms of a synthetic gyro: each simulates itself and knows its exact discrete-time AV.

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
``stream(dt, rng)``
    a :class:`TermStream` whose ``next(n)`` returns the next ``n`` samples. The samples do not depend
    on how a record is cut into requests: ``next(a)`` then ``next(b)`` equals ``next(a + b)`` bit for
    bit. Each term of a gyro draws from its own child generator, so terms do not interfere.

The formulas (SPEC, "Discrete generators and their exact Allan variance"):

=====================  ==========================================  =======================================
term                   generator                                   exact AV at tau = m dt
=====================  ==========================================  =======================================
Quantization(Q)        theta_k ~ N(0, Q^2), w_k = (theta_k -        3 Q^2 / tau^2
                       theta_{k-1}) / dt
AngleRandomWalk(N)     w_k = (N / sqrt(dt)) n_k                     N^2 / tau
RateRandomWalk(K)      w_k = w_{k-1} + K sqrt(dt) n_k               K^2 tau / 3 + K^2 dt^2 / (6 tau)
RateRamp(R)            w_k = R k dt                                 R^2 tau^2 / 2
GaussMarkov(sigma,tc)  x_k = phi x_{k-1} + sigma sqrt(1-phi^2) n_k   closed form below
BiasInstability(B)     Kasdin & Walter (1992) 1/f FIR, Q_d = B^2    from the exact autocovariance
SecondOrderGaussMarkov exact discretisation of Miao et al. 2015,    from the exact autocovariance
                       eq. 8
Sinusoidal(A, f0)      A sin(2 pi f0 k dt + phi), phi uniform       A^2 sin^4(m w/2) / (m^2 sin^2(w/2)),
                       (IEEE Std 952-1997, Annex C)                 w = 2 pi f0 dt
FilteredWhiteNoise(N)  white noise N through the sensor's low-pass  N^2/tau - 3 C2 / m^2 (FIR, m >= L);
                       (moving average, FIR or first-order IIR)     the GM form (first-order IIR)
Resonance(sigma, f0,   band-pass Gauss-Markov: ARMA(2,1), poles     Re[(1 + i c) GM form at complex phi]
          tc)          rho e^{+-i w}, MA zero at 1 (a structural    (closed form below)
                       mode's noise; no power at f = 0)
=====================  ==========================================  =======================================
"""

from __future__ import annotations

import functools
import math
from typing import ClassVar

import numpy as np

from avbench.noise_models.exact_avar import avar_from_autocovariance, check_m
from avbench.noise_models.exact_variances import gcov_from_autocovariance
from avbench.noise_models.units import as_si

__all__ = [
    "NoiseTerm",
    "TermStream",
    "Quantization",
    "AngleRandomWalk",
    "RateRandomWalk",
    "RateRamp",
    "GaussMarkov",
    "BiasInstability",
    "SecondOrderGaussMarkov",
    "Sinusoidal",
    "FilteredWhiteNoise",
    "Resonance",
    "GM_PEAK_TAU_OVER_TC",
    "GM_PEAK_ADEV_OVER_SIGMA",
    "B_EQUIV_OVER_SIGMA",
]

PLATEAU = 2.0 * math.log(2.0) / math.pi
#: continuous first-order GM: the AV peaks at tau = 1.8926 Tc ...
GM_PEAK_TAU_OVER_TC = 1.8926
#: ... with Allan deviation 0.6174 sigma
GM_PEAK_ADEV_OVER_SIGMA = 0.6174
#: SPEC's convention: the bias instability a GM term stands for, B_equiv = 0.6174 sigma / 0.6643
B_EQUIV_OVER_SIGMA = GM_PEAK_ADEV_OVER_SIGMA / math.sqrt(PLATEAU)


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


class NoiseTerm:
    """Base class of the noise terms."""

    #: the IEEE coefficient the term reports (None if it reports none)
    coefficient: ClassVar[str | None] = None
    #: False for a term without an exact Allan variance (a user's term may declare so): then
    #: ``Gyro.avar`` is an error and study tables and figures say the truth curve is unavailable
    has_exact_avar: ClassVar[bool] = True

    def coefficients(self) -> dict[str, float]:
        """The IEEE coefficient(s) the term stands for, in SI (none by default)."""
        return {}

    def avar(self, m, dt) -> np.ndarray:
        raise NotImplementedError

    def psd(self, f, dt) -> np.ndarray:
        raise NotImplementedError

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

    def stream(self, dt, rng: np.random.Generator) -> TermStream:
        raise NotImplementedError

    def phase_gcov(self, lags, dt) -> np.ndarray:
        """Generalized covariance G(d) of the phase at integer lags (see ``noise_models.exact_variances``).

        Default: from ``autocovariance(max_lag, dt)`` for a stationary term, G = -D/2.
        """
        lags = np.abs(np.asarray(lags, dtype=np.int64))
        if not hasattr(self, "autocovariance"):
            raise NotImplementedError(f"{type(self).__name__}: no phase_gcov and no autocovariance")
        return gcov_from_autocovariance(self.autocovariance(int(lags.max()) if lags.size else 0, dt), lags, dt)

    def simulate(self, n: int, dt, rng: np.random.Generator) -> np.ndarray:
        """``n`` samples (rad/s) of this term alone."""
        return self.stream(_check_dt(dt), rng).next(_check_n(n))

    def __repr__(self) -> str:
        args = ", ".join(f"{k}={v!r}" for k, v in self._params().items())
        return f"{type(self).__name__}({args})"

    def _params(self) -> dict:
        return {}

    def __eq__(self, other) -> bool:
        return type(self) is type(other) and self._params() == other._params()

    def __hash__(self):
        return hash((type(self).__name__, tuple(self._params().items())))


def _omega_dt(f, dt):
    f = np.asarray(f, dtype=float)
    if np.any(f <= 0) or np.any(f > 0.5 / dt * (1 + 1e-12)):
        raise ValueError(f"f: expected frequencies in (0, 1/(2 dt)] = (0, {0.5 / dt}] Hz")
    return f, 2 * np.pi * f * dt


# --- white-noise-driven terms ---------------------------------------------------------------


class _WhiteStream(TermStream):
    def __init__(self, dt, rng, scale):
        super().__init__(dt, rng)
        self.scale = scale

    def next(self, n):
        x = self.rng.standard_normal(n)
        x *= self.scale  # in place: one array, one pass fewer
        return x


class AngleRandomWalk(NoiseTerm):
    """White rate noise: w_k = (N / sqrt(dt)) n_k; AV = N^2 / tau exactly.

    Parameters
    ----------
    N : float or (value, unit)
        Angle random walk coefficient; SI rad/sqrt(s), or e.g. ``(2.24, "deg/sqrt(h)")``.

    Examples
    --------
    >>> import numpy as np
    >>> t = AngleRandomWalk(N=1e-3)
    >>> float(t.avar([1, 10], dt=0.1)[1])  # N^2 / tau at tau = 1 s
    1e-06
    """

    coefficient = "N"

    def __init__(self, N):
        self.N = as_si("N", N)

    def psd_factor(self):
        return self.N**2, AngleRandomWalk(N=1.0)

    def _params(self):
        return {"N": self.N}

    def coefficients(self):
        return {"N": self.N}

    def avar(self, m, dt):
        return self.N**2 / (check_m(m) * _check_dt(dt))

    def psd(self, f, dt):
        f, _ = _omega_dt(f, dt)
        return np.full_like(f, 2 * self.N**2)

    def stream(self, dt, rng):
        return _WhiteStream(_check_dt(dt), rng, self.N / math.sqrt(dt))

    def phase_gcov(self, lags, dt):
        return -(self.N**2) * _check_dt(dt) * np.abs(np.asarray(lags, dtype=float)) / 2


class _QuantStream(TermStream):
    def __init__(self, dt, rng, Q):
        super().__init__(dt, rng)
        self.Q = Q
        self.prev = rng.standard_normal() * Q  # theta_{-1}: the record starts stationary

    def next(self, n):
        out = self.rng.standard_normal(n)
        if n:  # theta_k = Q n_k; w_k = (theta_k - theta_{k-1}) / dt, in place, one pass
            self.prev = _diff_kernel(out, self.Q, self.prev, self.dt)
        return out


class Quantization(NoiseTerm):
    """Quantization noise: white angle noise of std Q, differenced to rate; AV = 3 Q^2 / tau^2.

    The angle noise is Gaussian (SPEC allows Gaussian or uniform with step sqrt(12) Q; the AV is the
    same). The cluster mean of the rate telescopes to (theta_end - theta_start)/tau, so the AV is
    3 Q^2 / tau^2 exactly for every m >= 1.

    Parameters
    ----------
    Q : float or (value, unit)
        Quantization coefficient; SI rad, or e.g. ``(6.87e-3, "urad")``.
    """

    coefficient = "Q"

    def __init__(self, Q):
        self.Q = as_si("Q", Q)

    def psd_factor(self):
        return self.Q**2, Quantization(Q=1.0)

    def _params(self):
        return {"Q": self.Q}

    def coefficients(self):
        return {"Q": self.Q}

    def avar(self, m, dt):
        tau = check_m(m) * _check_dt(dt)
        return 3 * self.Q**2 / tau**2

    def psd(self, f, dt):
        f, w = _omega_dt(f, dt)
        return 2 * self.Q**2 * 4 * np.sin(w / 2) ** 2 / dt

    def stream(self, dt, rng):
        return _QuantStream(_check_dt(dt), rng, self.Q)

    def phase_gcov(self, lags, dt):
        return np.where(np.asarray(lags) == 0, self.Q**2, 0.0)


class _RRWStream(TermStream):
    def __init__(self, dt, rng, K):
        super().__init__(dt, rng)
        self.step = K * math.sqrt(dt)
        self.last = np.zeros(1)

    def next(self, n):
        out = self.rng.standard_normal(n)
        if n:  # w_k = w_{k-1} + K sqrt(dt) n_k: the same sequential sum in one shot or in chunks
            self.last[0] = _walk_kernel(out, self.step, self.last[0])
        return out


class RateRandomWalk(NoiseTerm):
    """Rate random walk: w_k = w_{k-1} + K sqrt(dt) n_k, w_{-1} = 0.

    Exact AV of the sampled walk: (2m^2 + 1) K^2 dt / (6m) = K^2 tau / 3 + K^2 dt^2 / (6 tau);
    the second term is the point-sampling correction (Zhang 2008, Metrologia).

    Parameters
    ----------
    K : float or (value, unit)
        Rate random walk coefficient; SI rad/s^1.5, or e.g. ``(55.44, "deg/h^1.5")``.
    """

    coefficient = "K"

    def __init__(self, K):
        self.K = as_si("K", K)

    def psd_factor(self):
        return self.K**2, RateRandomWalk(K=1.0)

    def _params(self):
        return {"K": self.K}

    def coefficients(self):
        return {"K": self.K}

    def avar(self, m, dt):
        m = check_m(m)
        dt = _check_dt(dt)
        return (2.0 * m * m + 1.0) * self.K**2 * dt / (6.0 * m)

    def psd(self, f, dt):
        f, w = _omega_dt(f, dt)
        return 2 * self.K**2 * dt**2 / (4 * np.sin(w / 2) ** 2)

    def stream(self, dt, rng):
        return _RRWStream(_check_dt(dt), rng, self.K)

    def phase_gcov(self, lags, dt):
        d = np.abs(np.asarray(lags, dtype=float))
        return self.K**2 * _check_dt(dt) ** 3 * (d**3 - d) / 12


class _RampStream(TermStream):
    def __init__(self, dt, rng, R):
        super().__init__(dt, rng)
        self.R = R
        self.k = 0

    def next(self, n):
        out = self.R * self.dt * np.arange(self.k, self.k + n, dtype=float)
        self.k += n
        return out


class RateRamp(NoiseTerm):
    """Deterministic rate ramp w_k = R k dt; AV = R^2 tau^2 / 2 exactly.

    Parameters
    ----------
    R : float or (value, unit)
        Rate ramp coefficient; SI rad/s^2, or e.g. ``(0.35, "deg/h^2")``.
    """

    coefficient = "R"

    def __init__(self, R):
        self.R = as_si("R", R)

    def psd_factor(self):
        return 0.0, self  # deterministic: no spectrum

    def _params(self):
        return {"R": self.R}

    def coefficients(self):
        return {"R": self.R}

    def avar(self, m, dt):
        tau = check_m(m) * _check_dt(dt)
        return self.R**2 * tau**2 / 2

    def psd(self, f, dt):
        f, _ = _omega_dt(f, dt)
        return np.zeros_like(f)

    def stream(self, dt, rng):
        return _RampStream(_check_dt(dt), rng, self.R)

    def phase_gcov(self, lags, dt):
        return np.zeros(np.shape(lags))  # deterministic: no covariance, only a mean (phase_mean)

    def phase_mean(self, k, dt):
        """Phase (angle) x_k = dt sum_{j<k} R j dt = R dt^2 k (k - 1) / 2 (rad)."""
        k = np.asarray(k, dtype=float)
        return self.R * _check_dt(dt) ** 2 * k * (k - 1) / 2


# --- first-order Gauss-Markov ----------------------------------------------------------------


class _AR1Stream(TermStream):
    def __init__(self, dt, rng, sigma, phi):
        super().__init__(dt, rng)
        self.phi = phi
        self.scale = sigma * math.sqrt(1.0 - phi * phi)
        # stationary start: x_{-1} ~ N(0, sigma^2)
        self.zi = np.array([phi * rng.standard_normal() * sigma])

    def next(self, n):
        out = self.rng.standard_normal(n)
        out *= self.scale
        if n:  # x_k = e_k + phi x_{k-1}, in place (the recursion of lfilter([1], [1, -phi]))
            self.zi[0] = _ar1_kernel(out, self.phi, self.zi[0])
        return out


def _diff_kernel_py(x, Q, prev, dt):
    """x_k <- (Q x_k - theta_{k-1}) / dt in place (theta_{-1} = prev); returns theta_last."""
    last = Q * x[x.shape[0] - 1]
    for k in range(x.shape[0] - 1, 0, -1):
        x[k] = (Q * x[k] - Q * x[k - 1]) / dt
    x[0] = (Q * x[0] - prev) / dt
    return last


def _walk_kernel_py(x, step, acc):
    """x_k <- acc_k = acc_{k-1} + step x_k in place; returns the last value."""
    for k in range(x.shape[0]):
        acc = acc + step * x[k]
        x[k] = acc
    return acc


def _ar1_kernel_py(e, phi, z):
    """e_k <- e_k + z, z <- phi e_k (in place); returns the carry phi x_last for the next chunk."""
    for k in range(e.shape[0]):
        x = e[k] + z
        e[k] = x
        z = phi * x
    return z


def _gm_f_over_c2(m: np.ndarray, a: float) -> np.ndarray:
    """f(m) / (1 - phi)^2 with phi = exp(-a), f = m(1-phi^2) - 3phi + 4phi^(m+1) - phi^(2m+1).

    Evaluated without catastrophic cancellation: a Taylor series in a (whose first three
    coefficients vanish identically) where (2m+1) a < 1, the expm1 form elsewhere.
    """
    m = m.astype(float)
    c = -math.expm1(-a)
    out = np.empty_like(m)
    x = (2 * m + 1) * a
    small = x < 1.0
    if np.any(small):
        ms = m[small]
        total = np.zeros_like(ms)
        term_a = a**3 / 6.0  # a^k / k!, starting at k = 3
        for k in range(3, 60):
            ck = -ms * 2.0**k - 3.0 + 4.0 * (ms + 1.0) ** k - (2.0 * ms + 1.0) ** k
            total += (-1) ** k * term_a * ck
            term_a *= a / (k + 1)
            if term_a * (2 * ms.max() + 1) ** (k + 1) < 1e-18 * np.abs(total).min():
                break
        out[small] = total / c**2
    big = ~small
    if np.any(big):
        mb = m[big]
        f = mb * (-math.expm1(-2 * a)) - math.exp(-a) * (
            -4 * np.expm1(-mb * a) + np.expm1(-2 * mb * a)
        )
        out[big] = f / c**2
    return out


def _gm_shape_py(m, a, g, dg):
    """g(m, a) = f(m) / (1 - phi)^2 (:func:`_gm_f_over_c2`, phi = exp(-a)) and its derivative dg/da,
    per cluster size ``m`` (float array), written into ``g`` and ``dg``.

    Element by element, the same two forms as :func:`_gm_f_over_c2`: where (2m+1) a < 1 the Taylor
    series f = sum_{k>=3} (-a)^k / k! c_k, c_k = -m 2^k - 3 + 4 (m+1)^k - (2m+1)^k, and its term-by-term
    derivative f' = sum_{k>=3} (-1)^k a^(k-1) / (k-1)! c_k (powers by recurrence); elsewhere
    f = m (1 - phi^2) - phi (-4 expm1(-m a) + expm1(-2 m a)) and
    f' = 2m phi^2 + 3 phi - 4(m+1) phi^(m+1) + (2m+1) phi^(2m+1)
    = phi (2m expm1(-a) - 4(m+1) expm1(-m a) + (2m+1) expm1(-2 m a)) (no cancellation). Then
    g' = f'/c^2 - 2 f phi / c^3 with c = 1 - phi. Each series stops where its next term is below
    1e-18 of its sum (per element; :func:`_gm_f_over_c2` stops for the whole array at once: the values
    agree to round-off, tests)."""
    c = -math.expm1(-a)
    phi = math.exp(-a)
    for i in range(m.shape[0]):
        mi = m[i]
        if (2.0 * mi + 1.0) * a < 1.0:
            p2, pm, p2m = 8.0, (mi + 1.0) ** 3, (2.0 * mi + 1.0) ** 3
            term = a * a * a / 6.0  # a^k / k!
            dterm = a * a / 2.0  # a^(k-1) / (k-1)!
            f = 0.0
            df = 0.0
            sign = -1.0
            for k in range(3, 60):
                ck = -mi * p2 - 3.0 + 4.0 * pm - p2m
                f += sign * term * ck
                df += sign * dterm * ck
                dterm = term
                term *= a / (k + 1)
                p2 *= 2.0
                pm *= mi + 1.0
                p2m *= 2.0 * mi + 1.0
                sign = -sign
                if term * p2m < 1e-18 * abs(f) and dterm * p2m < 1e-18 * abs(df):
                    break
        else:
            e1 = math.expm1(-mi * a)
            e2 = math.expm1(-2.0 * mi * a)
            f = mi * (-math.expm1(-2.0 * a)) - phi * (-4.0 * e1 + e2)
            df = phi * (2.0 * mi * math.expm1(-a) - 4.0 * (mi + 1.0) * e1 + (2.0 * mi + 1.0) * e2)
        g[i] = f / (c * c)
        dg[i] = df / (c * c) - 2.0 * f * phi / (c * c * c)


class GaussMarkov(NoiseTerm):
    """First-order Gauss-Markov rate noise (Miao et al. 2015, eq. 6), stationary std sigma.

    .. math:: x_k = \\phi x_{k-1} + \\sigma\\sqrt{1-\\phi^2}\\,n_k,\\qquad \\phi = e^{-dt/T_c}

    Exact discrete AV (SPEC): sigma^2 [m(1-phi^2) - 3phi + 4phi^(m+1) - phi^(2m+1)] / [m^2 (1-phi)^2],
    evaluated without cancellation. It reports the bias instability it stands for as SPEC's
    ``B_equiv = 0.6174 sigma / 0.6643 = 0.9294 sigma`` (AV peak matched to the flicker plateau).

    Parameters
    ----------
    sigma : float or (value, unit)
        Stationary standard deviation of the rate (rad/s, or e.g. ``(20, "deg/h")``).
    tc : float
        Correlation time Tc in seconds.
    """

    coefficient = "B"
    shape_parameter = "tc"

    def __init__(self, sigma, tc):
        self.sigma = as_si("B", sigma)
        if self.sigma == 0:
            raise ValueError("sigma: expected a positive standard deviation, got 0")
        self.tc = _positive("tc", tc)

    @classmethod
    def from_bias_instability(cls, B, tau_peak) -> "GaussMarkov":
        """The GM whose AV peak equals the plateau (2 ln2/pi) B^2 at ``tau_peak`` seconds."""
        return cls(sigma=as_si("B", B) / B_EQUIV_OVER_SIGMA, tc=_positive("tau_peak", tau_peak) / GM_PEAK_TAU_OVER_TC)

    def psd_factor(self):
        return self.sigma**2, GaussMarkov(sigma=1.0, tc=self.tc)

    def _params(self):
        return {"sigma": self.sigma, "tc": self.tc}

    def coefficients(self):
        return {"B": B_EQUIV_OVER_SIGMA * self.sigma}

    def phi(self, dt) -> float:
        return math.exp(-_check_dt(dt) / self.tc)

    def avar(self, m, dt):
        m = check_m(m)
        a = _check_dt(dt) / self.tc
        return self.sigma**2 * _gm_f_over_c2(m, a) / m.astype(float) ** 2

    def avar_shape_derivative(self, m, dt):
        """``(avar, d avar / d ln tc)``, analytic (compiled :func:`_gm_shape_py`): with a = dt / tc,
        d/d ln tc = -a d/da. The AV agrees with :meth:`avar` to round-off (a compiled series whose
        stopping rule is per cluster size; :meth:`avar` stays the exact truth of the studies)."""
        mf = check_m(m).astype(float)
        a = _check_dt(dt) / self.tc
        g, dg = np.empty_like(mf), np.empty_like(mf)
        _gm_shape_kernel(mf, a, g, dg)
        scale = self.sigma**2 / (mf * mf)
        return scale * g, scale * (-a) * dg

    def autocovariance(self, lags, dt) -> np.ndarray:
        return self.sigma**2 * self.phi(dt) ** np.asarray(lags, dtype=float)

    def phase_gcov(self, lags, dt):
        lags = np.abs(np.asarray(lags, dtype=np.int64))
        L = int(lags.max()) if lags.size else 0
        return gcov_from_autocovariance(self.autocovariance(np.arange(L + 1), dt), lags, dt)

    def psd(self, f, dt):
        f, w = _omega_dt(f, dt)
        phi = self.phi(dt)
        return 2 * dt * self.sigma**2 * (1 - phi**2) / (1 - 2 * phi * np.cos(w) + phi**2)

    def stream(self, dt, rng):
        return _AR1Stream(_check_dt(dt), rng, self.sigma, self.phi(dt))


# --- flicker bias instability ----------------------------------------------------------------


def _kasdin_walter_h(n_taps: int, alpha: float = 1.0) -> np.ndarray:
    """Impulse response of the fractional-difference filter (1 - z^-1)^(-alpha/2)."""
    k = np.arange(1, n_taps, dtype=float)
    return np.concatenate(([1.0], np.cumprod((alpha / 2 + k - 1) / k)))


@functools.lru_cache(maxsize=8)
def _kasdin_walter_h_cached(n_taps: int) -> np.ndarray:
    h = _kasdin_walter_h(n_taps)
    h.setflags(write=False)
    return h


def _fft_sizes(L: int) -> tuple[int, int]:
    """FFT lengths (first, steady) of the overlap-save filter with ``L`` taps.

    A segment gives nfft - (L - 1) new samples. The first segment is short (nfft ~ 1.5 L: the
    presets' records are L / 2 samples long, so one short segment covers them); the following ones
    are longer (nfft ~ 2-4 L, at most 2^22 unless 2 L is more) so that long streams spend less
    FFT work per sample. Both lengths depend on L only, so every record that starts from the same
    generator shares its prefix, and chunked streaming equals one-shot generation bit for bit.
    Lengths are 2-3-5-smooth (``scipy.fft.next_fast_len``).
    """
    from scipy.fft import next_fast_len

    first = next_fast_len(max(L + L // 2, L - 1 + (1 << 12)), real=True)
    steady = next_fast_len(max(first, 2 * L, min(4 * L, 1 << 22)), real=True)
    return first, steady


@functools.lru_cache(maxsize=4)
def _fir_spectrum(h_bytes: bytes, nfft: int) -> np.ndarray:
    """rfft of the impulse response zero-padded to ``nfft`` (cached across replicates)."""
    H = np.fft.rfft(np.frombuffer(h_bytes, dtype=np.float64), nfft)
    H.setflags(write=False)
    return H


class _FIRStream(TermStream):
    """Overlap-save FIR filtering of white noise in fixed segments (chunk-invariant).

    Segment j filters the buffer [last L-1 noise samples | nfft - L + 1 new ones] with one real FFT
    of length nfft (no zero padding: the first L-1 outputs of the circular convolution are
    discarded). The buffers (noise, spectrum, output) are allocated once per FFT length and reused,
    and the filter's spectrum is cached per (filter, nfft).
    """

    def __init__(self, dt, rng, h, scale):
        super().__init__(dt, rng)
        self.h = h
        self.scale = scale
        self.L = len(h)
        self.sizes = _fft_sizes(self.L)
        self.n_segments = 0
        self._nfft = 0
        # burn-in: L-1 past noise samples, so the first output is already stationary
        self._buffers(self.sizes[0])
        hist = self._x[: self.L - 1]
        rng.standard_normal(out=hist)
        hist *= scale
        self.buf = np.empty(0)

    def _buffers(self, nfft):
        if nfft == self._nfft:
            return
        x = np.empty(nfft)
        if self._nfft:  # carry the history into the new buffer
            x[: self.L - 1] = self._x[self._nfft - (self.L - 1) :]
        self._x, self._X, self._y, self._nfft = x, np.empty(nfft // 2 + 1, complex), np.empty(nfft), nfft
        self._H = _fir_spectrum(self.h.tobytes(), nfft)

    def _segment(self):
        self._buffers(self.sizes[0] if self.n_segments == 0 else self.sizes[1])
        L1, x = self.L - 1, self._x
        w = x[L1:]
        self.rng.standard_normal(out=w)
        w *= self.scale
        X = np.fft.rfft(x, out=self._X)
        X *= self._H
        y = np.fft.irfft(X, self._nfft, out=self._y)[L1:].copy()
        if L1:
            x[:L1] = x[len(x) - L1 :]  # the history of the next segment
        self.n_segments += 1
        return y

    def next(self, n):
        parts = [self.buf]
        have = len(self.buf)
        while have < n:
            y = self._segment()
            parts.append(y)
            have += len(y)
        allv = np.concatenate(parts) if len(parts) > 1 else self.buf
        out, self.buf = allv[:n], allv[n:]
        return out


@functools.lru_cache(maxsize=8)
def _full_autocorrelation(h_bytes: bytes, L: int) -> np.ndarray:
    h = np.frombuffer(h_bytes, dtype=np.float64)
    nfft = 1 << int(math.ceil(math.log2(2 * L)))
    Hf = np.fft.rfft(h, nfft)
    return np.fft.irfft(Hf * np.conj(Hf), nfft)[:L]


class BiasInstability(NoiseTerm):
    """Flicker (1/f) bias instability, Kasdin & Walter (1992) with alpha = 1.

    White noise w ~ N(0, B^2) is filtered by h_0 = 1, h_k = h_{k-1}(alpha/2 + k - 1)/k, truncated to
    ``n_taps = ceil(tau_max / dt)`` taps. With Q_d = B^2 the one-sided PSD is
    2 B^2 dt / |2 sin(pi f dt)| above f ~ 1/tau_max, and the AV has the plateau (2 ln2/pi) B^2 over
    the band dt << tau << tau_max. The discrete AV approaches the plateau from above (AV(1) = 2B^2/pi
    exactly) and, beyond ~tau_max/10, falls off as the truncated filter makes the process white at
    the lowest frequencies: :meth:`avar` gives this exact discrete curve (from the exact
    autocovariance of the truncated filter), which is the truth estimators are scored against.

    Burn-in: the generator starts with n_taps - 1 past noise samples, so every record is an exactly
    stationary moving average (no start-up transient).

    Parameters
    ----------
    B : float or (value, unit)
        Bias instability coefficient; SI rad/s, or e.g. ``(20.8, "deg/h")``.
    tau_max : float
        Length in seconds of the filter memory, the upper edge of the 1/f band (default 1 h). Use at
        least the record length to keep the plateau flat over every usable tau.
    """

    coefficient = "B"

    def __init__(self, B, tau_max: float = 3600.0):
        self.B = as_si("B", B)
        self.tau_max = _positive("tau_max", tau_max)

    def psd_factor(self):
        return self.B**2, BiasInstability(B=1.0, tau_max=self.tau_max)

    def _params(self):
        return {"B": self.B, "tau_max": self.tau_max}

    def coefficients(self):
        return {"B": self.B}

    def n_taps(self, dt) -> int:
        return max(2, int(math.ceil(self.tau_max / _check_dt(dt) - 1e-9)))

    def impulse_response(self, dt) -> np.ndarray:
        return _kasdin_walter_h_cached(self.n_taps(dt))

    def autocovariance(self, max_lag: int, dt) -> np.ndarray:
        """r(0..max_lag) of the truncated-filter process (exact: direct sums or FFT)."""
        h = self.impulse_response(dt)
        L = len(h)
        K = min(L - 1, int(max_lag))
        if (K + 1) * L <= 5e7:  # a few lags: direct dot products
            r = np.array([np.dot(h[: L - k], h[k:]) for k in range(K + 1)])
        else:
            r = _full_autocorrelation(h.tobytes(), L)[: K + 1]
        out = np.zeros(int(max_lag) + 1)
        out[: K + 1] = r
        return self.B**2 * out

    def avar(self, m, dt):
        m = check_m(m)
        return avar_from_autocovariance(self.autocovariance(int(2 * m.max()), dt), m)

    def psd(self, f, dt):
        """One-sided PSD of the ideal (untruncated) filter, 2 B^2 dt / |2 sin(pi f dt)|.

        Exact for the truncated generator only well above f = 1/tau_max.
        """
        f, w = _omega_dt(f, dt)
        return 2 * self.B**2 * dt / np.abs(2 * np.sin(w / 2))

    def stream(self, dt, rng):
        dt = _check_dt(dt)
        return _FIRStream(dt, rng, self.impulse_response(dt), self.B)


# --- second-order Gauss-Markov ---------------------------------------------------------------


class _SOGMStream(TermStream):
    def __init__(self, dt, rng, A, chol, P):
        super().__init__(dt, rng)
        self.A = A
        self.chol = chol
        self.x = np.linalg.cholesky(P) @ rng.standard_normal(2)  # stationary start

    def next(self, n):
        e = self.rng.standard_normal((n, 2))
        out = np.empty(n)
        if n:
            _sogm_kernel(self.A, self.chol, e, self.x, out)
        return out


def _sogm_kernel_py(A, C, e, x, out):
    """x_k = A x_{k-1} + C e_k (C lower-triangular), out_k = first state; x updated in place."""
    a00, a01, a10, a11 = A[0, 0], A[0, 1], A[1, 0], A[1, 1]
    c00, c10, c11 = C[0, 0], C[1, 0], C[1, 1]
    x0, x1 = x[0], x[1]
    for k in range(e.shape[0]):
        w0 = c00 * e[k, 0]
        w1 = c10 * e[k, 0] + c11 * e[k, 1]
        x0, x1 = a00 * x0 + a01 * x1 + w0, a10 * x0 + a11 * x1 + w1
        out[k] = x0
    x[0], x[1] = x0, x1


try:  # compiled when numba is available (it is a dependency); same arithmetic either way
    from numba import njit

    _sogm_kernel = njit(cache=True)(_sogm_kernel_py)
    _ar1_kernel = njit(cache=True)(_ar1_kernel_py)
    _diff_kernel = njit(cache=True)(_diff_kernel_py)
    _walk_kernel = njit(cache=True)(_walk_kernel_py)
    _gm_shape_kernel = njit(cache=True)(_gm_shape_py)
except ImportError:  # pragma: no cover
    _gm_shape_kernel = _gm_shape_py
    _diff_kernel = _diff_kernel_py
    _walk_kernel = _walk_kernel_py
    _sogm_kernel = _sogm_kernel_py
    _ar1_kernel = _ar1_kernel_py


class SecondOrderGaussMarkov(NoiseTerm):
    """Second-order Gauss-Markov process, the rate-ramp stand-in of Miao et al. 2015 (eq. 8).

    .. math:: y = \\frac{q\\,v(t)}{D^2 + \\sqrt2\\,w_0 D + w_0^2}

    discretised exactly (matrix exponential and Van Loan process-noise covariance), started from its
    stationary state. The paper writes the numerator as ``R v``; read literally, that R is not the
    ramp coefficient (the AV for tau << 1/w0 would be R^2 tau^2 / (4 sqrt2 w0)). Here ``R`` is the
    rate-ramp coefficient the process imitates: the driving intensity is chosen so that the
    stationary variance of dy/dt is R^2, which makes AV ~ R^2 tau^2 / 2 for dt << tau << 1/w0.
    Beyond tau ~ 1/w0 the AV peaks and then falls like white noise, N_equiv^2 / tau with
    N_equiv = q / w0^2. :meth:`avar` is exact for the discrete sequence (from its autocovariance).

    Parameters
    ----------
    R : float or (value, unit)
        Ramp coefficient imitated (rad/s^2, or e.g. ``(0.35, "deg/h^2")``).
    w0 : float
        Natural angular frequency (rad/s); the ramp-like band is tau << 1/w0.
    """

    coefficient = "R"

    def __init__(self, R, w0):
        self.R = as_si("R", R)
        if self.R == 0:
            raise ValueError("R: expected a positive ramp coefficient, got 0")
        self.w0 = _positive("w0", w0)

    def _params(self):
        return {"R": self.R, "w0": self.w0}

    def coefficients(self):
        return {"R": self.R}

    @property
    def q(self) -> float:
        """Driving intensity q of eq. 8: Var(dy/dt) = q^2 / (2 sqrt2 w0) = R^2."""
        return self.R * math.sqrt(2 * math.sqrt(2) * self.w0)

    def _continuous(self):
        w0 = self.w0
        F = np.array([[0.0, 1.0], [-(w0**2), -math.sqrt(2) * w0]])
        G = np.array([[0.0], [self.q]])
        return F, G

    def discretise(self, dt):
        """(A, Qd, P): transition, process-noise covariance, stationary covariance."""
        dt = _check_dt(dt)
        F, G = self._continuous()
        n = 2
        M = np.zeros((2 * n, 2 * n))
        M[:n, :n] = -F
        M[:n, n:] = G @ G.T
        M[n:, n:] = F.T
        from scipy.linalg import expm

        E = expm(M * dt)
        A = E[n:, n:].T
        Qd = A @ E[:n, n:]
        Qd = (Qd + Qd.T) / 2
        from scipy.linalg import solve_continuous_lyapunov

        P = solve_continuous_lyapunov(F, -G @ G.T)
        return A, Qd, (P + P.T) / 2

    def autocovariance(self, max_lag: int, dt) -> np.ndarray:
        A, _, P = self.discretise(dt)
        mu, V = np.linalg.eig(A)
        left = V[0, :]  # e1^T V
        right = np.linalg.solve(V, P[:, 0])  # V^-1 P e1
        k = np.arange(max_lag + 1)
        r = np.real((left * right)[None, :] * mu[None, :] ** k[:, None]).sum(axis=1)
        return r

    def avar(self, m, dt):
        m = check_m(m)
        return avar_from_autocovariance(self.autocovariance(int(2 * m.max()), dt), m)

    def psd(self, f, dt):
        f, w = _omega_dt(f, dt)
        A, _, P = self.discretise(dt)
        mu, V = np.linalg.eig(A)
        a = V[0, :] * np.linalg.solve(V, P[:, 0])
        z = np.exp(-1j * w)[:, None] * mu[None, :]
        s = np.real(a[None, :] * z / (1 - z)).sum(axis=1)
        return 2 * dt * (P[0, 0] + 2 * s)

    def stream(self, dt, rng):
        dt = _check_dt(dt)
        A, Qd, P = self.discretise(dt)
        chol = np.linalg.cholesky(Qd + 1e-300 * np.eye(2))
        return _SOGMStream(dt, rng, np.ascontiguousarray(A), chol, P)


# --- sinusoidal noise (IEEE Std 952-1997, Annex C) ------------------------------------------


class _SineStream(TermStream):
    def __init__(self, dt, rng, amplitude, frequency):
        super().__init__(dt, rng)
        self.amplitude = amplitude
        self.w = 2 * math.pi * frequency * dt
        self.phase = rng.uniform(0.0, 2 * math.pi)  # random phase: a stationary process
        self.k = 0

    def next(self, n):
        # each sample from its absolute index: the same values however the record is cut
        k = np.arange(self.k, self.k + n, dtype=float)
        self.k += n
        out = np.sin(self.w * k + self.phase)
        out *= self.amplitude
        return out


class Sinusoidal(NoiseTerm):
    """Sinusoidal rate noise of IEEE Std 952-1997, Annex C: w_k = A sin(2 pi f0 k dt + phi).

    The phase phi is uniform on [0, 2 pi) (drawn once per record), which makes the sequence
    stationary with autocovariance r(k) = (A^2 / 2) cos(omega k), omega = 2 pi f0 dt.

    Exact discrete AV. The mean of m samples of cos(omega k + phi) is the real part of
    e^{i phi} D with |D| = |sin(m omega / 2)| / (m |sin(omega / 2)|); consecutive cluster means
    differ by a phase shift of m omega, |e^{i m omega} - 1| = 2 |sin(m omega / 2)|, so

    .. math:: \\sigma^2(m) = A^2 \\frac{\\sin^4(m\\omega/2)}{m^2 \\sin^2(\\omega/2)}.

    As dt -> 0 at fixed tau = m dt (sin(omega/2) -> pi f0 dt) this is IEEE 952's continuous form,
    Omega_0^2 (sin^2(pi f0 tau) / (pi f0 tau))^2 with Omega_0 = A (Annex C, sinusoidal noise). The AV
    peaks at tau = 0.371 / f0 and is zero at every whole number of periods.

    The term reports no IEEE coefficient (``coefficients()`` is empty); its parameters are
    ``amplitude`` (rad/s) and ``frequency`` (Hz). Its spectrum is a line: :meth:`psd` is zero at
    every frequency but f0 and :meth:`spectral_lines` gives the line's power A^2 / 2.

    Parameters
    ----------
    amplitude : float or (value, unit)
        Amplitude A of the rate (rad/s, or e.g. ``(50, "deg/h")``).
    frequency : float
        Frequency f0 in Hz; at most the Nyquist frequency 1/(2 dt) of the sampling it is used at
        (a higher frequency would alias, and is refused).
    """

    coefficient = None
    shape_parameter = "frequency"

    def __init__(self, amplitude, frequency):
        self.amplitude = as_si("B", amplitude)  # a rate, like B
        if self.amplitude == 0:
            raise ValueError("amplitude: expected a positive amplitude, got 0")
        self.frequency = _positive("frequency", frequency)

    def _params(self):
        return {"amplitude": self.amplitude, "frequency": self.frequency}

    def _omega(self, dt) -> float:
        dt = _check_dt(dt)
        if self.frequency > 0.5 / dt * (1 + 1e-12):
            raise ValueError(
                f"frequency: {self.frequency} Hz is above the Nyquist frequency 1/(2 dt) = {0.5 / dt} Hz "
                "of this sampling; expected a frequency the samples resolve"
            )
        return 2 * math.pi * self.frequency * dt

    def autocovariance(self, lags, dt) -> np.ndarray:
        return 0.5 * self.amplitude**2 * np.cos(self._omega(dt) * np.asarray(lags, dtype=float))

    def avar(self, m, dt):
        m = check_m(m).astype(float)
        w = self._omega(dt)
        return self.amplitude**2 * np.sin(m * w / 2) ** 4 / (m**2 * math.sin(w / 2) ** 2)

    def spectral_lines(self, dt) -> list[tuple[float, float]]:
        """[(f0, power)]: the line's frequency (Hz) and the variance it carries, A^2 / 2."""
        self._omega(dt)
        return [(self.frequency, 0.5 * self.amplitude**2)]

    def psd(self, f, dt):
        """Zero: the spectrum is the line of :meth:`spectral_lines` (a Dirac delta at f0)."""
        self._omega(dt)
        f, _ = _omega_dt(f, dt)
        return np.zeros_like(f)

    def stream(self, dt, rng):
        dt = _check_dt(dt)
        self._omega(dt)
        return _SineStream(dt, rng, self.amplitude, self.frequency)


# --- white noise through the sensor's front-end filter ----------------------------------------


def _boxcar_taps(length: int) -> np.ndarray:
    return np.full(length, 1.0 / length)


class FilteredWhiteNoise(NoiseTerm):
    """White rate noise (angle random walk N) seen through the sensor's own low-pass filter.

    Real sensors filter before they sample: a MEMS IMU averages its internal samples (a moving
    average or Bartlett window before decimation), an IIR low-pass, a FIR set by a register. The
    white noise then reaches the output as y = h * e, e white with variance N^2 / dt, through a
    filter with unit DC gain (sum h = 1): the long-tau AV is still N^2 / tau, and the first octaves
    lie below the white-noise line. Exactly one filter, in output samples:

    ``length=L``
        a moving average of L samples (h = 1/L, ..., 1/L);
    ``taps=h``
        any FIR (normalised here to unit DC gain);
    ``tc=T``
        a first-order low-pass y_k = a y_{k-1} + (1 - a) e_k, a = exp(-dt / T).

    Exact discrete AV. For a FIR with autocovariance r(i) = (N^2 / dt) sum_j h_j h_{j+i} (zero for
    i >= L) and m >= L, 4V(m) - V(2m) = 2 m S - 6 C2 with S = sum over all lags of r = N^2 / dt and
    C2 = sum_{i>=1} i r(i), hence

    .. math:: \\sigma^2(m) = \\frac{N^2}{\\tau} - \\frac{3 C_2}{m^2},

    a *negative* 3 Q^2 / tau^2 term (Q^2 = -C2 dt^2): why a five-term fit reads a filter as negative
    quantization. The moving average: C2 = (N^2 / dt)(L^2 - 1) / (6 L), so
    AV = (N^2 / tau)(1 - (L^2 - 1) / (2 L m)), continuous limit (N^2 / tau)(1 - T / (2 tau)) with
    T = L dt. All m (also m < L) come from the autocovariance (``exact_avar``). The first-order
    low-pass is a Gauss-Markov sequence with sigma^2 = (N^2 / dt)(1 - a) / (1 + a) and phi = a
    (the closed form of :class:`GaussMarkov`); its continuous limit (dt -> 0 at fixed T) is
    (N^2 / tau)[1 - (T / (2 tau))(3 - 4 e^{-tau/T} + e^{-2 tau/T})].

    The filter acts here on the white noise only: on the slow terms (B, K, R) its effect is of
    relative order (T / tau)^2 and negligible at the taus where they show.

    Parameters
    ----------
    N : float or (value, unit)
        Angle random walk coefficient (the white noise before the filter; SI rad/sqrt(s)).
    length, taps, tc :
        The filter (exactly one), see above.
    """

    coefficient = "N"
    #: the first-order filter's time constant (fitted by gmwm_filtered); None for the other filters
    shape_parameter = "tc"

    def __init__(self, N, *, length=None, taps=None, tc=None):
        self.N = as_si("N", N)
        given = [k for k, v in (("length", length), ("taps", taps), ("tc", tc)) if v is not None]
        if len(given) != 1:
            raise ValueError(
                f"FilteredWhiteNoise: expected exactly one filter (length=L, taps=[...] or tc=T), got {given or 'none'}"
            )
        self.length = self.taps = self.tc = None
        if length is not None:
            if isinstance(length, bool) or not isinstance(length, int | np.integer) or length < 1:
                raise ValueError(f"length: expected a positive integer number of samples, got {length!r}")
            self.length = int(length)
        elif taps is not None:
            h = np.asarray(taps, dtype=float)
            if h.ndim != 1 or h.size == 0 or not np.all(np.isfinite(h)) or abs(h.sum()) < 1e-12:
                raise ValueError(f"taps: expected a finite 1-D FIR with non-zero sum (its DC gain), got {taps!r}")
            self.taps = tuple(float(v) for v in h / h.sum())
        else:
            self.tc = _positive("tc", tc)

    def _params(self):
        return {"N": self.N, "length": self.length, "taps": self.taps, "tc": self.tc}

    def coefficients(self):
        return {"N": self.N}

    def impulse_response(self) -> np.ndarray | None:
        """The FIR (unit DC gain), or None for the first-order low-pass."""
        if self.length is not None:
            return _boxcar_taps(self.length)
        return None if self.taps is None else np.array(self.taps)

    def _gauss_markov(self, dt) -> GaussMarkov:
        """The first-order low-pass of white noise as the Gauss-Markov sequence it is."""
        a = math.exp(-_check_dt(dt) / self.tc)
        return GaussMarkov(sigma=math.sqrt(self.N**2 / dt * (1 - a) / (1 + a)), tc=self.tc)

    def autocovariance(self, max_lag: int, dt) -> np.ndarray:
        """r(0..max_lag) of the filtered sequence (exact)."""
        dt = _check_dt(dt)
        lags = np.arange(int(max_lag) + 1)
        h = self.impulse_response()
        if h is None:
            return self._gauss_markov(dt).autocovariance(lags, dt)
        full = np.correlate(h, h, mode="full")[len(h) - 1 :]  # sum_j h_j h_{j+i}, i = 0..L-1
        out = np.zeros(len(lags))
        k = min(len(full), len(out))
        out[:k] = full[:k]
        return self.N**2 / dt * out

    def avar(self, m, dt):
        m = check_m(m)
        dt = _check_dt(dt)
        if self.impulse_response() is None:
            return self._gauss_markov(dt).avar(m, dt)
        h = self.impulse_response()
        r = self.autocovariance(len(h), dt)
        out = np.empty(len(m))
        small = m < len(h)
        if np.any(small):
            out[small] = avar_from_autocovariance(r, m[small])
        if np.any(~small):  # the closed form above (m >= L): no sums of length 2m
            c2 = float(np.dot(np.arange(1, len(r)), r[1:]))
            mb = m[~small].astype(float)
            out[~small] = self.N**2 / (mb * dt) - 3 * c2 / mb**2
        return out

    def gain2(self, f, dt) -> np.ndarray:
        """|H(e^{i 2 pi f dt})|^2, the filter's power gain (1 at f = 0)."""
        f, w = _omega_dt(f, dt)
        h = self.impulse_response()
        if h is None:
            a = math.exp(-dt / self.tc)
            return (1 - a) ** 2 / (1 - 2 * a * np.cos(w) + a * a)
        H = np.exp(-1j * np.outer(w, np.arange(len(h)))) @ h
        return np.abs(H) ** 2

    def psd(self, f, dt):
        return 2 * self.N**2 * self.gain2(f, dt)

    def stream(self, dt, rng):
        dt = _check_dt(dt)
        h = self.impulse_response()
        if h is None:
            return self._gauss_markov(dt).stream(dt, rng)
        return _FIRStream(dt, rng, np.ascontiguousarray(h), self.N / math.sqrt(dt))


# --- a resonance: band-pass (oscillatory) Gauss-Markov noise --------------------------------------


def _gm_form(m: np.ndarray, alpha: complex) -> np.ndarray:
    """F(m) = [m(1 - phi^2) - 3 phi + 4 phi^(m+1) - phi^(2m+1)] / [m^2 (1 - phi)^2] at phi = exp(-alpha),
    complex alpha (Re alpha > 0): the Gauss-Markov AV per unit variance (:class:`GaussMarkov`), an
    algebraic identity in phi that holds for complex phi too. The expm1 form (no cancellation in
    1 - phi^k); callers keep (2m + 1)|alpha| >= 1, below which the form loses digits."""
    mf = m.astype(float)
    c = -np.expm1(-alpha)
    f = mf * (-np.expm1(-2 * alpha)) - np.exp(-alpha) * (-4 * np.expm1(-mf * alpha) + np.expm1(-2 * mf * alpha))
    return f / (mf * mf * c * c)


class Resonance(NoiseTerm):
    r"""Band-pass (oscillatory) Gauss-Markov rate noise: the noise of a lightly damped mode at f0.

    A MEMS gyro's drive or sense mode, a mount's structural mode, a neighbouring rotor: power in a
    band around f0 of width ~1/(pi tc) and none at f = 0 (it is not a bias). Beyond IEEE Std 952
    (whose exponentially correlated term is the f0 = 0 member of the family). The discrete sequence
    is the ARMA(2, 1)

    .. math:: x_k = 2\rho\cos\omega\,x_{k-1} - \rho^2 x_{k-2} + s\,(e_k - e_{k-1}),\qquad
        \rho = e^{-dt/t_c},\ \omega = 2\pi f_0\,dt ,

    (poles rho e^{+-i omega}, the MA zero at 1 takes out the power at f = 0), s set so that the
    stationary variance is sigma^2. Its autocovariance is

    .. math:: r(k) = \sigma^2 \rho^{|k|} [\cos(\omega k) - c \sin(\omega |k|)] = \sigma^2\,
        \mathrm{Re}[(1 + i c)\,\phi^{|k|}],\qquad \phi = \rho e^{i\omega},\quad
        c = \frac{1 - \rho^2}{2 \rho \sin\omega},

    c from the zero at f = 0 (sum over all lags of r = sigma^2 Re[(1 + i c)(1 + phi)/(1 - phi)] = 0). The
    AV is linear in r and the first-order Gauss-Markov AV (:class:`GaussMarkov`) is an algebraic identity
    in phi, so the exact discrete AV is

    .. math:: \sigma^2(m) = \sigma^2\,\mathrm{Re}\,\{(1 + i c)\,F_m(\phi)\},\qquad
        F_m(\phi) = \frac{m(1-\phi^2) - 3\phi + 4\phi^{m+1} - \phi^{2m+1}}{m^2 (1-\phi)^2}

    (the extended-precision autocovariance route of ``exact_avar`` where (2m + 1)|ln phi| < 1, where the
    closed form would lose digits). It peaks near tau = 0.371 / f0 as a sinusoid's and falls as 1/tau^2
    beyond the band (no white-noise or bias share at long tau). Continuous limit (dt -> 0 at fixed f0,
    tc): c -> 1 / (2 pi f0 tc), the velocity of a damped oscillator driven by white noise. ``frequency``
    must lie below the Nyquist frequency (at it, sin omega = 0).

    Parameters
    ----------
    sigma : float or (value, unit)
        Stationary standard deviation of the rate (rad/s, or e.g. ``(300, "deg/h")``).
    frequency : float
        Centre frequency f0 in Hz, 0 < f0 < 1/(2 dt).
    tc : float
        Damping time in seconds (the band's half width at half power ~ 1/(2 pi tc)).
    """

    coefficient = None

    def __init__(self, sigma, frequency, tc):
        self.sigma = as_si("B", sigma)  # a rate, like B
        if self.sigma == 0:
            raise ValueError("sigma: expected a positive standard deviation, got 0")
        self.frequency = _positive("frequency", frequency)
        self.tc = _positive("tc", tc)

    @classmethod
    def shape_parameters(cls):
        return ("frequency", "tc")

    def _params(self):
        return {"sigma": self.sigma, "frequency": self.frequency, "tc": self.tc}

    def psd_factor(self):
        return self.sigma**2, Resonance(sigma=1.0, frequency=self.frequency, tc=self.tc)

    def _poles(self, dt):
        """(rho, omega, c) of the sampling ``dt``; a ValueError at or above the Nyquist frequency."""
        dt = _check_dt(dt)
        if self.frequency >= 0.5 / dt * (1 - 1e-12):
            raise ValueError(
                f"frequency: {self.frequency} Hz is not below the Nyquist frequency 1/(2 dt) = {0.5 / dt} Hz "
                "of this sampling; expected a frequency the samples resolve"
            )
        rho, w = math.exp(-dt / self.tc), 2 * math.pi * self.frequency * dt
        return rho, w, -math.expm1(-2 * dt / self.tc) / (2 * rho * math.sin(w))

    def autocovariance(self, lags, dt) -> np.ndarray:
        """r at the given lags (or at 0..lags for an integer, as the FIR terms), exact."""
        rho, w, c = self._poles(dt)
        k = np.abs(np.arange(int(lags) + 1) if np.ndim(lags) == 0 else np.asarray(lags, dtype=float))
        return self.sigma**2 * rho**k * (np.cos(w * k) - c * np.sin(w * k))

    def avar(self, m, dt):
        m = check_m(m)
        rho, w, c = self._poles(dt)
        alpha = complex(dt / self.tc, -w)  # phi = exp(-alpha) = rho e^{i w}
        out = np.empty(m.size)
        small = (2 * m + 1) * abs(alpha) < 1.0
        if np.any(small):
            out[small] = avar_from_autocovariance(self.autocovariance(int(2 * m[small].max()), dt), m[small])
        if np.any(~small):
            out[~small] = self.sigma**2 * np.real((1 + 1j * c) * _gm_form(m[~small], alpha))
        return out

    def psd(self, f, dt):
        """One-sided: 2 dt [r(0) + 2 sum_{k>=1} r(k) cos(k theta)], summed in closed form."""
        rho, w, c = self._poles(dt)
        f, theta = _omega_dt(f, dt)
        phi = rho * np.exp(1j * w)
        z1, z2 = phi * np.exp(1j * theta), phi * np.exp(-1j * theta)
        s = np.real((1 + 1j * c) * (z1 / (1 - z1) + z2 / (1 - z2)))
        return 2 * dt * self.sigma**2 * (1 + s)

    def arma(self, dt):
        """(A, G, P): the state-space form of the ARMA(2, 1) (state (x_k, u_k), x_k = a1 x_{k-1} + u_{k-1}
        + s e_k, u_k = a2 x_{k-1} - s e_k), its noise loading and stationary state covariance."""
        from scipy.linalg import solve_discrete_lyapunov

        rho, w, _ = self._poles(dt)
        A = np.array([[2 * rho * math.cos(w), 1.0], [-rho * rho, 0.0]])
        g = np.array([1.0, -1.0])
        P1 = solve_discrete_lyapunov(A, np.outer(g, g))
        s = self.sigma / math.sqrt(P1[0, 0])
        return A, s * g, s * s * (P1 + P1.T) / 2

    def stream(self, dt, rng):
        dt = _check_dt(dt)
        A, G, P = self.arma(dt)
        chol = np.array([[G[0], 0.0], [G[1], 0.0]])  # one driving noise: x_k's and u_k's share e_k
        return _SOGMStream(dt, rng, np.ascontiguousarray(A), chol, P)
