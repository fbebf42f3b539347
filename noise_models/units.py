"""Units of the Allan-variance coefficients: the one place where SI meets the papers' units.

Internally every quantity is SI: rate in rad/s, angle in rad, time in s. The five coefficients
(IEEE Std 952 / 647 conventions) then have the SI units

======  ===================  ====================================  ===============
symbol  term                 SI unit                               Allan variance
======  ===================  ====================================  ===============
Q       quantization         rad                                   3 Q^2 / tau^2
N       angle random walk    rad / s^(1/2)                         N^2 / tau
B       bias instability     rad / s                               (2 ln2 / pi) B^2
K       rate random walk     rad / s^(3/2)                         K^2 tau / 3
R       rate ramp            rad / s^2                             R^2 tau^2 / 2
======  ===================  ====================================  ===============

An accelerometer record (m/s^2) has the same five terms with their own names and units
(:data:`TERM_NAMES`, :data:`ACCEL_SI_UNITS`, :data:`ACCEL_UNITS`): Q velocity quantization (m/s),
N velocity random walk (m/s/sqrt(s), shown in m/s/sqrt(h)), B bias instability (m/s^2, shown in
ug), K acceleration random walk (m/s^2/sqrt(s) = m/s^2.5), R acceleration ramp (m/s^3). Pass
``sensor="accel"`` to :func:`to_si` / :func:`from_si`; :func:`samples_to_si` converts the samples of
either sensor (rad/s, deg/s, ... or m/s^2, g, mg, ug).

Users speak in the units of the papers (deg/sqrt(h), deg/h, ...). Every conversion goes through
:func:`to_si` and :func:`from_si`; a quantity may be given as a plain float (SI) or as a
``(value, "unit")`` pair, e.g. ``N=(2.24, "deg/sqrt(h)")``.

Examples
--------
>>> round(to_si("N", 1.0, "deg/sqrt(h)"), 12)
0.000290888209
>>> round(from_si("B", to_si("B", 20.0, "deg/h"), "deg/h"), 12)
20.0
>>> as_si("K", (62.0, "deg/h^1.5")) == to_si("K", 62.0, "deg/h^1.5")
True
"""

from __future__ import annotations

import math
from numbers import Real

__all__ = [
    "COEFFICIENTS",
    "PAPER_UNITS",
    "SI_UNITS",
    "units_for",
    "to_si",
    "from_si",
    "as_si",
    "rate_to_si",
    "SENSORS",
    "TERM_NAMES",
    "ACCEL_SI_UNITS",
    "ACCEL_UNITS",
    "DISPLAY_UNITS",
    "SAMPLE_UNITS",
    "SI_SAMPLE_UNIT",
    "samples_to_si",
    "si_units",
]

COEFFICIENTS: tuple[str, ...] = ("Q", "N", "B", "K", "R")

DEG = math.pi / 180.0
HOUR = 3600.0
ARCSEC = DEG / 3600.0

# factor such that value_in_unit * factor = value_in_SI
_FACTORS: dict[str, dict[str, float]] = {
    "Q": {
        "rad": 1.0,
        "urad": 1e-6,
        "microrad": 1e-6,
        "mrad": 1e-3,
        "deg": DEG,
        "arcsec": ARCSEC,
    },
    "N": {
        "rad/sqrt(s)": 1.0,
        "deg/sqrt(h)": DEG / math.sqrt(HOUR),
        "deg/sqrt(s)": DEG,
        "deg/s/sqrt(Hz)": DEG,
        "deg/h/sqrt(Hz)": DEG / HOUR,
        "rad/s/sqrt(Hz)": 1.0,
    },
    "B": {
        "rad/s": 1.0,
        "deg/h": DEG / HOUR,
        "deg/s": DEG,
    },
    "K": {
        "rad/s^1.5": 1.0,
        "rad/s/sqrt(s)": 1.0,
        "deg/h^1.5": DEG / HOUR**1.5,
        "deg/h/sqrt(h)": DEG / HOUR**1.5,
        "deg/s^1.5": DEG,
        "rad/s^2/sqrt(Hz)": 1.0,
    },
    "R": {
        "rad/s^2": 1.0,
        "deg/h^2": DEG / HOUR**2,
        "deg/s^2": DEG,
    },
}

