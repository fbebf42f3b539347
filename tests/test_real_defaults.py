"""The default methods on the real recordings (optional: skipped unless AVBENCH_REAL_DATA names the
folder of the licensed recordings, read in place), read as ``avbench estimate``
and ``avbench.studies.real_runs`` read them: through the recordings pipeline, units from one place."""

import math

import numpy as np
import pytest

from avbench import estimators
from conftest import real_recording
from avbench.estimators.allan.variance import allan_variance
from avbench.estimators.base import DEFAULT_METHODS
from avbench.noise_models.units import DISPLAY_UNITS, from_si

ADIS, _needs_adis = real_recording("adis16405-calgary/adis_16405_imu1.npz")
MTIG, _needs_mtig = real_recording("mtig-cont-imu1/cont_imu1.npz")


def needs(test):
    return _needs_adis(_needs_mtig(test))


def _axes(path, units, accel_units=None):
    """(sensor, axis, samples in SI) of a recording, through the pipeline of ``avbench estimate``."""
    from avbench.recordings.readers import read_recording
    from avbench.recordings.sensors import to_si

    for s in to_si(read_recording(path), units, accel_units):
        for axis, x in s.axes.items():
            yield s.sensor, axis, x


@pytest.mark.slow
@needs
@pytest.mark.parametrize("name", DEFAULT_METHODS)
def test_defaults_are_physically_plausible_on_real_gyros(name):
    # plausibility bounds (DEFAULT_METHODS gave N 1.8-2.8, B 7.7-58 on all 19 gyro axes; results/real):
    # N within a factor 1.5 of the 2-3 deg/sqrt(h) every method and the datasheet's noise density
    # agree on (MTi-G: 1.3-2.2), B between a fifth and twice the ADEV minimum read as a plateau
    # (B = min ADEV / 0.664: 38-46 deg/h on ADIS, 7-60 on the MTi-G)
    records = [(f"ADIS {a}", x) for s, a, x in _axes(ADIS, "deg/s", "g") if s == "gyro"]
    records += [("MTi-G", x) for _, _, x in _axes(MTIG, "rad/s")]
    assert len(records) == 4
    for label, rate in records:
        est = estimators.get(name).fit(rate, 0.01)
        n = from_si("N", est.coefficients_["N"], "deg/sqrt(h)")
        b = from_si("B", est.coefficients_["B"], "deg/h")
        assert 1.0 < n < 4.0, (label, n)
        assert 5.0 < b < 100.0, (label, b)
        assert isinstance(est.diagnostics_["poor_fit"], bool)


@pytest.mark.slow
@needs
@pytest.mark.parametrize("name", DEFAULT_METHODS)
def test_defaults_on_real_accelerometers_plausible_or_flagged(name):
    # The ADIS16405 accelerometers (samples in g, m/s^2 in SI): velocity random walk N in
    # m/s/sqrt(h) within a factor 2 of the white level read off the curve after its bump
    # (ADEV(2.56 s) sqrt(2.56 s)); B in ug between half and twice the ADEV minimum read as a
    # plateau -- or, where a method reads B elsewhere (GMWM's single Gauss-Markov term takes the
    # bump at 0.3-0.6 s, results/real/README.md), the fit is flagged poor: no implausible number
    # without a flag.
    axes = [(a, x) for s, a, x in _axes(ADIS, "deg/s", "g") if s == "accel"]
    assert [a for a, _ in axes] == ["x", "y", "z"]
    assert DISPLAY_UNITS["accel"]["N"] == "m/s/sqrt(h)" and DISPLAY_UNITS["accel"]["B"] == "ug"
    for axis, acc in axes:
        assert 5.0 < abs(float(np.mean(acc))) < 15.0 if axis == "z" else abs(float(np.mean(acc))) < 2.0  # m/s^2
        av = allan_variance(acc, 0.01, "octave")
        white = from_si("N", av.adev[av.m == 256][0] * math.sqrt(2.56), "m/s/sqrt(h)", "accel")
        plateau = from_si("B", av.adev.min() / math.sqrt(2 * math.log(2) / math.pi), "ug", "accel")
        est = estimators.get(name).fit(acc, 0.01)
        n = from_si("N", est.coefficients_["N"], "m/s/sqrt(h)", "accel")
        b = from_si("B", est.coefficients_["B"], "ug", "accel")
        assert white / 2 < n < 2 * white, (axis, n, white)
        assert (plateau / 2 < b < 2 * plateau) or est.diagnostics_["poor_fit"], (axis, b, plateau)


@pytest.mark.slow
@_needs_adis
@pytest.mark.parametrize("minutes", [30, 60])
def test_defaults_on_short_real_records_plausible_or_flagged(minutes):
    """The records robotics users make: the first 30 / 60 minutes of ADIS run 1. Every default
    method gives N in 1.9-3.0 deg/sqrt(h) and B in 15-80 deg/h, or flags what is outside (B "not
    resolved" with its interval, or a poor fit). The target is in range on >= 90 % of the
    slices: on the three axes of one record that is all three, which the 60-minute slice is held to
    (at 30 minutes run 1 z is the one exception over the six runs, and it is flagged; the share over
    all six runs is ``real_runs --slices``, results/real/slices.md). ``gmwm_despiked`` with the plain
    ``WN+GM+RW`` model says "B not resolved" on x; its default model is the real sensor's."""
    from avbench.recordings.fit import fit_axis
    from avbench.recordings.report import coefficient_flags
    from avbench.studies.real_runs import SLICE_B_RANGE, SLICE_N_RANGE

    n = minutes * 60 * 100
    for sensor, axis, x in _axes(ADIS, "deg/s", "g"):
        if sensor != "gyro":
            continue
        fits = fit_axis(np.asarray(x[:n]), 0.01, np.empty(0, dtype=np.int64), DEFAULT_METHODS)
        for name, fit in fits.items():
            c, flags = fit.coefficients(), coefficient_flags(fit)
            N = from_si("N", c["N"], "deg/sqrt(h)")
            B = from_si("B", c["B"], "deg/h")
            inside = SLICE_N_RANGE[0] <= N <= SLICE_N_RANGE[1] and SLICE_B_RANGE[0] <= B <= SLICE_B_RANGE[1]
            flagged = fit.result.fit_check.poor_fit or "not resolved" in flags.values()
            assert inside or flagged, (axis, name, N, B)
            assert inside or minutes != 60, (axis, name, N, B)


ADIS2, _needs_adis2 = real_recording("adis16405-calgary/adis_16405_imu2.npz")


@_needs_adis2
def test_gyro_z_hump_is_a_resonance_the_default_models():
    """ADIS16405 run 2, gyro z (results/real/README.md): a band near 20 Hz stands out of
    the spectrum, gmwm_filtered adds a resonance there and fits every octave, and the fit passes the
    check; on gyro x (no band) nothing is added. The rule can say no: x's band test is reported."""
    import warnings

    axes = {a: x for s, a, x in _axes(ADIS2, "deg/s", "g") if s == "gyro"}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        z = estimators.get("gmwm_filtered").fit(axes["z"], 0.01).diagnostics_
        x = estimators.get("gmwm_filtered").fit(axes["x"], 0.01).diagnostics_
    rs = z["resonance_test"]
    assert rs["included"] and 17.0 < rs["f0"] < 22.0 and rs["prominence"] > 4
    assert z["min_m"] == 1 and not z["poor_fit"]
    assert not x["resonance_test"]["included"] and x["resonance_test"]["prominence"] < 2
    assert x["bias_evidence"]["preferred"] in ("GM", "FL")
