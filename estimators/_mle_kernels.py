"""The block-mean state-space model of :mod:`estimators.mle` and its compiled Kalman likelihood.

:class:`BlockMeanSystem` builds the system matrices (transition ``T``, disturbance covariance
``Qc``, design ``Z``, observation variance ``H``, initial covariances) of the exact block-mean
model derived in the :mod:`estimators.mle` docstring; :func:`diffuse_loglike` evaluates its exact
Gaussian log-likelihood by the Kalman filter with the exact initial treatment of the diffuse
states (level, drift) of Durbin & Koopman (2012, Sec. 5.2, univariate form of Sec. 6.4; Koopman &
Durbin 2000): while the diffuse covariance :math:`P_\\infty` is non-zero, an observation with
:math:`F_\\infty = Z P_\\infty Z' > 0` contributes :math:`-\\tfrac12\\log(2\\pi F_\\infty)` and
updates with the gains :math:`K_0 = P_\\infty Z'/F_\\infty`,
:math:`K_1 = (P_* Z' - F_* K_0)/F_\\infty`; afterwards the ordinary prediction-error decomposition
:math:`-\\tfrac12\\sum_t(\\log 2\\pi F_t + v_t^2/F_t)` (Durbin & Koopman 2012, eq. 7.2).

The recursion is the one statsmodels runs for ``BlockMeanModel`` (univariate diffuse filter,
diffuse tolerance 1e-10, predicted covariance forced symmetric, and the covariance frozen once
the squared Frobenius norm of its change is below 1e-19 -- a time-invariant filter has then
reached its steady state, so later steps update the state only). That model
(:mod:`estimators._mle_model`) is kept as the reference the tests hold this one to. Everything
here is NumPy + numba: no statsmodels import.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["BlockMeanSystem", "diffuse_loglike", "_gm_block", "_level_block"]

#: statsmodels' thresholds (``KalmanFilter``): diffuse F_inf, and the steady-state test on P
TOL_DIFFUSE = 1e-10
TOL_CONVERGED = 1e-19


def _gm_block(phi_log, sigma, m):
    """Transition and disturbance covariance of (s, xbar) for a GM with log(phi) = phi_log."""
    j = np.arange(1, m + 1, dtype=float)
    phi = math.exp(phi_log)
    c = np.expm1(j * phi_log) / math.expm1(phi_log)  # (1 - phi^j) / (1 - phi), stable as phi -> 1
    pw = np.exp((j - 1) * phi_log)  # phi^(j-1)
    q = sigma**2 * -math.expm1(2 * phi_log)  # sigma^2 (1 - phi^2)
    a = float(np.exp(j * phi_log).sum()) / m
    cov = q * np.array([[pw @ pw, pw @ c / m], [pw @ c / m, c @ c / m**2]])
    T = np.array([[phi**m, 0.0], [a, 0.0]])
    return T, cov


def _level_block(K2dt, m, dt, drift):
    j = np.arange(1, m + 1, dtype=float)
    cov = K2dt * np.array([[m, j.sum() / m], [j.sum() / m, (j @ j) / m**2]])
    T = np.array([[1.0, 0.0], [1.0, 0.0]])
    if drift:
        T = np.hstack([T, [[m * dt], [dt * (m + 1) / 2]]])
        T = np.vstack([T, [0.0, 0.0, 1.0]])
        cov = np.pad(cov, ((0, 1), (0, 1)))
    return T, cov


class BlockMeanSystem:
    """Layout and system matrices of the block-mean model (see :mod:`estimators.mle`).

    State: ``(s, xbar)`` if "GM", ``(theta_j, theta_{j-1})`` if "QN", then ``(L, Lbar[, r])``; the
    level (and slope) are diffuse. Parameters are the natural logarithms of, in order, Q (if
    "QN"), N (if "WN"), sigma and Tc (if "GM"), K (if "RW").
    """

    def __init__(self, latents, m: int, dt: float):
        self.latents = tuple(latents)
        self.m, self.dt = int(m), float(dt)
        self.has_gm = "GM" in self.latents
        self.has_q = "QN" in self.latents
        self.drift = "DR" in self.latents
        self.q0 = 2 if self.has_gm else 0  # first state of the quantization block
        self.lev = self.q0 + (2 if self.has_q else 0)
        self.k = self.lev + 2 + (1 if self.drift else 0)
        Z = np.zeros(self.k)
        Z[self.lev + 1] = 1.0
        if self.has_gm:
            Z[1] = 1.0
        if self.has_q:  # block mean of theta-differences telescopes: (theta_j - theta_{j-1}) / (m dt)
            Z[self.q0], Z[self.q0 + 1] = 1.0 / (m * dt), -1.0 / (m * dt)
        self.Z = Z
        names = []
        for lat in self.latents:
            names += {"QN": ["log_Q"], "WN": ["log_N"], "GM": ["log_sigma", "log_tc"], "RW": ["log_K"]}.get(lat, [])
        self.names = names

    def values(self, params) -> dict:
        return dict(zip(self.names, np.exp(np.asarray(params, dtype=float))))

    def matrices(self, params, scale: float = 1.0):
        """``(T, Qc, H, P0, Pinf0)`` for log-parameters ``params``, data multiplied by ``scale``.

        ``P0`` is the covariance of the first state from its stationary distribution (GM,
        quantization); ``Pinf0`` is the identity on the diffuse block (level, drift).
        """
        v = {key: (val if key == "log_tc" else val * scale) for key, val in self.values(params).items()}
        m, dt, k = self.m, self.dt, self.k
        T, Qc, P0, Pinf0 = np.zeros((k, k)), np.zeros((k, k)), np.zeros((k, k)), np.zeros((k, k))
        if self.has_gm:
            sigma, tc = v["log_sigma"], v["log_tc"]
            Tg, Qg = _gm_block(-dt / tc, sigma, m)
            T[:2, :2], Qc[:2, :2] = Tg, Qg
            P0[:2, :2] = sigma**2 * np.outer(Tg[:, 0], Tg[:, 0]) + Qg  # (s_1, xbar_1) from a stationary s_0
        if self.has_q:
            q, Q2 = self.q0, v["log_Q"] ** 2
            T[q + 1, q] = 1.0
            Qc[q, q] = Q2
            P0[q, q] = P0[q + 1, q + 1] = Q2
        K2dt = v.get("log_K", 0.0) ** 2 * dt
        Tl, Ql = _level_block(K2dt, m, dt, self.drift)
        T[self.lev :, self.lev :], Qc[self.lev :, self.lev :] = Tl, Ql
        for i in range(self.lev, k):
            Pinf0[i, i] = 1.0
        H = v.get("log_N", 0.0) ** 2 / (m * dt)
        return T, Qc, H, P0, Pinf0

    def loglike(self, y, params, scale: float = 1.0, final=None) -> float:
        """Exact diffuse log-likelihood of ``y * scale`` (scaled units); ``final``: optional
        ``(a, P)`` arrays that receive the last filtered state and its covariance."""
        T, Qc, H, P0, Pinf0 = self.matrices(params, scale)
        a_out = np.empty(self.k) if final is None else final[0]
        P_out = np.empty((self.k, self.k)) if final is None else final[1]
        return diffuse_loglike(y, scale, T, Qc, self.Z, H, P0, Pinf0, a_out, P_out)


@njit(cache=True)
def _predict(tp, ti, tl, tv, Pf, Qc, P, tmp):
    """P = T Pf T' + Qc, then forced symmetric (statsmodels' STABILITY_FORCE_SYMMETRY).

    T is given by its non-zero entries, row by row (``tp``: row pointers, ``tl``: columns, ``tv``:
    values, ``ti`` unused): the block-mean transition has at most 8 of its 49 entries non-zero.
    The sums run over the same terms in the same order as the dense product, less the zeros.
    """
    k = P.shape[0]
    for i in range(k):
        for j in range(k):
            acc = 0.0
            for e in range(tp[i], tp[i + 1]):
                acc += tv[e] * Pf[tl[e], j]
            tmp[i, j] = acc
    for i in range(k):
        for j in range(k):
            acc = 0.0
            for e in range(tp[j], tp[j + 1]):
                acc += tmp[i, tl[e]] * tv[e]
            P[i, j] = acc + Qc[i, j]
    for i in range(k):
        for j in range(i + 1, k):
            s = 0.5 * (P[i, j] + P[j, i])
            P[i, j] = s
            P[j, i] = s


@njit(cache=True)
def _forecast(P, Z, H, M):
    """M = P Z and the forecast variance Z' P Z + H."""
    k = P.shape[0]
    F = H
    for i in range(k):
        acc = 0.0
        for j in range(k):
            acc += P[i, j] * Z[j]
        M[i] = acc
        F += Z[i] * acc
    return F


