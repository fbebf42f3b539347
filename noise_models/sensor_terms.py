"""Terms of real sensors beyond the IEEE five: a sinusoid, white noise through the sensor's own low-pass
filter, and a resonance.

=====================  ==========================================  =======================================
term                   generator                                   exact AV at tau = m dt
=====================  ==========================================  =======================================
Sinusoidal(A, f0)      A sin(2 pi f0 k dt + phi), phi uniform       A^2 sin^4(m w/2) / (m^2 sin^2(w/2)),
                       (IEEE Std 952-1997, Annex C)                 w = 2 pi f0 dt
FilteredWhiteNoise(N)  white noise N through the sensor's low-pass  N^2/tau - 3 C2 / m^2 (FIR, m >= L);
                       (moving average, FIR or first-order IIR)     the GM form (first-order IIR)
Resonance(sigma, f0,   band-pass Gauss-Markov: ARMA(2,1), poles     Re[(1 + i c) GM form at complex phi]
          tc)          rho e^{+-i w}, MA zero at 1 (a structural    (closed form, :class:`Resonance`)
                       mode's noise; no power at f = 0)
=====================  ==========================================  =======================================

(SPEC, "Discrete generators and their exact Allan variance"; the interface:
:mod:`avbench.noise_models.term_base`.)
"""

from __future__ import annotations

import functools
import math

import numpy as np

from avbench.noise_models.exact_avar import avar_from_autocovariance, check_m
from avbench.noise_models._term_kernels import _resonance_rows_kernel, numpy_complex_product
from avbench.noise_models.markov_terms import GaussMarkov, _gm_central, _SOGMStream
from avbench.noise_models.power_law_terms import _FIRStream
from avbench.noise_models.term_base import NoiseTerm, TermStream, _check_dt, _grid_value, _omega_dt, _positive
from avbench.noise_models.units import as_si

__all__ = ["Sinusoidal", "FilteredWhiteNoise", "Resonance", "RESONANCE_MAX_FREQUENCY", "GRADIENT_PHASE_STEP"]

