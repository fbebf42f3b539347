"""Kalibr's family: Kalibr's ``imu.yaml``, allan_variance_ros's ``imu.yaml`` and OpenVINS's ``kalibr_imu_chain.yaml``.

All three hold Kalibr's continuous-time densities, the same numbers as avbench's SI coefficients:

==============================  =================  ====================================
key                             unit               value
==============================  =================  ====================================
``gyroscope_noise_density``     rad/s/sqrt(Hz)     N of the gyro (largest over the axes)
``gyroscope_random_walk``       rad/s^2/sqrt(Hz)   K of the gyro
``accelerometer_noise_density`` m/s^2/sqrt(Hz)     N of the accelerometer
``accelerometer_random_walk``   m/s^3/sqrt(Hz)     K of the accelerometer
``update_rate``                 Hz                 the sample rate
==============================  =================  ====================================

The reader discretises at the sample interval :math:`\\Delta t`:
:math:`\\sigma_d = \\sigma / \\sqrt{\\Delta t}` for the white noise and :math:`\\sigma_{bd} = \\sigma_b \\sqrt{\\Delta t}`
for the bias random walk's increment per sample.

Sources:

* Kalibr -- doc: the wiki page "IMU Noise Model" (github.com/ethz-asl/kalibr/wiki/IMU-Noise-Model),
  the two formulas above; source: ``aslam_offline_calibration/kalibr/python/kalibr_common/ConfigReader.py``,
  ``ImuParameters.getAccelerometerStatistics`` / ``getGyroStatistics``:
  ``noise_density / math.sqrt(1.0 / self.getUpdateRate())``; it refuses a density or random walk <= 0.
* allan_variance_ros (ori-drs) -- ``scripts/analysis.py`` writes the same keys (README, "imu.yaml").
* OpenVINS -- doc: "Discrete Propagation" (docs.openvins.com/propagation_discrete.html): continuous
  noise densities, discretised per IMU interval; source: ``ov_msckf/src/state/Propagator.cpp``,
  ``Qc = sigma_w^2 / dt`` (and ``sigma_a^2``, ``sigma_wb^2``, ``sigma_ab^2`` over ``dt``) with ``Qd = G Qc G^T``
  where G holds ``dt`` -- per step an angle variance ``sigma_w^2 dt`` and a bias variance
  ``sigma_wb^2 dt``; ``VioManagerOptions::print_and_load_noise`` reads the four keys under ``imu0``
  (``parse_external("relative_config_imu", "imu0", ...)``) and ``print_and_load_state`` reads the
  intrinsics ``Tw``, ``Ta``, ``R_IMUtoACC``, ``R_IMUtoGYRO``, ``Tg`` -- written here as identity (no
  intrinsic calibration), with ``T_i_b`` identity and ``time_offset`` 0 (not measured by avbench).
  The file opens with ``%YAML:1.0``: OpenVINS reads it with OpenCV's FileStorage, as in its
  ``config/euroc_mav/kalibr_imu_chain.yaml`` (``ov_core/src/utils/opencv_yaml_parse.h``: ``node >> value``;
  a string read from a node that is not a string is empty). OpenCV keeps an unquoted scalar up to the end
  of the line, ``#`` included, and makes a map of one with a colon in it: the topic is written quoted,
  with no comment on its line; a comment after a number is dropped by OpenCV and PyYAML alike.

Kalibr and allan_variance_ros get today's text unchanged
(:func:`~avbench.recordings.filter_yaml.kalibr_yaml`, at the record's rate: the rate of the bag Kalibr
reads); ``--filter-rate`` sets OpenVINS's ``update_rate`` where the IMU stream it reads is not the record's.
"""

from __future__ import annotations

import json

from avbench.recordings import filter_yaml
from avbench.recordings.exports.base import Entry, Exporter, Request, bound_lines, fmt, header, sensor_values

__all__ = ["KALIBR", "ALLAN_VARIANCE_ROS", "OPENVINS", "kalibr", "allan_variance_ros", "openvins"]

_UNITS = {"accelerometer_noise_density": "[ m / s^2 / sqrt(Hz) ]", "accelerometer_random_walk": "[ m / s^3 / sqrt(Hz) ]",
          "gyroscope_noise_density": "[ rad / s / sqrt(Hz) ]", "gyroscope_random_walk": "[ rad / s^2 / sqrt(Hz) ]"}
