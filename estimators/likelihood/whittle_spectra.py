"""The spectra the Whittle likelihood is built from: the terms it models (:func:`components`), each
term's discrete-time spectrum, its expected periodogram over a record of n samples, its
autocovariance, and the covariances of the lowest DFT ordinates of a stationary record.

The likelihood keeps no table of terms: its components are the latent terms of
:data:`avbench.noise_models.latents.LATENT_TERMS` that have a random part, each named by the IEEE
coefficient it reports when its spectrum is that coefficient squared times a fixed shape (``"Q"``,
``"N"``, ``"B"``, ``"K"``), by its latent code when a shape parameter shapes it (``"GM"``, a first-order
Gauss-Markov process of correlation time ``tc``). Every function takes one component with unit
amplitude (:func:`unit_term`: sigma = 1 for Gauss-Markov), in the likelihood's units (a record of rate
samples spaced ``dt``; angular frequency per sample :math:`\\omega_k = 2\\pi k/n`), and asks the term:

* :func:`unit_spectrum` -- the exact discrete-time spectrum of the generator, ``term.psd(f, dt) / (2 dt)``
  (as :func:`avbench.estimators.likelihood.crlb.crlb` uses them): quantization
  :math:`(Q/\\Delta t)^2 4\\sin^2(\\omega/2)`, white rate :math:`N^2/\\Delta t`, flicker
  :math:`B^2/|2\\sin(\\omega/2)|` (Kasdin & Walter 1992, alpha = 1), Gauss-Markov
  :math:`\\sigma^2(1-\\phi^2)/|1-\\phi e^{-i\\omega}|^2` (Miao et al. 2015, eq. 6), rate random walk
  :math:`K^2\\Delta t/(4\\sin^2(\\omega/2))` (pseudo-spectrum);
* :func:`expected_periodogram` -- :math:`E[I_k]`, the de-biased Whittle likelihood's replacement of
  the spectrum (Sykulski et al. 2019), from the term's :meth:`~avbench.noise_models.NoiseTerm.psd_autocovariance`;
* :func:`autocovariance` and :func:`low_dft_covariance` -- the second moments of the record the
  sandwich information (:meth:`~avbench.estimators.likelihood.whittle_likelihood.WhittleFit.godambe_ratio`)
  and the trend slope's exact variance are computed from.
"""

from __future__ import annotations

import functools

import numpy as np

from avbench.noise_models.latents import LATENT_TERMS

__all__ = ["components", "component", "component_of", "is_shaped", "trend", "walk", "unit_term", "unit_spectrum",
           "expected_periodogram", "autocovariance", "low_dft_covariance"]


def _name(cls) -> str:
    return cls.latent if cls.shape_parameters() or cls.coefficient is None else cls.coefficient


def components() -> dict:
    """The likelihood's components, name -> term class, in the canonical order of the latent terms
    (:data:`~avbench.noise_models.latents.LATENT_TERMS`): every latent term with a random part (the
    deterministic ramp is the likelihood's trend regression), named by its reported coefficient when
    no shape parameter shapes its spectrum, by its latent code otherwise (module docstring). Read-only
    (kept per set of latent terms: a term registered later is a component from then on)."""
    return _components(tuple(LATENT_TERMS.values()))


@functools.lru_cache(maxsize=8)
def _components(classes) -> dict:
    return {_name(cls): cls for cls in classes if not cls.deterministic}


def component(name: str):
    """The term class of component ``name`` (:func:`components`); a ValueError naming the components
    for any other name."""
    comps = components()
    if name not in comps:
        raise ValueError(f"Whittle component: expected one of {', '.join(comps)}, got {name!r}")
    return comps[name]


def component_of(coefficient: str, shaped: bool = False) -> str:
    """The name of the component reporting ``coefficient`` whose spectrum has (``shaped``) or has not a
    shape parameter (``"B"`` -> ``"B"``, flicker; ``"B", shaped=True`` -> ``"GM"``)."""
    for name, cls in components().items():
        if cls.coefficient == coefficient and bool(cls.shape_parameters()) == bool(shaped):
            return name
    raise ValueError(f"no {'shaped ' if shaped else ''}component reports {coefficient!r}")


def is_shaped(name: str) -> bool:
    """Whether a shape parameter (a Gauss-Markov Tc) sets component ``name``'s spectrum beside its amplitude."""
    return bool(component(name).shape_parameters())