#: a fitted resonance is centred below this fraction of the sampling rate (at the Nyquist frequency its
#: autocovariance's sine weight, (1 - rho^2) / (2 rho sin w), has no finite value)
RESONANCE_MAX_FREQUENCY = 0.45


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
    ``A`` (rad/s) and ``f0`` (Hz), named alike in the constructor and a fit (:attr:`fit_parameters`). Its spectrum is a line: :meth:`psd` is zero at
    every frequency but f0 and :meth:`spectral_lines` gives the line's power A^2 / 2.

    Parameters
    ----------
    A : float or (value, unit)
        Amplitude of the rate (rad/s, or e.g. ``(50, "deg/h")``).
    f0 : float
        Frequency in Hz; at most the Nyquist frequency 1/(2 dt) of the sampling it is used at
        (a higher frequency would alias, and is refused).
    """

    coefficient = None
    shape_parameter = "f0"
    latent = "SN"
    fit_parameters = ("A", "f0")

    @classmethod
    def from_fit(cls, values, *, tau_max=None):
        return cls(A=values[0], f0=values[1])

    @classmethod
    def fit_amplitude_top(cls, tau, avar):
        """The amplitude whose AV peak (0.525 A^2) is the curve's highest AV."""
        return math.sqrt(np.max(avar) / 0.525)

    @classmethod
    def fit_shape_bounds(cls, tau, dt, T, hint=None):
        """A frequency the fitted taus see (AV peak 0.371 / f0 inside the tau range, at most the Nyquist
        frequency), within ``hint.window`` where given (a spectral line found in the record: the periodogram
        places it to a few 1/T, the AV curve hardly at all, and a free f0 wanders off the line to shape
        another part of the curve)."""
        f_lo, f_hi = 0.371 / tau[-1], 0.5 / dt
        if hint is not None and hint.window is not None:
            f_lo = max(f_lo, hint.window[0])
            f_hi = min(f_hi, hint.window[1])
        return [math.log(f_lo)], [math.log(max(f_hi, f_lo * 1.001))]

    @classmethod
    def fit_starts(cls, tau, avar, lo, hi, *, n_starts=1, hint=None):
        """At ``hint.starts`` (a spectral line's amplitude and frequency) where given, else at the eight
        strongest bumps of the curve (AV over the geometric mean of its neighbours): the peak tau 0.371 / f0
        there, the peak AV 0.525 A^2 half the bump; each moved inside the box."""
        if hint is not None and hint.starts:
            sn = list(hint.starts)
        else:
            bump = np.full(tau.size, -np.inf)
            if tau.size >= 3:
                bump[1:-1] = np.log(avar[1:-1]) - 0.5 * (np.log(avar[:-2]) + np.log(avar[2:]))
            order = [i for i in np.argsort(-bump)[:8] if np.isfinite(bump[i])] or [0]
            sn = [(math.sqrt(avar[i] / 0.525) / 2, 0.371 / tau[i]) for i in order]
        return [(min(max(amp, math.exp(lo[0]) * 1.01), math.exp(hi[0]) / 1.01),
                 min(max(f0, math.exp(lo[1]) * 1.01), math.exp(hi[1]) / 1.01)) for amp, f0 in sn]

    def __init__(self, A, f0):
        self.A = as_si("B", A)  # a rate, like B
        if self.A == 0:
            raise ValueError("A: expected a positive amplitude, got 0")
        self.f0 = _positive("f0", f0)

    def _params(self):
        return {"A": self.A, "f0": self.f0}

    def _omega(self, dt) -> float:
        dt = _check_dt(dt)
        if self.f0 > 0.5 / dt * (1 + 1e-12):
            raise ValueError(
                f"f0: {self.f0} Hz is above the Nyquist frequency 1/(2 dt) = {0.5 / dt} Hz "
                "of this sampling; expected a frequency the samples resolve"
            )
        return 2 * math.pi * self.f0 * dt

    def autocovariance(self, lags, dt) -> np.ndarray:
        """(A^2 / 2) cos(omega k)."""
        return 0.5 * self.A**2 * np.cos(self._omega(dt) * np.asarray(lags, dtype=float))

    def avar(self, m, dt):
        m = check_m(m).astype(float)
        w = self._omega(dt)
        return self.A**2 * np.sin(m * w / 2) ** 4 / (m**2 * math.sin(w / 2) ** 2)

    def avar_shape_derivative(self, m, dt):
        """``(avar, d avar / d ln f0)``, the derivative analytic: with s = sin(m omega / 2), d/d ln f0 =
        omega d/d omega,

        .. math:: \\frac{\\partial\\sigma^2(m)}{\\partial\\ln f_0} = \\frac{A^2\\,\\omega\\,s^3}{m^2\\sin^2(\\omega/2)}
            \\left[2m\\cos(m\\omega/2) - s\\cot(\\omega/2)\\right].

        Why not a central difference: at long taus the AV oscillates in f0 with period 2 / (m dt) (a zero at
        every whole number of periods), so a step of 1e-4 in ln f0 spans several oscillations where m omega
        exceeds ~1e4 (a 13 Hz line at 100 Hz from tau ~ 100 s on): the difference is then no derivative, the
        fit's Jacobian is wrong there, and its solves stop where the rounding of their path leaves them (a
        record's answer moved by 1e-4 of its AV between units)."""
        mf = check_m(m).astype(float)
        w = self._omega(dt)
        half, sw = mf * w / 2, math.sin(w / 2)
        s = np.sin(half)
        value = self.A**2 * s**4 / (mf**2 * sw**2)
        d = self.A**2 * w * s**3 * (2 * mf * np.cos(half) - s * (math.cos(w / 2) / sw)) / (mf**2 * sw**2)
        return value, d

    def spectral_lines(self, dt) -> list[tuple[float, float]]:
        """[(f0, power)]: the line's frequency (Hz) and the variance it carries, A^2 / 2."""
        self._omega(dt)
        return [(self.f0, 0.5 * self.A**2)]

    def psd(self, f, dt):
        """Zero: the spectrum is the line of :meth:`spectral_lines` (a Dirac delta at f0)."""
        self._omega(dt)
        f, _ = _omega_dt(f, dt)
        return np.zeros_like(f)

    def stream(self, dt, rng):
        dt = _check_dt(dt)
        self._omega(dt)
        return _SineStream(dt, rng, self.A, self.f0)


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
    ``tf=T``
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
    length, taps, tf :
        The filter (exactly one), see above; ``tf`` is named alike in a fit (:attr:`fit_parameters`).
    """

    coefficient = "N"
    #: the first-order filter's time constant (fitted by gmwm_filtered); None for the other filters
    shape_parameter = "tf"
    latent = "FW"
    fit_parameters = ("N", "tf")

    @classmethod
    def from_fit(cls, values, *, tau_max=None):
        """White noise ``values[0]`` through the first-order low-pass of time constant ``values[1]``."""
        return cls(N=values[0], tf=values[1])

    @classmethod
    def fit_amplitude_top(cls, tau, avar):
        return math.sqrt(np.max(avar * tau))

    @classmethod
    def fit_shape_bounds(cls, tau, dt, T, hint=None):
        """The filter's time constant: from far below dt (a white record) to 16 shortest taus."""
        return [math.log(dt / 100)], [math.log(max(dt, tau[0]) * 16)]

    @classmethod
    def fit_starts(cls, tau, avar, lo, hi, *, n_starts=1, hint=None):
        """N on the curve's highest white line, tf a quarter of the shortest tau."""
        return [(math.sqrt(np.max(avar * tau)), tau[0] / 4)]

    def __init__(self, N, *, length=None, taps=None, tf=None):
        self.N = as_si("N", N)
        given = [k for k, v in (("length", length), ("taps", taps), ("tf", tf)) if v is not None]
        if len(given) != 1:
            raise ValueError(
                f"FilteredWhiteNoise: expected exactly one filter (length=L, taps=[...] or tf=T), got {given or 'none'}"
            )
        self.length = self.taps = self.tf = None
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
            self.tf = _positive("tf", tf)

    def _params(self):
        return {"N": self.N, "length": self.length, "taps": self.taps, "tf": self.tf}

    def coefficients(self):
        return {"N": self.N}

    def impulse_response(self) -> np.ndarray | None:
        """The FIR (unit DC gain), or None for the first-order low-pass."""
        if self.length is not None:
            return _boxcar_taps(self.length)
        return None if self.taps is None else np.array(self.taps)

    def _gauss_markov(self, dt) -> GaussMarkov:
        """The first-order low-pass of white noise as the Gauss-Markov sequence it is."""
        a = math.exp(-_check_dt(dt) / self.tf)
        return GaussMarkov(sigma=math.sqrt(self.N**2 / dt * (1 - a) / (1 + a)), tc=self.tf)

    def autocovariance(self, lags, dt) -> np.ndarray:
        """r at ``lags`` of the filtered sequence (exact): (N^2 / dt) sum_j h_j h_{j+|k|} for a FIR, the
        Gauss-Markov form for the first-order low-pass."""
        dt = _check_dt(dt)
        h = self.impulse_response()
        if h is None:
            return self._gauss_markov(dt).autocovariance(lags, dt)
        d = np.abs(np.asarray(lags, dtype=np.int64))
        full = np.correlate(h, h, mode="full")[len(h) - 1 :]  # sum_j h_j h_{j+i}, i = 0..L-1
        out = np.zeros((int(d.max()) if d.size else 0) + 1)
        k = min(len(full), len(out))
        out[:k] = full[:k]
        return (self.N**2 / dt * out)[d]

    def avar(self, m, dt):
        m = check_m(m)
        dt = _check_dt(dt)
        if self.impulse_response() is None:
            return self._gauss_markov(dt).avar(m, dt)
        h = self.impulse_response()
        r = self.autocovariance(np.arange(len(h) + 1), dt)
        out = np.empty(len(m))
        small = m < len(h)
        if np.any(small):
            out[small] = avar_from_autocovariance(r, m[small])
        if np.any(~small):  # the closed form above (m >= L): no sums of length 2m
            c2 = float(np.dot(np.arange(1, len(r)), r[1:]))
            mb = m[~small].astype(float)
            out[~small] = self.N**2 / (mb * dt) - 3 * c2 / mb**2
        return out

    def avar_shape_derivative(self, m, dt):
        """``(avar, d avar / d ln tf)`` of the first-order low-pass: the base class's central difference in
        ln tf (relative step 1e-4), with its three AVs (at tf, tf e^h, tf e^-h) in one compiled call
        (:func:`avbench.noise_models.markov_terms._gm_central`), bit for bit the three
        :meth:`avar` calls it stands for. The FIR filters have no shape parameter: the base class's."""
        if self.tf is None:
            return super().avar_shape_derivative(m, dt)
        m = check_m(m)
        dt = _check_dt(dt)
        h = 1e-4
        tfs = (self.tf, self.tf * math.exp(h), self.tf * math.exp(-h))
        sigma2 = []
        for tf in tfs:  # _gauss_markov(dt) at each tf: the GaussMarkov sequence's variance
            a = math.exp(-dt / tf)
            sigma = math.sqrt(self.N**2 / dt * (1 - a) / (1 + a))
            if not (sigma > 0 and math.isfinite(sigma) and math.isfinite(tf) and tf > 0):
                return super().avar_shape_derivative(m, dt)  # a step outside the values a term accepts
            sigma2.append(sigma**2)
        return _gm_central(m, [dt / tf for tf in tfs], sigma2, h - (-h))

    def gain2(self, f, dt) -> np.ndarray:
        """|H(e^{i 2 pi f dt})|^2, the filter's power gain (1 at f = 0)."""
        grid = f
        f, w = _omega_dt(f, dt)
        h = self.impulse_response()
        if h is None:
            a = math.exp(-dt / self.tf)
            return (1 - a) ** 2 / (1 - 2 * a * _grid_value(grid, dt, "cos(w)", w) + a * a)
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


