"""Step 3: channels in SI units, grouped by sensor (gyro, accel) and axis.

Units come from the format when it defines them (``sensor_msgs/Imu``: rad/s and m/s^2, PX4
``sensor_combined``: the same) or from the user (``--units`` for gyros, ``--accel-units`` for
accelerometers); there is no silent default, and a user unit that contradicts the format is an
error. Every conversion goes through :func:`avbench.noise_models.units.samples_to_si`; a factor of 1 on
float64 samples keeps the file's (memory-mapped) array without a copy, so memory stays proportional
to the record.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from avbench.noise_models.units import SAMPLE_UNITS, SI_SAMPLE_UNIT, samples_to_si

__all__ = ["SensorRecord", "to_si", "MIN_SAMPLES", "PLAUSIBLE_SI", "plausibility"]

MIN_SAMPLES = 16
#: the range (SI) the largest sample magnitude of a real sensor's record falls in: a gyro's rates up to
#: 1e3 rad/s (~57 000 deg/s, beyond every IMU's range), down to 1e-9 rad/s (below the noise of a
#: sample of the best inertial gyros, and below the earth rate every static gyro sees); an
#: accelerometer's up to 1e4 m/s^2 (~1000 g) and down to 1e-7 m/s^2 (0.01 ug). Outside it the
#: declared unit (or the column) is almost certainly wrong: :func:`plausibility` says so.
PLAUSIBLE_SI = {"gyro": (1e-9, 1e3), "accel": (1e-7, 1e4)}
_OPTION = {"gyro": "--units", "accel": "--accel-units"}


@dataclass
class SensorRecord:
    """The axes of one sensor in SI (rad/s or m/s^2), and the units they were given in."""

    sensor: str
    unit_in: str
    axes: dict[str, np.ndarray] = field(default_factory=dict)
    names: dict[str, str] = field(default_factory=dict)  # axis -> channel name in the file

    @property
    def si_unit(self) -> str:
        return SI_SAMPLE_UNIT[self.sensor]


def _unit(rec, sensor, given):
    defined = {c.unit for c in rec.channels if c.sensor == sensor and c.unit}
    option = _OPTION[sensor]
    if defined:
        (unit,) = defined
        if given is not None and given != unit:
            raise ValueError(f"{option} {given}: {rec.path} ({rec.format}) defines its {sensor} samples in {unit}; "
                             f"expected {option} {unit} or no {option}")
        return unit
    if given is None:
        raise ValueError(f"{option}: {rec.path} does not say the units of its {sensor} samples; expected "
                         f"{option} {'|'.join(SAMPLE_UNITS[sensor])}")
    if given not in SAMPLE_UNITS[sensor]:
        samples_to_si(1.0, given, sensor)  # raises, naming the accepted units
    return given


def plausibility(x, unit, sensor, name="samples", from_format=False) -> str | None:
    """A sentence if the largest magnitude of ``x`` (in ``unit``) is outside what a real ``sensor`` records
    (:data:`PLAUSIBLE_SI`, converted to ``unit``), saying what was expected; else None. A general rule
    per declared unit, not a list of cases (1e297 rad/s, 1e-12 rad/s written as deg/s, a record of
    zeros). A wrong unit within the range (deg/s read as rad/s) is not detectable this way."""
    peak = float(np.max(np.abs(x))) if x.size else 0.0
    lo_si, hi_si = PLAUSIBLE_SI[sensor]
    per_unit = float(samples_to_si(1.0, unit, sensor))  # SI value of 1 unit
    lo, hi = lo_si / per_unit, hi_si / per_unit
    si = SI_SAMPLE_UNIT[sensor]
    if lo <= peak <= hi:
        return None
    what = "rates" if sensor == "gyro" else "accelerations"
    source = "the format's unit" if from_format else f"check {_OPTION[sensor]} and the column"
    if peak == 0.0:
        return f"{name}: every sample is zero; a {sensor}'s {what} are expected to vary ({source})"
    side = "above" if peak > hi else "below"
    in_si = "" if per_unit == 1.0 else f" ({peak * per_unit:.3g} {si})"
    range_si = "" if per_unit == 1.0 else f" ({lo_si:g} to {hi_si:g} {si})"
    return (f"{name}: samples up to {peak:.3g} {unit}{in_si}, {side} what a {sensor} records; expected largest "
            f"magnitudes between {lo:.3g} and {hi:.3g} {unit}{range_si}: {source}")


def to_si(rec, units=None, accel_units=None) -> list[SensorRecord]:
    """The recording's channels in SI, one :class:`SensorRecord` per sensor present (gyro first)."""
    out = []
    for sensor, given in (("gyro", units), ("accel", accel_units)):
        chans = [c for c in rec.channels if c.sensor == sensor]
        if not chans:
            continue
        unit = _unit(rec, sensor, given)
        s = SensorRecord(sensor, unit)
        for c in chans:
            x = c.values
            if x.dtype != np.float64:
                x = x.astype(np.float64)
            if x.size < MIN_SAMPLES:
                raise ValueError(f"{rec.path}: {x.size} samples; expected at least {MIN_SAMPLES}")
            bad = ~np.isfinite(x)
            if bad.any():
                raise ValueError(f"{rec.path}: {c.name}: {int(bad.sum())} non-finite sample(s) (NaN/inf), the first at "
                                 f"index {int(np.flatnonzero(bad)[0])}; expected finite samples (mark gaps with time stamps)")
            axis = c.axis if c.axis not in s.axes else c.name
            s.axes[axis] = samples_to_si(x, unit, sensor)
            note = plausibility(x, unit, sensor, c.name, given is None)
            if note:  # printed with the results ("# note:") and kept in the JSON report
                rec.notes.append(note)
            s.names[axis] = c.name
        out.append(s)
    for sensor, given in (("gyro", units), ("accel", accel_units)):
        if given is not None and not any(s.sensor == sensor for s in out):
            raise ValueError(f"{_OPTION[sensor]}: {rec.path} has no {sensor} channel chosen; expected "
                             f"{'--gyro/--column' if sensor == 'gyro' else '--accel'} with it")
    return out
