"""The covariance of the overlapping Allan variance under a noise model (Gaussian, asymptotic): the
weight matrix of GMWM's second step (:mod:`avbench.estimators.likelihood.gmwm`) and the reference
distribution of the poor-fit check (:mod:`avbench.estimators.allan.fit_check`).

Isserlis' theorem turns the covariance of two AV estimates into an integral of the product of their
Haar filter gains against the squared spectrum (Percival 1995); the model's spectrum comes from its
noise terms (``gyro.psd``).
"""

from __future__ import annotations

import numpy as np

__all__ = ["av_covariance"]


def _haar_gain(m, w, s):
    """|H_m(w)|^2 of the overlapping-AV difference filter (d = mean of next m - mean of last m);
    ``s`` = sin(w/2)."""
    g = np.sin(0.5 * m * w)
    g *= g
    g *= g  # sin^4 by two in-place squarings (several times faster than ** 4)
    g *= 4.0 / (m * m)
    g /= s * s
    return g


def av_covariance(gyro, m, n_samples, grid_per_cycle: int = 8, max_grid: int = 1 << 21) -> np.ndarray:
    """Asymptotic covariance of the overlapping AV at cluster sizes ``m`` under ``gyro`` (Gaussian).

    .. math::

        \\Omega_{jk} = \\frac{1}{2\\sqrt{M_jM_k}}\\frac1\\pi\\int_0^\\pi
            |H_j|^2|H_k|^2 S^2\\,d\\omega,\\quad S = \\mathrm{psd}(f)/(2\\Delta t),\\ \\omega = 2\\pi f\\Delta t

    by the midpoint rule on ``min(grid_per_cycle * max(m), max_grid)`` points (the filters oscillate
    with period 2 pi / m). Deterministic terms (ramp) have zero PSD and add nothing. For white
    noise the diagonal agrees with the NIST SP 1065 edf, Var = 2 AV^2 / edf (checked in the tests).
    """
    m = np.asarray(m, dtype=float)
    n_grid = int(min(max(grid_per_cycle * m.max(), 4096), max_grid))
    omega_all = (np.arange(n_grid) + 0.5) * (np.pi / n_grid)
    out = np.zeros((m.size, m.size))
    chunk = 1 << 17
    for a in range(0, n_grid, chunk):
        w = omega_all[a : a + chunk]
        S = gyro.psd(w / (2 * np.pi * gyro.dt)) / (2 * gyro.dt)
        G = _haar_gain(m[:, None], w[None, :], np.sin(w / 2)[None, :])
        out += (G * S**2) @ G.T
    out *= 1.0 / n_grid  # (1/pi) * integral = mean over the grid
    M = n_samples - 2 * m + 1
    return out / (2.0 * np.sqrt(np.outer(M, M)))
