"""The variance family beside the Allan variance: Hadamard, modified, time, total (plain, modified,
time, Hadamard), parabolic, Theo1 and TheoBR, with avbench's exact edf or Stable32's intervals.

All are computed on the phase (angle) record x of the rate record w: x_0 = 0,
x_k = dt * sum_{j<k} (w_j - mean w), N = n + 1 phase points (allantools ``frequency2phase``; the
mean removal changes none of the statistics, whose filters cancel constants and linear phase).
Definitions (NIST SP 1065, Riley 2008; tau = m dt unless said otherwise):

* ``hvar`` (non-overlapping) Hadamard variance, SP1065 eq. 18: the same third differences on the phase
  decimated by m, x_i, x_{i+m}, ...: 1/(6 tau^2 (M-3)) sum_{i=1}^{M-3} (...)^2, M = floor((N-1)/m) + 1
  (allantools ``hdev``, Stable32 HDEV).
* ``ohvar`` overlapping Hadamard variance, SP1065 eq. 20:
  1/(6 tau^2 (N-3m)) sum_{i=1}^{N-3m} (x_{i+3m} - 3x_{i+2m} + 3x_{i+m} - x_i)^2.
  A third difference: blind to a constant rate and to a linear rate ramp (R).
* ``mvar`` modified Allan variance, SP1065 eq. 14:
  1/(2 m^2 tau^2 (N-3m+1)) sum_{j=1}^{N-3m+1} [sum_{i=j}^{j+m-1} (x_{i+2m} - 2x_{i+m} + x_i)]^2.
* ``tvar`` time variance (here an angle variance, rad^2), SP1065 eq. 15: tau^2/3 * mvar.
* ``totvar`` total variance, SP1065 eq. 25: 1/(2 tau^2 (N-2)) sum_{i=2}^{N-1} (x*_{i-m} - 2x*_i + x*_{i+m})^2
  on the doubly reflected phase x*_{1-j} = 2x_1 - x_{1+j}, x*_{N+j} = 2x_N - x_{N-j}; m <= (N-1)/2.
  SP1065's published 1000-point TOTDEV values are of this "doubly reflected" form (its p. 108).
* ``mtotvar`` modified total variance, SP1065 eq. 27 (Howe & Vernotte 1999):
  1/(2 m^2 tau^2 (N-3m+1)) sum_{n=1}^{N-3m+1} (1/6m) sum_{i=n-3m}^{n+3m-1} [z#_i(m)]^2: each of the N-3m+1
  windows of 3m phases has its linear trend removed (slope from the means of its two halves, the
  middle point skipped when 3m is odd: Stable32 and allantools), is extended by uninverted even
  reflection to 9m points, and z# is the MVAR inner sum on it (6m terms). m <= (N-1)/3.
* ``htotvar`` Hadamard total variance, SP1065 eq. 29 (Howe et al. 2001): 1/(6 (n-3m+1)) sum over the
  n-3m+1 windows of 3m *rate* samples of (1/6m) sum_{j<6m} (ybar_j - 2 ybar_{j+m} + ybar_{j+2m})^2,
  ybar the m-point averages of the window with its rate drift removed the same way and reflected
  the same way (a third difference of the phase). Blind to a constant rate and to a ramp. At
  m = 1 the overlapping Hadamard variance stands in (Riley: "for best consistency"; Stable32,
  allantools). m <= (N-2)/3.
  MTOTVAR and HTOTVAR cost 9m + 6m per window, O(N m) per m (O(N^2) over octaves): a compiled loop
  per window (running sums as Stable32's MTC.c); ``max_terms`` bounds it. SP1065 divides them by
  noise-dependent bias factors in its plots (e.g. MTOT: 0.94 white PM ... 0.69 RW FM); they are
  not applied here (as allantools): ``noise_models.exact_variances`` gives the exact expectation of
  the statistic as defined, for every noise term, which is what the tests and fits compare with.
* ``theo1`` Theo1, SP1065 eq. 30, m even, 10 <= m <= N-1 in SP1065 (here every even m >= 2, as
  allantools, so that the two agree on the same m):
  1/(0.75 (N-m) (m dt)^2) sum_{i=1}^{N-m} sum_{d=0}^{m/2-1} [(x_i - x_{i-d+m/2}) + (x_{i+m} - x_{i+d+m/2})]^2 / (m/2-d),
  reported at tau = 0.75 m dt (SP1065: "Theo1 at tau = 0.75 m tau0"; allantools labels it m dt).
  Cost: (N - m) m / 2 terms per m, the definition, which is also the fastest exact form found
  (``_deviation_kernels.theo1_sum``: the pair sums x_i + x_{i+m} formed once, then one SIMD pass per
  lag d over cache-sized blocks of start indices). Measured (CPU time, this 2-core machine at 2.3 GHz,
  octave m): 0.16 ns per term at n = 1e4 (3.7e7 terms, 6 ms) and 3e4 (3.1e8 terms, 49 ms), about 0.37
  cycles per term, the machine's SIMD throughput for 3 loads and 3 floating-point operations per term;
  four lags per pass (one read of the pair sums for four) measured no faster. So Theo1 over an octave
  grid reaching m ~ N is O(N^2) (0.34-0.37 N^2 terms for n = 1e4-1e6: 6 ms at n = 1e4, ~1 min at
  1e6); ``theo1_max_m`` and ``max_terms`` bound it. The alternatives and why they are not used:
  (a) expanding the square into lagged products (the cross terms by one FFT correlation per m,
  O(N log N), the squares by prefix sums) leaves edge corrections of O(m^2 / 4) per m (the products
  x_{i+m/2-d} x_{i+m/2+d} over the shifted ranges); taking per m the cheaper of it and the direct
  form, an octave grid costs 0.09-0.13 N^2 instead of 0.34-0.37 N^2 (3-4x less, FFTs aside). But it
  subtracts sums of squared phases (~N sigma^2 for white FM) to get squared increments (~m sigma^2):
  ~log10(N/m) digits lost for white FM, ~3 log10(N/m) for random-walk FM (x ~ N^1.5). Measured at
  n = 1e5 (the expanded sums as dot products, against the definition): white FM 6e-11 relative at
  m = 2; random-walk FM 2e-2 at m = 2, 9e-7 at m = 64, 3e-10 at m = 1024, where the definition's
  kernel agrees with its NumPy reference to ~1e-15 (3e-12 for RW FM at m = 2) -- not an exact
  method in floating point, so not used;
  (b) in increments, the same statistic is sum_{L=1}^{m/2} (1/L) sum_i (D_{i+m-L}(L) - D_i(L))^2 with
  D_i(L) = x_{i+L} - x_i (L = m/2 - d): m/2 structure functions of L-increments at gap m - L, the
  same (N - m) m / 2 terms; its expansion has the same edge and cancellation costs as (a);
  (c) the fast TheoBR / TheoH of Taylor & Howe (2010) decimate the phase before Theo1 at long tau:
  another statistic (an approximation), not implemented.
* ``theobr`` bias-removed Theo1 (Howe & Tasset 2004; SP1065 §5.2.12):
  TheoBR(m) = [1/(k+1) sum_{i=0}^{k} OAVAR(m = 9+3i) / Theo1(m = 12+4i)] Theo1(m), k = floor(0.1 N/3 - 3)
  (N >= 90 phases), at tau = 0.75 m dt. The ratio needs Theo1 at k + 1 ~ N/30 sizes up to m ~ 0.13 N:
  O(N^3) work, refused beyond ``THEOBR_MAX_TERMS`` (about N = 1.7e4) with an error saying so. Its
  edf is taken as Theo1's (the ratio averages k + 1 values; its own spread is not counted).
* ``ttotvar`` time total variance, SP1065 eq. 28: tau^2/3 * mtotvar (rad^2, as tvar).
* ``pvar`` parabolic variance (Vernotte, Lenczner, Bourgeois & Rubiola 2016, "The parabolic variance
  (PVAR): a wavelet variance based on the least-square fit", IEEE UFFC 63(4)), in phase samples:
  72 / (M m^4 tau^2) sum_{i=0}^{M-1} [sum_{k=0}^{m-1} ((m-1)/2 - k)(x_{i+k} - x_{i+k+m})]^2 with M = N - 2m
  terms (allantools ``pdev``, which drops the last of the N - 2m + 1 windows; SigmaTheta's published values
  agree, tests/test_deviations_tf.py), and PVAR = AVAR at m = 1 (the weights vanish there; allantools and
  SigmaTheta take the AV). The inner sum is carried along i
  (``_tf_kernels.pvar_sums``): O(N) per m.
* ``oavar`` the overlapping AV and ``avar`` the non-overlapping AV of
  :func:`~avbench.estimators.allan.variance.allan_variance`.

Intervals and bias corrections. ``intervals="exact"`` (the default) gives the edf below; ``intervals=
"stable32"`` gives Stable32's edf, noise identification and interval rule
(:mod:`~avbench.estimators.allan.stable32`, :mod:`~avbench.estimators.allan.noise_id`), equal to its
published PHASE.DAT bounds (tests/test_deviations.py). ``bias_corrected=True`` divides the total
variances by their bias at the noise type (MTOT, TTOT 0.94 ... 0.69; HTOT 1 + a; TOT 1 - a tau/T) and
multiplies Theo1 by Stable32's run ratio AVAR/Theo1 (its default Theo1 output), as
:mod:`~avbench.estimators.allan.stable32` states; it changes the values, not the edf.

Equivalent degrees of freedom. Each statistic (bar totvar) is V = (1/K) sum_i sum_f w_f q_{i,f}^2, a
stationary average of squared phase filters. For Gaussian noise with phase generalized covariance G
its edf is exactly 2 E[V]^2 / Var V with
Var V = (2/K^2) sum_{|k|<K} (K - |k|) sum_{f,g} w_f w_g rho_fg(k)^2, rho_fg(k) = sum_{a,b} c_fa c_gb G(k + p_gb - p_fa),
which is the computation of Greenhall & Riley (2003, "Uncertainty of stability variances based on
finite differences", the algorithm SP1065 §5.3 defers to) carried out with the power-law G of the
noise type identified at that tau (white PM: G = [d=0]; white FM: -|d|/2; flicker FM: d^2 ln|d|;
random-walk FM: (|d|^3 - |d|)/12, the exact discrete RRW). The noise type is read from the local
slope of the overlapping AV, as ``allan_variance`` does (same rule, ``_noise_from_slope``); for hvar on
octave m the AV is the one its block-sum pass gives on the way (adjacent blocks of m at every start that
is a multiple of m/2: unbiased, about twice the non-overlapping AV's terms, no pass over the record of its
own; measured: the type given by the slope where >= 64 blocks agree with the true one in 30 of 30 white-FM
and white-PM records and 29 of 30 random-walk-FM records of 2^14 samples). For long filters of the scale-free types
(white, flicker, random-walk FM) the edf is evaluated at m' = 64 with K' = K m'/m (Greenhall's
"m' = infinity" limit); for Theo1 under white PM this scaling is an approximation that
underestimates the edf (wider intervals) when m > 64. The total variance is given the edf of the
overlapping AV filter over its N - 2 terms (the reflected ends taken as if stationary): an
approximation, measured in tests/test_deviations.py against the ensemble variance. MTOTVAR and
HTOTVAR are exactly of the quadratic form above (per window, 6m filters of 3m (+1) phases whose
coefficients come from ``noise_models.exact_variances.total_window_filters``: detrending and
reflection are linear), so their edf is exact for their filters, with m' = 16 for the scale-free
limit (the F x F cross-correlations of 6m filters cost F^2 P); TTOTVAR has MTOTVAR's edf (a constant
factor). PVAR is one dense filter of 2m phases, taken through the several-filter path (m' = 64). Intervals: chi^2 with that edf, like
the AV engine. Computation (``edf_quadratics``, all taus of a call at once): for the single-filter
statistics one compiled call (``_deviation_kernels.edf_single_filter``): rho once per distinct (m, noise)
from the filter's nonzero lags -- exact integers or halves for white PM, white FM and random-walk FM,
so only flicker FM's logarithms and the order of the K-sum differ from a dense NumPy evaluation
(<= 1e-14 relative, tested) -- then the K-sum per tau; the several-filter ones take rho from FFT
cross-correlations once per distinct (m, noise).

Cost (``python -m avbench.bench --only Deviations``): every statistic is computed on the unscaled
cumulative sum S (x = dt S; tau^2 -> m^2), one pass to make it, except hvar on octave m, whose pass reads
the rate itself (block sums; its sum doubles as the record's finiteness test); the compiled passes are
described in :mod:`~avbench.estimators.allan._deviation_kernels`.
"""

