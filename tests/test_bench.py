"""Smoke test of the benchmark suite: the quick run on tiny sizes writes well-formed outputs.

No timing assertions: only that every output exists and has the expected structure.
"""

import argparse
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("allantools")

from avbench.bench import harness, report, startup, suite  # noqa: E402
from avbench.bench.__main__ import add_parser, main  # noqa: E402


def test_quick_run_writes_outputs(tmp_path, monkeypatch):
    # tiny sizes: the smallest quick sizes only
    monkeypatch.setattr(suite.Generation, "quick_params", [["gauss_markov", "flicker"], [10_000]])
    monkeypatch.setattr(suite.AllanOverlapping, "quick_params", [[10_000]])
    monkeypatch.setattr(suite.AllanEngine, "quick_params", [[10_000]])
    monkeypatch.setattr(suite.StreamingMemory, "quick_params", [[20_000, 40_000]])
    monkeypatch.setattr(suite.ReadRecording, "quick_params", [[2_000]])
    monkeypatch.setattr(suite.EstimateMemory, "quick_params", [[20_000]])
    monkeypatch.setattr(startup, "WARM_PROCESSES", 1)  # the first-call measurement's plumbing: one later process
    assert main(["--quick", "--out", str(tmp_path)]) == 0
    for name in ("README.md", "results.json", "results.csv", "scaling.png"):
        assert (tmp_path / name).stat().st_size > 0
    payload = json.loads((tmp_path / "results.json").read_text())
    assert payload["quick"] is True
    assert {"cpu_count", "loadavg_1_5_15", "numpy"} <= set(payload["machine"])
    cases = payload["cases"]
    benches = {c["benchmark"] for c in cases}
    assert {"Generation", "AllanOverlapping", "AllanEngine", "EstimatorScaling", "StreamingMemory", "QuickStartUp",
            "FirstCall"} <= benches
    for c in cases:
        if c["kind"] == "time":
            assert c["median_s"] > 0 and c["repeats"] >= 1
    with_baseline = [c for c in cases if c.get("baseline_median_s") is not None and c["kind"] == "time"]
    assert {c["benchmark"] for c in with_baseline} >= {"Generation", "AllanOverlapping"}
    for c in with_baseline:
        assert np.isclose(c["ratio"], c["baseline_median_s"] / c["median_s"])
    mem = [c for c in cases if c["kind"] == "peakmem" and c["benchmark"] == "StreamingMemory"]
    assert len(mem) == 2 and all(c["peak_rss_mb"] > 0 and c["traced_peak_mb"] > 0 for c in mem)
    est = [c for c in cases if c["benchmark"] == "EstimateMemory"]
    assert len(est) == 1 and est[0]["peak_rss_mb"] > 0 and est[0]["record_mb"] > 0
    read = {c["method"]: c for c in cases if c["benchmark"] == "ReadRecording"}
    assert read["time_read"]["baseline_median_s"] > 0 and read["peakmem_read"]["peak_over_data"] > 0
    readme = (tmp_path / "README.md").read_text()
    assert "## Targets" in readme and "allantools" in readme
    # start-up and first-call rows are in the targets table, measured, with no claim in a quick run
    targets = {t["target"]: t for t in payload["targets"]}
    for key in ("`avbench --help`", "`from avbench import estimators, noise_models`", "a second process pays"):
        row = next(t for name, t in targets.items() if name.startswith(key))
        assert row["met"] is None and row["measured"]
    first = next(c for c in cases if c["benchmark"] == "FirstCall")
    assert first["first_ever_s"] > -1 and first["second_process_s"] > -1 and first["fit_s"] > 0
    # the real-record path, on 2 minutes of the consumer record: the whole process and where its time went
    real = next(c for c in cases if c["benchmark"] == "EstimateRealRecords")
    assert real["param_case"] == "quick_consumer_2min" and real["wall_s"] > 0 and real["cpu_s"] > 0
    assert real["parts_s"]["fits"] > 0 and set(real["fits_per_method_s"]) == {"gmwm_filtered", "gmwm_despiked"}
    assert real["calls"]["latent model AV + Jacobian (likelihood LatentAV)"] > 0
    assert "## First call of each estimator" in readme


