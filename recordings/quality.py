"""Step 3c: is the record what the fits assume? Judged before any fit, each verdict a flag with what to do.

Every method assumes stationary Gaussian-like noise sampled finely enough. A record can break that in
ways no fit names: its coefficients then come out biased, with status ``ok`` and intervals that do not
hold. Each channel (each gyro and accelerometer axis, in SI) is checked for six things; each verdict is
a :class:`Flag` -- its name, the channel, its size and what to do:

* ``spikes`` -- isolated outliers. The residual of each sample from the mean of its two neighbours,
  :math:`r_i = x_i - (x_{i-1} + x_{i+1})/2` (variance :math:`1.5\\sigma^2` for white noise, blind to
  slow terms), in robust standard deviations (the RMS of r within its 0.1-99.9 % quantiles, which holds
  on a coarsely rounded record where the MAD does not, over blocks of at least 4096 samples, so that a
  noise level that moves makes no spikes); a spike's neighbours show half of it, so only the largest of
  three is counted. Beyond the Gaussian Bonferroni limit at family-wise level
  :data:`FAMILY_LEVEL` over the samples (:func:`avbench.recordings.static.level_threshold`; about 6.8
  sigma on 1e5 samples) is a spike. A spike adds its square to every Allan variance it touches: the AV
  methods read it as noise. ``gmwm_despiked`` leaves spikes out (a Hampel filter,
  :mod:`avbench.estimators.robust.gmwm`).
* ``clipping`` -- samples piled on the record's extreme value: at least 3 samples at it where the
  record is not quantized (a tie at the extreme of continuous noise does not happen by chance), or,
  where it is, more than the next value inward holds beyond chance (a tail thins outward, so at most
  as many are expected: the binomial tail of the extreme's share of the two at 1/2 below
  :data:`FAMILY_LEVEL`; a rail piles up). Clipping cuts the noise: N and the slower terms come out low.
* ``raw counts`` -- the samples are whole numbers in the unit they were declared in (a lattice of step
  1): ADC counts read as rad/s or m/s^2. ``implausible mean`` -- a mean no sensor at rest shows: a gyro
  axis beyond :data:`GYRO_MEAN_LIMIT` (1 rad/s, 57 deg/s: beyond any gyro's zero-rate offset), or an
  accelerometer whose mean vector's magnitude is off standard gravity by more than
  :data:`GRAVITY_SHARE` of it (three axes; one axis: beyond 2 g).
* ``quantization`` -- the samples lie on a lattice of step q (:func:`lattice_step`) whose rounding
  variance :math:`q^2/12` is at least :data:`QUANTIZATION_SHARE` of the short-scale variance
  :math:`\\overline{\\Delta x^2}/2`. Rounding each sample adds white noise of variance :math:`q^2/12`
  (where the noise dithers it) or a staircase (where it does not): at the shortest taus the AV shows
  the rounding, not the sensor, and N is inflated by up to :math:`\\sqrt{1 + q^2/(12\\sigma^2)}`.
* ``non-stationary`` -- the noise level moves during the record. The short-scale variance
  :math:`\\overline{\\Delta x^2}` is taken in :data:`N_BLOCKS` blocks (spikes left out), grouped in
  :data:`N_SEGMENTS` consecutive segments; a one-way analysis of variance of the blocks' log variances
  between the segments (F test, the within-segment spread of the blocks as its own reference, so a
  non-white short-scale noise does not make it over-confident) at level :data:`STATIONARITY_LEVEL`.
  Its size: the noise level (RMS) of the second half over the first, with its 95 % interval from the
  blocks' spread (t with the blocks' degrees of freedom), and the largest and smallest segment's level
  over the record's. A fit averages over the record; a filter running at another time sees another level.

The result is a :class:`RecordQuality`; its :meth:`~RecordQuality.to_dict` is the payload's
``record_quality`` (:data:`KEY`), from which every surface renders the flags: the screen
(:func:`screen_lines`), the page (:mod:`avbench.recordings.html`), and each filter file's header
(:func:`file_lines`). The false-alarm rate on clean simulated records is measured in
``tests/test_quality.py``.

Examples
--------
>>> import numpy as np
>>> from avbench.recordings.quality import judge_record
>>> from avbench.recordings.sensors import SensorRecord
>>> x = np.random.default_rng(0).normal(0.0, 1e-3, 20_000)
>>> x[5000] = 10.0                                        # one spike of 1e4 sigma
>>> q = judge_record([SensorRecord("gyro", "rad/s", {"x": x}, {})], 0.01)
>>> [f.name for f in q.flags]
['spikes']
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

import numpy as np

__all__ = ["Flag", "RecordQuality", "judge_record", "lattice_step", "noise_level_change", "screen_lines", "file_lines", "KEY", "NAMES",
           "FAMILY_LEVEL", "STATIONARITY_LEVEL", "QUANTIZATION_SHARE", "GYRO_MEAN_LIMIT", "GRAVITY_SHARE",
           "N_BLOCKS", "N_SEGMENTS"]

KEY = "record_quality"  #: the payload's key
#: every flag's name, in the order the checks run
NAMES = ("spikes", "clipping", "raw counts", "implausible mean", "quantization", "non-stationary")
FAMILY_LEVEL = 1e-6  #: per channel: chance that Gaussian noise shows a spike
STATIONARITY_LEVEL = 1e-3  #: per channel: chance that a stationary record is called non-stationary
QUANTIZATION_SHARE = 0.1  #: rounding variance q^2/12 over the short-scale variance from which it is flagged
GYRO_MEAN_LIMIT = 1.0  #: rad/s: a gyro mean beyond this is no sensor at rest
GRAVITY_SHARE = 0.5  #: |mean vector| / g - 1 beyond this is no accelerometer at rest
N_BLOCKS = 64  #: blocks of the short-scale variance
N_SEGMENTS = 8  #: consecutive segments the blocks are grouped in
_MIN_BLOCK = 16  #: at least this many differences per block (else the stationarity check is skipped)
_TRIMMED_SD = 0.98952  #: SD of a standard normal truncated to its 0.1-99.9 % quantiles (+-3.09)
_SPIKE_BLOCK = 4096  #: samples per block of the spikes' robust scale (at least; 1.4826 MAD to about 2 %)
_G = 9.80665


@dataclass(frozen=True)
class Flag:
    """One verdict on one channel: ``name`` (one of :data:`NAMES`), ``channel`` ("gyro x"), ``size`` (the
    statistic that decided, a number), ``finding`` (what was seen, with its size) and ``todo`` (what to do)."""

    name: str
    channel: str
    size: float
    finding: str
    todo: str
    interval: tuple[float, float] | None = None

    def text(self) -> str:
        """One line: ``name (channel): finding -- todo``."""
        return f"{self.name} ({self.channel}): {self.finding} -- {self.todo}"


@dataclass(frozen=True)
class RecordQuality:
    """Every flag of a record (empty: nothing seen) and the checks made."""

    flags: tuple[Flag, ...]
    checked: tuple[str, ...] = NAMES
    family_level: float = FAMILY_LEVEL
    stationarity_level: float = STATIONARITY_LEVEL
    #: per channel ("gyro x") with spikes, the samples that are spikes (the static check leaves them out)
    spikes: dict = field(default_factory=dict, repr=False, compare=False)

    @property
    def names(self) -> list[str]:
        """The names flagged, each once, in the order of :data:`NAMES`."""
        seen = {f.name for f in self.flags}
        return [n for n in NAMES if n in seen]

    def to_dict(self) -> dict:
        """The payload's ``record_quality``: ``ok`` (no flag), ``flagged`` (names), ``flags`` (each as a dict
        with its ``text``), ``checked`` and the levels."""
        return {"ok": not self.flags, "flagged": self.names, "checked": list(self.checked),
                "flags": [{**asdict(f), "interval": None if f.interval is None else list(f.interval), "text": f.text()}
                          for f in self.flags],
                "family_level": self.family_level, "stationarity_level": self.stationarity_level}


def lattice_step(x) -> float | None:
    """The step q of the lattice the samples lie on (all differences between distinct values whole
    multiples of the smallest, to 1e-6 of it), or None where they do not (more distinct values than half
    the samples: a continuous record)."""
    x = np.asarray(x, dtype=np.float64)
    return _lattice(np.unique(x), x.size)


def _lattice(u, n: int) -> float | None:
    if u.size < 2 or u.size > n // 2:
        return None
    d = np.diff(u)
    q = float(d.min())
    k = d / q
    return q if np.all(np.abs(k - np.round(k)) <= 1e-6 * np.maximum(k, 1.0)) else None


def _scale(r) -> float:
    """Robust standard deviation: the RMS within the 0.1-99.9 % quantiles over the Gaussian's share of it
    (0.990); unlike the MAD it holds on a coarsely rounded record, whose residuals take few values."""
    lo, hi = np.quantile(r, [0.001, 0.999])
    core = r[(r >= lo) & (r <= hi)]
    return float(np.sqrt(np.mean(core**2))) / _TRIMMED_SD if core.size else 0.0


def _spikes(x, channel, t0):
    from avbench.recordings.static import level_threshold

    r = x[1:-1] - 0.5 * (x[:-2] + x[2:])
    z = np.zeros(r.size)
    step = max(_SPIKE_BLOCK, -(-r.size // N_BLOCKS))
    for a in range(0, r.size, step):  # each block's own scale: a noise level that moves makes no spikes
        b = r.size if r.size - a < 2 * step else a + step
        s = _scale(r[a:b])
        if s > 0:
            z[a:b] = np.abs(r[a:b]) / s
        if b == r.size:
            break
    thr = level_threshold(z.size, FAMILY_LEVEL)
    peak = np.r_[False, (z[1:-1] >= z[:-2]) & (z[1:-1] >= z[2:]), False] if z.size > 2 else np.ones(z.size, bool)
    hit = np.flatnonzero((z > thr) & peak) + 1  # a spike's neighbours show half of it: the peak is the spike
    mask = np.zeros(x.size, dtype=bool)
    mask[hit] = True
    if not hit.size:
        return None, mask
    where = ", ".join(f"{t0 * i:.4g} s" for i in hit[:5]) + (" ..." if hit.size > 5 else "")
    zmax = float(z.max())
    return Flag("spikes", channel, zmax,
                f"{hit.size} sample(s) beyond {thr:.3g} robust sigma of their neighbours (largest {zmax:.3g} sigma) at "
                f"{where}",
                "the Allan-variance methods read a spike as noise: use gmwm_despiked (a default method; "
                "--filter-method gmwm_despiked), which leaves spikes out, or remove them"), mask


def _clipping(u, c, channel, q):
    # the binomial tail P(X > k) by the incomplete beta: scipy.stats.binom.sf(k, n, p) to 1e-12 relative, without
    # importing scipy.stats (~0.7 s of a process that answers a record in motion)
    from scipy.special import bdtrc

    n = int(c.sum())
    if u.size < 3:
        return None
    railed = []
    for e, k, k_in in ((u[-1], c[-1], c[-2]), (u[0], c[0], c[1])):
        if k >= 3 and (q is None or bdtrc(k - 1, k + k_in, 0.5) < FAMILY_LEVEL):
            railed.append((e, int(k)))
    if not railed:
        return None
    share = sum(k for _, k in railed) / n
    at = " and ".join(f"{k} at {e:.6g}" for e, k in railed)
    return Flag("clipping", channel, share,
                f"{100 * share:.3g} % of the samples sit on the record's extreme value ({at}): the sensor's range cut "
                "the noise", "the coefficients come out low (N roughly by that share): record with a wider "
                "full-scale range, or leave out the clipped spans")


def _raw_counts(x, channel, sensor, unit_in, q):
    from avbench.noise_models.units import samples_to_si

    factor = float(samples_to_si(1.0, unit_in, sensor))
    if q is None or abs(q / factor - 1.0) > 1e-9:
        return None
    given = x / factor  # the samples in the unit they were declared in
    if np.any(np.abs(given - np.round(given)) > 1e-9 * np.maximum(np.abs(given), 1.0)):
        return None
    return Flag("raw counts", channel, q / factor,
                f"every sample is a whole number of {unit_in} (step 1 {unit_in}): raw ADC counts declared as {unit_in}?",
                "convert the counts with the datasheet's sensitivity (counts per unit) before estimating: every "
                "coefficient is in counts until then")


def _mean_flags(sensor_record):
    s = sensor_record
    out = []
    means = {a: float(np.mean(np.asarray(x, dtype=np.float64))) for a, x in s.axes.items()}
    if s.sensor == "gyro":
        for a, m in means.items():
            if abs(m) > GYRO_MEAN_LIMIT:
                out.append(Flag("implausible mean", f"gyro {a}", m,
                                f"mean {m:.4g} rad/s ({math.degrees(m):.4g} deg/s): no gyro at rest reads more than "
                                f"{GYRO_MEAN_LIMIT:g} rad/s", "check --units (raw counts? deg/s declared as rad/s?) "
                                "and that the sensor was at rest"))
    elif s.sensor == "accel" and means:
        g = math.sqrt(sum(m * m for m in means.values()))
        off = g / _G - 1.0 if len(means) == 3 else (g / _G - 2.0 if g > 2 * _G else 0.0)
        if (len(means) == 3 and abs(off) > GRAVITY_SHARE) or (len(means) != 3 and off > 0):
            out.append(Flag("implausible mean", "accel", g,
                            f"the mean acceleration's magnitude is {g:.4g} m/s^2 ({g / _G:.3g} g): at rest it is 1 g",
                            "check --accel-units (raw counts? g declared as m/s^2?) and that the sensor was at rest"))
    return out


def _quantization(channel, q, si_unit, short_var):
    if q is None or not short_var > 0:
        return None
    share = q * q / 12.0 / short_var
    if share < QUANTIZATION_SHARE:
        return None
    return Flag("quantization", channel, share,
                f"the samples are rounded to {q:.4g} {si_unit}; the rounding's variance q^2/12 is {100 * share:.3g} % of the "
                "short-scale variance: the shortest taus show the rounding, not the sensor",
                f"N is inflated by up to {100 * (math.sqrt(1 + share) - 1):.3g} % and the quantization term Q is the "
                "rounding's: record at a finer resolution, or read N from the longer taus (fit from a larger tau)")


def noise_level_change(x, spikes=None) -> dict | None:
    """The stationarity check of the module docstring on one channel ``x`` (``spikes``: a mask of samples
    left out): ``p`` (the F test's p-value), ``ratio`` (second half / first half, RMS), its 95 %
    ``interval`` and ``segments`` (each segment's level over the record's); None where the record is too
    short (fewer than :data:`N_BLOCKS` blocks of 16 differences) or a block holds no variance."""
    # scipy.stats.f.sf(x, a, b) is fdtrc(a, b, x) and t.ppf(q, df) is stdtrit(df, q): the same functions, without
    # importing scipy.stats (~0.7 s of a process that answers a record in motion)
    from scipy.special import fdtrc, stdtrit

    x = np.asarray(x, dtype=np.float64)
    d2 = np.diff(x) ** 2
    bad = np.zeros(x.size, dtype=bool) if spikes is None else np.asarray(spikes, bool)
    bad = bad[1:] | bad[:-1]
    L = d2.size // N_BLOCKS
    if L < _MIN_BLOCK:
        return None
    d2 = d2[: L * N_BLOCKS].reshape(N_BLOCKS, L)
    keep = ~bad[: L * N_BLOCKS].reshape(N_BLOCKS, L)
    with np.errstate(divide="ignore", invalid="ignore"):
        v = np.sum(d2 * keep, axis=1) / np.sum(keep, axis=1)
    if not np.all(np.isfinite(v) & (v > 0)):
        return None
    y = np.log(v).reshape(N_SEGMENTS, N_BLOCKS // N_SEGMENTS)
    k, m = y.shape
    within = float(np.sum((y - y.mean(axis=1, keepdims=True)) ** 2)) / (k * (m - 1))
    between = m * float(np.sum((y.mean(axis=1) - y.mean()) ** 2)) / (k - 1)
    if not within > 0:
        return None
    p = float(fdtrc(k - 1, k * (m - 1), between / within))
    h = N_BLOCKS // 2
    first, second = np.log(v[:h]), np.log(v[h:])
    diff = float(second.mean() - first.mean())
    se = math.sqrt((np.var(first, ddof=1) + np.var(second, ddof=1)) / 2 * (2 / h))
    t = float(stdtrit(2 * h - 2, 0.975))
    return {"p": p, "ratio": math.exp(diff / 2), "interval": (math.exp((diff - t * se) / 2), math.exp((diff + t * se) / 2)),
            "segments": np.exp((y.mean(axis=1) - y.mean()) / 2)}


def _stationarity(x, channel, spikes):
    r = noise_level_change(x, spikes)
    if r is None or r["p"] >= STATIONARITY_LEVEL:
        return None
    iv, seg = r["interval"], r["segments"]
    return Flag("non-stationary", channel, r["ratio"],
                f"the short-scale noise level moves during the record (F test between {N_SEGMENTS} segments, p = "
                f"{r['p']:.2g}): second half / first half = {r['ratio']:.3g} [{iv[0]:.3g}, {iv[1]:.3g}] (95 %); segments "
                f"from {seg.min():.3g} to {seg.max():.3g} x the record's", "the coefficients are the record's average "
                "and their intervals do not hold this change: fit the part of the record like the conditions you will "
                "run in, or inflate the filter's values (--inflate)", iv)


def judge_record(sensors, dt: float) -> RecordQuality:
    """The checks of the module docstring on SI ``sensors``
    (:class:`~avbench.recordings.sensors.SensorRecord` each), sampled every ``dt`` seconds."""
    flags: list[Flag] = []
    spikes: dict = {}
    for s in sensors:
        for axis, x in s.axes.items():
            x = np.asarray(x, dtype=np.float64)
            if x.size < 8:
                continue
            channel = f"{s.sensor} {axis}"
            spike, mask = _spikes(x, channel, dt)
            if spike is not None:
                spikes[channel] = mask
            u, c = np.unique(x, return_counts=True)
            q = _lattice(u, x.size)
            clip = _clipping(u, c, channel, q)
            d = np.diff(x)
            keep = ~(mask[1:] | mask[:-1])
            short_var = float(np.mean(d[keep] ** 2)) / 2 if keep.any() else 0.0
            found = [spike, clip, _raw_counts(x, channel, s.sensor, s.unit_in, q),
                     _quantization(channel, q, s.si_unit, short_var), _stationarity(x, channel, mask)]
            flags += [f for f in found if f is not None]
        flags += _mean_flags(s)
    order = {n: i for i, n in enumerate(NAMES)}
    return RecordQuality(tuple(sorted(flags, key=lambda f: order[f.name])), spikes=spikes)


def screen_lines(rq: dict | None) -> list[str]:
    """The screen's lines on the record's quality (``rq``: :meth:`RecordQuality.to_dict`): one per flag, or one
    saying nothing was seen; none where no check was made (``None``)."""
    from avbench.recordings.report import wrap

    if rq is None:
        return []
    if rq["ok"]:
        return wrap("# record checks: no spikes, clipping, raw counts, implausible mean, dominant rounding or moving "
                    "noise level seen", "#   ")
    out = wrap(f"# RECORD FLAGGED ({', '.join(rq['flagged'])}): the fits below assume a record without these", "#   ")
    for f in rq["flags"]:
        out += wrap(f"# FLAG {f['text']}", "#   ")
    return out


def file_lines(rq: dict | None) -> list[str]:
    """The lines (without comment marks) each filter file's header carries on the record's quality (``rq``:
    :meth:`RecordQuality.to_dict`, or None): one per flag, none where nothing was flagged."""
    rq = rq or {}
    return [f"RECORD FLAG {f['text']}" for f in rq.get("flags") or []]
