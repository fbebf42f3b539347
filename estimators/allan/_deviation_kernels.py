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
* the modified AV is the running sum of SP1065 / allantools (its inner sum carried along the
  start index by third differences), blocked over the start index like the Hadamard sums: per
  block and m, the third differences (and the AV's squared second differences, which the edf's
  noise identification needs: no separate AV pass) in one SIMD pass into an L1 buffer, then the
  sequential chain over it as four chains over the buffer's quarters (``mvar_sums_blocked``).
  Measured at n = 1e6, octave m (CPU time, loaded machine): 17 ms for both sums, against 21 ms for the
  modified AV alone by box-sum passes over the whole record (one memory pass per octave) plus 5 ms for a
  separate AV pass;
* for octave m up to ``MVAR_BOX_MAX`` the modified AV is instead summed from box sums of the phase
  built level by level inside each block (the box of 2m is two boxes of m; ``mvar_sums_box_octaves``):
  one SIMD pass per level over an L1 buffer (the next level's boxes, the modified AV's and the AV's
  squares together), ~0.5 ms per level at n = 1e6 against ~0.8-1 ms per m for the chain; for larger m
  the buffer (block + 3m) outgrows the block and the chain is used. Measured (CPU, n = 1e6, octave m,
  best block/limit of 1024-8192 x 32-256): both sums 13.4-13.5 ms against 16.4 ms with the chain for
  every m; larger blocks/limits, up to 16384/4096 (the levels in L2), measure the same 14.6-15.8 ms
  (loaded machine), so ``BLOCK_MVAR_BOX`` and ``MVAR_BOX_MAX`` keep the levels in L1. The chain is not
  vectorised over start indices (v_{j+16} = v_j + the third difference of the box sums of 16 phases,
  in SIMD lanes): that needs a second 8 MB array read at four offsets per m and measures 14.5 ms
  against 8.2 ms for the chain's ten m >= 512 (the chain's third differences and the AV's share the
  four slices of x: it is bound by them, not by its sequential part, 0.35 ns per step from L1);
  ``results/bench/README.md`` holds these measurements;
