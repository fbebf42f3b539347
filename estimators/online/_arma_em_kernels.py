"""Compiled (numba) kernel of the Elliott-Krishnamurthy recursive EM filters (Miao et al. 2015, §3.2).

Model (Miao et al. 2015, eq. 16), scalar observation, state dimension m (1 or 2 here):

.. math::

    x_{k+1} = A x_k + w_k,\\quad w_k \\sim N(0, Q);\\qquad
    y_k = C x_k + v_k,\\quad v_k \\sim N(0, R).

For each incoming sample :math:`y_{k+1}` the kernel

1. forms the one-step-back smoothing density of :math:`x_k` given :math:`x_{k+1}` and
   :math:`Y_k` (Miao et al. 2015, eqs 19-21; Elliott & Krishnamurthy 1999):
   :math:`P^-_{k+1} = A P_k A^T + Q`, :math:`O_k = (P^-_{k+1})^{-1} A P_k`,
   :math:`S_k = (I - O_k^T A)\\hat x_k`, and
   :math:`Z_k^{-1} = (I-O_k^TA)P_k(I-O_k^TA)^T + O_k^T Q O_k`
   (algebraically equal to eq. 19, :math:`P_k - P_k A^T (P^-_{k+1})^{-1} A P_k`, but a sum of
   positive semi-definite terms, so it does not lose digits when Q is tiny beside P);
2. updates the coefficients :math:`a, b, d` of the quadratic forms whose conditional means are the
   sufficient statistics (eqs 22-27 for :math:`H^{(0)} = \\sum_{l=0}^{k} x_l x_l^T`,
   :math:`H^{(1)} = \\sum_{l=1}^{k} x_l x_{l-1}^T`, :math:`H^{(2)} = \\sum_{l=1}^{k} x_{l-1}x_{l-1}^T`;
   eqs 31-32 for :math:`T = \\sum_{l=0}^k x_l y_l`; and, for the exact Q update,
   :math:`H^{(3)} = \\sum_{l=1}^{k} x_l x_l^T`, the recursion of :math:`H^{(0)}` started at 0); eq. 30 is used in its symmetric form
   :math:`b \\leftarrow O(b + 2(d + \\tfrac12(e_ie_j^T + e_je_i^T))S)` (the paper's
   :math:`e_je_i^T` gives a non-symmetric matrix whose symmetric part is the same statistic).
   Only the filters that are needed run: :math:`H^{(2)}_k = H^{(0)}_k - x_kx_k^T`, so
   :math:`U^{(2)} = U^{(0)} - (P_k + \\hat x_k\\hat x_k^T)` (eqs 24-25 and 32 give the same
   value); :math:`H^{(3)}` only with ``exact_q``; the filters of :math:`H^{(0)}_{ij}` and
   :math:`H^{(0)}_{ji}` (and of :math:`H^{(3)}`) are the same and run once; the state dimension
   is passed as the length of a tuple, a compile-time constant, so the small loops unroll;
3. runs the Kalman measurement update with :math:`y_{k+1}` (eqs 16-18) and accumulates the
   Gaussian log-likelihood of the innovations;
4. when ``recursive`` is set, every ``update_every`` samples after ``warmup``, replaces
   A, C, Q, R by the M-step (eqs 28-31) evaluated on the current filtered statistics
   (eqs 32-33) - the recursive EM of Elliott & Krishnamurthy. Updates that would give a singular
   :math:`U^{(2)}`, a negative R or an indefinite Q are rejected (parameters kept) and counted;
   an A with an eigenvalue outside the closed unit disk is clipped onto it before Q is formed
   (:func:`_clip_spectrum`; why: :mod:`avbench.estimators.online.arma_em`, "Numerics").

State is carried in the arrays passed in (mutated in place), so a record can be fed in chunks
with results identical to one call; nothing is allocated per sample. The plain NumPy reference of the same recursion is
:mod:`avbench.estimators.online._arma_em_reference` (tests only).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["ek_run", "m_step", "evaluate_stats"]

# indices into the integer state vector ``ic``
I_K, I_UPDATES, I_REJECTED, I_FIRST_REJECT, I_STATUS, I_FAIL_INDEX, I_CLIPPED = range(7)
N_IC = 7
# indices into the float state vector ``sc``
S_SYY, S_LOGLIK = range(2)
N_SC = 2
# status codes
OK, FAIL_SINGULAR_PRED, FAIL_FILTER, FAIL_MSTEP = 0, 1, 2, 3
FAILURE_MESSAGES = {
    FAIL_SINGULAR_PRED: "predicted state covariance A P A' + Q singular or non-finite",
    FAIL_FILTER: "innovation variance C P C' + R not positive or non-finite (filter diverged)",
    FAIL_MSTEP: "M-step singular (U0 or U2 not positive definite) or gave R <= 0 / indefinite Q",
}


@njit(cache=True)
def _inv_small(M, out):
    """Inverse of a 1x1 or 2x2 matrix into ``out``; returns the determinant (0: singular)."""
    m = M.shape[0]
    if m == 1:
        det = M[0, 0]
        if det != 0.0:
            out[0, 0] = 1.0 / det
        return det
    det = M[0, 0] * M[1, 1] - M[0, 1] * M[1, 0]
    if det != 0.0:
        r = 1.0 / det
        out[0, 0] = M[1, 1] * r
        out[1, 1] = M[0, 0] * r
        out[0, 1] = -M[0, 1] * r
        out[1, 0] = -M[1, 0] * r
    return det


@njit(cache=True)
def _clip_spectrum(A):
    """Move the eigenvalues of the 1x1 or 2x2 matrix A that lie outside the closed unit disk onto it.

    Real eigenvalues are clipped to [-1, 1] with the eigenvectors kept (Sylvester's formula,
    :math:`A' = A + \\sum_i (\\lambda_i' - \\lambda_i)\\prod_{j\\ne i}(A - \\lambda_jI)/(\\lambda_i-\\lambda_j)`);
    a complex pair of modulus :math:`r > 1` is scaled by :math:`1/r`. Returns True if A changed.
    """
    if A.shape[0] == 1:
        if abs(A[0, 0]) <= 1.0:
            return False
        A[0, 0] = 1.0 if A[0, 0] > 0 else -1.0
        return True
    tr = A[0, 0] + A[1, 1]
    det = A[0, 0] * A[1, 1] - A[0, 1] * A[1, 0]
    if abs(det) <= 1.0 and abs(tr) <= 1.0 + det:  # Jury: both eigenvalues in the closed unit disk
        return False
    disc = tr * tr - 4.0 * det
    if disc < 0.0:  # complex pair, modulus sqrt(det) > 1
        r = math.sqrt(det)
        for i in range(2):
            for j in range(2):
                A[i, j] /= r
        return True
    big = 0.5 * (tr + math.copysign(math.sqrt(disc), tr))
    l1 = big
    l2 = det / big
    n1 = min(max(l1, -1.0), 1.0)
    n2 = min(max(l2, -1.0), 1.0)
    if l1 == l2:
        for i in range(2):
            A[i, i] += n1 - l1
        return True
    c1 = (n1 - l1) / (l1 - l2)  # coefficient of (A - l2 I)
    c2 = (n2 - l2) / (l2 - l1)  # coefficient of (A - l1 I)
    a00, a01, a10, a11 = A[0, 0], A[0, 1], A[1, 0], A[1, 1]
    A[0, 0] = a00 + c1 * (a00 - l2) + c2 * (a00 - l1)
    A[1, 1] = a11 + c1 * (a11 - l2) + c2 * (a11 - l1)
    A[0, 1] = a01 * (1.0 + c1 + c2)
    A[1, 0] = a10 * (1.0 + c1 + c2)
    return True


def evaluate_stats(a, b, d, aT, bT, x, P, U, E):
    """U^(M)_{ij} = a + b'x + tr(dP) + x'dx and E_i = aT_i + bT_i'x into U, E (see :func:`_evaluate_stats`)."""
    _evaluate_stats((0,) * x.shape[0], a, b, d, aT, bT, x, P, U, E)


