"""The Allan-variance engine: batch (overlapping or not), streaming, and recursive.

Definitions (Lv et al. 2015, eqs 1-2; IEEE Std 952 Annex C). With S_k = sum of the first k rate
samples (S_0 = 0), the cluster sum of m samples starting at index i is S_{i+m} - S_i, and

* non-overlapping: J = floor(n/m) clusters with means w_j; sigma^2 = sum (w_{j+1} - w_j)^2 / (2(J-1));
* fully overlapping (allantools ``oadev``):
  sigma^2 = sum_{k=0}^{n-2m} (S_{k+2m} - 2S_{k+m} + S_k)^2 / (2 m^2 (n - 2m + 1)).

Both come from one cumulative sum; there is no Python loop over samples (only over tau values).
Each value carries its cluster count J, the relative 1-sigma error of the Allan *deviation* of
Lv et al. 2015 eq. 8, 1/sqrt(2(J-1)), and an equivalent number of degrees of freedom (edf) with a
chi^2 confidence interval: for the overlapping estimator the edf of NIST SP 1065 Table 5 (Howe,
Allan & Barnes) for the noise type, identified per tau from the local slope of the AV curve unless
given; for the non-overlapping estimator edf = J - 1 (the white-noise value behind eq. 8).
"""

from __future__ import annotations

import contextlib
import math
import threading
from dataclasses import dataclass

import numpy as np

from avbench.estimators.allan import _kernels
from avbench.estimators.validation import check_record, check_taus

__all__ = [
    "AllanResult",
    "allan_variance",
    "cluster_sizes",
    "edf_overlapping",
    "StreamingAllan",
    "RecursiveAllan",
    "recursive_avar",
    "memoize_allan",
    "allan_variance_gaps",
    "skip_gaps",
]

NOISE_TYPES = ("white_pm", "white_fm", "flicker_fm", "rw_fm")
_SLOPE_OF = {"white_pm": -2, "white_fm": -1, "flicker_fm": 0, "rw_fm": 1}


@dataclass(frozen=True)
class AllanResult:
    """Allan variance at a set of cluster sizes, with its uncertainty.

    Attributes
    ----------
    tau, m, avar, adev : ndarray
        Averaging time (s), cluster size (samples), Allan variance (rad^2/s^2), deviation (rad/s).
    J : ndarray of int
        Number of clusters floor(n/m).
    rel_error : ndarray
        Relative 1-sigma error of the Allan deviation, 1/sqrt(2(J-1)) (Lv et al. 2015, eq. 8).
    edf : ndarray
        Equivalent degrees of freedom of the AV value (Var(avar) ~ 2 avar^2 / edf).
    ci_low, ci_high : ndarray
        chi^2 interval of the AV with probability ``confidence`` (default 0.683, "1 sigma");
        computed on first access.
    overlapping : bool
    n_samples : int
    dt : float
    """

    tau: np.ndarray
    m: np.ndarray
    avar: np.ndarray
    J: np.ndarray
    rel_error: np.ndarray
    edf: np.ndarray
    overlapping: bool
    n_samples: int
    dt: float
    confidence: float = 0.683
    #: the statistic held in ``avar``: "avar"/"oavar" here; "ohvar", "mvar", "tvar", "totvar",
    #: "theo1" from :func:`avbench.estimators.allan.deviations.deviation` (one result type for all)
    kind: str = "avar"

    @property
    def adev(self) -> np.ndarray:
        return np.sqrt(self.avar)

    @property
    def deviation(self) -> np.ndarray:
        """Square root of the statistic (rad/s; tvar: rad)."""
        return np.sqrt(self.avar)

    @property
    def ci_low(self) -> np.ndarray:
        return self._bounds()[0]

    @property
    def ci_high(self) -> np.ndarray:
        return self._bounds()[1]

    def _bounds(self):
        """(low, high) of the chi^2 interval at ``confidence`` (a subclass states its own rule here)."""
        return _interval(self.avar, self.edf, self.confidence)

    @property
    def variance(self) -> np.ndarray:
        """Approximate variance of each AV value, 2 avar^2 / edf."""
        return 2 * self.avar**2 / self.edf

    def to_frame(self) -> pd.DataFrame:
        import pandas as pd

        return pd.DataFrame(
            {
                "tau": self.tau,
                "m": self.m,
                "J": self.J,
                "avar": self.avar,
                "adev": self.adev,
                "rel_error": self.rel_error,
                "edf": self.edf,
                "ci_low": self.ci_low,
                "ci_high": self.ci_high,
            }
        )

    def __len__(self) -> int:
        return len(self.tau)