* the non-overlapping Hadamard variance (hdev) on octave m reads the rate, not the phase: blocks of 2m
  are pairs of blocks of m, and its third differences are second differences of consecutive blocks
  (``hvar_octave_sums``; the AV for the edf's noise identification from the same blocks). The record is
  read once, in chunks of 4096 samples; the block levels up to m = 128 are made and differenced inside
  each chunk (L1/L2), and only the next level is written out (n / 256 values). Measured (CPU, n = 1e6,
  19 octaves, right after allantools' hdev has run as in the bench): 2.3-2.8 ms, against 2.8-3.2 ms
  with every level made over the whole record in a 4 MB work array (~1.6 ms either way when the
  record is in cache);
* the edf (``edf_single_filter``): rho(k) = sum_d A(d) G(k + d) from the filter's nonzero lags (every
  m-th for the difference filters, SIMD over the dense modified-AV filter), once per distinct (m, noise)
  of a call, then the K-sum per tau: ~0.05-0.12 ms for 19 octave taus (a Python loop per tau takes
  0.4-1.4 ms);
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
#: start indices per block of the modified AV (its buffer of third differences stays in L1)
BLOCK_MVAR = 2048
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


@njit(cache=True)
def hvar_sums(x, ms):
    """Non-overlapping Hadamard sums: sum_{i = 0, m, 2m, ..., i + 3m <= N-1} (x[i+3m] - 3x[i+2m] + 3x[i+m] - x[i])^2
    (SP1065 eq. 18 on the phase decimated by m; (N-1)//m - 2 terms, N/m reads per m)."""
    N = x.size
    out = np.zeros(ms.size)
    for t in range(ms.size):
        m = ms[t]
        acc = 0.0
        i = 0
        while i + 3 * m <= N - 1:
            d = x[i + 3 * m] - 3.0 * x[i + 2 * m] + 3.0 * x[i + m] - x[i]
            acc += d * d
            i += m
        out[t] = acc
    return out


@njit(cache=True, fastmath=_FM, inline="always")
def _ssq_block_diffs_range(z, k0, k1):
    """(sum_k (z[k+2] - 2z[k+1] + z[k])^2, sum_k (z[k+3] + z[k+2] - z[k+1] - z[k])^2, sum_k (z[k+1] - z[k])^2)
    for k0 <= k < k1 (z must reach k1 + 2)."""
    a = z[k0 + 3 : k1 + 3]
    b = z[k0 + 2 : k1 + 2]
    c = z[k0 + 1 : k1 + 1]
    d = z[k0:k1]
    acc2 = 0.0
    acch = 0.0
    acc1 = 0.0
    for k in range(a.size):
        d2 = b[k] - 2.0 * c[k] + d[k]
        dh = (a[k] + b[k]) - (c[k] + d[k])
        d1 = c[k] - d[k]
        acc2 += d2 * d2
        acch += dh * dh
        acc1 += d1 * d1
    return acc2, acch, acc1


@njit(cache=True, inline="always")
def _block_diffs_tail(z):
    """The terms ``_ssq_block_diffs_range(z, 0, size - 3)`` leaves: the second difference at size - 3 and
    the first differences at size - 3 and size - 2 (size >= 3)."""
    p = z.size
    d2 = z[p - 1] - 2.0 * z[p - 2] + z[p - 3]
    acc1 = 0.0
    for k in range(max(p - 3, 0), p - 1):
        d1 = z[k + 1] - z[k]
        acc1 += d1 * d1
    return d2 * d2, acc1


@njit(cache=True, fastmath=_FM, inline="always")
def _ssq_block_diffs(z):
    """``_ssq_block_diffs_range`` over all of ``z`` (size >= 3) with its tail: on blocks z of m, (the
    Hadamard sum of m (size - 2 terms), the AV sum of 2m at every start that is a multiple of m (size - 3
    terms), the non-overlapping AV sum of m (size - 1 terms))."""
    h, a2, a1 = _ssq_block_diffs_range(z, 0, max(z.size - 3, 0))
    t2, t1 = _block_diffs_tail(z)
    return h + t2, a2, a1 + t1


#: samples per chunk of ``hvar_octave_sums`` (the record is read once, chunk by chunk)
HVAR_CHUNK = 4096
#: block levels m = 2 .. 2^HVAR_CHUNK_LEVELS made and differenced inside each chunk (from L1/L2); the next
#: level is written out (n / 2^(HVAR_CHUNK_LEVELS + 1) values) and the longer blocks are made from it
HVAR_CHUNK_LEVELS = 7


@njit(cache=True, fastmath=_FM, inline="always")
def _ssq_dh(a, b, c, d):
    """sum_k ((a[k] + b[k]) - (c[k] + d[k]))^2 over equal-length slices."""
    acc = 0.0
    for k in range(a.size):
        v = (a[k] + b[k]) - (c[k] + d[k])
        acc += v * v
    return acc


@njit(cache=True, fastmath=_FM, inline="always")
def _pairs_minus(out, z, off):
    """out[i] = (z[2i] + z[2i+1]) - off for i < out.size."""
    a = z[0::2]
    b = z[1::2]
    for i in range(out.size):
        out[i] = (a[i] + b[i]) - off


@njit(cache=True, fastmath=_FM)
def hvar_octave_sums(w, levels, buf):
    """(Hadamard, Allan) sums at m = 1, 2, 4, ..., 2^(levels-1) from block sums of the rate (no phase), and
    the sum of ``w`` (not finite exactly when a sample is not, barring overflow: the caller's record check).

    Hadamard (non-overlapping, SP1065 eq. 18): on the unit phase S (x / dt), its decimated third
    difference is the second difference of consecutive block sums, S[(i+3)m] - 3S[(i+2)m] +
    3S[(i+1)m] - S[im] = y_{i+2} - 2y_{i+1} + y_i with y_i = sum_{k=im}^{(i+1)m-1} w_k (n // m full
    blocks, n // m - 2 terms: ``hvar_sums``' count).
    Allan (for the edf's noise identification): the sum of squared differences of adjacent blocks of
    m at every start offset that is a multiple of m/2 -- from the blocks of m/2 (n // (m/2) - 3 terms;
    at m = 1 every offset: n - 1 terms) -- an unbiased AV estimate with about twice the non-overlapping
    AV's terms.
    Blocks of 2m are sums of pairs of blocks of m. The record is read once, in chunks of ``HVAR_CHUNK``
    samples: each chunk's samples give the m = 1 sums, their pairs the blocks of 2, and the blocks up to
    m = 2^HVAR_CHUNK_LEVELS are made and differenced inside the chunk (each level carries its last three
    blocks into the next chunk, so every term is counted once); the next level is written into ``buf``
    (at least n / 2^(HVAR_CHUNK_LEVELS + 1) entries) and the longer blocks are made from it. The
    differences cancel the mean; the blocks from m = 4 on are centred so that long blocks hold no large
    values whose differences cost digits: inside the chunks with the first chunk's mean, the written-out
    level then moved to the record's mean (known at the end). Measured (CPU, n = 1e6, 19 octaves, right
    after allantools' hdev has run, as in the bench): 2.3-2.8 ms against 2.8-3.2 ms for the levels made
    over the whole record (a 4 MB work array written and read back).
    """
    N = w.size
    h = np.zeros(levels)
    a = np.zeros(levels)
    total = 0.0
    CH = HVAR_CHUNK
    lin = max(0, min(HVAR_CHUNK_LEVELS, levels - 1))  # the block levels made inside each chunk
    U = np.empty((lin + 2, 3 + CH // 2))  # row l: up to 3 carried blocks of level l, then the chunk's new ones
    t = np.zeros(lin + 2, dtype=np.int64)  # blocks carried per level
    mu0 = 0.0
    h0 = 0.0
    a1 = 0.0
    a0 = 0.0
    for k0 in range(0, N, CH):
        k1 = min(k0 + CH, N - 3)
        if k1 > k0:
            x2, xh, x1 = _ssq_block_diffs_range(w, k0, k1)
            h0 += x2
            a1 += xh
            a0 += x1
        L = (min(k0 + CH, N) - k0) // 2  # blocks of 2 in this chunk (k0 is a multiple of every block length)
        row = U[1]
        s = 0.0
        for i in range(L):
            v = w[k0 + 2 * i] + w[k0 + 2 * i + 1]
            row[3 + i] = v
            s += v
        total += s
        if k0 == 0 and L > 0:
            mu0 = s / (2 * L)
        for lev in range(1, lin + 1):
            row = U[lev]
            tl = t[lev]
            z = row[3 - tl : 3 + L]  # the carried blocks, then the new ones
            ln = tl + L
            lo = max(0, tl - 2)  # terms that end in a new block
            if ln - 2 > lo:
                h[lev] += _ssq_second(z[lo + 2 : ln], z[lo + 1 : ln - 1], z[lo : ln - 2])
            lo = max(0, tl - 3)
            if lev + 1 < levels and ln - 3 > lo:
                a[lev + 1] += _ssq_dh(z[lo + 3 : ln], z[lo + 2 : ln - 1], z[lo + 1 : ln - 2], z[lo : ln - 3])
            off = 4.0 * mu0 if lev == 1 else 0.0  # blocks of 2 still hold 2 mu each
            L2 = L // 2
            if lev < lin:
                _pairs_minus(U[lev + 1, 3 : 3 + L2], row[3 : 3 + 2 * L2], off)
            elif lin + 1 < levels:
                j0 = k0 >> (lin + 1)
                _pairs_minus(buf[j0 : j0 + L2], row[3 : 3 + 2 * L2], off)
            nt = min(3, ln)  # carry the last (up to) 3 blocks into the slots before the next chunk's
            src = 3 + L - nt
            for q in range(nt):
                row[3 - nt + q] = row[src + q]
            t[lev] = nt
            L = L2
    if N >= 3 and levels > 0:
        t2, t1 = _block_diffs_tail(w)
        h[0] = h0 + t2
        a[0] = a0 + t1
        if levels > 1:
            a[1] = a1
    if N % 2:
        total += w[N - 1]
    if lin + 1 >= levels:
        return h, a, total
    c = N >> (lin + 1)
    corr = (1 << (lin + 1)) * (total / N - mu0)  # centred on the first chunk's mean -> on the record's
    for i in range(c):
        buf[i] -= corr
    for lev in range(lin + 1, levels):
        if c < 3:  # no term left (the callers ask for m <= n // 3)
            break
        hh, aa, _ = _ssq_block_diffs(buf[:c])
        h[lev] = hh
        if lev + 1 < levels:
            a[lev + 1] = aa
        half = c // 2
        for i in range(half):
            buf[i] = buf[2 * i] + buf[2 * i + 1]
        c = half
    return h, a, total


def hvar_octave_buffer_size(n):
    """Entries of the work array ``hvar_octave_sums`` needs for a record of n samples."""
    return (n >> (HVAR_CHUNK_LEVELS + 1)) + 1


def hvar_octave_av_terms(n, levels):
    """Number of terms of each of ``hvar_octave_sums``' AV sums: n - 1 at m = 1, n // (m/2) - 3 beyond."""
    m = 1 << np.arange(levels)
    return np.where(m == 1, n - 1, n // np.maximum(m // 2, 1) - 3)


def hvar_sum_numpy(x, m):
    xd = x[::m]
    d = xd[3:] - 3 * xd[2:-1] + 3 * xd[1:-2] - xd[:-3]
    return float(np.sum(d * d))


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
def _third_into_and_second(out, a, b, c, d):
    """out[k] = a[k] - 3b[k] + 3c[k] - d[k]; returns sum_k (b[k] - 2c[k] + d[k])^2 (one read for both)."""
    acc = 0.0
    for k in range(a.size):
        out[k] = a[k] - 3.0 * b[k] + 3.0 * c[k] - d[k]
        w = b[k] - 2.0 * c[k] + d[k]
        acc += w * w
    return acc


#: steps per group of the modified AV's carried chain (``_group_terms``)
CHAIN_GROUP = 16


@njit(cache=True, fastmath=_FM)
def _group_terms(steps, A, B, T, ng):
    """Per group g of G = CHAIN_GROUP steps s: partial sums P_r = s_0 + ... + s_{r-1} (r = 1..G-1),
    A_g = sum_r P_r, B_g = sum_r P_r^2, T_g = the group's total (independent groups: SIMD across them)."""
    G = CHAIN_GROUP
    for g in range(ng):
        b = G * g
        p = 0.0
        a = 0.0
        q = 0.0
        for r in range(G - 1):
            p += steps[b + r]
            a += p
            q += p * p
        A[g] = a
        B[g] = q
        T[g] = p + steps[b + G - 1]


@njit(cache=True)
def _carried_squares(steps, v, A, B, T):
    """(sum_{k<K} v_k^2, v_K) for v_0 = v, v_{k+1} = v_k + steps[k], K = steps.size.

    The chain is carried a group of G steps at a time: with v the group's first value,
    sum_{r<G} (v + P_r)^2 = G v^2 + 2 v A_g + B_g (``_group_terms``), so the sequential part is one
    step per G terms; the last K mod G steps one at a time. The expansion's rounding is relative to
    the group's squares (v^2, P^2), of the order of the terms summed. ``A``, ``B``, ``T``: work
    arrays of at least K // G entries. Measured in place (CPU time, n = 1e6, octave m): the blocked
    pass 17 ms, against 19.5 ms with four chains over the quarters of the block.
    """
    K = steps.size
    G = CHAIN_GROUP
    ng = K // G
    _group_terms(steps, A, B, T, ng)
    acc = 0.0
    for g in range(ng):
        acc += (G * v * v + 2.0 * v * A[g]) + B[g]
        v += T[g]
    for k in range(G * ng, K):
        acc += v * v
        v += steps[k]
    return acc, v


@njit(cache=True, fastmath=_FM)
def mvar_sums_blocked(x, ms, block=BLOCK_MVAR):
    """(modified-AV, Allan) sums for every m of ``ms`` in one blocked pass over the start index j.

    Modified AV: sum_{j=0}^{N-3m} v_j^2, v_j = sum_{i=j}^{j+m-1} (x[i+2m] - 2x[i+m] + x[i]) (SP1065
    eq. 14); v is carried along j, v_{j+1} = v_j + (x[j+3m] - 3x[j+2m] + 3x[j+m] - x[j]) (the
    running sum of SP1065 / adev_lib / allantools), its first value summed directly. Allan: sum_{j<N-2m}
    (x[j+2m] - 2x[j+m] + x[j])^2 (the overlapping AV's, for the edf's noise identification), read
    from the same slices. Each block of start indices visits every m while its four slices of x
    are in cache: the third differences of the block into a buffer (SIMD, with the AV's squares),
    then the carried chain over them (``_carried_squares``). ``block >= x.size``: one pass per m.
    """
    N = x.size
    T = ms.size
    out = np.zeros(T)
    av = np.zeros(T)
    v = np.empty(T)
    if T == 0:
        return out, av
    for t in range(T):
        v[t] = _window_second_sum(x, 0, ms[t])
    block = max(1, min(block, N))
    buf = np.empty(block)
    wa = np.empty(block // CHAIN_GROUP + 1)
    wb = np.empty(block // CHAIN_GROUP + 1)
    wt = np.empty(block // CHAIN_GROUP + 1)
    jmax = N - 3 * ms.min()
    for b0 in range(0, jmax, block):
        for t in range(T):
            m = ms[t]
            b1 = min(b0 + block, N - 3 * m)
            if b1 > b0:
                nb = b1 - b0
                av[t] += _third_into_and_second(buf[:nb], x[b0 + 3 * m : b1 + 3 * m], x[b0 + 2 * m : b1 + 2 * m],
                                                x[b0 + m : b1 + m], x[b0:b1])
                s, v[t] = _carried_squares(buf[:nb], v[t], wa, wb, wt)
                out[t] += s
    for t in range(T):
        m = ms[t]
        out[t] += v[t] * v[t]  # the last term, j = N - 3m
        lo = max(N - 3 * m, 0)
        hi = N - 2 * m
        if hi > lo:
            av[t] += _ssq_second(x[lo + 2 * m : hi + 2 * m], x[lo + m : hi + m], x[lo:hi])
    return out, av


#: octave m up to this are summed from box sums built level by level in each block (``mvar_sums_box_octaves``)
MVAR_BOX_MAX = 256
#: start indices per block of ``mvar_sums_box_octaves`` (its two level buffers of block + 3 MVAR_BOX_MAX: 28 KB, in L1)
BLOCK_MVAR_BOX = 1024


@njit(cache=True, fastmath=_FM)
def mvar_sums_box_octaves(x, levels, block=BLOCK_MVAR_BOX):
    """(modified-AV, Allan) sums at m = 1, 2, 4, ..., 2^(levels-1), from box sums of the phase.

    SP1065 eq. 14's inner sum is v_j = Z_{j+2m} - 2 Z_{j+m} + Z_j with Z_j = sum_{i=j}^{j+m-1} x[i] (the
    box sum of m phases), and the box of 2m is two boxes of m: Z^{2m}_j = Z^m_j + Z^m_{j+m}. For each
    block of start indices, the phases the block needs (block + 3 M, M the largest m) are copied relative to
    the block's first phase (the filters cancel constants: no large values whose differences cost digits),
    then level by level one SIMD pass makes the boxes of 2m from those of m and sums v^2 and the AV's
    squares (``_box_level``): O(1) operations per term and level, no carried chain (``mvar_sums_blocked``,
    ~2 cycles per term, for the other m). Allan: sum_{j<N-2m} (x[j+2m] - 2x[j+m] + x[j])^2 from the same
    block of x.
    """
    N = x.size
    out = np.zeros(levels)
    av = np.zeros(levels)
    if levels == 0 or N < 3:
        return out, av
    top = 1 << (levels - 1)
    W = block + 3 * top
    buf = np.empty((2, W))
    for b0 in range(0, N - 2, block):
        L = min(W, N - b0)
        _shifted_into(buf[0, :L], x[b0 : b0 + L], x[b0])
        cur = L  # buf[t % 2, :cur] are the level's boxes Z_{b0+i}
        for t in range(levels):
            m = 1 << t
            z = buf[t % 2]
            zn = buf[(t + 1) % 2]
            nj = max(min(block, N - 3 * m + 1 - b0), 0)  # v_j for j in [b0, b0 + nj)
            na = max(min(block, N - 2 * m - b0), 0)  # the AV's j in [b0, b0 + na)
            nxt = cur - m if t + 1 < levels and cur > m else 0  # the next level's boxes
            c = min(nj, na, nxt)  # the three in one pass, then each one's rest
            if c > 0:
                sv, sa = _box_level(zn[:c], z[:c], z[m : m + c], z[2 * m : 2 * m + c],
                                    x[b0 : b0 + c], x[b0 + m : b0 + m + c], x[b0 + 2 * m : b0 + 2 * m + c])
                out[t] += sv
                av[t] += sa
            if nj > c:
                out[t] += _ssq_second(z[2 * m + c : 2 * m + nj], z[m + c : m + nj], z[c:nj])
            if na > c:
                av[t] += _ssq_second(x[b0 + 2 * m + c : b0 + 2 * m + na], x[b0 + m + c : b0 + m + na], x[b0 + c : b0 + na])
            if nxt > 0:
                if nxt > c:
                    _pair_into(zn[c:nxt], z[c:nxt], z[m + c : m + nxt])
                cur = nxt
    return out, av


@njit(cache=True, fastmath=_FM, inline="always")
def _box_level(out, z0, z1, z2, x0, x1, x2):
    """One pass over a level of ``mvar_sums_box_octaves``: out = z0 + z1 (the next level's boxes), and
    (sum (z2 - 2 z1 + z0)^2, sum (x2 - 2 x1 + x0)^2) (the modified AV's and the AV's terms)."""
    sv = 0.0
    sa = 0.0
    for k in range(out.size):
        a = z0[k]
        b = z1[k]
        out[k] = a + b
        v = z2[k] - 2.0 * b + a
        sv += v * v
        y = x2[k] - 2.0 * x1[k] + x0[k]
        sa += y * y
    return sv, sa


@njit(cache=True, fastmath=_FM, inline="always")
def _shifted_into(out, a, c):
    for k in range(a.size):
        out[k] = a[k] - c


@njit(cache=True, fastmath=_FM, inline="always")
def _pair_into(out, a, b):
    for k in range(a.size):
        out[k] = a[k] + b[k]


def mvar_sums(x, ms):
    """(modified-AV, Allan) sums for every m of ``ms``: octave m up to ``MVAR_BOX_MAX`` from box sums
    (``mvar_sums_box_octaves``), the others by the carried chain, blocked for few taus, one pass per m beyond."""
    ms = np.ascontiguousarray(ms, dtype=np.int64)
    box = ((ms & (ms - 1)) == 0) & (ms >= 1) & (ms <= MVAR_BOX_MAX)
    if ms.size > MAX_BLOCKED_TAUS or not box.any():
        return mvar_sums_blocked(x, ms, BLOCK_MVAR if ms.size <= MAX_BLOCKED_TAUS else x.size)
    out = np.empty(ms.size)
    av = np.empty(ms.size)
    ob, ab = mvar_sums_box_octaves(x, int(ms[box].max()).bit_length())
    lev = np.log2(ms[box]).astype(np.int64)
    out[box], av[box] = ob[lev], ab[lev]
    if not box.all():
        out[~box], av[~box] = mvar_sums_blocked(x, ms[~box], BLOCK_MVAR)
    return out, av


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


# -- equivalent degrees of freedom (``deviations.edf_quadratic``) ------------------------------------------------
#: noise types of the edf's generalized phase covariance G (``deviations._canonical_gcov``)
WHITE_PM, WHITE_FM, FLICKER_FM, RW_FM = 0, 1, 2, 3
#: the one phase filter of the single-filter statistics: second difference (oavar, totvar), third difference
#: (ohvar, hvar), the modified AV's box(m) * second difference (mvar, tvar)
SECOND_DIFF, THIRD_DIFF, MODIFIED = 0, 1, 2


@njit(cache=True)
def _gcov(noise, d):
    """The canonical power-law phase generalized covariance G(d) (``deviations._canonical_gcov``); exact
    (integers or halves) but for flicker FM."""
    a = float(abs(d))
    if noise == WHITE_PM:
        return 1.0 if a == 0.0 else 0.0
    if noise == WHITE_FM:
        return -a / 2
    if noise == FLICKER_FM:
        return a * a * np.log(a) if a > 0.0 else 0.0
    return (a * a * a - a) / 12


@njit(cache=True)
def filter_acf(shape, m):
    """A(d), d = 0..span, the exact (integer) autocorrelation of the one phase filter of ``shape`` at m:
    (1, -2, 1) at (0, m, 2m) -> 6, -4, 1 at 0, m, 2m; (-1, 3, -3, 1) at (0, m, 2m, 3m) -> 20, -15, 6, -1;
    the modified AV's filter, sum_s a_s T(d - s m), a = {0: 6, +-1: -4, +-2: 1}, T(u) = max(m - |u|, 0)
    (``noise_models.exact_variances.mvar_filter_acf``)."""
    if shape == SECOND_DIFF:
        A = np.zeros(2 * m + 1)
        A[0] = 6.0
        A[m] = -4.0
        A[2 * m] = 1.0
        return A
    if shape == THIRD_DIFF:
        A = np.zeros(3 * m + 1)
        A[0] = 20.0
        A[m] = -15.0
        A[2 * m] = 6.0
        A[3 * m] = -1.0
        return A
    A = np.zeros(3 * m + 1)
    for s in range(-2, 3):
        a = 6.0 if s == 0 else (-4.0 if abs(s) == 1 else 1.0)
        lo = max(0, s * m - m + 1)
        hi = min(3 * m, s * m + m - 1)
        for d in range(lo, hi + 1):
            A[d] += a * (m - abs(d - s * m))
    return A


@njit(cache=True)
def rho_squares_single(shape, m, noise, kmax):
    """(E[V] = rho(0), rho(k)^2 for k = 0..kmax) of one filter: rho(k) = sum_{|d| <= span} A(|d|) G(k + d).

    Only the filter's nonzero lags are visited (every m-th for the difference filters). For white PM
    rho = A; for white FM and random-walk FM every product and partial sum is an exact integer or half
    (|rho| far below 2^53), so rho does not depend on the order of summation.
    """
    A = filter_acf(shape, m)
    span = A.size - 1
    nz = np.empty(2 * span + 1, dtype=np.int64)  # the lags d with A(|d|) != 0
    c = 0
    for d in range(-span, span + 1):
        if A[abs(d)] != 0.0:
            nz[c] = d
            c += 1
    T = np.zeros(kmax + 1)
    rho0 = 0.0
    if noise == WHITE_PM:
        for k in range(min(kmax, span) + 1):
            T[k] = A[k] * A[k]
        return A[0], T
    # G once on the lags -span..kmax+span
    G = np.empty(kmax + 2 * span + 1)
    for i in range(G.size):
        G[i] = _gcov(noise, i - span)
    Gr = G[::-1].copy()  # G backwards: both sides of a dense filter are forward slices
    for k in range(kmax + 1):
        if shape == MODIFIED:  # a dense filter: SIMD over its lags
            r = _rho_dense(A, G, Gr, k + span)
        else:
            r = 0.0
            for j in range(c):
                d = nz[j]
                r += A[abs(d)] * G[k + d + span]
        if k == 0:
            rho0 = r
        T[k] = r * r
    return rho0, T


@njit(cache=True, fastmath=_FM)
def _rho_dense(A, G, Gr, c):
    """A(0) G[c] + sum_{d >= 1} A(d) (G[c + d] + G[c - d]), Gr = G backwards (not inlined at Numba's IR
    level, which would drop its fastmath flags: the caller's sums must stay in order)."""
    span = A.size - 1
    hi = G[c + 1 : c + span + 1]
    r0 = G.size - c  # Gr[r0 + d - 1] = G[c - d]
    lo = Gr[r0 : r0 + span]
    a = A[1:]
    r = 0.0
    for d in range(span):
        r += a[d] * (hi[d] + lo[d])
    return A[0] * G[c] + r


@njit(cache=True)
def edf_from_rho_squares(E, T, K):
    """2 E^2 / Var V with Var V = (2/K^2) (K T_0 + 2 sum_{k=1}^{min(K-1, kmax)} (K - k) T_k), at least 1;
    K if Var V is not positive (the quadratic form's edf, ``deviations.edf_quadratic``); 1 for K < 1."""
    if K < 1:
        return 1.0
    kk = min(K - 1, T.size - 1)
    s = 0.0
    for k in range(1, kk + 1):
        s += (K - k) * T[k]
    var = 2.0 / (K * K) * (K * T[0] + 2 * s)
    if not (var > 0):
        return float(K)
    return max(2 * E * E / var, 1.0)


@njit(cache=True)
def edf_single_filter(shape, m, K, noise, order, span_factor):
    """The edf of each (m[j], K[j], noise[j]) of a single-filter statistic (``deviations.edf_quadratic``,
    after its m' scaling), visited in ``order`` (sorted by (m, noise): rho is computed once per run of equal
    keys). ``span_factor``: the filter's span in units of m (2 or 3); flicker FM's rho is summed to 8 spans + 50."""
    out = np.empty(m.size)
    last_m = -1
    last_noise = -1
    E = 0.0
    T = np.zeros(1)
    for j in order:
        if K[j] < 1:
            out[j] = 1.0
            continue
        if m[j] != last_m or noise[j] != last_noise:
            span = span_factor * m[j]
            kmax = 8 * span + 50 if noise[j] == FLICKER_FM else span
            E, T = rho_squares_single(shape, m[j], noise[j], kmax)
            last_m = m[j]
            last_noise = noise[j]
        out[j] = edf_from_rho_squares(E, T, K[j])
    return out