from __future__ import annotations

import dataclasses
import functools
import math

import numpy as np

from avbench.estimators.allan import _deviation_kernels as _k
from avbench.estimators.allan import _kernels
from avbench.estimators.allan import _tf_kernels as _tf
from avbench.estimators.allan.noise_id import ALPHA_NAMES, noise_id
from avbench.estimators.allan.stable32 import (Stable32Result, alpha_of, bias_factor, stable32_edf, theo1_bias_sizes,
                                               theo1_noise_from_ratio, theo1_nominal_bias)
from avbench.estimators.allan.variance import (
    AllanResult,
    _checked_record_and_mean,
    _cumsum_buffer,
    _record_rules,
    _noise_codes_from_slope,
    _noise_from_slope,
    allan_variance,
    cluster_sizes,
)
from avbench.estimators.validation import check_taus
from avbench.noise_models.exact_variances import total_window_filters

__all__ = ["KINDS", "DEVIATION_NAMES", "INTERVALS", "deviation", "deviations", "phase_of", "edf_quadratic", "edf_quadratics",
           "clear_caches", "terms_per_tau", "theobr_bias_sizes", "check_feasible"]

#: the statistics
KINDS = ("avar", "oavar", "hvar", "ohvar", "mvar", "tvar", "totvar", "mtotvar", "ttotvar", "htotvar", "pvar", "theo1",
         "theobr")
