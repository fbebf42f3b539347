"""Stable32's equivalent degrees of freedom and bias corrections for the deviation family.

Stable32 (W. J. Riley, Hamilton Technical Services) gives each deviation a chi^2 interval from an edf
chosen by the statistic and by the power-law noise type alpha (S_y(f) ~ f^alpha: 2 white PM, 1 flicker
PM, 0 white FM, -1 flicker FM, -2 random-walk FM, -3 flicker-walk FM, -4 random-run FM) identified at
that tau (:mod:`avbench.estimators.allan.noise_id`). This module gives those edf and the bias factors of
the total variances and Theo1, so that ``deviation(..., intervals="stable32")`` prints Stable32's bounds.

* ADEV, OADEV, MDEV, TDEV, HDEV, OHDEV: the combined edf algorithm of Greenhall & Riley (2003, "Uncertainty
  of stability variances based on finite differences", 35th PTTI; SP1065 section 5.3 defers to it),
  :func:`greenhall_edf`: the phase modelled as the first difference of a continuous power-law process of
  generalized autocovariance

  .. math::

      s_w(t) = -|t|,\\ t^2\\ln|t|,\\ |t|^3,\\ -t^4\\ln|t|,\\ -|t|^5,\\ t^6\\ln|t|,\\ |t|^7 \\quad (\\alpha = 2 \\ldots -4),

  s_x(t) = F^2 [2 s_w(t) - s_w(t - 1/F) - s_w(t + 1/F)] (s_w of alpha + 2 for F = infinity), s_z the d-th
  binomial difference of s_x, and 1/edf = BasicSum(J, M, S, F) / (M s_z(0)^2) with
  BasicSum = s_z(0)^2 + 2 sum_{j=1}^{J-1} (1 - j/M) s_z(j/S)^2 + (1 - J/M) s_z(J/S)^2 (its eqs. 7-10):
  L = m/F + m d phases per term, M = 1 + floor(S (N - L) / m) terms, J = min(M, (d+1) S), r = M/S; d = 2
  (Allan) or 3 (Hadamard); F = m (unmodified) or 1 (modified); S = 1 (non-overlapping) or m (overlapping).
  For J > 100 the paper's asymptotic forms (1/r)(a0 - a1/r) with its Tables 1-3 (r >= d + 1) or the sum at
  m' = 100/r (r < d + 1). Stable32 stores the tables' a0, a1 of white PM and white FM to three decimals
  (0.667 for 2/3, 0.778 for 7/9 ...: Riley's CombinedEDF); so does this module, to print its bounds.
* TOTDEV (SP1065 Table 7, Howe & Greenhall 1997): edf = b (T/tau) - c with T/tau = N/m (N phases);
  Stable32 keeps the unrounded b, c: (1.500, 0), (1.16832, 0.222), (0.92715, 0.358) for white, flicker and
  random-walk FM (SP1065 prints 1.50, 1.17/0.22, 0.93/0.36). White and flicker PM: the total-variance fallback
  below.
* MTOTDEV and TTOTDEV: edf = b (N/m) - c. Stable32 departs from SP1065 Table 8 ((1.90, 2.10), (1.20,
  1.40), (1.10, 1.20), (0.85, 0.50), (0.75, 0.31) for alpha = 2 ... -2): it uses Howe's revised values
  (2.16, 2.28), (1.73, 2.99), (1.33, 1.89), (0.92, 0.76), (0.79, 0.37), and they are what its published
  PHASE.DAT intervals show (tests/test_deviations.py); avbench uses Stable32's.
* MTOTDEV and TTOTDEV below m = 9 (Riley's ModTotvarEDF "applies only for m > 8"): the MDEV edf, as
  PHASE.DAT's AF 1-8 rows show.
* HTOTDEV (Howe et al. 2000, 32nd PTTI): edf = (N/m) / (b0 + b1 m/N), (b0, b1) = (0.559, 1.004),
  (0.868, 1.140), (0.938, 1.696), (0.974, 2.554), (1.276, 3.149) for alpha = 0 ... -4, for m >= 16.
* The total-variance fallback, where those fits do not apply (TOTDEV at white and flicker PM; HTOTDEV below
  m = 16 and at white and flicker PM): the overlapping-AV edf of SP1065 Table 5 (NIST TN 1337 Table 12-4) for N
  phase points, plus 2:

  .. math::

      \\mathrm{edf} = 2 + \\begin{cases}
      (N+1)(N-2m) / (2(N-m)) & \\text{white PM} \\\\
      \\exp\\sqrt{\\ln\\frac{N-1}{2m}\\,\\ln\\frac{(2m+1)(N-1)}{4}} & \\text{flicker PM} \\\\
      \\left(\\frac{3(N-1)}{2m} - \\frac{2(N-2)}{N}\\right)\\frac{4m^2}{4m^2+5} & \\text{white FM} \\\\
      \\frac{2(N-2)^2}{2.3N-4.9}\\ (m=1),\\ \\frac{5N^2}{4m(N+3m)}\\ (m>1) & \\text{flicker FM} \\\\
      \\frac{N-2}{m(N-3)^2}\\left((N-1)^2 - 3m(N-1) + 4m^2\\right) & \\text{random-walk FM}
      \\end{cases}

  (Table 5's term taken as 1 where 2m = N, as CalcDegFree does). Source: W. J. Riley's edf program
  (github.com/k2hrt/edf): edf.c states that Stable32 "uses AVAR edf+2 for TOTVAR where TotvarEDF() doesn't
  apply"; edf4.c's CalcDegFree is the Table 5 edf above, and its HadTotvarEDF applies only to alpha = 0 ... -4.
  Stable32 does the same for HTOTVAR: its printed bounds on PHASE.DAT (HTOTDEV white FM at AF 1-8, flicker PM
  at AF 128 and 256) and on the BIPM Sr87 set of allantoolkit's tests (tests/assets/Sr87/phase: HTOTDEV
  flicker FM, random-walk FM and white FM below AF 16, flicker PM at AF 100; TOTDEV flicker PM at AF 100) are
  those of this edf to <= 4e-5 (the SP1065 Table 5 edf alone, or the OADEV edf of Greenhall's algorithm,
  misses the flicker-PM bounds by 0.1-1.4 %). HTOTDEV at flicker-walk and random-run FM below m = 16, which
  Table 5 does not cover: the OHDEV edf (no published Stable32 value to compare).
* Theo1 (Howe & Peppler 2003, "Estimation of very long-term frequency stability using a special-purpose
  statistic", EFTF/FCS), with r = 0.75 m and N phases:
  white PM 0.86 (N + 1)(N - 4r/3)/(N - r) * r/(r + 1.14); flicker PM (4.798 N^2 - 6.374 N r + 12.387 r)
  / (sqrt(r + 36.6)(N - r)) * r/(r + 0.3); white FM ((4.1 N + 0.8)/r - (3.1 N + 6.5)/N) r^1.5/(r^1.5 + 5.2);
  flicker FM (2 N^2 - 1.3 N r - 3.5 r)/(N r) r^3/(r^3 + 2.3); random-walk FM (4.4 N - 2)/(2.9 r)
  ((4.4 N - 1)^2 - 8.6 r (4.4 N - 1) + 11.4 r^2)/(4.4 N - 3)^2.

Intervals (:class:`Stable32Result`): chi^2 with the edf above, as SP1065 eq. 45, with two readings of
Stable32 that its printed PHASE.DAT bounds show (the tail probability each bound implies, over every row of
the ADEV ... TOTDEV tables): its "confidence factor 0.683" is the one-sigma probability erf(1/sqrt 2) =
0.6826895 (implied 0.68268 +- 0.00002 where edf <= 100), and where edf > 100 it takes the quantiles at the
confidence factor rounded to two decimals (0.68: tail probabilities 0.1600 and 0.8400, implied to +- 0.0002
in every such row), i.e. the approximate quantiles of its large-edf branch. avbench's own intervals
(``intervals="exact"``) use neither.

Bias corrections (Stable32's "bias-corrected" output, ``deviation(..., bias_corrected=True)``): the
variance is divided by its expected ratio to the AV (or MVAR):

* MTOTVAR and TTOTVAR / B, B = 0.94, 0.83, 0.73, 0.70, 0.69 for alpha = 2 ... -2 (Howe & Vernotte 1999;
  SP1065 section 5.2.11);
* HTOTVAR / (1 + a), a = -0.005, -0.149, -0.229, -0.283, -0.321 for alpha = 0 ... -4, m > 1 (Howe et al.
  2000; SP1065 section 5.2.12); none for the PM types;
* TOTVAR / (1 - a tau/T), a = 1/(3 ln 2) flicker FM, 3/4 random-walk FM (Howe 1999; SP1065 section 5.2.11),
  none for the others;
* Theo1: Stable32's default Theo1 output is bias-removed with one factor for the whole run, the fast
  TheoBR ratio k = mean_{i=0}^{n} AVAR(m = 9 + 3i) / Theo1(m = 12 + 4i) with n = floor(N/6 - 3) (what its
  printed values show; SP1065's TheoBR, Howe & Tasset 2004, averages n = floor(N/30 - 3) ratios): Theo1 * k; its noise
  type, one for the run, is the nominal Theo1 bias (AVAR/Theo1 = 0.4, 0.6, 1.0, 1.71, 2.24 for alpha = 2
  ... -2) nearest to k on a log scale (geometric-mean boundaries). PHASE.DAT's Stable32 Theo1 table is
  Theo1 * 0.602787 with alpha = 1 (tests/test_deviations.py).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from avbench.estimators.allan.variance import AllanResult

__all__ = ["ONE_SIGMA", "Stable32Result", "stable32_interval", "ALPHAS", "NOISE_ALPHA", "alpha_of", "greenhall_edf",
           "stable32_edf", "bias_factor", "theo1_nominal_bias", "theo1_noise_from_ratio", "theo1_bias_sizes"]

#: noise type name -> power-law exponent alpha of S_y(f)
NOISE_ALPHA = {"white_pm": 2, "flicker_pm": 1, "white_fm": 0, "flicker_fm": -1, "rw_fm": -2, "fw_fm": -3, "rr_fm": -4}
ALPHAS = tuple(sorted(NOISE_ALPHA.values(), reverse=True))
_J_MAX = 100
# Greenhall & Riley (2003) Tables 1 (modified) and 2 (unmodified): (a0, a1) by alpha (row 2 - alpha) and d (1-3),
# as Stable32 stores them; Table 3: (b0, b1) of flicker PM's logarithmic denominator by d
_T1 = np.array([[0.667, 0.333, 0.778, 0.500, 0.880, 0.667], [0.840, 0.345, 0.997, 0.616, 1.141, 0.843],
                [1.079, 0.368, 1.033, 0.607, 1.184, 0.848], [0.0, 0.0, 1.048, 0.534, 1.180, 0.816],
                [0.0, 0.0, 1.302, 0.535, 1.175, 0.777], [0.0, 0.0, 0.0, 0.0, 1.194, 0.703],
                [0.0, 0.0, 0.0, 0.0, 1.489, 0.702]])
_T2 = np.array([[1.500, 0.500, 1.944, 1.000, 2.310, 1.500], [78.60, 25.20, 790.0, 410.0, 9950.0, 6520.0],
                [0.667, 0.167, 0.667, 0.333, 0.778, 0.500], [0.0, 0.0, 0.852, 0.375, 0.997, 0.617],
                [0.0, 0.0, 1.079, 0.368, 1.033, 0.607], [0.0, 0.0, 0.0, 0.0, 1.053, 0.553],
                [0.0, 0.0, 0.0, 0.0, 1.302, 0.535]])
_T3 = np.array([[6.000, 4.000], [15.23, 12.00], [47.80, 40.00]])
#: the filter of each statistic in Greenhall's algorithm: (d, modified, overlapping)
GREENHALL_FILTER = {"avar": (2, False, False), "oavar": (2, False, True), "mvar": (2, True, True),
                    "tvar": (2, True, True), "hvar": (3, False, False), "ohvar": (3, False, True)}
_TOT = {0: (1.500, 0.0), -1: (1.16832, 0.222), -2: (0.92715, 0.358)}
_MTOT = {2: (2.16, 2.28), 1: (1.73, 2.99), 0: (1.33, 1.89), -1: (0.92, 0.76), -2: (0.79, 0.37)}
_HTOT = {0: (0.559, 1.004), -1: (0.868, 1.140), -2: (0.938, 1.696), -3: (0.974, 2.554), -4: (1.276, 3.149)}
_MTOT_BIAS = {2: 0.94, 1: 0.83, 0: 0.73, -1: 0.70, -2: 0.69}
_HTOT_BIAS = {0: -0.005, -1: -0.149, -2: -0.229, -3: -0.283, -4: -0.321}
_TOT_BIAS = {-1: 1.0 / (3.0 * math.log(2.0)), -2: 0.75}
_THEO1_NOMINAL = {2: 0.4, 1: 0.6, 0: 1.0, -1: 1.71, -2: 2.24}


#: the one-sigma probability erf(1/sqrt 2), Stable32's "confidence factor 0.683"
ONE_SIGMA = math.erf(1.0 / math.sqrt(2.0))


def stable32_interval(avar, edf, confidence):
    """(low, high) chi^2 bounds of the variance as Stable32 prints them (module docstring: 0.683 read as
    ``ONE_SIGMA``; above 100 degrees of freedom the confidence factor rounded to two decimals)."""
    from scipy.special import gammaincinv

    c = ONE_SIGMA if abs(float(confidence) - 0.683) < 5e-4 else float(confidence)
    edf = np.asarray(edf, dtype=float)
    cc = np.where(edf > 100, np.round(c, 2), c)
    a = (1.0 - cc) / 2.0
    half = np.where(edf > 0, edf / 2.0, np.nan)
    return edf * avar / (2.0 * gammaincinv(half, 1.0 - a)), edf * avar / (2.0 * gammaincinv(half, a))


@dataclass(frozen=True)
class Stable32Result(AllanResult):
    """An :class:`~avbench.estimators.allan.variance.AllanResult` whose edf and bounds are Stable32's.

    ``alpha`` holds the noise type of each tau (S_y ~ f^alpha) the edf (and a bias correction) used;
    ``bias`` the factor divided out of the statistic (1 where none; ``bias_corrected=False``: all 1);
    ``ci_low``, ``ci_high`` follow :func:`stable32_interval`.
    """

    alpha: np.ndarray | None = None
    bias: np.ndarray | None = None

    def _bounds(self):
        return stable32_interval(self.avar, self.edf, self.confidence)


def alpha_of(noise) -> np.ndarray:
    """The alpha of each noise type: a name of ``NOISE_ALPHA`` or an integer alpha in 2 ... -4."""
    out = []
    for v in np.atleast_1d(np.asarray(noise, dtype=object)).ravel():
        if isinstance(v, str):
            if v not in NOISE_ALPHA:
                raise ValueError(f"noise: expected one of {', '.join(NOISE_ALPHA)} or an integer alpha 2 ... -4, got {v!r}")
            out.append(NOISE_ALPHA[v])
        else:
            a = int(v)
            if a != v or a not in ALPHAS:
                raise ValueError(f"noise: expected an integer alpha in 2 ... -4 or a noise name, got {v!r}")
            out.append(a)
    return np.array(out, dtype=np.int64)


def _sw(t, alpha):
    """Generalized autocovariance s_w of the continuous power-law process (Greenhall & Riley 2003, eq. 7)."""
    b = np.abs(t)
    if alpha % 2 == 0:  # 2, 0, -2, -4: -|t|, |t|^3, -|t|^5, |t|^7
        return (-1.0) ** ((2 - alpha) // 2 + 1) * b ** (3 - alpha)
    lg = np.log(np.where(b > 0, b, 1.0))
    return (-1.0) ** ((1 - alpha) // 2) * b ** (3 - alpha) * lg  # 1, -1, -3: t^2 ln|t|, -t^4 ln|t|, t^6 ln|t|


def _sx(t, F, alpha):
    if math.isinf(F):
        return _sw(t, alpha + 2)
    return F * F * (2 * _sw(t, alpha) - _sw(t - 1.0 / F, alpha) - _sw(t + 1.0 / F, alpha))


def _sz(t, F, alpha, d):
    """The d-th binomial difference of s_x (Greenhall & Riley 2003, eq. 9)."""
    out = 0.0
    for k in range(-d, d + 1):
        out = out + (-1) ** k * math.comb(2 * d, d + k) * _sx(t + k, F, alpha)
    return out


def _basic_sum(J, M, S, F, alpha, d):
    """BasicSum (Greenhall & Riley 2003, eq. 10)."""
    j = np.arange(1, int(J), dtype=float)
    s0 = _sz(np.zeros(1), F, alpha, d)[0]
    mid = np.sum(2.0 * (1.0 - j / M) * _sz(j / S, F, alpha, d) ** 2) if j.size else 0.0
    last = (1.0 - J / M) * _sz(np.array([J / S]), F, alpha, d)[0] ** 2
    return s0 * s0 + mid + last


def _greenhall_one(alpha, d, m, N, modified, overlapping) -> float:
    F = 1 if modified else m
    S = m if overlapping else 1
    if alpha + 2 * d <= 1:
        raise ValueError(f"noise: alpha = {alpha} is not defined for a d = {d} variance (needs alpha + 2d > 1)")
    L = m // F + m * d
    if N < L:
        return float("nan")
    M = math.floor(S * (N - L) / m) + 1.0
    J = min(int(M), (d + 1) * S)
    r = M / S
    row, col = 2 - alpha, 2 * (d - 1)
    sz0 = lambda F_: _sz(np.zeros(1), F_, alpha, d)[0]  # noqa: E731
    if F == 1:  # case 1: modified variances (and unmodified at m = 1), every alpha
        if J <= _J_MAX:
            return sz0(1) ** 2 * M / _basic_sum(J, M, S, 1, alpha, d)
        if r >= d + 1:
            a0, a1 = _T1[row, col], _T1[row, col + 1]
            return 1.0 / ((a0 - a1 / r) / r)
        return sz0(1) ** 2 * _J_MAX / _basic_sum(_J_MAX, _J_MAX, _J_MAX / r, 1, alpha, d)
    if alpha <= 0:  # case 2: unmodified, white FM ... random-run FM
        if J <= _J_MAX:
            Fp = float(m) if m * (d + 1) <= _J_MAX else math.inf
            return sz0(Fp) ** 2 * M / _basic_sum(J, M, S, Fp, alpha, d)
        if r >= d + 1:
            a0, a1 = _T2[row, col], _T2[row, col + 1]
            return 1.0 / ((a0 - a1 / r) / r)
        return sz0(math.inf) ** 2 * _J_MAX / _basic_sum(_J_MAX, _J_MAX, _J_MAX / r, math.inf, alpha, d)
    if alpha == 1:  # case 3: unmodified, flicker PM
        b0, b1 = _T3[d - 1]
        if J <= _J_MAX:
            return sz0(float(m)) ** 2 * M / _basic_sum(J, M, S, float(m), 1, d)
        if r >= d + 1:
            a0, a1 = _T2[row, col], _T2[row, col + 1]
            return (b0 + b1 * math.log(m)) ** 2 * r / (a0 - a1 / r)
        return (b0 + b1 * math.log(m)) ** 2 * _J_MAX / _basic_sum(_J_MAX, _J_MAX, _J_MAX / r, _J_MAX / r, 1, d)
    # case 4: unmodified, white PM
    K = math.ceil(r)
    if K <= d:
        a0 = math.comb(2 * d, d)
        s = sum((1.0 - k / r) * math.comb(2 * d, d - k) ** 2 for k in range(1, K))
        return M / (1.0 + 2.0 * s / (a0 * a0))
    a0, a1 = _T2[0, col], _T2[0, col + 1]
    return M / (a0 - a1 / r)


def greenhall_edf(alpha, d: int, m, N: int, *, modified: bool, overlapping: bool) -> np.ndarray:
    """Greenhall & Riley's (2003) combined edf at each (alpha[j], m[j]) for N phase points (module docstring).

    Examples
    --------
    >>> [round(float(e), 2) for e in greenhall_edf(0, 2, [1, 16], 1001, modified=False, overlapping=True)]
    [782.03, 86.37]
    """
    alpha = np.atleast_1d(np.asarray(alpha, dtype=np.int64))
    m = np.atleast_1d(np.asarray(m, dtype=np.int64))
    alpha, m = np.broadcast_arrays(alpha, m)
    cache = {}
    out = np.empty(m.size)
    for j, (a, mi) in enumerate(zip(alpha.tolist(), m.tolist())):
        key = (a, mi)
        if key not in cache:
            cache[key] = _greenhall_one(a, d, mi, int(N), modified, overlapping)
        out[j] = cache[key]
    return out


def _table(coef: dict, alpha, what: str):
    try:
        return np.array([coef[int(a)] for a in alpha], dtype=float).reshape(-1, 2)
    except KeyError as e:
        raise ValueError(f"{what}: no edf for alpha = {e.args[0]}") from None


def _avar_table5(alpha: int, m: int, N: int) -> float:
    """SP1065 Table 5's overlapping-AV edf for N phase points (NIST TN 1337 Table 12-4 as corrected; Riley's
    CalcDegFree, Stable32's "AVAR edf"), alpha = 2 ... -2."""
    n, k = float(N), float(m)
    if alpha == 2:
        return 1.0 if 2 * m == N else (n + 1) * (n - 2 * k) / (2 * (n - k))
    if alpha == 1:
        if 2 * m == N:
            return 1.0
        return math.exp(math.sqrt(math.log((2 * k + 1) * (n - 1) / 4) * math.log((n - 1) / (2 * k))))
    if alpha == 0:
        return (3 * (n - 1) / (2 * k) - 2 * (n - 2) / n) * 4 * k * k / (4 * k * k + 5)
    if alpha == -1:
        return 2 * (n - 2) ** 2 / (2.3 * n - 4.9) if m == 1 else 5 * n * n / (4 * k * (n + 3 * k))
    return (n - 2) / (k * (n - 3) ** 2) * ((n - 1) ** 2 - 3 * k * (n - 1) + 4 * k * k)


