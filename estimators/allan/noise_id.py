"""Power-law noise identification as Stable32 does it: the lag-1 autocorrelation, the B1 and R(n) ratios.

The noise type at an averaging time tau = m dt is the exponent alpha of S_y(f) ~ f^alpha (2 white PM,
1 flicker PM, 0 white FM, -1 flicker FM, -2 random-walk FM, -3 flicker-walk FM, -4 random-run FM: in
gyro terms quantization, -, angle random walk, bias instability, rate random walk).

Lag-1 autocorrelation (Riley & Greenhall 2004, "Power law noise identification using the lag 1
autocorrelation", 18th EFTF; Stable32 with >= 30 points): the data at tau -- the phase decimated by m
(x_0, x_m, x_2m, ...), its quadratic trend removed, or the frequency averaged over m, its linear trend
removed -- is differenced d = 0, 1, ... times until

.. math::

    r_1 = \\frac{\\sum_{i=1}^{N-1} (z_i - \\bar z)(z_{i+1} - \\bar z)}{\\sum_{i=1}^{N} (z_i - \\bar z)^2},
    \\qquad \\delta = \\frac{r_1}{1 + r_1} < 0.25

or d reaches d_max (2 for the Allan family, 3 for the Hadamard family); then p = -2(delta + d) and alpha
= p + 2 (phase data) or p (frequency data), rounded to the integer -round(2 delta) - 2d (+2). The same
preprocessing, differencing and rounding as allantools' ``autocorr_noise_id`` (tests: equal to 1e-9).

With fewer than 30 points (Stable32's rule) the B1 ratio decides (Barnes 1969; Howe, Beard, Greenhall &
Riley 2000, 32nd PTTI, Tables 3-4): B1 = (standard variance of the N averages of m samples) / (their
non-overlapping AV), against its expectation for S_x ~ f^mu, B1(N, mu) = N (1 - N^mu) / (2 (N - 1)
(1 - 2^mu)) (limits: mu = 0: N ln N / (2 (N-1) ln 2), mu = -1: 1, mu = -2: (N^2 - 1)/(1.5 N (N - 1))),
the boundary between adjacent mu at the geometric mean of their expectations, mu = -alpha - 1 (mu = 2,
flicker-walk FM, for the Hadamard family only); for PM (mu = -2) the ratio R(n) = MVAR / AVAR (both
overlapping) against 1/m (white PM) and 3.37 / (1.04 + 3 ln(pi m)) (flicker PM; NIST TN1337, A-6)
separates alpha = 2 from 1. B1 decides only while the N = n/m averages number at least twice the
statistic's Stable32 stop ratio (``B1_MIN_AVERAGES``: the stop ratio is the record length over the largest
AF of its octave and decade runs, 5 for ADEV and HDEV, 4 for OADEV, MDEV, TDEV and OHDEV, 3 for MTOTDEV,
TTOTDEV and HTOTDEV, 2 for TOTDEV, as allantoolkit's tables.yml gives them from W. J. Riley's Stable32 papers),
i.e. up to half the largest AF; beyond, and where B1 has fewer than three averages, the type of the previous
tau is kept. That is what Stable32's printed types show: on its every-AF runs the type never changes beyond
that AF (PHASE.DAT MTOTDEV and TTOTDEV from AF 167 = 1000/6 on; on the BIPM Sr87 record of allantoolkit's
tests, 1252 frequency points, ADEV from AF 127 > 1252/10, TDEV from AF 158 > 1252/8, HTOTDEV from AF 209 >
1252/6), and two runs print different types at the same AF (PHASE.DAT MTOTDEV at AF 200: 1 on the decade run,
kept from AF 100; 0 on the every-AF run). Agreement with Stable32's
printed types on PHASE.DAT (every AF of its ADEV ... HTOTDEV tables): every lag-1 row; 270 of the 278 B1 rows.
The other eight are three B1 decisions within 2 % of a boundary (MTOTDEV and TTOTDEV at AF 75, 93 and 113)
and TOTDEV at AF 128 (and 256, kept from it), where Stable32 1.60 prints white FM and B1 says flicker PM.

Computation: per tau the decimated or averaged series (n/m points) and up to three differences, its
least-squares trend of degree 2 or 1 from the normal equations in a centred, scaled index and the lag-1
sums (compiled: ``_tf_kernels.detrend``, ``lag1_acf``, held to numpy.polyfit and the plain sums by the
tests): O(n/m) per tau, O(n) over an octave grid.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from avbench.estimators.allan import _kernels
from avbench.estimators.allan import _tf_kernels as _tf
from avbench.estimators.allan._deviation_kernels import mvar_sums
from avbench.estimators.allan.variance import _checked_record_and_mean, cluster_sizes

__all__ = ["NoiseId", "noise_id", "lag1_acf", "acf_noise_id", "b1_ratio_expected", "D_MAX", "ALPHA_NAMES",
           "B1_MIN_AVERAGES"]

#: the differencing order d_max of each statistic's family (Allan 2, Hadamard 3)
D_MAX = {"avar": 2, "oavar": 2, "mvar": 2, "tvar": 2, "totvar": 2, "mtotvar": 2, "ttotvar": 2, "theo1": 2,
         "theobr": 2, "pvar": 2, "gradev": 2, "hvar": 3, "ohvar": 3, "htotvar": 3}
#: alpha -> noise type name
ALPHA_NAMES = {2: "white_pm", 1: "flicker_pm", 0: "white_fm", -1: "flicker_fm", -2: "rw_fm", -3: "fw_fm", -4: "rr_fm"}
#: Stable32 uses the lag-1 autocorrelation from this many points on
MIN_ACF_POINTS = 30
#: B1 decides from this many averages on: twice Stable32's stop ratio of the statistic (module docstring); fewer
#: keep the previous tau's type (3 where Stable32 prints no such run)
B1_MIN_AVERAGES = {"avar": 10, "hvar": 10, "oavar": 8, "mvar": 8, "tvar": 8, "ohvar": 8, "totvar": 4, "mtotvar": 6,
                   "ttotvar": 6, "htotvar": 6}


@dataclass(frozen=True)
class NoiseId:
    """Noise type per tau: ``alpha`` (integer), ``estimate`` (its unrounded value; B1's are integers), ``d``
    (differences taken), ``method`` ("acf", "b1", "rn" or "kept")."""

    tau: np.ndarray
    m: np.ndarray
    alpha: np.ndarray
    estimate: np.ndarray
    d: np.ndarray
    method: np.ndarray

    @property
    def names(self) -> np.ndarray:
        """The noise type names of ``alpha`` ("white_fm", ...)."""
        return np.array([ALPHA_NAMES[int(a)] for a in self.alpha], dtype=object)


def lag1_acf(z) -> float:
    """Lag-1 autocorrelation r_1 of a series (Riley & Greenhall 2004, eq. 2; compiled: ``_tf_kernels.lag1_acf``)."""
    return float(_tf.lag1_acf(np.ascontiguousarray(z, dtype=float)))


def acf_noise_id(z, *, dmin: int = 0, dmax: int = 2, phase: bool = True):
    """(alpha, unrounded alpha, d, delta) of a series already at its tau and detrended (module docstring)."""
    d = 0
    while True:
        r1 = lag1_acf(z)
        delta = r1 / (1.0 + r1)
        if d >= dmin and (delta < 0.25 or d >= dmax):
            add = 2 if phase else 0
            return int(-np.round(2 * delta) - 2 * d) + add, -2.0 * (delta + d) + add, d, delta
        z = np.diff(z)
        d += 1


def b1_ratio_expected(N: int, mu: int) -> float:
    """E[B1] for N frequency averages and phase exponent mu (S_x ~ f^mu), module docstring."""
    N = float(N)
    if mu == 0:
        return N * math.log(N) / (2.0 * (N - 1.0) * math.log(2.0))
    if mu == -1:
        return 1.0
    if mu == -2:
        return (N * N - 1.0) / (1.5 * N * (N - 1.0))
    return N * (1.0 - N**mu) / (2.0 * (N - 1.0) * (1.0 - 2.0**mu))


def _b1_alpha(rate, S, m, n, dmax):
    """(alpha, method) from B1 (and R(n) for PM) at cluster size m; None when fewer than 3 averages."""
    N = n // m
    if N < 3:
        return None
    ybar = (S[m : N * m + 1 : m] - S[0 : N * m : m]) / m
    av = np.sum(np.diff(ybar) ** 2) / (2.0 * (N - 1))
    if not av > 0:
        return None
    b1 = np.var(ybar, ddof=1) / av
    mus = [2, 1, 0, -1, -2] if dmax >= 3 else [1, 0, -1, -2]
    mu = mus[-1]
    for hi, lo in zip(mus[:-1], mus[1:]):
        if b1 > math.sqrt(b1_ratio_expected(N, hi) * b1_ratio_expected(N, lo)):
            mu = hi
            break
    if mu > -2:
        return -mu - 1, "b1"
    if m == 1 or n - 3 * m + 1 < 1:
        return 2, "b1"
    mv = float(mvar_sums(S, np.array([m], dtype=np.int64))[0][0]) / (2.0 * m**4 * (n - 3 * m + 2))
    oav = float(_kernels.oavar_sums(S, np.array([m], dtype=np.int64))[0]) / (2.0 * m * m * (n - 2 * m + 1))
    bound = math.sqrt((1.0 / m) * 3.37 / (1.04 + 3.0 * math.log(math.pi * m)))
    return (1 if mv / oav > bound else 2), "rn"


def noise_id(rate, dt, taus="octave", *, kind: str = "oavar", data: str = "phase",
             points_per_decade: int = 10) -> NoiseId:
    """Noise type alpha at each tau of a rate record, as Stable32 identifies it (module docstring).

    Parameters
    ----------
    rate : array_like
        Rate samples (rad/s), 1-D, finite; the phase is their mean-removed cumulative sum (as in
        :func:`~avbench.estimators.allan.deviations.deviation`).
    dt : float
        Sample interval (s).
    taus : "octave", "decade", "all" or array of seconds
        As :func:`~avbench.estimators.allan.variance.allan_variance`.
    kind : str
        The statistic the type is for: its family sets d_max (``D_MAX``: 3 for "hvar", "ohvar", "htotvar").
    data : "phase" or "rate"
        Identify on the decimated phase (Stable32 on phase data; the default) or on the averaged rate.

    Examples
    --------
    >>> import numpy as np
    >>> r = noise_id(np.random.default_rng(1).standard_normal(4000), 1.0, [1.0, 4.0, 16.0])
    >>> r.alpha.tolist()
    [0, 0, 0]
    """
    if kind not in D_MAX:
        raise ValueError(f"kind: expected one of {', '.join(D_MAX)}, got {kind!r}")
    if data not in ("phase", "rate"):
        raise ValueError(f"data: expected 'phase' or 'rate', got {data!r}")
    rate, dt, mean = _checked_record_and_mean(rate, dt)
    n = rate.size
    m = cluster_sizes(taus, n, dt, points_per_decade)
    S = _kernels.centred_cumsum(rate, mean, np.empty(n + 1))
    dmax = D_MAX[kind]
    alpha = np.empty(m.size, dtype=np.int64)
    est = np.empty(m.size)
    d = np.zeros(m.size, dtype=np.int64)
    method = np.empty(m.size, dtype=object)
    last = None
    for j, mi in enumerate(m.tolist()):
        if data == "phase":
            z = S[::mi]
        else:
            k = n // mi
            z = (S[mi : k * mi + 1 : mi] - S[0 : k * mi : mi]) / mi
        if z.size >= MIN_ACF_POINTS:
            zd = _tf.detrend(np.ascontiguousarray(z), 2 if data == "phase" else 1)
            a, e, dd, _ = acf_noise_id(zd, dmax=dmax, phase=data == "phase")
            alpha[j], est[j], d[j], method[j] = a, e, dd, "acf"
        else:
            few = n // mi < B1_MIN_AVERAGES.get(kind, 3) and last is not None
            got = None if few else _b1_alpha(rate, S, mi, n, dmax)
            if got is None:
                if last is None:
                    raise ValueError(f"noise_id: too few samples ({n}) to identify a noise type at m = {mi}")
                alpha[j], est[j], method[j] = last, last, "kept"
            else:
                alpha[j], method[j] = got
                est[j] = alpha[j]
        last = int(alpha[j])
    return NoiseId(m * dt, m, alpha, est, d, method)
