"""Steps 1-3 in one call: a recording file read (:mod:`~avbench.recordings.readers`), timed
(:mod:`~avbench.recordings.timing`) and converted to SI (:mod:`~avbench.recordings.sensors`), as every
command that reads a recording reads it (``avbench estimate``, ``avbench deviations``).

:func:`load_recording` takes the reader options as keywords named as the command line's options
(:data:`READER_OPTIONS`: ``--accel-units`` is ``accel_units``) and returns a :class:`LoadedRecording`:
the file's :class:`~avbench.recordings.readers.Recording` (format, topic, time source, and the notes the
readers and the unit checks wrote), its :class:`~avbench.recordings.timing.Timing` and one
:class:`~avbench.recordings.sensors.SensorRecord` per sensor in SI. :func:`pool_recordings` makes one
record of several recordings of one sensor (``--combine``: file boundaries are gaps).

Example::

    from avbench.recordings import load_recording

    rec = load_recording("imu.csv", units="deg/s", accel_units="g")   # time from the 't' column
    print(rec.timing.fs, [s.sensor for s in rec.sensors], rec.notes)
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from avbench.recordings.readers import Recording, read_recording
from avbench.recordings.sensors import SensorRecord, check_units, to_si
from avbench.recordings.time_units import check_time_units, coarse, gap_threshold
from avbench.recordings.timing import FS_TOLERANCE, Timing, check_fs, timing_of

__all__ = ["READER_OPTIONS", "LoadedRecording", "load_recording", "check_reader_options", "reader_options_of",
           "pool_recordings"]

#: the reader options: the keywords of :func:`load_recording`, the dests of the command line's options
READER_OPTIONS = ("fs", "units", "accel_units", "column", "gyro", "accel", "time", "time_units", "topic")


class LoadedRecording(NamedTuple):
    """A recording as read: the file's channels and notes, its timing, its sensors in SI."""

    recording: Recording
    timing: Timing
    sensors: list[SensorRecord]

    @property
    def notes(self) -> list[str]:
        """What the readers and the unit checks said about the file (inferred time units, implausible
        magnitudes, re-sorted messages, ...)."""
        return self.recording.notes

    @property
    def path(self):
        return self.recording.path


def check_reader_options(*, fs=None, units=None, accel_units=None, column=None, gyro=None, accel=None, time=None,
                         time_units=None, topic=None) -> None:
    """Refuse, before any file is read, reader options that are wrong by themselves or together: a sample
    rate that is not one, an unknown sample or time unit, a gyro chosen both as ``column`` and ``gyro``."""
    check_fs(fs)
    check_units(units, accel_units)
    check_time_units(time_units)
    if column is not None and gyro is not None:
        raise ValueError("--column: give either --column or --gyro, not both")


def load_recording(path, *, fs=None, units=None, accel_units=None, column=None, gyro=None, accel=None, time=None,
                   time_units=None, topic=None, progress=False) -> LoadedRecording:
    """Read ``path`` (any format of :mod:`avbench.recordings.readers`) into its SI sensor records and timing.

    ``fs``: sample rate in Hz, needed when the file has neither time stamps nor a stated rate, else only
    checked against them (and choosing between two plausible time units);
    ``units`` / ``accel_units``: the gyro / accelerometer sample units when the file does not state
    them (never guessed); ``column``: one gyro column of a table; ``gyro`` / ``accel``: columns of a
    table or arrays of an .npz/.mat (names or indices, comma-separated); ``time``: the time column
    (``"none"`` to ignore one); ``time_units``: s, ms, us or ns (default: the header's, else from the
    stamps); ``topic``: the ``sensor_msgs/Imu`` topic of a bag; ``progress``: a progress bar while a
    bag is read. Every problem is a ``ValueError`` naming the file or the option.
    """
    check_reader_options(fs=fs, units=units, accel_units=accel_units, column=column, gyro=gyro, accel=accel, time=time,
                         time_units=time_units, topic=topic)
    rec = read_recording(path, gyro=gyro if gyro is not None else column, accel=accel, time_column=time,
                         time_units=time_units, topic=topic, progress=progress, fs=fs)
    timing = timing_of(rec.time, fs, rec.n_samples, rec.path, rec.time_resolution, rec.rate)
    if rec.time is None and rec.rate is not None:
        rec.notes.append(f"sample rate {rec.rate[0]:.6g} Hz from the file's {rec.rate[1]}")
    if coarse(timing.dt, timing.resolution):
        rec.notes.append(f"time stamps resolved to {timing.resolution:.3g} s, {timing.resolution / timing.dt:.0%} of "
                         f"the interval: the rate is their span over the samples ({timing.fs:.6g} Hz), and steps "
                         f"up to {gap_threshold(timing.dt, timing.resolution):.3g} s are not gaps")
    return LoadedRecording(rec, timing, to_si(rec, units, accel_units))


def reader_options_of(namespace) -> dict:
    """The reader options of a parsed command line (an ``argparse.Namespace``), as keywords of
    :func:`load_recording`."""
    return {name: getattr(namespace, name) for name in READER_OPTIONS}


def pool_recordings(loaded: list[LoadedRecording]) -> tuple[Timing, list[SensorRecord]]:
    """One (timing, sensors) from several recordings of one sensor: concatenated, file boundaries are
    gaps (their missing time NaN). The recordings must hold the same sensors and axes, sampled at one
    rate (within :data:`~avbench.recordings.timing.FS_TOLERANCE`)."""
    from avbench.recordings.files import check_distinct

    check_distinct([rec.path for rec, _, _ in loaded], [f"--combine: recording {k + 1} ({rec.path})"
                                                        for k, (rec, _, _) in enumerate(loaded)])
    rec0, t0, s0 = loaded[0]
    layout = [(s.sensor, tuple(s.axes)) for s in s0]
    for rec, t, s in loaded[1:]:
        if [(x.sensor, tuple(x.axes)) for x in s] != layout:
            raise ValueError(f"--combine: {rec.path} has other sensors/axes than {rec0.path}; expected recordings of one sensor")
        if abs(t.dt / t0.dt - 1) > FS_TOLERANCE:
            raise ValueError(f"--combine: {rec.path} is sampled at {t.fs:.6g} Hz, {rec0.path} at {t0.fs:.6g} Hz; "
                             "expected one sample rate")
    offsets = np.cumsum([0] + [t.n_samples for _, t, _ in loaded[:-1]])
    starts = np.concatenate([np.concatenate(([o] if o else [], t.starts + o)) for o, (_, t, _) in zip(offsets, loaded)])
    gaps = np.concatenate([np.concatenate(([np.nan] if o else [], t.gap_seconds)) for o, (_, t, _) in zip(offsets, loaded)])
    n = int(sum(t.n_samples for _, t, _ in loaded))
    timing = Timing(t0.dt, t0.source + f" ({len(loaded)} recordings pooled; file boundaries are gaps)", n,
                    starts.astype(np.int64), gaps, t0.jitter, t0.max_deviation, t0.resolution)
    sensors = []
    for k, s in enumerate(s0):
        axes = {a: np.concatenate([np.asarray(sl[k].axes[a]) for _, _, sl in loaded]) for a in s.axes}
        sensors.append(SensorRecord(s.sensor, s.unit_in, axes, s.names))
    return timing, sensors
