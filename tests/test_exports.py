"""The noise parameters in each filter stack's own format (:mod:`avbench.recordings.exports`).

Each stack's conversion is checked from first principles: a white noise of the density and a random
walk of the coefficient the payload gives are simulated (avbench's noise models) at the rate the file
names; the written parameter is put through the stack's own discretisation, re-implemented here from
the line its module cites; the variance that predicts for a sample, a step or an interval must lie in
the chi^2 interval (level 1 - 1e-6) of the simulated one. Every file is read by its consumer's parser:
OpenCV's FileStorage for OpenVINS, VINS and ORB-SLAM3, with the node types each one's code asks for;
PyYAML for Kalibr, allan_variance_ros and the ROS covariances; JSON with basalt's keys and types; the
GTSAM snippet executed (against GTSAM itself where it is installed); the MATLAB and ``.params`` text by
regex. A property test holds every format to its stated conversion of the JSON's coefficients over
unit factors, rates and inflation.
"""

from __future__ import annotations

import functools
import json
import math
import re
import sys
import types
import warnings
import zlib
from unittest import mock

import cv2
import numpy as np
import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy import stats

from avbench.estimators.allan.variance import allan_variance
from avbench.noise_models import AngleRandomWalk, BiasInstability, Gyro, RateRandomWalk
from avbench.recordings import filter_yaml, report
from avbench.recordings.exports import FORMATS, render
from avbench.recordings.exports.base import PLATEAU
from avbench.recordings.fit import fit_axis, scaled_allan
from avbench.recordings.sensors import SensorRecord
from avbench.recordings.timing import Timing

RATE = 100.0
N_RECORD = 2**15
N_SIM = 2**17
ALPHA = 1e-6
SENSORS = ("gyro", "accel")
AXES = ("x", "y", "z")
#: per sensor and axis: (N, B, K) of the simulated record (K = 0: a random walk the record cannot resolve)
TRUTH = {"gyro": {"x": (1e-3, 1e-5, 1e-5), "y": (2e-3, 1e-5, 0.0), "z": (1.5e-3, 1e-5, 2e-5)},
         "accel": {"x": (2e-3, 1e-4, 1e-4), "y": (1e-3, 1e-4, 5e-5), "z": (3e-3, 1e-4, 0.0)}}


# -- the payload ------------------------------------------------------------------------------------------
@functools.lru_cache(maxsize=None)
def _payload(method: str = "gmwm", axes: tuple = AXES):
    """(fits ``{sensor: {axis: {method: FitResult}}}``, AVs) of a simulated 6-axis record fitted by ``method``
    (as test_one_result builds it)."""
    rng = np.random.default_rng(20240611)
    dt = 1.0 / RATE
    sensors = []
    for sensor, unit in (("gyro", "rad/s"), ("accel", "m/s^2")):
        rec = {}
        for a in axes:
            n_, b_, k_ = TRUTH[sensor][a]
            terms = [AngleRandomWalk(N=n_), BiasInstability(B=b_, tau_max=N_RECORD * dt)]
            terms += [RateRandomWalk(K=k_)] if k_ > 0 else []
            rec[a] = Gyro(dt=dt, terms=terms).simulate(N_RECORD, rng)
        sensors.append(SensorRecord(sensor, unit, rec, {}))
    starts = np.zeros(0, dtype=np.int64)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with np.errstate(all="ignore"):
            fits = {s.sensor: {a: fit_axis(x, dt, starts, [method]) for a, x in s.axes.items()} for s in sensors}
    data = report.Estimate(["sim.npz"], Timing(dt, "--fs", N_RECORD), sensors, fits).results()
    avs = {s.sensor: {a: scaled_allan(x, dt, starts) for a, x in s.axes.items()} for s in sensors}
    return data, avs


def _scaled(data: dict, u: float) -> dict:
    """The fits of the same record in a unit u times smaller: every SI quantity x u."""
    return {s: {a: {m: r.rescaled(1.0 / u) for m, r in per.items()} for a, per in axes.items()}
            for s, axes in data.items()}


# -- the rule, restated from the docs (filter_yaml's module docstring), and the conversions ---------------
def _rule(r, c: str):
    """An axis's value (``r``: its FitResult): the estimate where resolved, else the upper end of its
    interval -- the coefficient's one rule, :meth:`~avbench.estimators.results.Coefficient.estimate_or_bound`."""
    return r.coefficients[c].estimate_or_bound(r.fit_check.poor_fit)[0]


def _reference(data: dict, method: str, inflate=(1.0, 1.0)):
    """(per axis {(sensor, coef): {axis: value}}, largest over the axes {(sensor, coef): value}); N and K
    inflated, B as it is."""
    per_axis = {}
    for sensor in SENSORS:
        for axis, per_method in data[sensor].items():
            for c in ("N", "K", "B"):
                f = {"N": inflate[0], "K": inflate[1], "B": 1.0}[c]
                per_axis.setdefault((sensor, c), {})[axis] = _rule(per_method[method], c) * f
    largest = {sc: max(v.values()) for sc, v in per_axis.items()}
    return per_axis, largest


# -- each consumer's parser ------------------------------------------------------------------------------
#: what the consumer's code asks of a node: "real" (``isReal()``), "int" (``isInt()``), "number" (either:
#: ``node >> double``, ``(double)node``), "string" (``isString()``; ``>> std::string`` reads "" otherwise),
#: "matrix" (a sequence of sequences of numbers, read as ``(double)node[r][c]``)
OPENCV_NUMBER_KINDS = {"real": ("isReal",), "int": ("isInt",), "number": ("isReal", "isInt")}
#: OpenVINS: VioManagerOptions.h print_and_load_noise / print_and_load_state, StateOptions.h ("model"),
#: ROS1Visualizer.cpp ("rostopic") -- all under ``imu0`` through opencv_yaml_parse.h
OPENVINS_NODES = {"gyroscope_noise_density": "number", "gyroscope_random_walk": "number",
                  "accelerometer_noise_density": "number", "accelerometer_random_walk": "number",
                  "rostopic": "string", "model": "string", "Tw": "matrix", "Ta": "matrix", "R_IMUtoACC": "matrix",
                  "R_IMUtoGYRO": "matrix", "Tg": "matrix", "T_i_b": "matrix", "time_offset": "number",
                  "update_rate": "number"}
