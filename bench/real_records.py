"""Records that are not five-term gyros, for ``avbench estimate`` end to end
(:mod:`avbench.bench.estimate_e2e`).

* :func:`consumer_imu` -- a consumer-grade MEMS IMU the project can simulate faithfully and ship: per axis
  white noise through the sensor's first-order low-pass filter, a spectral line, a resonance of the
  sense mode, flicker bias instability, a rate random walk and the output quantization (the gyro's and
  the accelerometer's own values; gravity on the accelerometer's z axis);
* :func:`write_consumer` -- that IMU's 6-axis record as an ``.npz`` (arrays ``gyro`` in rad/s, ``accel``
  in m/s^2, ``fs``), at rest or with motion (:func:`add_motion`: rotations by 90 degrees about the three
  axes in turn, the gyro seeing the rotation rate and the accelerometer the turning gravity);
* :func:`write_rounded` -- a consumer module's own calibrated output: the consumer IMU written in deg/s
  and g, rounded to 0.01 deg/s and 0.001 g (as such modules print them), a spectral line and a
  resonance in it;
* :func:`write_flight` -- a PX4-like flight log: the consumer IMU at 200 Hz on a vehicle that moves all
  the time (band-limited rotation rates of ~0.5 rad/s, the gravity they turn, linear accelerations of
  ~1 m/s^2), 69 s by default;
* :func:`write_adis` -- the ADIS16405 runs of ``$AVBENCH_REAL_DATA`` (read in place; a temporary slice
  written for the command, never kept), the first ``n`` samples of the runs given, stitched in order
  (the runs' biases differ: a stitched record has steps where one run ends); ``euroc=True`` writes
  them as a EuRoC-style CSV (ns stamps, rad/s and m/s^2, 9 digits: what visual-inertial users have);
* :func:`real_data_folder` -- the ADIS16405 folder, or None when ``$AVBENCH_REAL_DATA`` is not set or
  does not hold it (a real-data case is then skipped).

>>> imu = consumer_imu(0.01)
>>> sorted(imu)
['accel', 'gyro']
>>> [type(t).__name__ for t in imu["gyro"][0].terms]  # doctest: +NORMALIZE_WHITESPACE
['FilteredWhiteNoise', 'Sinusoidal', 'Resonance', 'BiasInstability', 'RateRandomWalk', 'Quantization']
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np

__all__ = ["consumer_imu", "add_motion", "write_consumer", "write_rounded", "write_flight", "write_adis",
           "write_table", "real_data_folder", "ADIS_FOLDER", "GRAVITY", "HEADER"]

#: the header of a EuRoC-style IMU CSV (names, units and time units all from it: the command needs no flag)
HEADER = ("#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],w_RS_S_z [rad s^-1],"
          "a_RS_S_x [m s^-2],a_RS_S_y [m s^-2],a_RS_S_z [m s^-2]")

#: standard gravity (m/s^2), on the accelerometer's z axis at rest
GRAVITY = 9.80665
#: the ADIS16405 runs' folder under ``$AVBENCH_REAL_DATA``
ADIS_FOLDER = "adis16405-calgary"

#: (gyro, accel) per axis: white noise density N, the filter's time constant (s), the line's amplitude and
#: frequency (Hz), the resonance's sigma, frequency (Hz) and damping time (s), flicker B, random walk K,
#: output step (LSB, in the sensor's unit: rad/s, m/s^2). Values of the BMI088 / ICM-42688 class of
#: datasheets (gyro noise ~0.014 deg/s/sqrt(Hz), accel ~150 ug/sqrt(Hz), in-run bias ~2-10 deg/h / 40 ug,
#: 16-bit outputs at +-2000 deg/s and +-6 g) with a fan's line and a mount's mode.
_CONSUMER = {
    "gyro": dict(N=2.4e-4, tf=0.008, line=(1.5e-4, 13.7), res=(3.0e-4, 31.0, 0.4), B=2.5e-5, K=1.5e-6,
                 lsb=1.065e-3),
    "accel": dict(N=1.5e-3, tf=0.008, line=(1.0e-3, 13.7), res=(2.0e-3, 31.0, 0.4), B=4.0e-4, K=2.0e-5,
                  lsb=1.8e-3),
}


def consumer_imu(dt: float, hours: float = 1.0) -> dict:
    """``{"gyro": [Gyro x3], "accel": [Gyro x3]}``: the consumer IMU's axes (module docstring) at sample
    interval ``dt``; the axes differ by a few per cent in every coefficient (factors 1, 1.07, 0.94), the
    flicker filter's memory is twice ``hours``. Lines and resonances above 0.45 of the sampling rate are
    left out (a 100 Hz record keeps the line, loses nothing)."""
    from avbench.noise_models import (BiasInstability, FilteredWhiteNoise, Gyro, Quantization, RateRandomWalk,
                                      Resonance, Sinusoidal)

    out = {}
    for sensor, p in _CONSUMER.items():
        axes = []
        for f in (1.0, 1.07, 0.94):
            terms = [FilteredWhiteNoise(N=p["N"] * f, tf=p["tf"])]
            if p["line"][1] < 0.45 / dt:
                terms.append(Sinusoidal(A=p["line"][0] * f, f0=p["line"][1]))
            if p["res"][1] < 0.45 / dt:
                terms.append(Resonance(sigma=p["res"][0] * f, f0=p["res"][1], tc=p["res"][2]))
            terms += [BiasInstability(B=p["B"] * f, tau_max=2 * hours * 3600), RateRandomWalk(K=p["K"] * f),
                      Quantization(Q=p["lsb"] * dt / math.sqrt(12))]
            axes.append(Gyro(dt, terms, name=f"consumer {sensor}"))
        out[sensor] = axes
    return out


def add_motion(gyro, accel, dt: float, every_s: float = 300.0, rate: float = math.radians(45.0)):
    """Rotations by 90 degrees at ``rate`` (rad/s) about x, y, z in turn, one every ``every_s`` seconds,
    added in place to the (n, 3) rate ``gyro`` (rad/s) and the (n, 3) ``accel`` (m/s^2): the gyro sees the
    rotation rate, the accelerometer the gravity vector turning into the body axes. The record is then not
    static; its Allan variance has the steps' and ramps' slopes."""
    n = gyro.shape[0]
    g_world = np.array([0.0, 0.0, GRAVITY])
    g_body = np.tile(g_world, (n, 1))  # gravity in the body axes, sample by sample
    attitude = np.eye(3)  # body-from-world rotation before the current move
    dur = int(round((math.pi / 2) / rate / dt))
    every = int(round(every_s / dt))
    start, axis = every, 0
    while start + dur < n:
        gyro[start : start + dur, axis] += rate
        ang = rate * dt * np.arange(1, dur + 1)
        c, s = np.cos(ang), np.sin(ang)
        i, j = (axis + 1) % 3, (axis + 2) % 3
        before = attitude @ g_world  # a world vector seen from a body turning by +ang about ``axis``
        g_body[start : start + dur, axis] = before[axis]
        g_body[start : start + dur, i] = c * before[i] + s * before[j]
        g_body[start : start + dur, j] = -s * before[i] + c * before[j]
        rot = np.eye(3)
        rot[[i, i, j, j], [i, j, i, j]] = [0.0, 1.0, -1.0, 0.0]
        attitude = rot @ attitude
        g_body[start + dur :] = attitude @ g_world
        start += every
        axis = (axis + 1) % 3
    accel += g_body - g_world
    return gyro, accel


def write_consumer(path, hours: float, fs: float, seed: int = 0, motion: bool = False) -> Path:
    """The consumer IMU's 6-axis record (:func:`consumer_imu`) of ``hours`` at ``fs`` Hz as an ``.npz``:
    ``gyro`` (rad/s), ``accel`` (m/s^2, gravity on z), ``fs``; with ``motion``, :func:`add_motion` on the
    same samples (the same seed gives the same noise with and without motion)."""
    dt = 1.0 / fs
    n = int(round(hours * 3600 * fs))
    gyro, accel = _consumer_samples(n, dt, hours, seed)
    if motion:
        add_motion(gyro, accel, dt)
    np.savez(path, gyro=gyro, accel=accel, fs=np.float64(fs))
    return Path(path)


def _consumer_samples(n: int, dt: float, hours: float, seed: int):
    """(gyro rad/s, accel m/s^2 with gravity on z): ``n`` samples of :func:`consumer_imu`'s six axes."""
    imu = consumer_imu(dt, hours)
    gyro = np.column_stack([g.simulate(n, np.random.default_rng([seed, i])) for i, g in enumerate(imu["gyro"])])
    accel = np.column_stack([g.simulate(n, np.random.default_rng([seed, 3 + i]))
                             for i, g in enumerate(imu["accel"])])
    accel[:, 2] += GRAVITY
    return gyro, accel


