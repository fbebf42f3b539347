"""Compiled passes of the deviation family (:mod:`avbench.estimators.allan.deviations`).

Every kernel reads the phase (angle) record ``x`` (x[0] = 0, x[k] = dt * sum of the first k
mean-removed rate samples, so N = n + 1 phase points) once per cluster size m and returns the sum of
squares that the statistic divides by its normaliser. The plain NumPy versions beside each kernel
(``*_numpy``) are the references the tests compare against; they are never used on a hot path.

Performance notes (``python -m avbench.bench --only Deviations``; serial, no thread pool):

* inner loops run over contiguous *slices* of x (``x[i + 3m : ...]`` as its own array), so there is
  no per-element negative-index check and, with ``fastmath`` reassociation, LLVM sums squares in
  SIMD lanes (results move at rounding level, ~1e-15 relative);
* the Hadamard and total-variance sums are blocked over the start index for few taus (octave,
  decade): a block of start indices visits every m while its slices of x are in cache;
* the modified AV's inner sum is a second difference of box sums of x; on an octave grid the box
  sums of 2m are pairs of those of m, so each octave is two SIMD passes (``mvar_sums_octave``). For
  other grids it is a running sum (a sequential chain) split into four independent lanes over
  quarters of the record, each started from its own directly summed window and fed by blocks of
  third differences computed as SIMD (``mvar_sum``);
* Theo1 is its definition, (N - m) m / 2 terms per m: one SIMD pass per lag d over each block of
  start indices (the pair sums x[i] + x[i+m] formed once).
"""

import numpy as np
from numba import njit

from avbench.estimators.allan._kernels import _ssq_second_diff as _ssq_second

#: start indices per block of the multi-tau kernels (ohvar, totvar)
BLOCK = 4096
#: up to this many taus the blocked kernels are used; beyond (the "all" grid) one pass per tau
MAX_BLOCKED_TAUS = 128
_FM = {"reassoc", "contract"}


@njit(cache=True, fastmath=_FM, inline="always")
def _ssq_third(a, b, c, d):
    """sum_k (a[k] - 3 b[k] + 3 c[k] - d[k])^2 over equal-length slices."""
    acc = 0.0
    for k in range(a.size):
        v = a[k] - 3.0 * b[k] + 3.0 * c[k] - d[k]
        acc += v * v
    return acc


@njit(cache=True, fastmath=_FM, inline="always")
def _ssq_third_and_second(a, b, c, d):
    """(sum_k (a - 3b + 3c - d)^2, sum_k (b - 2c + d)^2) over equal-length slices: one read for both."""
    acc3 = 0.0
    acc2 = 0.0
    for k in range(a.size):
        v = a[k] - 3.0 * b[k] + 3.0 * c[k] - d[k]
        w = b[k] - 2.0 * c[k] + d[k]
        acc3 += v * v
        acc2 += w * w
    return acc3, acc2


@njit(cache=True, fastmath=_FM)
def ohvar_sums(x, ms, block=BLOCK):
    """(Hadamard, Allan) sums for every m of ``ms`` in one blocked pass.

    Hadamard: sum_{i=0}^{N-3m-1} (x[i+3m] - 3x[i+2m] + 3x[i+m] - x[i])^2 (SP1065 eq. 20); Allan:
    sum_{i=0}^{N-2m-1} (x[i+2m] - 2x[i+m] + x[i])^2 (the overlapping AV's, read from the same slices;
    the noise identification of the edf uses it), its last m terms apart.
    """
    N = x.size
    out = np.zeros(ms.size)
    av = np.zeros(ms.size)
    if ms.size == 0:
        return out, av
    kmax = N - 3 * ms.min()
    for b0 in range(0, kmax, block):
        for t in range(ms.size):
            m = ms[t]
            b1 = min(b0 + block, N - 3 * m)
            if b1 > b0:
                h, a = _ssq_third_and_second(x[b0 + 3 * m : b1 + 3 * m], x[b0 + 2 * m : b1 + 2 * m],
                                             x[b0 + m : b1 + m], x[b0:b1])
                out[t] += h
                av[t] += a
    for t in range(ms.size):
        m = ms[t]
        lo = max(N - 3 * m, 0)
        hi = N - 2 * m
        if hi > lo:
            av[t] += _ssq_second(x[lo + 2 * m : hi + 2 * m], x[lo + m : hi + m], x[lo:hi])
    return out, av


