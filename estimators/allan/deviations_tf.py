"""Time-and-frequency statistics beside the deviation family: MTIE, TIE rms, the gap-resistant ADEV and
the three-cornered hat.

All read the phase (angle) record x of a rate record w as :func:`~avbench.estimators.allan.deviations.
deviation` does: x_0 = 0, x_k = dt sum_{j<k} (w_j - mean w), N = n + 1 points (the mean rate removed, as
Stable32's PHASE.DAT is the NBS 1000-point frequency set so integrated; MTIE and TIE rms, unlike the
variances, see a rate offset, and a gyro's offset is its bias, not its noise). tau = m dt.

* ``mtie`` maximum time interval error (ITU-T G.810; Bregni 2001): the largest peak-to-peak phase within
  any window of m + 1 points, max_i (max_{i<=k<=i+m} x_k - min_{i<=k<=i+m} x_k) -- allantools ``mtie``
  and Stable32's MTIE (its "Fast" run: the same windows). Exact, from a sparse table of window maxima
  and minima (``_tf_kernels.mtie_max``): O(N) per m. It has no closed-form expectation, so
  ``noise_models.exact_variances`` gives none.
* ``tie_rms`` TIE rms: sqrt( (1/(N - m)) sum_{i=0}^{N-m-1} (x_{i+m} - x_i)^2 ) (allantools ``tierms``,
  Stable32's TIE rms). ``noise_models.exact_variances.tie_ms`` gives the exact mean square for every term.
* ``gradev`` the gap-resistant overlapping ADEV (allantools ``gradev``; Sesia & Tavella's treatment of
  gaps): the overlapping AV's second differences x_{i+2m} - 2x_{i+m} + x_i that a gap does not touch,
  sigma^2 = sum' / (2 n' tau^2) over the n' of them. Phase data (``data="phase"``, NaN at the missing
  points): a term is kept when its three phases are finite (allantools' rule). Rate data (the default,
  NaN at the missing samples): when its 2m rate samples are (the phase across a gap is unknown, the
  differences inside a window are not). One compiled pass per m (``_tf_kernels.gradev_sums``). Its edf: the exact one of the overlapping AV over n' terms
  (``deviations.edf_quadratics``) with the type from the slope of the gradev values (as the AV engine);
  allantools' own intervals pass the confidence and the edf in swapped order and are not reproduced.
* ``three_cornered_hat`` (Gray & Allan 1974; SP1065 section 8.3): three sensors recorded together, their
  pairwise differences a - b, b - c, c - a analysed by one statistic of the family; with independent
  noises s_ab = s_a + s_b and so on, so s_a = (s_ab + s_ca - s_bc) / 2 (cyclically). Error bars as
  Ekstrom & Koppang (2006, "Error bars for three-cornered hats", IEEE UFFC 53(5)) build them, from the
  variances and covariances of the pairwise estimates: with each pair's estimate a quadratic form of
  edf nu (the three pairs' harmonic-mean edf) and the three noises of one spectral shape per tau,
  Var(s_ab) = 2 (S_a + S_b)^2 / nu and Cov(s_ab, s_ca) = 2 S_a^2 / nu, whence

  .. math::

      \\mathrm{Var}(\\hat s_a) = \\frac{2}{\\nu}\\left[S_a^2 + \\tfrac12 (S_a S_b + S_a S_c + S_b S_c)\\right],

  evaluated at the estimates (negative ones as 0). The interval of a positive estimate is chi^2 with
  Satterthwaite's edf nu_a = 2 s_a^2 / Var(s_a). The negative-variance case (the sensor is quieter than
  the pairs can resolve, or the noises are correlated): the estimate is kept as it is, its deviation is
  NaN, and its interval is [0, s_a + z Var(s_a)^(1/2)] (z the normal quantile of the confidence; an upper
  bound, in Ekstrom & Koppang's reading of a negative estimate as consistent with zero within its error
  bar). allantools' ``three_cornered_hat_phase`` sets such a variance to 0 instead.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from avbench.estimators.allan import _tf_kernels as _tf
from avbench.estimators.allan.deviations import deviation, edf_quadratics
from avbench.estimators.allan.variance import AllanResult, _checked_record_and_mean, _noise_codes_from_slope, cluster_sizes

__all__ = ["TimeIntervalResult", "mtie", "tie_rms", "gradev", "ThreeCorneredHat", "three_cornered_hat"]


@dataclass(frozen=True)
class TimeIntervalResult:
    """MTIE or TIE rms per tau: ``value`` (rad, the phase's unit times dt: an angle), ``J`` the windows or
    differences it is taken over."""

    tau: np.ndarray
    m: np.ndarray
    value: np.ndarray
    J: np.ndarray
    kind: str
    n_samples: int
    dt: float

    def to_frame(self):
        import pandas as pd

        return pd.DataFrame({"tau": self.tau, "m": self.m, "J": self.J, self.kind: self.value})

    def __len__(self) -> int:
        return len(self.tau)


def _phase_and_m(rate, dt, taus, points_per_decade):
    rate, dt, mean = _checked_record_and_mean(rate, dt)
    n = rate.size
    x = np.empty(n + 1)
    x[0] = 0.0
    np.cumsum(rate - mean, out=x[1:])
    x *= dt
    # the grids stop at half the record, as every statistic's; a tau given may reach the whole record (MTIE's
    # window of m + 1 phases, TIE's one difference)
    m = cluster_sizes(taus, n if isinstance(taus, str) else 2 * n, dt, points_per_decade)
    if m.max() > n:
        raise ValueError(f"taus: {(m[m > n] * dt).tolist()} s exceed the record ({n} samples x {dt} s)")
    return x, m, n, dt


def mtie(rate, dt, taus="octave", *, points_per_decade: int = 10) -> TimeIntervalResult:
    """Maximum time interval error of a rate record (module docstring), rad.

    Examples
    --------
    >>> import numpy as np
    >>> r = mtie(np.array([1.0, -1.0] * 8), 1.0, [1.0, 2.0])
    >>> r.value.tolist()
    [1.0, 1.0]
    """
    x, m, n, dt = _phase_and_m(rate, dt, taus, points_per_decade)
    return TimeIntervalResult(m * dt, m, _tf.mtie_max(x, m), n + 1 - m, "mtie", n, dt)


def tie_rms(rate, dt, taus="octave", *, points_per_decade: int = 10) -> TimeIntervalResult:
    """TIE rms of a rate record (module docstring), rad.

    Examples
    --------
    >>> import numpy as np
    >>> tie_rms(np.ones(32) * 2.0, 0.5, [0.5]).value.tolist()  # the mean rate is removed: no error left
    [0.0]
    """
    x, m, n, dt = _phase_and_m(rate, dt, taus, points_per_decade)
    J = n + 1 - m
    return TimeIntervalResult(m * dt, m, np.sqrt(_tf.tie_sums(x, m) / J), J, "tierms", n, dt)


def gradev(data, dt, taus="octave", *, data_type: str = "rate", noise="auto", confidence: float = 0.683,
           points_per_decade: int = 10) -> AllanResult:
    """Gap-resistant overlapping Allan variance (module docstring): NaN marks a gap.

    Parameters
    ----------
    data : array_like
        Rate samples (rad/s; ``data_type="rate"``) or phase (angle, rad; ``data_type="phase"``), NaN where
        missing.
    dt : float
        Sample interval (s).
    taus : "octave", "decade", "all" or array of seconds
        As :func:`~avbench.estimators.allan.variance.allan_variance`.
    noise : "auto" or a noise type name
        For the edf, as :func:`~avbench.estimators.allan.deviations.deviation`.

    Returns
    -------
    AllanResult
        ``kind`` "gradev"; ``J`` the number of second differences kept at each tau (a tau with none is
        left out).

    Examples
    --------
    >>> import numpy as np
    >>> w = np.random.default_rng(2).standard_normal(400)
    >>> bool(np.allclose(gradev(w, 1.0).avar, deviation(w, 1.0, "oavar").avar, rtol=1e-12))  # no gap: OAVAR
    True
    """
    if data_type not in ("rate", "phase"):
        raise ValueError(f"data_type: expected 'rate' or 'phase', got {data_type!r}")
    v = np.asarray(data, dtype=float)
    if v.ndim != 1 or v.size < 3:
        raise ValueError(f"data: expected a 1-D record of at least 3 values, got shape {v.shape}")
    dt = float(dt)
    if not (math.isfinite(dt) and dt > 0):
        raise ValueError(f"dt: expected a positive number of seconds, got {dt!r}")
    good = np.isfinite(v)
    if good.sum() < 3:
        raise ValueError("data: fewer than three finite values")
    if data_type == "rate":
        n = v.size
        w = np.where(good, v - v[good].mean(), 0.0)
        x = np.concatenate(([0.0], np.cumsum(w))) * dt
        bad = np.concatenate(([0], np.cumsum(~good))).astype(np.int64)  # missing samples before each phase point
    else:
        n = v.size - 1
        x = v
    m = cluster_sizes(taus, n, dt, points_per_decade)
    if data_type == "phase":
        bad = np.zeros(1, dtype=np.int64)
    sums, K = _tf.gradev_sums(np.ascontiguousarray(x), m, bad, data_type == "rate")
    keep = K > 0  # a tau every window of which a gap touches has no estimate
    if not keep.any():
        raise ValueError("data: the gaps leave no second difference at any tau")
    m, K, sums = m[keep], K[keep], sums[keep]
    mf = m.astype(float)
    avar = sums / (2.0 * K * (mf * dt) ** 2)
    tau = mf * dt
    if isinstance(noise, str) and noise == "auto":
        codes = _noise_codes_from_slope(tau, avar, K // m)
        kinds = np.array(["white_pm", "white_fm", "flicker_fm", "rw_fm"], dtype=object)[codes]
    else:
        kinds = np.broadcast_to(np.asarray(noise, dtype=object), m.shape)
    e = edf_quadratics("oavar", m, np.maximum(K, 1), kinds)
    return AllanResult(tau, m, avar, K, 1.0 / np.sqrt(2.0 * e), e, True, n, dt, confidence, kind="gradev")


@dataclass(frozen=True)
class ThreeCorneredHat:
    """Each of three sensors' own variance from their pairwise differences (module docstring).

    Rows of the (3, T) arrays are the sensors a, b, c; ``pair_avar`` rows the pairs a - b, b - c, c - a.
    ``avar`` may be negative (then ``deviation`` is NaN and the interval an upper bound).
    """

    tau: np.ndarray
    m: np.ndarray
    avar: np.ndarray
    pair_avar: np.ndarray
    edf: np.ndarray
    std_err: np.ndarray
    kind: str
    n_samples: int
    dt: float
    confidence: float = 0.683

    @property
    def deviation(self) -> np.ndarray:
        with np.errstate(invalid="ignore"):
            return np.where(self.avar > 0, np.sqrt(np.maximum(self.avar, 0.0)), np.nan)

    @property
    def negative(self) -> np.ndarray:
        return ~(self.avar > 0)

    @property
    def sensor_edf(self) -> np.ndarray:
        """Satterthwaite's edf of each estimate, 2 s^2 / Var(s) (NaN where the estimate is not positive)."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(self.avar > 0, 2.0 * self.avar**2 / self.std_err**2, np.nan)

    def _bounds(self):
        from scipy.special import gammaincinv, ndtri

        a = (1.0 - self.confidence) / 2.0
        nu = self.sensor_edf
        with np.errstate(invalid="ignore", divide="ignore"):
            lo = nu * self.avar / (2.0 * gammaincinv(nu / 2.0, 1.0 - a))
            hi = nu * self.avar / (2.0 * gammaincinv(nu / 2.0, a))
        up = np.maximum(self.avar + ndtri(1.0 - a) * self.std_err, 0.0)
        pos = self.avar > 0
        return np.where(pos, lo, 0.0), np.where(pos, hi, up)

    @property
    def ci_low(self) -> np.ndarray:
        return self._bounds()[0]

    @property
    def ci_high(self) -> np.ndarray:
        return self._bounds()[1]

    def to_frame(self):
        import pandas as pd

        lo, hi = self._bounds()
        rows = []
        for s, name in enumerate("abc"):
            rows.append(pd.DataFrame({"sensor": name, "tau": self.tau, "m": self.m, "avar": self.avar[s],
                                      "deviation": self.deviation[s], "std_err": self.std_err[s], "ci_low": lo[s],
                                      "ci_high": hi[s]}))
        return pd.concat(rows, ignore_index=True)


def three_cornered_hat(a, b, c, dt, kind: str = "oadev", taus="octave", *, confidence: float = 0.683,
                       **kw) -> ThreeCorneredHat:
    """The three-cornered hat of three simultaneous rate records (module docstring).

    ``kind``, ``taus`` and the keywords (``noise``, ``intervals``, ``points_per_decade``, ...) go to
    :func:`~avbench.estimators.allan.deviations.deviation` for each pairwise difference.

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(4)
    >>> a, b, c = (s * rng.standard_normal(20000) for s in (1.0, 2.0, 3.0))
    >>> h = three_cornered_hat(a, b, c, 1.0, "oadev", [1.0])
    >>> [round(float(v)) for v in h.avar[:, 0]]
    [1, 4, 9]
    """
    recs = [np.asarray(r, dtype=float) for r in (a, b, c)]
    if not (recs[0].shape == recs[1].shape == recs[2].shape) or recs[0].ndim != 1:
        raise ValueError(f"a, b, c: expected three 1-D records of one length, got shapes {[r.shape for r in recs]}")
    pairs = [deviation(recs[0] - recs[1], dt, kind, taus, confidence=confidence, **kw),
             deviation(recs[1] - recs[2], dt, kind, taus, confidence=confidence, **kw),
             deviation(recs[2] - recs[0], dt, kind, taus, confidence=confidence, **kw)]
    ab, bc, ca = (p.avar for p in pairs)
    est = 0.5 * np.array([ab + ca - bc, ab + bc - ca, bc + ca - ab])
    nu = 3.0 / np.sum([1.0 / p.edf for p in pairs], axis=0)
    S = np.maximum(est, 0.0)
    cross = S[0] * S[1] + S[0] * S[2] + S[1] * S[2]
    std_err = np.sqrt(2.0 / nu * (S**2 + 0.5 * cross))
    p0 = pairs[0]
    return ThreeCorneredHat(p0.tau, p0.m, est, np.array([ab, bc, ca]), nu, std_err, p0.kind, p0.n_samples, p0.dt,
                            confidence)
