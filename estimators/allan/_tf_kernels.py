"""Compiled passes of the time-and-frequency statistics beside the variances: PDEV, TIE rms and MTIE
(:mod:`avbench.estimators.allan.deviations_tf`), each with the plain NumPy form the tests hold it to
(``*_numpy``; never used on a hot path).

* PDEV's sum (``pvar_sums``): with u_j = x_j - x_{j+m} and c_k = (m-1)/2 - k, the weighted window
  W_i = sum_{k<m} c_k u_{i+k} is carried along i by W_{i+1} = W_i - ((m-1)/2) u_i - ((m+1)/2) u_{i+m}
  + B_{i+1}, B_i = sum_{k<m} u_{i+k} (itself carried by B_{i+1} = B_i - u_i + u_{i+m}): O(1) per term,
  O(N) per m. The chain is restarted from its definition every max(4096, 4m) steps (amortised cost <= 1/4
  of a step), so that its rounding does not accumulate over the record.
* TIE rms (``tie_sums``): sum (x_{i+m} - x_i)^2 per m, one SIMD pass over two slices.
* MTIE (``mtie_max``): the windows of m + 1 phases; their max and min from a table of maxima and minima of
  windows of 2^j points (built level by level, each level from the previous: 2^(j+1)-windows are pairs
  of 2^j-windows), a window of L points being the union of the two 2^j-windows at its ends, j = floor(log2 L)
  (a sparse table): O(N) per level and per m, against O(N m) for the windows one by one. Max and min are
  exact, so the result is bit-equal to the direct definition.
"""

import numpy as np
from numba import njit

_FM = {"reassoc", "contract"}


@njit(cache=True)
def _pvar_direct(u, i, m, c0):
    """(W_i, B_i) from their definitions."""
    w = 0.0
    b = 0.0
    for k in range(m):
        v = u[i + k]
        w += (c0 - k) * v
        b += v
    return w, b


@njit(cache=True)
def pvar_sums(x, ms):
    """sum_{i=0}^{N-2m-1} [sum_{k=0}^{m-1} ((m-1)/2 - k)(x[i+k] - x[i+k+m])]^2 for each m of ``ms`` (PDEV;
    allantools' M = N - 2m terms)."""
    N = x.size
    out = np.zeros(ms.size)
    for t in range(ms.size):
        m = ms[t]
        M = N - 2 * m
        if M < 1:
            continue
        u = x[: N - m] - x[m:]
        c0 = 0.5 * (m - 1)
        c1 = 0.5 * (m + 1)
        period = max(4096, 4 * m)
        acc = 0.0
        w = 0.0
        b = 0.0
        for i in range(M):
            if i % period == 0:
                w, b = _pvar_direct(u, i, m, c0)
            acc += w * w
            if i + 1 < M:
                bn = b - u[i] + u[i + m]
                w = w - c0 * u[i] - c1 * u[i + m] + bn
                b = bn
        out[t] = acc
    return out


def pvar_sum_numpy(x, m):
    u = x[: x.size - m] - x[m:]
    c = 0.5 * (m - 1) - np.arange(m)
    w = np.convolve(u, c[::-1], "valid")[: x.size - 2 * m]
    return float(np.sum(w * w))


@njit(cache=True, fastmath=_FM)
def _ssq_diff(a, b):
    acc = 0.0
    for k in range(a.size):
        v = a[k] - b[k]
        acc += v * v
    return acc


@njit(cache=True)
def tie_sums(x, ms):
    """sum_{i=0}^{N-m-1} (x[i+m] - x[i])^2 for each m of ``ms`` (TIE rms)."""
    N = x.size
    out = np.zeros(ms.size)
    for t in range(ms.size):
        m = ms[t]
        if m < N:
            out[t] = _ssq_diff(x[m:], x[: N - m])
    return out


def tie_sum_numpy(x, m):
    d = x[m:] - x[:-m]
    return float(np.sum(d * d))


