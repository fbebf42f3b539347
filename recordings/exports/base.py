"""What every export writes: the values, their notes, and the header each file opens with.

An exporter turns the fits of ``avbench estimate`` -- per sensor, axis and method a
:class:`~avbench.estimators.results.FitResult` (:meth:`avbench.recordings.report.Estimate.results`) --
into the text of one filter stack's file. They all write the same numbers, chosen once here:

* **Which value.** Per sensor (gyro, accel) and coefficient (N, K) the rule of the Kalibr yaml,
  :func:`avbench.recordings.filter_yaml.filter_choices`, each coefficient's
  :meth:`~avbench.estimators.results.Coefficient.estimate_or_bound`: an axis gives its estimate where the method
  resolves it and else the upper end of its interval (a BOUND, with the reason), or the bound the
  Allan variance allows where the method gives no interval. A stack that takes one number per sensor
  gets the largest over the axes (:func:`sensor_values`); a stack that takes one per axis gets each
  axis's own choice (:func:`axis_values`), made by the same function on the fits of that
  axis alone, so the two cannot disagree on an axis.
* **Bias instability B** (only MATLAB's ``gyroparams`` takes it): the same rule per axis
  (:func:`bias_instability`); where the method gives no interval the bound comes from IEEE Std 952's
  flat line: the flicker term adds at least :math:`(2 \\ln 2/\\pi) B^2` to the Allan variance over its
  flat band, so :math:`B \\le \\min_\\tau \\sqrt{AV_{95}(\\tau) \\pi / (2 \\ln 2)}` with :math:`AV_{95}` the
  one-sided 95 % chi^2 upper limit of the measured AV -- the usual reading ``B = min ADEV / 0.664``
  with the AV's own uncertainty added.
* **Inflation.** ``inflate`` as :func:`~avbench.recordings.filter_yaml.kalibr_yaml` takes it: a pair
  (noise densities N, random walks K) or a mapping Kalibr key -> factor (``--inflate auto``). B is
  not inflated (the factors are defined for N and K).
* **Rate.** ``rate`` is the record's sample rate; ``filter_rate`` (``--filter-rate``), where given,
  the rate at which the stack receives -- or, for PX4's EKF2, predicts with -- the samples. A stack
  that discretises at a rate uses ``filter_rate`` if given and else the record's rate, and its file
  says which (:meth:`Request.rate_text`).

Numbers are written with 17 significant digits (``%.16e``): a float64 survives the round trip, and
YAML 1.1 readers (PyYAML) read every one as a float (they read ``1e-05`` without a point as a string).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from avbench.recordings import filter_yaml

__all__ = ["Value", "Entry", "Request", "Exporter", "PLATEAU", "fmt", "factor", "sensor_values", "axis_values",
           "axis_order", "bias_instability", "plateau_bound", "header", "not_static_lines", "bound_lines",
           "inflate_text"]

#: the Allan variance of bias instability on its flat band, per B^2 (IEEE Std 952 Annex C): 2 ln2 / pi
PLATEAU = 2.0 * math.log(2.0) / math.pi
#: SI units of the coefficients, by sensor
UNITS = {("gyro", "N"): "rad/s/sqrt(Hz)", ("gyro", "K"): "rad/s^2/sqrt(Hz)", ("gyro", "B"): "rad/s",
         ("accel", "N"): "m/s^2/sqrt(Hz)", ("accel", "K"): "m/s^3/sqrt(Hz)", ("accel", "B"): "m/s^2"}
SENSORS = ("gyro", "accel")


@dataclass(frozen=True)
class Value:
    """One written coefficient (SI): ``value`` = ``estimate`` x ``factor``; ``bound`` says why it is an
    upper bound and not an estimate (None for a resolved estimate)."""

    value: float
    estimate: float
    factor: float
    axis: str
    bound: str | None


@dataclass(frozen=True)
class Request:
    """What an exporter is asked to write (see the module docstring for each field)."""

    results: dict  # {sensor: {axis: {method: FitResult}}}
    method: str
    rate: float
    filter_rate: float | None = None
    inflate: tuple | dict = (1.0, 1.0)
    topic: str | None = None
    sources: tuple = ()
    avs: dict | None = None
    option: str = "--format"
    flags: tuple = ()  # the record's quality flags, one header line each (avbench.recordings.quality.file_lines)
    static_check: dict | None = None  # the record's static check (avbench.recordings.static): a file opens with
    #                                   NOT STATIC where it says the record moved

    @property
    def used_rate(self) -> float:
        """The rate (Hz) a stack that discretises uses: ``filter_rate`` if given, else the record's."""
        return float(self.filter_rate) if self.filter_rate is not None else float(self.rate)

    def rate_text(self, what: str) -> str:
        """One sentence: which rate is written as ``what`` and where it comes from."""
        if self.filter_rate is None:
            return f"{what}: {self.used_rate:.6g} Hz, the record's rate (--filter-rate not given)"
        return f"{what}: {self.used_rate:.6g} Hz from --filter-rate (the record's rate: {float(self.rate):.6g} Hz)"


