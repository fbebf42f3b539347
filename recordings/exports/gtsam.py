"""GTSAM: a Python snippet that builds ``PreintegrationCombinedParams`` with its API.

GTSAM has no file format for IMU noise; its parameters are continuous-time covariances (one number
per sensor, the largest over the axes, on the diagonal):

===========================  ======================  ==================
parameter                    unit                    value
===========================  ======================  ==================
``gyroscopeCovariance``      rad^2/s^2/Hz            N_gyro^2 I
``accelerometerCovariance``  m^2/s^4/Hz              N_accel^2 I
``biasOmegaCovariance``      rad^2/s^4/Hz            K_gyro^2 I
``biasAccCovariance``        m^2/s^6/Hz              K_accel^2 I
``integrationCovariance``    --                      not a sensor noise (below)
===========================  ======================  ==================

Sources:

* doc: ``gtsam/navigation/PreintegrationParams.h`` (``accelerometerCovariance``: 'continuous-time
  "Covariance" of accelerometer'; ``integrationCovariance``: 'continuous-time "Covariance" describing
  integration uncertainty'), ``PreintegratedRotation.h`` (``gyroscopeCovariance``, continuous-time),
  ``PreintegrationCombinedParams.h`` (``biasAccCovariance`` / ``biasOmegaCovariance``:
  'continuous-time "Covariance" describing accelerometer / gyroscope bias random walk');
* source: ``gtsam/navigation/ImuFactor.cpp``, ``PreintegratedImuMeasurements::integrateMeasurement``:
  ``preintMeasCov_ += B (aCov / dt) B^T + C (wCov / dt) C^T`` ("(1/dt) allows to pass from
  continuous time noise to discrete time noise") with ``C`` holding ``dt`` -- an angle variance
  :math:`N^2 \\Delta t` per measurement; ``CombinedImuFactor.cpp``,
  ``PreintegratedCombinedMeasurements::integrateMeasurement``: ``D_g_g = dt * biasOmegaCovariance``
  -- a bias variance :math:`K^2 \\Delta t`.

GTSAM takes ``dt`` with each measurement, so no rate is written. ``integrationCovariance`` is the
error of integrating velocity into position, not a property of the sensor: avbench does not estimate
it and writes a small placeholder (``1e-8 I``, m^2/s), named so that the user sets their own.
``MakeSharedU`` is GTSAM's z-up navigation frame (``MakeSharedD`` for z down); gravity 9.81 m/s^2.
"""

from __future__ import annotations

from avbench.recordings.exports.base import Entry, Exporter, Request, bound_lines, fmt, header, sensor_values

__all__ = ["GTSAM", "gtsam_snippet", "INTEGRATION_COVARIANCE"]

#: the placeholder written for integrationCovariance (module docstring), m^2/s
INTEGRATION_COVARIANCE = 1e-8
#: constant name -> (sensor, coefficient, unit)
NAMES = {"GYRO_NOISE_DENSITY": ("gyro", "N", "rad/s/sqrt(Hz)"),
         "ACCEL_NOISE_DENSITY": ("accel", "N", "m/s^2/sqrt(Hz)"),
         "GYRO_RANDOM_WALK": ("gyro", "K", "rad/s^2/sqrt(Hz)"),
         "ACCEL_RANDOM_WALK": ("accel", "K", "m/s^3/sqrt(Hz)")}


def table(req: Request) -> list[Entry]:
    """The four constants as written (module docstring)."""
    values = sensor_values(req)
    return [Entry(name, float(fmt(values[(s, c)].value)), unit, values[(s, c)].axis, values[(s, c)].bound)
            for name, (s, c, unit) in NAMES.items()]


def gtsam_snippet(req: Request) -> str:
    """The Python text that builds ``params`` (module docstring)."""
    values = sensor_values(req)
    by_name = {k: values[(s, c)] for k, (s, c, _) in NAMES.items()}
    lines = ["# " + s for s in header(
        req, "GTSAM PreintegrationCombinedParams (a Python snippet: GTSAM has no file format)",
        "each value is the largest over the sensor's axes (axis in the comment)",
        ["convention: continuous-time covariances (PreintegrationParams.h, PreintegrationCombinedParams.h); GTSAM "
         "discretises per measurement as wCov / dt (ImuFactor.cpp integrateMeasurement) and dt * biasOmegaCovariance "
         "(CombinedImuFactor.cpp)",
         "PreintegrationParams (the plain ImuFactor) takes the first two covariances and integrationCovariance; "
         "the random walks then go into a BetweenFactor on the biases with sigma K sqrt(delta t)"],
        "rate: none written -- GTSAM takes dt with each measurement")]
    lines += ["# " + s for s in bound_lines(by_name)]
    lines += ["import numpy as np", "import gtsam", ""]
    for name, (_, _, unit) in NAMES.items():
        v = by_name[name]
        note = f", x {v.factor:.3g}" if v.factor != 1.0 else ""
        lines.append(f"{name} = {fmt(v.value)}  # {unit}, axis {v.axis}{note}")
    lines += [f"INTEGRATION_COVARIANCE = {fmt(INTEGRATION_COVARIANCE)}  # m^2/s: NOT measured by avbench (the error of "
              "integrating velocity into position): a placeholder, set your own",
              "GRAVITY = 9.81  # m/s^2",
              "",
              "params = gtsam.PreintegrationCombinedParams.MakeSharedU(GRAVITY)  # z up; MakeSharedD(GRAVITY) for z down",
              "params.setGyroscopeCovariance(GYRO_NOISE_DENSITY**2 * np.eye(3))",
              "params.setAccelerometerCovariance(ACCEL_NOISE_DENSITY**2 * np.eye(3))",
              "params.setBiasOmegaCovariance(GYRO_RANDOM_WALK**2 * np.eye(3))",
              "params.setBiasAccCovariance(ACCEL_RANDOM_WALK**2 * np.eye(3))",
              "params.setIntegrationCovariance(INTEGRATION_COVARIANCE * np.eye(3))"]
    return "\n".join(lines) + "\n"


GTSAM = Exporter("gtsam", "py", "GTSAM PreintegrationCombinedParams (Python snippet)", False, gtsam_snippet, table)
