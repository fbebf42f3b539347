"""Compiled passes of the deviation family (:mod:`avbench.estimators.allan.deviations`).

Every kernel reads the phase (angle) record ``x`` (x[0] = 0, x[k] = dt * sum of the first k
mean-removed rate samples, so N = n + 1 phase points) once per cluster size m and returns the sum of
squares that the statistic divides by its normaliser. The plain NumPy versions beside each kernel
(``*_numpy``) are the references the tests compare against; they are never used on a hot path.
"""

import numpy as np
from numba import njit

#: start indices per block of the multi-tau total-variance kernel: the block of x and its copies at
#: -m and +m for every m stay in cache while all m are visited. (Measured at 1e6 samples: 60 ms
#: against 75-80 ms per-m for totvar; the same blocking made ohvar and mvar slower, so they run per m.)
BLOCK = 4096


@njit(cache=True, fastmath={"reassoc", "contract"})
def ohvar_sum(x, m):
    """sum_{i=0}^{N-3m-1} (x[i+3m] - 3x[i+2m] + 3x[i+m] - x[i])^2 (SP1065 eq. 20)."""
    acc = 0.0
    for i in range(x.size - 3 * m):
        d = x[i + 3 * m] - 3.0 * x[i + 2 * m] + 3.0 * x[i + m] - x[i]
        acc += d * d
    return acc


def ohvar_sum_numpy(x, m):
    k = x.size - 3 * m
    d = x[3 * m : 3 * m + k] - 3 * x[2 * m : 2 * m + k] + 3 * x[m : m + k] - x[:k]
    return float(np.sum(d * d))


@njit(cache=True)
def mvar_sum(x, m):
    """sum_{j=0}^{N-3m} [sum_{i=j}^{j+m-1} (x[i+2m] - 2x[i+m] + x[i])]^2 (SP1065 eq. 14).

    The inner sum is carried along j: moving the window by one adds the third difference
    x[j+3m] - 3x[j+2m] + 3x[j+m] - x[j] (the loop-unrolled form of SP1065 / adev_lib).
    """
    v = 0.0
    for i in range(m):
        v += x[i + 2 * m] - 2.0 * x[i + m] + x[i]
    acc = v * v
    for j in range(x.size - 3 * m):
        v += x[j + 3 * m] - 3.0 * x[j + 2 * m] + 3.0 * x[j + m] - x[j]
        acc += v * v
    return acc


def mvar_sum_numpy(x, m):
    N = x.size
    c = np.concatenate(([0.0], np.cumsum(x)))  # c[k] = sum x[:k]
    j = np.arange(N - 3 * m + 1)
    inner = (c[j + 3 * m] - c[j + 2 * m]) - 2 * (c[j + 2 * m] - c[j + m]) + (c[j + m] - c[j])
    return float(np.sum(inner * inner))


@njit(cache=True, inline="always")
def _reflected(x, j):
    N = x.size
    if j < 0:
        return 2.0 * x[0] - x[-j]
    if j > N - 1:
        return 2.0 * x[N - 1] - x[2 * (N - 1) - j]
    return x[j]


@njit(cache=True, fastmath={"reassoc", "contract"})
def totvar_sums(x, ms, block=BLOCK):
    """``totvar_sum`` for every m of ``ms``: the interior (no reflection) blocked, the ends apart."""
    N = x.size
    out = np.zeros(ms.size)
    for t in range(ms.size):
        m = ms[t]
        lo = min(m, N - 1)
        hi = max(lo, N - 1 - m)
        acc = 0.0
        for i in range(1, lo):
            d = _reflected(x, i - m) - 2.0 * x[i] + _reflected(x, i + m)
            acc += d * d
        for i in range(max(hi, 1), N - 1):
            d = _reflected(x, i - m) - 2.0 * x[i] + _reflected(x, i + m)
            acc += d * d
        out[t] = acc
    for b0 in range(0, N, block):
        for t in range(ms.size):
            m = ms[t]
            lo = max(b0, min(m, N - 1))
            hi = min(b0 + block, max(min(m, N - 1), N - 1 - m))
            acc = 0.0
            for i in range(lo, hi):
                d = x[i - m] - 2.0 * x[i] + x[i + m]
                acc += d * d
            out[t] += acc
    return out


def totvar_sum_numpy(x, m):
    N = x.size
    ext = np.concatenate((2 * x[0] - x[N - 2 : 0 : -1], x, 2 * x[-1] - x[-2:0:-1]))  # x*[-(N-2)..2N-3]
    off = N - 2
    i = np.arange(1, N - 1)
    d = ext[off + i - m] - 2 * ext[off + i] + ext[off + i + m]
    return float(np.sum(d * d))


@njit(cache=True)
def theo1_sum(x, m):
    """sum_{i=0}^{N-m-1} sum_{d=0}^{m/2-1} [(x[i] - x[i-d+m/2]) + (x[i+m] - x[i+d+m/2])]^2 / (m/2 - d).

    SP1065 eq. 30, m even. Cost (N - m) m / 2 terms: this is the definition evaluated in one compiled
    pass per (i); no O(N log N) reformulation is used.
    """
    h = m // 2
    acc = 0.0
    for d in range(h):
        w = 1.0 / (h - d)
        s = 0.0
        for i in range(x.size - m):
            v = x[i] - x[i - d + h] + x[i + m] - x[i + d + h]
            s += v * v
        acc += w * s
    return acc


def theo1_sum_numpy(x, m):
    h = m // 2
    K = x.size - m
    i = np.arange(K)
    acc = 0.0
    for d in range(h):
        v = x[i] - x[i - d + h] + x[i + m] - x[i + d + h]
        acc += np.sum(v * v) / (h - d)
    return float(acc)
