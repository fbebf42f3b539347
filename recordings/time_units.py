"""Time stamps to seconds by one plausibility rule: the unit, the counter's wrap, the stamps' resolution.

A time column is a list of stamps in some unit (s, ms, us or ns) from some origin (boot, the epoch, a
counter's last wrap). What the stamps say about themselves decides their unit:

* **The sample interval** of stamps ``t`` (:func:`sample_interval`) is their span over the gap-free
  runs: ``dt = sum of the within-run steps / their number``, not the median step. A step is a gap when
  it is longer than ``ceil(GAP_FACTOR dt / q) q`` (:func:`gap_threshold`), the longest step an interval
  of ``GAP_FACTOR dt`` gives once its ends are rounded to the stamps' resolution ``q``
  (:func:`resolution`): stamps resolved to 1 ms at 800 Hz step 1 ms and 2 ms without missing a sample.
  The first ``dt`` is the median over blocks of :data:`BLOCK` steps (resolution and jitter averaged),
  then the span rule is applied twice.
* **The unit** (:func:`choose_unit`) is the one whose rate ``1 / dt`` is a rate an IMU samples at
  (:data:`PLAUSIBLE_RATE`). Units are 1000x apart and that range is wider, so two units can stay
  plausible (integer stamps 125 apart: 8 Hz in ms, 8 kHz in us); then the one that puts the first stamp
  on a date between 1990 and now (an epoch stamp) is taken, else the one whose rate agrees with
  ``--fs`` or the file's stated rate, else the reading is refused, naming ``--time-units``. No
  plausible unit is refused as well. The date is a tie-break, not a proof: stamps since boot read in a
  unit 1000x too coarse fall after 1990 once the device has run 7.3 days (6.3e8 ms), so ms since boot
  at 1 kHz or more, logged after a week of uptime, are read as seconds (``--time-units ms`` reads them). A unit the header declares is held to the same range (a refusal
  names ``--time-units`` to confirm it); a unit the format defines (bags: ns, ULog: us) and
  ``--time-units`` are taken as given.
* **A wrapping counter** (:func:`unwrap_counter`): integer stamps that fall back by more than half of
  2^16 or 2^32, where every stamp lies in [0, 2^W), are a W-bit counter that wrapped; 2^W is added
  from each wrap on (a note says how many).
* **Resolution** ``q``: the greatest common divisor of the steps of integer stamps; for floats, the
  coarser of their float spacing at the largest stamp (float32 stamps of 1e5 s are 7.8 ms apart) and
  the decimal quantum they are written to (``%.3f`` seconds: 1 ms).

The rule is tested over generated stamps (unit, origin, rate, rounding, dtype) in
``tests/test_reading_rules.py``.
"""

from __future__ import annotations

import math
import time as _time
from dataclasses import dataclass

import numpy as np

__all__ = ["TIME_SCALE", "PLAUSIBLE_RATE", "EPOCH_START", "GAP_FACTOR", "BLOCK", "Stamps", "resolution",
           "sample_interval", "gap_threshold", "coarse", "unwrap_counter", "choose_unit", "stamps_in_seconds",
           "check_time_units"]

#: seconds per unit of a time column
TIME_SCALE = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
#: the rates an IMU samples at (Hz): from 1 Hz logs of navigation-grade units to the 32 kHz of the
#: fastest MEMS output data rates (ICM-42688)
PLAUSIBLE_RATE = (1.0, 32_000.0)
#: an epoch stamp lies between 1990-01-01 (in s since 1970) and the time of reading
EPOCH_START = 631_152_000.0
GAP_FACTOR = 1.5  #: a step longer than this many dt (and than the resolution allows) is a gap
BLOCK = 16  #: steps per block of the first, median estimate of dt
_SAMPLE = 100_000  #: stamps looked at for the resolution
_COUNTER_BITS = (16, 32)


@dataclass
class Stamps:
    """Raw time stamps as a file holds them, with what the file says of their unit."""

    values: np.ndarray
    what: str  # "column 't'", "variable 'imu.t'", "header stamps"
    declared: str | None = None  # the unit the header or the format states
    declared_by: str | None = None  # "the header", "the format"


def check_time_units(units) -> None:
    """``--time-units``: one of :data:`TIME_SCALE` (or None)."""
    if units is not None and units not in TIME_SCALE:
        raise ValueError(f"--time-units: expected one of {', '.join(TIME_SCALE)}, got {units!r}")


