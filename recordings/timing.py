"""Step 2: the sample interval, its jitter and the gaps, from the time stamps, the file's rate or ``--fs``.

With time stamps (a time column, bag header stamps, ULog timestamps) the interval ``dt`` is their span
over the gap-free runs (:func:`avbench.recordings.time_units.sample_interval`): the sum of the
within-run steps over their number, so that stamps rounded to 1 ms at 300 Hz give 300 Hz, not the
333 Hz of their median step. A step longer than ``ceil(1.5 dt / q) q`` (``q`` the stamps' resolution:
the longest step an interval of 1.5 dt gives once rounded) is a gap: the record is split into gap-free runs there, and the Allan variance leaves out
every cluster that straddles a gap (:func:`avbench.estimators.allan.variance.allan_variance_gaps`).
``--fs`` and a rate the file states (an ``fs``, ``rate`` or ``dt`` variable) are checks of the stamps:
more than 1 % apart is an error, never silently used. Without stamps the file's stated rate is the
rate (``--fs`` then a check of it), else ``--fs``. The jitter reported is the standard deviation of
the intervals within runs, relative to ``dt``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from avbench.recordings.time_units import GAP_FACTOR, sample_interval

__all__ = ["Timing", "timing_of", "check_fs", "GAP_FACTOR", "FS_TOLERANCE", "MAX_FS"]

FS_TOLERANCE = 0.01  #: --fs and the time stamps may differ by this relative amount
MAX_FS = 1e9  #: sample rates above 1 GHz are refused (no inertial sensor samples that fast)


@dataclass
class Timing:
    """How the samples lie in time: interval, where it came from, gap-free runs, jitter."""

    dt: float
    source: str
    n_samples: int
    starts: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))  # first sample of each run after a gap
    gap_seconds: np.ndarray = field(default_factory=lambda: np.zeros(0))  # missing time at each gap (s)
    jitter: float | None = None  # std of the within-run intervals / dt
    max_deviation: float | None = None  # max |interval - dt| / dt within runs
    resolution: float | None = None  # the stamps' resolution (s), None without stamps

    @property
    def fs(self) -> float:
        return 1.0 / self.dt

    @property
    def n_gaps(self) -> int:
        return int(self.starts.size)

    def longest_run(self) -> tuple[int, int]:
        """(first index, length) of the longest gap-free run."""
        s = np.concatenate(([0], self.starts))
        lengths = np.diff(np.append(s, self.n_samples))
        i = int(np.argmax(lengths))
        return int(s[i]), int(lengths[i])

    def to_dict(self) -> dict:
        return {
            "sample_interval_s": self.dt,
            "rate_hz": self.fs,
            "from": self.source,
            "n_samples": self.n_samples,
            "jitter_rel": self.jitter,
            "max_interval_deviation_rel": self.max_deviation,
            "stamp_resolution_s": self.resolution,
            "gaps": [{"before_sample": int(i), "missing_s": float(g)} for i, g in zip(self.starts, self.gap_seconds)],
        }


def check_fs(fs, option: str = "--fs") -> float:
    """A sample rate given by the user: finite, positive, at most :data:`MAX_FS`."""
    if fs is None:
        return None
    fs = float(fs)
    if not (math.isfinite(fs) and fs > 0):
        raise ValueError(f"{option}: expected a positive sample rate in Hz, got {fs!r}")
    if fs > MAX_FS:
        raise ValueError(f"{option}: expected a sample rate of at most {MAX_FS:g} Hz, got {fs!r}")
    return fs


def timing_of(time, fs, n_samples: int, path, resolution: float | None = None, stated=None) -> Timing:
    """The :class:`Timing` of a record of ``n_samples`` from its ``time`` stamps (s) or a rate.

    ``resolution``: the stamps' resolution in s (:func:`avbench.recordings.time_units.resolution`),
    which widens the gap threshold where it is coarser than the jitter allowed; ``stated``: ``(Hz,
    what)``, the rate the file states (an ``fs``/``rate``/``dt`` variable). With stamps, ``fs`` and
    ``stated`` are checks; without, the stated rate is the rate and ``fs`` a check of it."""
    fs = check_fs(fs)
    if stated is not None:
        check_fs(stated[0], f"{path}: {stated[1]}")
    if time is None:
        if stated is not None:
            if fs is not None and abs(fs / stated[0] - 1.0) > FS_TOLERANCE:
                raise ValueError(f"--fs {fs:g}: {path} states its rate as {stated[0]:.6g} Hz ({stated[1]}); expected "
                                 f"--fs to agree within {FS_TOLERANCE:.0%} or be left out")
            return Timing(1.0 / stated[0], f"the file's {stated[1]}", n_samples)
        if fs is None:
            raise ValueError(f"--fs: {path} has no time stamps; expected the sample rate as --fs HZ")
        return Timing(1.0 / fs, "--fs", n_samples)
    t = np.asarray(time, dtype=np.float64)
    if t.size != n_samples:
        raise ValueError(f"{path}: {t.size} time stamps for {n_samples} samples; expected one per sample")
    bad = ~np.isfinite(t)
    if bad.any():
        raise ValueError(f"{path}: non-finite time stamp at sample {int(np.flatnonzero(bad)[0])}; expected finite times")
    if t.size < 2:
        raise ValueError(f"{path}: one time stamp; expected a record of several samples")
    d = np.diff(t)
    back = d <= 0
    if back.any():
        i = int(np.flatnonzero(back)[0])
        raise ValueError(f"{path}: time stamps do not increase at sample {i + 1} ({t[i]!r} then {t[i + 1]!r}); "
                         "expected strictly increasing times")
    dt, gap = sample_interval(t, resolution, d)
    if not dt > 0 or not math.isfinite(1.0 / dt):
        raise ValueError(f"{path}: time stamps {dt!r} s apart; expected a positive interval")
    if fs is not None and abs(fs * dt - 1.0) > FS_TOLERANCE:
        raise ValueError(f"--fs {fs:g}: conflicts with the time stamps of {path} ({1 / dt:.6g} Hz, their span over "
                         f"their samples); expected --fs to agree within {FS_TOLERANCE:.0%} or be left out")
    if stated is not None and abs(stated[0] * dt - 1.0) > FS_TOLERANCE:
        raise ValueError(f"{path}: its {stated[1]} says {stated[0]:.6g} Hz but its time stamps give {1 / dt:.6g} Hz; "
                         "expected one rate (check --time-units, or --time none to use the stated rate)")
    if 1.0 / dt > MAX_FS:
        raise ValueError(f"{path}: time stamps {dt!r} s apart; expected a sample rate of at most {MAX_FS:g} Hz "
                         "(are the time units right? see --time-units)")
    from avbench.estimators.validation import DT_RANGE

    if dt > DT_RANGE[1]:  # the estimators' own bound, said here about the time stamps, before any fit
        raise ValueError(f"{path}: time stamps {dt:.6g} s apart; expected a sample interval of at most "
                         f"{DT_RANGE[1]:g} s (are the time units right? see --time-units)")
    starts = np.flatnonzero(gap).astype(np.int64) + 1
    within = d[~gap]
    rel = (within - dt) / dt
    return Timing(dt, "time stamps", n_samples, starts, d[gap] - dt,
                  float(np.std(rel)) if rel.size else None, float(np.max(np.abs(rel))) if rel.size else None,
                  resolution)
