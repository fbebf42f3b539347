"""``avbench estimate`` end to end on records that are not five-term gyros: a real one, a consumer MEMS one,
one in motion, and where the time goes.

The records (:mod:`avbench.bench.real_records`), 6 axes each, with the command's defaults:

========================  =========================================================================
``adis_1h_100Hz``         the first hour of ADIS16405 run 1 (``$AVBENCH_REAL_DATA``; skipped without it)
``adis_stitched_2h_400Hz``  ADIS16405 runs 1-3 stitched, 2.88e6 samples (8 h at 100 Hz) given to the
                          command as 400 Hz: the sample count of 2 h at 400 Hz (skipped without the data)
``consumer_1h_100Hz``     the simulated consumer IMU, 1 h at 100 Hz, at rest
``consumer_1h_100Hz_motion``  the same samples with rotations added (not static)
``consumer_2h_400Hz``     the consumer IMU, 2 h at 400 Hz, at rest
``quick_consumer_2min``   2 minutes of it (the ``--quick`` smoke case, no target)
========================  =========================================================================

:func:`measure` times one whole process ``avbench estimate FILE`` (after one untimed run on a 2-minute
record of the same kind: numba's disk cache and the OS file cache warm), wall and CPU (the child's user +
system time) and the load average, and reads the breakdown the same process wrote: its imports, reading
(reading, timing and SI), the static check, the fits by method, and within the fits, by timers around
the calls (inclusive seconds; nested calls counted in each enclosing part): GMWM's scale choices
(``selection.scales``), the resonance choice (``selection.resonance``, its refits), the bias-model
evidence (``GMWM._bias_evidence``), the line test (``selection.lines.choose_line``), the fit check
(``allan.fit_check.assess_fit``, its covariance included), and across them the trust-region solves
(``likelihood.solve.solve``; those still running after ``SETTLE_NFEV`` evaluations: ``settle``), the latent model's
AV and Jacobian evaluations (``LatentAV``) and the AV covariance (``allan.covariance.av_covariance``: GMWM's
weights and the fit check's); outside the fits, the figures (``recordings.figure.figure``, their layout) and
their PNG rendering (``recordings.estimate._png``). What is left of the wall time is the outputs (figures,
tables, writing) and the interpreter's start. The timers cost ~1 us per call (~0.1 s per 10^5 model evaluations).

``python -m avbench.bench.real_e2e CASE`` runs one measurement and prints it as JSON;
``python -m avbench.bench.real_e2e --timed OUT.json -- ARGS`` is the timed process itself
(``avbench estimate ARGS`` with the timers, the breakdown written to OUT.json).
"""

from __future__ import annotations

import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

__all__ = ["CASES", "OUTPUT_PARTS", "measure", "available", "EstimateRealRecords"]

#: case -> its record (``kind``: "adis" with ``n`` samples of ``runs``, or "consumer" of ``hours``, with
#: ``motion``), the rate given to the command (``fs``), the target wall seconds (``target_s``) and, for a
#: record in motion, the static case it is compared with (``static_case``)
CASES = {
    "adis_1h_100Hz": {"kind": "adis", "n": 360_000, "runs": (1,), "fs": 100.0, "target_s": 10.0},
    "consumer_1h_100Hz": {"kind": "consumer", "hours": 1.0, "fs": 100.0, "target_s": 10.0},
    "consumer_1h_100Hz_motion": {"kind": "consumer", "hours": 1.0, "fs": 100.0, "motion": True,
                                 "static_case": "consumer_1h_100Hz"},
    "consumer_2h_400Hz": {"kind": "consumer", "hours": 2.0, "fs": 400.0, "target_s": 60.0},
    "adis_stitched_2h_400Hz": {"kind": "adis", "n": 2_880_000, "runs": (1, 2, 3), "fs": 400.0, "target_s": 60.0},
    "quick_consumer_2min": {"kind": "consumer", "hours": 2 / 60, "fs": 100.0},
}