def cluster_sizes(taus, n: int, dt: float, points_per_decade: int = 10) -> np.ndarray:
    """Cluster sizes m for a tau specification and a record of ``n`` samples (m <= n // 2).

    ``taus`` is "octave" (m = 1, 2, 4, ...), "decade" (``points_per_decade`` log-spaced m per
    decade, rounded, unique), "all" (every m from 1 to n // 2), or an array of tau in seconds
    (each a multiple of dt, at most n dt / 2).
    """
    mmax = n // 2
    if mmax < 1:
        raise ValueError(f"record too short: {n} samples give no Allan variance (need at least 2)")
    if isinstance(taus, str):
        if taus == "octave":
            return 2 ** np.arange(int(math.floor(math.log2(mmax))) + 1, dtype=np.int64)
        if taus == "decade":
            k = int(points_per_decade)
            if k < 1:
                raise ValueError(f"points_per_decade: expected a positive integer, got {points_per_decade!r}")
            grid = np.unique(np.rint(10 ** (np.arange(0, math.log10(mmax) * k + 1) / k)).astype(np.int64))
            return grid[(grid >= 1) & (grid <= mmax)]
        if taus == "all":
            return np.arange(1, mmax + 1, dtype=np.int64)
        raise ValueError(f"taus: expected 'octave', 'decade', 'all' or an array of seconds, got {taus!r}")
    check_taus(taus)
    tau = np.asarray(taus, dtype=float)
    if tau.ndim != 1 or tau.size == 0 or not np.all(np.isfinite(tau)):
        raise ValueError(f"taus: expected a non-empty 1-D array of finite seconds, got {taus!r}")
    m = np.rint(tau / dt)
    if np.any(m < 1) or np.any(np.abs(m * dt - tau) > 1e-6 * tau):
        raise ValueError(f"taus: expected positive multiples of dt = {dt} s, got {tau!r}")
    if np.any(m > mmax):
        raise ValueError(
            f"taus: {tau[m > mmax].tolist()} s exceed half the record ({n} samples x {dt} s / 2 = "
            f"{mmax * dt} s); the record is too short for them"
        )
    return m.astype(np.int64)


def edf_overlapping(m, n: int, noise) -> np.ndarray:
    """EDF of the overlapping AV (NIST SP 1065, Table 5) for ``n`` rate samples (N = n + 1 phases).

    ``noise`` is one of "white_pm" (quantization), "white_fm" (ARW), "flicker_fm" (bias
    instability), "rw_fm" (RRW), or an array of those, one per m.
    """
    m = np.asarray(m, dtype=float)
    N = float(n + 1)
    noise = np.broadcast_to(np.asarray(noise, dtype=object), m.shape)
    out = np.empty_like(m)
    for i, (mi, kind) in enumerate(zip(m, noise)):
        if kind == "white_pm":
            e = (N + 1) * (N - 2 * mi) / (2 * (N - mi))
        elif kind == "white_fm":
            e = (3 * (N - 1) / (2 * mi) - 2 * (N - 2) / N) * 4 * mi**2 / (4 * mi**2 + 5)
        elif kind == "flicker_fm":  # m = 1: (N-2) squared, as in SP 1065 (a copy without it gives edf < 1 for any N)
            e = 2 * (N - 2) ** 2 / (2.3 * N - 4.9) if mi == 1 else 5 * N**2 / (4 * mi * (N + 3 * mi))
        elif kind == "rw_fm":
            e = (N - 2) / (mi * (N - 3) ** 2) * ((N - 1) ** 2 - 3 * mi * (N - 1) + 4 * mi**2)
        else:
            raise ValueError(f"noise: expected one of {NOISE_TYPES}, got {kind!r}")
        out[i] = e
    return np.maximum(out, 1.0)