#: ORB-SLAM3, File.version "1.0": Settings::readIMU, readParameter<float> (aborts unless isReal())
ORBSLAM3_NODES = {"IMU.NoiseGyro": "real", "IMU.NoiseAcc": "real", "IMU.GyroWalk": "real", "IMU.AccWalk": "real",
                  "IMU.Frequency": "real"}
#: ORB-SLAM3, older settings files: Tracking::ParseIMUParamFile (IMU.Frequency: isInt(); the rest: isReal())
ORBSLAM3_LEGACY_NODES = {**ORBSLAM3_NODES, "IMU.Frequency": "int"}
#: VINS-Fusion parameters.cpp: ACC_N = fsSettings["acc_n"] ... (operator double); the config around the
#: fragment keeps its own keys (imu_topic >> std::string, g_norm as a double)
VINS_NODES = {"acc_n": "number", "gyr_n": "number", "acc_w": "number", "gyr_w": "number", "imu_topic": "string",
              "g_norm": "number"}
#: a VINS config's own lines around the pasted fragment (config/euroc/euroc_stereo_imu_config.yaml)
VINS_CONFIG = ('%YAML:1.0\n\nimu: 1\nnum_of_cam: 2\n\nimu_topic: "/imu0"\n\n#imu parameters\n{fragment}'
               "g_norm: 9.81007     # gravity magnitude\n")
#: basalt's calibration: the keys of value0 the fragment holds and their JSON types (data/euroc_ds_calib.json:
#: "imu_update_rate": 200.0, "accel_noise_std": [0.016, 0.016, 0.016], ...)
BASALT_TYPES = {"imu_update_rate": float, "accel_noise_std": list, "gyro_noise_std": list, "accel_bias_std": list,
                "gyro_bias_std": list}


def _opencv_value(node):
    """A FileNode as Python: int, float, str, list or dict by the node's own type."""
    if node.isInt():
        return int(node.real())
    if node.isReal():
        return node.real()
    if node.isString():
        return node.string()
    if node.isSeq():
        return [_opencv_value(node.at(i)) for i in range(node.size())]
    if node.isMap():
        return {k: _opencv_value(node.getNode(k)) for k in node.keys()}
    return None


def _opencv_type(node) -> str:
    return next((t for t in ("Int", "Real", "String", "Seq", "Map") if getattr(node, f"is{t}")()), "none")


def _opencv_read(text: str, nodes: dict, under: str | None = None, what: str = "") -> dict:
    """``text`` read by OpenCV's FileStorage as the consumer reads it: every node in ``nodes`` must be of
    the kind its code asks for (AssertionError naming the key, the kind and what OpenCV made of it); the
    values (under the map ``under``, if given) as Python."""
    fs = cv2.FileStorage(text, cv2.FILE_STORAGE_READ | cv2.FILE_STORAGE_MEMORY)
    try:
        root = fs.getNode(under) if under else fs.root()
        assert root.isMap(), f"{what}: OpenCV reads no map{' under ' + under if under else ''}"
        for key, kind in nodes.items():
            node = root.getNode(key)
            got = _opencv_type(node)
            if kind == "matrix":
                ok = node.isSeq() and all(node.at(r).isSeq() and all(
                    node.at(r).at(c).isReal() or node.at(r).at(c).isInt() for c in range(node.at(r).size()))
                    for r in range(node.size()))
            elif kind == "string":
                ok = node.isString()
            else:
                ok = any(getattr(node, m)() for m in OPENCV_NUMBER_KINDS[kind])
            assert ok, f"{what}: OpenCV reads {key} as {got} ({_opencv_value(node)!r}); the consumer needs {kind}"
        return {k: _opencv_value(root.getNode(k)) for k in root.keys()}
    finally:
        fs.release()


def _orbslam3_legacy(text: str) -> str:
    """The fragment as an older settings file takes it: the commented integer IMU.Frequency line in place of
    the real one, as the file's own comment says."""
    legacy = re.findall(r"^# (IMU\.Frequency: \S+)$", text, re.M)
    assert len(legacy) == 1, "orbslam3: expected one commented IMU.Frequency line for older settings files"
    return re.sub(r"^IMU\.Frequency: .*$", legacy[0], text, count=1, flags=re.M)


