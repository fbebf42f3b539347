"""PX4 EKF2: the IMU noise parameters as a QGroundControl ``.params`` file (and ``param set`` lines).

EKF2 takes discrete-time standard deviations at its prediction rate f (one number per sensor, the
largest over the axes):

=====================  =======  ==================  ==================================
parameter              unit     value               documented range (default)
=====================  =======  ==================  ==================================
``EKF2_GYR_NOISE``     rad/s    N_gyro sqrt(f)      0.0001 .. 0.1 (0.015)
``EKF2_ACC_NOISE``     m/s^2    N_accel sqrt(f)     0.01 .. 1.0 (0.35)
``EKF2_GYR_B_NOISE``   rad/s^2  K_gyro sqrt(f)      0.0 .. 0.01 (0.001)
``EKF2_ACC_B_NOISE``   m/s^3    K_accel sqrt(f)     0.0 .. 0.01 (0.003)
=====================  =======  ==================  ==================================

Sources:

* doc: the parameter definitions (``src/modules/ekf2/module.yaml``: ``EKF2_GYR_NOISE`` "Rate gyro noise
  for covariance prediction", rad/s; ``EKF2_ACC_NOISE``, m/s^2; ``params_gyro_bias.yaml``:
  ``EKF2_GYR_B_NOISE`` "Process noise for IMU rate gyro bias prediction", rad/s^2;
  ``params_accel_bias.yaml``: ``EKF2_ACC_B_NOISE``, m/s^3; ``EKF2_PREDICT_US``: the prediction period,
  10000 us by default), the source of PX4's parameter reference;
* source: ``src/modules/ekf2/EKF/covariance.cpp``, ``Ekf::predictCovariance``:
  ``d_ang_var = sq(imu_delayed.delta_ang_dt * gyro_noise)`` -- the variance of the delta angle over
  one prediction step of length :math:`\\Delta t = 1/f`, which a white noise of density N gives as
  :math:`N^2 \\Delta t`, so ``gyro_noise`` :math:`= N / \\sqrt{\\Delta t}`; ``gyro_bias_sig = dt *
  gyro_bias_p_noise``, ``P(i,i) += sq(gyro_bias_sig)`` -- a bias increment of variance
  :math:`(\\Delta t\\, q)^2` per step, the random walk's :math:`K^2 \\Delta t` for
  :math:`q = K / \\sqrt{\\Delta t}`; the same for the accelerometer.

f is EKF2's prediction rate, ``1e6 / EKF2_PREDICT_US`` (100 Hz by default): the IMU samples are
accumulated into delta angles and velocities over each step. It is not the sensor's rate:
``--filter-rate`` gives it; without it the file uses EKF2's default, 100 Hz (or the record's rate
where that is lower: a step holds at least one sample), and says so. A value outside a parameter's
documented range is written as computed, with a comment.

QGroundControl's parameter file: ``# Vehicle-Id Component-Id Name Value Type`` and tab-separated
lines, type 9 (``MAV_PARAM_TYPE_REAL32``), vehicle and component id 1.
"""

from __future__ import annotations

import math

from avbench.recordings.exports.base import Entry, Exporter, Request, bound_lines, header, sensor_values

__all__ = ["PX4", "px4", "PARAMETERS", "DEFAULT_PREDICTION_RATE", "prediction_rate"]

#: parameter -> (sensor, coefficient, unit, documented min, max)
PARAMETERS = {"EKF2_ACC_B_NOISE": ("accel", "K", "m/s^3", 0.0, 0.01),
              "EKF2_ACC_NOISE": ("accel", "N", "m/s^2", 0.01, 1.0),
              "EKF2_GYR_B_NOISE": ("gyro", "K", "rad/s^2", 0.0, 0.01),
              "EKF2_GYR_NOISE": ("gyro", "N", "rad/s", 0.0001, 0.1)}


#: EKF2's default prediction rate (Hz): 1e6 / EKF2_PREDICT_US, whose default is 10000 us (module.yaml)
DEFAULT_PREDICTION_RATE = 100.0