def _by_case(size: int, cases) -> np.ndarray:
    """The edfs of ``size`` rows from ``cases``, ``[(mask, edf), ...]`` with disjoint masks covering the rows:
    ``edf(mask)`` gives the rows of each mask that holds any."""
    out = np.empty(size)
    for mask, edf in cases:
        if mask.any():
            out[mask] = edf(mask)
    return out


def _total_fallback(alpha, m, N: int) -> np.ndarray:
    """Stable32's edf of TOTVAR and HTOTVAR where their fits do not apply: the AV edf of SP1065 Table 5 plus 2
    (module docstring)."""
    return np.array([_avar_table5(int(a), int(k), N) + 2.0 for a, k in zip(alpha, m)])


def stable32_edf(kind: str, m, N: int, alpha) -> np.ndarray:
    """Stable32's edf of statistic ``kind`` at cluster sizes ``m`` for N phase points and noise ``alpha``.

    ``kind``: "avar" (non-overlapping AV), "oavar", "mvar", "tvar", "hvar", "ohvar", "totvar", "mtotvar",
    "ttotvar", "htotvar", "theo1", "theobr" (Theo1's edf). Module docstring for each formula.
    """
    m = np.atleast_1d(np.asarray(m, dtype=np.int64))
    alpha = np.broadcast_to(np.atleast_1d(np.asarray(alpha, dtype=np.int64)), m.shape)
    N = int(N)
    ratio = N / m.astype(float)
    if kind in GREENHALL_FILTER:
        d, modified, overlapping = GREENHALL_FILTER[kind]
        return greenhall_edf(alpha, d, m, N, modified=modified, overlapping=overlapping)

    def linear(coef):  # edf = b (N/m) - c, (b, c) from a table by alpha
        def edf(i):
            bc = _table(coef, alpha[i], kind)
            return bc[:, 0] * ratio[i] - bc[:, 1]
        return edf

    def fallback(i):
        return _total_fallback(alpha[i], m[i], N)

    def other(name):
        return lambda i: stable32_edf(name, m[i], N, alpha[i])

    if kind == "totvar":
        fm, pm = np.isin(alpha, list(_TOT)), alpha > 0
        return _by_case(m.size, [(fm, linear(_TOT)), (pm, fallback), (~fm & ~pm, other("oavar"))])
    if kind in ("mtotvar", "ttotvar"):
        small = m <= 8
        return _by_case(m.size, [(small, other("mvar")), (~small, linear(_MTOT))])
    if kind == "htotvar":
        total = (m >= 16) & np.isin(alpha, list(_HTOT))
        table5 = ~total & (alpha >= -2)

        def htot(i):
            b = _table(_HTOT, alpha[i], kind)
            return ratio[i] / (b[:, 0] + b[:, 1] / ratio[i])

        return _by_case(m.size, [(total, htot), (table5, fallback), (~total & ~table5, other("ohvar"))])
    out = np.empty(m.size)
    if kind in ("theo1", "theobr"):
        r = 0.75 * m.astype(float)
        n = float(N)
        for j, (a, rj) in enumerate(zip(alpha.tolist(), r.tolist())):
            if a == 2:
                e = 0.86 * (n + 1) * (n - 4.0 * rj / 3.0) / (n - rj) * rj / (rj + 1.14)
            elif a == 1:
                e = (4.798 * n * n - 6.374 * n * rj + 12.387 * rj) / (math.sqrt(rj + 36.6) * (n - rj)) * rj / (rj + 0.3)
            elif a == 0:
                e = ((4.1 * n + 0.8) / rj - (3.1 * n + 6.5) / n) * rj**1.5 / (rj**1.5 + 5.2)
            elif a == -1:
                e = (2 * n * n - 1.3 * n * rj - 3.5 * rj) / (n * rj) * rj**3 / (rj**3 + 2.3)
            elif a == -2:
                e = (4.4 * n - 2) / (2.9 * rj) * ((4.4 * n - 1) ** 2 - 8.6 * rj * (4.4 * n - 1) + 11.4 * rj * rj) / (4.4 * n - 3) ** 2
            else:
                raise ValueError(f"{kind}: no edf for alpha = {a}")
            out[j] = e
        return out
    raise ValueError(f"kind: no Stable32 edf for {kind!r}")