@dataclass(frozen=True)
class Entry:
    """One number a file writes: under its ``key``, in the stack's ``unit``, from ``axis`` (or the
    axes), ``bound`` saying why it is an upper bound (None for an estimate)."""

    key: str
    value: float
    unit: str
    axis: str
    bound: str | None = None


@dataclass(frozen=True)
class Exporter:
    """One format: its ``name`` (the ``--format`` value), file ``extension``, the ``stack`` it is for,
    whether it writes one value per axis, ``write(request) -> text``, and ``table(request) -> [Entry]``
    (the noise numbers the text writes, each under its key; None where the format has none)."""

    name: str
    extension: str
    stack: str
    per_axis: bool
    write: Callable[[Request], str]
    table: Callable[[Request], list] | None = None

    @property
    def suffix(self) -> str:
        """What follows the output stem in the file name: ``_<name>.<extension>``."""
        return f"_{self.name}.{self.extension}"


def fmt(v: float) -> str:
    """``v`` with 17 significant digits and a decimal point (module docstring)."""
    return f"{float(v):.16e}"


def factor(inflate, sensor: str, coefficient: str) -> float:
    """The inflation factor of one sensor's N or K (1.0 for B): the pair's first (N) or second (K)
    element, or the mapping's entry for the Kalibr key (1.0 where the mapping has none)."""
    if coefficient not in ("N", "K"):
        return 1.0
    if isinstance(inflate, dict):
        return float(inflate.get(filter_yaml.KEYS[(sensor, coefficient)], 1.0))
    return float(inflate[0] if coefficient == "N" else inflate[1])


def _value(req: Request, sensor: str, coefficient: str, choice) -> Value:
    v, axis, why = choice
    f = factor(req.inflate, sensor, coefficient)
    return Value(value=v * f, estimate=v, factor=f, axis=axis, bound=why)


def sensor_values(req: Request) -> dict[tuple[str, str], Value]:
    """(sensor, "N"|"K") -> the largest over the axes (:func:`~avbench.recordings.filter_yaml.filter_choices`),
    inflated."""
    choices = filter_yaml.filter_choices(req.results, req.method, req.option, req.avs)
    return {(s, c): _value(req, s, c, choices[key]) for (s, c), key in filter_yaml.KEYS.items()}


def axis_order(req: Request, stack: str) -> dict[str, list[str]]:
    """sensor -> its three axes in the order a per-axis stack takes them (x, y, z where those are the
    names, else the record's order). Raises ValueError naming the stack where a sensor has not three."""
    filter_yaml.check_sensors(list(req.results), req.option)
    out = {}
    for sensor in SENSORS:
        axes = list(req.results[sensor])
        if len(axes) != 3:
            raise ValueError(f"{req.option} {stack}: takes three axes per sensor (x, y, z); the recording's "
                             f"{sensor} has {len(axes)} ({', '.join(axes)})")
        out[sensor] = ["x", "y", "z"] if set(axes) == {"x", "y", "z"} else axes
    return out


def _one_axis(results: dict, sensor: str, axis: str) -> dict:
    """The fits with ``sensor`` reduced to ``axis`` (the other sensor as it is)."""
    return {**results, sensor: {axis: results[sensor][axis]}}


def axis_values(req: Request, stack: str) -> dict[tuple[str, str], dict[str, Value]]:
    """(sensor, "N"|"K") -> axis -> that axis's own choice, inflated: the rule of
    :func:`~avbench.recordings.filter_yaml.filter_choices` on the fits of that axis alone."""
    out: dict[tuple[str, str], dict[str, Value]] = {}
    for sensor, axes in axis_order(req, stack).items():
        for axis in axes:
            choices = filter_yaml.filter_choices(_one_axis(req.results, sensor, axis), req.method, req.option, req.avs)
            for c in ("N", "K"):
                out.setdefault((sensor, c), {})[axis] = _value(req, sensor, c, choices[filter_yaml.KEYS[(sensor, c)]])
    return out


