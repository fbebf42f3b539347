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

__all__ = ["SensorRecord", "to_si", "MIN_SAMPLES"]

MIN_SAMPLES = 16
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
            s.names[axis] = c.name
        out.append(s)
    for sensor, given in (("gyro", units), ("accel", accel_units)):
        if given is not None and not any(s.sensor == sensor for s in out):
            raise ValueError(f"{_OPTION[sensor]}: {rec.path} has no {sensor} channel chosen; expected "
                             f"{'--gyro/--column' if sensor == 'gyro' else '--accel'} with it")
    return out
