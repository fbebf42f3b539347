"""Compiled per-sample recursions of the online Allan-variance filters (SHAKF, NEKF).

Both filters share one measurement model: for every cluster size ``m_j`` (``m = [1]`` for the
papers' filters, ``m = [1, 2, 4, ...]`` for the ``*_multitau`` extensions) the recursive Allan
variance of Miao et al. 2014, eqs 3.3-3.4 (Miao et al. 2015, eqs 43-44),

.. math::

    \\delta_k^2(m) = \\frac{k-2}{k-1}\\,\\delta_{k-1}^2(m)
                   + \\frac{1}{2(k-1)}\\left(\\bar w_k(m) - \\bar w_{k-1}(m)\\right)^2,
    \\qquad k \\ge 2,

is a measurement each time a cluster of ``m_j`` samples completes. In the scaled, dimensionless
units the kernels work in (state ``s_c = c / c_ref``, measurement ``z_j / h_j(c_ref)``) the model is

.. math::  h_j(s) = \\sum_c A_{jc}\\, s_c^2, \\qquad H_{jc} = 2 A_{jc} s_c,

with ``A_jc = beta_c(c_ref) tau_j^{p_c} / h_j(c_ref)`` (Miao et al. 2014, eqs 3.6-3.7). A vector
measurement with a diagonal noise covariance is processed as sequential scalar updates, so the
scalar filters of the papers are the special case ``m = [1]`` of the same code.

Everything here mutates the state arrays it is given, so that a record can be fed in chunks with
the result equal to one pass over the whole record. The plain-NumPy per-sample reference lives in
:mod:`avbench.estimators.online._reference` and is used by the tests only.

Failure codes (``istate[2]``): 0 none, 1 non-finite state, 2 non-positive innovation variance,
3 non-positive measurement-noise variance (SHAKF R), 4 covariance P not positive definite,
5 process-noise covariance Q with a negative diagonal (SHAKF).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from avbench.estimators.online._vec4 import v4_axpy, v4_store, v4_zero

__all__ = ["FAILURES", "av_step", "shakf_run", "nekf_run", "is_posdef"]

FAILURES = {
    0: "",
    1: "non-finite state estimate",
    2: "non-positive innovation variance",
    3: "non-positive measurement-noise variance R",
    4: "state covariance P not positive definite",
    5: "process-noise covariance Q with a negative diagonal",
}

# istate layout (int64): [samples seen, trajectory countdown, failure code, failure sample index]
_SEEN, _COUNTDOWN, _FAIL, _FAIL_AT = 0, 1, 2, 3


@njit(cache=True)
def is_posdef(P):
    """True when the symmetric matrix ``P`` has a Cholesky factorisation (positive definite)."""
    n = P.shape[0]
    L = np.zeros((n, n))
    for i in range(n):
        for j in range(i + 1):
            s = P[i, j]
            for k in range(j):
                s -= L[i, k] * L[j, k]
            if i == j:
                if not s > 0.0:
                    return False
                L[i, i] = math.sqrt(s)
            else:
                L[i, j] = s / L[j, j]
    return True


@njit(cache=True)
def av_step(j, x, m, acc, cnt, prev, kc, av):
    """Feed sample ``x`` to the recursive AV of cluster size ``m[j]``; True if it has a new value.

    ``acc``/``cnt`` hold the open cluster's sum and length, ``prev`` the previous cluster mean,
    ``kc`` the number of completed clusters (the paper's k), ``av`` the current delta_k^2.
    """
    acc[j] += x
    cnt[j] += 1
    if cnt[j] < m[j]:
        return False
    mean = acc[j] / m[j]
    acc[j] = 0.0
    cnt[j] = 0
    kc[j] += 1
    k = kc[j]
    new = False
    if k >= 2:
        d = mean - prev[j]
        av[j] = ((k - 2.0) / (k - 1.0)) * av[j] + d * d / (2.0 * (k - 1.0))
        new = True
    prev[j] = mean
    return new


@njit(cache=True)
def _record(istate, s, nq, every, traj, nt):
    # called after each sample; writes |s| every `every` samples
    if every > 0:
        istate[_COUNTDOWN] -= 1
        if istate[_COUNTDOWN] == 0:
            istate[_COUNTDOWN] = every
            traj_i = nt
            for c in range(nq):
                traj[traj_i, c] = abs(s[c])
            traj[traj_i, nq] = istate[_SEEN] - 1
            return nt + 1
    return nt


@njit(cache=True)
def _fail(istate, code, last, s, nq):
    istate[_FAIL] = code
    istate[_FAIL_AT] = istate[_SEEN] - 1
    for c in range(nq):
        s[c] = last[c]


@njit(cache=True)
def _diag_ok(P):
    for i in range(P.shape[0]):
        if not P[i, i] > 0.0:
            return False
    return True


@njit(cache=True)
def shakf_run(rate, zinv, A, m, acc, cnt, prev, kc, av,
              s, P, q, Q, r, R, b, adapt, istate, every, traj, pd_every):
    """Sage-Husa adaptive EKF of Miao et al. 2014, eqs 3.8-3.19, over one chunk of ``rate``.

    Per sample (k >= 2): time update ``s += q``, ``P += Q`` (eqs 3.8-3.9); then for each cluster
    size with a new recursive AV ``z`` a scalar measurement update (eqs 3.10-3.13) with innovation
    ``eps = z - h(s) - r`` (eq 3.11) followed by the Sage-Husa adaptation (eqs 3.14-3.19) with
    ``gamma_k = (1 - b) / (1 - b^(k+1))``, k the cluster index of that measurement. Returns the
    number of trajectory rows written.
    """
    nq = s.shape[0]
    nm = m.shape[0]
    nt = 0
    PH = np.empty(nq)
    QH = np.empty(nq)
    H = np.empty(nq)
    last = np.empty(nq)
    for i in range(rate.shape[0]):
        if istate[_FAIL] != 0:
            break
        istate[_SEEN] += 1
        x = rate[i]
        for c in range(nq):
            last[c] = s[c]
        if istate[_SEEN] >= 2:
            for c in range(nq):  # eqs 3.8-3.9
                s[c] += q[c]
                for d in range(nq):
                    P[c, d] += Q[c, d]
        for j in range(nm):
            if not av_step(j, x, m, acc, cnt, prev, kc, av):
                continue
            z = av[j] * zinv[j]
            k = kc[j]
            if b < 1.0:
                gam = (1.0 - b) / (1.0 - b ** (k + 1.0))
            else:
                gam = 1.0 / (k + 1.0)
            h = 0.0
            for c in range(nq):
                h += A[j, c] * s[c] * s[c]
                H[c] = 2.0 * A[j, c] * s[c]
            HPH = 0.0
            HQH = 0.0
            for c in range(nq):
                acc_p = 0.0
                acc_q = 0.0
                for d in range(nq):
                    acc_p += P[c, d] * H[d]
                    acc_q += Q[c, d] * H[d]
                PH[c] = acc_p
                QH[c] = acc_q
                HPH += H[c] * acc_p
                HQH += H[c] * acc_q
            S = HPH + R[j]  # eq 3.10 with R_{k-1}
            if not (S > 0.0 and math.isfinite(S)):
                _fail(istate, 2, last, s, nq)
                break
            eps = z - h - r[j]  # eq 3.11 with h(x_{k|k-1}) and r_{k-1}
            for c in range(nq):  # eqs 3.12-3.13, P -= K H P = PH PH^T / S
                s[c] += PH[c] / S * eps
                for d in range(nq):
                    P[c, d] -= PH[c] * PH[d] / S
            # eqs 3.14, 3.16-3.17: D = H^T / S, q += gam Q D eps, Q += gam Q D (eps^2 - S) D^T Q
            fq = gam * (eps * eps - S) / (S * S)
            for c in range(nq):
                if adapt & 1:
                    q[c] += gam * QH[c] * eps / S
                if adapt & 2:
                    for d in range(nq):
                        Q[c, d] += fq * QH[c] * QH[d]
            if adapt & 4:
                hpost = 0.0
                for c in range(nq):
                    hpost += A[j, c] * s[c] * s[c]
                r[j] = (1.0 - gam) * r[j] + gam * (z - hpost)  # eq 3.18
            if adapt & 8:
                HK = HPH / S
                HPkH = HPH - HPH * HPH / S
                R[j] = (1.0 - gam) * R[j] + gam * ((1.0 - HK) ** 2 * eps * eps + HPkH)  # eq 3.19
            code = 0
            for c in range(nq):
                if not math.isfinite(s[c]):
                    code = 1
            if code == 0 and not R[j] > 0.0:
                code = 3
            if code == 0 and not _diag_ok(P):
                code = 4
            if code == 0:
                for c in range(nq):
                    if Q[c, c] < 0.0:
                        code = 5
            if code != 0:
                _fail(istate, code, last, s, nq)
                break
        if istate[_FAIL] != 0:
            break
        if pd_every > 0 and istate[_SEEN] % pd_every == 0 and not is_posdef(P):
            _fail(istate, 4, last, s, nq)
            break
        nt = _record(istate, s, nq, every, traj, nt)
    return nt


@njit(cache=True)
def _nn_jacobian(xa, nq, p, t, G, nn):
    """NN output ``nn`` (length nq) and its Jacobian G (nq x n) w.r.t. the augmented state.

    Layout of ``xa``: ``[s (nq), eta (p x nq, row-major), lam (nq x p, row-major)]``;
    hidden ``t_h = tanh(sum_i eta[h, i] s_i)``, output ``NN_j = sum_h lam[j, h] t_h``
    (Miao et al. 2015, eq 51).
    """
    oe = nq
    ol = nq + p * nq
    for h in range(p):
        a = 0.0
        for i in range(nq):
            a += xa[oe + h * nq + i] * xa[i]
        t[h] = math.tanh(a)
    nn[:] = 0.0
    G[:, :] = 0.0
    for j in range(nq):
        for h in range(p):
            lam = xa[ol + j * p + h]
            nn[j] += lam * t[h]
            g = lam * (1.0 - t[h] * t[h])
            for i in range(nq):
                G[j, i] += g * xa[oe + h * nq + i]
                G[j, oe + h * nq + i] = g * xa[i]
            G[j, ol + j * p + h] = t[h]


@njit(cache=True)
def _gp_row_block(G, P, M, a, n, c0, width):
    """``M[a, c0:c0+width]`` (``width`` 32, 16 or 4) of ``M = G P``, each entry summed over ``e``
    in order from +0.0, skipping the exact zeros of ``G[a]``, in registers (:mod:`._vec4`)."""
    s0 = v4_zero()
    s1 = v4_zero()
    s2 = v4_zero()
    s3 = v4_zero()
    s4 = v4_zero()
    s5 = v4_zero()
    s6 = v4_zero()
    s7 = v4_zero()
    for e in range(n):  # `width` is loop-invariant: LLVM unswitches the loop into one per width
        g = G[a, e]
        if g != 0.0:
            s0 = v4_axpy(s0, g, P, e, c0)
            if width >= 16:
                s1 = v4_axpy(s1, g, P, e, c0 + 4)
                s2 = v4_axpy(s2, g, P, e, c0 + 8)
                s3 = v4_axpy(s3, g, P, e, c0 + 12)
            if width == 32:
                s4 = v4_axpy(s4, g, P, e, c0 + 16)
                s5 = v4_axpy(s5, g, P, e, c0 + 20)
                s6 = v4_axpy(s6, g, P, e, c0 + 24)
                s7 = v4_axpy(s7, g, P, e, c0 + 28)
    v4_store(M, a, c0, s0)
    if width >= 16:
        v4_store(M, a, c0 + 4, s1)
        v4_store(M, a, c0 + 8, s2)
        v4_store(M, a, c0 + 12, s3)
    if width == 32:
        v4_store(M, a, c0 + 16, s4)
        v4_store(M, a, c0 + 20, s5)
        v4_store(M, a, c0 + 24, s6)
        v4_store(M, a, c0 + 28, s7)


@njit(cache=True)
def _gp_rows(G, P, M, nq, n):
    """``M = G P`` for the ``nq`` rows of the NN Jacobian ``G`` (``nq x n``, ``P`` ``n x n``).

    Every entry is ``sum_e G[a, e] P[e, c]`` added in increasing ``e`` from +0.0, the exact zeros
    of ``G`` skipped (their products would add +-0, or NaN against an infinite ``P``): the sums of
    the plain loop, so bit-identical to it. Columns go in register blocks of 32, 16 and 4; the
    last block may overlap the one before (the same sums, written twice): a block of 4 for the
    last 1-4 columns, else of 16. Below 4 columns, the plain loop.
    """
    for a in range(nq):
        if n < 4:
            for c in range(n):
                M[a, c] = 0.0
            for e in range(n):
                g = G[a, e]
                if g != 0.0:
                    for c in range(n):
                        M[a, c] += g * P[e, c]
            continue
        c0 = 0
        while c0 < n:
            if c0 + 32 <= n:
                _gp_row_block(G, P, M, a, n, c0, 32)
                c0 += 32
            elif c0 + 16 <= n or (n - c0 > 4 and n >= 16):
                c0 = min(c0, n - 16)
                _gp_row_block(G, P, M, a, n, c0, 16)
                c0 += 16
            else:
                c0 = min(c0, n - 4)
                _gp_row_block(G, P, M, a, n, c0, 4)
                c0 += 4


@njit(cache=True)
def nekf_run(rate, zinv, A, m, acc, cnt, prev, kc, av,
             xa, P, Qs, qw, Rbar, nq, p, istate, every, traj, pd_every):
    """Neural extended Kalman filter of Miao et al. 2015, eqs 48-57, over one chunk of ``rate``.

    Per sample (k >= 2): prediction ``s += NN(s, eta, lam)``, weights unchanged (eq 55), covariance
    ``P = F P F^T + Qbar`` with ``F = I + [dNN/dxa; 0]`` (eqs 52-53); then for each cluster size
    with a new recursive AV a scalar EKF update (eqs 54, 56-57), ``H = [dh/ds, 0]``.
    Returns the number of trajectory rows written.

    The structure is used, not multiplied out: ``F - I`` has only ``nq`` non-zero rows, so
    ``F P F^T = P + E P + P E^T + E P E^T`` touches only the first ``nq`` rows and columns (and the
    zero entries of the Jacobian are skipped), and ``Qbar = blockdiag(Qs, qw I)`` (``Qs`` the
    ``nq x nq`` coefficient block, ``qw`` the weights' variance) is added as ``nq^2 + n - nq``
    terms instead of a dense ``n x n`` matrix: the same sums (the zeros of ``Qbar`` add nothing), so
    the result is bit-identical to adding the dense matrix.
    """
    n = xa.shape[0]
    nm = m.shape[0]
    nt = 0
    t = np.empty(p)
    G = np.zeros((nq, n))
    M = np.empty((nq, n))
    GG = np.empty((nq, nq))
    nn = np.empty(nq)
    PH = np.empty(n)
    H = np.empty(nq)
    last = np.empty(nq)
    for i in range(rate.shape[0]):
        if istate[_FAIL] != 0:
            break
        istate[_SEEN] += 1
        x = rate[i]
        for c in range(nq):
            last[c] = xa[c]
        if istate[_SEEN] >= 2:
            _nn_jacobian(xa, nq, p, t, G, nn)
            # M = G P (nq x n); P <- P + E P + P E^T + E P E^T + Qbar, E = [G; 0]
            _gp_rows(G, P, M, nq, n)
            for a in range(nq):  # G P G^T, computed once per pair so that P stays symmetric
                for c in range(a, nq):
                    acc_g = 0.0
                    for e in range(n):
                        acc_g += M[a, e] * G[c, e]
                    GG[a, c] = acc_g
                    GG[c, a] = acc_g
            for a in range(nq):
                for c in range(n):
                    P[a, c] += M[a, c]
                    P[c, a] += M[a, c]
                for c in range(nq):
                    P[a, c] += GG[a, c]
            for a in range(nq):
                for c in range(nq):
                    P[a, c] += Qs[a, c]
            for a in range(nq, n):
                P[a, a] += qw
            for c in range(nq):
                xa[c] += nn[c]
        for j in range(nm):
            if not av_step(j, x, m, acc, cnt, prev, kc, av):
                continue
            z = av[j] * zinv[j]
            h = 0.0
            for c in range(nq):
                h += A[j, c] * xa[c] * xa[c]
                H[c] = 2.0 * A[j, c] * xa[c]
            HPH = 0.0
            for a in range(n):
                acc_p = 0.0
                for c in range(nq):
                    acc_p += P[a, c] * H[c]
                PH[a] = acc_p
            for c in range(nq):
                HPH += H[c] * PH[c]
            S = HPH + Rbar[j]
            if not (S > 0.0 and math.isfinite(S)):
                _fail(istate, 2, last, xa, nq)
                break
            eps = z - h
            for a in range(n):
                xa[a] += PH[a] / S * eps
                f = PH[a] / S
                for c in range(n):
                    P[a, c] -= f * PH[c]
            code = 0
            for a in range(n):
                if not math.isfinite(xa[a]):
                    code = 1
            if code == 0 and not _diag_ok(P):
                code = 4
            if code != 0:
                _fail(istate, code, last, xa, nq)
                break
        if istate[_FAIL] != 0:
            break
        if pd_every > 0 and istate[_SEEN] % pd_every == 0 and not is_posdef(P):
            _fail(istate, 4, last, xa, nq)
            break
        nt = _record(istate, xa, nq, every, traj, nt)
    return nt