def resolution(t) -> float | None:
    """The resolution of stamps ``t`` in their own unit (see the module docstring); None for fewer than two."""
    t = np.asarray(t)
    if t.size < 2:
        return None
    head = t[: _SAMPLE + 1]
    if t.dtype.kind in "iu":
        d = np.diff(head.astype(np.int64))
        d = d[d > 0]
        return float(np.gcd.reduce(d)) if d.size else None
    big = max(abs(float(np.nanmax(t))), abs(float(np.nanmin(t))))  # two passes, no copy of a large record
    ulp = float(np.spacing(t.dtype.type(big))) if math.isfinite(big) else 0.0
    rel = head.astype(np.float64) - float(head[0])
    if not np.all(np.isfinite(rel)):
        return ulp
    tol = 4 * float(np.spacing(np.float64(big)))  # what float64 keeps of a stamp of this size
    for digits in range(10):
        q = 10.0 ** -digits
        if np.all(np.abs(rel - np.round(rel / q) * q) <= max(tol, 1e-6 * q)):
            return max(q, ulp)
    return ulp


def gap_threshold(dt: float, q: float | None) -> float:
    """The longest step that is not a gap: ``ceil(GAP_FACTOR dt / q) q``, the longest step an interval of
    ``GAP_FACTOR dt`` gives once both its ends are rounded to ``q`` (``GAP_FACTOR dt`` without ``q``),
    and a millionth more (the rounding of stamps converted to seconds)."""
    if q is None or not q > 0:
        return GAP_FACTOR * dt * (1 + 1e-6)
    return math.ceil(GAP_FACTOR * dt / q - 1e-6) * q * (1 + 1e-6)


def coarse(dt: float, q: float | None) -> bool:
    """True where stamps resolved to ``q`` cannot step by ``dt`` every time: ``dt`` is not a whole number of
    ``q`` (to 1 %), so the steps alternate between multiples of ``q`` and only their span gives ``dt``."""
    if q is None or not q > 0:
        return False
    k = dt / q
    return abs(k - round(k)) > 0.01


def sample_interval(t, q: float | None = None, d=None) -> tuple[float, np.ndarray]:
    """``(dt, gap)`` of increasing stamps ``t`` (any unit; ``q`` their resolution in it): the span of the
    gap-free runs over their steps, and the boolean mask of the steps that are gaps. ``d``: the steps
    ``np.diff(t)`` when the caller has them (a large record's steps are not made twice)."""
    t = np.asarray(t)
    if d is None:
        d = np.diff(t.astype(np.int64)) if t.dtype.kind in "iu" else np.diff(t.astype(np.float64))
    if d.size == 0:
        raise ValueError("one stamp has no interval")
    k = min(BLOCK, d.size)
    tf = t.astype(np.float64) if t.dtype.kind == "f" else None
    if tf is not None:
        blocks = (tf[k::k] - tf[:-k:k]) / k
    else:
        ti = t.astype(np.int64)
        blocks = (ti[k::k] - ti[:-k:k]).astype(np.float64) / k
    dt = float(np.median(blocks)) if blocks.size else float(np.median(d))
    gap = np.zeros(d.size, dtype=bool)
    for _ in range(3):
        gap = d > gap_threshold(dt, q)
        within = d[~gap]
        if within.size == 0:
            break
        dt = float(within.sum()) / within.size
    return dt, gap


