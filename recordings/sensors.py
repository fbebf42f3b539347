"""Step 3: channels in SI units, grouped by sensor (gyro, accel) and axis.

Units come from the format when it defines them (``sensor_msgs/Imu``: rad/s and m/s^2, PX4
``sensor_combined``: the same; a header's bracket) or from the user (``--units`` for gyros,
``--accel-units`` for accelerometers); a user unit that contradicts the format is an error. A gyro's
unit is never guessed. An accelerometer's is, where the file and the user do not say it, read from
physics: a static accelerometer measures gravity, so the magnitude of the mean of its three axes is
9.81 m/s^2 = 1 g = 1000 mg = 10^6 ug; the unit in which it lies within :data:`GRAVITY_TOLERANCE` of
that (the windows of the four units are disjoint) is taken, and a note says so. Where none fits (a
moving record, fewer than three axes) ``--accel-units`` is asked for.

Every axis is checked before the fits: a non-finite sample, samples that overflow in SI or are
subnormal (below 2.2e-308 in SI: no estimator's arithmetic holds them) are refused; a constant axis
(all zero included) has no noise to characterise and is skipped with a note (every axis constant is
refused). Every conversion goes through :func:`avbench.noise_models.units.samples_to_si`; a factor of 1
on float64 samples keeps the file's (memory-mapped) array without a copy, so memory stays proportional
to the record.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from avbench.noise_models.units import SAMPLE_UNITS, SI_SAMPLE_UNIT, STANDARD_GRAVITY, samples_to_si

__all__ = ["SensorRecord", "to_si", "MIN_SAMPLES", "PLAUSIBLE_SI", "plausibility", "GRAVITY_TOLERANCE",
           "accel_unit_from_gravity", "check_units"]

MIN_SAMPLES = 16
#: the range (SI) the largest sample magnitude of a real sensor's record falls in: a gyro's rates up to
#: 1e3 rad/s (~57 000 deg/s, beyond every IMU's range), down to 1e-9 rad/s (below the noise of a
#: sample of the best inertial gyros, and below the earth rate every static gyro sees); an
#: accelerometer's up to 1e4 m/s^2 (~1000 g) and down to 1e-7 m/s^2 (0.01 ug). Outside it the
#: declared unit (or the column) is almost certainly wrong: :func:`plausibility` says so.
PLAUSIBLE_SI = {"gyro": (1e-9, 1e3), "accel": (1e-7, 1e4)}
_OPTION = {"gyro": "--units", "accel": "--accel-units"}
TINY = float(np.finfo(np.float64).tiny)  #: the smallest normal double
#: a static accelerometer's mean magnitude lies within this relative distance of standard gravity (local
#: gravity is 9.78-9.83 m/s^2; the rest allows for bias and scale error); 9.8x between m/s^2 and g keeps
#: the units' windows apart
GRAVITY_TOLERANCE = 0.2


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


def check_units(units=None, accel_units=None) -> None:
    """``--units`` / ``--accel-units``: a unit of :data:`~avbench.noise_models.units.SAMPLE_UNITS` (or None),
    checked before any file is read."""
    for sensor, given in (("gyro", units), ("accel", accel_units)):
        if given is not None and given not in SAMPLE_UNITS[sensor]:
            raise ValueError(f"{_OPTION[sensor]} {given}: unknown {'rate' if sensor == 'gyro' else 'acceleration'} "
                             f"unit {given!r}; expected one of {', '.join(SAMPLE_UNITS[sensor])}")


def accel_unit_from_gravity(axes) -> tuple[str | None, float]:
    """(unit, magnitude of the mean vector) of three accelerometer axes at rest (in one unknown unit): the
    unit in which that magnitude is standard gravity within :data:`GRAVITY_TOLERANCE`, None if none."""
    mean = [float(np.mean(np.asarray(x, dtype=np.float64))) for x in axes]
    m = math.sqrt(sum(v * v for v in mean))
    for unit in SAMPLE_UNITS["accel"]:
        g = m * float(samples_to_si(1.0, unit, "accel"))
        if abs(g / STANDARD_GRAVITY - 1.0) <= GRAVITY_TOLERANCE:
            return unit, m
    return None, m


def _unit(rec, sensor, given, chans):
    """(unit, note or None) of one sensor's channels: the format's, the user's, or (accelerometer) gravity's."""
    defined = {c.unit for c in chans if c.unit}
    option = _OPTION[sensor]
    if defined:
        if len(defined) > 1:
            raise ValueError(f"{rec.path}: its {sensor} columns state different units ({', '.join(sorted(defined))}); "
                             f"expected one unit per sensor")
        (unit,) = defined
        if given is not None and given != unit:
            raise ValueError(f"{option} {given}: {rec.path} ({rec.format}) defines its {sensor} samples in {unit}; "
                             f"expected {option} {unit} or no {option}")
        return unit, None
    if given is not None:
        if given not in SAMPLE_UNITS[sensor]:
            samples_to_si(1.0, given, sensor)  # raises, naming the accepted units
        if sensor == "accel" and len(chans) == 3:
            fits, m = accel_unit_from_gravity([c.values for c in chans])
            if fits is not None and fits != given:
                return given, (f"accel: the mean of its three axes has magnitude {m:.4g} {given}, which is gravity in "
                               f"{fits}, not in {given}: check --accel-units")
        return given, None
    choices = "|".join(SAMPLE_UNITS[sensor])
    if sensor == "accel" and len(chans) == 3:
        unit, m = accel_unit_from_gravity([c.values for c in chans])
        if unit is not None:
            return unit, (f"accel samples read in {unit}: the mean of the three axes has magnitude {m:.4g}, gravity "
                          f"({STANDARD_GRAVITY:g} m/s^2) in {unit}; --accel-units to override")
        raise ValueError(f"{option}: {rec.path} does not say the units of its accel samples, and the magnitude of "
                         f"their mean ({m:.4g}) is gravity in none of them (within {GRAVITY_TOLERANCE:.0%}); expected "
                         f"{option} {choices}")
    raise ValueError(f"{option}: {rec.path} does not say the units of its {sensor} samples; expected "
                     f"{option} {choices}")


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
    """The recording's channels in SI, one :class:`SensorRecord` per sensor present (gyro first); each
    axis checked as the module docstring says (constant axes skipped, with a note)."""
    check_units(units, accel_units)
    out, skipped = [], []
    for sensor, given in (("gyro", units), ("accel", accel_units)):
        chans = [c for c in rec.channels if c.sensor == sensor]
        if not chans:
            continue
        unit, note = _unit(rec, sensor, given, chans)
        if note:
            rec.notes.append(note)
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
            lo, hi = float(x.min()), float(x.max())
            if lo == hi:
                skipped.append(f"{sensor} {c.name}")
                rec.notes.append(f"{sensor} {c.name}: every sample is {lo:g} {unit}, constant: no noise to "
                                 f"characterise; this axis is skipped")
                continue
            xs = samples_to_si(x, unit, sensor)
            peak = max(abs(lo), abs(hi)) * float(samples_to_si(1.0, unit, sensor))
            if not math.isfinite(peak):
                raise ValueError(f"{rec.path}: {c.name}: samples up to {max(abs(lo), abs(hi)):.3g} {unit} overflow "
                                 f"double precision in SI ({SI_SAMPLE_UNIT[sensor]}); expected {_OPTION[sensor]} for the "
                                 f"unit of the samples")
            if peak < TINY:
                raise ValueError(f"{rec.path}: {c.name}: samples up to {peak:.3g} {SI_SAMPLE_UNIT[sensor]} are subnormal "
                                 f"numbers (below {TINY:.3g}), not a sensor's record; expected {_OPTION[sensor]} for the "
                                 f"unit of the samples, or another column")
            axis = c.axis if c.axis not in s.axes else c.name
            s.axes[axis] = xs
            note = plausibility(x, unit, sensor, c.name, given is None)
            if note:  # printed with the results ("# note:") and kept in the JSON report
                rec.notes.append(note)
            s.names[axis] = c.name
        if s.axes:
            out.append(s)
    if not out and skipped:
        raise ValueError(f"{rec.path}: every chosen axis is constant ({', '.join(skipped)}); expected a sensor's "
                         "samples (--gyro/--accel/--column to choose other columns)")
    for sensor, given in (("gyro", units), ("accel", accel_units)):
        if given is not None and not any(c.sensor == sensor for c in rec.channels):
            raise ValueError(f"{_OPTION[sensor]}: {rec.path} has no {sensor} channel chosen; expected "
                             f"{'--gyro/--column' if sensor == 'gyro' else '--accel'} with it")
    return out
