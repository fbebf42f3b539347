"""Exact expected values of the Allan-variance family for the discrete generators.

Every statistic of :mod:`avbench.estimators.allan.deviations` is an average of squares of *phase
filters* q = sum_a c_a x_{i+p_a}, where x is the phase (angle) x_k = dt * sum_{j<k} w_j of the rate
record w (x_0 = 0) and the coefficients satisfy sum c_a = 0 and sum c_a p_a = 0 (second or third
differences, their averages, the reflected differences of the total variance, the four-point
differences of Theo1). For such filters

.. math::

    E[q^2] = \\sum_{a,b} c_a c_b\\, G(p_a - p_b),

where G is any *generalized covariance* of the phase: Cov(x_k, x_l) up to terms of the form
f(k) + f(l) + k g(l) + l g(k), which the two conditions on c cancel. Each noise term states its G
(``NoiseTerm.phase_gcov``):

* stationary rate with autocovariance r: G(d) = -D(d)/2, with the phase structure function
  D(d) = E[(x_{k+d} - x_k)^2] = dt^2 [d r(0) + 2 sum_{j=1}^{d-1} (d - j) r(j)];
* white rate (ARW, r(0) = N^2/dt): G(d) = -N^2 dt |d| / 2;
* quantization (x is white angle noise of std Q, shifted): G(d) = Q^2 [d = 0];
* rate random walk (w_k = w_{k-1} + K sqrt(dt) n_k): Cov(x_k, x_l) = K^2 dt^3 [min^2-polynomial],
  which reduces to G(d) = K^2 dt^3 (|d|^3 - |d|) / 12;
* rate ramp (deterministic): no covariance (G = 0) but a mean phase ``phase_mean(k, dt)`` =
  R dt^2 k (k - 1) / 2, which adds (sum_a c_a E x_{p_a})^2 to E[q^2]. (Its square could be written
  as G(d) = R^2 dt^4 d^4 / 24, but the sum of those quartic terms cancels to zero for the Hadamard
  filter only at rounding level; the mean's sum on positions shifted to start at 0 is exact.)

Checks (tests/test_deviations.py): with c = (1, -2, 1) at (0, m, 2m) the formula gives back every
term's exact discrete Allan variance (``NoiseTerm.avar``), e.g. RRW: (8m^3 + 4m) K^2 dt^3 / 12 /
(2 m^2 dt^2) = K^2 tau / 3 + K^2 dt^2 / (6 tau). The ramp's G is the square of its mean, so a sum
of independent terms has the sum of the terms' G.

The total variance depends on the record length (its reflected ends are not stationary); every
other statistic here has the same expectation for every term i of its sum, but TIE's mean square: the
phase's first difference over m samples, taken after the record's mean rate is removed, is the filter
x_{i+m} - x_i - (m/n)(x_n - x_0) (coefficients summing to 0 and cancelling linear phase, so G applies),
whose expectation depends on i; ``tie_ms`` averages it over the N - m differences exactly. MTIE (a maximum
of ranges) has no such closed form and is not here.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "gcov_from_autocovariance",
    "phase_gcov",
    "phase_mean",
    "filter_expectation",
    "oavar",
    "ohvar",
    "mvar",
    "tvar",
    "totvar",
    "theo1",
    "total_window_filters",
    "mtotvar",
    "htotvar",
    "theobr",
    "ttotvar",
    "pvar",
    "tie_ms",
    "KINDS",
]


def gcov_from_autocovariance(r, lags, dt) -> np.ndarray:
    """G(d) = -D(d)/2 at integer ``lags`` from the rate autocovariance ``r`` (lags 0..len(r)-1; 0 beyond).

    Accumulated in extended precision (numpy.longdouble), like ``exact_avar``.
    """
    d = np.abs(np.asarray(lags, dtype=np.int64))
    L = int(d.max()) if d.size else 0
    rr = np.zeros(L + 1, dtype=np.longdouble)
    r = np.asarray(r, dtype=np.longdouble)
    k = min(r.size, L + 1)
    rr[:k] = r[:k]
    j = np.arange(L + 1, dtype=np.longdouble)
    c1 = np.concatenate(([0.0, 0.0], np.cumsum(rr[1:L])))[: L + 1]  # sum_{j=1}^{d-1} r(j)
    c2 = np.concatenate(([0.0, 0.0], np.cumsum((j * rr)[1:L])))[: L + 1]  # sum_{j=1}^{d-1} j r(j)
    dl = d.astype(np.longdouble)
    D = float(dt) ** 2 * (dl * rr[0] + 2 * (dl * c1[d] - c2[d]))
    return np.asarray(-D / 2, dtype=np.float64)


def phase_gcov(terms, lags, dt) -> np.ndarray:
    """Generalized phase covariance G of a sum of independent terms (a ``Gyro`` or a list of terms)."""
    terms = getattr(terms, "terms", terms)
    lags = np.asarray(lags, dtype=np.int64)
    out = np.zeros(lags.shape)
    for t in terms:
        g = getattr(t, "phase_gcov", None)
        if g is None:
            raise NotImplementedError(
                f"{type(t).__name__}: no phase_gcov(lags, dt) (nor autocovariance) -- the exact value of the "
                "deviation family needs one"
            )
        out = out + g(lags, dt)
    return out


def phase_mean(terms, k, dt) -> np.ndarray:
    """Mean phase of a sum of terms at integer indices ``k`` (only deterministic terms have one)."""
    terms = getattr(terms, "terms", terms)
    out = np.zeros(np.shape(k))
    for t in terms:
        f = getattr(t, "phase_mean", None)
        if f is not None:
            out = out + f(k, dt)
    return out


def filter_expectation(terms, pos, coef, dt) -> np.ndarray:
    """E[(sum_a coef_a x_{pos_a})^2] for filters in the last axis of ``pos``/``coef`` (broadcast)."""
    pos = np.asarray(pos, dtype=np.int64)
    coef = np.asarray(coef, dtype=float)
    pos, coef = np.broadcast_arrays(pos, coef)
    lag = np.abs(pos[..., :, None] - pos[..., None, :])
    uniq, inv = np.unique(lag, return_inverse=True)
    G = phase_gcov(terms, uniq, dt)[inv.reshape(lag.shape)]
    shifted = pos - pos.min(axis=-1, keepdims=True)  # the filters cancel constant and linear phase
    mean = np.sum(coef * phase_mean(terms, shifted, dt), axis=-1)
    return np.einsum("...a,...b,...ab->...", coef, coef, G) + mean**2


def _m(m) -> np.ndarray:
    arr = np.atleast_1d(np.asarray(m))
    mi = np.rint(arr).astype(np.int64)
    if arr.ndim != 1 or np.any(mi < 1) or np.any(np.abs(arr - mi) > 1e-9):
        raise ValueError(f"cluster sizes: expected positive integers, got {m!r}")
    return mi


def oavar(terms, m, dt) -> np.ndarray:
    """Allan variance E[(x_{k+2m} - 2x_{k+m} + x_k)^2] / (2 tau^2): the check of the machinery."""
    m = _m(m)
    pos = np.stack([0 * m, m, 2 * m], axis=-1)
    return filter_expectation(terms, pos, [1.0, -2.0, 1.0], dt) / (2 * (m * dt) ** 2)


def ohvar(terms, m, dt) -> np.ndarray:
    """Hadamard variance E[(x_{i+3m} - 3x_{i+2m} + 3x_{i+m} - x_i)^2] / (6 tau^2) (SP1065 eq. 18/20)."""
    m = _m(m)
    pos = np.stack([0 * m, m, 2 * m, 3 * m], axis=-1)
    return filter_expectation(terms, pos, [-1.0, 3.0, -3.0, 1.0], dt) / (6 * (m * dt) ** 2)


def mvar_filter_acf(m: int) -> np.ndarray:
    """Autocorrelation A(d), d = 0..3m, of the MVAR phase filter (box of m) * (1, -2, 1 at 0, m, 2m).

    A(d) = sum_s a_s T(d - s m) with a = {0: 6, +-1: -4, +-2: 1} and T(u) = max(m - |u|, 0): exact integers.
    """
    d = np.arange(3 * m + 1)
    A = np.zeros(d.size)
    for s, a in ((-2, 1), (-1, -4), (0, 6), (1, -4), (2, 1)):
        A += a * np.maximum(m - np.abs(d - s * m), 0)
    return A


def mvar(terms, m, dt) -> np.ndarray:
    """Modified AV E[(sum_{i<m} x_{i+2m} - 2x_{i+m} + x_i)^2] / (2 m^2 tau^2) (SP1065 eq. 14)."""
    out = []
    for mi in _m(m):
        A = mvar_filter_acf(int(mi))
        G = phase_gcov(terms, np.arange(A.size), dt)
        c = np.zeros(3 * mi + 1)  # the phase filter box(m) * (1, -2, 1 at 0, m, 2m)
        for s, a in ((0, 1.0), (mi, -2.0), (2 * mi, 1.0)):
            c[s : s + mi] += a
        mean = np.dot(c, phase_mean(terms, np.arange(c.size), dt))
        E = A[0] * G[0] + 2 * np.dot(A[1:], G[1:]) + mean**2
        out.append(E / (2.0 * mi**2 * (mi * dt) ** 2))
    return np.array(out)


def tvar(terms, m, dt) -> np.ndarray:
    """Time (angle) variance tau^2/3 * MVAR (SP1065 eq. 15), rad^2."""
    m = _m(m)
    return (m * dt) ** 2 / 3 * mvar(terms, m, dt)


def _reflected_filters(i, m, N):
    """Positions and coefficients (shape (len(i), 6)) of x*_{i-m} - 2x_i + x*_{i+m} (0-based, SP1065 eq. 25).

    Reflection: x*_{-j} = 2x_0 - x_j, x*_{N-1+j} = 2x_{N-1} - x_{N-1-j}; each point takes two slots
    (the second with coefficient 0 when the point is inside the record).
    """
    cols_p, cols_c = [], []
    for j, c in ((i - m, 1.0), (i, -2.0), (i + m, 1.0)):
        low, high = j < 0, j > N - 1
        inside = ~(low | high)
        cols_p += [np.where(low, 0, np.where(high, N - 1, j)), np.where(low, -j, np.where(high, 2 * (N - 1) - j, 0))]
        cols_c += [np.where(inside, c, 2 * c), np.where(inside, 0.0, -c)]
    return np.stack(cols_p, axis=-1), np.stack(cols_c, axis=-1)


def totvar(terms, m, n: int, dt) -> np.ndarray:
    """Total variance of a record of ``n`` rate samples (N = n + 1 phases), SP1065 eq. 25.

    The N - 2 terms are the interior second difference (stationary) except the first and last
    m - 1, which read reflected points: those are evaluated one by one (vectorised).
    """
    N = int(n) + 1
    out = []
    for mi in _m(m):
        mi = int(mi)
        if mi > N - 2:
            raise ValueError(f"totvar: m = {mi} exceeds N - 2 = {N - 2}")
        i = np.arange(1, N - 1)
        edge = i[(i - mi < 0) | (i + mi > N - 1)]
        interior = (N - 2) - edge.size
        total = interior * float(filter_expectation(terms, [0, mi, 2 * mi], [1.0, -2.0, 1.0], dt)) if interior else 0.0
        if edge.size:
            p, c = _reflected_filters(edge, mi, N)
            total += float(np.sum(filter_expectation(terms, p, c, dt)))
        out.append(total / (2 * (mi * dt) ** 2 * (N - 2)))
    return np.array(out)


def theo1(terms, m, dt) -> np.ndarray:
    """Theo1 (SP1065 eq. 30): (1 / (0.75 (m dt)^2)) sum_{d<m/2} E[q_d^2] / (m/2 - d), m even.

    q_d = x_i - x_{i+m/2-d} + x_{i+m} - x_{i+m/2+d}; the average over i is stationary, so N drops out.
    The tau of Theo1 is 0.75 m dt.
    """
    out = []
    for mi in _m(m):
        mi = int(mi)
        if mi % 2:
            raise ValueError(f"theo1: m must be even, got {mi}")
        h = mi // 2
        d = np.arange(h)
        pos = np.stack([0 * d, h - d, np.full(h, mi), h + d], axis=-1)
        E = filter_expectation(terms, pos, [1.0, -1.0, 1.0, -1.0], dt)
        out.append(np.sum(E / (h - d)) / (0.75 * (mi * dt) ** 2))
    return np.array(out)


def _half_average_slope(W: int) -> np.ndarray:
    """Row a with a @ v = the slope of v (per sample) from the means of its two halves (SP1065 MTOT/HTOT).

    W = 3m points: halves of floor(W/2) points at both ends (the middle point skipped when W is
    odd), their means a distance W/2 (W even) or (W - 1)/2 + 1 (W odd) apart -- as Stable32 and
    allantools ``calc_mtotdev_phase`` / ``calc_htotdev_freq``.
    """
    h1, h2 = W // 2, (W + 1) // 2
    dist = 0.5 * W if W % 2 == 0 else 0.5 * (W - 1) + 1
    a = np.zeros(W)
    a[:h1] = -1.0 / h1
    a[h2:] = 1.0 / (W - h2)
    return a / dist


def total_window_filters(kind: str, m: int) -> np.ndarray:
    """The 6m phase filters (rows, over the window's points) of one window of MTOTVAR or HTOTVAR.

    ``mtotvar`` (SP1065 eq. 27; Howe & Vernotte 1999): the window is 3m phase points; a linear
    trend (slope from the half averages, ``_half_average_slope``) is removed, the result x0 is
    extended by uninverted even reflection to 9m points (x0 reversed, x0, x0 reversed) and the 6m
    terms are second differences of m-point averages, (A_j - 2A_{j+m} + A_{j+2m}), j < 6m. Rows:
    3m columns (phase x_n .. x_{n+3m-1}).

    ``htotvar`` (SP1065 eq. 29; Howe, Beard, Greenhall, Vernotte, Riley 2001): the same on 3m rate
    (frequency) samples, whose linear drift is removed; written on the 3m + 1 phase points
    (y_k = x_{k+1} - x_k, unit sample time), so a constant rate and a rate ramp give 0.
    """
    W = 3 * m
    T = np.eye(W) - np.outer(np.arange(W), _half_average_slope(W))  # detrend
    R = np.concatenate((np.eye(W)[::-1], np.eye(W), np.eye(W)[::-1]))  # 9m x 3m: uninverted even reflection
    Q = np.zeros((6 * m, 9 * m))  # second differences of m-point averages
    for j in range(6 * m):
        Q[j, j : j + m] += 1.0 / m
        Q[j, j + m : j + 2 * m] -= 2.0 / m
        Q[j, j + 2 * m : j + 3 * m] += 1.0 / m
    C = Q @ R @ T
    if kind == "mtotvar":
        return C
    if kind == "htotvar":
        D = np.zeros((W, W + 1))  # y_k = x_{k+1} - x_k
        D[np.arange(W), np.arange(W)] = -1.0
        D[np.arange(W), np.arange(W) + 1] = 1.0
        return C @ D
    raise ValueError(f"kind: expected 'mtotvar' or 'htotvar', got {kind!r}")


def _window_expectation(terms, C, dt) -> float:
    """sum_j E[(C_j . x)^2] over the rows of C (positions 0..P-1 of the phase)."""
    P = C.shape[1]
    pos = np.broadcast_to(np.arange(P), C.shape)
    return float(np.sum(filter_expectation(terms, pos, C, dt)))


def mtotvar(terms, m, dt) -> np.ndarray:
    """Modified total variance, SP1065 eq. 27: E[(1/6m) sum_j (C_j x)^2] / (2 tau^2) (stationary in n).

    m = 1 included (its window of 3 points is reflected like every other).
    """
    return np.array([_window_expectation(terms, total_window_filters("mtotvar", int(mi)), dt) / (6 * mi)
                     / (2 * (mi * dt) ** 2) for mi in _m(m)])


def htotvar(terms, m, dt) -> np.ndarray:
    """Hadamard total variance, SP1065 eq. 29: E[(1/6m) sum_j (C_j y)^2] / 6 on the rate y (stationary in n).

    At m = 1 the overlapping Hadamard variance stands in (Riley's "for best consistency", as
    Stable32 and allantools do).
    """
    out = []
    for mi in _m(m):
        if mi == 1:
            out.append(float(ohvar(terms, [1], dt)[0]))
            continue
        C = total_window_filters("htotvar", int(mi)) / dt
        out.append(_window_expectation(terms, C, dt) / (6 * mi) / 6)
    return np.array(out)


def theobr(terms, m, n: int, dt) -> np.ndarray:
    """First-order value of TheoBR (Howe & Tasset 2004; SP1065 eq. 31) for a record of n rate samples.

    TheoBR(m) = [1/(k+1) sum_{i=0}^{k} AV(9 + 3i) / Theo1(12 + 4i)] Theo1(m), k = floor(0.1 N/3 - 3),
    N = n + 1 phases; here with every variance replaced by its exact expectation (the expectation of
    a ratio differs from the ratio of expectations by O(1/edf) of the Theo1 values in it).
    """
    N = int(n) + 1
    k = int(np.floor(0.1 * N / 3 - 3))
    if k < 0:
        raise ValueError(f"theobr: needs N >= 90 phase points (k = floor(0.1 N/3 - 3) >= 0), got N = {N}")
    i = np.arange(k + 1)
    ratio = np.mean(oavar(terms, 9 + 3 * i, dt) / theo1(terms, 12 + 4 * i, dt))
    return ratio * theo1(terms, m, dt)


def ttotvar(terms, m, dt) -> np.ndarray:
    """Time total variance tau^2/3 * MTOTVAR (SP1065 eq. 28), rad^2."""
    m = _m(m)
    return (m * dt) ** 2 / 3 * mtotvar(terms, m, dt)


def _filter_acf(coef) -> np.ndarray:
    """A(d) = sum_a c_a c_{a+d}, d = 0 .. len - 1 (direct below 4096 taps, FFT beyond)."""
    P = coef.size
    if P <= 4096:
        return np.correlate(coef, coef, "full")[P - 1 :]
    F = np.fft.rfft(coef, 2 * P)
    return np.fft.irfft(F * np.conj(F), 2 * P)[:P]


def pvar(terms, m, dt) -> np.ndarray:
    """Parabolic variance (Vernotte et al. 2016): 72 E[w^2] / (m^4 tau^2), w = sum_{k<m} ((m-1)/2 - k)
    (x_k - x_{k+m}); at m = 1 the AV (the weights vanish there, as the estimator takes)."""
    out = []
    for mi in _m(m):
        mi = int(mi)
        if mi == 1:
            out.append(float(oavar(terms, [1], dt)[0]))
            continue
        c = 0.5 * (mi - 1) - np.arange(mi)
        coef = np.concatenate((c, -c))
        A = _filter_acf(coef)
        G = phase_gcov(terms, np.arange(coef.size), dt)
        mean = np.dot(coef, phase_mean(terms, np.arange(coef.size), dt))
        E = A[0] * G[0] + 2 * np.dot(A[1:], G[1:]) + mean**2
        out.append(72.0 * E / (mi**4 * (mi * dt) ** 2))
    return np.array(out)


def tie_ms(terms, m, n: int, dt) -> np.ndarray:
    """Mean square TIE of a record of ``n`` rate samples with its mean removed: (1/(N - m)) sum_i E[(x_{i+m} -
    x_i)^2] over the N - m = n + 1 - m differences (module docstring), rad^2."""
    n = int(n)
    out = []
    for mi in _m(m):
        mi = int(mi)
        if mi > n:
            raise ValueError(f"tie_ms: m = {mi} exceeds the record's n = {n} samples")
        i = np.arange(n + 1 - mi)
        pos = np.stack([np.zeros_like(i), i, i + mi, np.full_like(i, n)], axis=-1)
        coef = np.array([mi / n, -1.0, 1.0, -mi / n])
        out.append(float(np.mean(filter_expectation(terms, pos, coef, dt))))
    return np.array(out)


#: kind -> callable(terms, m, n, dt): the exact expected value of each statistic
KINDS = {
    "avar": lambda t, m, n, dt: oavar(t, m, dt),  # the non-overlapping AV: the same terms, fewer of them
    "gradev": lambda t, m, n, dt: oavar(t, m, dt),  # the gap-resistant AV: the terms a gap leaves
    "oavar": lambda t, m, n, dt: oavar(t, m, dt),
    "hvar": lambda t, m, n, dt: ohvar(t, m, dt),  # the same filter, fewer terms: the same expectation
    "ohvar": lambda t, m, n, dt: ohvar(t, m, dt),
    "mvar": lambda t, m, n, dt: mvar(t, m, dt),
    "tvar": lambda t, m, n, dt: tvar(t, m, dt),
    "totvar": lambda t, m, n, dt: totvar(t, m, n, dt),
    "theo1": lambda t, m, n, dt: theo1(t, m, dt),
    "mtotvar": lambda t, m, n, dt: mtotvar(t, m, dt),
    "ttotvar": lambda t, m, n, dt: ttotvar(t, m, dt),
    "pvar": lambda t, m, n, dt: pvar(t, m, dt),
    "htotvar": lambda t, m, n, dt: htotvar(t, m, dt),
    "theobr": theobr,
}
