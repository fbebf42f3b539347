"""Step 5b: the noise parameters a navigation filter takes -- Kalibr's ``imu.yaml``.

Kalibr (and allan_variance_ros, which writes the same file) describes each sensor by a continuous-time
white-noise density and a bias random walk:

==============================  =================  ==========================================
key                             unit               avbench coefficient (SI value, same number)
==============================  =================  ==========================================
``gyroscope_noise_density``     rad/s/sqrt(Hz)     N, angle random walk (rad/sqrt(s))
``gyroscope_random_walk``       rad/s^2/sqrt(Hz)   K, rate random walk (rad/s^1.5)
``accelerometer_noise_density`` m/s^2/sqrt(Hz)     N, velocity random walk (m/s/sqrt(s))
``accelerometer_random_walk``   m/s^3/sqrt(Hz)     K, acceleration random walk (m/s^2.5)
``update_rate``                 Hz                 1 / dt
``rostopic``                    --                 the bag's topic
==============================  =================  ==========================================

One number per sensor: the largest over the axes (a filter that assumes the noisiest axis is not
over-confident on the others). Bias instability B has no key (Kalibr models no flicker noise);
many users inflate the values before giving them to a filter (unmodelled vibration, temperature),
typically by a few times: that is ``inflate`` -- never applied unless asked.

``--inflate auto`` (with ``--combine`` and at least three recordings of one sensor) derives the
factors from the data: each recording is also fitted alone, the between-run spread of N and K is
estimated by random effects (:func:`avbench.recordings.fit.random_effects`, DerSimonian & Laird
1986), and each key is multiplied by (upper end of the 95 % prediction interval of a new run's
value) / (the random-effects mean), largest over the axes. What it covers: the run-to-run
variation of the sensor's noise under the conditions the recordings span (warm-up, supply,
mounting, the temperatures they happened at), plus the uncertainty of the mean. What it does not:
temperatures, ages and vibration the recordings did not see, dynamics (g-sensitivity, scale factor),
and anything the model omits; with few recordings the interval is wide (t with k - 2 dof).
"""

from __future__ import annotations

import math

__all__ = ["KEYS", "filter_values", "kalibr_yaml", "parse_inflate"]

#: (sensor, coefficient) -> Kalibr key
KEYS = {("accel", "N"): "accelerometer_noise_density", ("accel", "K"): "accelerometer_random_walk",
        ("gyro", "N"): "gyroscope_noise_density", ("gyro", "K"): "gyroscope_random_walk"}
_UNITS = {"accelerometer_noise_density": "m/s^2/sqrt(Hz)", "accelerometer_random_walk": "m/s^3/sqrt(Hz)",
          "gyroscope_noise_density": "rad/s/sqrt(Hz)", "gyroscope_random_walk": "rad/s^2/sqrt(Hz)"}


def parse_inflate(text) -> tuple[float, float] | str:
    """``"F"`` or ``"F_N,F_K"`` -> factors for the noise densities and the random walks (>= 1 not required, > 0);
    ``"auto"`` is returned as it is (factors from the between-run spread, see the module docstring)."""
    if text is None:
        return 1.0, 1.0
    if str(text).strip().lower() == "auto":
        return "auto"
    parts = [p.strip() for p in str(text).split(",")]
    try:
        vals = [float(p) for p in parts]
    except ValueError:
        vals = []
    if len(vals) == 1:
        vals *= 2
    if len(vals) != 2 or not all(math.isfinite(v) and v > 0 for v in vals):
        raise ValueError(f"--inflate: expected a positive factor F, a pair F_NOISE,F_WALK or 'auto', got {text!r}")
    return vals[0], vals[1]


def filter_values(data: dict, method: str, option: str = "--kalibr") -> dict[str, tuple[float, str]]:
    """Kalibr key -> (SI value, the axis it comes from), from the JSON payload of ``avbench estimate``.

    Raises ValueError naming ``option`` when a sensor is missing or ``method`` gives no value.
    """
    out = {}
    for (sensor, coef), key in KEYS.items():
        sd = data["sensors"].get(sensor)
        if sd is None:
            raise ValueError(f"{option}: the recording has no {'accelerometer' if sensor == 'accel' else 'gyro'} "
                             f"channels; expected gyro and accelerometer axes (a sensor_msgs/Imu topic, or --gyro and --accel)")
        best = None
        for axis, ad in sd["axes"].items():
            md = ad["methods"].get(method)
            if md is None:
                raise ValueError(f"{option}: method {method!r} was not fitted; expected one of --method")
            e = md["coefficients"][coef]
            if e["si"] is None:
                raise ValueError(f"{option}: {method} gives no {coef} for {sensor} axis {axis} ({e['flag']}); expected "
                                 "a method that models it (choose one with --filter-method)")
            if best is None or e["si"] > best[0]:
                best = (e["si"], axis)
        out[key] = best
    return out


def kalibr_yaml(values, update_rate: float, topic: str | None, method: str, sources, inflate=(1.0, 1.0),
                style: str = "kalibr") -> str:
    """The text of a Kalibr ``imu.yaml`` (``style="allan_variance_ros"`` only changes the comment).

    ``inflate``: a pair (noise densities, random walks) given by the user, or a mapping Kalibr key ->
    factor derived from the between-run spread (``--inflate auto``)."""
    who = "Kalibr imu.yaml" if style == "kalibr" else "allan_variance_ros-style imu.yaml (Kalibr keys)"
    lines = [f"# {who} written by avbench estimate from {', '.join(map(str, sources))}",
             f"# method: {method}; each value is the largest over the sensor's axes (axis in the comment)"]
    if isinstance(inflate, dict):
        factors = dict(inflate)
        lines.append("# INFLATED from the between-run spread (--inflate auto): each value x (upper 95 % prediction "
                     "limit of a new run) / (random-effects mean); covers run-to-run variation under the recorded "
                     "conditions, not other temperatures, ageing or vibration")
    else:
        f_noise, f_walk = inflate
        factors = {k: f_noise if k.endswith("noise_density") else f_walk for k in _UNITS}
        lines.append("# values as estimated (no inflation)" if (f_noise, f_walk) == (1.0, 1.0) else
                     f"# INFLATED by the user: noise densities x {f_noise:g}, random walks x {f_walk:g} (--inflate)")
    for key in ("accelerometer_noise_density", "accelerometer_random_walk",
                "gyroscope_noise_density", "gyroscope_random_walk"):
        v, axis = values[key]
        v *= factors[key]
        note = (f"; x {factors[key]:.3g}" if isinstance(inflate, dict) else "") + ("" if v > 0 else "; zero: no random walk seen in this record -- a filter needs a positive value")
        lines.append(f"{key}: {v:.16e}  # {_UNITS[key]}, axis {axis}{note}")
    lines.append(f"rostopic: {topic if topic else '/imu0'}" + ("" if topic else "  # not a bag: Kalibr's default topic"))
    lines.append(f"update_rate: {float(update_rate):.6f}  # Hz")
    return "\n".join(lines) + "\n"