#: interval rules of ``deviation``
INTERVALS = ("exact", "stable32")
#: names users type (allantools' deviations) -> kind
DEVIATION_NAMES = {
    "adev": "avar",
    "oadev": "oavar",
    "ohdev": "ohvar",
    "hdev": "hvar",
    "mdev": "mvar",
    "tdev": "tvar",
    "totdev": "totvar",
    "mtotdev": "mtotvar",
    "ttotdev": "ttotvar",
    "htotdev": "htotvar",
    "pdev": "pvar",
    "theo1": "theo1",
    "theobr": "theobr",
}
_M_PRIME = 64
#: statistics made of several filters per term, and the m' their scale-free edf is evaluated at (the
#: F x F filter cross-correlations cost F^2 P: 6m filters of 3m points for the total variances)
_MULTI_FILTER = {"theo1": _M_PRIME, "theobr": _M_PRIME, "mtotvar": 16, "ttotvar": 16, "htotvar": 16, "pvar": _M_PRIME}
#: the Theo1 values TheoBR's bias ratio needs are refused beyond this many terms (see ``deviation``)
THEOBR_MAX_TERMS = 5e9


def _sample_phase(rate, dt):
    """(S, n, dt): S[0] = 0, S[k] = sum of the first k mean-removed rate samples (the phase in units of dt).

    Every statistic is a sum of squared filters of the phase x = dt S divided by (tau^2 = m^2 dt^2)
    times a count, so it is computed on S with m^2 in place of tau^2: one pass fewer than scaling.
    """
    rate, dt, mean = _checked_record_and_mean(rate, dt)
    return _unit_phase(rate, mean), rate.size, dt


def _unit_phase(rate, mean, out=None):
    """S of a checked record and its mean (``_sample_phase`` after the checks), into ``out`` if given."""
    return _kernels.centred_cumsum(rate, mean, np.empty(rate.size + 1) if out is None else out)


def _octave_levels(m) -> int:
    """1 + log2(max m) when every m is a power of two (the block-sum pass covers them), else 0."""
    m = np.asarray(m)
    if m.size == 0 or np.any(m < 1) or np.any(m & (m - 1)):
        return 0
    return int(m.max()).bit_length()


def phase_of(rate, dt):
    """(phase x with x[0] = 0 and N = n + 1 points, n, dt) of a rate record (mean removed)."""
    S, n, dt = _sample_phase(rate, dt)
    S *= dt
    return S, n, dt


def _max_m(kind: str, N: int) -> int:
    return {
        "oavar": (N - 1) // 2,
        "hvar": (N - 1) // 3,
        "ohvar": (N - 1) // 3,
        "mvar": N // 3,  # N - 3m + 1 >= 1 terms
        "tvar": N // 3,
        "totvar": (N - 1) // 2,
        "mtotvar": (N - 1) // 3,  # at least two windows of 3m phases (allantools drops one)
        "ttotvar": (N - 1) // 3,
        "pvar": (N - 1) // 2,  # M = N - 2m >= 1 terms
        "htotvar": (N - 2) // 3,  # at least two windows of 3m rates
        "theo1": N - 1,
        "theobr": N - 1,
    }[kind]


