"""Compiled evaluation of the profile Whittle log-likelihood, its score and expected information.

Two compiled passes over the Fourier frequencies (no temporaries), for :mod:`avbench.estimators.likelihood.whittle`. With
:math:`S_k = \\sum_j a_j B_{jk}` the model spectrum, the trend slope is profiled out by GLS,
:math:`\\hat\\beta = \\sum_k w_k \\mathrm{Re}(\\bar G_k X_k)/S_k \\big/ \\sum_k w_k|G_k|^2/S_k`, and with
:math:`I_k = (|X_k|^2 - 2\\hat\\beta\\,\\mathrm{Re}(\\bar G_kX_k) + \\hat\\beta^2|G_k|^2)/n`,

.. math::

    \\ell = -\\sum_k w_k(\\log S_k + I_k/S_k),\\quad
    s_i = \\sum_k w_k g_{ik}(I_k/S_k - 1),\\quad
    F_{il} = \\sum_k w_k g_{ik}g_{lk},\\quad g_{ik} = \\frac{\\partial S_k/\\partial u_i}{S_k},

with :math:`\\partial S/\\partial u_i = a_iB_{ik}` for the log-variances (``linear=False``) or
:math:`B_{ik}` for the variances themselves (``linear=True``: the score and information in
:math:`a`, defined where a variance is 0 or negative) and ``c_tc * D_k`` for a
Gauss-Markov log-Tc (``D`` its derivative spectrum). :func:`whittle_pass_py` is the plain-NumPy
twin used by the tests only.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["whittle_pass", "whittle_pass_py"]


def whittle_pass_py(a, Bm, D, c_tc, X2, GX, G2, w, n, grad, linear=False):
    """Reference: ``(loglik, beta, sgg, score, info)`` with NumPy arrays (tests only)."""
    S = a @ Bm
    if np.any(S <= 0):
        return -np.inf, np.nan, np.nan, np.zeros(0), np.zeros((0, 0))
    wS = w / S
    sgg = float(wS @ G2)
    beta = float(wS @ GX) / sgg
    I = (X2 - 2 * beta * GX + beta * beta * G2) / n
    ll = -float(w @ (np.log(S) + I / S))
    q = a.size + (1 if D.size else 0)
    if not grad:
        return ll, beta, sgg, np.zeros(q), np.zeros((q, q))
    g = (Bm if linear else a[:, None] * Bm) / S
    if D.size:
        g = np.vstack([g, c_tc * D / S])
    r = w * (I / S - 1.0)
    return ll, beta, sgg, g @ r, (g * w) @ g.T


@njit(cache=True)
def _pass(a, Bm, D, c_tc, X2, GX, G2, w, n, grad, linear, score, info):
    """Log-likelihood, beta, sgg; with ``grad`` accumulates the score and the (lower) information."""
    p, K = Bm.shape
    has_tc = D.size > 0
    q = p + 1 if has_tc else p
    sgg = 0.0
    sgx = 0.0
    for k in range(K):
        S = 0.0
        for j in range(p):
            S += a[j] * Bm[j, k]
        if not S > 0.0:
            return -np.inf, np.nan, np.nan
        wS = w[k] / S
        sgg += wS * G2[k]
        sgx += wS * GX[k]
    beta = sgx / sgg
    ll = 0.0
    gk = np.empty(q)
    for k in range(K):
        S = 0.0
        for j in range(p):
            S += a[j] * Bm[j, k]
        iS = 1.0 / S
        IS = (X2[k] - 2.0 * beta * GX[k] + beta * beta * G2[k]) * (iS / n)
        ll -= w[k] * (np.log(S) + IS)
        if grad:
            r = w[k] * (IS - 1.0)
            for j in range(p):
                gk[j] = Bm[j, k] * iS if linear else a[j] * Bm[j, k] * iS
            if has_tc:
                gk[p] = c_tc * D[k] * iS
            for i in range(q):
                score[i] += gk[i] * r
                wi = w[k] * gk[i]
                for m in range(i + 1):
                    info[i, m] += wi * gk[m]
    return ll, beta, sgg


def whittle_pass(a, Bm, D, c_tc, X2, GX, G2, w, n, grad, linear=False):
    """Compiled twin of :func:`whittle_pass_py`: two compiled passes over the frequencies (S and the
    GLS slope, then the likelihood, score and information), no temporaries."""
    q = a.size + (1 if D.size else 0)
    score = np.zeros(q)
    info = np.zeros((q, q))
    ll, beta, sgg = _pass(a, Bm, D, float(c_tc), X2, GX, G2, w, n, grad, bool(linear), score, info)
    if grad and np.isfinite(ll):
        info = np.tril(info) + np.tril(info, -1).T
    return ll, beta, sgg, score, info
