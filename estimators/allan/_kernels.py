"""Compiled inner loops of the Allan-variance engine (one pass over the cumulative sum per tau).

``S`` is the cumulative sum of the (mean-removed) rate with S[0] = 0. The plain NumPy versions in
:mod:`avbench.estimators.allan.variance` (``_oavar_sums_numpy``, ``_avar_sums_numpy``) are the reference the tests
compare against.

Performance notes (measured by ``python -m bench``). The overlapping sums read S at k, k+m and
k+2m. Two things make them fast:

* the inner loop runs over contiguous *slices* of S (no per-element negative-index wraparound
  check), with ``fastmath`` so LLVM may reassociate the sum of squares into SIMD lanes (the result
  changes only at rounding level, ~1e-14 relative);
* for a few taus (octave, decade grids) the loop is blocked over k: each block of ``block`` start
  indices visits every m while the block of S[k], and S[k+m] = S[k'+2m'] for octave grids, are
  still in cache, which cuts the memory traffic from one pass over S per tau to about one pass per
  tau larger than the block. For the "all" grid (thousands of taus) the plain per-tau loop is used.
"""

import numpy as np
from numba import get_num_threads, njit, prange

#: k-block length (samples) of the blocked overlapping kernel: 3 slices of 32 KB each
BLOCK = 4096
#: up to this many taus, the blocked kernel is used
MAX_BLOCKED_TAUS = 128


@njit(cache=True, fastmath={"reassoc", "contract"})
def finite_sum(x):
    """Sum of ``x`` in one read-only pass (8 interleaved partial sums, SIMD).

    A NaN or an infinity anywhere makes the sum non-finite, so the caller tests finiteness on the
    result instead of building a boolean temporary (and only scans for the first bad sample when
    the sum is not finite). No ``nnan``/``ninf`` fast-math flags: NaN and inf propagate.
    """
    n = x.size
    acc = np.zeros(8)
    k = 0
    while k + 8 <= n:
        for j in range(8):
            acc[j] += x[k + j]
        k += 8
    tail = 0.0
    while k < n:
        tail += x[k]
        k += 1
    return ((acc[0] + acc[4]) + (acc[1] + acc[5])) + ((acc[2] + acc[6]) + (acc[3] + acc[7])) + tail


@njit(cache=True, error_model="numpy")
def noise_codes_from_slope(log_tau, log_av):
    """rint(slope) + 2 clipped to 0..3 (white PM, white FM, flicker FM, random-walk FM) for the local slope
    np.gradient(log_av, log_tau), computed as NumPy computes it (second order inside, first order at the
    ends; its equal-spacing form when every spacing equals the first); a non-finite slope counts as -1
    (white FM). At least two points."""
    g = log_av.size
    dx0 = log_tau[1] - log_tau[0]
    uniform = True
    for i in range(g - 1):
        if not (log_tau[i + 1] - log_tau[i] == dx0):
            uniform = False
    slope = np.empty(g)
    if uniform:
        for i in range(1, g - 1):
            slope[i] = (log_av[i + 1] - log_av[i - 1]) / (2.0 * dx0)
        slope[0] = (log_av[1] - log_av[0]) / dx0
        slope[g - 1] = (log_av[g - 1] - log_av[g - 2]) / dx0
    else:
        for i in range(1, g - 1):
            dx1 = log_tau[i] - log_tau[i - 1]
            dx2 = log_tau[i + 1] - log_tau[i]
            a = -(dx2) / (dx1 * (dx1 + dx2))
            b = (dx2 - dx1) / (dx1 * dx2)
            c = dx1 / (dx2 * (dx1 + dx2))
            slope[i] = a * log_av[i - 1] + b * log_av[i] + c * log_av[i + 1]
        slope[0] = (log_av[1] - log_av[0]) / dx0
        slope[g - 1] = (log_av[g - 1] - log_av[g - 2]) / (log_tau[g - 1] - log_tau[g - 2])
    out = np.empty(g, dtype=np.int64)
    for i in range(g):
        s = slope[i] if np.isfinite(slope[i]) else -1.0
        out[i] = int(min(max(np.rint(s), -2.0), 1.0)) + 2
    return out


@njit(cache=True)
def centred_cumsum(x, mu, S):
    """S[0] = 0, S[k+1] = S[k] + (x[k] - mu): one pass, bit-identical to np.cumsum(x - mu)."""
    acc = 0.0
    S[0] = 0.0
    for k in range(x.size):
        acc += x[k] - mu
        S[k + 1] = acc
    return S


@njit(cache=True, fastmath=True, inline="always")
def _ssq_second_diff(a, b, c):
    acc = 0.0
    for k in range(a.size):
        d = a[k] - 2.0 * b[k] + c[k]
        acc += d * d
    return acc


def _oavar_sums_per_tau_py(S, m):
    out = np.empty(m.size)
    n1 = S.size
    for i in prange(m.size):
        mi = m[i]
        count = n1 - 2 * mi
        out[i] = _ssq_second_diff(S[2 * mi : 2 * mi + count], S[mi : mi + count], S[:count])
    return out