def _cluster_sizes(kind, taus, n, dt, points_per_decade, theo1_max_m):
    N = n + 1
    top = _max_m(kind, N)
    if kind in ("theo1", "theobr"):
        top = min(top, theo1_max_m) if theo1_max_m else top
        if isinstance(taus, str):
            m = cluster_sizes(taus, 2 * (top + 1), dt, points_per_decade)
        else:
            m = np.rint(np.asarray(taus, dtype=float) / (0.75 * dt)).astype(np.int64)
        m = np.unique(m[(m % 2 == 0) & (m >= 2) & (m <= top)])
    else:
        m = cluster_sizes(taus, 2 * top + 1, dt, points_per_decade)
        m = m[(m >= 1) & (m <= top)]
    return m.astype(np.int64)


def terms_per_tau(kind: str, m, N: int) -> np.ndarray:
    """Number of terms summed per cluster size (the cost of one value).

    (N - m) m / 2 for Theo1 and TheoBR; (N - 3m + 1) 15m for the modified, time and Hadamard total
    variances (9m reflected points and 6m running sums per window); ~N otherwise.
    """
    m = np.asarray(m, dtype=float)
    if kind in ("theo1", "theobr"):
        return (N - m) * m / 2
    if kind in ("mtotvar", "ttotvar", "htotvar"):
        return np.maximum(N - 3 * m + 1, 1) * 15 * m
    return np.full(m.shape, float(N))


def theobr_bias_sizes(N: int):
    """(AV m = 9 + 3i, Theo1 m = 12 + 4i), i = 0..k, k = floor(0.1 N/3 - 3): TheoBR's bias ratio (SP1065)."""
    k = int(np.floor(0.1 * N / 3 - 3))
    if k < 0:
        raise ValueError(f"theobr: needs a record of N >= 90 phase points (k = floor(0.1 N/3 - 3) >= 0), got N = {N}")
    i = np.arange(k + 1, dtype=np.int64)
    return 9 + 3 * i, 12 + 4 * i


def _filters(kind: str, m: int):
    """(positions (F, P), coefficients (F, P), weights (F,)) of the phase filters of one statistic."""
    if kind in ("oavar", "totvar"):
        return np.array([[0, m, 2 * m]]), np.array([[1.0, -2.0, 1.0]]), np.ones(1)
    if kind in ("ohvar", "hvar"):
        return np.array([[0, m, 2 * m, 3 * m]]), np.array([[-1.0, 3.0, -3.0, 1.0]]), np.ones(1)
    if kind in ("mvar", "tvar"):
        c = np.zeros(3 * m + 1)  # box(m) * (1, -2, 1 at 0, m, 2m): the phase filter of one MVAR term
        for s, a in ((0, 1.0), (m, -2.0), (2 * m, 1.0)):
            c[s : s + m] += a
        return np.arange(3 * m + 1)[None, :], c[None, :], np.ones(1)
    if kind in ("theo1", "theobr"):
        h = m // 2
        d = np.arange(h)
        pos = np.stack([0 * d, h - d, np.full(h, m), h + d], axis=-1)
        return pos, np.tile([1.0, -1.0, 1.0, -1.0], (h, 1)), 1.0 / (h - d)
    if kind == "pvar":
        if m == 1:  # PVAR is the AV at m = 1
            return _filters("oavar", 1)
        c = 0.5 * (m - 1) - np.arange(m)
        return np.arange(2 * m)[None, :], np.concatenate((c, -c))[None, :], np.ones(1)
    if kind in ("mtotvar", "ttotvar", "htotvar"):
        if kind == "htotvar" and m == 1:  # the overlapping Hadamard variance stands in at m = 1
            return _filters("ohvar", 1)
        C = total_window_filters("htotvar" if kind == "htotvar" else "mtotvar", m)
        return np.broadcast_to(np.arange(C.shape[1]), C.shape), C, np.ones(C.shape[0])
    raise ValueError(f"kind: expected one of {KINDS}, got {kind!r}")


def _canonical_gcov(noise: str, d):
    d = np.abs(np.asarray(d, dtype=float))
    if noise == "white_pm":
        return (d == 0).astype(float)
    if noise == "white_fm":
        return -d / 2
    if noise == "flicker_fm":
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(d > 0, d * d * np.log(np.where(d > 0, d, 1.0)), 0.0)
    if noise == "rw_fm":
        return (d**3 - d) / 12
    raise ValueError(f"noise: expected white_pm, white_fm, flicker_fm or rw_fm, got {noise!r}")


#: the single-filter statistics: (their filter's shape in the compiled edf, its span in units of m)
_SINGLE_FILTER = {"oavar": (_k.SECOND_DIFF, 2), "totvar": (_k.SECOND_DIFF, 2), "ohvar": (_k.THIRD_DIFF, 3),
                  "hvar": (_k.THIRD_DIFF, 3), "mvar": (_k.MODIFIED, 3), "tvar": (_k.MODIFIED, 3)}
_NOISE_CODE = {"white_pm": _k.WHITE_PM, "white_fm": _k.WHITE_FM, "flicker_fm": _k.FLICKER_FM, "rw_fm": _k.RW_FM}


def _noise_codes(noise) -> np.ndarray:
    """Codes of noise type names or integer alphas (the exact edf's four types)."""
    try:
        return np.array([_NOISE_CODE[v if isinstance(v, str) else ALPHA_NAMES.get(int(v), str(v))] for v in noise],
                        dtype=np.int64)
    except KeyError as e:
        raise ValueError(f"noise: expected white_pm, white_fm, flicker_fm or rw_fm (alpha 2, 0, -1, -2) for the exact edf, "
                         f"got {e.args[0]!r}") from None


@functools.lru_cache(maxsize=4096)
def edf_quadratic(kind: str, m: int, K: int, noise: str) -> float:
    """EDF 2 E[V]^2 / Var V of a stationary average of K squared phase filters (module docstring);
    :func:`edf_quadratics` at one point."""
    return float(edf_quadratics(kind, [int(m)], [int(K)], [noise])[0])


