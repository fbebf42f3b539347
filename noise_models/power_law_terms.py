"""The five terms of IEEE Std 952-1997's Allan-variance model, each a power law of tau over its band.

=====================  ==========================================  =======================================
term                   generator                                   exact AV at tau = m dt
=====================  ==========================================  =======================================
Quantization(Q)        theta_k ~ N(0, Q^2), w_k = (theta_k -        3 Q^2 / tau^2
                       theta_{k-1}) / dt
AngleRandomWalk(N)     w_k = (N / sqrt(dt)) n_k                     N^2 / tau
BiasInstability(B)     Kasdin & Walter (1992) 1/f FIR, Q_d = B^2    from the exact autocovariance
RateRandomWalk(K)      w_k = w_{k-1} + K sqrt(dt) n_k               K^2 tau / 3 + K^2 dt^2 / (6 tau)
RateRamp(R)            w_k = R k dt                                 R^2 tau^2 / 2
=====================  ==========================================  =======================================

(SPEC, "Discrete generators and their exact Allan variance"; the interface:
:mod:`avbench.noise_models.term_base`.) Overlap-save FIR filtering of white noise (:class:`_FIRStream`)
generates the flicker term, and the sensor filters of :class:`avbench.noise_models.FilteredWhiteNoise`.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from avbench.noise_models._term_kernels import _diff_kernel, _walk_kernel
from avbench.noise_models.exact_avar import avar_from_autocovariance, check_m
from avbench.noise_models.term_base import (PLATEAU, NoiseTerm, StateBlock, TermStream, _check_dt, _grid_value,
                                            _omega_dt, _positive)
from avbench.noise_models.units import as_si

__all__ = ["Quantization", "AngleRandomWalk", "BiasInstability", "RateRandomWalk", "RateRamp"]


# --- white noise, quantization, random walk and ramp -----------------------------------------


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
    latent = "WN"
    fit_parameters = ("N",)
    block_mean_states = 0

    @classmethod
    def block_mean_block(cls, values, m, dt):
        """No state: the block mean of white noise is white, of variance N^2 / (m dt)."""
        none = np.zeros((0, 0))
        return StateBlock(none, none, np.zeros(0), none, H=values[0] ** 2 / (m * dt))

    @classmethod
    def likelihood_start(cls, values, tau, avar):
        """The fitted N, or 1 % of the white line through the shortest tau's AV where the fit found none."""
        return (values[0] if values[0] > 0 else 0.01 * math.sqrt(avar[0] * tau[0]),)

    @classmethod
    def from_fit(cls, values, *, tau_max=None):
        return cls(N=values[0])

    @classmethod
    def fit_amplitude_top(cls, tau, avar):
        return math.sqrt(np.max(avar * tau))

    @classmethod
    def fit_starts(cls, tau, avar, lo, hi, *, n_starts=1, hint=None):
        """Half the white line through the shortest tau's AV."""
        return [(math.sqrt(avar[0] * tau[0]) / 2,)]

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

    def autocovariance(self, lags, dt):
        """N^2 / dt at lag 0, 0 elsewhere (white)."""
        return np.where(np.asarray(lags) == 0, self.N**2 / _check_dt(dt), 0.0)

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
    latent = "QN"
    fit_parameters = ("Q",)
    block_mean_states = 2

    @classmethod
    def block_mean_block(cls, values, m, dt):
        """States ``(theta_j, theta_{j-1})``, the angle errors at the ends of blocks j and j - 1 (white, of
        std Q): the block mean of the quantization rate telescopes to their difference over m dt."""
        Q2 = values[0] ** 2
        return StateBlock(np.array([[0.0, 0.0], [1.0, 0.0]]), np.array([[Q2, 0.0], [0.0, 0.0]]),
                          np.array([1.0 / (m * dt), -1.0 / (m * dt)]), np.array([[Q2, 0.0], [0.0, Q2]]))

    @classmethod
    def likelihood_start(cls, values, tau, avar):
        """The fitted Q, or 1 % of the quantization line through the shortest tau's AV where the fit found
        none."""
        return (values[0] if values[0] > 0 else 0.01 * math.sqrt(avar[0] * tau[0] ** 2 / 3),)

    @classmethod
    def from_fit(cls, values, *, tau_max=None):
        return cls(Q=values[0])

    @classmethod
    def fit_amplitude_top(cls, tau, avar):
        return math.sqrt(np.max(avar * tau**2) / 3)

    @classmethod
    def fit_starts(cls, tau, avar, lo, hi, *, n_starts=1, hint=None):
        """Half the quantization line through the shortest tau's AV."""
        return [(math.sqrt(avar[0] * tau[0] ** 2 / 3) / 2,)]

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
        grid = f
        f, w = _omega_dt(f, dt)
        return 2 * self.Q**2 * 4 * _grid_value(grid, dt, "sin(w/2)", w) ** 2 / dt

    def stream(self, dt, rng):
        return _QuantStream(_check_dt(dt), rng, self.Q)

    def autocovariance(self, lags, dt):
        """The differenced white angle noise: 2 Q^2 / dt^2 at lag 0, -Q^2 / dt^2 at lags +-1, 0 beyond."""
        d = np.abs(np.asarray(lags))
        dt = _check_dt(dt)
        return np.where(d == 0, 2 * self.Q**2 / dt**2, np.where(d == 1, -(self.Q**2) / dt**2, 0.0))

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
    stationary = False
    latent = "RW"
    fit_parameters = ("K",)
    block_mean_states = 0

    @classmethod
    def block_mean_block(cls, values, m, dt):
        """No state of its own: it moves the shared level, :math:`L_{j+1} = L_j + \\sum_{i=1}^m w_{(i)}`,
        :math:`\\bar L_{j+1} = L_j + \\tfrac1m\\sum_{i=1}^m i\\,w_{(i)}` (var w = K^2 dt), whose disturbance
        covariance this is."""
        K2dt = values[0] ** 2 * dt
        j = np.arange(1, m + 1, dtype=float)
        level = K2dt * np.array([[m, j.sum() / m], [j.sum() / m, (j @ j) / m**2]])
        none = np.zeros((0, 0))
        return StateBlock(none, none, np.zeros(0), none, level=level)

    @classmethod
    def likelihood_start(cls, values, tau, avar):
        """The fitted K, at least 1 % of :meth:`fit_amplitude_top`."""
        return (max(values[0], 0.01 * cls.fit_amplitude_top(tau, avar)),)

    @classmethod
    def from_fit(cls, values, *, tau_max=None):
        return cls(K=values[0])

    @classmethod
    def fit_amplitude_top(cls, tau, avar):
        return math.sqrt(np.max(3 * avar / tau))

    @classmethod
    def fit_starts(cls, tau, avar, lo, hi, *, n_starts=1, hint=None):
        """Half the random-walk line through the longest tau's AV."""
        return [(math.sqrt(3 * avar[-1] / tau[-1]) / 2,)]

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
        grid = f
        f, w = _omega_dt(f, dt)
        return 2 * self.K**2 * dt**2 / (4 * _grid_value(grid, dt, "sin(w/2)", w) ** 2)

    def stream(self, dt, rng):
        return _RRWStream(_check_dt(dt), rng, self.K)

    def autocovariance(self, lags, dt):
        """None: the random walk is not stationary (a ValueError; :meth:`phase_gcov` holds its exact
        statistics)."""
        raise self._not_stationary()

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
    deterministic = True
    latent = "DR"
    fit_parameters = ("R",)
    block_mean_states = 1

    @classmethod
    def block_mean_block(cls, values, m, dt):
        """The slope r, a diffuse constant state, entering the level as :math:`L_{j+1} = L_j + r\\,m\\Delta t`,
        :math:`\\bar L_{j+1} = L_j + r\\Delta t\\,\\tfrac{m+1}2`."""
        return StateBlock(np.ones((1, 1)), np.zeros((1, 1)), np.zeros(1), np.zeros((1, 1)),
                          level_input=np.array([[m * dt], [dt * (m + 1) / 2]]))

    @classmethod
    def block_mean_derivatives(cls, values, m, dt, block):
        """None: the slope is a state, not a parameter."""
        return []

    @classmethod
    def from_fit(cls, values, *, tau_max=None):
        return cls(R=values[0])

    @classmethod
    def fit_amplitude_top(cls, tau, avar):
        return math.sqrt(np.max(2 * avar / tau**2))

    @classmethod
    def fit_starts(cls, tau, avar, lo, hi, *, n_starts=1, hint=None):
        """A quarter of the ramp line through the longest tau's AV."""
        return [(math.sqrt(2 * avar[-1] / tau[-1] ** 2) / 4,)]

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

    def autocovariance(self, lags, dt):
        """Zero: the ramp is deterministic (a mean, :meth:`phase_mean`, and no covariance)."""
        _check_dt(dt)
        return np.zeros(np.shape(lags))

    def phase_gcov(self, lags, dt):
        return np.zeros(np.shape(lags))  # deterministic: no covariance, only a mean (phase_mean)

    def phase_mean(self, k, dt):
        """Phase (angle) x_k = dt sum_{j<k} R j dt = R dt^2 k (k - 1) / 2 (rad)."""
        k = np.asarray(k, dtype=float)
        return self.R * _check_dt(dt) ** 2 * k * (k - 1) / 2


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
    latent = "FL"
    fit_parameters = ("B",)

    @classmethod
    def from_fit(cls, values, *, tau_max=None):
        """The flicker term of bias instability ``values[0]`` and filter memory ``tau_max`` (required)."""
        return cls(B=values[0], tau_max=tau_max)

    @classmethod
    def fit_amplitude_top(cls, tau, avar):
        return math.sqrt(np.max(avar) / PLATEAU)

    @classmethod
    def fit_starts(cls, tau, avar, lo, hi, *, n_starts=1, hint=None):
        """Half the B whose plateau is the curve's lowest AV."""
        return [(math.sqrt(np.min(avar) / PLATEAU) / 2,)]

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

    def autocovariance(self, lags, dt) -> np.ndarray:
        """r at ``lags`` of the truncated-filter process, B^2 sum_j h_j h_{j+|k|} (zero from the filter's
        length on; exact: direct sums or FFT)."""
        d = np.abs(np.asarray(lags, dtype=np.int64))
        max_lag = int(d.max()) if d.size else 0
        h = self.impulse_response(dt)
        L = len(h)
        K = min(L - 1, max_lag)
        if (K + 1) * L <= 5e7:  # a few lags: direct dot products
            r = np.array([np.dot(h[: L - k], h[k:]) for k in range(K + 1)])
        else:
            r = _full_autocorrelation(h.tobytes(), L)[: K + 1]
        out = np.zeros(max_lag + 1)
        out[: K + 1] = r
        return (self.B**2 * out)[d]

    def psd_autocovariance(self, lags, dt) -> np.ndarray:
        """The autocovariance of the ideal 1/f spectrum :meth:`psd` up to a constant: minus its variogram,
        -B^2 (psi(|k| + 1/2) - psi(1/2)) / pi (psi the digamma function; Kasdin & Walter 1992, alpha = 1)."""
        from scipy.special import digamma

        _check_dt(dt)
        k = np.abs(np.asarray(lags, dtype=float))
        return self.B**2 * (-(digamma(k + 0.5) - digamma(0.5)) / math.pi)

    def avar(self, m, dt):
        m = check_m(m)
        return avar_from_autocovariance(self.autocovariance(np.arange(int(2 * m.max()) + 1), dt), m)

    def psd(self, f, dt):
        """One-sided PSD of the ideal (untruncated) filter, 2 B^2 dt / |2 sin(pi f dt)|.

        Exact for the truncated generator only well above f = 1/tau_max.
        """
        grid = f
        f, w = _omega_dt(f, dt)
        return 2 * self.B**2 * dt / np.abs(2 * _grid_value(grid, dt, "sin(w/2)", w))

    def stream(self, dt, rng):
        dt = _check_dt(dt)
        return _FIRStream(dt, rng, self.impulse_response(dt), self.B)