@njit(cache=True)
def _evaluate_stats(mt, a, b, d, aT, bT, x, P, U, E):
    """U^(M)_{ij} = a + b'x + tr(dP) + x'dx and E_i = aT_i + bT_i'x (Miao et al. 2015, eqs 32-33).

    :math:`U^{(2)} = U^{(0)} - (P + xx^T)`: :math:`H^{(2)}_k = \\sum_{l=0}^{k-1}x_lx_l^T` is
    :math:`H^{(0)}_k - x_kx_k^T`, so its E-K filter is not run. ``U[3]`` (:math:`H^{(3)}`) is
    meaningful only if the filter tracked it (``exact_q``).
    """
    m = len(mt)  # a tuple of length m: a compile-time constant (loops unrolled)
    for i in range(m):  # U[2] holds P + x x' until the end
        for j in range(m):
            U[2, i, j] = P[i, j] + x[i] * x[j]
    for M in (0, 1, 3):
        for i in range(m):
            for j in range(m):
                if M != 1 and j < i:  # H0, H3 symmetric
                    U[M, i, j] = U[M, j, i]
                    continue
                v = a[M, i, j]
                for p in range(m):
                    v += b[M, i, j, p] * x[p]
                    for q in range(m):
                        v += d[M, i, j, p, q] * U[2, q, p]
                U[M, i, j] = v
    for i in range(m):
        for j in range(m):
            U[2, i, j] = U[0, i, j] - U[2, i, j]
    for i in range(m):
        v = aT[i]
        for p in range(m):
            v += bT[i, p] * x[p]
        E[i] = v


