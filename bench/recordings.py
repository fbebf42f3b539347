"""Reading recordings and ``avbench estimate`` on long records: speed against pandas, peak memory.

* :func:`write_csv` -- a 7-column CSV (time + 3 gyro + 3 accel axes, header row) of ``n`` rows;
* :func:`read_peak` -- in a child process: the peak RSS of reading that CSV with
  :func:`avbench.recordings.readers.read_recording`, above the RSS after imports, against the size
  of the numeric data (n x 7 x 8 bytes);
* :func:`estimate_peak` -- in a child process: ``avbench estimate REC.npy --fs 100 --units rad/s``
  on ``n`` float64 samples; its peak RSS (``ru_maxrss`` of the child) against the record's size.

The benchmark classes that run them: :class:`ReadRecording` (the reader against a bare
``pandas.read_csv`` of the same file, and its peak memory over the numeric data),
:class:`EstimateMemory` (peak RSS of ``avbench estimate`` against the record's size, up to 5e7 samples,
400 MB) and :class:`EstimateEndToEnd` (``avbench estimate`` with its defaults on an EuRoC-style CSV,
whole process: 1 h at 100 Hz and 2 h at 400 Hz, 6 axes, with where the time goes;
:mod:`avbench.bench.estimate_e2e`).

``python -m avbench.bench.recordings csv N`` / ``python -m avbench.bench.recordings estimate N`` run one measurement
and print it as JSON.
"""

from __future__ import annotations

import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

__all__ = ["write_csv", "read_peak", "estimate_peak", "COLUMNS", "ReadRecording", "EstimateMemory", "EstimateEndToEnd"]

COLUMNS = "t,gyro_x,gyro_y,gyro_z,acc_x,acc_y,acc_z"


def write_csv(path, n: int, seed: int = 0) -> Path:
    """A 7-column CSV of ``n`` rows at 100 Hz, 9 significant digits, written in blocks."""
    rng = np.random.default_rng(seed)
    with open(path, "w") as fh:
        fh.write(COLUMNS + "\n")
        for a in range(0, n, 1 << 18):
            b = min(n, a + (1 << 18))
            block = np.column_stack([np.arange(a, b) * 0.01, 1e-3 * rng.standard_normal((b - a, 3)),
                                     9.81 + 1e-2 * rng.standard_normal((b - a, 3))])
            np.savetxt(fh, block, delimiter=",", fmt="%.9g")
    return Path(path)


def _vmhwm_mb() -> float:
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def _read_here(path: str, n: int) -> dict:
    import pandas  # noqa: F401  (imported before the baseline RSS is taken)

    from avbench.recordings.readers import read_recording

    base = _vmhwm_mb()
    t0 = time.perf_counter()
    rec = read_recording(path, gyro="gyro_x,gyro_y,gyro_z", accel="acc_x,acc_y,acc_z")
    seconds = time.perf_counter() - t0
    assert rec.n_samples == n
    data_mb = n * 7 * 8 / 2**20
    peak = _vmhwm_mb()
    return {"n": n, "seconds": seconds, "rss_after_imports_mb": base, "peak_rss_mb": peak, "data_mb": data_mb,
            "peak_over_data": (peak - base) / data_mb}


def read_peak(path, n: int) -> dict:
    """Peak memory of reading the CSV at ``path`` (child process)."""
    out = subprocess.run([sys.executable, "-m", "avbench.bench.recordings", "csv-file", str(path), str(n)],
                         capture_output=True, text=True, check=True)
    return json.loads(out.stdout)


def estimate_peak(n: int, methods: str = "nnls_rel,gmwm", seed: int = 0) -> dict:
    """Peak RSS of ``avbench estimate`` on an ``n``-sample .npy (white noise, 100 Hz), child process."""
    with tempfile.TemporaryDirectory(prefix="avbench_est_") as d:
        f = Path(d) / "rec.npy"
        mm = np.lib.format.open_memmap(f, mode="w+", dtype=np.float64, shape=(n,))
        rng = np.random.default_rng(seed)
        for a in range(0, n, 1 << 22):
            b = min(n, a + (1 << 22))
            mm[a:b] = 1e-3 * rng.standard_normal(b - a)
        mm.flush()
        del mm
        code = ("import resource, subprocess, sys, time; t = time.perf_counter(); "
                "r = subprocess.run(sys.argv[1:], capture_output=True, text=True); "
                "print(r.returncode, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss, time.perf_counter() - t); "
                "sys.stderr.write(r.stderr[-2000:])")
        cmd = [sys.executable, "-c", code, sys.executable, "-m", "avbench.cli", "estimate", str(f), "--fs", "100",
               "--units", "rad/s", "--method", methods, "--out", str(Path(d) / "out"), "--no-progress"]
        r = subprocess.run(cmd, capture_output=True, text=True, env={**os.environ, "MPLBACKEND": "Agg"})
        rc, kb, wall = r.stdout.split()
        if int(rc) != 0:
            raise RuntimeError(f"avbench estimate failed: {r.stderr[-500:]}")
    record_mb = n * 8 / 2**20
    peak = int(kb) / 1024
    return {"n": n, "methods": methods, "peak_rss_mb": peak, "record_mb": record_mb, "peak_over_record": peak / record_mb,
            "wall_s": float(wall), "loadavg_after": list(os.getloadavg())}


class ReadRecording:
    """A 7-column CSV read by ``avbench estimate``'s reader against ``pandas.read_csv`` (same file)."""

    params = [[10**5, 10**6]]
    quick_params = [[10**4]]
    param_names = ["n"]
    baselines = {"time_read": ("baseline_read", "pandas.read_csv of the same file (C engine, defaults)")}

    def setup(self, n):
        self.dir = Path(tempfile.mkdtemp(prefix="avbench_csv_"))
        self.path = write_csv(self.dir / "r.csv", n)
        self.n = n

    def teardown(self, n):
        shutil.rmtree(self.dir, ignore_errors=True)

    def time_read(self, n):
        from avbench.recordings.readers import read_recording

        read_recording(self.path, gyro="gyro_x,gyro_y,gyro_z", accel="acc_x,acc_y,acc_z")

    def baseline_read(self, n):
        import pandas as pd

        pd.read_csv(self.path)

    def peakmem_read(self, n):
        return read_peak(self.path, n)


class EstimateEndToEnd:
    """``avbench estimate FILE`` (defaults) from a fresh process, and where its time goes."""

    params = [["1h_100Hz", "2h_400Hz"]]
    quick_params = [["quick_2min_100Hz"]]
    param_names = ["case"]

    def setup(self, case):
        pass

    def track_end_to_end(self, case):
        from avbench.bench.estimate_e2e import measure

        return measure(case)


class EstimateMemory:
    """Peak RSS of ``avbench estimate`` on an n-sample .npy (child process), against the record's size."""

    params = [[10**6, 10**7, 5 * 10**7]]
    quick_params = [[10**5]]
    param_names = ["n"]

    def setup(self, n):
        pass

    def peakmem_estimate(self, n):
        return estimate_peak(n)


if __name__ == "__main__":
    what = sys.argv[1]
    if what == "csv-file":
        print(json.dumps(_read_here(sys.argv[2], int(sys.argv[3]))))
    elif what == "csv":
        n = int(float(sys.argv[2]))
        with tempfile.TemporaryDirectory() as d:
            p = write_csv(Path(d) / "r.csv", n)
            print(json.dumps(read_peak(p, n)))
    elif what == "estimate":
        print(json.dumps(estimate_peak(int(float(sys.argv[2])))))
    else:
        raise SystemExit("usage: python -m avbench.bench.recordings csv|estimate N")
