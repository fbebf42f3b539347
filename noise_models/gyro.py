"""A synthetic gyro: a sum of independent noise terms sampled at interval dt."""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence

import numpy as np

from avbench.noise_models.terms import NoiseTerm, _check_dt, _check_n
from avbench.noise_models.units import COEFFICIENTS

__all__ = ["Gyro"]


def _as_generator(rng) -> np.random.Generator:
    if isinstance(rng, np.random.Generator):
        return rng
    if isinstance(rng, np.random.SeedSequence):
        return np.random.default_rng(rng)
    if isinstance(rng, int | np.integer) and not isinstance(rng, bool) and rng >= 0:
        return np.random.default_rng(int(rng))
    raise ValueError(
        f"rng: expected a numpy.random.Generator, a SeedSequence or a non-negative int seed, got {rng!r}"
    )


#: block length (samples) in which :meth:`Gyro.simulate` fills long records
_SIMULATE_BLOCK = 1 << 16


def _sum_next(streams, n: int) -> np.ndarray:
    """Sum of the next ``n`` samples of every term, in term order (the first sum makes a new array,
    the later ones add in place: same values as ``a + b + c``, fewer allocations)."""
    out = streams[0].next(n)
    for i, s in enumerate(streams[1:]):
        if i == 0:
            out = out + s.next(n)
        else:
            out += s.next(n)
    return out