def _noise_codes_from_slope(tau, avar, J) -> np.ndarray:
    """Noise type per tau from the local log-log slope of the AV (rounded to -2, -1, 0, +1), as codes 0..3
    (white PM, white FM, flicker FM, random-walk FM: the slope + 2).

    The slope is only trusted where the AV values are precise (J >= 16 clusters); beyond, each tau
    takes the type identified at the longest trusted tau (a noisy tail would otherwise pass for
    quantization noise and get an absurdly large edf). The slope is NumPy's ``gradient`` of the
    logarithms (``_kernels.noise_codes_from_slope``, tested equal to it); a non-finite one (an
    overflowed AV) counts as white FM.
    """
    out = np.full(len(tau), 1, dtype=np.int64)
    good = np.flatnonzero(J >= 16)
    if len(good) < 2:
        return out
    g = good
    with np.errstate(invalid="ignore", divide="ignore"):
        codes = _kernels.noise_codes_from_slope(np.log(tau[g]), np.log(np.maximum(avar[g], np.finfo(float).tiny)))
    out[g] = codes
    out[g[-1] + 1 :] = codes[-1]
    return out


#: noise type names by code (``_noise_codes_from_slope``)
NOISE_NAMES = np.array(sorted(_SLOPE_OF, key=_SLOPE_OF.get), dtype=object)


def _noise_from_slope(tau, avar, J) -> np.ndarray:
    """Noise type names per tau (``_noise_codes_from_slope``)."""
    return NOISE_NAMES[_noise_codes_from_slope(tau, avar, J)]


def _interval(avar, edf, confidence):
    # chi^2 quantiles as scipy.stats.chi2.ppf computes them (2 gammaincinv(edf / 2, q): the same bits,
    # nan where edf <= 0 too), without importing scipy.stats (~0.3 s of every process that draws a figure)
    from scipy.special import gammaincinv

    a = (1 - confidence) / 2
    edf = np.asarray(edf, dtype=float)
    half = np.where(edf > 0, edf / 2, np.nan)
    lo = edf * avar / (2 * gammaincinv(half, 1 - a))
    hi = edf * avar / (2 * gammaincinv(half, a))
    return lo, hi


def _result(m, avar, n, dt, overlapping, noise, confidence) -> AllanResult:
    m = np.asarray(m, dtype=np.int64)
    J = n // m
    tau = m * dt
    with np.errstate(divide="ignore"):
        rel = 1.0 / np.sqrt(2.0 * (J - 1))
    if overlapping:
        kinds = _noise_from_slope(tau, avar, J) if noise == "auto" else noise
        edf = edf_overlapping(m, n, kinds)
    else:
        edf = np.maximum(J - 1, 1).astype(float)
    return AllanResult(tau, m, avar, J, rel, edf, overlapping, n, dt, confidence)


