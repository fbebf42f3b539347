"""Basalt: the IMU noise entries of its calibration JSON, one value per axis.

Basalt's ``Calibration`` holds continuous-time standard deviations as 3-vectors (x, y, z):

===================  =================  =====================================
key                  unit               value (per axis)
===================  =================  =====================================
``gyro_noise_std``   rad/s/sqrt(Hz)     N of the gyro
``accel_noise_std``  m/s^2/sqrt(Hz)     N of the accelerometer
``gyro_bias_std``    rad/s^2/sqrt(Hz)   K of the gyro
``accel_bias_std``   m/s^3/sqrt(Hz)     K of the accelerometer
``imu_update_rate``  Hz                 the rate of the IMU samples Basalt integrates
===================  =================  =====================================

Sources:

* doc: ``basalt-headers``, ``include/basalt/calibration/calibration.hpp``: "All noise parameters are
  continous time"; the cereal serialization (``headers_serialization.h``, ``serialize(Archive&,
  Calibration&)``) names the keys under ``value0`` of the calibration JSON (``data/euroc_ds_calib.json``);
* source: ``calibration.hpp``, ``dicrete_time_gyro_noise_std() = gyro_noise_std *
  std::sqrt(imu_update_rate)`` (and the accelerometer's), squared into the covariance that
  ``IntegratedImuMeasurement::integrate`` (``include/basalt/imu/preintegration.h``) propagates as
  ``cov = F cov F^T + A accel_cov A^T + G gyro_cov G^T`` with ``A``, ``G`` holding ``dt`` (angle
  variance :math:`N^2 f \\Delta t^2 = N^2 \\Delta t` per sample); the bias: ``gyro_bias_sqrt_weight =
  calib.gyro_bias_std.array().inverse()`` (``src/vi_estimator/sqrt_keypoint_vio.cpp``) divided by
  ``sqrt(dt)`` between two states ``dt`` apart (``include/basalt/linearization/imu_block.hpp``,
  ``linearizeImu``) -- a bias difference of variance :math:`K^2 \\Delta t`, the random walk's.

The file is a JSON fragment: ``value0`` holds the five keys to merge into the calibration's ``value0``
(the cameras, ``calib_accel_bias`` and ``calib_gyro_bias`` come from the camera-IMU calibration);
``avbench_notes`` (beside ``value0``, which cereal reads by name) carries what the other formats say in
comments: the sources, the convention, the rate and every value that is a bound.
"""

from __future__ import annotations

import json

from avbench.recordings.exports.base import Entry, Exporter, Request, axis_order, axis_values, bound_lines, header

__all__ = ["BASALT", "basalt"]

#: key -> (sensor, coefficient)
KEYS = {"accel_noise_std": ("accel", "N"), "gyro_noise_std": ("gyro", "N"),
        "accel_bias_std": ("accel", "K"), "gyro_bias_std": ("gyro", "K")}


#: key -> its unit (module docstring)
UNITS = {"accel_noise_std": "m/s^2/sqrt(Hz)", "gyro_noise_std": "rad/s/sqrt(Hz)", "accel_bias_std": "m/s^3/sqrt(Hz)",
         "gyro_bias_std": "rad/s^2/sqrt(Hz)"}


def table(req: Request) -> list[Entry]:
    """Each axis's value as written, ``key[i]`` (i: x, y, z)."""
    values, order = axis_values(req, "basalt"), axis_order(req, "basalt")
    return [Entry(f"{key}[{i}]", float(values[sc][axis].value), UNITS[key], axis, values[sc][axis].bound)
            for key, sc in KEYS.items() for i, axis in enumerate(order[sc[0]])]


def basalt(req: Request) -> str:
    """Basalt's calibration JSON fragment (module docstring)."""
    values = axis_values(req, "basalt")
    order = axis_order(req, "basalt")
    notes = header(req, "Basalt calibration JSON fragment (merge value0 into your calibration's value0)",
                   "one value per axis (x, y, z)",
                   ["convention: continuous-time standard deviations (calibration.hpp); the noise is discretised as "
                    "noise_std * sqrt(imu_update_rate) (dicrete_time_*_noise_std), the bias difference between two "
                    "states dt apart weighted by 1 / (bias_std * sqrt(dt)) (imu_block.hpp linearizeImu)"],
                   req.rate_text("imu_update_rate"))
    notes += bound_lines({f"{key}[{i}]": values[sc][axis] for key, sc in KEYS.items()
                          for i, axis in enumerate(order[sc[0]])})
    body = {"imu_update_rate": req.used_rate}
    for key, (sensor, c) in KEYS.items():
        body[key] = [float(values[(sensor, c)][axis].value) for axis in order[sensor]]
    return json.dumps({"value0": body, "avbench_notes": notes}, indent=4) + "\n"


BASALT = Exporter("basalt", "json", "Basalt calibration JSON (per axis)", True, basalt, table)