def ohvar_sum_numpy(x, m):
    k = x.size - 3 * m
    d = x[3 * m : 3 * m + k] - 3 * x[2 * m : 2 * m + k] + 3 * x[m : m + k] - x[:k]
    return float(np.sum(d * d))


@njit(cache=True, fastmath=_FM, inline="always")
def _window_second_sum(x, j, m):
    """sum_{i=j}^{j+m-1} (x[i+2m] - 2x[i+m] + x[i]): the modified AV's inner sum at j, summed directly."""
    a = x[j + 2 * m : j + 3 * m]
    b = x[j + m : j + 2 * m]
    c = x[j : j + m]
    s = 0.0
    for k in range(m):
        s += a[k] - 2.0 * b[k] + c[k]
    return s


@njit(cache=True, fastmath=_FM, inline="always")
def _third_into(out, a, b, c, d):
    for k in range(a.size):
        out[k] = a[k] - 3.0 * b[k] + 3.0 * c[k] - d[k]


@njit(cache=True)
def _mvar_run(x, m, j0, j1, v):
    """sum_{j=j0}^{j1-1} v_j^2 carrying v_{j+1} = v_j + (third difference at j), v = v_{j0}."""
    acc = 0.0
    for j in range(j0, j1):
        acc += v * v
        if j + 3 * m < x.size:
            v += x[j + 3 * m] - 3.0 * x[j + 2 * m] + 3.0 * x[j + m] - x[j]
    return acc


@njit(cache=True)
def mvar_sum(x, m, block=2048):
    """sum_{j=0}^{N-3m} [sum_{i=j}^{j+m-1} (x[i+2m] - 2x[i+m] + x[i])]^2 (SP1065 eq. 14).

    The inner sum v_j is carried along j: moving the window by one adds the third difference
    x[j+3m] - 3x[j+2m] + 3x[j+m] - x[j] (the loop-unrolled form of SP1065 / adev_lib). Four lanes
    carry it over the four quarters of j at once (each lane's first v summed directly, so no lane
    depends on another), when the record holds at least 8m + 64 terms; else one lane.
    """
    N = x.size
    K = N - 3 * m + 1
    if K < 8 * m + 64:
        return _mvar_run(x, m, 0, K, _window_second_sum(x, 0, m))
    C = K // 4
    v0 = _window_second_sum(x, 0, m)
    v1 = _window_second_sum(x, C, m)
    v2 = _window_second_sum(x, 2 * C, m)
    v3 = _window_second_sum(x, 3 * C, m)
    a0 = 0.0
    a1 = 0.0
    a2 = 0.0
    a3 = 0.0
    buf = np.empty((4, block))
    T = C - 1  # lock-step steps: every update of every lane reads inside the record
    for t0 in range(0, T, block):
        nb = min(block, T - t0)
        for lane in range(4):
            j = lane * C + t0
            _third_into(buf[lane, :nb], x[j + 3 * m : j + 3 * m + nb], x[j + 2 * m : j + 2 * m + nb],
                        x[j + m : j + m + nb], x[j : j + nb])
        b0 = buf[0]
        b1 = buf[1]
        b2 = buf[2]
        b3 = buf[3]
        for k in range(nb):
            a0 += v0 * v0
            v0 += b0[k]
            a1 += v1 * v1
            v1 += b1[k]
            a2 += v2 * v2
            v2 += b2[k]
            a3 += v3 * v3
            v3 += b3[k]
    # lanes 0-2 end with one term left (their next v is the next lane's first); lane 3 runs to K
    a3 += _mvar_run(x, m, 3 * C + T, K, v3)
    return ((a0 + v0 * v0) + (a1 + v1 * v1)) + ((a2 + v2 * v2) + a3)


@njit(cache=True, fastmath=_FM)
def _pair_sums(out, y, cur, L):
    """out[k] = y[k] + y[k + cur], k < L: the box sums of 2 cur from those of cur."""
    a = y[:L]
    b = y[cur : cur + L]
    o = out[:L]
    for k in range(L):
        o[k] = a[k] + b[k]


@njit(cache=True, fastmath=_FM)
def _box_ssq_and_pairs(out, y, m, K):
    """sum_{k<K} (y[k+2m] - 2y[k+m] + y[k])^2, writing out[k] = y[k] + y[k+m] on the way (one pass)."""
    a = y[:K]
    b = y[m : m + K]
    c = y[2 * m : 2 * m + K]
    o = out[:K]
    acc = 0.0
    for k in range(K):
        o[k] = a[k] + b[k]
        v = c[k] - 2.0 * b[k] + a[k]
        acc += v * v
    return acc