def allan_variance(
    rate,
    dt,
    taus="octave",
    overlapping: bool = True,
    *,
    points_per_decade: int = 10,
    noise="auto",
    confidence: float = 0.683,
) -> AllanResult:
    """Allan variance of a rate record.

    .. math::

        \\sigma^2(\\tau_m) = \\frac{1}{2(J-1)}\\sum_{k=1}^{J-1}(\\bar\\omega_{k+1} - \\bar\\omega_k)^2
        \\quad\\text{(Lv et al. 2015, eq. 2; non-overlapping)}

    and its fully overlapping form (IEEE Std 952 Annex C; allantools ``oadev`` squared).

    Parameters
    ----------
    rate : array_like
        Rate samples (rad/s), 1-D, finite.
    dt : float
        Sample interval (s).
    taus : "octave", "decade", "all" or array of seconds
        See :func:`cluster_sizes`.
    overlapping : bool
        Fully overlapping (default) or non-overlapping clusters.
    noise : "auto" or noise-type name(s)
        Noise type for the overlapping edf (see :func:`edf_overlapping`); "auto" identifies it per
        tau from the local slope of the AV curve.
    confidence : float
        Probability of the chi^2 interval ``ci_low``..``ci_high``.

    Examples
    --------
    >>> import numpy as np
    >>> x = np.random.default_rng(0).standard_normal(100_000)  # white: AV = 1/m at dt = 1
    >>> r = allan_variance(x, 1.0, taus=[1.0, 10.0])
    >>> bool(np.all(np.abs(r.avar * r.m - 1) < 0.05))
    True
    """
    gaps = getattr(_GAPS, "table", None)
    if gaps:
        hit = gaps.get(id(rate))
        if hit is not None and hit[0] is rate:
            return allan_variance_gaps(rate, dt, hit[1], taus, overlapping, points_per_decade=points_per_decade,
                                       noise=noise, confidence=confidence)
    memo = getattr(_MEMO, "table", None)
    if memo is not None:
        key = _memo_key(rate, dt, taus, overlapping, points_per_decade, noise, confidence)
        hit = memo.get(key)
        if hit is not None and hit[0] is rate:
            return hit[1]
    result = _allan_variance(rate, dt, taus, overlapping, points_per_decade, noise, confidence)
    if memo is not None and key is not None:
        memo[key] = (rate, result)  # the reference keeps id(rate) from being reused meanwhile
    return result


_MEMO = threading.local()


@contextlib.contextmanager
def memoize_allan():
    """Within this block, :func:`allan_variance` of the *same array object* is computed once.

    Several estimators fitted to one record (a Monte Carlo replicate) often ask for the same AV
    curve; the study runner enables this per replicate so that the curve is computed once and the
    same :class:`AllanResult` is shared. The key is (id(rate), dt, taus, overlapping, options) and
    the cached entry holds a reference to the array, so an id cannot be reused while the block is
    open. Do not modify the array (or the returned result) inside the block.
    """
    prev = getattr(_MEMO, "table", None)
    _MEMO.table = {}
    try:
        yield
    finally:
        _MEMO.table = prev


def memoized(rate, key, compute):
    """``compute()``, computed once per array object ``rate`` and ``key`` within :func:`memoize_allan`
    (every call outside it computes): e.g. the standardised copy of a replicate that
    :meth:`avbench.estimators.base.Estimator.fit` hands each estimator, so that they share it and
    its Allan variance."""
    memo = getattr(_MEMO, "table", None)
    if memo is None or not isinstance(rate, np.ndarray):
        return compute()
    k = ("memoized", id(rate), key)
    hit = memo.get(k)
    if hit is not None and hit[0] is rate:
        return hit[1]
    value = compute()
    memo[k] = (rate, value)  # the reference keeps id(rate) from being reused meanwhile
    return value


def _memo_key(rate, dt, taus, overlapping, points_per_decade, noise, confidence):
    if not isinstance(rate, np.ndarray):
        return None
    if isinstance(taus, str):
        tkey = taus
    else:
        try:
            tkey = ("array", np.asarray(taus, dtype=float).tobytes())
        except (TypeError, ValueError):
            return None
    nkey = noise if isinstance(noise, str) else ("array", tuple(np.ravel(np.asarray(noise, dtype=object)).tolist()))
    try:
        return (id(rate), rate.shape, float(dt), tkey, bool(overlapping), points_per_decade, nkey, float(confidence))
    except (TypeError, ValueError):
        return None