#: the output steps of a consumer module's calibrated output: gyro (deg/s), accelerometer (g)
ROUNDING = (0.01, 0.001)


def write_rounded(path, hours: float, fs: float, seed: int = 0) -> Path:
    """A consumer module's calibrated output as an ``.npz``: :func:`consumer_imu`'s record in ``gyro``
    (deg/s) and ``accel`` (g), each rounded to its step (:data:`ROUNDING`), and ``fs``."""
    n = int(round(hours * 3600 * fs))
    gyro, accel = _consumer_samples(n, 1.0 / fs, hours, seed)
    step_g, step_a = ROUNDING
    np.savez(path, gyro=np.round(np.rad2deg(gyro) / step_g) * step_g,
             accel=np.round(accel / GRAVITY / step_a) * step_a, fs=np.float64(fs))
    return Path(path)


def write_flight(path, seconds: float = 69.0, fs: float = 200.0, seed: int = 0) -> Path:
    """A PX4-like flight log as an ``.npz`` (``gyro`` rad/s, ``accel`` m/s^2, ``fs``): the consumer IMU's
    noise on a vehicle that moves throughout -- per axis a sum of six sinusoids of 0.1-2 Hz (rates of
    ~0.5 rad/s), the roll and pitch they integrate to turning gravity, and linear accelerations of
    ~1 m/s^2 (0.2-3 Hz)."""
    dt = 1.0 / fs
    n = int(round(seconds * fs))
    gyro, accel = _consumer_samples(n, dt, seconds / 3600, seed)
    rng = np.random.default_rng([seed, 99])
    t = np.arange(n) * dt
    w = sum(0.5 / 3 * np.sin(2 * np.pi * rng.uniform(0.1, 2.0) * t[:, None] + rng.uniform(0, 2 * np.pi, 3))
            for _ in range(6))
    lin = sum(1.0 / 3 * np.sin(2 * np.pi * rng.uniform(0.2, 3.0) * t[:, None] + rng.uniform(0, 2 * np.pi, 3))
              for _ in range(3))
    roll, pitch = (np.cumsum(w[:, i]) * dt for i in (0, 1))
    g_body = GRAVITY * np.column_stack([-np.sin(pitch), np.sin(roll) * np.cos(pitch), np.cos(roll) * np.cos(pitch)])
    accel += g_body - np.array([0.0, 0.0, GRAVITY]) + lin
    gyro += w
    np.savez(path, gyro=gyro, accel=accel, fs=np.float64(fs))
    return Path(path)


