"""The noise parameters of ``avbench estimate`` in the file each filter stack reads.

One module per stack (or family), each an :class:`~avbench.recordings.exports.base.Exporter` -- a
name, a file extension and a function from the fits (per sensor, axis and method a
:class:`~avbench.estimators.results.FitResult`) to the file's text:

======================  ===========  ============================================================
name                    extension    stack (module)
======================  ===========  ============================================================
``kalibr``              yaml         Kalibr ``imu.yaml``, today's text (:mod:`.kalibr`)
``allan_variance_ros``  yaml         allan_variance_ros ``imu.yaml`` (:mod:`.kalibr`)
``openvins``            yaml         OpenVINS ``kalibr_imu_chain.yaml`` (:mod:`.kalibr`)
``vins``                yaml         VINS-Mono / VINS-Fusion ``acc_n`` ... (:mod:`.vins`)
``orbslam3``            yaml         ORB-SLAM3 ``IMU.*`` settings (:mod:`.orbslam3`)
``basalt``              json         Basalt calibration JSON, per axis (:mod:`.basalt`)
``gtsam``               py           GTSAM ``PreintegrationCombinedParams`` snippet (:mod:`.gtsam`)
``px4``                 params       PX4 EKF2 parameters, QGroundControl format (:mod:`.px4`)
``matlab``              m            MATLAB ``gyroparams`` / ``accelparams``, per axis (:mod:`.matlab`)
``ros_imu_covariance``  yaml         ``sensor_msgs/Imu`` covariances, per axis (:mod:`.ros_imu`)
======================  ===========  ============================================================

Every module's docstring gives the stack's keys, units and continuous/discrete convention with the
documentation and source line it follows, and every file repeats them in its header; the values and
their conservative choices (bounds where the record does not resolve a coefficient, ``inflate``) are
made once, in :mod:`.base`. docs/EXPORTS.md has the table of all of them.

:func:`render` writes several at once: ``{name: (suffix, text)}``, the file being ``<stem><suffix>``
with ``suffix = "_<name>.<ext>"``.

Examples
--------
>>> from avbench.recordings.exports import FORMATS
>>> FORMATS["px4"].suffix, FORMATS["basalt"].per_axis
('_px4.params', True)
"""

from __future__ import annotations

import math

from avbench.recordings.exports.base import Exporter, Request
from avbench.recordings.exports.basalt import BASALT
from avbench.recordings.exports.gtsam import GTSAM
from avbench.recordings.exports.kalibr import ALLAN_VARIANCE_ROS, KALIBR, OPENVINS
from avbench.recordings.exports.matlab import MATLAB
from avbench.recordings.exports.orbslam3 import ORBSLAM3
from avbench.recordings.exports.px4 import PX4
from avbench.recordings.exports.ros_imu import ROS_IMU_COVARIANCE
from avbench.recordings.exports.vins import VINS

__all__ = ["FORMATS", "Exporter", "Request", "render", "tables", "parse_names", "default_method"]

#: name -> exporter, in the order of the table above
FORMATS: dict[str, Exporter] = {e.name: e for e in (KALIBR, ALLAN_VARIANCE_ROS, OPENVINS, VINS, ORBSLAM3, BASALT,
                                                   GTSAM, PX4, MATLAB, ROS_IMU_COVARIANCE)}


def parse_names(names, option: str = "--format") -> list[str]:
    """``"a,b"`` or an iterable of names -> the list of known format names, in the order given, each
    once. Raises ValueError naming the unknown ones and the known."""
    if isinstance(names, str):
        names = names.split(",")
    wanted = []
    for n in names:
        n = str(n).strip()
        if n and n not in wanted:
            wanted.append(n)
    unknown = [n for n in wanted if n not in FORMATS]
    if unknown or not wanted:
        got = ", ".join(unknown) if unknown else "nothing"
        raise ValueError(f"{option}: unknown format {got}; expected one or more of {', '.join(FORMATS)} "
                         "(comma-separated)")
    return wanted


def default_method(results: dict) -> str:
    """The method a file is written from when none is named: the first method fitted (the first of
    ``--method``, the default of ``--filter-method``)."""
    for axes in results.values():
        for per_method in axes.values():
            for method in per_method:
                return method
    raise ValueError("no fitted method; expected {sensor: {axis: {method: FitResult}}} of avbench estimate")


