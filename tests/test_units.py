import math

import pytest

from avbench.noise_models import units


def test_known_conversions():
    deg = math.pi / 180
    assert units.to_si("N", 1.0, "deg/sqrt(h)") == pytest.approx(deg / 60)
    assert units.to_si("B", 1.0, "deg/h") == pytest.approx(deg / 3600)
    assert units.to_si("K", 1.0, "deg/h^1.5") == pytest.approx(deg / 3600**1.5)
    assert units.to_si("R", 1.0, "deg/h^2") == pytest.approx(deg / 3600**2)
    assert units.to_si("Q", 1.0, "urad") == 1e-6
    assert units.to_si("Q", 1.0, "arcsec") == pytest.approx(deg / 3600)
    # deg/s/sqrt(Hz) is the same quantity as deg/sqrt(s) = 60 deg/sqrt(h)
    assert units.to_si("N", 1.0, "deg/s/sqrt(Hz)") == pytest.approx(units.to_si("N", 60.0, "deg/sqrt(h)"))


@pytest.mark.parametrize("coef", units.COEFFICIENTS)
def test_round_trip(coef):
    for u in units.units_for(coef):
        assert units.from_si(coef, units.to_si(coef, 3.7, u), u) == pytest.approx(3.7)


@pytest.mark.parametrize(
    "coef, q, msg",
    [
        ("N", (1.0, "deg/h"), "unknown unit"),
        ("N", -1.0, "non-negative"),
        ("N", float("nan"), "non-negative"),
        ("X", 1.0, "unknown coefficient"),
        ("B", (1.0,), "pair"),
        ("B", "3", "number"),
    ],
)
def test_bad_quantities(coef, q, msg):
    with pytest.raises(ValueError, match=msg):
        units.as_si(coef, q)


def test_rate_units():
    assert units.rate_to_si(1.0, "deg/s") == pytest.approx(math.pi / 180)
    with pytest.raises(ValueError, match="unknown rate unit"):
        units.rate_to_si(1.0, "furlong/fortnight")
