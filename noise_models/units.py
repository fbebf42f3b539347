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
    },
    "R": {
        "rad/s^2": 1.0,
        "deg/h^2": DEG / HOUR**2,
        "deg/s^2": DEG,
    },
}

# rate samples
_RATE_FACTORS: dict[str, float] = {"rad/s": 1.0, "deg/s": DEG, "deg/h": DEG / HOUR, "mrad/s": 1e-3}

#: SI unit of each coefficient.
SI_UNITS: dict[str, str] = {"Q": "rad", "N": "rad/sqrt(s)", "B": "rad/s", "K": "rad/s^1.5", "R": "rad/s^2"}

#: The units the seed papers print (Lv et al. 2015 for Q; all three for N, B, K, R).
PAPER_UNITS: dict[str, str] = {"Q": "urad", "N": "deg/sqrt(h)", "B": "deg/h", "K": "deg/h^1.5", "R": "deg/h^2"}


def _check_coef(coef: str) -> None:
    if coef not in _FACTORS:
        raise ValueError(f"unknown coefficient {coef!r}: expected one of {', '.join(COEFFICIENTS)}")


def units_for(coef: str) -> list[str]:
    """The unit strings accepted for coefficient ``coef``."""
    _check_coef(coef)
    return list(_FACTORS[coef])


def _factor(coef: str, unit: str) -> float:
    _check_coef(coef)
    try:
        return _FACTORS[coef][unit]
    except KeyError:
        raise ValueError(
            f"unknown unit {unit!r} for coefficient {coef}: expected one of {units_for(coef)}"
        ) from None


def to_si(coef: str, value, unit: str):
    """Convert ``value`` of coefficient ``coef`` from ``unit`` to SI."""
    return value * _factor(coef, unit)


def from_si(coef: str, value, unit: str):
    """Convert ``value`` of coefficient ``coef`` from SI to ``unit``."""
    return value / _factor(coef, unit)


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