def m_step(a, b, d, aT, bT, x, P, sc, k, A, C, Q, R, exact_q=False):
    """M-step (Miao et al. 2015, eqs 28-31) into A, C, Q, R if valid; returns True if applied.

    :math:`A = U^{(1)}(U^{(2)})^{-1}`, :math:`Q = (U^{(0)} - AU^{(1)T} - U^{(1)}A^T + AU^{(2)}A^T)/k`
    (eq. 29 prints the last sign as minus, a misprint: with it Q would be negative; with
    ``exact_q`` the first term is :math:`\\sum_{l=1}^k x_lx_l^T` (statistic :math:`H^{(3)}`) instead
    of eq. 29's :math:`U^{(0)} = \\sum_{l=0}^k x_lx_l^T`, which makes the step the exact EM update),
    :math:`C = E^T(U^{(0)})^{-1}`, :math:`R = (\\sum y^2 - 2CE + CU^{(0)}C^T)/(k+1)`.
    """
    m = x.shape[0]
    return _m_step((0,) * m, a, b, d, aT, bT, x, P, sc, k, A, C, Q, R, bool(exact_q), np.empty((4, m, m)),
                   np.empty(m), np.empty((4, m, m)), np.empty(m)) > 0


@njit(cache=True)
def _m_step(mt, a, b, d, aT, bT, x, P, sc, k, A, C, Q, R, exact_q, U, E, W, Cn):
    """Allocation-free M-step; U, E, W (4, m, m), Cn (m,) are scratch arrays.

    Returns 0 (rejected, parameters kept), 1 (applied) or 2 (applied with A's spectrum clipped).
    """
    m = len(mt)
    _evaluate_stats(mt, a, b, d, aT, bT, x, P, U, E)  # U0, U2, U3 exactly symmetric
    U2i = W[0]
    U0i = W[1]
    An = W[2]
    Qn = W[3]
    if not (_inv_small(U[2], U2i) > 0.0) or not (_inv_small(U[0], U0i) > 0.0):
        return 0
    for i in range(m):
        for j in range(m):
            v = 0.0
            for p in range(m):
                v += U[1, i, p] * U2i[p, j]
            An[i, j] = v
    # the model has no explosive mode (eq. 63: eigenvalues 1 and 1 - beta dt): clip onto |z| <= 1
    for i in range(m):
        for j in range(m):
            if not math.isfinite(An[i, j]):
                return 0
    clipped = _clip_spectrum(An)
    # Q = (U0 - A U1' - U1 A' + A U2 A') / k   (U3 instead of U0 if exact_q)
    mq = 3 if exact_q else 0
    rk = 1.0 / k
    for i in range(m):
        for j in range(i, m):
            v = U[mq, i, j]
            for p in range(m):
                v -= An[i, p] * U[1, j, p] + U[1, i, p] * An[j, p]
                for q in range(m):
                    v += An[i, p] * U[2, p, q] * An[j, q]
            Qn[i, j] = v * rk
            Qn[j, i] = v * rk
    # C = U0^-1 E ; R = (sum y^2 - 2 C E + C U0 C') / (k + 1)
    ce = 0.0
    cuc = 0.0
    for i in range(m):
        v = 0.0
        for p in range(m):
            v += U0i[i, p] * E[p]
        Cn[i] = v
    for i in range(m):
        ce += Cn[i] * E[i]
        for p in range(m):
            cuc += Cn[i] * U[0, i, p] * Cn[p]
    Rn = (sc[S_SYY] - 2.0 * ce + cuc) / (k + 1)
    # Q is a Schur complement, positive semi-definite up to rounding: a diagonal element that is
    # negative by less than 1e-9 of its first term is rounding; set it (and its row) to 0
    for i in range(m):
        if Qn[i, i] < 0.0 and Qn[i, i] > -1e-9 * abs(U[mq, i, i]) / k:
            for j in range(m):
                Qn[i, j] = 0.0
                Qn[j, i] = 0.0
    ok = (Rn > 0.0) & math.isfinite(Rn)  # & rather than `and`: no branch per element
    for i in range(m):
        ok &= (Qn[i, i] >= 0.0) & math.isfinite(Cn[i])
        for j in range(m):
            ok &= math.isfinite(Qn[i, j])
    if m == 2:
        ok &= Qn[0, 0] * Qn[1, 1] - Qn[0, 1] * Qn[1, 0] >= -1e-10 * Qn[0, 0] * Qn[1, 1]
    if not ok:
        return 0
    for i in range(m):
        C[i] = Cn[i]
        for j in range(m):
            A[i, j] = An[i, j]
            Q[i, j] = Qn[i, j]
    R[0] = Rn
    return 2 if clipped else 1


