"""The spectra the Whittle likelihood is built from: each noise term's discrete-time spectrum, its
expected periodogram over a record of n samples, its autocovariance, and the covariances of the
lowest DFT ordinates of a stationary record.

Every function takes one term with unit coefficient (``"Q"``, ``"N"``, ``"B"``, ``"K"``, or ``"GM"``,
a first-order Gauss-Markov process with :math:`\\sigma = 1` and correlation time ``tc``), in the
likelihood's units (a record of rate samples spaced ``dt``; angular frequency per sample
:math:`\\omega_k = 2\\pi k/n`):

* :func:`unit_spectrum` -- the exact discrete-time spectra of the generators in
  :mod:`avbench.noise_models` (``term.psd(f, dt) / (2 dt)``, as :func:`avbench.estimators.likelihood.crlb.crlb`
  uses them): quantization :math:`(Q/\\Delta t)^2 4\\sin^2(\\omega/2)`, white rate :math:`N^2/\\Delta t`,
  flicker :math:`B^2/|2\\sin(\\omega/2)|` (Kasdin & Walter 1992, alpha = 1), Gauss-Markov
  :math:`\\sigma^2(1-\\phi^2)/|1-\\phi e^{-i\\omega}|^2` (Miao et al. 2015, eq. 6), rate random walk
  :math:`K^2\\Delta t/(4\\sin^2(\\omega/2))` (pseudo-spectrum);
* :func:`expected_periodogram` -- :math:`E[I_k]`, the de-biased Whittle likelihood's replacement of
  the spectrum (Sykulski et al. 2019);
* :func:`autocovariance` and :func:`low_dft_covariance` -- the second moments of the record the
  sandwich information (:meth:`~avbench.estimators.likelihood.whittle_likelihood.WhittleFit.godambe_ratio`)
  and the trend slope's exact variance are computed from.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["unit_spectrum", "expected_periodogram", "autocovariance", "low_dft_covariance"]


def unit_spectrum(coef: str, f: np.ndarray, dt: float, tc: float | None = None) -> np.ndarray:
    """Spectrum S_j(omega) / c^2 of one term with unit coefficient (sigma = 1 for Gauss-Markov) at
    the frequencies ``f`` (Hz)."""
    from avbench.noise_models import AngleRandomWalk, BiasInstability, GaussMarkov, Quantization, RateRandomWalk

    if coef == "GM":
        term = GaussMarkov(sigma=1.0, tc=tc)
    else:
        term = {"Q": Quantization, "N": AngleRandomWalk, "K": RateRandomWalk}.get(coef)
        term = term(**{coef: 1.0}) if term else BiasInstability(B=1.0)
    return term.psd(f, dt) / (2.0 * dt)


def expected_periodogram(coef: str, n: int, dt: float, tc: float | None = None) -> np.ndarray:
    """Expected periodogram :math:`E[I_k]`, k = 1..n//2, of one term with unit coefficient, for a
    record of ``n`` samples: the de-biased Whittle likelihood's replacement of the spectrum
    (Sykulski et al. 2019, Biometrika 106(2); arXiv 1605.06718),

    .. math:: E[I_k] = 2\\,\\mathrm{Re}\\sum_{\\tau=0}^{n-1} \\big(1-\\tfrac{\\tau}{n}\\big)
        c(\\tau)e^{-i\\omega_k\\tau} - c(0),

    one FFT of length n. Autocovariances (unit coefficient): quantization :math:`c(0) = 2/\\Delta t^2,
    c(1) = -1/\\Delta t^2`; Gauss-Markov :math:`\\phi^\\tau`; ideal flicker (the likelihood's 1/f
    spectrum, not stationary) :math:`c(\\tau) = -\\gamma(\\tau)`, its variogram
    :math:`\\gamma(\\tau) = (\\psi(\\tau+\\tfrac12)-\\psi(\\tfrac12))/\\pi` (a constant added to c
    changes no ordinate k >= 1: the Fejer kernel vanishes there). White noise (:math:`1/\\Delta t`)
    and the random walk's pseudo-spectrum (exact after the trend regression of the likelihood) are
    their own expected periodograms: the plain spectrum is returned for N and K."""
    if coef not in ("Q", "GM", "B"):
        f = np.arange(1, n // 2 + 1) / (n * dt)
        return unit_spectrum(coef, f, dt, tc)
    c = autocovariance(coef, n, dt, tc)
    h = (1.0 - np.arange(n, dtype=float) / n) * c
    h[0] *= 0.5
    return 2.0 * np.fft.rfft(h).real[1:]


def autocovariance(coef: str, n: int, dt: float, tc: float | None = None) -> np.ndarray | None:
    """Autocovariance :math:`c(\\tau)`, :math:`\\tau = 0..n-1`, of one stationary term with unit
    coefficient in the likelihood's units (as in :func:`expected_periodogram`; ideal flicker up to
    a constant, which changes no ordinate k >= 1 and no trend-free contrast), or None for the random
    walk (not stationary: :meth:`~avbench.estimators.likelihood.whittle_likelihood.WhittleFit.godambe_ratio`
    treats it in closed form)."""
    tau = np.arange(n, dtype=float)
    c = np.zeros(n)
    if coef == "N":
        c[0] = 1.0 / dt
    elif coef == "Q":
        c[0], c[1] = 2.0 / dt**2, -1.0 / dt**2
    elif coef == "GM":
        c = np.exp(-tau * dt / tc)
    elif coef == "B":
        from scipy.special import digamma

        c = -(digamma(tau + 0.5) - digamma(0.5)) / math.pi
    else:
        return None
    return c


def low_dft_covariance(c: np.ndarray, m: int):
    """Covariances of the DFT :math:`X_k = \\sum_t x_t e^{-i\\omega_k t}` of a stationary record with
    autocovariance ``c`` (lags 0..n-1) at the lowest ``m`` Fourier frequencies k = 1..m (m < n/2):
    ``(A, P)`` with :math:`A_{kl} = E[X_k\\bar X_l]`, :math:`P_{kl} = E[X_kX_l]`, in closed form from
    one FFT of c. Summing the Toeplitz double sum along its diagonals (a geometric series in t),

    .. math:: A_{kl} = \\frac{D(\\omega_k) - D(\\omega_l)}{1 - e^{-i(\\omega_k-\\omega_l)}},\\quad
        P_{kl} = \\frac{D(\\omega_k) - D(-\\omega_l)}{1 - e^{-i(\\omega_k+\\omega_l)}},\\quad
        D(\\omega) = c(0) + 2i\\,\\mathrm{Im}\\sum_{\\tau=0}^{n-1}c(\\tau)e^{-i\\omega\\tau},

    (k != l for A; :math:`A_{kk} = n\\,E[I_k]` is the expected periodogram times n). A circulant
    covariance (white noise) gives D constant: A diagonal and P = 0, the independence the Whittle
    likelihood assumes; a 1/f process does not. O(n log n + m^2); checked against the explicit
    matrix products in the tests."""
    n = c.size
    C = np.fft.fft(c)
    D = c[0] + 2j * C.imag
    k = np.arange(1, m + 1)
    kk, ll = np.meshgrid(k, k, indexing="ij")
    with np.errstate(divide="ignore", invalid="ignore"):
        A = (D[kk] - D[ll]) / (1.0 - np.exp(-2j * np.pi * (kk - ll) / n))
        P = (D[kk] - np.conj(D[ll])) / (1.0 - np.exp(-2j * np.pi * (kk + ll) / n))
    h = (1.0 - np.arange(n) / n) * c
    h[0] *= 0.5
    A[np.diag_indices(m)] = n * 2.0 * np.fft.rfft(h).real[1:m + 1]
    return A, P