#: (part, module, attribute[, method]): the calls timed inside the process, inclusive
_TIMED = [
    ("reading (read, timing, SI)", "avbench.recordings.load", "load_recording", None),
    ("static check", "avbench.recordings.static", "static_check", None),
    ("fits", "avbench.recordings.fit", "fit_axis", None),
    ("scale choice (selection.scales)", "avbench.estimators.selection.scales", "choose_scales", None),
    ("resonance choice (selection.resonance)", "avbench.estimators.selection.resonance", "choose_resonance", None),
    ("bias-model evidence (GMWM._bias_evidence)", "avbench.estimators.likelihood.gmwm", "GMWM", "_bias_evidence"),
    ("line test (selection.lines.choose_line)", "avbench.estimators.selection.lines", "choose_line", None),
    ("fit check (allan.fit_check.assess_fit)", "avbench.estimators.allan.fit_check", "assess_fit", None),
    ("latent model AV + Jacobian (likelihood LatentAV)", "avbench.estimators.likelihood._gmwm_model", "LatentAV",
     ("__call__", "jacobian")),
    ("AV covariance (allan.covariance.av_covariance)", "avbench.estimators.allan.covariance", "av_covariance", None),
    ("trust-region solves (likelihood.solve.solve)", "avbench.estimators.likelihood.solve", "solve", None),
    ("solves past SETTLE_NFEV evaluations (likelihood.solve.settle)",
     "avbench.estimators.likelihood.solve", "settle", None),
    ("figures (recordings.figure.figure)", "avbench.recordings.figure", "figure", None),
    ("PNG rendering (recordings.estimate._png)", "avbench.recordings.estimate", "_png", None),
]
#: the parts of :data:`_TIMED` outside the fits (the outputs, in the rest of the wall time)
OUTPUT_PARTS = ("figures (recordings.figure.figure)", "PNG rendering (recordings.estimate._png)")


def available(case: str) -> bool:
    """Whether the case can run here (a real-data case needs ``$AVBENCH_REAL_DATA``)."""
    from avbench.bench.real_records import real_data_folder

    return CASES[case]["kind"] != "adis" or real_data_folder() is not None


def _write(case: str, path: Path, short: bool = False) -> tuple[Path, list[str]]:
    """The case's record at ``path`` (``short``: 2 minutes of the same kind) and the command's options."""
    from avbench.bench.real_records import write_adis, write_consumer

    c = CASES[case]
    fs = c["fs"]
    if c["kind"] == "adis":
        n = int(120 * fs) if short else c["n"]
        write_adis(path, n, c["runs"])
        return path, ["--fs", f"{fs:g}", "--units", "deg/s", "--accel-units", "g"]
    hours = 2 / 60 if short else c["hours"]
    write_consumer(path, hours, fs, seed=1 if short else 0, motion=c.get("motion", False) and not short)
    return path, ["--fs", f"{fs:g}", "--units", "rad/s", "--accel-units", "m/s^2"]


def _timed_process(out_json: str, argv: list[str]) -> int:
    """``avbench estimate argv`` with inclusive timers around the calls of :data:`_TIMED`; the seconds per
    part, the per-method fit seconds and the calls counted are written to ``out_json``."""
    import importlib

    t_start = time.perf_counter()
    for mod in {m for _, m, _, _ in _TIMED} | {"avbench.recordings.estimate", "avbench.estimators.robust.gmwm"}:
        importlib.import_module(mod)
    missing = []  # parts whose call is not where the table says (renamed): not timed, and said so
    seconds: dict = {}
    calls: dict = {}
    per_method: dict = {}
    depth: dict = {}

    def timed(part, f):
        def wrapper(*a, **k):
            depth[part] = depth.get(part, 0) + 1
            t0 = time.perf_counter()
            try:
                return f(*a, **k)
            finally:
                depth[part] -= 1
                calls[part] = calls.get(part, 0) + 1
                if not depth[part]:  # a part inside itself is counted once
                    seconds[part] = seconds.get(part, 0.0) + time.perf_counter() - t0
        wrapper.__wrapped__ = f
        return wrapper

    def replace_everywhere(orig, new):
        for mod in list(sys.modules.values()):
            if getattr(mod, "__name__", "").startswith("avbench"):
                for name, value in list(vars(mod).items()):
                    if value is orig:
                        setattr(mod, name, new)

    for part, mod, attr, method in _TIMED:
        owner = getattr(importlib.import_module(mod), attr, None)
        names = () if method is None else (method,) if isinstance(method, str) else method
        if owner is None or any(not hasattr(owner, name) for name in names):
            missing.append(part)
        elif method is None:
            replace_everywhere(owner, timed(part, owner))
        else:
            for name in names:
                setattr(owner, name, timed(part, getattr(owner, name)))
    fit_axis = sys.modules["avbench.recordings.fit"].fit_axis

    def fit_axis_by_method(*a, **k):
        out = fit_axis(*a, **k)
        for name, fit in out.items():
            per_method[name] = per_method.get(name, 0.0) + float(getattr(fit, "seconds", 0.0))
        return out

    replace_everywhere(fit_axis, fit_axis_by_method)
    t_imported = time.perf_counter()
    import runpy

    # the command as ``python -m avbench.cli estimate ...`` runs it (the bench sits below the command: no import)
    sys.argv = ["avbench", "estimate", *argv]
    try:
        runpy.run_module("avbench.cli", run_name="__main__", alter_sys=True)
        rc = 0
    except SystemExit as e:
        rc = e.code if isinstance(e.code, int) else (0 if e.code is None else 1)
    Path(out_json).write_text(json.dumps({"imports_s": t_imported - t_start, "run_s": time.perf_counter() - t_imported,
                                          "parts_s": seconds, "calls": calls, "fits_per_method_s": per_method,
                                          "not_timed": missing}))
    return rc


