"""The accuracy limit: asymptotic Cramér-Rao bound of the coefficients from the Whittle information.

For a Gaussian record of ``n`` samples whose (discrete-time, two-sided) spectral density is
:math:`S(\\omega;\\theta)`, the Whittle approximation of the log-likelihood gives the Fisher information

.. math::

    I_{ij}(\\theta) = \\frac{n}{2}\\,\\frac{1}{n-1}\\sum_{k=1}^{n-1}
        \\frac{\\partial \\log S(\\omega_k)}{\\partial\\theta_i}
        \\frac{\\partial \\log S(\\omega_k)}{\\partial\\theta_j},
    \\qquad \\omega_k = 2\\pi k/n,

(Whittle 1953; SPEC "The accuracy limit"), and the bound
:math:`\\mathrm{std}(\\hat\\theta_i) \\ge \\sqrt{(I^{-1})_{ii}}`. The zero frequency is left out so
that non-stationary terms (rate random walk, flicker) can be handled through their pseudo-spectra:
differencing a record multiplies every term's spectrum by the same known factor
:math:`|1-e^{-i\\omega}|^2`, which leaves :math:`\\partial\\log S/\\partial\\theta` unchanged.

The spectral densities are the terms' own ``psd`` (``noise_models``: the one-sided PSD of each
discrete generator, SPEC "Discrete generators"); up to the constant factor :math:`2\\Delta t` they
are, with :math:`\\omega = 2\\pi f\\Delta t`:

=============================  ==============================================================
white rate (N)                 :math:`N^2/\\Delta t`
quantization (Q)               :math:`(Q/\\Delta t)^2\\,4\\sin^2(\\omega/2)`
rate random walk (K)           :math:`K^2\\Delta t / (4\\sin^2(\\omega/2))`
Gauss-Markov (sigma, Tc)       :math:`\\sigma^2(1-\\phi^2)/(1-2\\phi\\cos\\omega+\\phi^2)`,
                               :math:`\\phi = e^{-\\Delta t/T_c}` (Miao et al. 2015, eq. 6)
flicker bias instability (B)   :math:`B^2/|2\\sin(\\omega/2)|` (Kasdin & Walter 1992, alpha = 1)
2nd-order Gauss-Markov (R, w0) the spectrum of the exactly discretised process (Miao et al.
                               2015, eq. 8), from its autocovariance
filtered white (N; tc)         :math:`(N^2/\\Delta t)\\,|H(\\omega)|^2` (the sensor's filter, unit DC gain;
                               a moving average or FIR has no shape parameter, so N's bound is
                               that of white noise, 1/sqrt(2n) relative)
=============================  ==============================================================

A sinusoid (IEEE 952 Annex C) is a spectral line, not a density: it is left out, and the other
coefficients are bounded as if it were known (valid, possibly loose, lower bounds, as for the ramp).

The bound is parameterised in the coefficients themselves; nuisance parameters (Tc, w0) are
estimated jointly (they enter the information matrix and are then marginalised by the inverse).
A Gauss-Markov term reports B through SPEC's :math:`B_{equiv} = 0.9294\\,\\sigma`, so
:math:`\\mathrm{std}(\\hat B) = 0.9294\\,\\mathrm{std}(\\hat\\sigma)`.

The deterministic rate ramp :math:`\\omega = R t` has no spectrum; its coefficient is a regression
slope, not a variance parameter, so the Whittle bound does not cover it: R is returned as NaN when a
``RateRamp`` term is present. The other coefficients' bounds are then computed as if the ramp were
known; knowing more can only lower a bound, so they remain valid (possibly loose) lower bounds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from avbench.noise_models.units import COEFFICIENTS

__all__ = ["crlb", "whittle_information", "spectral_density"]

_CHUNK = 1 << 18

@dataclass
class _Component:
    """One term with its free parameters: the scale (first) and the shape parameters."""

    term: object
    params: dict  # free parameter name -> value; the first one is the scale
    coef: str | None  # coefficient reported by the term
    scale: float  # coefficient / scale parameter

    def psd(self, f, dt, **override):
        term = self.term if not override else type(self.term)(**dict(self.term._params(), **override))
        return term.psd(f, dt)


def _components(gyro) -> tuple[list[_Component], set[str]]:
    """The stochastic terms of a ``avbench.noise_models.Gyro`` with their free parameters."""
    comps, unbounded = [], set()
    for term in gyro.terms:
        if term.deterministic:
            unbounded.add(term.coefficient)  # the ramp: no spectrum (module docstring)
            continue
        if term.spectral_lines(gyro.dt):
            continue  # a sinusoid: a line, not a spectral density; the others bounded as if it were known
        params = term._params()
        coef = term.coefficient
        # the amplitude (a fitted term's first fit parameter, else its coefficient), then the shape parameters,
        # estimated jointly with it (nuisance for the bound)
        scale_key = term.fit_parameters[0] if term.fit_parameters else coef
        if scale_key not in params:
            raise ValueError(f"crlb: cannot find the scale parameter of {term!r}")
        free = {scale_key: params[scale_key]}
        free.update({k: params[k] for k in term.shape_parameters() if params.get(k) is not None})
        value = term.coefficients().get(coef, math.nan) if coef else math.nan
        comps.append(_Component(term, free, coef, value / params[scale_key] if coef else 1.0))
    return comps, unbounded


def spectral_density(gyro, f) -> np.ndarray:
    """One-sided PSD of ``gyro`` at frequencies ``f`` (Hz): the sum of its terms' ``psd``.

    Non-stationary terms (rate random walk, flicker) give their pseudo-spectra; the deterministic
    ramp contributes nothing.
    """
    comps, _ = _components(gyro)
    f = np.asarray(f, dtype=float)
    return sum((c.psd(f, gyro.dt) for c in comps), np.zeros_like(f))


def _log_param_vector(comps):
    names, values = [], []
    for i, c in enumerate(comps):
        for k, v in c.params.items():
            names.append((i, k))
            values.append(float(v))
    return names, np.array(values)


def whittle_information(gyro, n_samples: int, rel_step: float = 1e-4):
    """Whittle Fisher information of the log-parameters of ``gyro``'s terms for ``n_samples`` samples.

    Returns ``(names, values, info)``: ``names`` a list of ``(term index, parameter)``, ``values``
    their values, ``info`` the information matrix of their logarithms,
    :math:`I = \\frac{n}{2}\\,\\overline{g g^T}` with :math:`g = \\partial\\log S/\\partial\\log\\theta`
    (exact, :math:`2S_i/S`, for each term's scale parameter; central differences with relative step
    ``rel_step`` for the shape parameters Tc, w0), averaged over the Fourier frequencies
    :math:`2\\pi k/n`, k = 1..n-1 (using the symmetry of S about pi).
    """
    n = _check_n(n_samples)
    comps, _ = _components(gyro)
    if not comps:
        raise ValueError("crlb: the gyro has no stochastic term to bound")
    names, values = _log_param_vector(comps)
    p = len(names)
    info = np.zeros((p, p))
    half = (n - 1) // 2
    h = rel_step
    for start in range(1, half + 1, _CHUNK):
        k = np.arange(start, min(start + _CHUNK, half + 1), dtype=float)
        info += 2.0 * _gram(comps, names, k / (n * gyro.dt), gyro.dt, h)
    if n % 2 == 0:
        info += _gram(comps, names, np.array([0.5 / gyro.dt]), gyro.dt, h)
    info *= (n / 2.0) / (n - 1)
    return names, values, info


def _gram(comps, names, f, dt, h):
    parts = [c.psd(f, dt) for c in comps]
    total = sum(parts)
    g = np.empty((len(names), f.size))
    for j, (i, key) in enumerate(names):
        c = comps[i]
        if key == next(iter(c.params)):
            # every spectrum is proportional to its scale parameter squared: exact derivative
            g[j] = 2.0 * parts[i] / total
            continue
        ds = c.psd(f, dt, **{key: c.params[key] * math.exp(h)}) - c.psd(f, dt, **{key: c.params[key] * math.exp(-h)})
        g[j] = ds / (2 * h) / total
    return g @ g.T


def _check_n(n_samples) -> int:
    if isinstance(n_samples, bool) or not isinstance(n_samples, (int, np.integer)):
        raise ValueError(f"n_samples: expected an integer number of samples, got {n_samples!r}")
    if n_samples < 16:
        raise ValueError(f"n_samples: expected at least 16 samples, got {n_samples}")
    return int(n_samples)


def crlb(gyro, n_samples: int) -> pd.Series:
    """Cramér-Rao lower bound on the standard deviation of each coefficient estimate.

    .. math::

        \\mathrm{std}(\\hat c) \\ge c\\,\\sqrt{(I^{-1})_{\\log c,\\log c}},
        \\qquad I = \\frac{n}{2}\\,\\overline{\\nabla\\log S\\,\\nabla\\log S^T}

    (Whittle information, SPEC "The accuracy limit"). The scale parameter of each term is its
    coefficient (up to a constant: B = 0.9294 sigma for a Gauss-Markov term), so the delta method is
    exact here: :math:`\\mathrm{std}(c) = c\\,\\mathrm{std}(\\log c)`.

    Parameters
    ----------
    gyro : avbench.noise_models.Gyro
        The true model (its ``dt`` and ``terms``).
    n_samples : int
        Record length in samples.

    Returns
    -------
    pandas.Series
        Indexed Q, N, B, K, R (SI units, like ``Estimator.coefficients_``); NaN for absent terms and
        for the deterministic ramp R (see the module docstring). If two terms report the same
        coefficient, the bound is NaN for it (the coefficient is then not a single parameter).

    Examples
    --------
    White noise alone: var(N_hat)/N^2 = 1/(2n).

    >>> from avbench.noise_models import Gyro, AngleRandomWalk
    >>> g = Gyro(dt=0.01, terms=[AngleRandomWalk(N=1e-3)])
    >>> round(float(crlb(g, 5000)["N"] / 1e-3 * (2 * 5000) ** 0.5), 6)
    1.0
    """
    comps, unbounded = _components(gyro)
    names, values, info = whittle_information(gyro, n_samples)
    try:
        cov = np.linalg.inv(info)
    except np.linalg.LinAlgError:
        cov = np.full_like(info, np.nan)
    out = {c: math.nan for c in COEFFICIENTS}
    seen: dict[str, int] = {}
    for j, (i, key) in enumerate(names):
        comp = comps[i]
        if comp.coef is None or key != next(iter(comp.params)):
            continue  # nuisance parameter
        seen[comp.coef] = seen.get(comp.coef, 0) + 1
        var = cov[j, j]
        out[comp.coef] = comp.scale * values[j] * math.sqrt(var) if var >= 0 else math.nan
    for c, count in seen.items():
        if count > 1:
            out[c] = math.nan
    for c in unbounded:
        out[c] = math.nan
    import pandas as pd

    return pd.Series(out, index=list(COEFFICIENTS), dtype=float)