def prediction_rate(req: Request) -> float:
    """f (Hz): ``--filter-rate`` where given, else EKF2's default prediction rate, at most the record's rate
    (a prediction step holds at least one IMU sample)."""
    if req.filter_rate is not None:
        return float(req.filter_rate)
    return min(DEFAULT_PREDICTION_RATE, float(req.rate))


def _num(v: float) -> str:
    return f"{float(v):.9g}"  # a float32 parameter: 9 digits restore it exactly


def _written(req: Request):
    """(parameter -> its chosen Value, parameter -> the number written: the Value times sqrt(f))."""
    values = sensor_values(req)
    by_name = {p: values[(s, c)] for p, (s, c, _, _, _) in PARAMETERS.items()}
    return by_name, {p: by_name[p].value * math.sqrt(prediction_rate(req)) for p in PARAMETERS}


def table(req: Request) -> list[Entry]:
    """The four parameters as written (module docstring)."""
    by_name, written = _written(req)
    return [Entry(p, float(_num(written[p])), unit, by_name[p].axis, by_name[p].bound)
            for p, (_, _, unit, _, _) in PARAMETERS.items()]


def px4(req: Request) -> str:
    """The four EKF2 parameters in QGroundControl's ``.params`` format (module docstring)."""
    by_name, written = _written(req)
    f = prediction_rate(req)
    what = "f (EKF2's prediction rate, 1e6 / EKF2_PREDICT_US)"
    if req.filter_rate is not None:
        rate = req.rate_text(what)
    elif f < DEFAULT_PREDICTION_RATE:
        rate = (f"{what}: {f:.6g} Hz, the record's rate: EKF2 cannot predict faster than its IMU samples arrive "
                f"(its default is {DEFAULT_PREDICTION_RATE:g} Hz, EKF2_PREDICT_US = 10000); --filter-rate sets another")
    else:
        rate = (f"{what}: {f:.6g} Hz, EKF2's default (EKF2_PREDICT_US = 10000 us), not the record's "
                f"{float(req.rate):.6g} Hz; where your EKF2_PREDICT_US differs, give --filter-rate = 1e6 / EKF2_PREDICT_US")
    lines = ["# " + s for s in header(
        req, "PX4 EKF2 IMU noise parameters (QGroundControl .params file)",
        "each value is the largest over the sensor's axes (axis in the comment)",
        ["convention: discrete-time standard deviations at EKF2's prediction rate f: EKF2_GYR_NOISE = N sqrt(f), "
         "EKF2_GYR_B_NOISE = K sqrt(f), the same for the accelerometer (src/modules/ekf2/EKF/covariance.cpp "
         "predictCovariance: d_ang_var = sq(delta_ang_dt * gyro_noise), gyro_bias_sig = dt * gyro_bias_p_noise; "
         "units and ranges: src/modules/ekf2/module.yaml, params_gyro_bias.yaml, params_accel_bias.yaml)"],
        rate)]
    lines += ["# " + s for s in bound_lines(by_name)]
    for p, (_, c, unit, lo, hi) in PARAMETERS.items():
        v = by_name[p]
        note = f" (x {v.factor:.3g})" if v.factor != 1.0 else ""
        lines.append(f"# {p} = {c} sqrt(f) = {_num(written[p])} {unit}, axis {v.axis}{note}")
        if not lo <= written[p] <= hi:
            lines.append(f"# {p}: outside its documented range [{lo:g}, {hi:g}] {unit} -- written as computed")
    lines.append("# or in the MAVLink shell / nsh:")
    lines += [f"#   param set {p} {_num(written[p])}" for p in PARAMETERS]
    lines.append("# vehicle and component id 1 (QGroundControl's default): edit them for another vehicle")
    lines.append("#")
    lines.append("# Vehicle-Id Component-Id Name Value Type")
    lines += [f"1\t1\t{p}\t{_num(written[p])}\t9" for p in PARAMETERS]
    return "\n".join(lines) + "\n"


PX4 = Exporter("px4", "params", "PX4 EKF2 parameters (QGroundControl .params)", False, px4, table)