def _checked_record_and_mean(rate, dt):
    """``check_record`` with the finiteness test folded into the mean's compiled pass.

    For a 1-D float64 record the sum (one read-only pass) is finite exactly when every sample is
    finite (barring overflow near 1e308, which falls back to the full check): no boolean
    temporary and no separate mean pass. Anything else goes through :func:`check_record`.
    """
    fast = _record_rules(rate, dt)
    if fast is not None:
        total = _kernels.finite_sum(fast[0])
        if math.isfinite(total):
            return fast[0], fast[1], total / fast[0].size
    rate, dt = check_record(rate, dt)
    return rate, dt, _kernels.finite_sum(rate) / rate.size


def _record_rules(rate, dt):
    """(record, dt) of a 1-D float64 ndarray of >= 16 samples after every rule of ``check_record`` but
    finiteness, which the caller's own compiled pass over the record tests (a non-finite sum: then
    ``check_record`` names the bad sample); None for anything else (``check_record`` then does it all)."""
    if isinstance(rate, np.ndarray) and rate.dtype == np.float64 and rate.ndim == 1 and rate.size >= 16:
        _, dt = check_record(rate[:16], dt)  # dt and the record's shape/dtype rules
        return rate, dt
    return None


_SCRATCH = threading.local()
#: the cumulative-sum buffer of the last call is kept (per thread) for records up to this length
#: (64 MB), so that repeated calls on same-length records (Monte Carlo) reuse it
_SCRATCH_MAX = 1 << 23


def _cumsum_buffer(n1: int) -> np.ndarray:
    if n1 > _SCRATCH_MAX:
        return np.empty(n1)
    buf = getattr(_SCRATCH, "S", None)
    if buf is None or buf.size < n1:
        buf = _SCRATCH.S = np.empty(n1)
    return buf[:n1]