def unwrap_counter(t) -> tuple[np.ndarray, str | None]:
    """``(stamps, note)``: integer stamps of a W-bit counter with 2^W added from each wrap on (see the
    module docstring), or the stamps unchanged and None."""
    t = np.asarray(t)
    if t.dtype.kind not in "iu" or t.size < 2:
        return t, None
    t = t.astype(np.int64)
    d = np.diff(t)
    back = d < 0
    if not back.any():
        return t, None
    lo, hi = int(t.min()), int(t.max())
    for bits in _COUNTER_BITS:
        span = 1 << bits
        if lo >= 0 and hi < span and np.all(d[back] < -span // 2):
            wraps = np.concatenate(([0], np.cumsum(back))).astype(np.int64)
            return t + wraps * span, f"a {bits}-bit counter: it wraps {int(back.sum())} time(s), unwrapped"
    return t, None


def _rate_text(hz: float) -> str:
    return f"{hz:.4g} Hz"


def choose_unit(path, what, dt_raw: float, first: float, hint: tuple[float, str] | None = None) -> tuple[str, str]:
    """``(unit, how)`` of stamps whose interval is ``dt_raw`` in their own unit and whose first stamp is
    ``first``: the rule of the module docstring. ``hint``: ``(rate in Hz, its source)`` from ``--fs`` or
    the file, used only to choose between plausible units. A ``ValueError`` naming ``--time-units``
    where no unit or more than one stays plausible."""
    rates = {u: 1.0 / (dt_raw * s) for u, s in TIME_SCALE.items()}
    lo, hi = PLAUSIBLE_RATE
    plausible = [u for u, r in rates.items() if lo <= r <= hi]
    band = f"{lo:g} Hz to {hi / 1000:g} kHz"
    if len(plausible) == 1:
        u = plausible[0]
        return u, f"its interval, {dt_raw:.6g} {u} = {_rate_text(rates[u])} (no other unit gives an IMU's rate, {band})"
    if not plausible:
        shown = ", ".join(f"{_rate_text(r)} as {u}" for u, r in rates.items())
        raise ValueError(f"{path}: {what}: no time unit makes its interval ({dt_raw:.6g}) a rate an IMU samples at "
                         f"({band}): {shown}; expected --time-units s|ms|us|ns, or --time none with --fs")
    now = _time.time()
    epoch = [u for u in plausible if EPOCH_START <= first * TIME_SCALE[u] <= now]
    if len(epoch) == 1:
        u = epoch[0]
        return u, (f"its interval, {_rate_text(rates[u])} as {u}, and its first stamp, a date in "
                   f"{_time.gmtime(first * TIME_SCALE[u]).tm_year} as {u} since 1970")
    if hint is not None:
        agree = [u for u in plausible if abs(rates[u] / hint[0] - 1.0) <= 0.01]
        if len(agree) == 1:
            u = agree[0]
            return u, f"its interval, {_rate_text(rates[u])} as {u}, as {hint[1]} says"
    shown = " and ".join(f"{_rate_text(rates[u])} as {u}" for u in plausible)
    raise ValueError(f"{path}: {what}: its interval ({dt_raw:.6g}) gives {shown}, each a rate an IMU samples at; "
                     f"expected --time-units {' or --time-units '.join(plausible)} (or --fs HZ to choose)")


def stamps_in_seconds(path, stamps: Stamps, time_units=None, hint=None):
    """``(seconds since the first stamp (float64), unit, how, resolution in s, notes)`` of raw ``stamps``.

    The unit: ``time_units`` if given; else a unit the format defines; else the header's, held to
    :data:`PLAUSIBLE_RATE`; else :func:`choose_unit`. Non-finite or non-increasing stamps (after a
    counter's wrap is undone) are a ``ValueError`` naming the sample."""
    check_time_units(time_units)
    t = np.asarray(stamps.values)
    what = stamps.what
    if t.ndim != 1 or t.size == 0:
        raise ValueError(f"{path}: {what} has shape {t.shape}; expected one time stamp per sample")
    if t.dtype.kind not in "iuf":
        raise ValueError(f"{path}: {what} is not numeric (dtype {t.dtype}); expected time stamps")
    notes = []
    if t.dtype.kind == "f":
        bad = ~np.isfinite(t)
        if bad.any():
            raise ValueError(f"{path}: non-finite time stamp at sample {int(np.flatnonzero(bad)[0])}; "
                             "expected finite times")
    elif stamps.declared_by != "the format":
        t, note = unwrap_counter(t)
        if note:
            notes.append(f"{what}: {note}")
    integer = t.dtype.kind in "iu"
    if integer:
        t = t.astype(np.int64)
        d = np.diff(t)
    else:
        d = np.diff(t.astype(np.float64))
    back = np.flatnonzero(d <= 0)
    if back.size:
        i = int(back[0])
        raise ValueError(f"{path}: time stamps do not increase at sample {i + 1} ({t[i]!r} then {t[i + 1]!r}); "
                         "expected strictly increasing times")
    del back
    q = resolution(t)
    if time_units is not None:
        unit, how = time_units, "--time-units"
    elif stamps.declared is not None and stamps.declared_by == "the format":
        unit, how = stamps.declared, stamps.declared_by
    elif t.size < 2:
        unit, how = stamps.declared or "s", stamps.declared_by or "the default (one stamp)"
    else:
        dt_raw, _ = sample_interval(t, q, d)
        if stamps.declared is not None:
            unit, how = stamps.declared, stamps.declared_by or "the header"
            rate = 1.0 / (dt_raw * TIME_SCALE[unit])
            lo, hi = PLAUSIBLE_RATE
            if not lo <= rate <= hi:
                raise ValueError(f"{path}: {what}: {how} says {unit}, which makes {_rate_text(rate)}, not a rate an "
                                 f"IMU samples at ({lo:g} Hz to {hi / 1000:g} kHz); expected --time-units to confirm "
                                 f"or correct it")
        else:
            unit, how = choose_unit(path, what, dt_raw, float(t[0]), hint)
            notes.append(f"{what} read in {unit}: from {how}; --time-units to override")
    del d
    scale = TIME_SCALE[unit]
    rel = (t - t[0]) if integer else (t.astype(np.float64) - float(t[0]))
    seconds = np.asarray(rel, dtype=np.float64) * scale
    return seconds, unit, how, (None if q is None else q * scale), notes
