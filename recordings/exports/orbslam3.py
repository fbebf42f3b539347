"""ORB-SLAM3: the ``IMU.*`` noise keys of its OpenCV-YAML settings file.

ORB-SLAM3 takes continuous-time densities (one number per sensor, the largest over the axes) and the
IMU's rate, and discretises them itself:

==================  =================  =====
key                 unit               value
==================  =================  =====
``IMU.NoiseGyro``   rad/s/sqrt(Hz)     N of the gyro
``IMU.NoiseAcc``    m/s^2/sqrt(Hz)     N of the accelerometer
``IMU.GyroWalk``    rad/s^2/sqrt(Hz)   K of the gyro
``IMU.AccWalk``     m/s^3/sqrt(Hz)     K of the accelerometer
``IMU.Frequency``   Hz                 the rate of the IMU samples ORB-SLAM3 receives
==================  =================  =====

Sources:

* doc: ORB-SLAM3's example settings (``Examples/Monocular-Inertial/EuRoC.yaml``: ``IMU.NoiseGyro:
  1.7e-4 #1.6968e-04`` -- Kalibr's EuRoC densities) and the units it prints when it loads them
  (``Tracking::ParseIMUParamFile``: "IMU gyro noise: ... rad/s/sqrt(Hz)", "IMU gyro walk: ...
  rad/s^2/sqrt(Hz)");
* source: ``src/Settings.cc``, ``Settings::readIMU`` reads the five keys; ``src/Tracking.cc``
  (``Tracking::newParameterLoader`` / ``ParseIMUParamFile``): ``const float sf = sqrt(mImuFreq);
  mpImuCalib = new IMU::Calib(Tbc, Ng*sf, Na*sf, Ngw/sf, Naw/sf);`` -- per sample the white noise's
  standard deviation :math:`N \\sqrt{f}` and the bias increment's :math:`K / \\sqrt{f}`;
  ``src/ImuTypes.cc``, ``Preintegrated::IntegrateNewMeasurement``: ``C = A C A^T + B Nga B^T`` with
  ``B`` holding ``dt`` (angle variance :math:`N^2 f \\Delta t^2 = N^2 \\Delta t` per sample) and
  ``C.block(9,9) += NgaWalk`` (bias variance :math:`K^2 / f = K^2 \\Delta t` per sample).

``IMU.Frequency`` is the rate of the samples ORB-SLAM3 integrates: ``--filter-rate`` where that is not
the record's rate. ORB-SLAM3 reads it in one of two ways, chosen by the settings file: with
``File.version: "1.0"`` (``System.cc``), ``Settings::readIMU`` takes it through
``readParameter<float>``, which aborts unless the node ``isReal()``; without it,
``Tracking::ParseIMUParamFile`` takes it only if ``node.isInt()`` ("IMU.Frequency parameter doesn't
exist or is not an integer"). The fragment writes the real number and, commented out below it, the
integer an older file needs. The four densities are real numbers on both paths (``isReal()``). The
fragment opens with ``%YAML:1.0`` (OpenCV's FileStorage); paste its ``IMU.*`` lines into the settings
file.
"""

from __future__ import annotations

from avbench.recordings.exports.base import Entry, Exporter, Request, bound_lines, fmt, header, sensor_values

__all__ = ["ORBSLAM3", "orbslam3", "frequency_lines"]

#: key -> (sensor, coefficient, unit)
KEYS = {"IMU.NoiseGyro": ("gyro", "N", "rad/s/sqrt(Hz)"), "IMU.NoiseAcc": ("accel", "N", "m/s^2/sqrt(Hz)"),
        "IMU.GyroWalk": ("gyro", "K", "rad/s^2/sqrt(Hz)"), "IMU.AccWalk": ("accel", "K", "m/s^3/sqrt(Hz)")}


def table(req: Request) -> list[Entry]:
    """The four ``IMU.*`` densities as written (module docstring)."""
    values = sensor_values(req)
    return [Entry(key, float(fmt(values[(s, c)].value)), unit, values[(s, c)].axis, values[(s, c)].bound)
            for key, (s, c, unit) in KEYS.items()]


def orbslam3(req: Request) -> str:
    """ORB-SLAM3's ``IMU.*`` keys (module docstring)."""
    values = sensor_values(req)
    by_key = {k: values[(s, c)] for k, (s, c, _) in KEYS.items()}
    lines = ["%YAML:1.0"]
    lines += ["# " + s for s in header(
        req, "ORB-SLAM3 IMU noise settings (paste the IMU.* lines into the settings file)",
        "each value is the largest over the sensor's axes (axis in the comment)",
        ["convention: continuous-time densities; ORB-SLAM3 discretises with sf = sqrt(IMU.Frequency): "
         "IMU::Calib(Tbc, Ng*sf, Na*sf, Ngw/sf, Naw/sf) (src/Tracking.cc; src/ImuTypes.cc IntegrateNewMeasurement)"],
        req.rate_text("IMU.Frequency"))]
    lines += ["# " + s for s in bound_lines(by_key)]
    for key, (_, _, unit) in KEYS.items():
        v = by_key[key]
        note = f", x {v.factor:.3g}" if v.factor != 1.0 else ""
        lines.append(f"{key}: {fmt(v.value)}  # {unit}, axis {v.axis}{note}")
    lines += frequency_lines(req.used_rate)
    return "\n".join(lines) + "\n"


def frequency_lines(rate: float) -> list[str]:
    """``IMU.Frequency`` as a settings file with ``File.version: "1.0"`` reads it (a real number), and the
    line an older file needs instead (an integer), commented out (module docstring)."""
    legacy = round(rate)
    rounded = "" if legacy == rate else f", {rate!r} Hz rounded"
    return ['# IMU.Frequency (Hz): a real number for a settings file with File.version: "1.0" (Settings::readIMU); '
            "an older settings file needs an integer (Tracking::ParseIMUParamFile): use the commented line below "
            f"instead{rounded}",
            f"IMU.Frequency: {float(rate)!r}",
            f"# IMU.Frequency: {legacy:d}"]


ORBSLAM3 = Exporter("orbslam3", "yaml", "ORB-SLAM3 settings (IMU.*)", False, orbslam3, table)
