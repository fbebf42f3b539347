"""``avbench estimate`` end to end on a corpus of records that stand for what users bring, and where the time goes.

The corpus (:data:`CASES`; each record simulated by a generator of :mod:`avbench.bench.real_records`, or
read from the optional real data), 6 axes each, the command's defaults:

================================  ===================================================================
``adis_1h_100Hz``                 the first hour of ADIS16405 run 1 (``$AVBENCH_REAL_DATA``; skipped without it)
``adis_1h_euroc_csv``             the same hour as a EuRoC-style CSV (ns stamps, rad/s, m/s^2, 9 digits)
``adis_stitched_2h_400Hz``        ADIS16405 runs 1-3 stitched, 2.88e6 samples given as 400 Hz (real data; the
                                  runs' bias steps where they join make it not static: fitted anyway)
``consumer_1h_100Hz``             the simulated consumer IMU, 1 h at 100 Hz, at rest
``consumer_53min_rounded``        a consumer module's calibrated output: 53 min at 100 Hz in deg/s and g,
                                  rounded to 0.01 deg/s and 0.001 g, with its spectral line and resonance
``consumer_10min_100Hz``          10 minutes of the consumer IMU at 100 Hz
``consumer_2h_400Hz``             the consumer IMU, 2 h at 400 Hz, at rest
``consumer_1h_100Hz_motion``      the consumer hour with rotations added: answered not static, nothing fitted
``consumer_1h_100Hz_motion_fit``  the same, fitted anyway (``--fit-not-static``), against the static hour
``px4_flight_69s_200Hz``          a PX4-like flight log, 69 s at 200 Hz, moving throughout: answered not static
``quick_consumer_2min``           2 minutes of the consumer IMU (the ``--quick`` smoke case, no target)
================================  ===================================================================

:func:`measure` times one whole process ``avbench estimate FILE`` (after one untimed run on a 2-minute
record of the same kind: numba's disk cache, Python's bytecode cache and the OS file cache warm), wall and
CPU (the child's user + system time, its worker processes included) and the load average, and reads the
breakdown the same process wrote: its imports, reading (reading, timing and SI), the Allan variances, the
static check, the fits (:func:`avbench.recordings.estimate.fit_sensors`, wall: the axes on this process and
its workers), the seconds of each method summed over the axes (wherever they ran), and within this process's share of
the fits, by timers around the calls (inclusive seconds; nested calls counted in each enclosing part):
GMWM's scale choices (``selection.scales``), the resonance choice (``selection.resonance``), the
bias-model evidence (``GMWM._bias_evidence``), the line test (``selection.lines.choose_line``), the fit
check (``allan.fit_check.assess_fit``), the trust-region solves (``likelihood.solve.solve``; those
settled: ``settle``), the latent model's AV and Jacobian evaluations (``LatentAV``) and the AV covariance;
outside the fits, the figures (``recordings.figure.figure``), their PNG rendering
(``recordings.estimate._png``) and the writing (``recordings.plan.OutputPlan.write``). What is left of
the wall time is the interpreter's start and the payload and tables. The timers cost ~1 us per call.
:func:`limited_by` names the largest part of a case's time.

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

__all__ = ["CASES", "OUTPUT_PARTS", "TOP_PARTS", "measure", "available", "limited_by", "EstimateRealRecords"]

#: case -> its record (``kind``: "adis" with ``n`` samples of ``runs`` (``euroc``: as a CSV), "consumer" of
#: ``hours`` (``motion``; ``rounded``: the module's rounded output), or "flight" of ``seconds``), the rate
#: (``fs``), the target wall seconds (``target_s``), the command's extra options (``options``), whether the
#: command answers it not static (``answered``: exit code 3, nothing fitted) and, for a record in motion
#: fitted anyway, the static case it is compared with (``static_case``, at most ``ratio`` its CPU seconds)
CASES = {
    "adis_1h_100Hz": {"kind": "adis", "n": 360_000, "runs": (1,), "fs": 100.0, "target_s": 10.0},
    "adis_1h_euroc_csv": {"kind": "adis", "n": 360_000, "runs": (1,), "fs": 100.0, "euroc": True, "target_s": 10.0},
    "consumer_1h_100Hz": {"kind": "consumer", "hours": 1.0, "fs": 100.0, "target_s": 10.0},
    "consumer_53min_rounded": {"kind": "consumer", "hours": 53 / 60, "fs": 100.0, "rounded": True, "target_s": 10.0},
    "consumer_10min_100Hz": {"kind": "consumer", "hours": 10 / 60, "fs": 100.0, "target_s": 10.0},
    "consumer_1h_100Hz_motion": {"kind": "consumer", "hours": 1.0, "fs": 100.0, "motion": True, "answered": True,
                                 "target_s": 3.0},
    "consumer_1h_100Hz_motion_fit": {"kind": "consumer", "hours": 1.0, "fs": 100.0, "motion": True,
                                     "options": ["--fit-not-static"], "static_case": "consumer_1h_100Hz",
                                     "ratio": 1.5},
    "px4_flight_69s_200Hz": {"kind": "flight", "seconds": 69.0, "fs": 200.0, "answered": True, "target_s": 3.0},
    "consumer_2h_400Hz": {"kind": "consumer", "hours": 2.0, "fs": 400.0, "target_s": 20.0},
    "adis_stitched_2h_400Hz": {"kind": "adis", "n": 2_880_000, "runs": (1, 2, 3), "fs": 400.0, "target_s": 20.0,
                               "options": ["--fit-not-static"]},
    "quick_consumer_2min": {"kind": "consumer", "hours": 2 / 60, "fs": 100.0},
}
#: the corpus whose median is held to :data:`MEDIAN_TARGET_S` (every case with a target)
MEDIAN_TARGET_S = 5.0

#: (part, module, attribute[, method]): the calls timed inside the process, inclusive
_TIMED = [
    ("reading (read, timing, SI)", "avbench.recordings.load", "load_recording", None),
    ("Allan variances (recordings.fit.scaled_allan)", "avbench.recordings.fit", "scaled_allan", None),
    ("static check", "avbench.recordings.static", "static_check", None),
    ("fits", "avbench.recordings.estimate", "fit_sensors", None),
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
    ("writing (recordings.plan.OutputPlan.write)", "avbench.recordings.plan", "OutputPlan", "write"),
]
#: the parts of :data:`_TIMED` outside the fits (the outputs, in the rest of the wall time)
OUTPUT_PARTS = ("figures (recordings.figure.figure)", "PNG rendering (recordings.estimate._png)",
                "writing (recordings.plan.OutputPlan.write)")
#: the parts a case's wall time is split into, in the order of the pipeline (the rest: interpreter start,
#: payload and tables)
TOP_PARTS = ("reading (read, timing, SI)", "Allan variances (recordings.fit.scaled_allan)", "static check", "fits",
             *OUTPUT_PARTS)


def available(case: str) -> bool:
    """Whether the case can run here (a real-data case needs ``$AVBENCH_REAL_DATA``)."""
    from avbench.bench.real_records import real_data_folder

    return CASES[case]["kind"] != "adis" or real_data_folder() is not None


def _write(case: str, path: Path, short: bool = False) -> tuple[Path, list[str]]:
    """The case's record at ``path`` (``short``: 2 minutes of the same kind) and the command's options."""
    from avbench.bench.real_records import write_adis, write_consumer

    from avbench.bench.real_records import write_flight, write_rounded

    c = CASES[case]
    fs = c["fs"]
    extra = list(c.get("options", []))
    if c["kind"] == "adis":
        n = int(120 * fs) if short else c["n"]
        if c.get("euroc"):
            return write_adis(path.with_suffix(".csv"), n, c["runs"], euroc=True), extra
        write_adis(path, n, c["runs"])
        return path, ["--fs", f"{fs:g}", "--units", "deg/s", "--accel-units", "g", *extra]
    if c["kind"] == "flight":
        write_flight(path, 20.0 if short else c["seconds"], fs, seed=1 if short else 0)
        return path, ["--units", "rad/s", "--accel-units", "m/s^2", *extra]
    hours = 2 / 60 if short else c["hours"]
    if c.get("rounded"):
        write_rounded(path, hours, fs, seed=1 if short else 0)
        return path, ["--units", "deg/s", "--accel-units", "g", *extra]
    write_consumer(path, hours, fs, seed=1 if short else 0, motion=c.get("motion", False) and not short)
    return path, ["--fs", f"{fs:g}", "--units", "rad/s", "--accel-units", "m/s^2", *extra]


def _timed_process(out_json: str, argv: list[str]) -> int:
    """``avbench estimate argv`` with inclusive timers around the calls of :data:`_TIMED`; the seconds per
    part, the per-method fit seconds and the calls counted are written to ``out_json``."""
    import importlib

    t_start = time.perf_counter()
    for mod in {m for _, m, _, _ in _TIMED} | {"avbench.recordings.estimate", "avbench.recordings.fit_pool",
                                                "avbench.estimators.robust.gmwm"}:
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
    fit_axes = sys.modules["avbench.recordings.fit_pool"].fit_axes

    def fit_axes_by_method(*a, **k):  # each axis's fits come back here from whichever process fitted them
        out = fit_axes(*a, **k)
        for fits in out:
            for name, fit in fits.items():
                per_method[name] = per_method.get(name, 0.0) + float(getattr(fit, "seconds", 0.0))
        return out

    replace_everywhere(fit_axes, fit_axes_by_method)
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


def _child_env() -> dict:
    """The timed process's environment: this one's, with matplotlib's Agg backend, and Python's bytecode cache
    on as a user's Python has it (``PYTHONDONTWRITEBYTECODE`` dropped: the untimed warm run writes the
    ``.pyc`` files, as it fills numba's disk cache, and the timed run reads them)."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    return {**env, "MPLBACKEND": "Agg"}