def _parse(name: str, text: str) -> dict:
    """The numbers a file holds, read as its stack reads it."""
    if name in ("kalibr", "allan_variance_ros", "ros_imu_covariance"):
        return yaml.safe_load(text)
    if name == "openvins":
        return _opencv_read(text, OPENVINS_NODES, "imu0", name)
    if name == "vins":
        assert not text.startswith("%YAML"), "vins: a fragment to paste into a config, which has its own %YAML:1.0"
        d = _opencv_read(VINS_CONFIG.format(fragment=text), VINS_NODES, None, name)
        assert d["imu_topic"] == "/imu0" and d["g_norm"] == 9.81007, "vins: the fragment changed the config around it"
        return d
    if name == "orbslam3":
        first = text.split("\n", 1)[0]
        assert first == "%YAML:1.0", f"{name}: OpenCV's FileStorage needs the %YAML:1.0 directive first, got {first!r}"
        d = _opencv_read(text, ORBSLAM3_NODES, None, "orbslam3 (File.version 1.0: Settings::readIMU)")
        old = _opencv_read(_orbslam3_legacy(text), ORBSLAM3_LEGACY_NODES, None,
                           "orbslam3 (older settings: Tracking::ParseIMUParamFile)")
        assert old["IMU.Frequency"] == round(d["IMU.Frequency"]), (old["IMU.Frequency"], d["IMU.Frequency"])
        return d
    if name == "basalt":
        body = json.loads(text)["value0"]
        assert set(body) == set(BASALT_TYPES), f"basalt: value0 holds {sorted(body)}, expected {sorted(BASALT_TYPES)}"
        for key, t in BASALT_TYPES.items():
            assert isinstance(body[key], t), f"basalt: {key} is {type(body[key]).__name__}, expected {t.__name__}"
            if t is list:
                assert len(body[key]) == 3 and all(isinstance(v, float) for v in body[key]), (key, body[key])
        return body
    if name == "gtsam":
        return _run_gtsam_snippet(text)
    if name == "px4":
        rows = re.findall(r"^1\t1\t(EKF2_\w+)\t(\S+)\t9$", text, re.M)
        assert re.search(r"^# Vehicle-Id Component-Id Name Value Type$", text, re.M)
        return {k: float(v) for k, v in rows}
    if name == "matlab":
        out = {}
        for var, obj, body in re.findall(r"^(\w+) = (gyroparams|accelparams)\( \.\.\.\n(.*?\);)", text, re.M | re.S):
            for prop, vec in re.findall(r"'(\w+)', \[([^\]]*)\]", body):
                out[(obj, prop)] = [float(v) for v in vec.split()]
        out["SampleRate"] = float(re.search(r"'SampleRate', ([0-9.eE+-]+)", text).group(1))
        assert re.search(r"^imu = imuSensor\('accel-gyro', 'SampleRate', .*'Accelerometer', accel, 'Gyroscope', gyro\);$",
                         text, re.M)
        return out
    raise AssertionError(name)


class _GtsamParams:
    """What the snippet may call: GTSAM's five setters (the Python API of PreintegrationCombinedParams)."""

    def __init__(self, gravity):
        self.n_gravity = gravity
        self.set = {}

    def _store(self, name, m):
        m = np.asarray(m, dtype=float)
        assert m.shape == (3, 3), f"{name}: expected a 3x3 matrix, got {m.shape}"
        self.set[name] = m

    def setGyroscopeCovariance(self, m):
        self._store("gyroscopeCovariance", m)

    def setAccelerometerCovariance(self, m):
        self._store("accelerometerCovariance", m)

    def setBiasOmegaCovariance(self, m):
        self._store("biasOmegaCovariance", m)

    def setBiasAccCovariance(self, m):
        self._store("biasAccCovariance", m)

    def setIntegrationCovariance(self, m):
        self._store("integrationCovariance", m)


def _run_gtsam_snippet(text: str) -> dict:
    stub = types.ModuleType("gtsam")
    stub.PreintegrationCombinedParams = types.SimpleNamespace(MakeSharedU=lambda g=9.81: _GtsamParams((0, 0, -g)),
                                                              MakeSharedD=lambda g=9.81: _GtsamParams((0, 0, g)))
    namespace: dict = {}
    with mock.patch.dict(sys.modules, {"gtsam": stub}):
        exec(compile(text, "<gtsam snippet>", "exec"), namespace)
    return namespace["params"].set