#: how NumPy multiplies complex arrays on this machine (:func:`numpy_complex_product`), probed on first use
_numpy_complex_product = functools.cache(numpy_complex_product)


def _resonance_poles(f0: float, tc: float, dt: float) -> tuple[float, float, float]:
    """(rho, omega, c) of a resonance at ``f0`` with damping time ``tc`` sampled every ``dt``
    (:class:`Resonance`); a ValueError at or above the Nyquist frequency."""
    if f0 >= 0.5 / dt * (1 - 1e-12):
        raise ValueError(
            f"f0: {f0} Hz is not below the Nyquist frequency 1/(2 dt) = {0.5 / dt} Hz "
            "of this sampling; expected a frequency the samples resolve"
        )
    rho, w = math.exp(-dt / tc), 2 * math.pi * f0 * dt
    return rho, w, -math.expm1(-2 * dt / tc) / (2 * rho * math.sin(w))


def _resonance_short_avar(terms, ms: np.ndarray, dt) -> np.ndarray:
    """``[avar_from_autocovariance(t.autocovariance(np.arange(2 * ms.max() + 1), dt), ms) for t in terms]`` as one
    (len(terms), len(ms)) array, bit for bit: the same element-wise operations (the extended-precision sums
    of :func:`avbench.noise_models.exact_avar.avar_from_autocovariance` per row, in their order) on
    arrays of all the terms at once."""
    lmax = int(2 * ms.max())
    k = np.abs(np.arange(lmax + 1))
    poles = [t._poles(dt) for t in terms]
    rho = np.array([p[0] for p in poles])[:, None]
    w = np.array([p[1] for p in poles])[:, None]
    c = np.array([p[2] for p in poles])[:, None]
    sigma2 = np.array([t.sigma**2 for t in terms])[:, None]
    rr = np.asarray(sigma2 * rho**k * (np.cos(w * k) - c * np.sin(w * k)), dtype=np.longdouble)
    i = np.arange(lmax + 1, dtype=np.longdouble)
    zeros = np.zeros((len(terms), 2))
    c1 = np.concatenate((zeros, np.cumsum(rr[:, 1:lmax], axis=1)), axis=1)
    c2 = np.concatenate((zeros, np.cumsum((i * rr)[:, 1:lmax], axis=1)), axis=1)

    def var_sum(l):
        return l * rr[:, :1] + 2 * (l * c1[:, l] - c2[:, l])

    ml = ms.astype(np.longdouble)
    return np.asarray((4 * var_sum(ms) - var_sum(2 * ms)) / (2 * ml * ml), dtype=np.float64)