def _rate(value, what: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        v = math.nan
    if not (math.isfinite(v) and v > 0):
        raise ValueError(f"{what}: expected a positive rate in Hz, got {value!r}")
    return v


def _inflate(inflate, option: str):
    if isinstance(inflate, dict):
        bad = {k: v for k, v in inflate.items() if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0)}
        if bad:
            raise ValueError(f"{option}: inflation factors must be positive numbers; got {bad}")
        return dict(inflate)
    try:
        f_noise, f_walk = (float(v) for v in inflate)
    except (TypeError, ValueError):
        raise ValueError(f"{option}: inflate must be a pair (noise densities, random walks) or a mapping Kalibr key "
                         f"-> factor; got {inflate!r}") from None
    if not all(math.isfinite(v) and v > 0 for v in (f_noise, f_walk)):
        raise ValueError(f"{option}: inflation factors must be positive numbers; got {inflate!r}")
    return f_noise, f_walk


def render(results: dict, names, method: str | None, rate: float, filter_rate: float | None = None,
           inflate=(1.0, 1.0), topic: str | None = None, sources=(), *, avs=None,
           option: str = "--format", flags=(), static_check=None) -> dict[str, tuple[str, str]]:
    """The text of each format in ``names``: ``{name: (suffix, text)}``, the file ``<stem><suffix>``.

    Parameters
    ----------
    results : dict
        ``{sensor: {axis: {method: FitResult}}}``, the fits of ``avbench estimate``
        (:meth:`avbench.recordings.report.Estimate.results`).
    names : str or iterable of str
        Format names (:data:`FORMATS`), a comma-separated string or a list.
    method : str or None
        The method whose values are written; None: :func:`default_method`.
    rate : float
        The record's sample rate (Hz).
    filter_rate : float, optional
        ``--filter-rate``: the rate at which the stack receives (PX4: predicts with) the samples, where a
        stack discretises at it; at most the record's rate.
    inflate : pair or dict
        As :func:`avbench.recordings.filter_yaml.kalibr_yaml` takes it.
    topic, sources
        The bag's IMU topic (None: Kalibr's ``/imu0``) and the recordings named in the headers.
    avs : dict, optional
        ``{sensor: {axis: (AllanResult, scale)}}``, the Allan variances of ``avbench estimate``: the bound
        the AV allows where the method gives no interval.
    flags : sequence of str
        The record's quality flags as each file's header carries them
        (:func:`avbench.recordings.quality.file_lines`).
    static_check : dict, optional
        The record's static check (:func:`avbench.recordings.static.static_check`): every file opens with
        ``NOT STATIC`` where it says the record moved.

    Raises
    ------
    ValueError
        An unknown format, a rate that is not a positive number, a filter rate above the record's, a
        method that was not fitted or gives neither a value nor a bound, a per-axis format on a
        sensor without three axes -- each message names the option and what was expected.
    """
    wanted = parse_names(names, option)
    req = _request(results, method, rate, filter_rate, inflate, topic, sources, avs, option, flags, static_check)
    return {name: (FORMATS[name].suffix, FORMATS[name].write(req)) for name in wanted}


def tables(results: dict, names, method: str | None, rate: float, filter_rate: float | None = None,
           inflate=(1.0, 1.0), *, avs=None, option: str = "--format") -> dict[str, list]:
    """The noise numbers each format of ``names`` writes, ``{name: [Entry]}``
    (:class:`~avbench.recordings.exports.base.Entry`: key, value as written, unit, axis, bound), for the
    formats that have such a table; the arguments as :func:`render` takes them."""
    wanted = parse_names(names, option)
    req = _request(results, method, rate, filter_rate, inflate, None, (), avs, option)
    return {name: FORMATS[name].table(req) for name in wanted if FORMATS[name].table is not None}


def _request(results, method, rate, filter_rate, inflate, topic, sources, avs, option, flags=(),
             static_check=None) -> Request:
    """The :class:`Request` of :func:`render`'s arguments, each checked."""
    rate = _rate(rate, "the record's rate")
    if filter_rate is not None:
        filter_rate = _rate(filter_rate, "--filter-rate")
        if filter_rate > rate * (1 + 1e-9):
            raise ValueError(f"--filter-rate {filter_rate:g} Hz: above the record's rate {rate:g} Hz; expected the rate "
                             "at which the stack receives (or predicts with) the samples, at most the record's")
    return Request(results=results, method=method if method is not None else default_method(results), rate=rate,
                   filter_rate=filter_rate, inflate=_inflate(inflate, "--inflate"), topic=topic,
                   sources=tuple(sources), avs=avs, option=option, flags=tuple(flags),
                   static_check=static_check)