#: per format: the written number under each label from the continuous coefficients (docs' conventions)
def _expected(name: str, per_axis: dict, largest: dict, f_record: float, f_used: float, f_predict: float) -> dict:
    """``f_predict``: PX4's prediction rate (--filter-rate, else EKF2's default 100 Hz, at most the record's)."""
    s = math.sqrt(f_used)
    if name in ("kalibr", "allan_variance_ros", "openvins"):
        out = {"accelerometer_noise_density": largest[("accel", "N")], "accelerometer_random_walk": largest[("accel", "K")],
               "gyroscope_noise_density": largest[("gyro", "N")], "gyroscope_random_walk": largest[("gyro", "K")]}
        out["update_rate"] = f_used if name == "openvins" else f_record
        return out
    if name == "vins":
        return {"acc_n": largest[("accel", "N")] * s, "gyr_n": largest[("gyro", "N")] * s,
                "acc_w": largest[("accel", "K")] * s, "gyr_w": largest[("gyro", "K")] * s}
    if name == "orbslam3":
        return {"IMU.NoiseGyro": largest[("gyro", "N")], "IMU.NoiseAcc": largest[("accel", "N")],
                "IMU.GyroWalk": largest[("gyro", "K")], "IMU.AccWalk": largest[("accel", "K")], "IMU.Frequency": f_used}
    if name == "basalt":
        return {"imu_update_rate": f_used,
                **{key: [per_axis[sc][a] for a in AXES] for key, sc in
                   (("accel_noise_std", ("accel", "N")), ("gyro_noise_std", ("gyro", "N")),
                    ("accel_bias_std", ("accel", "K")), ("gyro_bias_std", ("gyro", "K")))}}
    if name == "gtsam":
        eye = np.eye(3)
        return {"gyroscopeCovariance": largest[("gyro", "N")] ** 2 * eye,
                "accelerometerCovariance": largest[("accel", "N")] ** 2 * eye,
                "biasOmegaCovariance": largest[("gyro", "K")] ** 2 * eye,
                "biasAccCovariance": largest[("accel", "K")] ** 2 * eye,
                "integrationCovariance": 1e-8 * eye}
    if name == "px4":
        s = math.sqrt(f_predict)
        return {"EKF2_GYR_NOISE": largest[("gyro", "N")] * s, "EKF2_ACC_NOISE": largest[("accel", "N")] * s,
                "EKF2_GYR_B_NOISE": largest[("gyro", "K")] * s, "EKF2_ACC_B_NOISE": largest[("accel", "K")] * s}
    if name == "matlab":
        out = {"SampleRate": f_used}
        for obj, sensor in (("gyroparams", "gyro"), ("accelparams", "accel")):
            for prop, c in (("NoiseDensity", "N"), ("BiasInstability", "B"), ("RandomWalk", "K")):
                out[(obj, prop)] = [per_axis[(sensor, c)][a] for a in AXES]
        return out
    if name == "ros_imu_covariance":
        return {field: [per_axis[(sensor, "N")][AXES[i // 4]] ** 2 * f_used if i % 4 == 0 else 0.0 for i in range(9)]
                for field, sensor in (("angular_velocity_covariance", "gyro"), ("linear_acceleration_covariance", "accel"))}
    raise AssertionError(name)


def _close(got, want, rel: float, what: str):
    got, want = np.asarray(got, float), np.asarray(want, float)
    assert got.shape == want.shape, f"{what}: shape {got.shape}, expected {want.shape}"
    assert np.allclose(got, want, rtol=rel, atol=0.0), f"{what}: wrote {got}, expected {want}"


# -- simulation and the statistical check -------------------------------------------------------------------
def _sim(term, f: float, *key, n: int = N_SIM) -> np.ndarray:
    seed = np.random.SeedSequence(61107, spawn_key=(zlib.crc32(repr(key).encode()),))
    return Gyro(dt=1.0 / f, terms=[term]).simulate(n, np.random.default_rng(seed))


def _check_var(samples, predicted: float, what: str):
    """``predicted`` lies in the 1 - ALPHA chi^2 interval of the variance of zero-mean iid ``samples``."""
    samples = np.asarray(samples, float)
    n = samples.size
    s2 = float(np.mean(samples**2))
    lo, hi = s2 * n / stats.chi2.ppf(1 - ALPHA / 2, n), s2 * n / stats.chi2.ppf(ALPHA / 2, n)
    assert lo <= predicted <= hi, (f"{what}: the stack's variance {predicted:.5g} is outside [{lo:.5g}, {hi:.5g}], the "
                                   f"{1 - ALPHA} interval of the simulated {s2:.5g} (n = {n})")


def _check_avar(av, predicted: float, what: str, allowance: float = 0.0):
    """``predicted`` AV lies in the 1 - ALPHA chi^2 interval of an AV estimate ``av`` (one tau) with its edf,
    widened by ``allowance`` (a known relative difference of the simulated term from the convention)."""
    a, edf = float(av.avar[0]), float(av.edf[0])
    lo = a * edf / stats.chi2.ppf(1 - ALPHA / 2, edf) * (1 - allowance)
    hi = a * edf / stats.chi2.ppf(ALPHA / 2, edf) * (1 + allowance)
    assert lo <= predicted <= hi, (f"{what}: the convention's AV {predicted:.5g} is outside [{lo:.5g}, {hi:.5g}] "
                                   f"(edf {edf:.0f})")


def _text(name: str, method: str = "gmwm", **kw) -> str:
    data, avs = _payload(method)
    return render(data, [name], method, RATE, avs=avs, **kw)[name][1]


# -- the registry ---------------------------------------------------------------------------------------
def test_registry_names_extensions_and_file_suffixes():
    assert list(FORMATS) == ["kalibr", "allan_variance_ros", "openvins", "vins", "orbslam3", "basalt", "gtsam", "px4",
                             "matlab", "ros_imu_covariance"]
    data, avs = _payload()
    out = render(data, "px4,basalt,px4", "gmwm", RATE, avs=avs)
    assert list(out) == ["px4", "basalt"]
    assert out["px4"][0] == "_px4.params" and out["basalt"][0] == "_basalt.json"
    assert {n: e.extension for n, e in FORMATS.items()}["matlab"] == "m"


@pytest.mark.parametrize("names, match", [("kalibr,rovio", "unknown format rovio"), ("", "unknown format nothing")])
def test_an_unknown_format_is_named_with_the_known_ones(names, match):
    data, _ = _payload()
    with pytest.raises(ValueError, match=match) as err:
        render(data, names, "gmwm", RATE)
    assert "ros_imu_covariance" in str(err.value) and "--format" in str(err.value)


@pytest.mark.parametrize("filter_rate, match", [(0.0, "positive rate"), (float("nan"), "positive rate"),
                                                (400.0, "above the record's rate")])
def test_a_bad_filter_rate_is_refused(filter_rate, match):
    data, _ = _payload()
    with pytest.raises(ValueError, match=match):
        render(data, "vins", "gmwm", RATE, filter_rate=filter_rate)


def test_a_method_not_fitted_is_refused():
    data, _ = _payload()
    with pytest.raises(ValueError, match="method 'mle' was not fitted"):
        render(data, "orbslam3", "mle", RATE)


@pytest.mark.parametrize("name", ["basalt", "matlab", "ros_imu_covariance"])
def test_a_per_axis_format_needs_three_axes(name):
    data, _ = _payload("gmwm", ("x", "y"))
    with pytest.raises(ValueError, match=rf"--format {name}: takes three axes per sensor.*gyro has 2 \(x, y\)"):
        render(data, name, "gmwm", RATE)


def test_the_default_method_is_the_first_fitted():
    data, avs = _payload()
    a = render(data, "orbslam3", None, RATE, avs=avs)["orbslam3"][1]
    b = render(data, "orbslam3", "gmwm", RATE, avs=avs)["orbslam3"][1]
    assert a == b


# -- Kalibr and OpenVINS: keys and types, today's text ----------------------------------------------------
KALIBR_KEYS = {"accelerometer_noise_density": float, "accelerometer_random_walk": float,
               "gyroscope_noise_density": float, "gyroscope_random_walk": float, "rostopic": str, "update_rate": float}


@pytest.mark.parametrize("style", ["kalibr", "allan_variance_ros"])
def test_kalibr_is_todays_text(style):
    data, avs = _payload()
    choices = filter_yaml.filter_choices(data, "gmwm", "--format", avs)
    today = filter_yaml.kalibr_yaml(choices, RATE, "/imu", "gmwm", ["a.bag"], (2.0, 3.0), style)
    assert render(data, style, "gmwm", RATE, inflate=(2.0, 3.0), topic="/imu", sources=["a.bag"], avs=avs)[style][1] == today


def test_kalibr_and_openvins_load_with_kalibrs_keys():
    d = _parse("kalibr", _text("kalibr"))
    assert set(d) == set(KALIBR_KEYS) and all(isinstance(d[k], t) for k, t in KALIBR_KEYS.items())
    o = _parse("openvins", _text("openvins", topic="/dev/imu"))
    extra = {"T_i_b": (4, 4), "Tw": (3, 3), "R_IMUtoGYRO": (3, 3), "Ta": (3, 3), "R_IMUtoACC": (3, 3), "Tg": (3, 3)}
    assert set(o) == set(KALIBR_KEYS) | set(extra) | {"time_offset", "model"}
    assert all(isinstance(o[k], t) for k, t in KALIBR_KEYS.items()) and o["rostopic"] == "/dev/imu"
    assert isinstance(o["time_offset"], float) and o["model"] in ("calibrated", "kalibr", "rpng")
    for k, shape in extra.items():
        assert np.asarray(o[k], float).shape == shape
    assert np.array_equal(o["T_i_b"], np.eye(4)) and np.array_equal(o["Tw"], np.eye(3)) and not np.any(o["Tg"])


# -- each stack's conversion from first principles --------------------------------------------------------
def _truth(method="gmwm"):
    data, _ = _payload(method)
    return _reference(data, method)


@pytest.mark.parametrize("name", ["kalibr", "allan_variance_ros", "openvins"])
def test_kalibr_family_discretises_to_the_simulated_noise(name):
    """Kalibr (wiki "IMU Noise Model"; ConfigReader.py): sigma_d = sigma / sqrt(dt), sigma_bd = sigma_b sqrt(dt);
    OpenVINS (Propagator.cpp): Qc = sigma^2 / dt through G = dt I per step."""
    w = _parse(name, _text(name, filter_rate=50.0))
    _, largest = _truth()
    f = w["update_rate"]
    assert f == (50.0 if name == "openvins" else RATE)
    dt = 1.0 / f
    for sensor, prefix in (("gyro", "gyroscope"), ("accel", "accelerometer")):
        x = _sim(AngleRandomWalk(N=largest[(sensor, "N")]), f, name, sensor, "N")
        r = _sim(RateRandomWalk(K=largest[(sensor, "K")]), f, name, sensor, "K")
        sigma, sigma_b = w[f"{prefix}_noise_density"], w[f"{prefix}_random_walk"]
        if name == "openvins":  # Qd = G Qc G^T, G = dt I, Qc = sigma^2 / dt: per step of the integrated rate
            _check_var(x * dt, dt * (sigma**2 / dt) * dt, f"{name} {sensor} white")
            _check_var(np.diff(r), dt * (sigma_b**2 / dt) * dt, f"{name} {sensor} bias")
        else:
            _check_var(x, (sigma / math.sqrt(dt)) ** 2, f"{name} {sensor} white")
            _check_var(np.diff(r), (sigma_b * math.sqrt(dt)) ** 2, f"{name} {sensor} bias")


def test_vins_midpoint_propagation_recovers_the_simulated_steps():
    """integration_base.h: noise = diag(ACC_N^2, GYR_N^2, ACC_N^2, GYR_N^2, ACC_W^2, GYR_W^2), V(3,3) = V(3,9) =
    0.5 I dt, V(6,0) = V(6,6) = 0.5 R dt, V(9,12) = V(12,15) = I dt; per step (R = I at rest) the angle variance
    0.25 dt^2 (GYR_N^2 + GYR_N^2) must be that of the midpoint 0.5 (w_k + w_k+1) dt of the simulated samples."""
    w = _parse("vins", _text("vins"))
    _, largest = _truth()
    dt = 1.0 / RATE
    for sensor, n_key, w_key in (("gyro", "gyr_n", "gyr_w"), ("accel", "acc_n", "acc_w")):
        x = _sim(AngleRandomWalk(N=largest[(sensor, "N")]), RATE, "vins", sensor, "N")
        r = _sim(RateRandomWalk(K=largest[(sensor, "K")]), RATE, "vins", sensor, "K")
        midpoint = 0.5 * (x[0:-1:2] + x[1::2]) * dt  # non-overlapping pairs: independent steps
        _check_var(midpoint, 0.25 * dt**2 * (w[n_key] ** 2 + w[n_key] ** 2), f"vins {n_key}")
        _check_var(np.diff(r), (w[w_key] * dt) ** 2, f"vins {w_key}")


def test_the_checks_can_fail():
    """The same check, with VINS's number read as a continuous density (Kalibr's convention), is refused:
    the checks tell the conventions apart."""
    w = _parse("vins", _text("vins"))
    _, largest = _truth()
    x = _sim(AngleRandomWalk(N=largest[("gyro", "N")]), RATE, "vins", "gyro", "N")
    with pytest.raises(AssertionError, match="outside"):
        _check_var(x, (w["gyr_n"] * math.sqrt(RATE)) ** 2, "gyr_n as a density")


def test_orbslam3_discretisation_recovers_the_simulated_steps():
    """Tracking.cc: IMU::Calib(Tbc, Ng*sf, Na*sf, Ngw/sf, Naw/sf), sf = sqrt(IMU.Frequency); ImuTypes.cc
    IntegrateNewMeasurement: C += B Nga B^T with B = (rightJ) dt, C(9:15) += NgaWalk per measurement."""
    w = _parse("orbslam3", _text("orbslam3", filter_rate=40.0))
    _, largest = _truth()
    f = w["IMU.Frequency"]
    assert f == 40.0
    sf, dt = math.sqrt(f), 1.0 / f
    for sensor, n_key, k_key in (("gyro", "IMU.NoiseGyro", "IMU.GyroWalk"), ("accel", "IMU.NoiseAcc", "IMU.AccWalk")):
        x = _sim(AngleRandomWalk(N=largest[(sensor, "N")]), f, "orbslam3", sensor, "N")
        r = _sim(RateRandomWalk(K=largest[(sensor, "K")]), f, "orbslam3", sensor, "K")
        _check_var(x * dt, (w[n_key] * sf * dt) ** 2, f"orbslam3 {n_key}")
        _check_var(np.diff(r), (w[k_key] / sf) ** 2, f"orbslam3 {k_key}")


def test_basalt_discretisation_recovers_the_simulated_noise_per_axis():
    """calibration.hpp: dicrete_time_*_noise_std = noise_std * sqrt(imu_update_rate), propagated with
    G = R Jr dt (preintegration.h); imu_block.hpp: the bias difference over dt weighted by
    (1 / bias_std) / sqrt(dt), i.e. of variance bias_std^2 dt -- checked over 10 samples."""
    w = _parse("basalt", _text("basalt"))
    per_axis, _ = _truth()
    f = w["imu_update_rate"]
    dt, span = 1.0 / f, 10
    for sensor in SENSORS:
        for i, a in enumerate(AXES):
            x = _sim(AngleRandomWalk(N=per_axis[(sensor, "N")][a]), f, "basalt", sensor, a, "N")
            r = _sim(RateRandomWalk(K=per_axis[(sensor, "K")][a]), f, "basalt", sensor, a, "K")
            noise, bias = w[f"{sensor}_noise_std"][i], w[f"{sensor}_bias_std"][i]
            _check_var(x * dt, (noise * math.sqrt(f)) ** 2 * dt**2, f"basalt {sensor}_noise_std[{i}]")
            _check_var(r[span::span] - r[:-span:span], bias**2 * (span * dt), f"basalt {sensor}_bias_std[{i}]")


def test_gtsam_covariances_recover_the_simulated_steps():
    """ImuFactor.cpp integrateMeasurement: preintMeasCov += C (wCov / dt) C^T with C = dt I at rest;
    CombinedImuFactor.cpp: D_g_g = dt * biasOmegaCovariance (and the accelerometer's)."""
    w = _parse("gtsam", _text("gtsam"))
    _, largest = _truth()
    dt = 1.0 / RATE
    for sensor, cov, bias in (("gyro", "gyroscopeCovariance", "biasOmegaCovariance"),
                              ("accel", "accelerometerCovariance", "biasAccCovariance")):
        x = _sim(AngleRandomWalk(N=largest[(sensor, "N")]), RATE, "gtsam", sensor, "N")
        r = _sim(RateRandomWalk(K=largest[(sensor, "K")]), RATE, "gtsam", sensor, "K")
        for i in range(3):
            _check_var(x * dt, dt * (w[cov][i, i] / dt) * dt, f"gtsam {cov}")
            _check_var(np.diff(r), dt * w[bias][i, i], f"gtsam {bias}")
        assert not np.any(w[cov] - np.diag(np.diag(w[cov])))


def test_gtsam_snippet_runs_with_gtsam():
    """With GTSAM installed: the snippet builds real params, and one measurement's covariance is the
    simulated step's (preintMeasCov: rotation block first, the biases last)."""
    gtsam = pytest.importorskip("gtsam")
    namespace: dict = {}
    exec(compile(_text("gtsam"), "<gtsam snippet>", "exec"), namespace)
    pim = gtsam.PreintegratedCombinedMeasurements(namespace["params"], gtsam.imuBias.ConstantBias())
    dt = 1.0 / RATE
    pim.integrateMeasurement(np.array([0.0, 0.0, 9.81]), np.zeros(3), dt)
    cov = np.asarray(pim.preintMeasCov())
    _, largest = _truth()
    x = _sim(AngleRandomWalk(N=largest[("gyro", "N")]), RATE, "gtsam", "gyro", "N")
    r = _sim(RateRandomWalk(K=largest[("gyro", "K")]), RATE, "gtsam", "gyro", "K")
    _check_var(x * dt, cov[0, 0], "gtsam rotation block")
    _check_var(np.diff(r), cov[12, 12], "gtsam gyro bias block")


def test_px4_delta_angles_over_the_prediction_step_match():
    """covariance.cpp predictCovariance: d_ang_var = sq(delta_ang_dt * gyro_noise) over an EKF step (here
    25 Hz on a 100 Hz record: 4 samples accumulated), gyro_bias_sig = dt * gyro_bias_p_noise per step."""
    text = _text("px4", filter_rate=25.0)
    w = _parse("px4", text)
    _, largest = _truth()
    k, dt_ekf = 4, 1.0 / 25.0
    for sensor, noise, bias in (("gyro", "EKF2_GYR_NOISE", "EKF2_GYR_B_NOISE"),
                                ("accel", "EKF2_ACC_NOISE", "EKF2_ACC_B_NOISE")):
        x = _sim(AngleRandomWalk(N=largest[(sensor, "N")]), RATE, "px4", sensor, "N")
        r = _sim(RateRandomWalk(K=largest[(sensor, "K")]), RATE, "px4", sensor, "K")
        delta = x[: x.size // k * k].reshape(-1, k).sum(axis=1) / RATE  # the accumulated delta angle of a step
        _check_var(delta, (dt_ekf * w[noise]) ** 2, f"px4 {noise}")
        _check_var(r[k::k] - r[:-k:k], (dt_ekf * w[bias]) ** 2, f"px4 {bias}")
        assert f"param set {noise} " in text
    assert "25 Hz from --filter-rate" in text


def test_px4_says_when_a_value_is_outside_its_documented_range():
    data, _ = _payload()
    text = render(_scaled(data, 1e-3), "px4", "gmwm", RATE)["px4"][1]
    assert re.search(r"EKF2_ACC_NOISE: outside its documented range \[0\.01, 1\]", text)


@pytest.mark.parametrize("record_rate, f", [(400.0, 100.0), (100.0, 100.0), (50.0, 50.0)])
def test_px4_predicts_at_ekf2s_default_rate_unless_told(record_rate, f):
    """Without --filter-rate: EKF2_PREDICT_US's default, 10000 us (100 Hz), at most the record's rate; said."""
    data, avs = _payload()
    text = render(data, "px4", "gmwm", record_rate, avs=avs)["px4"][1]
    _, largest = _truth()
    w = _parse("px4", text)
    _close(w["EKF2_GYR_NOISE"], largest[("gyro", "N")] * math.sqrt(f), 1e-8, "EKF2_GYR_NOISE")
    said = re.search(r"^# f \(EKF2's prediction rate, 1e6 / EKF2_PREDICT_US\): (\S+) Hz, (.*)$", text, re.M)
    assert said and float(said.group(1)) == f
    assert ("EKF2's default (EKF2_PREDICT_US = 10000 us)" in said.group(2)) == (record_rate >= 100.0)


@pytest.mark.parametrize("name, line, match", [
    ("openvins", "  rostopic: /imu0  # not a bag: Kalibr's default topic", "rostopic as Map"),
    ("orbslam3", "IMU.Frequency: 100.000000  # Hz", r"IMU\.Frequency as Real .* needs int")])
def test_the_opencv_readers_refuse_what_their_stacks_cannot_take(name, line, match):
    """The checks fail on lines a stack's file must not hold: an unquoted topic with a comment (OpenCV makes a
    map of it, and OpenVINS's ``>> std::string`` an empty topic) and ORB-SLAM3's frequency as a real number
    (an older settings file's ``isInt()`` refuses it)."""
    text = _text(name)
    key = line.split(":")[0].strip()
    bad = re.sub(rf"^(# )?\s*{re.escape(key)}: .*\n", "", text, flags=re.M)
    bad = bad.replace("imu0:\n", "imu0:\n" + line + "\n") if name == "openvins" else bad + line + "\n"
    _parse(name, text)
    with pytest.raises(AssertionError, match=match if name == "openvins" else "one commented IMU.Frequency line"):
        _parse(name, bad)
    if name == "orbslam3":  # and with the integer line present but a real one, as older files of the stack hold
        with pytest.raises(AssertionError, match=match):
            _opencv_read(bad, ORBSLAM3_LEGACY_NODES, None, "orbslam3 (older settings)")


def test_matlab_values_follow_the_allan_relations_of_mathworks_example():
    """The example reads NoiseDensity at tau = 1 s on N/sqrt(tau), RandomWalk at tau = 3 s on K sqrt(tau/3) and
    BiasInstability from the flat line sqrt(2 ln2/pi) B: each written value must predict the AV of its
    simulated term there (the flicker term's exact AV at 1 s differs from the flat line by a known 0.3 %)."""
    w = _parse("matlab", _text("matlab"))
    per_axis, _ = _truth()
    f = w["SampleRate"]
    b_term = BiasInstability(B=1.0, tau_max=100.0)
    allowance = abs(float(b_term.avar(np.array([int(f)]), 1.0 / f)[0]) / PLATEAU - 1.0)
    for obj, sensor in (("gyroparams", "gyro"), ("accelparams", "accel")):
        for i, a in enumerate(AXES):
            x = _sim(AngleRandomWalk(N=per_axis[(sensor, "N")][a]), f, "matlab", sensor, a, "N")
            r = _sim(RateRandomWalk(K=per_axis[(sensor, "K")][a]), f, "matlab", sensor, a, "K")
            b = _sim(BiasInstability(B=per_axis[(sensor, "B")][a], tau_max=100.0), f, "matlab", sensor, a, "B")
            _check_avar(allan_variance(x, 1 / f, taus=np.array([1.0]), noise="white_fm"),
                        w[(obj, "NoiseDensity")][i] ** 2 / 1.0, f"matlab {obj}.NoiseDensity({i + 1})")
            _check_avar(allan_variance(r, 1 / f, taus=np.array([3.0]), noise="rw_fm"),
                        w[(obj, "RandomWalk")][i] ** 2 * 3.0 / 3.0, f"matlab {obj}.RandomWalk({i + 1})")
            _check_avar(allan_variance(b, 1 / f, taus=np.array([1.0]), noise="flicker_fm"),
                        PLATEAU * w[(obj, "BiasInstability")][i] ** 2, f"matlab {obj}.BiasInstability({i + 1})",
                        allowance)


def test_ros_covariance_is_the_simulated_per_sample_variance():
    """sensor_msgs/Imu: row major about x, y, z; the diagonal holds each axis's variance of one sample."""
    w = _parse("ros_imu_covariance", _text("ros_imu_covariance", filter_rate=80.0))
    per_axis, _ = _truth()
    for field, sensor in (("angular_velocity_covariance", "gyro"), ("linear_acceleration_covariance", "accel")):
        cov = np.asarray(w[field], float).reshape(3, 3)
        assert not np.any(cov - np.diag(np.diag(cov)))
        for i, a in enumerate(AXES):
            x = _sim(AngleRandomWalk(N=per_axis[(sensor, "N")][a]), 80.0, "ros", sensor, a)
            _check_var(x, cov[i, i], f"ros {field}[{4 * i}]")


# -- bounds and notes -------------------------------------------------------------------------------------
def _bound_axes(data, method, sensor, coef):
    """The axes whose value is a bound (not a resolved estimate), by the rule of the docs."""
    return [a for a, per in data[sensor].items()
            if per[method].coefficients[coef].estimate_or_bound(per[method].fit_check.poor_fit)[1] is not None]


@pytest.mark.parametrize("name", list(FORMATS))
def test_every_bound_is_said(name):
    data, avs = _payload()
    text = render(data, name, "gmwm", RATE, sources=["sim.npz"], avs=avs)[name][1]
    per_axis, largest = _reference(data, "gmwm")
    said = re.findall(r"a BOUND, not an estimate -- axis (\w)", text)
    per_axis_format = FORMATS[name].per_axis
    expected = 0
    for sensor in SENSORS:
        for coef in ("N", "K", "B"):
            if coef == "B" and name != "matlab":
                continue
            if coef == "K" and name == "ros_imu_covariance":
                continue
            bounds = _bound_axes(data, "gmwm", sensor, coef)
            if per_axis_format:
                expected += len(bounds)
            elif coef != "B":
                top = max(per_axis[(sensor, coef)], key=per_axis[(sensor, coef)].get)
                expected += top in bounds
    # the record is short: its random walks and bias instabilities are bounds; every N is resolved
    assert expected > 0 or name == "ros_imu_covariance", "the payload should hold bounds"
    assert len(said) == expected, f"{name}: {len(said)} bounds said, {expected} expected"
    assert "written by avbench estimate from sim.npz" in text


def test_bounds_from_the_allan_variance_where_the_method_gives_no_interval():
    data, avs = _payload("wls")
    out = render(data, ["basalt", "matlab", "vins"], "wls", RATE, avs=avs)
    notes = json.loads(out["basalt"][1])["avbench_notes"]
    assert any("the bound the AV allows" in n for n in notes)
    assert "the bound the AV allows (flat line 0.664 B)" in out["matlab"][1]
    with pytest.raises(ValueError, match="--format: wls gives no"):
        render(data, "basalt", "wls", RATE)  # without the AVs there is no bound to write


def test_the_file_says_which_rate():
    assert "f: 100 Hz, the record's rate (--filter-rate not given)" in _text("vins")
    assert "f: 50 Hz from --filter-rate (the record's rate: 100 Hz)" in _text("vins", filter_rate=50.0)
    assert re.search(r"^IMU\.Frequency: 50\.0$", _text("orbslam3", filter_rate=50.0), re.M)


def test_inflation_is_said_and_applied():
    text = _text("vins", inflate=(2.0, 3.0))
    assert "INFLATED by the user: noise densities x 2, random walks x 3 (--inflate)" in text
    auto = _text("orbslam3", inflate={"gyroscope_noise_density": 1.5, "gyroscope_random_walk": 2.0,
                                      "accelerometer_noise_density": 1.0, "accelerometer_random_walk": 1.0})
    _, largest = _truth()
    assert math.isclose(_parse("orbslam3", auto)["IMU.GyroWalk"], 2.0 * largest[("gyro", "K")], rel_tol=1e-14)
    assert "--inflate auto" in auto


# -- the property: every format is its stated conversion of the JSON's coefficients --------------------------
@settings(max_examples=30, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(u=st.floats(1e-6, 1e6), rate=st.floats(1.0, 4000.0), share=st.one_of(st.none(), st.floats(0.01, 1.0)),
       f_noise=st.floats(0.5, 5.0), f_walk=st.floats(0.5, 5.0))
def test_every_format_is_its_conversion_of_the_json(u, rate, share, f_noise, f_walk):
    base, _ = _payload()
    data = _scaled(base, u)
    filter_rate = None if share is None else rate * share
    out = render(data, list(FORMATS), "gmwm", rate, filter_rate, (f_noise, f_walk))
    per_axis, largest = _reference(data, "gmwm", (f_noise, f_walk))
    per_axis_1, largest_1 = _reference(base, "gmwm", (f_noise, f_walk))
    for sc in largest:  # the JSON's coefficients scale with the unit
        assert math.isclose(largest[sc], u * largest_1[sc], rel_tol=1e-12)
    f_used = rate if filter_rate is None else filter_rate
    for name, (suffix, text) in out.items():
        assert suffix == f"_{name}.{FORMATS[name].extension}"
        got = _parse(name, text)
        want = _expected(name, per_axis, largest, rate, f_used, min(100.0, rate) if filter_rate is None else filter_rate)
        for label, value in want.items():
            rates = label in ("update_rate", "IMU.Frequency", "imu_update_rate", "SampleRate")
            if rates:  # written with 6 decimals
                assert abs(got[label] - value) <= 5e-7 * (1 + 1e-9 * value), (name, label, got[label], value)
            else:
                _close(got[label], value, 1e-8 if name == "px4" else 1e-12, f"{name} {label}")
        if name == "px4":
            from avbench.recordings.exports.px4 import PARAMETERS

            for p, (_, _, _, lo, hi) in PARAMETERS.items():
                assert (f"{p}: outside its documented range" in text) == (not lo <= got[p] <= hi)