def _run(path: Path, opts: list[str], out: Path, breakdown: Path) -> tuple[float, float, dict]:
    """(wall s, child CPU s, breakdown) of the timed process on ``path``."""
    cmd = [sys.executable, "-m", "avbench.bench.real_e2e", "--timed", str(breakdown), "--", str(path), *opts,
           "--out", str(out), "--no-progress"]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    r = subprocess.run(cmd, capture_output=True, text=True, env={**os.environ, "MPLBACKEND": "Agg"})
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if r.returncode != 0:
        raise RuntimeError(f"avbench estimate failed: {r.stderr[-800:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu, json.loads(breakdown.read_text())


def measure(case: str) -> dict:
    """The whole-process wall and CPU time of ``avbench estimate`` on the case's record, with the breakdown
    (module docstring)."""
    c = CASES[case]
    with tempfile.TemporaryDirectory(prefix="avbench_real_e2e_") as d:
        d = Path(d)
        warm, warm_opts = _write(case, d / "warm.npz", short=True)
        _run(warm, warm_opts, d / "warm_out", d / "warm.json")
        f, opts = _write(case, d / "rec.npz")
        load_before = list(os.getloadavg())
        wall, cpu, b = _run(f, opts, d / "out", d / "breakdown.json")
        n = c.get("n") or int(round(c["hours"] * 3600 * c["fs"]))
        out = {"case": case, "kind": c["kind"], "n": n, "fs": c["fs"], "hours": n / c["fs"] / 3600,
               "motion": bool(c.get("motion", False)), "target_s": c.get("target_s"),
               "static_case": c.get("static_case"), "wall_s": wall, "cpu_s": cpu, "loadavg_before": load_before,
               "loadavg_after": list(os.getloadavg()), "file_mb": f.stat().st_size / 2**20, **b}
    parts = out["parts_s"]
    known = out["imports_s"] + sum(parts.get(p, 0.0) for p in ("reading (read, timing, SI)", "static check", "fits"))
    out["rest_s"] = wall - known  # interpreter start, the six AVs, figures, tables, writing
    return out


class EstimateRealRecords:
    """``avbench estimate FILE`` (defaults) on real and consumer-grade records, whole process, with the
    breakdown (:mod:`avbench.bench.real_e2e`); a real-data case is skipped without ``$AVBENCH_REAL_DATA``."""

    params = [["adis_1h_100Hz", "consumer_1h_100Hz", "consumer_1h_100Hz_motion", "consumer_2h_400Hz",
               "adis_stitched_2h_400Hz"]]
    quick_params = [["quick_consumer_2min"]]
    param_names = ["case"]

    def setup(self, case):
        if not available(case):
            raise NotImplementedError(f"{case}: $AVBENCH_REAL_DATA is not set (or holds no ADIS16405 runs)")

    def track_end_to_end(self, case):
        return measure(case)


if __name__ == "__main__":
    if len(sys.argv) > 2 and sys.argv[1] == "--timed":
        sys.exit(_timed_process(sys.argv[2], sys.argv[4:] if sys.argv[3] == "--" else sys.argv[3:]))
    if len(sys.argv) != 2 or sys.argv[1] not in CASES:
        raise SystemExit(f"usage: python -m avbench.bench.real_e2e CASE  (one of {', '.join(CASES)})")
    print(json.dumps(measure(sys.argv[1]), indent=1))