def edf_quadratics(kind: str, m, K, noise) -> np.ndarray:
    """``edf_quadratic`` at every (m[j], K[j], noise[j]) at once (1-D arrays of equal length).

    rho_fg(k) = sum_d A_fg(d) G(k + d) with A_fg the cross-correlation of filters f and g; for the
    white, white-FM and random-walk-FM G, rho vanishes beyond the filter span (the filters cancel
    constants and linear phase), for flicker FM it decays as k^-2 and is summed to 8 spans + 50. The
    single-filter statistics (oavar, totvar, ohvar, hvar, mvar, tvar) are one compiled call
    (``_deviation_kernels.edf_single_filter``: rho once per distinct (m, noise), from the filter's nonzero
    lags); the several-filter ones (theo1, theobr, mtotvar, htotvar) take rho from ``_rho_squares`` (FFT
    cross-correlations) once per distinct (m, noise). K < 1 gives 1.
    """
    m = np.asarray(m, dtype=np.int64).reshape(-1)
    return _edf_codes(kind, m, K, _noise_codes(np.broadcast_to(np.asarray(noise, dtype=object), m.shape)))


def _edf_codes(kind, m, K, codes) -> np.ndarray:
    """``edf_quadratics`` with the noise types as codes (``_deviation_kernels.WHITE_PM`` ...)."""
    m = np.asarray(m, dtype=np.int64).reshape(-1)
    K = np.asarray(K, dtype=np.int64).reshape(-1)
    if kind not in _SINGLE_FILTER and kind not in _MULTI_FILTER:
        raise ValueError(f"kind: expected one of {KINDS}, got {kind!r}")
    mp = _MULTI_FILTER.get(kind, _M_PRIME)
    # the scale-free types' long filters: at m' with K' = K m'/m (white PM too for several filters)
    scaled = (m > mp) & ((codes != _k.WHITE_PM) | (kind in _MULTI_FILTER)) & (K >= 1)
    Ks = np.where(scaled, np.maximum(1, np.rint(K * mp / np.maximum(m, 1))), K).astype(np.int64)
    ms = np.where(scaled, mp, m)
    if kind in _SINGLE_FILTER:
        shape, span = _SINGLE_FILTER[kind]
        return _k.edf_single_filter(shape, ms, Ks, codes, np.lexsort((codes, ms)), span)
    names = {v: k for k, v in _NOISE_CODE.items()}
    out = np.ones(m.size)
    for j in np.flatnonzero(Ks >= 1):
        mi, nj = int(ms[j]), names[int(codes[j])]
        E, total = _rho_squares(kind, mi, nj, _kmax(kind, mi, nj))
        out[j] = _k.edf_from_rho_squares(E, total, int(Ks[j]))
    return out


def _kmax(kind, m, noise):
    span = int(_filters(kind, m)[0].max())
    return 8 * span + 50 if noise == "flicker_fm" else span


@functools.lru_cache(maxsize=256)
def _rho_squares(kind: str, m: int, noise: str, kmax: int):
    """(E[V], sum_{f,g} w_f w_g rho_fg(k)^2 for k = 0..kmax): the K-free part of the edf of a statistic of
    several filters (theo1, mtotvar, htotvar; the single-filter ones: ``_deviation_kernels.rho_squares_single``)."""
    pos, coef, w = _filters(kind, m)
    P = int(pos.max()) + 1
    C = np.zeros((len(w), P))
    np.add.at(C, (np.arange(len(w))[:, None], pos), coef)
    L = 2 * P - 1
    Fc = np.fft.rfft(C, 2 * L)
    # A_fg(d) = sum_a C_f[a] C_g[a + d], d = -(P-1)..P-1 (integer filters: rounded back to exact)
    A = np.fft.irfft(np.conj(Fc)[:, None, :] * Fc[None, :, :], 2 * L)
    A = np.concatenate((A[..., -(P - 1) :], A[..., :P]), axis=-1) if P > 1 else A[..., :1]
    if np.all(C == np.rint(C)):
        A = np.rint(A)
    # rho(k) = sum_d A(d) G(k + d), d = -(P-1)..P-1: G once on the lags -(P-1)..kmax+P-1, then windows
    G = _canonical_gcov(noise, np.arange(-(P - 1), kmax + P))
    windows = np.lib.stride_tricks.sliding_window_view(G, 2 * P - 1)  # (kmax+1, 2P-1), row k: G(k-P+1..k+P-1)
    rho = A.reshape(-1, 2 * P - 1) @ windows.T  # (F*F, kmax+1)
    ww = (w[:, None] * w[None, :]).reshape(-1)
    E = float(np.dot(w, np.diagonal(rho[:, 0].reshape(len(w), len(w)))))
    return E, ww @ (rho * rho)


def clear_caches() -> None:
    """Forget the cached edf computations (benchmarks time a cold call)."""
    edf_quadratic.cache_clear()
    _rho_squares.cache_clear()


