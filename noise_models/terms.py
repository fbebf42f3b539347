"""Noise terms of a synthetic gyro: each simulates itself and knows its exact discrete-time AV.

Every term answers the same small questions (``coefficients()``, ``avar(m, dt)``, ``psd(f, dt)``,
``stream(dt, rng)``, ``phase_gcov(lags, dt)``; a latent of the fits also its parameters, their box and
starting values): :mod:`avbench.noise_models.term_base`. The terms live in one module per family, and
this module gathers them: the five terms of IEEE Std 952's model
(:mod:`avbench.noise_models.power_law_terms`), the Gauss-Markov processes
(:mod:`avbench.noise_models.markov_terms`) and the terms of real sensors beyond them, a sinusoid, the
sensor's own filter and a resonance (:mod:`avbench.noise_models.sensor_terms`); the generators' compiled
recursions are in :mod:`avbench.noise_models._term_kernels`.

The formulas (SPEC, "Discrete generators and their exact Allan variance"):

=====================  ==========================================  =======================================
term                   generator                                   exact AV at tau = m dt
=====================  ==========================================  =======================================
Quantization(Q)        theta_k ~ N(0, Q^2), w_k = (theta_k -        3 Q^2 / tau^2
                       theta_{k-1}) / dt
AngleRandomWalk(N)     w_k = (N / sqrt(dt)) n_k                     N^2 / tau
RateRandomWalk(K)      w_k = w_{k-1} + K sqrt(dt) n_k               K^2 tau / 3 + K^2 dt^2 / (6 tau)
RateRamp(R)            w_k = R k dt                                 R^2 tau^2 / 2
GaussMarkov(sigma,tc)  x_k = phi x_{k-1} + sigma sqrt(1-phi^2) n_k   closed form (:class:`GaussMarkov`)
BiasInstability(B)     Kasdin & Walter (1992) 1/f FIR, Q_d = B^2    from the exact autocovariance
SecondOrderGaussMarkov exact discretisation of Miao et al. 2015,    from the exact autocovariance
                       eq. 8
Sinusoidal(A, f0)      A sin(2 pi f0 k dt + phi), phi uniform       A^2 sin^4(m w/2) / (m^2 sin^2(w/2)),
                       (IEEE Std 952-1997, Annex C)                 w = 2 pi f0 dt
FilteredWhiteNoise(N)  white noise N through the sensor's low-pass  N^2/tau - 3 C2 / m^2 (FIR, m >= L);
                       (moving average, FIR or first-order IIR)     the GM form (first-order IIR)
Resonance(sigma, f0,   band-pass Gauss-Markov: ARMA(2,1), poles     Re[(1 + i c) GM form at complex phi]
          tc)          rho e^{+-i w}, MA zero at 1 (a structural    (closed form, :class:`Resonance`)
                       mode's noise; no power at f = 0)
=====================  ==========================================  =======================================
"""

from __future__ import annotations

from avbench.noise_models._term_kernels import (  # noqa: F401  (the kernels and their plain twins, for tests)
    _ar1_kernel,
    _ar1_kernel_py,
    _diff_kernel,
    _diff_kernel_py,
    _gm_shape_kernel,
    _gm_shape_py,
    _sogm_kernel,
    _sogm_kernel_py,
    _walk_kernel,
    _walk_kernel_py,
)
from avbench.noise_models.markov_terms import (
    B_EQUIV_OVER_SIGMA,
    GM_PEAK_ADEV_OVER_SIGMA,
    GM_PEAK_TAU_OVER_TC,
    GaussMarkov,
    SecondOrderGaussMarkov,
    _gm_f_over_c2,  # noqa: F401
)
from avbench.noise_models.power_law_terms import (
    AngleRandomWalk,
    BiasInstability,
    Quantization,
    RateRamp,
    RateRandomWalk,
    _FIRStream,  # noqa: F401
    _kasdin_walter_h,  # noqa: F401
)
from avbench.noise_models.sensor_terms import FilteredWhiteNoise, Resonance, Sinusoidal
from avbench.noise_models.term_base import (  # noqa: F401  (the checks gyro and the estimators share)
    PLATEAU,
    NoiseTerm,
    TermStream,
    _check_dt,
    _check_n,
    _omega_dt,
    _positive,
)

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