@njit(cache=True)
def diffuse_loglike(y, scale, T, Qc, Z, H, P0, Pinf0, a_out, P_out):
    """Log-likelihood of ``y * scale`` under the state-space model (module docstring).

    Returns the log-likelihood in the scaled units; ``a_out``/``P_out`` receive the last filtered
    state and covariance. A non-positive forecast variance outside the diffuse period gives -inf.
    """
    n = y.shape[0]
    k = T.shape[0]
    a = np.zeros(k)
    af = np.empty(k)
    P = P0.copy()
    Pi = Pinf0.copy()
    Pf = np.empty((k, k))
    Pif = np.empty((k, k))
    Pprev = np.empty((k, k))
    tmp = np.empty((k, k))
    M = np.empty(k)
    Mi = np.empty(k)
    K0 = np.empty(k)
    K1 = np.empty(k)
    # T's non-zero entries by rows (CSR), for the covariance prediction
    tp = np.zeros(k + 1, dtype=np.int64)
    nnz = 0
    for i in range(k):
        for j in range(k):
            if T[i, j] != 0.0:
                nnz += 1
        tp[i + 1] = nnz
    ti = np.empty(nnz, dtype=np.int64)
    tl = np.empty(nnz, dtype=np.int64)
    tv = np.empty(nnz)
    e = 0
    for i in range(k):
        for j in range(k):
            if T[i, j] != 0.0:
                ti[e], tl[e], tv[e] = i, j, T[i, j]
                e += 1
    zero = np.zeros((k, k))
    log2pi = math.log(2.0 * math.pi)
    ll = 0.0
    nobs_diffuse = 0
    converged = False
    Fc = 1.0
    ssq = 0.0
    t_conv = n
    for t in range(n):
        diffuse = False
        if t == nobs_diffuse:
            ss = 0.0
            for i in range(k):
                for j in range(k):
                    ss += Pi[i, j] * Pi[i, j]
            if ss > TOL_DIFFUSE:
                nobs_diffuse += 1
                diffuse = True
        v = y[t] * scale
        for i in range(k):
            v -= Z[i] * a[i]
        if converged:
            # steady state: fixed gain K0 and forecast variance Fc (the log-determinant term
            # -0.5 log(2 pi Fc) per step is added once at the end)
            for i in range(k):
                af[i] = a[i] + K0[i] * v
            ssq += v * v
            for i in range(k):
                acc = 0.0
                for e in range(tp[i], tp[i + 1]):
                    acc += tv[e] * af[tl[e]]
                a[i] = acc
            continue
        F = max(_forecast(P, Z, H, M), 0.0)
        Fi = max(_forecast(Pi, Z, 0.0, Mi), 0.0) if diffuse else 0.0
        if diffuse and Fi > TOL_DIFFUSE:
            for i in range(k):
                K0[i] = Mi[i] / Fi
            for i in range(k):
                K1[i] = M[i] / Fi + (-F / Fi) * K0[i]
            for i in range(k):
                af[i] = a[i] + K0[i] * v
            # Pf = P L0' + Pi L1', Pif = Pi L0' with L0 = I - K0 Z', L1 = -K1 Z'
            for i in range(k):
                for j in range(k):
                    Pf[i, j] = P[i, j] - M[i] * K0[j] - Mi[i] * K1[j]
                    Pif[i, j] = Pi[i, j] - Mi[i] * K0[j]
            ll -= 0.5 * math.log(2.0 * math.pi * Fi)
        elif F > TOL_DIFFUSE:
            for i in range(k):
                K0[i] = M[i] / F
            for i in range(k):
                af[i] = a[i] + K0[i] * v
            for i in range(k):
                for j in range(k):
                    Pf[i, j] = P[i, j] - M[i] * K0[j]
                    Pif[i, j] = Pi[i, j]
            ll -= 0.5 * (log2pi + math.log(F) + v * v / F)
        else:
            if not diffuse:
                return -np.inf
            for i in range(k):
                af[i] = a[i]
                for j in range(k):
                    Pf[i, j] = P[i, j]
                    Pif[i, j] = Pi[i, j]
        # prediction
        for i in range(k):
            acc = 0.0
            for j in range(k):
                acc += T[i, j] * af[j]
            a[i] = acc
        for i in range(k):
            for j in range(k):
                Pprev[i, j] = P[i, j]
        _predict(tp, ti, tl, tv, Pf, Qc, P, tmp)
        if diffuse or t < nobs_diffuse + 1:
            _predict(tp, ti, tl, tv, Pif, zero, Pi, tmp)
        elif t + 1 < n:
            ss = 0.0
            for i in range(k):
                for j in range(k):
                    d = P[i, j] - Pprev[i, j]
                    ss += d * d
            if ss < TOL_CONVERGED:
                # the next forecast's F and gain are those of this step's covariance
                converged = True
                t_conv = t + 1
                Fc = _forecast(P, Z, H, M)
                for i in range(k):
                    K0[i] = M[i] / Fc
                for i in range(k):
                    for j in range(k):
                        Pf[i, j] = P[i, j] - M[i] * K0[j]
    if converged:
        ll -= 0.5 * ((n - t_conv) * (log2pi + math.log(Fc)) + ssq / Fc)
    for i in range(k):
        a_out[i] = af[i]
        for j in range(k):
            P_out[i, j] = Pf[i, j]
    return ll
