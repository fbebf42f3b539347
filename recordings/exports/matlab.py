"""MATLAB: a script building ``gyroparams`` and ``accelparams`` (and an ``imuSensor``), one value per axis.

MATLAB's sensor parameters take the IEEE Std 952 coefficients themselves, as 1x3 vectors (x, y, z):

===================  ==================  ====================  ==========================
property             gyroparams unit     accelparams unit      value (per axis)
===================  ==================  ====================  ==========================
``NoiseDensity``     (rad/s)/sqrt(Hz)    (m/s^2)/sqrt(Hz)      N
``BiasInstability``  rad/s               m/s^2                 B (flat line 0.664 B)
``RandomWalk``       (rad/s)*sqrt(Hz)    (m/s^2)*sqrt(Hz)      K
===================  ==================  ====================  ==========================

Sources:

* doc: MathWorks, ``gyroparams`` and ``accelparams`` reference pages (the units above; "specified as a
  real scalar or 3-element row vector"); the example "Inertial Sensor Noise Analysis Using Allan
  Variance" (``AllanVarianceExample``), which reads ``N`` off the Allan deviation's -1/2 line at
  tau = 1 s, ``K`` off the +1/2 line at tau = 3 s and ``B`` from the flat line divided by
  ``scfB = sqrt(2*log(2)/pi)`` (0.664), and passes them to ``gyroparams('NoiseDensity', N,
  'RandomWalk', K, 'BiasInstability', B)`` -- the IEEE Std 952 relations
  :math:`\\sigma^2(\\tau) = N^2/\\tau`, :math:`K^2 \\tau / 3` and :math:`(2 \\ln 2 / \\pi) B^2`;
* source: the example's script (shipped with the toolbox): ``lineN = N ./ sqrt(tau)``,
  ``lineK = K .* sqrt(tau/3)``, ``lineB = B * scfB * ones(size(tau))``.

``imuSensor``'s ``SampleRate`` is the rate it simulates at (``--filter-rate`` where that is not the
record's). B is written as the method gives it, per axis, not inflated (``--inflate`` scales N and K);
where the method does not resolve B the upper end of its interval, or the flat-line bound the Allan
variance allows (:func:`~avbench.recordings.exports.base.bias_instability`), is written and said.
"""

from __future__ import annotations

from avbench.recordings.exports.base import (Entry, Exporter, Request, axis_order, axis_values, bias_instability,
                                             bound_lines, fmt, header)

__all__ = ["MATLAB", "matlab"]

#: MATLAB object -> (sensor, {property: (coefficient, unit)})
OBJECTS = {"gyroparams": ("gyro", {"NoiseDensity": ("N", "(rad/s)/sqrt(Hz)"), "BiasInstability": ("B", "rad/s"),
                                   "RandomWalk": ("K", "(rad/s)*sqrt(Hz)")}),
           "accelparams": ("accel", {"NoiseDensity": ("N", "(m/s^2)/sqrt(Hz)"), "BiasInstability": ("B", "m/s^2"),
                                     "RandomWalk": ("K", "(m/s^2)*sqrt(Hz)")})}
_VARIABLE = {"gyroparams": "gyro", "accelparams": "accel"}


def _per_axis(req: Request):
    """((object, property) -> the Value of each axis, sensor -> its axes in order)."""
    nk = axis_values(req, "matlab")
    b = bias_instability(req, "matlab")
    order = axis_order(req, "matlab")
    per_axis = {}
    for obj, (sensor, props) in OBJECTS.items():
        for prop, (c, _) in props.items():
            per_axis[(obj, prop)] = [b[sensor][a] if c == "B" else nk[(sensor, c)][a] for a in order[sensor]]
    return per_axis, order


def table(req: Request) -> list[Entry]:
    """Each property's value per axis as written, ``variable.Property(i)``."""
    per_axis, _ = _per_axis(req)
    return [Entry(f"{_VARIABLE[obj]}.{prop}({i + 1})", float(fmt(v.value)), OBJECTS[obj][1][prop][1], v.axis, v.bound)
            for (obj, prop), vs in per_axis.items() for i, v in enumerate(vs)]


def matlab(req: Request) -> str:
    """The MATLAB script (module docstring)."""
    per_axis, order = _per_axis(req)
    lines = ["% " + s for s in header(
        req, "MATLAB gyroparams / accelparams (Sensor Fusion and Tracking / Navigation Toolbox)",
        "one value per axis (x, y, z); BiasInstability not inflated",
        ["convention: the IEEE Std 952 coefficients as MathWorks' example 'Inertial Sensor Noise Analysis Using "
         "Allan Variance' reads them: NoiseDensity = N (ADEV = N/sqrt(tau)), RandomWalk = K (ADEV = K sqrt(tau/3)), "
         "BiasInstability = B (flat ADEV = sqrt(2 ln2/pi) B = 0.664 B); units: the gyroparams / accelparams pages"],
        req.rate_text("SampleRate"))]
    lines += ["% " + s for s in bound_lines({f"{_VARIABLE[obj]}.{prop}({i + 1})": v
                                             for (obj, prop), vs in per_axis.items() for i, v in enumerate(vs)})]
    for obj, (sensor, props) in OBJECTS.items():
        lines.append(f"{_VARIABLE[obj]} = {obj}( ...")
        items = list(props.items())
        for k, (prop, (_, unit)) in enumerate(items):
            vector = "[" + " ".join(fmt(v.value) for v in per_axis[(obj, prop)]) + "]"
            end = ");" if k == len(items) - 1 else ", ..."
            lines.append(f"    '{prop}', {vector}{end}  % {unit}, axes {' '.join(order[sensor])}")
    lines.append(f"imu = imuSensor('accel-gyro', 'SampleRate', {req.used_rate:.6f}, "
                 "'Accelerometer', accel, 'Gyroscope', gyro);")
    return "\n".join(lines) + "\n"


MATLAB = Exporter("matlab", "m", "MATLAB gyroparams / accelparams script (per axis)", True, matlab, table)