def write_table(path, gyro, accel, fs: float) -> Path:
    """``gyro`` (n, 3) rad/s and ``accel`` (n, 3) m/s^2 as a EuRoC-style CSV at ``fs`` (the header of
    :data:`HEADER`, int64 ns stamps, 9 significant digits), written in blocks."""
    n = gyro.shape[0]
    block = 1 << 18
    t0 = 1_403_636_579_758_555_392
    step_ns = int(round(1e9 / fs))
    with open(path, "w") as fh:
        fh.write(HEADER + "\n")
        for a in range(0, n, block):
            b = min(n, a + block)
            t = (t0 + np.arange(a, b, dtype=np.int64) * step_ns).astype(str)
            vals = np.char.mod("%.9g", np.column_stack([gyro[a:b], accel[a:b]]))
            fh.write("\n".join(",".join(row) for row in np.column_stack([t, vals])) + "\n")
    return Path(path)


def real_data_folder() -> Path | None:
    """The ADIS16405 runs' folder under ``$AVBENCH_REAL_DATA``, or None (not set, or not there)."""
    root = os.environ.get("AVBENCH_REAL_DATA")
    if not root:
        return None
    folder = Path(root) / ADIS_FOLDER
    return folder if (folder / "adis_16405_imu1.npz").is_file() else None


def write_adis(path, n: int, runs=(1,), euroc: bool = False) -> Path:
    """The first ``n`` samples of the ADIS16405 runs ``runs`` stitched in order, as an ``.npz`` (``gyro`` in
    deg/s, ``accel`` in g: the files' units, given to the command by flag), or with ``euroc`` as a
    EuRoC-style CSV at 100 Hz (:func:`write_table`: ns stamps, rad/s, m/s^2).
    Raises when the data are not there (:func:`real_data_folder`) or the runs hold fewer than ``n``
    samples."""
    folder = real_data_folder()
    if folder is None:
        raise FileNotFoundError("AVBENCH_REAL_DATA is not set or holds no ADIS16405 runs")
    parts, have = [], 0
    for r in runs:
        if have >= n:
            break
        data = np.load(folder / f"adis_16405_imu{r}.npz")["data"]
        parts.append(data[: n - have])
        have += parts[-1].shape[0]
    if have < n:
        raise ValueError(f"runs {runs} hold {have} samples, fewer than {n}")
    data = np.concatenate(parts)
    if euroc:
        return write_table(path, np.deg2rad(data[:, :3]), data[:, 3:6] * GRAVITY, 100.0)
    np.savez(path, gyro=data[:, :3], accel=data[:, 3:6])
    return Path(path)