def ek_run(y, A, C, Q, R, x, P, a, b, d, aT, bT, sc, ic, recursive, warmup, update_every,
           trace_every, trace, exact_q=False):
    """Run the E-K filters (and, if ``recursive``, the recursive EM) over the samples ``y``.

    Parameters
    ----------
    y : ndarray (n,)
        New observations :math:`y_{k+1}, ..., y_{k+n}` (the first sample of a pass is consumed by
        the initial measurement update, outside this kernel).
    A, C, Q, R : ndarray (m, m), (m,), (m, m), (1,)
        Model parameters; updated in place by the recursive M-step.
    x, P : ndarray (m,), (m, m)
        Filtered state mean and covariance at the last sample seen.
    a, b, d : ndarray (4, m, m), (4, m, m, m), (4, m, m, m, m)
        Coefficients of the E-K filters for :math:`H^{(0)}, H^{(1)}, H^{(2)}` and
        :math:`H^{(3)} = \\sum_{l=1}^k x_lx_l^T` (same recursion as :math:`H^{(0)}`, started at 0).
    aT, bT : ndarray (m,), (m, m)
        Coefficients of the E-K filter for :math:`T = \\sum x_l y_l`.
    sc : ndarray (2,) float
        ``[sum y^2, log-likelihood]``.
    ic : ndarray (7,) int64
        ``[k (transitions), n_updates, n_rejected, first_rejected, status, fail_index, n_clipped]``.
    recursive : bool
        Apply the M-step on line (recursive EM); otherwise parameters stay fixed.
    warmup, update_every : int
        No M-step before ``warmup`` transitions; then one every ``update_every``.
    trace_every : int
        Record ``[k, A, C, Q, R]`` in ``trace`` every ``trace_every`` transitions (0: never).
    trace : ndarray (n_rows, 1 + 2m^2 + m + 1)
    exact_q : bool
        Use :math:`H^{(3)}` instead of :math:`H^{(0)}` in the Q update (see :func:`m_step`).

    Returns
    -------
    int
        Number of trace rows written. On failure ``ic[4]`` holds the status code and ``ic[5]``
        the sample index (transitions since the start of the pass) and the kernel returns early.
    """
    return _ek_run((0,) * x.shape[0], y, A, C, Q, R, x, P, a, b, d, aT, bT, sc, ic, bool(recursive),
                   int(warmup), int(update_every), int(trace_every), trace, bool(exact_q))


