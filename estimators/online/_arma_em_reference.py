"""Plain NumPy, per-sample reference of the Elliott-Krishnamurthy recursive EM filters.

Used only by the tests, to check that the compiled kernel in :mod:`avbench.estimators.online._arma_em_kernels`
gives the same numbers (arguments, state arrays and return value are identical; see
:func:`avbench.estimators.online._arma_em_kernels.ek_run` for the equations). Deliberately written as directly
as possible, one sample at a time, with matrix products: it is slow by design.
"""

from __future__ import annotations

import math

import numpy as np

from avbench.estimators.online._arma_em_kernels import (
    FAIL_FILTER,
    FAIL_SINGULAR_PRED,
    I_CLIPPED,
    I_FAIL_INDEX,
    I_FIRST_REJECT,
    I_K,
    I_REJECTED,
    I_STATUS,
    I_UPDATES,
    S_LOGLIK,
    S_SYY,
)

__all__ = ["ek_run_reference", "m_step_reference", "evaluate_stats_reference", "clip_spectrum_reference"]


def _sym(i: int, j: int, m: int) -> np.ndarray:
    e = np.eye(m)
    return 0.5 * (np.outer(e[i], e[j]) + np.outer(e[j], e[i]))


def evaluate_stats_reference(a, b, d, aT, bT, x, P):
    """U^(M) (M = 0, 1, 2, 3) and E from the filter coefficients (Miao et al. 2015, eqs 32-33)."""
    m = x.shape[0]
    U = np.empty((4, m, m))
    for M in (0, 1, 3):
        for i in range(m):
            for j in range(m):
                dij = d[M, i, j]
                U[M, i, j] = a[M, i, j] + b[M, i, j] @ x + np.trace(dij @ P) + x @ dij @ x
    U[2] = U[0] - (P + np.outer(x, x))  # H2_k = H0_k - x_k x_k'
    E = aT + bT @ x
    return U, E


def clip_spectrum_reference(A):
    """Eigenvalues of A outside the closed unit disk moved onto it; returns ``(A, changed)``.

    Real eigenvalues clipped to [-1, 1] by Sylvester's formula (eigenvectors kept); a complex pair
    of modulus r > 1 scaled by 1/r.
    """
    lam = np.linalg.eigvals(A)
    if np.all(np.abs(lam) <= 1.0):
        return A, False
    if np.any(np.iscomplex(lam)):
        return A / np.abs(lam[0]), True
    lam = lam.real
    new = np.clip(lam, -1.0, 1.0)
    m = A.shape[0]
    if m == 1 or lam[0] == lam[1]:
        return A + (new[0] - lam[0]) * np.eye(m), True
    eye = np.eye(m)
    out = A.copy()
    for i, j in ((0, 1), (1, 0)):
        out += (new[i] - lam[i]) * (A - lam[j] * eye) / (lam[i] - lam[j])
    return out, True


def m_step_reference(a, b, d, aT, bT, x, P, sc, k, exact_q=False):
    """Parameter update (Miao et al. 2015, eqs 28-31, sign of eq. 29 corrected).

    Returns ``(ok, A, C, Q, R, clipped)``; ``ok`` is False when U^(0) or U^(2) is singular or
    the new R, Q are not positive (semi-)definite; ``clipped`` when A's spectrum was moved onto
    the unit disk (:func:`clip_spectrum_reference`) before Q was formed.
    """
    U, E = evaluate_stats_reference(a, b, d, aT, bT, x, P)
    U0 = 0.5 * (U[0] + U[0].T)
    U3 = 0.5 * (U[3] + U[3].T)
    U1 = U[1]
    U2 = 0.5 * (U[2] + U[2].T)
    m = x.shape[0]
    if np.linalg.det(U2) <= 0 or np.linalg.det(U0) <= 0:
        return False, None, None, None, None, False
    A = U1 @ np.linalg.inv(U2)
    if not np.all(np.isfinite(A)):
        return False, None, None, None, None, False
    A, clipped = clip_spectrum_reference(A)
    Q = ((U3 if exact_q else U0) - A @ U1.T - U1 @ A.T + A @ U2 @ A.T) / k
    Q = 0.5 * (Q + Q.T)
    C = np.linalg.solve(U0, E)
    R = (sc[S_SYY] - 2.0 * C @ E + C @ U0 @ C) / (k + 1)
    first = U3 if exact_q else U0
    for i in range(m):  # rounding-level negative diagonal of Q -> 0 (with its row and column)
        if -1e-9 * abs(first[i, i]) / k < Q[i, i] < 0:
            Q[i, :] = 0.0
            Q[:, i] = 0.0
    ok = R > 0 and np.all(np.diag(Q) >= 0) and (m == 1 or np.linalg.det(Q) >= -1e-10 * Q[0, 0] * Q[1, 1])
    ok = ok and np.all(np.isfinite(A)) and np.all(np.isfinite(Q)) and np.all(np.isfinite(C))
    return bool(ok), A, C, Q, np.array([R]), clipped


