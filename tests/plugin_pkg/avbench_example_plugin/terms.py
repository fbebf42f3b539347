"""Noise terms of the example plugin: a random-phase sinusoid with its exact Allan variance, and a
square wave that declares it has none (``has_exact_avar = False``)."""

import math

import numpy as np

from avbench.noise_models import NoiseTerm
from avbench.noise_models.terms import TermStream


class _PeriodicStream(TermStream):
    def __init__(self, dt, rng, term):
        super().__init__(dt, rng)
        self.term = term
        self.phase = float(rng.uniform(0.0, 2.0 * math.pi))
        self.k = 0

    def next(self, n):
        k = np.arange(self.k, self.k + n)
        self.k += n
        return self.term.wave(2.0 * math.pi * k * self.dt / self.term.period + self.phase)


class SineRate(NoiseTerm):
    """A rate sinusoid A sin(2 pi t / period + phi) with a uniform random phase per record.

    Exact Allan variance of the sampled sequence at tau = m dt, theta = 2 pi dt / period:

        AV = A^2 sin^2(m theta / 2) D_m^2,   D_m = sin(m theta / 2) / (m sin(theta / 2)),

    which tends to A^2 sin^4(pi tau / period) / (pi tau / period)^2 as dt -> 0.
    """

    def __init__(self, amplitude, period):
        self.amplitude = float(amplitude)
        self.period = float(period)

    def _params(self):
        return {"amplitude": self.amplitude, "period": self.period}

    def wave(self, x):
        return self.amplitude * np.sin(x)

    def avar(self, m, dt):
        m = np.asarray(m, dtype=float)
        half = math.pi * dt / self.period  # theta / 2
        d = np.sin(m * half) / (m * math.sin(half))
        return self.amplitude**2 * np.sin(m * half) ** 2 * d**2

    def autocovariance(self, lags, dt):
        """(A^2 / 2) cos(2 pi k dt / period): the random phase makes the sequence stationary."""
        return 0.5 * self.amplitude**2 * np.cos(2.0 * math.pi * dt / self.period * np.asarray(lags, dtype=float))

    def psd(self, f, dt):
        """Zero: the power is a line at 1 / period (spectral_lines)."""
        return np.zeros_like(np.asarray(f, dtype=float))

    def spectral_lines(self, dt):
        return [(1.0 / self.period, 0.5 * self.amplitude**2)]

    def stream(self, dt, rng):
        return _PeriodicStream(dt, rng, self)


class SquareWaveRate(SineRate):
    """A rate square wave of amplitude A (a thermostat cycling, say); no exact statistics are derived here."""

    has_exact_avar = False

    def wave(self, x):
        return self.amplitude * np.sign(np.sin(x))

    def avar(self, m, dt):
        raise NotImplementedError("SquareWaveRate declares no exact Allan variance")

    def autocovariance(self, lags, dt):
        raise NotImplementedError("SquareWaveRate declares no exact autocovariance")

    def psd(self, f, dt):
        raise NotImplementedError("SquareWaveRate declares no spectrum")

    def spectral_lines(self, dt):
        raise NotImplementedError("SquareWaveRate declares no spectrum")