STANDARD_GRAVITY = 9.80665  # m/s^2 (CGPM 1901)

# accelerometer coefficients: value_in_unit * factor = value_in_SI (m/s, m/s/sqrt(s), m/s^2, ...)
_ACCEL_FACTORS: dict[str, dict[str, float]] = {
    "Q": {"m/s": 1.0, "mm/s": 1e-3},
    "N": {
        "m/s/sqrt(s)": 1.0,
        "m/s^2/sqrt(Hz)": 1.0,
        "m/s/sqrt(h)": 1.0 / math.sqrt(HOUR),
        "ug/sqrt(Hz)": 1e-6 * STANDARD_GRAVITY,
        "mg/sqrt(Hz)": 1e-3 * STANDARD_GRAVITY,
    },
    "B": {"m/s^2": 1.0, "ug": 1e-6 * STANDARD_GRAVITY, "mg": 1e-3 * STANDARD_GRAVITY},
    "K": {
        "m/s^2.5": 1.0,
        "m/s^2/sqrt(s)": 1.0,
        "m/s^3/sqrt(Hz)": 1.0,
        "m/s^2/sqrt(h)": 1.0 / math.sqrt(HOUR),
        "ug/sqrt(s)": 1e-6 * STANDARD_GRAVITY,
    },
    "R": {"m/s^3": 1.0, "m/s^2/h": 1.0 / HOUR},
}

# rate samples
_RATE_FACTORS: dict[str, float] = {"rad/s": 1.0, "deg/s": DEG, "deg/h": DEG / HOUR, "mrad/s": 1e-3}

_ACCEL_SAMPLE_FACTORS: dict[str, float] = {
    "m/s^2": 1.0,
    "g": STANDARD_GRAVITY,
    "mg": 1e-3 * STANDARD_GRAVITY,
    "ug": 1e-6 * STANDARD_GRAVITY,
}

#: The two kinds of inertial sensor whose records avbench reads.
SENSORS: tuple[str, ...] = ("gyro", "accel")

#: Names of the five terms for each sensor.
TERM_NAMES: dict[str, dict[str, str]] = {
    "gyro": {"Q": "angle quantization", "N": "angle random walk", "B": "bias instability",
             "K": "rate random walk", "R": "rate ramp"},
    "accel": {"Q": "velocity quantization", "N": "velocity random walk", "B": "bias instability",
              "K": "acceleration random walk", "R": "acceleration ramp"},
}

#: SI unit of each accelerometer coefficient.
ACCEL_SI_UNITS: dict[str, str] = {"Q": "m/s", "N": "m/s/sqrt(s)", "B": "m/s^2", "K": "m/s^2.5", "R": "m/s^3"}

#: The units accelerometer coefficients are usually quoted in (VRW in m/s/sqrt(h), B in ug).
ACCEL_UNITS: dict[str, str] = {"Q": "m/s", "N": "m/s/sqrt(h)", "B": "ug", "K": "m/s^2/sqrt(h)", "R": "m/s^2/h"}

#: Units of the samples of each sensor accepted by :func:`samples_to_si`, and their SI unit.
SAMPLE_UNITS: dict[str, tuple[str, ...]] = {"gyro": ("rad/s", "deg/s", "deg/h", "mrad/s"),
                                            "accel": tuple(_ACCEL_SAMPLE_FACTORS)}
SI_SAMPLE_UNIT: dict[str, str] = {"gyro": "rad/s", "accel": "m/s^2"}

#: SI unit of each coefficient.
SI_UNITS: dict[str, str] = {"Q": "rad", "N": "rad/sqrt(s)", "B": "rad/s", "K": "rad/s^1.5", "R": "rad/s^2"}

#: The units the seed papers print (Lv et al. 2015 for Q; all three for N, B, K, R).
PAPER_UNITS: dict[str, str] = {"Q": "urad", "N": "deg/sqrt(h)", "B": "deg/h", "K": "deg/h^1.5", "R": "deg/h^2"}


#: Units in which tables print each sensor's coefficients.
DISPLAY_UNITS: dict[str, dict[str, str]] = {"gyro": PAPER_UNITS, "accel": ACCEL_UNITS}