def ek_run_reference(y, A, C, Q, R, x, P, a, b, d, aT, bT, sc, ic,
                     recursive, warmup, update_every, trace_every, trace, exact_q=False):
    """Same contract as :func:`avbench.estimators.online._arma_em_kernels.ek_run`, one sample at a time in NumPy."""
    m = x.shape[0]
    eye = np.eye(m)
    ntr = 0
    for t in range(y.shape[0]):
        yk = y[t]
        # smoothing quantities for x_k given x_{k+1} and Y_k (eqs 19-21, stable form of Z^-1)
        Pp = A @ P @ A.T + Q
        if np.linalg.det(Pp) <= 0 or not np.all(np.isfinite(Pp)):
            ic[I_STATUS], ic[I_FAIL_INDEX] = FAIL_SINGULAR_PRED, ic[I_K] + 1
            return ntr
        J = P @ A.T @ np.linalg.inv(Pp)
        O = J.T
        IJA = eye - J @ A
        Zi = IJA @ P @ IJA.T + J @ Q @ J.T
        S = IJA @ x
        # E-K filters (eqs 22-27, 31-32); eq. 30 in its symmetric form
        for i in range(m):
            for j in range(m):
                Eij = _sym(i, j, m)
                # M = 0
                dd = d[0, i, j]
                a[0, i, j] += b[0, i, j] @ S + np.trace(dd @ Zi) + S @ dd @ S
                b[0, i, j] = O @ (b[0, i, j] + 2.0 * dd @ S)
                d[0, i, j] = O @ dd @ O.T + Eij
                # M = 3: as M = 0, started at 0 (sum over l >= 1); needed for the exact Q only
                if exact_q:
                    dd = d[3, i, j]
                    a[3, i, j] += b[3, i, j] @ S + np.trace(dd @ Zi) + S @ dd @ S
                    b[3, i, j] = O @ (b[3, i, j] + 2.0 * dd @ S)
                    d[3, i, j] = O @ dd @ O.T + Eij
                # M = 1: sum of x_l[i] x_{l-1}[j]
                dd = d[1, i, j]
                a[1, i, j] += b[1, i, j] @ S + np.trace(dd @ Zi) + S @ dd @ S
                b[1, i, j] = O @ (b[1, i, j] + 2.0 * dd @ S) + eye[i] * S[j]
                d[1, i, j] = O @ dd @ O.T + 0.5 * (np.outer(eye[i], O[:, j]) + np.outer(O[:, j], eye[i]))
                # M = 2 (sum of x_{l-1}[i] x_{l-1}[j]) is H0 - x_k x_k': see evaluate_stats_reference
        for i in range(m):
            aT[i] += bT[i] @ S
            bT[i] = O @ bT[i] + eye[i] * yk
        sc[S_SYY] += yk * yk
        # Kalman measurement update (eqs 16-18, sign of the gain term in eq. 17 corrected)
        xp = A @ x
        s = C @ Pp @ C + R[0]
        if not (s > 0) or not math.isfinite(s):
            ic[I_STATUS], ic[I_FAIL_INDEX] = FAIL_FILTER, ic[I_K] + 1
            return ntr
        K = Pp @ C / s
        e = yk - C @ xp
        x[:] = xp + K * e
        IKC = eye - np.outer(K, C)
        P[:] = IKC @ Pp @ IKC.T + np.outer(K, K) * R[0]
        sc[S_LOGLIK] += -0.5 * (math.log(2.0 * math.pi * s) + e * e / s)
        ic[I_K] += 1
        k = ic[I_K]
        if recursive and k >= warmup and k % update_every == 0:
            ok, An, Cn, Qn, Rn, clipped = m_step_reference(a, b, d, aT, bT, x, P, sc, k, exact_q)
            if ok:
                A[:], C[:], Q[:], R[:] = An, Cn, Qn, Rn
                ic[I_UPDATES] += 1
                ic[I_CLIPPED] += clipped
            else:
                if ic[I_REJECTED] == 0:
                    ic[I_FIRST_REJECT] = k
                ic[I_REJECTED] += 1
        if trace_every > 0 and k % trace_every == 0 and ntr < trace.shape[0]:
            trace[ntr, 0] = k
            trace[ntr, 1:] = np.concatenate([A.ravel(), C, Q.ravel(), R])
            ntr += 1
    return ntr