@njit(cache=True)
def _box_level(src, dst, m, K, L, want, more):
    """One octave of ``mvar_sums_octave``: the sum of squares at m (if wanted) and the box sums of 2m."""
    acc = 0.0
    done = 0
    if want and more:
        acc = _box_ssq_and_pairs(dst, src, m, K)
        done = K
    elif want:
        acc = _ssq_second(src[2 * m : 2 * m + K], src[m : m + K], src[:K])
    if more and L > done:
        _pair_sums(dst[done:], src[done:], m, L - done)
    return acc


@njit(cache=True)
def mvar_sums_octave(x, ms):
    """``mvar_sum`` for increasing powers of two ``ms``, by the box sums of x (no running sum).

    The inner sum is a second difference of box sums, sum_{i=j}^{j+m-1} (x[i+2m] - 2x[i+m] + x[i])
    = y[j+2m] - 2y[j+m] + y[j] with y[i] = x[i] + ... + x[i+m-1]; the box sums of 2m are pairs of
    those of m, y2[i] = y[i] + y[i+m], read from the same two streams. So each octave is one SIMD
    pass (squares of the second differences at m, box sums of 2m), and every value is a sum of at
    most m phases (no subtraction of large prefix sums, no long running sum).
    """
    N = x.size
    out = np.zeros(ms.size)
    bufs = (x.copy(), np.empty(N))
    which = 0  # bufs[which] holds the N - cur + 1 box sums of length cur
    cur = 1
    t = 0
    top = ms[ms.size - 1]
    while cur <= top:
        want = ms[t] == cur
        more = cur < top
        K = N - 3 * cur + 1
        L = N - 2 * cur + 1  # box sums of 2 cur
        if which == 0:
            acc = _box_level(bufs[0], bufs[1], cur, K, L, want, more)
        else:
            acc = _box_level(bufs[1], bufs[0], cur, K, L, want, more)
        if want:
            out[t] = acc
            t += 1
        which = 1 - which
        cur *= 2
    return out


def _powers_of_two_increasing(ms) -> bool:
    ms = np.asarray(ms)
    return bool(ms.size and np.all(ms >= 1) and np.all((ms & (ms - 1)) == 0) and np.all(np.diff(ms) > 0))


def mvar_sums(x, ms):
    """``mvar_sum`` for every m of ``ms``: by octave box sums for an octave grid, else one pass per m."""
    ms = np.ascontiguousarray(ms, dtype=np.int64)
    if _powers_of_two_increasing(ms):
        return mvar_sums_octave(x, ms)
    return np.array([mvar_sum(x, int(m)) for m in ms])


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


@njit(cache=True, fastmath=_FM)
def totvar_sums(x, ms, block=BLOCK):
    """(total, Allan) sums for every m: sum_{i=1}^{N-2} (x*[i-m] - 2x[i] + x*[i+m])^2 on the doubly
    reflected x* (SP1065 eq. 25), and its interior part (no reflection: m <= i <= N-1-m), which is
    exactly the overlapping AV's sum of the N - 2m second differences.

    The interior blocked over i; the 2(m - 1) reflected ends apart.
    """
    N = x.size
    out = np.zeros(ms.size)
    av = np.zeros(ms.size)
    for t in range(ms.size):
        m = ms[t]
        lo = min(m, N - 1)
        hi = max(lo, N - m)  # the interior is m <= i <= N-1-m: N - 2m terms
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
            hi = min(b0 + block, max(min(m, N - 1), N - m))
            if hi > lo:
                av[t] += _ssq_second(x[lo + m : hi + m], x[lo:hi], x[lo - m : hi - m])
    return out + av, av


def totvar_sum_numpy(x, m):
    N = x.size
    ext = np.concatenate((2 * x[0] - x[N - 2 : 0 : -1], x, 2 * x[-1] - x[-2:0:-1]))  # x*[-(N-2)..2N-3]
    off = N - 2
    i = np.arange(1, N - 1)
    d = ext[off + i - m] - 2 * ext[off + i] + ext[off + i + m]
    return float(np.sum(d * d))