def bias_factor(kind: str, m, N: int, alpha) -> np.ndarray:
    """E[statistic] / (the AV or MVAR it estimates) for noise ``alpha`` (module docstring); 1 where none.

    Stable32's bias-corrected value is the statistic divided by this factor (Theo1: see ``theo1_bias_sizes``).
    """
    m = np.atleast_1d(np.asarray(m, dtype=np.int64))
    alpha = np.broadcast_to(np.atleast_1d(np.asarray(alpha, dtype=np.int64)), m.shape)
    out = np.ones(m.size)
    for j, (a, mi) in enumerate(zip(alpha.tolist(), m.tolist())):
        if kind in ("mtotvar", "ttotvar"):
            out[j] = _MTOT_BIAS.get(a, 1.0)
        elif kind == "htotvar" and mi > 1:
            out[j] = 1.0 + _HTOT_BIAS.get(a, 0.0)
        elif kind == "totvar":
            out[j] = 1.0 - _TOT_BIAS.get(a, 0.0) * mi / N
    return out


def theo1_nominal_bias(alpha) -> np.ndarray:
    """Nominal AVAR/Theo1 ratio of each noise type (0.4, 0.6, 1.0, 1.71, 2.24 for alpha = 2 ... -2)."""
    return np.array([_THEO1_NOMINAL[int(a)] for a in np.atleast_1d(alpha)])


def theo1_noise_from_ratio(k: float) -> int:
    """The alpha whose nominal AVAR/Theo1 ratio is nearest to ``k`` on a log scale (geometric-mean boundaries)."""
    alphas = sorted(_THEO1_NOMINAL, reverse=True)  # 2, 1, 0, -1, -2: increasing nominal ratio
    for hi, lo in zip(alphas[:-1], alphas[1:]):
        if k < math.sqrt(_THEO1_NOMINAL[hi] * _THEO1_NOMINAL[lo]):
            return hi
    return alphas[-1]


def theo1_bias_sizes(N: int):
    """(AV m = 9 + 3i, Theo1 m = 12 + 4i), i = 0 ... floor(N/6 - 3): Stable32's fast TheoBR ratio (Taylor & Howe)."""
    n = int(math.floor(N / 6 - 3))
    if n < 0:
        raise ValueError(f"theo1: its bias ratio needs N >= 18 phase points, got N = {N}")
    i = np.arange(n + 1, dtype=np.int64)
    return 9 + 3 * i, 12 + 4 * i