def trend() -> str:
    """The coefficient of the deterministic latent term (the ramp R): the likelihood's trend regression,
    not a spectral component."""
    return next(cls.coefficient for cls in LATENT_TERMS.values() if cls.deterministic)


def walk(comps) -> str | None:
    """The component of ``comps`` that is not stationary (the random walk, whose drift a trend regression
    sees), or None."""
    return next((c for c in comps if not component(c).stationary), None)


#: the filter memory a unit flicker term is built with: its likelihood spectrum is the ideal 1/f
#: (``psd``, ``psd_autocovariance``), which the memory does not enter
_UNIT_TAU_MAX = 1.0


def unit_term(name: str, tc: float | None = None):
    """Component ``name`` at unit amplitude (its first fit parameter 1), its shape parameter ``tc``."""
    cls = component(name)
    values = (1.0, tc) if cls.shape_parameters() else (1.0,)
    return cls.from_fit(values, tau_max=_UNIT_TAU_MAX)


def unit_spectrum(coef: str, f: np.ndarray, dt: float, tc: float | None = None) -> np.ndarray:
    """Spectrum S_j(omega) / c^2 of one component with unit amplitude (sigma = 1 for Gauss-Markov) at
    the frequencies ``f`` (Hz): ``psd(f, dt) / (2 dt)``."""
    return unit_term(coef, tc).psd(f, dt) / (2.0 * dt)


def expected_periodogram(coef: str, n: int, dt: float, tc: float | None = None) -> np.ndarray:
    """Expected periodogram :math:`E[I_k]`, k = 1..n//2, of one component with unit amplitude, for a
    record of ``n`` samples: the de-biased Whittle likelihood's replacement of the spectrum
    (Sykulski et al. 2019, Biometrika 106(2); arXiv 1605.06718),

    .. math:: E[I_k] = 2\\,\\mathrm{Re}\\sum_{\\tau=0}^{n-1} \\big(1-\\tfrac{\\tau}{n}\\big)
        c(\\tau)e^{-i\\omega_k\\tau} - c(0),

    one FFT of length n, c the term's :meth:`~avbench.noise_models.NoiseTerm.psd_autocovariance`:
    quantization :math:`c(0) = 2/\\Delta t^2, c(1) = -1/\\Delta t^2`; Gauss-Markov :math:`\\phi^\\tau`;
    ideal flicker (the likelihood's 1/f spectrum, not stationary) :math:`c(\\tau) = -\\gamma(\\tau)`,
    its variogram :math:`\\gamma(\\tau) = (\\psi(\\tau+\\tfrac12)-\\psi(\\tfrac12))/\\pi` (a constant
    added to c changes no ordinate k >= 1: the Fejer kernel vanishes there). A white term (c = 0 beyond
    lag 0) and the random walk's pseudo-spectrum (exact after the trend regression of the likelihood)
    are their own expected periodograms: the plain spectrum is returned for them."""
    c = autocovariance(coef, n, dt, tc)
    if c is None or not np.any(c[1:]):
        f = np.arange(1, n // 2 + 1) / (n * dt)
        return unit_spectrum(coef, f, dt, tc)
    h = (1.0 - np.arange(n, dtype=float) / n) * c
    h[0] *= 0.5
    return 2.0 * np.fft.rfft(h).real[1:]


def autocovariance(coef: str, n: int, dt: float, tc: float | None = None) -> np.ndarray | None:
    """Autocovariance :math:`c(\\tau)`, :math:`\\tau = 0..n-1`, of one stationary component with unit
    amplitude in the likelihood's units (as in :func:`expected_periodogram`; ideal flicker up to a
    constant, which changes no ordinate k >= 1 and no trend-free contrast), or None for a component
    that is not stationary (the random walk:
    :meth:`~avbench.estimators.likelihood.whittle_likelihood.WhittleFit.godambe_ratio` treats it in
    closed form). A shape parameter the term refuses (a NaN Tc a profile step proposed): NaN at every
    lag, which the likelihood scores as no maximum."""
    try:
        term = unit_term(coef, tc)
    except ValueError:
        return np.full(n, np.nan)
    if not term.stationary:
        return None
    return term.psd_autocovariance(np.arange(n), dt)


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
