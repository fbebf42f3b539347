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

**A yaml from a short record** (:func:`filter_choices`). A filter needs a positive random walk even
when the record cannot resolve one. Where an axis's value is not a resolved estimate -- the estimator
flags it "not resolved", its evidence says the term is not present, it is zero, its interval reaches
zero, or (for a random walk) the fit is poor -- the yaml takes the upper end of its interval (the method's
95 % interval, or its evidence bound) and says so in a comment. Where the fit of a random walk is poor the
model misses the curve and its interval is not trusted alone: the larger of it and the AV's own bound
(below) is taken. A noise density N that is resolved (its interval above zero) is the estimate also where
the fit check flags the fit: N is read at the shortest scales, where hours of samples pin the AV to a
fraction of a per cent and the white noise dominates it, and its interval already holds the cut-offs of
the sensor's front end the record accepts; the random walk is read at the longest scales, where a
misfit moves it (on the six ADIS16405 runs the upper end of N's interval was 0.3-2 % above N on every
flagged fit). Where the method gives no interval at all, the
bound comes from the Allan variance itself: every term adds to the AV, so ``K^2 tau / 3 <= AV(tau)``
and ``N^2 / tau <= AV(tau)`` at every tau; the bound is the smallest over the octave taus of the
AV's one-sided 95 % chi^2 upper limit turned into the coefficient. For a random walk the comment
also gives the record length that would resolve it: its line ``K^2 tau / 3`` must rise to 4 times
the AV's floor at a tau of at most a quarter of the record, so ``T >= 48 AV_min / K^2`` with K at the
bound -- a lower limit (a smaller true K needs longer).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["KEYS", "UNITS", "axis_value", "filter_values", "filter_choices", "check_sensors", "kalibr_yaml", "parse_inflate", "av_upper_limit", "av_bound"]

#: (sensor, coefficient) -> Kalibr key
KEYS = {("accel", "N"): "accelerometer_noise_density", ("accel", "K"): "accelerometer_random_walk",
        ("gyro", "N"): "gyroscope_noise_density", ("gyro", "K"): "gyroscope_random_walk"}
