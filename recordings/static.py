"""Step 2b: does the record look static? Said before any fit, with where it moved.

Every noise coefficient assumes a sensor at rest: a record in which the sensor moved is fitted all
the same, and every fit is then poor for a reason no fit can name. This check says so first. Per
channel (each gyro axis, each accelerometer axis and the accelerometer magnitude), in windows of
``T`` (1 s, at least :data:`MIN_WINDOW` samples) with window means ``m_k``:

* **level** -- for a sensor at rest the differences of adjacent window means are noise with
  variance ``2 AV(T)`` (the Allan variance's own definition). Their robust scale (the median
  absolute difference / 0.6745, set by the quiet windows) bounds what the noise allows; a
  difference beyond :func:`level_threshold` times it (Bonferroni over the windows at family-wise
  level :data:`FAMILY_LEVEL`) is a move, and its time is reported.
* **spread** -- a record that moves throughout has no quiet windows to set that scale, so the
  overlapping AV at the octaves ``tau`` from ``tau_s = 8 dt`` to ``T`` is also compared with the
  short-scale noise: ``ratio = max_tau AV(tau) / (AV(tau_s) tau_s / tau)`` is about 1 for white noise, a
  little above for bias instability and rate random walk below ``T = 1 s``, below for quantization,
  and far above where motion between those scales moves the level. A ratio above
  :data:`SPREAD_LIMIT` is a move.

A record that is not static is answered before any fit: the verdict, its reasons, the Allan
deviation figure and what to do (:func:`what_to_do`); nothing is fitted and no filter file is
written unless the user asks for the fits anyway (``avbench estimate --fit-not-static``,
``estimate_file(..., fit_not_static=True)``, which raises :class:`NotStaticError` otherwise). The
JSON carries the check (``static_check``). The false-alarm rate on simulated presets and on the six ADIS runs, and
the detection of simulated motion, are measured in ``tests/test_static_check.py`` and stated in
``results/README.md``.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["static_check", "level_threshold", "what_to_do", "verdict", "NotStaticError", "MIN_WINDOW", "SPREAD_LIMIT",
           "FAMILY_LEVEL", "WINDOW_S"]

WINDOW_S = 1.0  #: window length (s)
MIN_WINDOW = 32  #: at least this many samples per window
FAMILY_LEVEL = 1e-6  #: per channel: chance that a static record with Gaussian window differences flags a window
SPREAD_LIMIT = 8.0  #: AV(tau) over the white-noise extrapolation of the short-scale AV beyond which a record moves
#: (measured at rest: at most 1.9 on the simulated presets, 3.0 on the six ADIS runs; tests/test_static_check.py)
_SHORT = 8  #: tau_s = 8 dt: above the sensor's own anti-alias filter, below the window


class NotStaticError(ValueError):
    """The record is not static, and its fits were not asked for anyway: ``check`` is the static check
    (:func:`static_check`), the message its verdict and what to do."""

    def __init__(self, message: str, check: dict):
        super().__init__(message)
        self.check = check


def level_threshold(n_windows: int, level: float = FAMILY_LEVEL) -> float:
    """The |z| beyond which one of ``n_windows`` adjacent-window differences is a move: the two-sided
    Gaussian quantile at ``level / n_windows`` (Bonferroni)."""
    from scipy.special import ndtri

    return float(-ndtri(level / (2 * max(n_windows, 1))))


def _channel(x, dt, n_w, av=None):
    """The two statistics of one channel; ``av``: its octave AV already computed (an AllanResult of the
    record times any scale: the ratio does not depend on it), else computed here."""
    k = x.size // n_w
    if k < 4:
        return None
    m = np.asarray(x[: k * n_w], dtype=np.float64).reshape(k, n_w).mean(axis=1)
    d = np.diff(m)
    from avbench.estimators.allan.variance import allan_variance

    ms = _SHORT * 2 ** np.arange(int(math.log2(max(n_w // _SHORT, 1))) + 1)
    if av is not None and all(np.any(av.m == m) for m in ms):
        av = np.array([av.avar[np.flatnonzero(av.m == m)[0]] for m in ms], dtype=float)
    else:
        av = allan_variance(np.asarray(x, dtype=np.float64), dt, ms * dt).avar
    white = av[0] * ms[0] / ms  # the short-scale AV extrapolated as white noise
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.where(white > 0, av / white, np.where(av > 0, np.inf, 1.0))
    ratio = float(np.max(r))
    scale = float(np.median(np.abs(d))) / 0.6745
    z = np.abs(d) / scale if scale > 0 else np.where(d != 0, np.inf, 0.0)
    thr = level_threshold(d.size)
    moved = np.flatnonzero(z > thr)
    return {"ratio": ratio, "z_max": float(np.max(z)) if z.size else 0.0, "threshold": thr,
            "moved_windows": moved, "n_windows": int(k)}


def _spans(windows, T) -> list[tuple[float, float]]:
    """[(start s, end s)] of the runs of flagged window boundaries (a boundary k lies between windows k, k+1)."""
    out = []
    for w in windows:
        a, b = w * T, (w + 2) * T
        if out and a <= out[-1][1]:
            out[-1] = (out[-1][0], b)
        else:
            out.append((a, b))
    return out


def _without_spikes(x, mask):
    """``x`` with the samples of ``mask`` replaced by the line between their unflagged neighbours."""
    x = np.array(x, dtype=np.float64)
    keep = np.flatnonzero(~mask)
    x[mask] = np.interp(np.flatnonzero(mask), keep, x[keep])
    return x


def static_check(sensors, dt: float, avs=None, spikes=None) -> dict:
    """The check of the module docstring on SI channels (``sensors``: list of
    :class:`~avbench.recordings.sensors.SensorRecord`), as a JSON-ready dict: ``static`` (bool),
    ``reasons`` (sentences), per channel the spread ratio, the largest level z and its threshold, and
    ``moved`` (time spans, s, where a level changed). ``avs``: ``{sensor: {axis: (AllanResult, scale)}}``
    already computed by the pipeline (:func:`~avbench.recordings.fit.scaled_allan`), reused here.
    ``spikes``: per channel ("gyro x") the samples the record's quality check found to be spikes
    (:func:`avbench.recordings.quality.judge_record`): a spike is no motion, so the check reads the
    channel with them bridged (``spikes_left_out`` counts them)."""
    n_w = max(MIN_WINDOW, int(round(WINDOW_S / dt)))
    T = n_w * dt
    channels, given, spikes = {}, {}, spikes or {}
    for s in sensors:
        axes = {}
        for axis, x in s.axes.items():
            name, mask = f"{s.sensor} {axis}", spikes.get(f"{s.sensor} {axis}")
            bridged = mask is not None and 0 < mask.sum() < mask.size
            axes[axis] = _without_spikes(x, mask) if bridged else x
            channels[name] = axes[axis]
            given[name] = None if bridged else ((avs or {}).get(s.sensor, {}).get(axis) or (None,))[0]
        if s.sensor == "accel" and len(s.axes) == 3:
            a = np.sqrt(sum(np.asarray(v, dtype=np.float64) ** 2 for v in axes.values()))
            channels["accel magnitude"] = a
    out = {"static": True, "window_s": T, "spread_limit": SPREAD_LIMIT, "family_level": FAMILY_LEVEL,
           "channels": {}, "reasons": [], "moved": [],
           "spikes_left_out": {name: int(m.sum()) for name, m in spikes.items() if 0 < m.sum() < m.size}}
    spans_all = []
    for name, x in channels.items():
        r = _channel(np.asarray(x), dt, n_w, given.get(name))
        if r is None:
            continue
        spans = _spans(r["moved_windows"], T)
        out["channels"][name] = {"spread_ratio": r["ratio"], "level_z_max": r["z_max"], "level_threshold": r["threshold"],
                                 "moved_s": [list(p) for p in spans], "n_windows": r["n_windows"]}
        if r["ratio"] > SPREAD_LIMIT:
            out["reasons"].append(f"{name}: its means over 8 dt to 1 s wander {math.sqrt(r['ratio']):.3g} x more than its "
                                  f"short-scale noise allows (limit {math.sqrt(SPREAD_LIMIT):.3g} x)")
        if spans:
            where = ", ".join(f"{a:.0f}-{b:.0f} s" for a, b in spans[:5]) + (" ..." if len(spans) > 5 else "")
            out["reasons"].append(f"{name}: level jumps beyond its noise at {where} ({len(r['moved_windows'])} of "
                                  f"{r['n_windows'] - 1} window steps, largest {r['z_max']:.3g} sigma, limit "
                                  f"{r['threshold']:.3g})")
            spans_all.extend(spans)
    out["static"] = not out["reasons"]
    spans_all.sort()
    merged = []
    for a, b in spans_all:
        if merged and a <= merged[-1][1]:
            merged[-1] = (merged[-1][0], max(b, merged[-1][1]))
        else:
            merged.append((a, b))
    out["moved"] = [list(p) for p in merged]
    return out


def _quiet_stretch(moved, duration_s: float) -> tuple[float, float] | None:
    """The longest stretch of ``[0, duration_s]`` outside the spans ``moved`` (s), or None."""
    edges = [0.0] + [v for span in moved for v in span] + [duration_s]
    gaps = [(max(a, 0.0), min(b, duration_s)) for a, b in zip(edges[::2], edges[1::2])]
    gaps = [(a, b) for a, b in gaps if b > a]
    return max(gaps, key=lambda g: g[1] - g[0]) if gaps else None


def verdict(check: dict, limit: int = 4) -> str:
    """``NOT STATIC: <the first reasons>`` of a check that found motion (its reasons joined)."""
    reasons = check["reasons"]
    return "NOT STATIC: " + "; ".join(reasons[:limit]) + ("; ..." if len(reasons) > limit else "")


def what_to_do(check: dict, duration_s: float, option: str = "--fit-not-static") -> str:
    """What a user can do with a record that is not static (``check``: :func:`static_check`'s result;
    ``duration_s``: the record's length; ``option``: how the fits are asked for anyway): record at
    rest, or keep the longest stretch without moves where the moves are located, or ``option``."""
    text = ("nothing fitted: every noise coefficient assumes a sensor at rest, and a record that moved gives "
            "poor fits for a reason no fit can name. Record the sensor at rest (fixed to a stable surface, "
            "after its warm-up)")
    stretch = _quiet_stretch(check.get("moved") or [], duration_s) if check.get("moved") else None
    if stretch is not None and stretch[1] - stretch[0] >= 10 * check.get("window_s", 1.0):
        text += (f", or fit its longest stretch without moves ({stretch[0]:.0f}-{stretch[1]:.0f} s, "
                 f"{stretch[1] - stretch[0]:.0f} s), if the sensor was at rest then")
    return text + f"; {option} fits it anyway (poor fits expected; a filter file then says the record was not static)"