def _allan_variance(rate, dt, taus, overlapping, points_per_decade, noise, confidence) -> AllanResult:
    rate, dt, mean = _checked_record_and_mean(rate, dt)
    n = rate.size
    m = cluster_sizes(taus, n, dt, points_per_decade)
    # removing the mean changes no AV value (second differences kill it) but keeps S small
    S = _kernels.centred_cumsum(rate, mean, _cumsum_buffer(n + 1))
    mf = m.astype(float)
    if overlapping:
        av = _kernels.oavar_sums(S, m) / (2.0 * mf * mf * (n - 2 * mf + 1))
    else:
        av = _kernels.avar_sums(S, m) / (2.0 * mf * mf * (n // m - 1))
    return _result(m, av, n, dt, overlapping, noise, confidence)


def _segment_starts(starts, n: int) -> np.ndarray:
    s = np.asarray(starts)
    if s.size == 0:
        s = s.astype(np.int64)
    if s.ndim != 1 or s.dtype.kind not in "iu":
        raise ValueError(f"starts: expected a 1-D array of sample indices, got {starts!r}")
    s = np.unique(np.concatenate(([0], s.astype(np.int64))))
    if s[-1] >= n or s[0] < 0:
        raise ValueError(f"starts: expected indices in 0..{n - 1}, got {starts!r}")
    return s


def allan_variance_gaps(
    rate,
    dt,
    starts,
    taus="octave",
    overlapping: bool = True,
    *,
    points_per_decade: int = 10,
    noise="auto",
    confidence: float = 0.683,
) -> AllanResult:
    r"""Allan variance of a record with gaps: clusters that straddle a gap are left out.

    The record is the concatenation of gap-free runs of uniformly sampled data; run ``i`` starts
    at sample ``starts[i]`` (0 is implied) and ends where the next begins. Within each run the sums
    are those of :func:`allan_variance`; they are pooled over the runs that hold at least ``2m``
    samples, and only the differences whose clusters all lie in one run count:

    .. math::

        \sigma^2(\tau_m) = \frac{\sum_i \sum_{k=0}^{n_i-2m} (S^{(i)}_{k+2m} - 2S^{(i)}_{k+m}
        + S^{(i)}_k)^2}{2 m^2 \sum_i (n_i - 2m + 1)}

        (overlapping; IEEE Std 952 Annex C per run), and for the non-overlapping form the
        sum over runs of the squared differences of adjacent cluster means in each run over
        ``2 \sum_i (J_i - 1)`` (Lv et al. 2015, eq. 2 per run).

    Uncertainty counts only the clusters used: ``J = 1 + sum_i (J_i - 1)`` with
    ``J_i = floor(n_i/m)`` over the runs used (so ``rel_error = 1/sqrt(2(J-1))`` as in
    Lv et al. 2015, eq. 8), and the edf is that of the pooled mean of independent runs,
    ``1 / sum_i (w_i^2 / edf_i)`` with weights ``w_i`` = the run's share of the terms (Satterthwaite)
    and ``edf_i`` the NIST SP 1065 Table 5 value of run ``i`` (overlapping) or ``J_i - 1``
    (non-overlapping). With a single run this is exactly :func:`allan_variance`.
    The tau grid is that of the longest run.

    Parameters
    ----------
    rate : array_like
        The gap-free runs, concatenated (rad/s).
    dt : float
        Sample interval within the runs (s).
    starts : array_like of int
        Index of the first sample of each run (0 may be omitted).
    taus, overlapping, points_per_decade, noise, confidence
        As for :func:`allan_variance`.

    Examples
    --------
    >>> import numpy as np
    >>> x = np.random.default_rng(0).standard_normal(100_000)
    >>> a = allan_variance_gaps(x, 1.0, [30_000, 70_000], taus=[1.0, 10.0])
    >>> bool(np.all(np.abs(a.avar * a.m - 1) < 0.05))
    True
    """
    rate, dt, mu = _checked_record_and_mean(rate, dt)  # the same centring as allan_variance
    n = rate.size
    s = _segment_starts(starts, n)
    ends = np.append(s[1:], n)
    lengths = ends - s
    m = cluster_sizes(taus, int(lengths.max()), dt, points_per_decade)
    mf = m.astype(float)
    sums = np.zeros(m.size)
    terms = np.zeros((s.size, m.size))  # number of squared differences of each run at each m
    used = []
    buf = np.empty(int(lengths.max()) + 1)
    for i, (a, L) in enumerate(zip(s, lengths)):
        ok = 2 * m <= L
        if not ok.any():
            continue
        used.append(i)
        S = _kernels.centred_cumsum(rate[a : a + L], mu, buf[: L + 1])
        mm = m[ok]
        if overlapping:
            sums[ok] += _kernels.oavar_sums(S, mm)
            terms[i, ok] = L - 2 * mm + 1
        else:
            sums[ok] += _kernels.avar_sums(S, mm)
            terms[i, ok] = L // mm - 1
    count = terms.sum(axis=0)
    av = sums / (2.0 * mf * mf * count)
    Ji = np.where(terms > 0, lengths[:, None] // m[None, :], 0)
    J = 1 + np.where(terms > 0, Ji - 1, 0).sum(axis=0)
    with np.errstate(divide="ignore"):
        rel = 1.0 / np.sqrt(2.0 * (J - 1))
    tau = m * dt
    if overlapping:
        kinds = _noise_from_slope(tau, av, J) if noise == "auto" else np.broadcast_to(np.asarray(noise, dtype=object), m.shape)
        inv = np.zeros(m.size)
        for i in used:
            ok = terms[i] > 0
            w = terms[i, ok] / count[ok]
            inv[ok] += w * w / edf_overlapping(m[ok], int(lengths[i]), np.asarray(kinds, dtype=object)[ok])
        edf = 1.0 / inv
    else:
        edf = np.maximum(J - 1, 1).astype(float)
    return AllanResult(tau, m, av, J.astype(np.int64), rel, edf, overlapping, n, dt, confidence)


_GAPS = threading.local()


@contextlib.contextmanager
def skip_gaps(rate, starts):
    """Within this block, :func:`allan_variance` of the *same array object* ``rate`` is
    :func:`allan_variance_gaps` with these run ``starts``.

    This lets every estimator that works on the Allan variance fit a record with gaps unchanged:
    ``with skip_gaps(x, starts): est.fit(x, dt)``. Estimators that work on the samples themselves
    (likelihood, filters) do not see the gaps; fit them on a gap-free run instead.
    """
    prev = getattr(_GAPS, "table", None)
    table = dict(prev or {})
    table[id(rate)] = (rate, np.asarray(starts))
    _GAPS.table = table
    try:
        yield
    finally:
        _GAPS.table = prev


def gap_starts(rate):
    """The run starts :func:`skip_gaps` registered for this very array object, or None."""
    hit = (getattr(_GAPS, "table", None) or {}).get(id(rate))
    return hit[1] if hit is not None and hit[0] is rate else None


def _oavar_sums_numpy(S, m):
    """Reference for the compiled kernel (tests only)."""
    out = np.empty(len(m))
    for i, mi in enumerate(m):
        d = S[2 * mi :] - 2 * S[mi:-mi] + S[: -2 * mi]
        out[i] = np.dot(d, d)
    return out


def _avar_sums_numpy(S, m):
    """Reference for the compiled kernel (tests only)."""
    n = S.size - 1
    out = np.empty(len(m))
    for i, mi in enumerate(m):
        d = np.diff(np.diff(S[: (n // mi) * mi + 1 : mi]))
        out[i] = np.dot(d, d)
    return out


class StreamingAllan:
    """Non-overlapping Allan variance at octave cluster sizes, fed chunk by chunk.

    Memory is O(number of octaves), whatever the record length: each level m = 2^j keeps the sum and
    count of its open cluster, the previous cluster mean, and the running sum of squared
    differences. ``result()`` equals ``allan_variance(record, dt, "octave", overlapping=False)``
    up to rounding.

    Parameters
    ----------
    dt : float
        Sample interval (s).
    n_octaves : int
        Levels m = 1, 2, ..., 2^(n_octaves - 1) (default 40: more than any record needs).

    Examples
    --------
    >>> import numpy as np
    >>> x = np.random.default_rng(1).standard_normal(10_000)
    >>> acc = StreamingAllan(dt=0.01)
    >>> for chunk in np.array_split(x, 7):
    ...     acc.update(chunk)
    >>> one = allan_variance(x, 0.01, "octave", overlapping=False)
    >>> bool(np.allclose(acc.result().avar, one.avar, rtol=1e-9))
    True
    """

    def __init__(self, dt, n_octaves: int = 40):
        _, self.dt = check_record(np.zeros(16), dt)
        if not isinstance(n_octaves, int) or n_octaves < 1:
            raise ValueError(f"n_octaves: expected a positive integer, got {n_octaves!r}")
        self.m = 2 ** np.arange(n_octaves, dtype=np.int64)
        L = n_octaves
        self.n = 0
        self.offset = None  # subtracted from every sample (AV-invariant) to keep sums small
        self.pending = np.zeros(L)  # level j: a completed level-(j-1) cluster sum awaiting its pair
        self.has_pending = np.zeros(L, dtype=np.bool_)
        self.prev = np.zeros(L)  # previous complete cluster mean (valid where ndiff or has_prev)
        self.has_prev = np.zeros(L, dtype=np.bool_)
        self.ssq = np.zeros(L)  # sum of squared differences of adjacent means
        self.ndiff = np.zeros(L, dtype=np.int64)

    def update(self, chunk) -> None:
        """Add the next samples: one compiled pass, cluster sums of level j+1 from pairs of level j."""
        x = np.asarray(chunk, dtype=np.float64)
        if x.ndim != 1:
            raise ValueError(f"chunk: expected a 1-D array, got shape {x.shape}")
        if x.size == 0:
            return
        if not np.all(np.isfinite(x)):
            raise ValueError(f"chunk: non-finite sample(s) after {self.n} samples")
        if self.offset is None:
            self.offset = float(x.mean())
        _kernels.streaming_octaves(
            x, self.offset, self.pending, self.has_pending, self.prev, self.has_prev, self.ssq, self.ndiff
        )
        self.n += x.size

    def result(self, confidence: float = 0.683) -> AllanResult:
        ok = self.ndiff >= 1
        if not ok.any():
            raise ValueError(f"StreamingAllan: {self.n} samples give no Allan variance yet (need 2)")
        m = self.m[ok]
        av = self.ssq[ok] / (2.0 * self.ndiff[ok])
        return _result(m, av, self.n, self.dt, False, "auto", confidence)


def recursive_avar(rate, m: int = 1) -> np.ndarray:
    """The recursive Allan variance of Miao et al. 2014, eqs 3.3-3.4, for a whole record at once.

    .. math::

        \\delta_k^2(m) = \\frac{k-2}{k-1}\\delta_{k-1}^2(m)
                        + \\frac{1}{2(k-1)}(\\bar w_k(m) - \\bar w_{k-1}(m))^2,\\quad \\delta_1^2 = 0

    i.e. the running mean of half the squared differences of adjacent cluster means. Returns
    delta_k^2 for k = 2, ..., floor(n/m) (one value per completed cluster after the first).
    """
    x = np.asarray(rate, dtype=np.float64)
    if x.ndim != 1:
        raise ValueError(f"rate: expected a 1-D array, got shape {x.shape}")
    if not isinstance(m, int | np.integer) or m < 1:
        raise ValueError(f"m: expected a positive integer cluster size, got {m!r}")
    J = x.size // m
    if J < 2:
        return np.empty(0)
    means = x[: J * m].reshape(J, m).mean(axis=1)
    d2 = np.diff(means) ** 2 / 2
    return np.cumsum(d2) / np.arange(1, J)


class RecursiveAllan:
    """Streaming form of :func:`recursive_avar`: constant memory, state carried across chunks.

    ``update(chunk)`` returns delta_k^2 for every cluster completed within the chunk (k >= 2);
    concatenating the returns over chunks equals ``recursive_avar(record, m)`` up to rounding.
    ``value`` is the current delta_k^2 (0 before two clusters are complete).
    """

    def __init__(self, m: int = 1):
        if not isinstance(m, int | np.integer) or m < 1:
            raise ValueError(f"m: expected a positive integer cluster size, got {m!r}")
        self.m = int(m)
        self.k = 0  # completed clusters
        self.partial = 0.0
        self.count = 0
        self.prev = math.nan
        self.sum_half_d2 = 0.0
        self.value = 0.0

    def update(self, chunk) -> np.ndarray:
        x = np.asarray(chunk, dtype=np.float64)
        if x.ndim != 1:
            raise ValueError(f"chunk: expected a 1-D array, got shape {x.shape}")
        m = self.m
        need = m - self.count
        if x.size < need:
            self.partial += x.sum()
            self.count += x.size
            return np.empty(0)
        head = (self.partial + x[:need].sum()) / m
        rest = x[need:]
        J = rest.size // m
        means = np.concatenate(([head], rest[: J * m].reshape(J, m).mean(axis=1)))
        tail = rest[J * m :]
        self.partial, self.count = float(tail.sum()), tail.size
        seq = np.concatenate(([self.prev], means)) if self.k > 0 else means
        d2 = np.diff(seq) ** 2 / 2
        k_before = self.k
        self.k += means.size
        self.prev = float(means[-1])
        if d2.size == 0:
            return np.empty(0)
        counts = np.arange(max(k_before, 1), self.k)  # k - 1 for each new delta_k
        vals = (self.sum_half_d2 + np.cumsum(d2)) / counts
        self.sum_half_d2 += float(d2.sum())
        self.value = float(vals[-1])
        return vals