@njit(cache=True, fastmath=_FM, inline="always")
def _ssq_less_two(a, b, e):
    """sum_k (a[k] - b[k] - e[k])^2 over equal-length slices."""
    acc = 0.0
    for k in range(a.size):
        v = a[k] - b[k] - e[k]
        acc += v * v
    return acc


#: start indices per block of ``theo1_sum``: the block and its m/2 shifted copies stay in cache
THEO1_BLOCK = 1024


@njit(cache=True, fastmath=_FM)
def theo1_sum(x, m, block=THEO1_BLOCK):
    """sum_{i=0}^{N-m-1} sum_{d=0}^{m/2-1} [(x[i] - x[i-d+m/2]) + (x[i+m] - x[i+d+m/2])]^2 / (m/2 - d).

    SP1065 eq. 30, m even: its definition, (N - m) m / 2 terms. The pair sums a[i] = x[i] + x[i+m]
    are formed once; then for each block of i every lag d is one SIMD pass of (a - x[i+m/2-d] -
    x[i+m/2+d])^2 over the block, whose slices stay in cache from one d to the next (measured 1.5-1.9x
    faster than one pass over the record per d, at n = 1e4 and 1e5).
    """
    h = m // 2
    K = x.size - m
    a = x[:K] + x[m : m + K]
    acc = 0.0
    for i0 in range(0, K, block):
        i1 = min(i0 + block, K)
        part = 0.0
        for d in range(h):
            part += _ssq_less_two(a[i0:i1], x[i0 + h - d : i1 + h - d], x[i0 + h + d : i1 + h + d]) / (h - d)
        acc += part
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


@njit(cache=True)
def total_window_sums(v, m, phase):
    """sum over the windows n of (1/6m) sum_{j<6m} (A_j - 2A_{j+m} + A_{j+2m})^2 (MTOTVAR, HTOTVAR).

    Each window is 3m points of ``v`` (phase for MTOTVAR, ``phase=True``; rate for HTOTVAR); a linear
    trend is removed with the half-average slope (``exact_variances._half_average_slope``: halves
    of floor(3m/2) points, the middle one skipped when 3m is odd), the result is extended by
    uninverted even reflection to 9m points, and A_j is the mean of m points from j (SP1065 eqs. 27,
    29). The three running window sums are updated by one point each per j (Stable32's MTC.c, as
    allantools). For the rate the trend is taken about the window's middle (a constant shift, which
    the second differences cancel). Cost 9m + 6m per window: O(N m) per m.
    """
    W = 3 * m
    nwin = v.size - W + 1
    h1 = W // 2
    h2 = (W + 1) // 2
    dist = 0.5 * W if W % 2 == 0 else 0.5 * (W - 1) + 1.0
    centre = 0.0 if phase else float(h1)
    star = np.empty(9 * m)
    x0 = np.empty(W)
    total = 0.0
    for n in range(nwin):
        s1 = 0.0
        for i in range(h1):
            s1 += v[n + i]
        s2 = 0.0
        for i in range(h2, W):
            s2 += v[n + i]
        slope = (s2 / (W - h2) - s1 / h1) / dist
        for i in range(W):
            x0[i] = v[n + i] - slope * (i - centre)
        for i in range(W):
            star[W - 1 - i] = x0[i]
            star[W + i] = x0[i]
            star[3 * W - 1 - i] = x0[i]
        a1 = 0.0
        a2 = 0.0
        a3 = 0.0
        for i in range(m):
            a1 += star[i]
            a2 += star[m + i]
            a3 += star[2 * m + i]
        acc = 0.0
        for j in range(6 * m):
            if j > 0:
                a1 += star[j + m - 1] - star[j - 1]
                a2 += star[j + 2 * m - 1] - star[m + j - 1]
                a3 += star[j + 3 * m - 1] - star[2 * m + j - 1]
            d = (a1 - 2.0 * a2 + a3) / m
            acc += d * d
        total += acc / (6.0 * m)
    return total


def total_window_sums_numpy(v, m, phase):
    """The reference: each window's 6m filters as a matrix (``exact_variances.total_window_filters``)."""
    from avbench.noise_models.exact_variances import total_window_filters

    W = 3 * m
    C = total_window_filters("mtotvar", m)  # on the window's own points (phase or rate alike)
    win = np.lib.stride_tricks.sliding_window_view(np.asarray(v, dtype=float), W)
    q = win @ C.T
    return float(np.sum(q * q) / (6.0 * m))