def _oavar_sums_blocked_py(S, m, n_chunks, block):
    nm = m.size
    n1 = S.size
    kmax = n1 - 2 * m.min()
    part = np.zeros((n_chunks, nm))
    per = (kmax + n_chunks - 1) // n_chunks
    for c in prange(n_chunks):
        lo = c * per
        hi = min(kmax, lo + per)
        b0 = lo
        while b0 < hi:
            bend = min(b0 + block, hi)
            for i in range(nm):
                mi = m[i]
                b1 = min(bend, n1 - 2 * mi)
                if b1 > b0:
                    part[c, i] += _ssq_second_diff(
                        S[b0 + 2 * mi : b1 + 2 * mi], S[b0 + mi : b1 + mi], S[b0:b1]
                    )
            b0 = bend
    out = np.zeros(nm)
    for c in range(n_chunks):
        for i in range(nm):
            out[i] += part[c, i]
    return out


def oavar_sums(S, m):
    """sum_k (S[k+2m] - 2 S[k+m] + S[k])^2, k = 0 .. n - 2m, for each m (fully overlapping)."""
    m = np.ascontiguousarray(m, dtype=np.int64)
    if m.size == 0:
        return np.empty(0)
    par = _parallel(S.size * m.size)
    if m.size <= MAX_BLOCKED_TAUS:
        kern = _oavar_sums_blocked_par if par else _oavar_sums_blocked_ser
        return kern(S, m, max(1, get_num_threads()) if par else 1, BLOCK)
    return (_oavar_sums_per_tau_par if par else _oavar_sums_per_tau_ser)(S, m)


def _avar_sums_py(S, m):
    """sum_j (C_{j+1} - C_j)^2 over adjacent non-overlapping cluster sums C_j, for each m."""
    out = np.empty(m.size)
    n = S.size - 1
    for i in prange(m.size):
        mi = m[i]
        J = n // mi
        acc = 0.0
        for j in range(J - 1):
            d = S[(j + 2) * mi] - 2.0 * S[(j + 1) * mi] + S[j * mi]
            acc += d * d
        out[i] = acc
    return out


@njit(cache=True)
def streaming_octaves(x, offset, pending, has_pending, prev, has_prev, ssq, ndiff):
    """One chunk of the streaming non-overlapping octave AV (state arrays updated in place).

    Level j holds clusters of m = 2^j samples aligned with the start of the record. The chunk's
    completed level-j cluster sums are paired (with a carried ``pending`` sum) into level j+1 sums,
    so the work is 2 n per chunk whatever the number of levels; for every completed cluster the
    squared difference of its mean and the previous one is added to ``ssq[j]``.
    """
    L = ssq.size
    cur = np.empty(x.size)
    for k in range(x.size):
        cur[k] = x[k] - offset
    ncur = x.size
    m = 1.0
    for j in range(L):
        for i in range(ncur):
            mean = cur[i] / m
            if has_prev[j]:
                d = mean - prev[j]
                ssq[j] += d * d
                ndiff[j] += 1
            prev[j] = mean
            has_prev[j] = True
        if j + 1 == L:
            break
        nnext = 0
        for i in range(ncur):
            if has_pending[j + 1]:
                cur[nnext] = pending[j + 1] + cur[i]
                nnext += 1
                has_pending[j + 1] = False
            else:
                pending[j + 1] = cur[i]
                has_pending[j + 1] = True
        ncur = nnext
        m *= 2.0
        if ncur == 0:
            break


#: below this many (sample x tau) visits a kernel runs serially: waking the thread pool costs
#: milliseconds on a loaded machine, more than the work
PARALLEL_MIN_WORK = 20_000_000


def _parallel(work: int) -> bool:
    return work >= PARALLEL_MIN_WORK and get_num_threads() > 1


_oavar_sums_per_tau_par = njit(cache=True, parallel=True, fastmath=True)(_oavar_sums_per_tau_py)
_oavar_sums_per_tau_ser = njit(cache=True, fastmath=True)(_oavar_sums_per_tau_py)
_oavar_sums_blocked_par = njit(cache=True, parallel=True, fastmath=True)(_oavar_sums_blocked_py)
_oavar_sums_blocked_ser = njit(cache=True, fastmath=True)(_oavar_sums_blocked_py)
_avar_sums_par = njit(cache=True, parallel=True)(_avar_sums_py)
_avar_sums_ser = njit(cache=True)(_avar_sums_py)


def avar_sums(S, m):
    """sum_j (C_{j+1} - C_j)^2 over adjacent non-overlapping cluster sums C_j, for each m."""
    m = np.ascontiguousarray(m, dtype=np.int64)
    if m.size == 0:
        return np.empty(0)
    work = int(np.sum((S.size - 1) // m))
    return (_avar_sums_par if _parallel(work) else _avar_sums_ser)(S, m)