def test_quick_run_never_writes_results_bench_unless_asked(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(suite.AllanEngine, "quick_params", [[10_000]])
    assert main(["--quick", "--only", "AllanEngine"]) == 0
    assert not (tmp_path / "results").exists()
    wrote = capsys.readouterr().out.strip().splitlines()[-1]
    folder = wrote.split()[1].rsplit("/README.md", 1)[0]
    assert "avbench-bench-quick-" in folder and (Path(folder) / "results.json").is_file()
    shutil.rmtree(folder)
    # a full run (no --quick) and an explicit --out keep their folders
    from avbench.bench.__main__ import output_folder

    assert output_folder(argparse.Namespace(out=None, quick=False)) == Path("results/bench")
    assert output_folder(argparse.Namespace(out="x", quick=True)) == Path("x")


def test_harness_grid_budget_and_skip():
    calls = []

    class B:
        params = [["a", "b"], [1, 2, 3]]
        param_names = ["kind", "n"]
        repeats = 3
        budget_s = -1.0  # every run is "over budget": larger n are skipped
        baselines = {"time_x": ("base_x", "nothing")}

        def setup(self, kind, n):
            if kind == "b":
                raise NotImplementedError

        def time_x(self, kind, n):
            calls.append((kind, n))

        def base_x(self, kind, n):
            pass

        def track_y(self, kind, n):
            return 2.0

    cases = harness.run_class(B, log=lambda s: None)
    assert calls == [("a", 1)]  # one run, then over budget; kind "b" skipped by setup
    assert [c.method for c in cases] == ["time_x", "track_y", "track_y", "track_y"]
    assert cases[0].result["repeats"] == 1 and "ratio" in cases[0].result
    assert cases[1].result == {"value": 2.0}


def test_add_parser_registers_bench():
    import argparse

    p = argparse.ArgumentParser()
    add_parser(p.add_subparsers())
    args = p.parse_args(["bench", "--quick", "--out", "x"])
    assert args.quick and args.out == "x" and callable(args.func)


def test_loglog_slope():
    n = np.array([1e4, 1e5, 1e6])
    assert suite.loglog_slope(n, 3e-8 * n) == pytest.approx(1.0)


def test_readme_states_each_limit_once_after_the_targets(tmp_path):
    """Rows sharing what limits them point to one numbered note under the table; the targets come
    first, the diary (notes.md) last; --report-only renders README.md and leaves results.json as it is."""
    result = {"median_s": 0.01, "min_s": 0.01, "repeats": 3, "baseline": "allantools", "baseline_median_s": 0.2,
              "ratio": 20.0}
    cases = [harness.Case("Deviations", "time_deviation", {"kind": k, "n": 10**6}, "time", dict(result))
             for k in ("hvar", "ohvar", "mvar")]
    machine = {"when": "now", "cpu_count": 2, "processor": "x86_64", "loadavg_1_5_15": [0.1, 0.1, 0.1],
               "numpy": "2", "numba": "0.6", "numba_threads": 2}
    report.write_outputs(cases, machine, tmp_path, False, 1.0)
    (tmp_path / "notes.md").write_text("## A dated note\n\nwhat was tried\n")
    before = (tmp_path / "results.json").read_bytes()
    assert main(["--report-only", "--out", str(tmp_path)]) == 0
    assert (tmp_path / "results.json").read_bytes() == before
    readme = (tmp_path / "README.md").read_text()
    assert readme.count(report.LIMITS["deviations"]) == 1
    assert readme.count("[1](#what-limits-them)") == 3 and "### What limits them" in readme
    assert "**3 of 3 targets met**" in readme
    assert readme.index("## Targets") < readme.index("## Runs and machine") < readme.index("## Diary")
    assert readme.index("## Diary") < readme.index("### A dated note")
    assert "python -m avbench.bench" in readme and "python -m bench" not in readme


def test_consumer_record_is_what_it_says_and_motion_turns_gravity(tmp_path):
    """The consumer IMU's terms, and the record in motion: the gyro integrates to whole quarter turns and
    the accelerometer keeps |g| (the same noise with and without motion)."""
    import math

    from avbench.bench import real_records

    imu = real_records.consumer_imu(0.0025, hours=0.1)  # 400 Hz: the line and the resonance stay
    assert [type(t).__name__ for t in imu["accel"][2].terms] == [
        "FilteredWhiteNoise", "Sinusoidal", "Resonance", "BiasInstability", "RateRandomWalk", "Quantization"]
    dt, n = 0.01, 40_000
    gyro, accel = np.zeros((n, 3)), np.tile([0.0, 0.0, real_records.GRAVITY], (n, 1))
    real_records.add_motion(gyro, accel, dt, every_s=100.0)
    turns = gyro.sum(axis=0) * dt / (math.pi / 2)
    np.testing.assert_allclose(turns, np.round(turns), atol=1e-9)
    assert turns.sum() == pytest.approx(3.0)  # at 100, 200, 300 s: about x, y, z
    np.testing.assert_allclose(np.linalg.norm(accel, axis=1), real_records.GRAVITY, rtol=1e-12)
    np.testing.assert_allclose(accel[-1], [real_records.GRAVITY, 0.0, 0.0], atol=1e-9)
    a = np.load(real_records.write_consumer(tmp_path / "a.npz", 0.01, 100.0))
    b = np.load(real_records.write_consumer(tmp_path / "b.npz", 0.01, 100.0, motion=True))
    np.testing.assert_array_equal(a["gyro"], b["gyro"])  # 36 s: before the first move
    assert float(a["fs"]) == 100.0


def test_real_data_cases_skip_without_the_data(monkeypatch):
    from avbench.bench import real_e2e, real_records

    monkeypatch.delenv("AVBENCH_REAL_DATA", raising=False)
    assert real_records.real_data_folder() is None
    with pytest.raises(NotImplementedError):
        real_e2e.EstimateRealRecords().setup("adis_1h_100Hz")
    real_e2e.EstimateRealRecords().setup("consumer_1h_100Hz")  # simulated: runs anywhere
    with pytest.raises(FileNotFoundError):
        real_records.write_adis("x.npz", 10)
    cases = harness.run_class(type("Only", (real_e2e.EstimateRealRecords,), {"params": [["adis_1h_100Hz"]]}),
                              log=lambda s: None)
    assert cases == []


def test_real_record_rows_state_the_targets_and_the_motion_ratio():
    """The targets rows of EstimateRealRecords: wall against the target with the breakdown and what limits it,
    a record answered not static against its own target, the corpus's median, and the record in motion fitted
    anyway against the static one of the same length by CPU seconds."""
    import pandas as pd

    from avbench.bench.real_e2e import limited_by

    def row(case, wall, cpu, target=None, static=None, answered=False, ratio=None):
        r = {"benchmark": "EstimateRealRecords", "method": "track_end_to_end", "kind": "track", "param_case": case,
             "n": 360_000, "wall_s": wall, "cpu_s": cpu, "target_s": target, "static_case": static,
             "answered": answered, "ratio_target": ratio,
             "loadavg_before": [1.0, 1, 1], "loadavg_after": [1.5, 1, 1], "imports_s": 1.0, "rest_s": 2.0,
             "parts_s": {"reading (read, timing, SI)": 0.1, "static check": 0.05,
                         "figures (recordings.figure.figure)": 0.8},
             "calls": {"AV covariance (allan.covariance.av_covariance)": 40},
             "fits_per_method_s": {"gmwm_filtered": 3.0, "gmwm_despiked": 2.0} if not answered else {}}
        if not answered:
            r["parts_s"].update({"fits": wall - 3.2, "AV covariance (allan.covariance.av_covariance)": 0.5})
        r["limited_by"] = limited_by(r)
        return r

    df = pd.DataFrame([row("consumer_1h_100Hz", 8.0, 7.0, 10.0),
                       row("consumer_1h_100Hz_motion_fit", 12.0, 12.0, static="consumer_1h_100Hz", ratio=1.5),
                       row("consumer_1h_100Hz_motion", 4.0, 3.5, 3.0, answered=True),
                       row("consumer_10min_100Hz", 5.5, 5.0, 10.0)])
    rows = {r["target"]: r for r in report.targets(df, quick=False)}
    static = next(r for t, r in rows.items() if "consumer MEMS record" in t and "1 h" in t and "<= 10 s" in t)
    assert static["met"] is True and "AV covariance (allan.covariance.av_covariance) 0.5 s (40 calls)" in static["measured"]
    assert "limited by fits (4.8 s, 60 % of the wall time)" in static["measured"]
    # a part the run did not time (here the AVs) is left out, not printed as nan
    assert "reading 0.10 s, static check 0.05 s, fits" in static["measured"] and "nan" not in static["measured"]
    motion = next(r for t, r in rows.items() if t.startswith("a record in motion fitted anyway at most 1.5x"))
    assert motion["met"] is False and motion["measured"].startswith("1.71x the static record's CPU seconds")
    answered = next(r for t, r in rows.items() if "answered not static" in t)
    assert answered["met"] is False and "nothing fitted" in answered["measured"]
    assert answered["limit"] == report.LIMITS["estimate_answered"]
    median = next(r for t, r in rows.items() if "median" in t)
    assert median["met"] is False and median["measured"].startswith("5.5 s wall over 3 records")
    # the outputs' parts are said apart from the fits; the ratio has its own limit
    assert "outputs (figures (recordings.figure.figure) 0.80 s)" in static["measured"]
    assert "figures" not in static["measured"].split("within this process's fits")[1]
    assert motion["limit"] == report.LIMITS["estimate_real_motion"] != static["limit"]


def test_corpus_generators_are_what_they_say(tmp_path):
    """The rounded consumer output sits on its steps (0.01 deg/s, 0.001 g); the flight log moves throughout
    (the static check calls it not static by both its tests)."""
    from avbench.bench import real_records
    from avbench.recordings.load import load_recording
    from avbench.recordings.static import static_check

    r = np.load(real_records.write_rounded(tmp_path / "r.npz", 2 / 60, 100.0))
    for key, step in zip(("gyro", "accel"), real_records.ROUNDING):
        np.testing.assert_allclose(r[key] / step, np.round(r[key] / step), atol=1e-6)
    assert r["accel"][:, 2].mean() == pytest.approx(1.0, abs=0.01) and r["gyro"].std() > 10 * real_records.ROUNDING[0]
    f = real_records.write_flight(tmp_path / "f.npz", 30.0, 200.0)
    rec = load_recording(f, units="rad/s", accel_units="m/s^2")
    assert rec.timing.n_samples == 6000
    check = static_check(rec.sensors, rec.timing.dt)
    assert not check["static"] and any("wander" in t for t in check["reasons"])


def test_the_timed_estimate_runs_with_the_bytecode_cache_a_user_has(monkeypatch):
    """The timed process does not inherit PYTHONDONTWRITEBYTECODE (a user's Python caches bytecode; the warm
    run writes it) and draws on Agg."""
    from avbench.bench.real_e2e import _child_env

    monkeypatch.setenv("PYTHONDONTWRITEBYTECODE", "1")
    env = _child_env()
    assert "PYTHONDONTWRITEBYTECODE" not in env and env["MPLBACKEND"] == "Agg"