def _noise_kinds(S, dt, m_av, n, av_sums=None):
    """Noise type per m from the overlapping AV slope (as allan_variance), m beyond n/2 take the last.

    The AV is computed from the same cumulative sum S (``_sample_phase``) as ``allan_variance`` does,
    unless ``av_sums`` ({m: sum of squared second differences}) already holds every m needed.
    """
    mm = np.unique(np.clip(m_av, 1, n // 2)).astype(np.int64)
    mf = mm.astype(float)
    if av_sums is not None and all(int(k) in av_sums for k in mm):
        sums = np.array([av_sums[int(k)] for k in mm])
    else:
        sums = _kernels.oavar_sums(S, mm)
    av = sums / (2.0 * mf * mf * (n - 2 * mf + 1))
    kinds = _noise_from_slope(mf * dt, av, n // mm)
    return dict(zip(mm.tolist(), kinds))


def deviation(
    rate,
    dt,
    kind: str = "ohvar",
    taus="octave",
    *,
    points_per_decade: int = 10,
    noise="auto",
    confidence: float = 0.683,
    theo1_max_m: int | None = None,
    max_terms: float | None = None,
    edf: bool = True,
    intervals: str = "exact",
    bias_corrected: bool = False,
) -> AllanResult:
    """One statistic of the family (module docstring) with its edf and chi^2 interval.

    Parameters
    ----------
    rate : array_like
        Rate samples (rad/s), 1-D, finite. (Angle data: pass ``np.diff(angle) / dt``.)
    dt : float
        Sample interval (s).
    kind : str
        One of ``KINDS`` ("avar", "oavar", "hvar", "ohvar", "mvar", "tvar", "totvar", "mtotvar", "ttotvar",
        "htotvar", "pvar", "theo1", "theobr"), or a deviation name (``DEVIATION_NAMES``: "adev", "oadev",
        "hdev", "ohdev", "mdev", "tdev", "totdev", "mtotdev", "ttotdev", "htotdev", "pdev", "theo1", "theobr").
    taus : "octave", "decade", "all" or array of seconds
        As :func:`~avbench.estimators.allan.variance.allan_variance`; each statistic keeps the m its
        definition allows (ohvar, mvar: m <= N/3; totvar: m <= (N-1)/2; theo1: even m <= N-1, tau = 0.75 m dt).
    noise : "auto", a noise type name or an integer alpha (one, or one per tau)
        For the edf and the bias correction ("white_pm", "white_fm", "flicker_fm", "rw_fm"; with
        ``intervals="stable32"`` also "flicker_pm", "fw_fm", "rr_fm", or alpha 2 ... -4). "auto": from the
        AV slope (``intervals="exact"``) or by Stable32's identification (:func:`~avbench.estimators.allan.
        noise_id.noise_id`: lag-1 autocorrelation, B1, R(n)).
    theo1_max_m : int, optional
        Largest Theo1 (TheoBR) m (its cost grows as N m / 2 per tau).
    max_terms : float, optional
        Keep the cluster sizes, smallest first, while the total number of terms summed stays within
        this budget (``terms_per_tau``: Theo1, TheoBR (N - m) m / 2 per m; MTOTVAR, HTOTVAR
        15 m (N - 3m + 1); the others about N): a bound on the cost. TheoBR's bias ratio has its own
        bound, ``THEOBR_MAX_TERMS``.
    edf : bool
        False: skip the noise identification and the edf (``edf`` NaN, no interval): the values only
        (a bias correction still identifies the noise it needs).
    intervals : "exact" or "stable32"
        The edf and interval rule (module docstring): avbench's exact Gaussian edf, or Stable32's (its
        noise identification, edf formulas and quantile rule; a ``Stable32Result``). PDEV has no
        Stable32 interval.
    bias_corrected : bool
        Divide the total variances by their bias at the noise type and give Theo1 Stable32's bias-removed
        value (module docstring); no other statistic changes.

    Returns
    -------
    AllanResult
        ``kind`` names the statistic; ``avar`` holds its variance (rad^2/s^2; tvar, ttotvar: rad^2),
        ``deviation`` its square root; ``J`` the number of terms averaged; ``edf``, ``ci_low``, ``ci_high``.
        With ``intervals="stable32"`` a :class:`~avbench.estimators.allan.stable32.Stable32Result` (a
        subclass) that also holds each tau's ``alpha`` and ``bias``.

    Examples
    --------
    >>> import numpy as np
    >>> w = np.random.default_rng(0).standard_normal(1000)
    >>> r = deviation(w, 1.0, "mtotdev", [1.0, 16.0], intervals="stable32", noise=0, bias_corrected=True)
    >>> r.bias.tolist(), [round(float(e), 2) for e in r.edf]
    ([0.73, 0.73], [782.03, 81.32])
    """
    kind = DEVIATION_NAMES.get(kind, kind)
    if kind not in KINDS:
        raise ValueError(f"kind: expected one of {', '.join(KINDS)} or {', '.join(DEVIATION_NAMES)}, got {kind!r}")
    if intervals not in INTERVALS:
        raise ValueError(f"intervals: expected one of {', '.join(INTERVALS)}, got {intervals!r}")
    if intervals == "stable32" and kind == "pvar":
        raise ValueError("intervals: Stable32 has no PDEV (parabolic deviation) interval; use intervals='exact'")
    check_taus(taus)
    plain = intervals == "exact" and not bias_corrected
    if kind in ("oavar", "avar"):  # no bias correction applies to the AV
        res = allan_variance(rate, dt, taus, kind == "oavar", points_per_decade=points_per_decade,
                             noise=noise if intervals == "exact" else "auto", confidence=confidence)
        return res if intervals == "exact" else _finish(kind, res, rate, None, noise, intervals, False, edf)
    fast = _record_rules(rate, dt) if kind == "hvar" else None  # hvar's octave pass tests finiteness itself
    if fast is None:
        rate, dt, mean = _checked_record_and_mean(rate, dt)
    else:
        (rate, dt), mean = fast, None
    n = rate.size
    N = n + 1
    m = _cluster_sizes(kind, taus, n, dt, points_per_decade, theo1_max_m)
    if max_terms is not None:
        m = m[np.cumsum(terms_per_tau(kind, m, N)) <= float(max_terms)]
    if m.size == 0:
        raise ValueError(f"taus: no cluster size of {kind} fits a record of {n} samples (N = {N} phases)"
                         + ("" if max_terms is None else f" within max_terms = {max_terms:g}"))
    mf = m.astype(float)
    av_sums = None  # the AV's sums where a kernel gives them on the way (for the noise identification)
    # the phase in units of dt (tau^2 -> m^2 below), except for hvar on octave m (block sums of the rate)
    levels = _octave_levels(m) if kind == "hvar" else 0
    if levels:
        h, a, total = _k.hvar_octave_sums(rate, levels, _cumsum_buffer(_k.hvar_octave_buffer_size(n)))
        if not math.isfinite(total):  # a non-finite sample (the full check names it) or an overflowed sum
            levels = 0
    if mean is None and not levels:
        rate, dt, mean = _checked_record_and_mean(rate, dt)
    # (into the engine's per-thread scratch buffer: x never leaves this call; a fresh 8 MB array at n = 1e6
    # costs its page faults, ~0.5-1 ms)
    x = None if levels else _unit_phase(rate, mean, _cumsum_buffer(n + 1))
    if kind == "hvar":
        K = n // m - 2
        if levels:  # blocks of 2m from pairs of blocks of m (above); the AV from the same blocks
            lev = np.log2(m).astype(np.int64)
            sums, av_sums = h[lev], a[lev]
        else:  # any other grid: the noise identified from the overlapping AV (below), as for ohvar
            sums = _k.hvar_sums(x, m)
        var = sums / (6.0 * mf * mf * K)
    elif kind == "ohvar":
        K = N - 3 * m
        sums, av_sums = _k.ohvar_sums(x, m, _k.BLOCK if m.size <= _k.MAX_BLOCKED_TAUS else x.size)
        var = sums / (6.0 * mf * mf * K)
    elif kind in ("mvar", "tvar"):
        K = N - 3 * m + 1
        sums, av_sums = _k.mvar_sums(x, m)
        var = sums / (2.0 * mf**4 * K)
        if kind == "tvar":
            var = var * (mf * dt) ** 2 / 3.0
    elif kind == "totvar":
        K = np.full(m.size, N - 2)
        sums, av_sums = _k.totvar_sums(x, m, _k.BLOCK if m.size <= _k.MAX_BLOCKED_TAUS else x.size)
        var = sums / (2.0 * mf * mf * (N - 2))
    elif kind in ("mtotvar", "ttotvar"):
        K = N - 3 * m + 1
        sums = np.array([_k.total_window_sums(x, int(mi), True) for mi in m])
        var = sums / (2.0 * mf * mf * K)
        if kind == "ttotvar":
            var = var * (mf * dt) ** 2 / 3.0
    elif kind == "pvar":
        K = N - 2 * m
        var = 72.0 * _tf.pvar_sums(x, m) / (K * mf**6)
        if m[0] == 1:  # the AV at m = 1 (the parabolic weights vanish there)
            K[0] = N - 2
            var[0] = _kernels.oavar_sums(x, m[:1])[0] / (2.0 * K[0])
    elif kind == "htotvar":
        y = np.asarray(rate, dtype=float)
        y = y - np.mean(y)  # cancelled by the differences, but a large bias would cost digits there
        K = n - 3 * m + 1
        sums = np.array([_k.total_window_sums(y, int(mi), False) if mi > 1 else np.nan for mi in m])
        var = sums / (6.0 * K)
        if m[0] == 1:  # SP1065 / Stable32: the overlapping Hadamard variance at m = 1
            K[0] = N - 3
            var[0] = _k.ohvar_sums(x, m[:1])[0][0] / (6.0 * K[0])
    else:  # theo1, theobr
        K = N - m
        sums = np.array([_k.theo1_sum(x, int(mi)) for mi in m])
        var = sums / (0.75 * K * mf * mf)
        if kind == "theobr":
            var = var * _theobr_ratio(x, N)
    tau = mf * dt * (0.75 if kind in ("theo1", "theobr") else 1.0)
    K = np.asarray(K, dtype=np.int64)
    if intervals == "stable32" or not edf:
        nan = np.full(m.size, np.nan)
        res = AllanResult(tau, m, var, K, nan, nan, True, n, dt, confidence, kind=kind)
        return res if plain else _finish(kind, res, rate, x, noise, intervals, bias_corrected, edf)
    if not edf:
        nan = np.full(m.size, np.nan)
        return AllanResult(tau, m, var, K, nan, nan, True, n, dt, confidence, kind=kind)
    if noise == "auto" and levels:
        # the AV's slope as for every statistic, the AV from hvar's own block sums (at every start offset
        # that is a multiple of m/2: an unbiased AV with about twice the non-overlapping AV's terms)
        count = _k.hvar_octave_av_terms(n, levels)[np.log2(m).astype(np.int64)]
        codes = _noise_codes_from_slope(mf * dt, av_sums / (2.0 * mf * mf * count), n // m)
    elif noise == "auto" and av_sums is not None and kind not in ("theo1", "theobr") and m[-1] <= n // 2:
        # the AV at every m came with the statistic's sums: the type per m from its slope directly (what
        # ``_noise_kinds`` gives for these m, without its table)
        codes = _noise_codes_from_slope(mf * dt, av_sums / (2.0 * mf * mf * (n - 2 * mf + 1)), n // m)
    elif noise == "auto":
        m_av = np.maximum(1, np.rint(tau / dt).astype(np.int64))
        table = _noise_kinds(x, dt, m_av, n, None if av_sums is None else dict(zip(m.tolist(), av_sums)))
        keys = np.array(sorted(table))
        codes = _noise_codes([table[int(keys[np.argmin(np.abs(keys - mi))])] for mi in m_av])
    else:
        codes = _noise_codes(np.broadcast_to(np.asarray(noise, dtype=object), m.shape))
    edf_kind = {"totvar": "oavar", "theobr": "theo1", "hvar": "ohvar", "ttotvar": "mtotvar"}.get(kind, kind)
    # hvar: its K terms are the m = 1 statistic of the phase decimated by m, whose G is that of the same
    # noise type scaled (white PM, white FM; flicker FM up to a quadratic in the lag, which the third
    # difference cancels): exact for them. RW FM approximately: the decimated G is m^3 (|d|^3 - |d|/m^2)/12,
    # the canonical discrete one (|d|^3 - |d|)/12.
    m_edf = np.ones_like(m) if kind == "hvar" else m
    e = _edf_codes(edf_kind, m_edf, K, codes)
    res = AllanResult(tau, m, var, K, 1.0 / np.sqrt(2.0 * e), e, True, n, dt, confidence, kind=kind)
    return res if plain else _finish(kind, res, rate, x, noise, intervals, bias_corrected, edf, _CODE_ALPHA[codes])


#: the exact path's noise codes (``_deviation_kernels.WHITE_PM`` ...) -> alpha
_CODE_ALPHA = np.array([2, 0, -1, -2], dtype=np.int64)


def _noise_alpha(kind, res, rate, noise):
    """alpha per tau for a bias correction or Stable32's edf: given, or by Stable32's identification at the
    tau of the AV (Theo1: 0.75 m; beyond half the record, the type at half the record)."""
    if not (isinstance(noise, str) and noise == "auto"):
        return np.broadcast_to(alpha_of(noise), res.m.shape).copy()
    n = res.n_samples
    m_id = np.clip(np.rint(res.tau / res.dt).astype(np.int64), 1, n // 2)
    ids = noise_id(rate, res.dt, np.unique(m_id) * res.dt, kind=kind)
    return ids.alpha[np.searchsorted(ids.m, m_id)]


def _finish(kind, res, rate, x, noise, intervals, bias_corrected, edf, exact_alpha=None):
    """``res`` with the bias correction and/or Stable32's edf and interval rule (module docstring).

    ``x``: the unit phase when the caller has it (Theo1's run ratio reads it); ``exact_alpha``: the types the
    exact path identified (a bias correction of its result uses them)."""
    n, dt, m = res.n_samples, res.dt, res.m
    N = n + 1
    need_alpha = bias_corrected or (intervals == "stable32" and edf)
    auto_theo1 = bias_corrected and kind == "theo1" and isinstance(noise, str) and noise == "auto"
    if auto_theo1:  # Stable32's run ratio AVAR/Theo1 and the type it implies, for every tau
        if x is None:
            x, _, _ = _sample_phase(rate, dt)
        k = _theo1_ratio(x, N, theo1_bias_sizes(N))
        alpha = np.full(m.size, theo1_noise_from_ratio(k), dtype=np.int64)
    elif exact_alpha is not None and isinstance(noise, str) and noise == "auto":
        alpha = exact_alpha
    else:
        alpha = _noise_alpha(kind, res, rate, noise) if need_alpha else None
    var, bias = res.avar, np.ones(m.size)
    if bias_corrected and kind == "theo1":
        bias = np.full(m.size, 1.0 / k) if auto_theo1 else 1.0 / theo1_nominal_bias(alpha)
        var = var / bias
    elif bias_corrected:
        bias = bias_factor(kind, m, N, alpha)
        var = var / bias
    if intervals == "exact":
        return dataclasses.replace(res, avar=var)
    if edf:
        e = stable32_edf({"theobr": "theo1"}.get(kind, kind), m, N, alpha)
        rel = 1.0 / np.sqrt(2.0 * e)
    else:
        e = rel = np.full(m.size, np.nan)
    return Stable32Result(res.tau, m, var, res.J, rel, e, res.overlapping, n, dt, res.confidence, kind=kind,
                          alpha=alpha, bias=bias)


def check_feasible(kinds, n: int) -> None:
    """Raise ValueError, before any work, for a statistic a record of ``n`` samples cannot have at a
    bounded cost: TheoBR, whose bias ratio needs Theo1 at ~N/30 cluster sizes (``THEOBR_MAX_TERMS``)."""
    if "theobr" not in {DEVIATION_NAMES.get(k, k) for k in kinds}:
        return
    N = int(n) + 1
    m_av, m_th = theobr_bias_sizes(N)
    cost = float(np.sum(terms_per_tau("theo1", m_th, N)))
    if cost > THEOBR_MAX_TERMS:
        raise ValueError(
            f"theobr: its bias ratio needs Theo1 at {m_th.size} cluster sizes up to m = {m_th[-1]} "
            f"({cost:.2g} terms, beyond THEOBR_MAX_TERMS = {THEOBR_MAX_TERMS:.2g}): a record of {n} samples "
            "is too long for it (Theo1 costs (N - m) m / 2 per m); use theo1 or a shorter record")


def _theobr_ratio(S, N):
    """1/(k+1) sum_i AV(9 + 3i) / Theo1(12 + 4i) on the unit phase S (Howe & Tasset 2004; SP1065)."""
    check_feasible(["theobr"], N - 1)
    return _theo1_ratio(S, N, theobr_bias_sizes(N))


def _theo1_ratio(S, N, sizes):
    """mean_i AV(m_av[i]) / Theo1(m_th[i]) on the unit phase S (TheoBR's and Stable32's bias ratios)."""
    m_av, m_th = sizes
    cost = float(np.sum(terms_per_tau("theo1", m_th, N)))
    if cost > THEOBR_MAX_TERMS:
        raise ValueError(f"theo1: its bias ratio needs Theo1 at {m_th.size} cluster sizes ({cost:.2g} terms, beyond "
                         f"THEOBR_MAX_TERMS = {THEOBR_MAX_TERMS:.2g}): the record of {N - 1} samples is too long for it")
    mf = m_av.astype(float)
    av = _kernels.oavar_sums(S, m_av) / (2.0 * mf * mf * (N - 2 * mf))
    mt = m_th.astype(float)
    th = np.array([_k.theo1_sum(S, int(mi)) for mi in m_th]) / (0.75 * (N - mt) * mt * mt)
    return float(np.mean(av / th))


def deviations(rate, dt, kinds=("oavar", "ohvar", "mvar", "totvar", "theo1"), taus="octave", **kw) -> dict:
    """{kind: AllanResult} for several statistics of one record."""
    return {DEVIATION_NAMES.get(k, k): deviation(rate, dt, k, taus, **kw) for k in kinds}

