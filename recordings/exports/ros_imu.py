"""ROS ``sensor_msgs/Imu``: the per-sample covariances of the rates and accelerations, one value per axis.

Each message carries ``angular_velocity_covariance`` ((rad/s)^2) and ``linear_acceleration_covariance``
((m/s^2)^2), 3x3 row-major about x, y, z. A sample at rate f of a white noise of density N has the
variance

.. math::

    \\sigma^2 = N^2 f

written on the diagonal per axis (the axes' noises are taken as independent: the off-diagonal terms
are 0).

Sources:

* doc and source: ``sensor_msgs/msg/Imu.msg`` (ros/common_msgs, ros2/common_interfaces):
  ``float64[9] angular_velocity_covariance # Row major about x, y, z axes``, ``float64[9]
  linear_acceleration_covariance # Row major x, y z``; "if all you know is the variance of each
  measurement, e.g. from the datasheet, just put those along the diagonal";
* the variance of a sample: Kalibr's discretisation :math:`\\sigma_d = \\sigma / \\sqrt{\\Delta t}`
  (wiki "IMU Noise Model"), IEEE Std 952's :math:`\\sigma^2(\\tau) = N^2/\\tau` at :math:`\\tau = \\Delta t`.

Only the white noise N is in it: the bias terms (B, K) are slow -- a filter carries them as states,
not as the noise of one sample -- and quantization is not included. f is the rate of the messages:
the record's, or ``--filter-rate`` where the driver publishes at another rate. The file is a YAML
fragment holding the two 9-element lists, for a driver's parameters or a relay node.
"""

from __future__ import annotations

from avbench.recordings.exports.base import Entry, Exporter, Request, axis_order, axis_values, bound_lines, fmt, header

__all__ = ["ROS_IMU_COVARIANCE", "ros_imu_covariance"]

#: message field -> (sensor, unit)
FIELDS = {"angular_velocity_covariance": ("gyro", "(rad/s)^2"),
          "linear_acceleration_covariance": ("accel", "(m/s^2)^2")}


def table(req: Request) -> list[Entry]:
    """Each diagonal element as written, ``field[k]``: the axis's N^2 f (module docstring)."""
    values, order = axis_values(req, "ros_imu_covariance"), axis_order(req, "ros_imu_covariance")
    return [Entry(f"{field}[{4 * i}]", float(fmt(values[(sensor, "N")][axis].value ** 2 * req.used_rate)), unit, axis,
                  values[(sensor, "N")][axis].bound)
            for field, (sensor, unit) in FIELDS.items() for i, axis in enumerate(order[sensor])]


def ros_imu_covariance(req: Request) -> str:
    """The two covariance fields (module docstring)."""
    values = axis_values(req, "ros_imu_covariance")
    order = axis_order(req, "ros_imu_covariance")
    f = req.used_rate
    lines = ["# " + s for s in header(
        req, "ROS sensor_msgs/Imu covariances (a YAML fragment)",
        "one value per axis on the diagonal (row major about x, y, z)",
        ["convention: per-sample variance of the white noise at the message rate f: N^2 f "
         "(sensor_msgs/msg/Imu.msg: 'Row major about x, y, z axes', variances along the diagonal); "
         "bias instability and random walk are not in it"],
        req.rate_text("f"))]
    lines += ["# " + s for s in bound_lines({f"{field}[{4 * i}]": values[(sensor, 'N')][axis]
                                            for field, (sensor, _) in FIELDS.items()
                                            for i, axis in enumerate(order[sensor])})]
    for field, (sensor, unit) in FIELDS.items():
        var = [values[(sensor, "N")][axis].value ** 2 * f for axis in order[sensor]]
        cells = [fmt(var[i // 4]) if i % 4 == 0 else "0.0" for i in range(9)]
        lines.append(f"{field}: [{', '.join(cells)}]  # {unit}, axes {' '.join(order[sensor])}")
    return "\n".join(lines) + "\n"


ROS_IMU_COVARIANCE = Exporter("ros_imu_covariance", "yaml", "ROS sensor_msgs/Imu covariances (per axis)", True,
                              ros_imu_covariance, table)