_ORDER = ("accelerometer_noise_density", "accelerometer_random_walk", "gyroscope_noise_density", "gyroscope_random_walk")


def kalibr(req: Request) -> str:
    """Kalibr's ``imu.yaml``: :func:`~avbench.recordings.filter_yaml.kalibr_yaml`'s text, at the record's rate."""
    choices = filter_yaml.filter_choices(req.results, req.method, req.option, req.avs)
    return filter_yaml.kalibr_yaml(choices, req.rate, req.topic, req.method, req.sources, req.inflate, "kalibr",
                                   flags=req.flags)


def allan_variance_ros(req: Request) -> str:
    """allan_variance_ros's ``imu.yaml``: Kalibr's keys, its own comment line."""
    choices = filter_yaml.filter_choices(req.results, req.method, req.option, req.avs)
    return filter_yaml.kalibr_yaml(choices, req.rate, req.topic, req.method, req.sources, req.inflate,
                                   "allan_variance_ros", flags=req.flags)


def _matrix(rows) -> list[str]:
    return ["    - [" + ", ".join(f"{float(v):.1f}" for v in row) + "]" for row in rows]


def openvins(req: Request) -> str:
    """OpenVINS's ``kalibr_imu_chain.yaml``: ``imu0`` with Kalibr's four densities (module docstring)."""
    values = sensor_values(req)
    by_key = {filter_yaml.KEYS[sc]: v for sc, v in values.items()}
    lines = ["%YAML:1.0"]
    lines += ["# " + s for s in header(
        req, "OpenVINS IMU chain (Kalibr's kalibr_imu_chain.yaml layout)",
        "each value is the largest over the sensor's axes (axis in the comment)",
        ["convention: continuous-time densities as Kalibr's; OpenVINS discretises per IMU interval dt as "
         "Qc = sigma^2 / dt, Qd = G Qc G^T (docs.openvins.com 'Discrete Propagation'; ov_msckf/src/state/Propagator.cpp)",
         "T_i_b, time_offset and the intrinsics (Tw, R_IMUtoGYRO, Ta, R_IMUtoACC, Tg) are identity / zero: "
         "not measured by avbench -- keep your calibrated ones"],
        req.rate_text("update_rate"))]
    lines += ["# " + s for s in bound_lines({k: by_key[k] for k in _ORDER})]
    identity = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
    lines += ["imu0:", "  T_i_b:"] + _matrix([[1.0, 0, 0, 0], [0, 1.0, 0, 0], [0, 0, 1.0, 0], [0, 0, 0, 1.0]])
    for key in _ORDER:
        v = by_key[key]
        note = f", x {v.factor:.3g}" if v.factor != 1.0 else ""
        lines.append(f"  {key}: {fmt(v.value)}  # {_UNITS[key]}, axis {v.axis}{note}")
    if not req.topic:
        lines.append("  # rostopic: not a bag -- Kalibr's default topic")
    lines.append(f"  rostopic: {json.dumps(req.topic if req.topic else '/imu0')}")
    lines.append("  time_offset: 0.0")
    lines.append(f"  update_rate: {req.used_rate!r}")
    lines.append('  model: "calibrated"')
    for name, rows in (("Tw", identity), ("R_IMUtoGYRO", identity), ("Ta", identity), ("R_IMUtoACC", identity),
                       ("Tg", [[0.0] * 3] * 3)):
        lines += [f"  {name}:"] + _matrix(rows)
    return "\n".join(lines) + "\n"


def table(req: Request) -> list[Entry]:
    """Kalibr's four densities as the three files write them (inflated; the units of Kalibr's wiki)."""
    values = {filter_yaml.KEYS[sc]: v for sc, v in sensor_values(req).items()}
    return [Entry(key, float(fmt(values[key].value)), filter_yaml.UNITS[key], values[key].axis, values[key].bound)
            for key in _ORDER]


KALIBR = Exporter("kalibr", "yaml", "Kalibr imu.yaml", False, kalibr, table)
ALLAN_VARIANCE_ROS = Exporter("allan_variance_ros", "yaml", "allan_variance_ros imu.yaml (Kalibr keys)", False,
                              allan_variance_ros, table)
OPENVINS = Exporter("openvins", "yaml", "OpenVINS kalibr_imu_chain.yaml", False, openvins, table)