def plateau_bound(av, scale: float = 1.0, level: float = 0.95) -> float | None:
    """The largest B the Allan variance allows under IEEE Std 952's flat line (module docstring):
    :math:`\\min_\\tau \\sqrt{AV_{level}(\\tau) / (2 \\ln 2 / \\pi)}`, with :math:`AV_{level}` the one-sided
    chi^2 upper limit of the AV (``av``: an AllanResult of the record times ``scale``). None where the AV
    has no usable point (:func:`~avbench.recordings.filter_yaml.av_upper_limit`)."""
    limit = filter_yaml.av_upper_limit(av, scale, level)
    return None if limit is None else float(np.sqrt(np.min(limit[1]) / PLATEAU))


def bias_instability(req: Request, stack: str) -> dict[str, dict[str, Value]]:
    """sensor -> axis -> B (SI, not inflated): the estimate where resolved, else the upper end of its
    interval, else the flat-line bound of :func:`plateau_bound` -- the rule of
    :func:`~avbench.recordings.filter_yaml.filter_choices` applied to B. Raises ValueError naming the
    axis where there is neither a value nor a bound."""
    from avbench.recordings.filter_yaml import axis_value

    out: dict[str, dict[str, Value]] = {}
    for sensor, axes in axis_order(req, stack).items():
        for axis in axes:
            r = req.results[sensor][axis].get(req.method)
            if r is None:
                raise ValueError(f"{req.option}: method {req.method!r} was not fitted; expected one of --method")
            av = (req.avs or {}).get(sensor, {}).get(axis)
            v, why = axis_value(r, "B")
            if why is not None and v is None and av is not None:
                v = plateau_bound(*av)
                why += " and the method gives no interval: the bound the AV allows (flat line 0.664 B)"
            elif r.fit_check.poor_fit and v is not None and av is not None:
                b = plateau_bound(*av)
                if b is not None and b > v:
                    v, why = b, (why or "the fit is poor") + "; the bound the AV allows is larger: taken"
            if v is None:
                raise ValueError(f"{req.option} {stack}: {req.method} gives no B for {sensor} axis {axis} ({r.coefficients['B'].status}); "
                                 "expected a method that models bias instability (choose one with --filter-method)")
            out.setdefault(sensor, {})[axis] = Value(value=v, estimate=v, factor=1.0, axis=axis, bound=why)
    return out


def inflate_text(inflate) -> str:
    """The sentence each file gives on inflation (the Kalibr yaml's words)."""
    if isinstance(inflate, dict):
        shown = ", ".join(f"{k} x {v:.3g}" for k, v in inflate.items())
        return ("INFLATED from the between-run spread (--inflate auto): each value x (upper 95 % prediction limit of a "
                "new run) / (random-effects mean): " + shown + "; covers run-to-run variation under the recorded "
                "conditions, not other temperatures, ageing or vibration")
    f_noise, f_walk = inflate
    if (f_noise, f_walk) == (1.0, 1.0):
        return "values as estimated (no inflation)"
    return f"INFLATED by the user: noise densities x {f_noise:g}, random walks x {f_walk:g} (--inflate)"


def header(req: Request, title: str, scope: str, convention: list[str], rate: str | None) -> list[str]:
    """The opening lines every file carries (without comment marks): what it is and where it comes
    from, the method and whether a value is per axis or the largest over the axes, the stack's
    convention with its sources, the rate used, the inflation and a line per flag on the record's
    quality (:func:`avbench.recordings.quality.file_lines`)."""
    sources = ", ".join(map(str, req.sources)) or "(no source named)"
    lines = not_static_lines(req.static_check)
    lines += [f"{title} written by avbench estimate from {sources}", f"method: {req.method}; {scope}"]
    lines += convention
    if rate is not None:
        lines.append(rate)
    lines.append(inflate_text(req.inflate))
    return lines + list(req.flags)


def not_static_lines(still: dict | None) -> list[str]:
    """The lines that open a file written from a record the static check (``still``,
    :func:`avbench.recordings.static.static_check`) called not static (fitted only because the user asked):
    none for a static record or where no check was made."""
    still = still or {}
    if still.get("static", True):
        return []
    return ["NOT STATIC: the record was not at rest (" + "; ".join(still.get("reasons", [])[:2]) + "); these values "
            "come from fits asked for anyway (--fit-not-static) and are not a sensor's noise at rest"]


def bound_lines(values: dict[str, Value]) -> list[str]:
    """One line per written value that is not a resolved estimate: ``KEY: a BOUND, not an estimate --
    axis a <why>``; and one per zero (a filter needs a positive value)."""
    out = []
    for key, v in values.items():
        if v.bound:
            out.append(f"{key}: a BOUND, not an estimate -- axis {v.axis} {v.bound}")
        if not v.value > 0:
            out.append(f"{key}: zero on axis {v.axis}: no such noise seen in this record -- a filter needs a positive value")
    return out