@njit(cache=True)
def _ek_run(mt, y, A, C, Q, R, x, P, a, b, d, aT, bT, sc, ic, recursive, warmup, update_every,
            trace_every, trace, exact_q):
    """Compiled body of :func:`ek_run`; ``mt`` is a tuple of length m (state dimension as a type)."""
    m = len(mt)
    n = y.shape[0]
    Pp = np.empty((m, m))
    Ppi = np.empty((m, m))
    J = np.empty((m, m))
    O = np.empty((m, m))
    IJA = np.empty((m, m))
    Zi = np.empty((m, m))
    S = np.empty(m)
    ZS = np.empty((m, m))
    tmp = np.empty((m, m))
    xp = np.empty(m)
    PC = np.empty(m)
    wU = np.empty((4, m, m))
    wE = np.empty(m)
    wW = np.empty((4, m, m))
    wC = np.empty(m)
    ntr = 0
    for t in range(n):
        yk = y[t]
        # ---- smoothing density of x_k given x_{k+1}: Pp, J = P A' Pp^-1, O = J', Zi, S
        for i in range(m):
            for j in range(m):
                v = Q[i, j]
                for p in range(m):
                    for q in range(m):
                        v += A[i, p] * P[p, q] * A[j, q]
                Pp[i, j] = v
        det = _inv_small(Pp, Ppi)
        if not (det > 0.0) or not math.isfinite(det):
            ic[I_STATUS] = FAIL_SINGULAR_PRED
            ic[I_FAIL_INDEX] = ic[I_K] + 1
            return ntr
        for i in range(m):  # tmp = P A'
            for j in range(m):
                v = 0.0
                for p in range(m):
                    v += P[i, p] * A[j, p]
                tmp[i, j] = v
        for i in range(m):
            for j in range(m):
                v = 0.0
                for p in range(m):
                    v += tmp[i, p] * Ppi[p, j]
                J[i, j] = v
                O[j, i] = v
        for i in range(m):
            for j in range(m):
                v = 1.0 if i == j else 0.0
                for p in range(m):
                    v -= J[i, p] * A[p, j]
                IJA[i, j] = v
        for i in range(m):
            v = 0.0
            for p in range(m):
                v += IJA[i, p] * x[p]
            S[i] = v
        for i in range(m):
            for j in range(i, m):
                v = 0.0
                for p in range(m):
                    for q in range(m):
                        v += IJA[i, p] * P[p, q] * IJA[j, q] + J[i, p] * Q[p, q] * J[j, q]
                Zi[i, j] = v
                Zi[j, i] = v
        # ---- E-K filters for H0, H1 (and H3 for the exact Q update); H2 = H0 - x_k x_k'.
        # ZS = Zi + S S' so that a += b'S + tr(d ZS); d symmetric in (p, q) and, for H0 and H3,
        # the filters of (i, j) and (j, i) are the same: computed once and copied.
        for p in range(m):
            for q in range(m):
                ZS[p, q] = Zi[p, q] + S[p] * S[q]
        for M in (0, 1, 3):
            if M == 3 and not exact_q:
                break
            for i in range(m):
                for j in range(m):
                    if M != 1 and j < i:
                        continue
                    v = 0.0
                    for p in range(m):
                        w = 0.0
                        for q in range(m):
                            dpq = d[M, i, j, p, q]
                            w += dpq * S[q]
                            v += dpq * ZS[q, p]
                        xp[p] = b[M, i, j, p] + 2.0 * w
                        v += b[M, i, j, p] * S[p]
                    a[M, i, j] += v
                    # b = O (b + 2 d S) [+ e_i S_j for M = 1]
                    for p in range(m):
                        w = 0.0
                        for q in range(m):
                            w += O[p, q] * xp[q]
                        b[M, i, j, p] = w
                    if M == 1:
                        b[M, i, j, i] += S[j]
                    # d = O d O' [+ sym(e_i e_j') for M = 0, 3; + sym(e_i (O e_j)') for M = 1]
                    for p in range(m):
                        for q in range(m):
                            w = 0.0
                            for r in range(m):
                                w += O[p, r] * d[M, i, j, r, q]
                            tmp[p, q] = w
                    for p in range(m):
                        for q in range(p, m):
                            w = 0.0
                            for r in range(m):
                                w += tmp[p, r] * O[q, r]
                            d[M, i, j, p, q] = w
                            d[M, i, j, q, p] = w
                    if M == 1:
                        for q in range(m):
                            d[M, i, j, i, q] += 0.5 * O[q, j]
                            d[M, i, j, q, i] += 0.5 * O[q, j]
                    else:
                        d[M, i, j, i, j] += 0.5
                        d[M, i, j, j, i] += 0.5
                        if i != j:
                            a[M, j, i] = a[M, i, j]
                            for p in range(m):
                                b[M, j, i, p] = b[M, i, j, p]
                                for q in range(m):
                                    d[M, j, i, p, q] = d[M, i, j, p, q]
        # ---- E-K filter for T = sum x_l y_l
        for i in range(m):
            v = 0.0
            for p in range(m):
                v += bT[i, p] * S[p]
            aT[i] += v
            for p in range(m):
                xp[p] = bT[i, p]
            for p in range(m):
                w = 0.0
                for q in range(m):
                    w += O[p, q] * xp[q]
                bT[i, p] = w
            bT[i, i] += yk
        sc[S_SYY] += yk * yk
        # ---- Kalman measurement update (Joseph form)
        e = yk
        for i in range(m):
            v = 0.0
            for p in range(m):
                v += A[i, p] * x[p]
            xp[i] = v
            e -= C[i] * v
        s = R[0]
        for i in range(m):
            v = 0.0
            for p in range(m):
                v += Pp[i, p] * C[p]
            PC[i] = v
            s += C[i] * v
        if not (s > 0.0) or not math.isfinite(s):
            ic[I_STATUS] = FAIL_FILTER
            ic[I_FAIL_INDEX] = ic[I_K] + 1
            return ntr
        for i in range(m):
            x[i] = xp[i] + PC[i] / s * e
        # IKC = I - K C ; P = IKC Pp IKC' + K K' R
        for i in range(m):
            for j in range(m):
                IJA[i, j] = (1.0 if i == j else 0.0) - PC[i] / s * C[j]
        for i in range(m):
            for j in range(m):
                w = 0.0
                for p in range(m):
                    w += IJA[i, p] * Pp[p, j]
                tmp[i, j] = w
        for i in range(m):
            for j in range(i, m):
                w = PC[i] * PC[j] / (s * s) * R[0]
                for p in range(m):
                    w += tmp[i, p] * IJA[j, p]
                P[i, j] = w
                P[j, i] = w
        sc[S_LOGLIK] += -0.5 * (math.log(2.0 * math.pi * s) + e * e / s)
        ic[I_K] += 1
        k = ic[I_K]
        if recursive and k >= warmup and k % update_every == 0:
            res = _m_step(mt, a, b, d, aT, bT, x, P, sc, k, A, C, Q, R, exact_q, wU, wE, wW, wC)
            if res > 0:
                ic[I_UPDATES] += 1
                if res == 2:
                    ic[I_CLIPPED] += 1
            else:
                if ic[I_REJECTED] == 0:
                    ic[I_FIRST_REJECT] = k
                ic[I_REJECTED] += 1
        if trace_every > 0 and k % trace_every == 0 and ntr < trace.shape[0]:
            trace[ntr, 0] = k
            c = 1
            for i in range(m):
                for j in range(m):
                    trace[ntr, c] = A[i, j]
                    c += 1
            for i in range(m):
                trace[ntr, c] = C[i]
                c += 1
            for i in range(m):
                for j in range(m):
                    trace[ntr, c] = Q[i, j]
                    c += 1
            trace[ntr, c] = R[0]
            ntr += 1
    return ntr