#: Kalibr key -> its unit
UNITS = {"accelerometer_noise_density": "m/s^2/sqrt(Hz)", "accelerometer_random_walk": "m/s^3/sqrt(Hz)",
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


def check_sensors(sensors, option: str = "--kalibr") -> None:
    """Refuse, before any fit, a recording that lacks a sensor the yaml needs (a gyro and an accelerometer)."""
    for sensor in ("accel", "gyro"):
        if sensor not in sensors:
            raise ValueError(f"{option}: the recording has no {'accelerometer' if sensor == 'accel' else 'gyro'} "
                             f"channels; expected gyro and accelerometer axes (a sensor_msgs/Imu topic, or --gyro and --accel)")


def av_upper_limit(av, scale: float = 1.0, level: float = 0.95):
    """``(tau, upper)`` at the taus where the Allan variance has a value and an edf: the one-sided ``level``
    chi^2 upper limit of AV(tau), AV edf / chi^2_{edf}(1 - level) (``av``: an AllanResult of the record times
    ``scale``); None where no tau has both."""
    # scipy.stats.chi2.ppf(q, nu) is 2 gammaincinv(nu / 2, q): the same bits, without importing scipy.stats
    from scipy.special import gammaincinv

    tau, edf = np.asarray(av.tau, float), np.asarray(av.edf, float)
    avar = np.asarray(av.avar, float) / scale**2
    ok = np.isfinite(avar) & (avar > 0) & np.isfinite(edf) & (edf > 0)
    if not ok.any():
        return None
    return tau[ok], avar[ok] * edf[ok] / (2 * gammaincinv(edf[ok] / 2, 1 - level))


def av_bound(coefficient: str, av, scale: float = 1.0, level: float = 0.95) -> float | None:
    """The upper bound on N or K that the Allan variance itself allows (module docstring): the smallest
    over the taus of the one-sided ``level`` chi^2 upper limit of AV(tau) (:func:`av_upper_limit`) turned
    into the coefficient. None for other coefficients."""
    limit = av_upper_limit(av, scale, level)
    if limit is None:
        return None
    tau, hi = limit
    if coefficient == "K":
        return float(np.sqrt(np.min(3 * hi / tau)))
    if coefficient == "N":
        return float(np.sqrt(np.min(hi * tau)))
    return None


def _resolve_length(k: float, av, scale: float) -> float | None:
    """Record length (s) at which a random walk ``k`` would show: 48 AV_min / k^2 (module docstring)."""
    avar = np.asarray(av.avar, float) / scale**2
    avar = avar[np.isfinite(avar) & (avar > 0)]
    if not avar.size or not k > 0:
        return None
    return float(48 * avar.min() / k**2)


def _duration(seconds: float) -> str:
    return f"{seconds / 3600:.3g} h" if seconds >= 3600 else f"{seconds / 60:.3g} min"


def _length_text(seconds, record_s) -> str:
    """The record length that would resolve a random walk at the bound (a lower limit: a smaller one
    needs longer); where that is no longer than this record, the record already says it is smaller."""
    if seconds is None:
        return ""
    if record_s is not None and seconds <= record_s:
        return (f"; a random walk at this bound would show within {_duration(seconds)}, so the true one is smaller: "
                f"resolving it needs a record longer than this one ({_duration(record_s)})")
    return f"; a record of at least {_duration(seconds)} would resolve it (longer if it is smaller than the bound)"


def _method_result(results: dict, sensor: str, axis: str, method: str, option: str):
    r = results[sensor][axis].get(method)
    if r is None:
        raise ValueError(f"{option}: method {method!r} was not fitted; expected one of --method")
    return r


def filter_choices(results: dict, method: str, option: str = "--kalibr", avs=None) -> dict[str, tuple]:
    """Kalibr key -> (SI value, axis, note or None): the largest over the axes, where each axis gives its
    estimate when resolved and else the upper end of its interval
    (:meth:`~avbench.estimators.results.Coefficient.estimate_or_bound`; module docstring); ``note`` says
    which are bounds and why. ``results``: ``{sensor: {axis: {method: FitResult}}}``
    (:meth:`avbench.recordings.report.Estimate.results`); ``avs``: ``{sensor: {axis: (AllanResult,
    scale)}}`` for the AV bound where the method has no interval. Raises ValueError naming ``option``
    when a sensor is missing or an axis has neither a value nor a bound."""
    check_sensors(list(results), option)
    out = {}
    for (sensor, coef), key in KEYS.items():
        best = None
        for axis in results[sensor]:
            r = _method_result(results, sensor, axis, method, option)
            e = r.coefficients[coef]
            av = (avs or {}).get(sensor, {}).get(axis)
            v, why = axis_value(r, coef)
            if why is not None and v is None and av is not None:
                v, why = av_bound(coef, *av), why + " and the method gives no interval: the bound the AV allows"
            elif r.fit_check.poor_fit and coef != "N" and v is not None and av is not None:  # the model misses the
                b = av_bound(coef, *av)                                      # curve: its interval is not trusted alone
                if b is not None and b > v:
                    v, why = b, (why or "the fit is poor") + "; the bound the AV allows is larger: taken"
            if v is None:
                fail = f"{e.status}: {r.failure}" if r.failure else e.status
                raise ValueError(f"{option}: {method} gives no {coef} for {sensor} axis {axis} ({fail}); expected "
                                 "a method that models it (choose one with --filter-method)")
            if why is not None and coef == "K" and av is not None:
                why += _length_text(_resolve_length(v, *av), av[0].n_samples * av[0].dt)
            if best is None or v > best[0]:
                best = (v, axis, why)
        out[key] = best
    return out


#: the files' words for a value that is a bound, by its code
#: (:meth:`avbench.estimators.results.Coefficient.estimate_or_bound`)
BOUND_NOTES = {"record": "not resolved by this record: the upper end of its interval",
               "evidence": "not resolved (its evidence): the upper end of its interval",
               "zero": "zero (no random walk seen)",
               "interval": "its interval reaches zero: the upper end of the interval",
               "poor fit": "the fit is poor: the upper end of its interval"}


def axis_value(result, coefficient: str):
    """(SI value, None) for a resolved estimate; (upper bound or None, why in words) otherwise: the
    coefficient's :meth:`~avbench.estimators.results.Coefficient.estimate_or_bound` under the fit
    check of ``result`` (a FitResult), its reason rendered (a status where there is no value)."""
    v, code = result.coefficients[coefficient].estimate_or_bound(result.fit_check.poor_fit)
    if code is None:
        return v, None
    if code not in BOUND_NOTES:
        return v, code
    if code == "zero" and v is not None:
        return v, BOUND_NOTES[code] + ": the upper end of its interval"
    return v, BOUND_NOTES[code]


def filter_values(results: dict, method: str, option: str = "--kalibr", avs=None) -> dict[str, tuple[float, str]]:
    """Kalibr key -> (SI value, the axis it comes from): :func:`filter_choices` without the notes."""
    return {k: (v, axis) for k, (v, axis, _) in filter_choices(results, method, option, avs).items()}


def kalibr_yaml(values, update_rate: float, topic: str | None, method: str, sources, inflate=(1.0, 1.0),
                style: str = "kalibr", notes=None, flags=()) -> str:
    """The text of a Kalibr ``imu.yaml`` (``style="allan_variance_ros"`` only changes the comment).

    ``inflate``: a pair (noise densities, random walks) given by the user, or a mapping Kalibr key ->
    factor derived from the between-run spread (``--inflate auto``); ``flags``: lines on the record's
    quality (:func:`avbench.recordings.quality.file_lines`), each a comment."""
    who = "Kalibr imu.yaml" if style == "kalibr" else "allan_variance_ros-style imu.yaml (Kalibr keys)"
    lines = [f"# {who} written by avbench estimate from {', '.join(map(str, sources))}",
             f"# method: {method}; each value is the largest over the sensor's axes (axis in the comment)"]
    lines += [f"# {f}" for f in flags]
    if isinstance(inflate, dict):
        factors = dict(inflate)
        lines.append("# INFLATED from the between-run spread (--inflate auto): each value x (upper 95 % prediction "
                     "limit of a new run) / (random-effects mean); covers run-to-run variation under the recorded "
                     "conditions, not other temperatures, ageing or vibration")
    else:
        f_noise, f_walk = inflate
        factors = {k: f_noise if k.endswith("noise_density") else f_walk for k in UNITS}
        lines.append("# values as estimated (no inflation)" if (f_noise, f_walk) == (1.0, 1.0) else
                     f"# INFLATED by the user: noise densities x {f_noise:g}, random walks x {f_walk:g} (--inflate)")
    for key in ("accelerometer_noise_density", "accelerometer_random_walk",
                "gyroscope_noise_density", "gyroscope_random_walk"):
        v, axis = values[key][:2]
        why = (notes or {}).get(key) or (values[key][2] if len(values[key]) > 2 else None)
        if why:
            lines.append(f"# {key}: a BOUND, not an estimate -- axis {axis} {why}")
        v *= factors[key]
        note = (f"; x {factors[key]:.3g}" if isinstance(inflate, dict) else "") + ("" if v > 0 else "; zero: no random walk seen in this record -- a filter needs a positive value")
        lines.append(f"{key}: {v:.16e}  # {UNITS[key]}, axis {axis}{note}")
    lines.append(f"rostopic: {topic if topic else '/imu0'}" + ("" if topic else "  # not a bag: Kalibr's default topic"))
    lines.append(f"update_rate: {float(update_rate):.6f}  # Hz")
    return "\n".join(lines) + "\n"
