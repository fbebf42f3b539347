"""Plain-NumPy per-sample reference of the online filters, for the tests only.

The same equations as the compiled kernels of :mod:`avbench.estimators.online._kernels`, written the
obvious way with matrices (Miao et al. 2014, eqs 3.8-3.19; Miao et al. 2015, eqs 52-57), with the
measurements taken from :func:`avbench.estimators.allan.variance.recursive_avar` rather than recomputed in the loop.
Slow by design: use on short records. Scaled units as in the kernels (state ``s = c / c_ref``,
measurement ``z_j * zinv_j``, model ``h_j(s) = A[j] @ s**2``).
"""

from __future__ import annotations

import numpy as np

__all__ = ["measurement_schedule", "shakf_reference", "nekf_reference"]


def measurement_schedule(rate, m):
    """For each sample, the list of ``(j, k, z_j)`` measurements that complete at it.

    Cluster ``k`` (1-based) of size ``m_j`` completes at sample ``k*m_j - 1``; its recursive AV
    (Miao et al. 2014, eq 3.4) exists for ``k >= 2``.
    """
    from avbench.estimators.allan.variance import recursive_avar

    sched = [[] for _ in range(len(rate))]
    for j, mj in enumerate(m):
        z = np.asarray(recursive_avar(rate, m=int(mj)), dtype=float)
        for i, zk in enumerate(z):
            k = i + 2
            sched[k * int(mj) - 1].append((j, k, float(zk)))
    return sched


def _check(s, P):
    if not np.all(np.isfinite(s)):
        return 1
    if not np.all(np.diag(P) > 0):
        return 4
    return 0


def shakf_reference(rate, zinv, A, m, s0, P0, Q0, R0, b, adapt=15):
    """SHAKF over ``rate``; returns ``(trajectory |s| per sample, failure code, failure index)``."""
    s = np.array(s0, float)
    P, Q = np.array(P0, float), np.array(Q0, float)
    q = np.zeros_like(s)
    r = np.zeros(len(m))
    R = np.array(R0, float)
    traj = np.full((len(rate), len(s)), np.nan)
    for i, meas in enumerate(measurement_schedule(rate, m)):
        last = s.copy()
        if i >= 1:
            s = s + q  # eq 3.8
            P = P + Q  # eq 3.9
        for j, k, zraw in meas:
            z = zraw * zinv[j]
            gam = (1 - b) / (1 - b ** (k + 1)) if b < 1 else 1 / (k + 1)  # eq 3.15
            h = A[j] @ s**2
            H = 2 * A[j] * s
            S = H @ P @ H + R[j]
            if not (S > 0 and np.isfinite(S)):
                return traj, 2, i, last
            K = P @ H / S  # eq 3.10
            eps = z - h - r[j]  # eq 3.11
            Pprior = P
            s = s + K * eps  # eq 3.12
            P = (np.eye(len(s)) - np.outer(K, H)) @ P  # eq 3.13
            P = (P + P.T) / 2
            D = H / (H @ Pprior @ H + R[j])  # eq 3.14 (with R_{k-1})
            if adapt & 1:
                q = q + gam * Q @ D * eps  # eq 3.16
            if adapt & 2:
                Q = Q + gam * np.outer(Q @ D, Q @ D) * (eps**2 - H @ Pprior @ H - R[j])  # eq 3.17
            if adapt & 4:
                r[j] = (1 - gam) * r[j] + gam * (z - A[j] @ s**2)  # eq 3.18
            if adapt & 8:
                HK = H @ K
                R[j] = (1 - gam) * R[j] + gam * ((1 - HK) ** 2 * eps**2 + H @ P @ H)  # eq 3.19
            code = _check(s, P)
            if code == 0 and not R[j] > 0:
                code = 3
            if code == 0 and np.any(np.diag(Q) < 0):
                code = 5
            if code:
                return traj, code, i, last
        traj[i] = np.abs(s)
    return traj, 0, -1, s


def _nn(xa, nq, p):
    s = xa[:nq]
    eta = xa[nq : nq + p * nq].reshape(p, nq)
    lam = xa[nq + p * nq :].reshape(nq, p)
    t = np.tanh(eta @ s)
    nn = lam @ t
    n = len(xa)
    G = np.zeros((nq, n))
    g = lam * (1 - t**2)  # (nq, p)
    G[:, :nq] = g @ eta
    for j in range(nq):
        G[j, nq : nq + p * nq] = np.outer(g[j], s).ravel()
        G[j, nq + p * nq + j * p : nq + p * nq + (j + 1) * p] = t
    return nn, G


def nekf_reference(rate, zinv, A, m, xa0, P0, Qbar, Rbar, nq, p):
    """NEKF over ``rate``; returns ``(trajectory |s| per sample, failure code, failure index)``."""
    xa = np.array(xa0, float)
    P = np.array(P0, float)
    n = len(xa)
    traj = np.full((len(rate), nq), np.nan)
    for i, meas in enumerate(measurement_schedule(rate, m)):
        last = xa[:nq].copy()
        if i >= 1:
            nn, G = _nn(xa, nq, p)  # eq 51 and its Jacobian
            F = np.eye(n)
            F[:nq] += G  # eq 53: [F 0; 0 I] + [dNN/dx; 0], f = identity
            P = F @ P @ F.T + Qbar
            xa = xa.copy()
            xa[:nq] += nn  # eq 55
        for j, k, zraw in meas:
            z = zraw * zinv[j]
            H = np.zeros(n)
            H[:nq] = 2 * A[j] * xa[:nq]  # eq 54
            S = H @ P @ H + Rbar[j]
            if not (S > 0 and np.isfinite(S)):
                return traj, 2, i, last
            K = P @ H / S  # eq 56
            xa = xa + K * (z - A[j] @ xa[:nq] ** 2)  # eq 57
            P = P - np.outer(K, H @ P)  # eq 57, (I - K H) P
            P = (P + P.T) / 2
            code = _check(xa, P)
            if code:
                return traj, code, i, last
        traj[i] = np.abs(xa[:nq])
    return traj, 0, -1, xa[:nq]