def _run(path: Path, opts: list[str], out: Path, breakdown: Path, answered: bool = False) -> tuple[float, float, dict]:
    """(wall s, child CPU s, breakdown) of the timed process on ``path`` (``answered``: the command is
    expected to answer the record not static, exit code 3)."""
    cmd = [sys.executable, "-m", "avbench.bench.real_e2e", "--timed", str(breakdown), "--", str(path), *opts,
           "--out", str(out), "--no-progress"]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    r = subprocess.run(cmd, capture_output=True, text=True, env=_child_env())
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if r.returncode != (3 if answered else 0):
        raise RuntimeError(f"avbench estimate ended with exit code {r.returncode}: {r.stderr[-800:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu, json.loads(breakdown.read_text())


def measure(case: str) -> dict:
    """The whole-process wall and CPU time of ``avbench estimate`` on the case's record, with the breakdown
    (module docstring)."""
    c = CASES[case]
    with tempfile.TemporaryDirectory(prefix="avbench_real_e2e_") as d:
        d = Path(d)
        answered = bool(c.get("answered"))
        warm, warm_opts = _write(case, d / "warm.npz", short=True)
        _run(warm, warm_opts, d / "warm_out", d / "warm.json", answered and c["kind"] != "consumer")
        f, opts = _write(case, d / "rec.npz")
        load_before = list(os.getloadavg())
        wall, cpu, b = _run(f, opts, d / "out", d / "breakdown.json", answered)
        n = c.get("n") or int(round((c["hours"] * 3600 if "hours" in c else c["seconds"]) * c["fs"]))
        out = {"case": case, "kind": c["kind"], "n": n, "fs": c["fs"], "hours": n / c["fs"] / 3600,
               "motion": bool(c.get("motion", False) or c["kind"] == "flight"), "answered": answered,
               "target_s": c.get("target_s"), "static_case": c.get("static_case"), "ratio_target": c.get("ratio"),
               "wall_s": wall, "cpu_s": cpu, "loadavg_before": load_before,
               "loadavg_after": list(os.getloadavg()), "file_mb": f.stat().st_size / 2**20, **b}
    parts = out["parts_s"]
    known = out["imports_s"] + sum(parts.get(p, 0.0) for p in TOP_PARTS)
    out["rest_s"] = wall - known  # interpreter start, the payload and tables
    out["limited_by"] = limited_by(out)
    return out


def limited_by(r: dict) -> str:
    """The largest part of a measured case's wall time (:data:`TOP_PARTS`, the imports, the rest), with
    its share: what limits it."""
    parts = {"imports": r["imports_s"], **{p: r["parts_s"].get(p, 0.0) for p in TOP_PARTS},
             "the rest (interpreter start, payload, tables)": r["rest_s"]}
    name, seconds = max(parts.items(), key=lambda kv: kv[1])
    return f"{name} ({seconds:.1f} s, {100 * seconds / r['wall_s']:.0f} % of the wall time)"


class EstimateRealRecords:
    """``avbench estimate FILE`` (defaults) on real and consumer-grade records, whole process, with the
    breakdown (:mod:`avbench.bench.real_e2e`); a real-data case is skipped without ``$AVBENCH_REAL_DATA``."""

    params = [[c for c in CASES if not c.startswith("quick_")]]
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