class Gyro:
    """A gyro whose rate noise is the sum of independent ``terms`` sampled every ``dt`` seconds.

    Parameters
    ----------
    dt : float
        Sample interval in seconds.
    terms : sequence of NoiseTerm
        At most one term per IEEE coefficient (e.g. not two terms both reporting B); terms that
        report none (e.g. :class:`~avbench.noise_models.terms.Sinusoidal`) may repeat.
    name : str, optional
        A label (presets set it).

    Notes
    -----
    Each term draws from its own child generator (``rng.spawn``), so the record does not depend on
    how it is cut into chunks: :meth:`stream` yields chunks whose concatenation equals
    :meth:`simulate` bit for bit. Monte Carlo replicates use independent generators from
    ``numpy.random.SeedSequence(seed).spawn(n)``.

    Examples
    --------
    >>> import numpy as np
    >>> from avbench.noise_models import Gyro, AngleRandomWalk, RateRandomWalk
    >>> g = Gyro(dt=0.01, terms=[AngleRandomWalk(N=(2.0, "deg/sqrt(h)")), RateRandomWalk(K=1e-6)])
    >>> x = g.simulate(1000, np.random.default_rng(0))
    >>> x.shape
    (1000,)
    >>> chunks = np.concatenate(list(g.stream(1000, np.random.default_rng(0), chunk_size=300)))
    >>> bool(np.array_equal(x, chunks))
    True
    """

    def __init__(self, dt, terms: Sequence[NoiseTerm], name: str | None = None):
        self.dt = _check_dt(dt)
        terms = list(terms)
        if not terms:
            raise ValueError("terms: expected at least one noise term")
        seen: dict[str, NoiseTerm] = {}
        for t in terms:
            if not isinstance(t, NoiseTerm):
                raise ValueError(f"terms: expected NoiseTerm instances, got {t!r}")
            if t.coefficient is not None and t.coefficient in seen:
                raise ValueError(
                    f"terms: {seen[t.coefficient]!r} and {t!r} both report coefficient "
                    f"{t.coefficient}; use at most one term per coefficient"
                )
            seen[t.coefficient] = t
        self.terms = terms
        self.name = name

    @classmethod
    def from_coefficients(cls, coefs, dt, flicker_tau_max=None) -> "Gyro | None":
        """The five-term model a coefficient set stands for, with the exact generators: Q quantization,
        N white, B flicker (``BiasInstability`` with ``tau_max=flicker_tau_max``, else its default), K random walk,
        R ramp. Coefficients that are missing, NaN or not positive are left out; ``None`` if none is left.
        """
        from avbench.noise_models.terms import (
            AngleRandomWalk, BiasInstability, Quantization, RateRamp, RateRandomWalk,
        )

        make = {"Q": lambda v: Quantization(Q=v), "N": lambda v: AngleRandomWalk(N=v),
                "B": lambda v: BiasInstability(B=v) if flicker_tau_max is None else BiasInstability(B=v, tau_max=flicker_tau_max), "K": lambda v: RateRandomWalk(K=v),
                "R": lambda v: RateRamp(R=v)}
        terms = []
        for c, term in make.items():
            v = coefs.get(c, math.nan) if hasattr(coefs, "get") else math.nan
            if v is not None and np.isfinite(v) and v > 0:
                terms.append(term(float(v)))
        return cls(dt=dt, terms=terms) if terms else None

    def __repr__(self) -> str:
        label = f"name={self.name!r}, " if self.name else ""
        return f"Gyro({label}dt={self.dt!r}, terms={self.terms!r})"

    @property
    def coefficients(self) -> pd.Series:
        """True coefficients Q, N, B, K, R in SI (NaN where absent; a GM term reports B_equiv)."""
        values = {}
        for t in self.terms:
            values.update(t.coefficients())
        import pandas as pd  # imported where used: `import noise_models` stays light

        return pd.Series([values.get(c, math.nan) for c in COEFFICIENTS], index=list(COEFFICIENTS), dtype=float)

    @property
    def term_set(self) -> str:
        """The coefficients this gyro's terms carry, in the order Q N B K R (e.g. ``"NBK"``): the
        ``terms`` setting of an estimator told the true model (a GM term carries B)."""
        c = self.coefficients
        return "".join(k for k in c.index if np.isfinite(c[k]))

    # -- truth ---------------------------------------------------------------------------------
    def m_of(self, tau) -> np.ndarray:
        """Cluster sizes m = tau / dt; an error if tau is not a positive multiple of dt."""
        tau = np.atleast_1d(np.asarray(tau, dtype=float))
        m = np.rint(tau / self.dt)
        if np.any(m < 1) or np.any(np.abs(m * self.dt - tau) > 1e-6 * tau):
            raise ValueError(f"tau: expected positive multiples of dt = {self.dt} s, got {tau!r}")
        return m.astype(np.int64)

    @property
    def has_exact_avar(self) -> bool:
        """True if every term knows its exact Allan variance (see ``NoiseTerm.has_exact_avar``)."""
        return all(t.has_exact_avar for t in self.terms)

    def avar(self, tau) -> np.ndarray:
        """Exact Allan variance (rad^2/s^2) of the discrete generator at ``tau`` (multiples of dt).

        A ValueError if a term has no exact AV (``has_exact_avar = False``).
        """
        missing = [t for t in self.terms if not t.has_exact_avar]
        if missing:
            raise ValueError(
                f"no exact Allan variance for this gyro: term {missing[0]!r} declares none (has_exact_avar = False)"
            )
        m = self.m_of(tau)
        return np.sum([t.avar(m, self.dt) for t in self.terms], axis=0)

    def adev(self, tau) -> np.ndarray:
        return np.sqrt(self.avar(tau))

    def psd(self, f) -> np.ndarray:
        """One-sided PSD (rad^2/s^2/Hz) of the rate at frequencies 0 < f <= 1/(2 dt)."""
        return np.sum([t.psd(f, self.dt) for t in self.terms], axis=0)

    # -- simulation ----------------------------------------------------------------------------
    def _term_streams(self, rng):
        rng = _as_generator(rng)
        children = rng.spawn(len(self.terms))
        return [t.stream(self.dt, r) for t, r in zip(self.terms, children)]

    def simulate(self, n_samples: int, rng) -> np.ndarray:
        """``n_samples`` rate samples (rad/s)."""
        n = _check_n(n_samples)
        streams = self._term_streams(rng)
        if n <= _SIMULATE_BLOCK:
            return _sum_next(streams, n)
        # long records: fill the output block by block (the terms' streams are chunk-invariant, so
        # the values are the same), keeping every temporary array small and in cache
        out = np.empty(n)
        for a in range(0, n, _SIMULATE_BLOCK):
            b = min(n, a + _SIMULATE_BLOCK)
            out[a:b] = _sum_next(streams, b - a)
        return out

    def stream(self, n_samples: int, rng, chunk_size: int = 1 << 18) -> Iterator[np.ndarray]:
        """Yield the same record as :meth:`simulate` in chunks of ``chunk_size`` samples."""
        n = _check_n(n_samples)
        chunk_size = _check_n(chunk_size)
        if chunk_size == 0:
            raise ValueError("chunk_size: expected a positive integer")
        streams = self._term_streams(rng)
        done = 0
        while done < n:
            c = min(chunk_size, n - done)
            out = _sum_next(streams, c)
            done += c
            yield out