def _table(sensor: str) -> dict[str, dict[str, float]]:
    if sensor == "gyro":
        return _FACTORS
    if sensor == "accel":
        return _ACCEL_FACTORS
    raise ValueError(f"unknown sensor {sensor!r}: expected one of {', '.join(SENSORS)}")


def si_units(sensor: str = "gyro") -> dict[str, str]:
    """SI unit of each coefficient of ``sensor`` ("gyro" or "accel")."""
    _table(sensor)
    return SI_UNITS if sensor == "gyro" else ACCEL_SI_UNITS


def _check_coef(coef: str) -> None:
    if coef not in _FACTORS:
        raise ValueError(f"unknown coefficient {coef!r}: expected one of {', '.join(COEFFICIENTS)}")


def units_for(coef: str, sensor: str = "gyro") -> list[str]:
    """The unit strings accepted for coefficient ``coef`` of ``sensor``."""
    _check_coef(coef)
    return list(_table(sensor)[coef])


def _factor(coef: str, unit: str, sensor: str = "gyro") -> float:
    _check_coef(coef)
    try:
        return _table(sensor)[coef][unit]
    except KeyError:
        raise ValueError(
            f"unknown unit {unit!r} for {sensor} coefficient {coef}: expected one of {units_for(coef, sensor)}"
        ) from None


def to_si(coef: str, value, unit: str, sensor: str = "gyro"):
    """Convert ``value`` of coefficient ``coef`` of ``sensor`` ("gyro", "accel") from ``unit`` to SI.

    >>> round(to_si("B", 50.0, "ug", sensor="accel"), 12)
    0.0004903325
    """
    return value * _factor(coef, unit, sensor)


def from_si(coef: str, value, unit: str, sensor: str = "gyro"):
    """Convert ``value`` of coefficient ``coef`` of ``sensor`` from SI to ``unit``."""
    return value / _factor(coef, unit, sensor)


def as_si(coef: str, quantity) -> float:
    """Read a coefficient given as an SI float or as a ``(value, unit)`` pair; return SI.

    Raises ``ValueError`` for a negative or non-finite value, an unknown unit, or a malformed pair.
    """
    _check_coef(coef)
    if isinstance(quantity, tuple | list):
        if len(quantity) != 2 or not isinstance(quantity[1], str):
            raise ValueError(
                f"{coef}: expected a float in SI or a (value, 'unit') pair, got {quantity!r}"
            )
        value = to_si(coef, _real(coef, quantity[0]), quantity[1])
    else:
        value = _real(coef, quantity)
    if not math.isfinite(value) or value < 0:
        raise ValueError(f"{coef}: expected a finite, non-negative value, got {value!r}")
    return float(value)


def _real(name: str, value) -> float:
    if isinstance(value, bool) or not isinstance(value, Real):
        raise ValueError(f"{name}: expected a number, got {value!r}")
    return float(value)


def rate_to_si(values, unit: str):
    """Convert rate samples from ``unit`` (rad/s, deg/s, deg/h, mrad/s) to rad/s."""
    try:
        return values * _RATE_FACTORS[unit]
    except KeyError:
        raise ValueError(f"unknown rate unit {unit!r}: expected one of {list(_RATE_FACTORS)}") from None


def samples_to_si(values, unit: str, sensor: str = "gyro"):
    """Convert samples of ``sensor`` from ``unit`` to SI (rad/s for a gyro, m/s^2 for an accelerometer).

    A factor of exactly 1 returns ``values`` unchanged (no copy of a large record).
    """
    if sensor == "gyro":
        if unit not in _RATE_FACTORS:
            raise ValueError(f"unknown rate unit {unit!r}: expected one of {list(_RATE_FACTORS)}")
        f = _RATE_FACTORS[unit]
    elif sensor == "accel":
        if unit not in _ACCEL_SAMPLE_FACTORS:
            raise ValueError(f"unknown acceleration unit {unit!r}: expected one of {list(_ACCEL_SAMPLE_FACTORS)}")
        f = _ACCEL_SAMPLE_FACTORS[unit]
    else:
        raise ValueError(f"unknown sensor {sensor!r}: expected one of {', '.join(SENSORS)}")
    return values if f == 1.0 else values * f
