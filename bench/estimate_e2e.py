"""``avbench estimate`` end to end: a whole process on a 6-axis recording, with where the time goes.

* :func:`write_euroc` -- an EuRoC-style CSV (``#timestamp [ns],w_RS_S_x [rad s^-1],...``: the shape
  visual-inertial users have; names, units and time units all from the header, so the command needs
  no flag) of ``hours`` at ``fs`` Hz: three axes of the ADIS16405 presets (N, B, K) and an
  accelerometer with white noise, a random walk and gravity;
* :func:`measure` -- the wall time of ``avbench estimate FILE`` with its defaults (every output: the
  screen table, CSV, JSON, the two figures) in a fresh process, after one untimed run on a short file
  of the same shape (numba's disk cache warm, as for any user's second run); then, in this process, the
  same pipeline step by step: reading the file, timing + SI, the static check, the six Allan variances;
  each default method's fits over the six axes as the timed run itself reports them (the timed process
  of :mod:`avbench.bench.real_e2e`); and within the
  fits, by a profile of one more pass, the share of the fit check (:mod:`avbench.estimators.allan.fit_check`, its AV covariance) and of
  GMWM's model evaluations; what is left of the wall time is imports, figures and writing.

``python -m avbench.bench.estimate_e2e CASE`` (a key of :data:`CASES`) runs one measurement and prints it as JSON.
"""

from __future__ import annotations

import cProfile
import json
import os
import pstats
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

__all__ = ["write_euroc", "measure", "CASES"]

#: the records timed: (hours, Hz, the target wall seconds; None: no target)
CASES = {"1h_100Hz": (1.0, 100.0, 10.0), "2h_400Hz": (2.0, 400.0, 60.0), "quick_2min_100Hz": (2 / 60, 100.0, None)}


def write_euroc(path, hours: float, fs: float, seed: int = 0) -> Path:
    """The EuRoC-style CSV of the module docstring, written in blocks (int64 ns stamps, 9 digits)."""
    from avbench.noise_models import presets
    from avbench.noise_models.gyro import Gyro

    n = int(round(hours * 3600 * fs))
    dt = 1.0 / fs
    gyros = [Gyro.from_coefficients(presets.get(p).coefficients, dt) for p in ("ADIS16405_X", "ADIS16405_Y", "ADIS16405_Z")]
    rates = np.column_stack([g.simulate(n, np.random.default_rng([seed, i])) for i, g in enumerate(gyros)])
    rng = np.random.default_rng([seed, 9])
    walk = np.cumsum(2e-5 * np.sqrt(dt) * rng.standard_normal((n, 3)), axis=0)
    acc = 2e-3 * rng.standard_normal((n, 3)) + walk + np.array([0.15, -0.2, 9.80])
    from avbench.bench.real_records import write_table

    return write_table(path, rates, acc, fs)


def _wall(path: Path, out: Path) -> tuple[float, dict]:
    """(wall seconds of ``avbench estimate FILE`` in a fresh process, seconds per method summed over the
    axes): the timed process of :mod:`avbench.bench.real_e2e`, which writes them."""
    from avbench.bench.real_e2e import _run

    with tempfile.TemporaryDirectory(prefix="avbench_e2e_breakdown_") as d:
        wall, _, breakdown = _run(path, [], out, Path(d) / "breakdown.json")
    return wall, breakdown["fits_per_method_s"]


def _steps(path: Path) -> dict:
    """The pipeline step by step in this process (seconds), and a profile of the fits."""
    from avbench.estimators.base import DEFAULT_METHODS
    from avbench.recordings.fit import fit_axis, scaled_allan
    from avbench.recordings.readers import read_recording
    from avbench.recordings.sensors import to_si
    from avbench.recordings.static import static_check
    from avbench.recordings.timing import timing_of

    out = {}
    t0 = time.perf_counter()
    rec = read_recording(path)
    out["read_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    timing = timing_of(rec.time, None, rec.n_samples, rec.path)
    sensors = to_si(rec)
    out["timing_si_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    static_check(sensors, timing.dt)
    out["static_check_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    for s in sensors:
        for x in s.axes.values():
            scaled_allan(x, timing.dt, timing.starts)
    out["six_avs_s"] = time.perf_counter() - t0
    prof = cProfile.Profile()  # shares only: the profiler slows Python-level calls, not the ratios much
    prof.enable()
    for s in sensors:
        for x in s.axes.values():
            fit_axis(x, timing.dt, timing.starts, list(DEFAULT_METHODS))
    prof.disable()
    st = pstats.Stats(prof)
    total = sum(v[3] for k, v in st.stats.items() if k[2] == "fit_axis")

    def share(fns, file_part):
        cum = sum(v[3] for k, v in st.stats.items() if k[2] in fns and file_part in k[0])
        return cum / total if total > 0 else float("nan")

    out["fits_profile_share"] = {
        "fit check (allan/fit_check.assess_fit)": share(("assess_fit",), "fit_check"),
        "AV covariance (allan/covariance.av_covariance)": share(("av_covariance",), "covariance"),
        "gmwm model AV and its Jacobian (likelihood/_gmwm_model.LatentAV)": share(
            ("__call__", "jacobian"), os.path.join("likelihood", "_gmwm_model.py")),
        "Gauss-Markov exact AV (noise_models/terms._gm_f_over_c2)": share(("_gm_f_over_c2",), "terms")}
    return out


def measure(case: str) -> dict:
    """The end-to-end wall time of ``avbench estimate`` on the case's record and its breakdown."""
    hours, fs, target = CASES[case]
    with tempfile.TemporaryDirectory(prefix="avbench_e2e_") as d:
        d = Path(d)
        t0 = time.perf_counter()
        f = write_euroc(d / "imu0.csv", hours, fs)
        t_write = time.perf_counter() - t0
        warm = write_euroc(d / "warm.csv", 120 / 3600, fs, seed=1)
        _wall(warm, d / "warm_out")  # numba's disk cache and the OS file cache warm, as on a second run
        wall, per_method = _wall(f, d / "out")
        steps = _steps(f)
        imports = subprocess.run([sys.executable, "-c", "import time; t=time.perf_counter(); "
                                  "import avbench.recordings.estimate, avbench.estimators, matplotlib.pyplot; "
                                  "print(time.perf_counter()-t)"], capture_output=True, text=True, check=True)
        out = {"case": case, "hours": hours, "fs": fs, "n": int(round(hours * 3600 * fs)), "target_s": target,
               "wall_s": wall, "file_mb": f.stat().st_size / 2**20, "write_s": t_write,
               "imports_s": float(imports.stdout.strip()), **steps, "fits_per_method_s": per_method,
               "fits_s": sum(per_method.values()), "loadavg_after": list(os.getloadavg())}
    known = out["imports_s"] + out["read_s"] + out["timing_si_s"] + out["static_check_s"] + out["six_avs_s"] + out["fits_s"]
    out["rest_s"] = wall - known  # figures, tables, JSON/CSV writing, and the payload
    return out


if __name__ == "__main__":
    print(json.dumps(measure(sys.argv[1]), indent=1))
