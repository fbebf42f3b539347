"""VINS-Mono / VINS-Fusion: the ``acc_n``, ``gyr_n``, ``acc_w``, ``gyr_w`` keys of the estimator's config.

VINS takes discrete-time standard deviations at the IMU's message rate f (one number per sensor, the
largest over the axes):

.. math::

    \\mathrm{gyr\\_n} = N \\sqrt{f}, \\qquad \\mathrm{gyr\\_w} = K \\sqrt{f}

and the same for ``acc_n``, ``acc_w`` with the accelerometer's N and K. Units: ``gyr_n`` rad/s,
``acc_n`` m/s^2 (the standard deviation of one sample), ``gyr_w`` rad/s^2, ``acc_w`` m/s^3 (the
standard deviation of the sampled white noise that drives the bias).

Sources:

* doc: the config files' comments (``config/euroc/euroc_config.yaml``): ``acc_n`` "accelerometer
  measurement noise standard deviation", ``acc_w`` "accelerometer bias random work noise standard
  deviation" (the same keys in VINS-Fusion's configs);
* source: ``vins_estimator/src/factor/integration_base.h``, ``IntegrationBase``: the constructor sets
  ``noise`` to ``ACC_N^2``, ``GYR_N^2`` (twice each: the step's two samples), ``ACC_W^2``, ``GYR_W^2``
  with no rate; ``midPointIntegration`` propagates ``covariance = F P F^T + V noise V^T`` with
  ``V.block(3,3) = V.block(3,9) = 0.5 I dt`` (angle from the two gyro samples) and
  ``V.block(12,15) = I dt`` (gyro bias). Per step the angle variance is
  :math:`0.5\\,\\mathrm{gyr\\_n}^2 \\Delta t^2`, the variance of the midpoint
  :math:`\\tfrac12 (n_k + n_{k+1}) \\Delta t` of two samples of standard deviation ``gyr_n``, which a
  white noise of density N sampled at f has for ``gyr_n = N sqrt(f)``; the bias variance per step is
  :math:`\\mathrm{gyr\\_w}^2 \\Delta t^2`, which equals the random walk's :math:`K^2 \\Delta t` for
  ``gyr_w = K sqrt(f)``.

VINS counts the two samples of each step as independent of the neighbouring steps', so over a
window of M steps its angle variance is :math:`0.5 M \\sigma^2 \\Delta t^2` where the sampled noise
gives :math:`(M - \\tfrac12) \\sigma^2 \\Delta t^2` -- about half. The file says so; ``--inflate 1.414``
(on N) makes the window's variance match, but is not applied unless asked.
"""

from __future__ import annotations

import math

from avbench.recordings.exports.base import Entry, Exporter, Request, bound_lines, fmt, header, sensor_values

__all__ = ["VINS", "vins"]

#: key -> (sensor, coefficient, unit, what VINS's config calls it)
KEYS = {"acc_n": ("accel", "N", "m/s^2", "accelerometer measurement noise standard deviation"),
        "gyr_n": ("gyro", "N", "rad/s", "gyroscope measurement noise standard deviation"),
        "acc_w": ("accel", "K", "m/s^3", "accelerometer bias random walk noise standard deviation"),
        "gyr_w": ("gyro", "K", "rad/s^2", "gyroscope bias random walk noise standard deviation")}


def table(req: Request) -> list[Entry]:
    """The four keys as written: each sensor's value times sqrt(f) (module docstring)."""
    values = sensor_values(req)
    f = req.used_rate
    return [Entry(key, float(fmt(values[(s, c)].value * math.sqrt(f))), unit, values[(s, c)].axis,
                  values[(s, c)].bound) for key, (s, c, unit, _) in KEYS.items()]


def vins(req: Request) -> str:
    """The four VINS keys as a YAML fragment to paste into the estimator's config (module docstring)."""
    values = sensor_values(req)
    f = req.used_rate
    by_key = {k: values[(s, c)] for k, (s, c, _, _) in KEYS.items()}
    lines = ["# " + s for s in header(
        req, "VINS-Mono / VINS-Fusion IMU noise (paste into the estimator's config yaml)",
        "each value is the largest over the sensor's axes (axis in the comment)",
        ["convention: discrete-time standard deviations at the IMU rate f: acc_n = N sqrt(f), gyr_n = N sqrt(f), "
         "acc_w = K sqrt(f), gyr_w = K sqrt(f) (config comments 'measurement noise standard deviation'; "
         "vins_estimator/src/factor/integration_base.h: noise = ACC_N^2 ..., V.block(3,3) = 0.5 I dt, "
         "V.block(12,15) = I dt)",
         "VINS's midpoint propagation treats each step's two samples as independent: over a window its angle and "
         "velocity variances are about half the sampled noise's; x sqrt(2) on acc_n, gyr_n (--inflate) matches them"],
        req.rate_text("f"))]
    lines += ["# " + s for s in bound_lines(by_key)]
    for key, (_, c, unit, what) in KEYS.items():
        v = by_key[key]
        note = f", x {v.factor:.3g}" if v.factor != 1.0 else ""
        lines.append(f"{key}: {fmt(v.value * math.sqrt(f))}  # {unit}, {what} = {c} sqrt(f), axis {v.axis}{note}")
    return "\n".join(lines) + "\n"


VINS = Exporter("vins", "yaml", "VINS-Mono / VINS-Fusion config keys", False, vins, table)