#: the largest turn (radians) of the longest cluster's phase, or its decay, within one step of
#: :meth:`Resonance.avar_shape_gradient`'s central differences (:meth:`Resonance.gradient_steps`)
GRADIENT_PHASE_STEP = 1e-2


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
    tc): c -> 1 / (2 pi f0 tc), the velocity of a damped oscillator driven by white noise. ``f0``
    must lie below the Nyquist frequency (at it, sin omega = 0). The parameters are named alike in the
    constructor and a fit (:attr:`fit_parameters`).

    Parameters
    ----------
    sigma : float or (value, unit)
        Stationary standard deviation of the rate (rad/s, or e.g. ``(300, "deg/h")``).
    f0 : float
        Centre frequency in Hz, 0 < f0 < 1/(2 dt).
    tc : float
        Damping time in seconds (the band's half width at half power ~ 1/(2 pi tc)).
    """

    coefficient = None
    latent = "RS"
    fit_parameters = ("sigma", "f0", "tc")

    @classmethod
    def from_fit(cls, values, *, tau_max=None):
        return cls(sigma=values[0], f0=values[1], tc=values[2])

    @classmethod
    def fit_amplitude_top(cls, tau, avar):
        """The curve's highest AV as a variance: a narrow resonance's AV peaks near it (1.05 sigma^2)."""
        return math.sqrt(np.max(avar))

    @classmethod
    def fit_shape_bounds(cls, tau, dt, T, hint=None):
        """The centre frequency seen by the taus (AV peak 0.371 / f0 inside their range), below
        :data:`RESONANCE_MAX_FREQUENCY` / dt, within ``hint.window`` where given (the band found in the
        spectrum); the damping time from a quality factor pi f0 tc of 1 (broader is no resonance: a
        Gauss-Markov or filter shape) to the record's length ``T``."""
        f_lo, f_hi = 0.371 / tau[-1], RESONANCE_MAX_FREQUENCY / dt
        if hint is not None and hint.window is not None:
            f_lo = max(f_lo, hint.window[0])
            f_hi = min(f_hi, hint.window[1])
        return ([math.log(f_lo), math.log(max(dt, 1.0 / (math.pi * f_hi)))],
                [math.log(max(f_hi, f_lo * 1.001)), math.log(T)])

    @classmethod
    def fit_starts(cls, tau, avar, lo, hi, *, n_starts=1, hint=None):
        """At each of ``hint.starts`` ((sigma, f0, tc) read off the record's spectrum), moved inside the box;
        none without them."""
        starts = () if hint is None else hint.starts
        return [tuple(min(max(start[k], math.exp(lo[k]) * 1.01), math.exp(hi[k]) / 1.01) for k in range(3))
                for start in starts]

    def __init__(self, sigma, f0, tc):
        self.sigma = as_si("B", sigma)  # a rate, like B
        if self.sigma == 0:
            raise ValueError("sigma: expected a positive standard deviation, got 0")
        self.f0 = _positive("f0", f0)
        self.tc = _positive("tc", tc)

    @classmethod
    def shape_parameters(cls):
        return ("f0", "tc")

    def _params(self):
        return {"sigma": self.sigma, "f0": self.f0, "tc": self.tc}

    def psd_factor(self):
        return self.sigma**2, Resonance(sigma=1.0, f0=self.f0, tc=self.tc)

    def _poles(self, dt):
        """(rho, omega, c) of the sampling ``dt``; a ValueError at or above the Nyquist frequency."""
        return _resonance_poles(self.f0, self.tc, _check_dt(dt))

    def autocovariance(self, lags, dt) -> np.ndarray:
        """r at ``lags``, exact: sigma^2 rho^|k| [cos(omega k) - c sin(omega |k|)]."""
        rho, w, c = self._poles(dt)
        k = np.abs(np.asarray(lags, dtype=float))
        return self.sigma**2 * rho**k * (np.cos(w * k) - c * np.sin(w * k))

    def avar(self, m, dt):
        m = check_m(m)
        rho, w, c = self._poles(dt)
        alpha = complex(dt / self.tc, -w)  # phi = exp(-alpha) = rho e^{i w}
        out = np.empty(m.size)
        small = (2 * m + 1) * abs(alpha) < 1.0
        if np.any(small):
            lags = np.arange(int(2 * m[small].max()) + 1)
            out[small] = avar_from_autocovariance(self.autocovariance(lags, dt), m[small])
        if np.any(~small):
            out[~small] = self.sigma**2 * np.real((1 + 1j * c) * _gm_form(m[~small], alpha))
        return out

    @staticmethod
    def _avar_rows(rows, m, dt) -> np.ndarray:
        """``[Resonance(*row).avar(m, dt) for row in rows]`` (rows of (sigma, f0, tc)) as one array,
        bit for bit: the closed form of every row in one compiled call
        (:func:`avbench.noise_models._term_kernels._resonance_rows_py`), the autocovariance route where
        (2m + 1)|alpha| < 1 as :meth:`avar` takes it."""
        m = check_m(m)
        fused = _numpy_complex_product()
        if fused is None:  # NumPy's complex products are neither form the kernel knows: NumPy's own route
            return np.array([Resonance(*row).avar(m, dt) for row in rows])
        dt_checked = _check_dt(dt)
        alpha, s, sigma2 = [], [], []
        for sg, f, tc in rows:  # the values Resonance(sg, f, tc) holds and its avar computes from them
            sg, f, tc = as_si("B", sg), _positive("f0", f), _positive("tc", tc)
            if sg == 0:
                raise ValueError("sigma: expected a positive standard deviation, got 0")
            rho, w, c = _resonance_poles(f, tc, dt_checked)
            alpha.append(complex(dt / tc, -w))
            s.append(1 + 1j * c)
            sigma2.append(sg**2)
        alpha = np.array(alpha)
        out = np.empty((len(rows), m.size))
        small = np.empty((len(rows), m.size), dtype=bool)
        _resonance_rows_kernel(m, np.abs(alpha), alpha, -np.expm1(-2 * alpha), np.exp(-alpha), -np.expm1(-alpha),
                               np.array(s), np.array(sigma2), fused, small, out)
        left = [r for r in range(len(rows)) if small[r].any()]
        while left:  # the rows sharing the first one's short clusters, in one NumPy pass
            same = [r for r in left if np.array_equal(small[r], small[left[0]])]
            mask = small[left[0]]
            out[np.ix_(same, mask)] = _resonance_short_avar([Resonance(*rows[r]) for r in same], m[mask], dt)
            left = [r for r in left if r not in same]
        return out

    def gradient_steps(self, m, dt) -> tuple[float, float]:
        """The steps in ln f0 and ln tc of :meth:`avar_shape_gradient`'s central differences at cluster sizes
        ``m``: 1e-4, or less where the longest cluster's phase m omega (in f0) or decay m dt / tc (in tc)
        would turn by more than :data:`GRADIENT_PHASE_STEP` within a step. The AV of a resonance oscillates in
        f0 at long taus (a narrow band's AV is a sinusoid's, zero at every whole number of periods), so a fixed
        step of 1e-4 spans several oscillations where m omega exceeds 1e4 and the difference is no
        derivative; the smaller step keeps its truncation error below (1e-2)^2 / 6 of the oscillation's
        derivative while its round-off, ~1e-16 / step of the AV, stays below 1e-8 of it."""
        m_max = float(np.max(check_m(m)))
        w, decay = 2 * math.pi * self.f0 * dt, m_max * dt / self.tc
        return (min(1e-4, GRADIENT_PHASE_STEP / (w * m_max)), min(1e-4, GRADIENT_PHASE_STEP / decay))

    def avar_shape_gradient(self, m, dt):
        """``(avar, [d avar / d ln f0, d avar / d ln tc])``: central differences in ln p with the steps of
        :meth:`gradient_steps`, its five AVs in one call of :meth:`_avar_rows` (bit for bit those of
        :meth:`avar`)."""
        hf, ht = self.gradient_steps(m, dt)
        sg, f, tc = self.sigma, self.f0, self.tc
        v = self._avar_rows([(sg, f, tc), (sg, f * math.exp(hf), tc), (sg, f * math.exp(-hf), tc),
                             (sg, f, tc * math.exp(ht)), (sg, f, tc * math.exp(-ht))], m, dt)
        return v[0], [(v[1] - v[2]) / (2 * hf), (v[3] - v[4]) / (2 * ht)]

    def psd(self, f, dt):
        """One-sided: 2 dt [r(0) + 2 sum_{k>=1} r(k) cos(k theta)], summed in closed form."""
        rho, w, c = self._poles(dt)
        grid = f
        f, theta = _omega_dt(f, dt)
        phi = rho * np.exp(1j * w)
        z1, z2 = phi * _grid_value(grid, dt, "exp(iw)", theta), phi * _grid_value(grid, dt, "exp(-iw)", theta)
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