@njit(cache=True)
def mtie_max(x, ms):
    """max_i (max - min of x[i .. i+m]) for each m of ``ms`` (windows of m + 1 points), visited in increasing m."""
    N = x.size
    out = np.zeros(ms.size)
    order = np.argsort(ms)
    hi = x.copy()  # level j: max / min of the 2^j-windows starting at each index
    lo = x.copy()
    width = 1
    for t in order:
        L = ms[t] + 1
        if L > N:
            out[t] = np.nan
            continue
        while 2 * width <= L:  # next level: pairs of windows
            n_new = N - 2 * width + 1
            for i in range(n_new):
                a = hi[i + width]
                if a > hi[i]:
                    hi[i] = a
                b = lo[i + width]
                if b < lo[i]:
                    lo[i] = b
            width *= 2
        best = 0.0
        off = L - width
        for i in range(N - L + 1):
            a = hi[i]
            b = hi[i + off]
            mx = a if a > b else b
            a = lo[i]
            b = lo[i + off]
            mn = a if a < b else b
            if mx - mn > best:
                best = mx - mn
        out[t] = best
    return out


def mtie_numpy(x, m):
    w = np.lib.stride_tricks.sliding_window_view(x, m + 1)
    return float(np.max(w.max(axis=1) - w.min(axis=1)))


# -- noise identification (``noise_id``) --------------------------------------------------------------------------


@njit(cache=True)
def lag1_acf(z):
    """r_1 = sum (z_i - zbar)(z_{i+1} - zbar) / sum (z_i - zbar)^2 (two passes, no temporaries)."""
    n = z.size
    mu = 0.0
    for i in range(n):
        mu += z[i]
    mu /= n
    num = 0.0
    den = 0.0
    prev = z[0] - mu
    den += prev * prev
    for i in range(1, n):
        c = z[i] - mu
        num += prev * c
        den += c * c
        prev = c
    return num / den


def lag1_acf_numpy(z):
    c = z - z.mean()
    return float(np.sum(c[:-1] * c[1:]) / np.sum(c * c))


@njit(cache=True)
def detrend(z, deg):
    """z minus its least-squares polynomial of degree ``deg`` (1 or 2) in the index, from the normal equations
    in the centred, scaled index u = (i - (n-1)/2) / (n/2) (well conditioned: |u| <= 1): one pass for the
    moments sum u^k (k <= 2 deg) and sum u^k z, one for the residual."""
    n = z.size
    k = deg + 1
    c0 = 0.5 * (n - 1)
    s = 0.5 * n
    S = np.zeros(2 * k - 1)
    b = np.zeros(k)
    for i in range(n):
        u = (i - c0) / s
        u2 = u * u
        zi = z[i]
        S[0] += 1.0
        S[1] += u
        S[2] += u2
        b[0] += zi
        b[1] += u * zi
        if k == 3:
            S[3] += u2 * u
            S[4] += u2 * u2
            b[2] += u2 * zi
    A = np.empty((k, k))
    for a in range(k):
        for c in range(k):
            A[a, c] = S[a + c]
    coef = np.linalg.solve(A, b)
    out = np.empty(n)
    for i in range(n):
        u = (i - c0) / s
        v = coef[0] + coef[1] * u
        if k == 3:
            v += coef[2] * u * u
        out[i] = z[i] - v
    return out


def detrend_numpy(z, deg):
    t = np.arange(z.size)
    return z - np.polyval(np.polyfit(t, z, deg), t)


# -- gap-resistant ADEV (``gradev``) --------------------------------------------------------------------------------


@njit(cache=True)
def gradev_sums(x, ms, bad, by_count):
    """(sum of the kept (x[i+2m] - 2x[i+m] + x[i])^2, their number) for each m. ``by_count``: a term is kept when
    ``bad`` (missing samples before each phase point) is the same at i and i + 2m (rate data); else when it is
    finite (phase data, NaN at the missing points). No fastmath: the NaN test must stay."""
    N = x.size
    sums = np.zeros(ms.size)
    cnt = np.zeros(ms.size, dtype=np.int64)
    for t in range(ms.size):
        m = ms[t]
        acc = 0.0
        c = 0
        for i in range(N - 2 * m):
            v = x[i + 2 * m] - 2.0 * x[i + m] + x[i]
            if by_count:
                ok = bad[i + 2 * m] == bad[i]
            else:
                ok = v == v
            if ok:
                acc += v * v
                c += 1
        sums[t] = acc
        cnt[t] = c
    return sums, cnt


def gradev_sum_numpy(x, m, bad=None):
    d2 = x[2 * m :] - 2.0 * x[m:-m] + x[: -2 * m]
    ok = np.isfinite(d2) if bad is None else bad[2 * m :] == bad[: -2 * m]
    return float(np.sum(d2[ok] ** 2)), int(np.count_nonzero(ok))
