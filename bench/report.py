"""Outputs of a benchmark run: results.json, results.csv, scaling.png and README.md (targets first, diary last)."""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import numpy as np
import pandas as pd

__all__ = ["write_outputs", "targets", "loglog_slope"]


def loglog_slope(n, t) -> float:
    """Least-squares slope of log t against log n (1 = linear cost); NaN with fewer than two positive points.

    >>> round(loglog_slope([1e4, 1e5, 1e6], [2e-4, 2e-3, 2e-2]), 6)
    1.0
    >>> loglog_slope([1e4], [1.0])
    nan
    """
    n, t = np.asarray(n, float), np.asarray(t, float)
    ok = (n > 0) & (t > 0)
    if ok.sum() < 2:
        return math.nan
    return float(np.polyfit(np.log(n[ok]), np.log(t[ok]), 1)[0])

#: what limits each target, today (the report states each once, under the targets table)
LIMITS = {
    "estimate_real": "GMWM's fits, then the outputs. The fits: the model choices of gmwm_filtered and gmwm_despiked "
                     "(the scale choice, the resonance and the bias-model evidence) fit the latent model tens of times "
                     "per axis, each fit several trust-region solves of tens to hundreds of evaluations (a solve still "
                     "running after 300 evaluations creeps toward a bound, where likelihood.solve.settle holds the "
                     "parameter and solves the rest in tens more). An evaluation "
                     "runs compiled where the arithmetic is (the Gauss-Markov series, the filter's, resonance's and "
                     "sinusoid's central-difference gradients, bit for bit the NumPy expressions), so what is left is "
                     "Python around ~15-element arrays: ~20-60 us per evaluation with its Jacobian, and the solver's own "
                     "iteration (an SVD, the trust-region step) of about as much. The AV covariance (second-step "
                     "weights, fit checks) keeps the grid's Haar gains and trigonometric values: a call is the model's "
                     "spectral arithmetic on the grid and one rank-k product. The axes are shared between the command's "
                     "process and worker processes (recordings.fit_pool) where the record is long enough and the "
                     "machine has the cores: each worker first pays its imports and kernel loads (~2-3 CPU-s), so on "
                     "2 cores the fits' wall time falls by less than half. Outside the fits, the two figures and their "
                     "PNGs (~0.4 CPU-s each: no tight-layout pass, no minor ticks) and the imports (~1 s). A wall-time "
                     "target holds only on a quiet machine: the measurement reports CPU seconds beside it. Each row "
                     "names its largest part (limited by). See the breakdown.",
    "estimate_answered": "Imports and the first call of the compiled AV kernels (numba's disk cache), then the two "
                         "figures: a record the static check calls not static is answered before any fit -- read, "
                         "its six AVs, the check, the figures, the AV table and the JSON. See the breakdown.",
    "estimate_real_motion": "The number of solves, not their cost: on the record in motion no cut-off is adequate, so "
                            "the scale choice (selection.scales) fits every cut-off, and the resonance choice "
                            "(selection.resonance) refits with three starts at each cut-off below the one kept: about "
                            "six times the static record's trust-region solves, more of them creeping toward a bound "
                            "(settled: likelihood.solve.settle; or run on to their evaluation limit), about twelve "
                            "times its latent-model evaluations, each costing the same (see the breakdown). Fewer "
                            "solves need the choices to stop refitting where their outcome is decided, which changes "
                            "the fits they list in their reports (the JSON's tried cut-offs) and, where no cut-off is "
                            "adequate, which one they keep.",
    "estimate_e2e": "The fits and the outputs. Within the fits (the default methods on six axes) every fit's check "
                    "builds the AV covariance under the fitted model (allan/covariance.av_covariance: _haar_gain, "
                    "_pair_integrals), the largest profiled share; GMWM's solves evaluate the latent model's exact AV "
                    "and its analytic Jacobian. Then the figures, tables and writing; reading, the six AVs and the "
                    "static check are a small share. See the breakdown.",
    "deviations": "Memory passes: SIMD passes over the phase, blocked over the start index for all taus (ohvar, "
                  "totvar, mvar, with the AV for the edf read from the same slices; mvar from box sums built level by "
                  "level in L1 for octave m <= 256, a chain carried 16 steps per dependent addition beyond); hvar one "
                  "read of the rate in 4096-sample chunks (block sums paired and differenced level by level inside "
                  "each chunk up to m = 128; its sum is the finiteness test); the record's check and cumulative sum "
                  "(~1.4 ms at 1e6, a sequential chain kept bit-identical to np.cumsum); the edf compiled (~0.1 ms) "
                  "but its Python around it cold after the passes (~0.3-0.5 ms). "
                  "Theo1 is (N - m) m / 2 terms per tau and MTOT/HTOT 15 m per window by definition (O(N^2) over "
                  "octaves), and allantools' theo1/mtotdev/htotdev are pure-Python loops, timed on <= 3000 / 1000 "
                  "samples only.",
    "gen_gm": "Bound by NumPy's normal generator (4 draws per sample); the rest is one fused compiled pass per "
    "term (Q difference, GM recursion, RRW running sum) plus three in-place sums.",
    "gen_flicker": "The flicker term's overlap-save FFT filter: per output sample one normal plus "
    "a forward and an inverse real FFT of nfft ~ 1.33-2x the segment (nfft ~ 2-4x the 360 000 taps), and the "
    "(taps - 1)-sample burn-in; cost grows with log(tau_max / dt), not with n.",
    "allan": "Memory bandwidth of the passes over the cumulative sum S (80 MB at 1e7): the blocked kernel "
    "reads each 4096-sample block of S once per tau larger than the block; S itself is built in one fused pass.",
    "stream": "Library code and state, not the stream: numpy 26 MB, numba 56 MB + its LLVM runtime when the first "
    "cached kernel loads ~60 MB, scipy.fft (the flicker filter) ~28 MB; the stream itself (traced) is the chunk buffers "
    "plus the flicker filter's FFT buffers (O(tau_max/dt)), constant in n. The stream does not load pandas (76 MB with "
    "pyarrow, which pandas 3 imports at import time): an online filter builds its result Series when they are read, "
    "so reading coefficients_ at the end loads it (second figure).",
    "mle": "Per likelihood evaluation one compiled Kalman pass over the block means (steady state after a few "
    "thousand steps: a state update per block mean; with a drift the augmented filter, whose diffuse columns "
    "also settle). The gradient is the analytic score (the filter's derivative recursions in the same pass): ~6-9 "
    "likelihood passes' worth for p = 4-5 (the p covariance derivatives cost ~p k^3 per step until they settle, a "
    "few thousand steps), where central differences would take 2p + 1; ~30 iterations; the Hessian is 2p scores. "
    "The diagonal-weight GMWM start (with its analytic Jacobian) and the fit check are a fixed share.",
    "whittle": "One FFT of the record; then Fisher scoring in log-parameters, each step one compiled pass over the "
    "n/2 Fourier frequencies with the terms' closed-form spectra; the ramp's exact variance costs two FFTs of twice "
    "the record per model reported, and with selection there is one fit per candidate term set.",
    "arma_em": "One compiled pass per sample: the Kalman update of the 2-state equivalent-ARMA model and the recursive EM statistics of "
    "Elliott & Krishnamurthy (its finite-dimensional filters); the default fit adds its AV-fit start.",
    "shakf": "One compiled pass (3 states): the recursive AV, the time update and a scalar measurement update per sample.",
    "nekf": "The 33-state augmented covariance, kept bit-identical (nekf feeds committed studies): per sample the "
    "Jacobian product G P (nq x n, in register blocks of 32/16/4 columns, estimators/online/_vec4.py: ~0.25 us of "
    "~1.25 us), a dense rank-one measurement update of the 33 x 33 P (~0.17 us: three memory operations per 4 lanes, "
    "no structure to skip), the NN and its Jacobian (~0.17 us: five tanh and short loops), G P G^T and P H (~0.1 us "
    "each, ordered scalar sums that may not be reassociated); the process noise is added by blocks.",
    "csv": "pandas' C parser (one pass, float64 columns, no strings); the reader adds the sniffing of the first "
    "lines and the checks (blank lines, NaN) on the float columns.",
    "estimate": "The record (memory-mapped, float64, not copied), one cumulative sum of it per AV (n + 1 values) "
    "and the estimators' own work arrays, plus ~300 MB of libraries (numpy, scipy, pandas, numba, matplotlib).",
    "study": "The 4 LS fits of each replicate on lv2015's grid (taus='all', non-overlapping: the AV at every cluster "
    "size, then the normal equations from one compiled pass of power sums over the 72 000 sizes, five more passes in "
    "wls_edf), then fresh-process imports and the report's figures. The poor-fit check's model covariance costs ~1 ms "
    "(per-pair integrals kept per grid and record length, avbench.estimators.allan.covariance). A run at load ~10 "
    "(other work on the 2 cores) measures the machine, not the code.",
    "fit_cost": "The fit check's model covariance is a weighted sum of per-pair integrals of the terms' spectral shapes, "
    "kept per grid and record length (avbench.estimators.allan.covariance), ~1 ms after a study's first record. "
    "The LS family does not build its design: the normal equations come from one compiled pass of power sums "
    "(avbench.estimators.curve_fits._kernels; wls_edf's re-weighting in the same pass) and are solved by Cholesky "
    "after column equilibration (the weighted design's SVD where their condition number exceeds 1e4; the studies' "
    "designs stay below 1e3), estimates within ~2e-10 relative of the SVD's (both within that of an "
    "extended-precision solution). Where a fit on its default grid spends its time: the non-overlapping AV at "
    "~72 000 cluster sizes (~5 ms), the fit check (~1.8 ms, its octave AV included), the contract's standardisation "
    "and pandas results (~3 ms), wls_edf's six passes (~1 ms each). nnls_rel, log_fit and slope_lines refer their "
    "check to a weighted chi^2 whose tail is Imhof's integral, compiled (a numba cfunc for QUADPACK, ~0.5 ms); log_fit "
    "hands the check its derivative by the implicit function theorem instead of 34 trust-region refits (nnls_rel's "
    "and slope_lines' refits are a few ms).",
    "gmwm_cost": "The solves, not the model: the latent model's exact AV comes with its analytic Jacobian (per-latent "
    "unit curves computed once, the Gauss-Markov curve and its d/d ln Tc in one compiled pass), and scipy's "
    "trust-region reflective iteration runs as a NumPy port without scipy's per-call machinery (no "
    "differentiable-function wrappers, svd's per-call checks and workspace query or norm's dispatch; "
    "estimators/likelihood/_trf.py, bit for bit scipy's result); the second step's whitening calls LAPACK's trtrs "
    "directly. The time: ~1 900 model AV and Jacobian evaluations in Python (~0.07 s; ~70 solves: min_m='auto' tries "
    "~10 sets of scales, 6 starts each plus the second step), the trust-region iterations' NumPy and LAPACK calls "
    "(~0.1 s) and the ten second-step weight matrices (a direct sum of the squared model spectrum over 65 536 grid "
    "points each, ~5 ms; the Haar gains are kept between them). A numba port of the iteration (0.20 s) would cost "
    "~16 s of compilation on first use and ~0.3 s in every new process.",
    "help": "The interpreter's own start (timed beside it) plus argparse and the CLI modules: the commands import "
    "numpy, pandas, the simulators and the estimators only when they run.",
    "import": "numpy (~0.15 CPU-s) and numba (~0.3 CPU-s, the simulators' compiled kernels); pandas, scipy.optimize, "
    "statsmodels and each estimator's module are imported on first use (lazy registry).",
    "first_call": "Loading the compiled kernels from numba's disk cache (`cache=True`: `__pycache__` beside the "
    "source, else `~/.cache/numba`, else a per-user temp folder) and importing the estimator's module.",
    "scaling": "The study is CPU-bound on 2 cores, so --jobs 2 takes at least half its CPU time, and --jobs 2 spends "
    "2-3 CPU-s more than --jobs 1 on ~8 CPU-s of work: each worker process pays its interpreter and imports "
    "(~0.65 CPU-s), the figures' imports (~0.33), its numba kernels' cache loads (~0.5), loky's resource tracker and "
    "its own start, which one process pays once. So even perfectly packed --jobs 2 takes ~(8 + 2.5) / 2 = 5.3 s, "
    "1.5x: 1.6x is not reachable on this study on 2 cores with spawned workers. Serial in the parent: its imports "
    "(~0.65 CPU-s), the config (~0.8 CPU-s; no trial fits: the LS fits check their settings without one, and the "
    "fit check's chi^2 tails need only scipy.special), collecting the shards (~0.1) and writing the tables (~0.65); "
    "the workers start while the parent imports, "
    "stay warm for every block, import matplotlib when idle after the last block is queued and draw the six figures "
    "(one task each) while the parent writes the tables; --jobs 1 runs its blocks on one BLAS thread as a worker "
    "does (a one-core baseline), and avbench run stops its idle workers instead of waiting for their exit. Not "
    "used, since they change what a worker guarantees: workers forked after the imports (fork with OpenBLAS's "
    "threads alive; the standard pool cannot kill a stuck worker) and the study's own process as a worker (a block "
    "that crashes its process would end the study instead of being retried). On a machine busy with other work, "
    "Linux's autogroup scheduler gives one login group a fixed share of the cores however many processes it runs, so "
    "the ratio only means something on a quiet machine.",
}


def _frame(cases) -> pd.DataFrame:
    return pd.DataFrame([c.as_row() for c in cases])


def _pick(df, bench, method, **params):
    d = df[(df["benchmark"] == bench) & (df["method"] == method)]
    for k, v in params.items():
        d = d[d[f"param_{k}"] == v] if f"param_{k}" in d else d.iloc[:0]
    return d


def _with_ratio(d: pd.DataFrame) -> pd.DataFrame:
    return d.dropna(subset=["ratio"]) if "ratio" in d else d.iloc[:0]


def targets(df: pd.DataFrame, quick: bool) -> list[dict]:
    """The targets' rows: target, measured figure, met (None: no target, a quick run, or the size not run),
    and what limits it."""
    rows = []
    for comp, key in (("gauss_markov", "gen_gm"), ("flicker", "gen_flicker")):
        d = _pick(df, "Generation", "time_simulate", composite=comp).pipe(_with_ratio) if len(df) else df
        if len(d):
            last = d.sort_values("param_n").iloc[-1]
            rows.append({"target": f"5-term gyro ({comp} B) >= 50 % of raw normal throughput per normal",
                         "measured": f"{100 * last['ratio']:.0f} % at n = {int(last['param_n']):.0e}",
                         "met": None if quick else bool(last["ratio"] >= 0.5),
                         "limit": LIMITS[key]})
    d = _pick(df, "AllanOverlapping", "time_allan_variance").pipe(_with_ratio) if len(df) else df
    if len(d):
        last = d.sort_values("param_n").iloc[-1]
        rows.append({"target": ">= 3x allantools oadev at 1e7 (octave, same values)",
                     "measured": f"{last['ratio']:.1f}x at n = {int(last['param_n']):.0e} "
                                 f"({last['median_s']:.3f} s vs {last['baseline_median_s']:.3f} s)",
                     "met": bool(last["ratio"] >= 3) if int(last["param_n"]) >= 10**7 else None,
                     "limit": LIMITS["allan"]})
    for kind in ("hvar", "ohvar", "mvar", "totvar", "theo1", "mtotvar", "htotvar"):
        d = _pick(df, "Deviations", "time_deviation", kind=kind).pipe(_with_ratio) if len(df) else df
        if len(d):
            last = d.sort_values("param_n").iloc[-1]
            big = int(last["param_n"]) >= 10**6
            rows.append({"target": f">= 10x allantools at 1e6 (octave, same values): {kind}",
                         "measured": f"{last['ratio']:.1f}x at n = {int(last['param_n']):.0e} "
                                     f"({last['median_s']:.3f} s vs {last['baseline_median_s']:.3f} s)",
                         "met": (bool(last["ratio"] >= 10) if big else None),
                         "limit": LIMITS["deviations"]})
    d = _pick(df, "StreamingMemory", "peakmem_stream") if len(df) else df
    if len(d):
        last = d.sort_values("param_n").iloc[-1]
        rows.append({"target": "24 h at 1 kHz streamed (gen + StreamingAllan + SHAKF) <= 250 MB peak",
                     "measured": f"{last['peak_rss_mb']:.0f} MB peak RSS "
                                 f"({last.get('peak_rss_with_readout_mb', math.nan):.0f} MB after reading coefficients_, "
                                 f"a pandas Series; {last['rss_after_imports_mb']:.0f} MB before the "
                                 f"stream; {last['traced_peak_mb']:.0f} MB allocated by it; at the end "
                                 f"{last.get('rss_anon_end_mb', math.nan):.0f} MB private + "
                                 f"{last.get('rss_file_end_mb', math.nan):.0f} MB shared library files) at n = "
                                 f"{int(last['param_n']):.3g}, {last['seconds']:.0f} s",
                     "met": bool(max(last["peak_rss_mb"], last.get("peak_rss_with_readout_mb", 0) or 0) <= 250)
                     if int(last["param_n"]) >= 86_400_000 else None,
                     "limit": LIMITS["stream"]})
    d = _with_ratio(_pick(df, "FitCost", "time_fit")) if len(df) else df
    if len(d):
        ls = d[d["param_estimator"].isin(["ols", "wls", "wls_edf", "ols@octave", "wls@octave", "wls_edf@octave",
                                          "nnls_rel", "log_fit", "slope_lines"])]
        times = ", ".join(f"{r['param_estimator']} {1e3 * r['median_s']:.1f} ms ({1 / r['ratio']:.0f}x)"
                          for _, r in ls.iterrows())
        av_ms = 1e3 * float(ls["baseline_median_s"].median()) if len(ls) else math.nan
        worst = float((1 / ls["ratio"]).max()) if len(ls) else math.nan
        rows.append({"target": "every least-squares fit with its fit check <= 20x the octave AV (4 h, 10 Hz)",
                     "measured": f"octave AV {av_ms:.2f} ms; {times}",
                     "met": None if quick else bool(worst <= 20), "limit": LIMITS["fit_cost"]})
        g = d[d["param_estimator"] == "gmwm"]
        if len(g):
            r = g.iloc[-1]
            rows.append({"target": "gmwm (defaults) <= 0.3 s on 4 h at 10 Hz",
                         "measured": f"{r['median_s']:.2f} s ({1 / r['ratio']:.0f}x the octave AV)",
                         "met": None if quick else bool(r["median_s"] <= 0.3), "limit": LIMITS["gmwm_cost"]})
    rows += _kernel_targets(df, quick)
    d = _pick(df, "LvStudy", "track_wall") if len(df) else df
    if len(d):
        r = d.iloc[-1]
        rows.append({"target": "lv2015 study (3 x 30 replicates, --jobs 2) < 15 s wall",
                     "measured": f"{r['wall_s']:.1f} s wall (load {r['loadavg_after'][0]:.1f} after; imports {r['imports_s']:.1f} s "
                                 f"per process; per replicate: simulate {1e3 * r['replicate_simulate_s']:.0f} ms + 4 fits "
                                 f"{1e3 * r['replicate_fits_s']:.0f} ms; report and figures {r.get('report_s', math.nan):.1f} s)",
                     "met": bool(r["wall_s"] < 15), "limit": LIMITS["study"] + _study_budget(r)})
    d = _with_ratio(_pick(df, "ReadRecording", "time_read")) if len(df) and "ratio" in df else df.iloc[0:0]
    if len(d):
        last = d.sort_values("param_n").iloc[-1]
        mem = _pick(df, "ReadRecording", "peakmem_read", n=last["param_n"])
        extra = f"; peak {mem.iloc[-1]['peak_over_data']:.2f}x the numeric data" if len(mem) else ""
        rows.append({"target": "a 1e6-row x 7-column CSV read in <= 1 s, peak memory <= 3x the numeric data",
                     "measured": f"{last['median_s']:.2f} s at n = {int(last['param_n']):.0e} (pandas.read_csv alone "
                                 f"{last['baseline_median_s']:.2f} s: ratio {last['ratio']:.2f}){extra}",
                     "met": (bool(last["median_s"] <= 1.0 and (not len(mem) or mem.iloc[-1]["peak_over_data"] <= 3))
                             if int(last["param_n"]) >= 10**6 else None),
                     "limit": LIMITS["csv"]})
    d = _pick(df, "EstimateMemory", "peakmem_estimate") if len(df) else df
    if len(d):
        last = d.sort_values("param_n").iloc[-1]
        rows.append({"target": "avbench estimate on 5e7 samples: peak <= ~3x the record + fixed overhead",
                     "measured": f"{last['peak_rss_mb']:.0f} MB peak RSS for a {last['record_mb']:.0f} MB record "
                                 f"({last['peak_over_record']:.2f}x) at n = {int(last['param_n']):.3g}, {last['wall_s']:.0f} s "
                                 f"(load {last['loadavg_after'][0]:.1f})",
                     "met": (bool(last["peak_rss_mb"] <= 3 * last["record_mb"] + 400)
                             if int(last["param_n"]) >= 5 * 10**7 else None),
                     "limit": LIMITS["estimate"]})
    rows += _estimate_targets(df)
    rows += _real_estimate_targets(df)
    rows += _startup_targets(df, quick)
    return rows


#: what each EstimateRealRecords case is, as the targets table names it
REAL_CASE_LABELS = {
    "adis_1h_100Hz": "a real record (ADIS16405 run 1, its first hour), 1 h at 100 Hz",
    "adis_1h_euroc_csv": "the same real hour as a EuRoC CSV (ns stamps)",
    "consumer_53min_rounded": "a consumer module's output (simulated), 53 min at 100 Hz rounded to 0.01 deg/s and "
                              "0.001 g, with a line and a resonance",
    "consumer_10min_100Hz": "a consumer MEMS record (simulated), 10 min at 100 Hz",
    "consumer_1h_100Hz_motion_fit": "the consumer record with rotations, fitted anyway (--fit-not-static)",
    "px4_flight_69s_200Hz": "a PX4-like flight log (simulated), 69 s at 200 Hz, moving throughout",
    "consumer_1h_100Hz": "a consumer MEMS record (simulated: filtered white noise, a line, a resonance, flicker, "
                         "random walk, quantization), 1 h at 100 Hz",
    "consumer_1h_100Hz_motion": "the same consumer record with rotations (not static: answered, nothing fitted)",
    "consumer_2h_400Hz": "a consumer MEMS record (simulated), 2 h at 400 Hz",
    "adis_stitched_2h_400Hz": "a real record (ADIS16405 runs 1-3 stitched, 2.88e6 samples read as 400 Hz; their bias "
                              "steps make it not static: fitted with --fit-not-static)",
}


def _real_breakdown(r) -> str:
    """One case's whole-process figures and where the time went (EstimateRealRecords)."""
    from avbench.bench.real_e2e import OUTPUT_PARTS

    parts = dict(r.get("parts_s") or {})
    calls = dict(r.get("calls") or {})
    per = ", ".join(f"{m} {v:.1f} s" for m, v in (r.get("fits_per_method_s") or {}).items())
    top = ("reading (read, timing, SI)", "Allan variances (recordings.fit.scaled_allan)", "static check", "fits")
    inner = ", ".join(f"{k} {v:.1f} s ({calls.get(k, 0)} calls)" for k, v in parts.items()
                      if k not in (*top, *OUTPUT_PARTS))
    shown = ", ".join(f"{k} {parts[k]:.2f} s" for k in OUTPUT_PARTS if k in parts)
    limit = f"; limited by {r['limited_by']}" if isinstance(r.get("limited_by"), str) else ""
    fits = (f"fits {parts['fits']:.1f} s wall ({per or 'none'})" if "fits" in parts else "nothing fitted")
    within = f"; within this process's fits (inclusive, nested parts counted in each): {inner}" if inner else ""
    # a part an older run did not time is left out (its seconds are then in "the rest")
    early = ", ".join(f"{name} {parts[k]:.2f} s" for name, k in (("reading", "reading (read, timing, SI)"),
                                                                  ("AVs", "Allan variances (recordings.fit.scaled_allan)"),
                                                                  ("static check", "static check")) if k in parts)
    return (f"{r['wall_s']:.1f} s wall, {r['cpu_s']:.1f} CPU-s (load {r['loadavg_before'][0]:.1f} before, "
            f"{r['loadavg_after'][0]:.1f} after; n = {int(r['n']):.3g}){limit}: imports {r['imports_s']:.1f} s, "
            f"{early + ', ' if early else ''}{fits}, outputs ({shown}), the rest (interpreter, payload, "
            f"tables) {r['rest_s']:.1f} s{within}")


def _real_estimate_targets(df: pd.DataFrame) -> list[dict]:
    """avbench estimate on the corpus of records (EstimateRealRecords): each against its target, their median, and
    a record in motion fitted anyway against the static one of the same length (CPU seconds: the wall time of a
    loaded machine measures the machine)."""
    from avbench.bench.real_e2e import MEDIAN_TARGET_S

    d = _pick(df, "EstimateRealRecords", "track_end_to_end") if len(df) else df
    rows = []
    by_case = {r["param_case"]: r for _, r in d.iterrows()} if len(d) else {}
    walls = []
    for case, r in by_case.items():
        label = REAL_CASE_LABELS.get(case, case)
        answered = bool(r.get("answered")) if not pd.isna(r.get("answered", None)) else False
        if r.get("target_s") is not None and not pd.isna(r.get("target_s")):
            walls.append(r["wall_s"])
            what = "answered not static, nothing fitted" if answered else "6 axes"
            rows.append({"target": f"avbench estimate (defaults), {label}, {what}, whole process <= {r['target_s']:g} s",
                         "measured": _real_breakdown(r), "met": bool(r["wall_s"] <= r["target_s"]),
                         "limit": LIMITS["estimate_answered" if answered else "estimate_real"]})
        static = by_case.get(r.get("static_case")) if isinstance(r.get("static_case"), str) else None
        if static is not None:
            ratio, wall_ratio = r["cpu_s"] / static["cpu_s"], r["wall_s"] / static["wall_s"]
            goal = r.get("ratio_target")
            goal = 1.0 if goal is None or pd.isna(goal) else float(goal)
            rows.append({"target": f"a record in motion fitted anyway at most {goal:g}x a static one of the same length "
                                   f"({label} against {REAL_CASE_LABELS.get(r['static_case'], r['static_case'])})",
                         "measured": f"{ratio:.2f}x the static record's CPU seconds ({wall_ratio:.2f}x its wall "
                                     f"time); {_real_breakdown(r)}",
                         "met": bool(ratio <= goal), "limit": LIMITS["estimate_real_motion"]})
    if len(walls) >= 3:
        median = float(np.median(walls))
        rows.append({"target": f"avbench estimate (defaults) on the corpus of records: median whole process <= "
                               f"{MEDIAN_TARGET_S:g} s",
                     "measured": f"{median:.1f} s wall over {len(walls)} records "
                                 f"({', '.join(f'{w:.1f}' for w in sorted(walls))} s)",
                     "met": bool(median <= MEDIAN_TARGET_S), "limit": LIMITS["estimate_real"]})
    return rows


def _estimate_targets(df: pd.DataFrame) -> list[dict]:
    """avbench estimate end to end (EstimateEndToEnd): wall time against the target, and its breakdown."""
    d = _pick(df, "EstimateEndToEnd", "track_end_to_end") if len(df) else df
    rows = []
    for _, r in d.iterrows():
        if r.get("target_s") is None or not isinstance(r.get("fits_per_method_s"), dict):
            continue
        per = ", ".join(f"{m} {v:.1f} s" for m, v in r["fits_per_method_s"].items())
        shares = ", ".join(f"{k} {100 * v:.0f} %" for k, v in r["fits_profile_share"].items())
        rows.append({"target": f"avbench estimate (defaults), {r['hours']:g} h at {r['fs']:g} Hz, 6 axes, whole process "
                               f"<= {r['target_s']:g} s",
                     "measured": f"{r['wall_s']:.1f} s wall (load {r['loadavg_after'][0]:.1f}; EuRoC CSV "
                                 f"{r['file_mb']:.0f} MB): imports {r['imports_s']:.1f} s, reading {r['read_s']:.2f} s, "
                                 f"timing + SI {r['timing_si_s']:.2f} s, static check {r['static_check_s']:.2f} s, six AVs "
                                 f"{r['six_avs_s']:.2f} s, fits {r['fits_s']:.1f} s ({per}), the rest (figures, tables, "
                                 f"writing) {r['rest_s']:.1f} s; within the fits (profiled, nested shares: the fit check holds "
                                 f"its AV covariance): {shares}",
                     "met": bool(r["wall_s"] <= r["target_s"]), "limit": LIMITS["estimate_e2e"]})
    return rows


def _kernel_targets(df: pd.DataFrame, quick: bool) -> list[dict]:
    """The kernel targets: mle, whittle, online filters with defaults, flicker preset, AV kernel."""
    rows = []
    if not len(df):
        return rows
    d = _with_ratio(_pick(df, "MleFit", "time_fit"))
    if len(d):
        r = d.sort_values("param_n").iloc[-1]
        rows.append({"target": "mle (defaults) >= 10x faster than the statsmodels path, 4 h at 100 Hz",
                     "measured": f"{r['ratio']:.1f}x at n = {int(r['param_n']):.3g} ({r['median_s']:.2f} s vs "
                                 f"{r['baseline_median_s']:.2f} s)",
                     "met": None if quick else bool(r["ratio"] >= 10), "limit": LIMITS["mle"]})
    d = _with_ratio(_pick(df, "MleFitDrift", "time_fit"))
    if len(d):
        r = d.sort_values("param_n").iloc[-1]
        rows.append({"target": "mle QN+WN+GM+RW+DR (the studies' model), 2 h ADIS16405_X: against the exact "
                               "initial (diffuse) filter (no target; the studies' share)",
                     "measured": f"{r['ratio']:.1f}x at n = {int(r['param_n']):.3g} ({r['median_s']:.2f} s vs "
                                 f"{r['baseline_median_s']:.2f} s)",
                     "met": None, "limit": LIMITS["mle"]})
    for method, what in (("time_fit", "defaults: BIC selection over QNBKR"), ("time_fit_full", "all five terms")):
        d = _with_ratio(_pick(df, "WhittleFit", method))
        if len(d):
            r = d.sort_values("param_n").iloc[-1]
            rows.append({"target": f"whittle ({what}) fits 4 h at 100 Hz in <= 1 s",
                         "measured": f"{r['median_s']:.2f} s at n = {int(r['param_n']):.3g} "
                                     f"({1 / r['ratio']:.0f}x the time of one FFT of the record, {r['baseline_median_s'] * 1e3:.1f} ms)",
                         "met": bool(r["median_s"] <= 1.0) if int(r["param_n"]) >= 1_440_000 else None,
                         "limit": LIMITS["whittle"]})
    for est, goal in (("shakf", 5e6), ("nekf", 1e6)):
        d = _pick(df, "OnlineDefaults", "time_fit_default", estimator=est)
        if len(d):
            r = d.sort_values("param_n").iloc[-1]
            rate = r["param_n"] / r["median_s"]
            rows.append({"target": f"{est} with default settings >= {goal / 1e6:.0f} M samples/s",
                         "measured": f"{rate / 1e6:.2f} M samples/s at n = {int(r['param_n']):.0e} "
                                     f"({r.get('ratio', math.nan):.1f}x the full per-sample trajectory)",
                         "met": None if quick else bool(rate >= goal), "limit": LIMITS[est]})
    d = df[df["benchmark"].str.contains("OnlineKernels") & (df["kind"] == "track")] if "kind" in df else df.iloc[:0]
    if len(d) and "arma_em_kernel_samples_per_s" in d and d["arma_em_kernel_samples_per_s"].notna().any():
        r = d[d["arma_em_kernel_samples_per_s"].notna()].iloc[-1]
        fit = _pick(df, "EstimatorScaling", "time_fit", estimator="arma_em")
        fit = fit[fit["param_n"] >= 10**6].sort_values("param_n") if len(fit) else fit
        extra = (f"; `fit` with default settings {fit.iloc[-1]['param_n'] / fit.iloc[-1]['median_s'] / 1e6:.2f} M samples/s "
                 f"at n = {int(fit.iloc[-1]['param_n']):.0e}") if len(fit) else ""
        rate = float(r["arma_em_kernel_samples_per_s"])
        rows.append({"target": "arma_em online >= 1 M samples/s",
                     "measured": f"{rate / 1e6:.2f} M samples/s (the online recursion, "
                                 f"{r['arma_em_ratio']:.0f}x its NumPy per-sample reference){extra}",
                     "met": None if quick else bool(rate >= 1e6), "limit": LIMITS["arma_em"]})
    d = _pick(df, "FlickerPreset", "time_simulate")
    if len(d):
        r = d.sort_values("param_n").iloc[-1]
        rows.append({"target": "ADIS16405 preset (flicker B) at 1e6 samples <= 0.3 s",
                     "measured": f"{r['median_s']:.2f} s at n = {int(r['param_n']):.0e}",
                     "met": bool(r["median_s"] <= 0.3) if int(r["param_n"]) >= 10**6 else None,
                     "limit": LIMITS["gen_flicker"]})
    d = _with_ratio(_pick(df, "AllanKernel", "time_allan_variance"))
    if len(d):
        r = d.sort_values("param_n").iloc[-1]
        b = _pick(df, "AllanKernel", "track_bound", n=r["param_n"])
        bound = f"; {b.iloc[-1]['ours_over_bound']:.1f}x the bound of one cumsum + {int(b.iloc[-1]['n_taus'])} reads " \
                f"of S ({b.iloc[-1]['bound_s'] * 1e3:.0f} ms)" if len(b) else ""
        rows.append({"target": "overlapping AV >= 1.5x faster at 1e7 than its unfused preparation (same run)",
                     "measured": f"{r['ratio']:.2f}x at n = {int(r['param_n']):.0e} ({r['median_s'] * 1e3:.0f} ms vs "
                                 f"{r['baseline_median_s'] * 1e3:.0f} ms){bound}",
                     "met": bool(r["ratio"] >= 1.5) if int(r["param_n"]) >= 10**7 else None, "limit": LIMITS["allan"]})
    return rows


def _startup_targets(df: pd.DataFrame, quick: bool) -> list[dict]:
    """Start-up, first call and parallel-study targets."""
    rows = []
    if not len(df):
        return rows
    startup = df[df["benchmark"].isin(["StartUp", "QuickStartUp"])]
    d = startup[startup["method"] == "track_help"]
    if len(d):
        r = d.iloc[-1]
        rows.append({"target": "`avbench --help` and every subcommand's help <= 0.5 s",
                     "measured": f"slowest {r['help_max_s']:.2f} s (`{r['help_worst']}`), median {r['help_median_s']:.2f} s; "
                                 f"the bare interpreter {r['interpreter_s']:.2f} s (same loop)",
                     "met": None if quick else bool(r["help_max_s"] <= 0.5), "limit": LIMITS["help"]})
    d = startup[startup["method"] == "track_import"]
    if len(d):
        r = d.iloc[-1]
        rows.append({"target": "`from avbench import estimators, noise_models` <= 1 CPU-s",
                     "measured": f"{r['import_cpu_s']:.2f} CPU-s ({r['import_wall_s']:.2f} s wall)",
                     "met": None if quick else bool(r["import_cpu_s"] <= 1.0), "limit": LIMITS["import"]})
    d = _pick(df, "FirstCall", "track_first_call")
    if len(d):
        worst = d.loc[d["second_process_s"].idxmax()]
        ever = ", ".join(f"{r['param_estimator']} {r['first_ever_s']:.1f} s" for _, r in d.iterrows())
        rows.append({"target": "a second process pays <= 0.5 s for the first call of any filter (kernels cached on disk)",
                     "measured": f"worst {worst['param_estimator']} {worst['second_process_s']:.2f} s"
                                 + (f" (median of {int(worst['warm_processes'])} later processes)"
                                    if pd.notna(worst.get("warm_processes", math.nan)) else "")
                                 + f"; first-ever compile: {ever}",
                     "met": None if quick else bool(d["second_process_s"].max() <= 0.5), "limit": LIMITS["first_call"]})
    d = _pick(df, "LvStudy", "track_wall")
    if len(d) and "speedup" in d and pd.notna(d.iloc[-1].get("speedup", math.nan)):
        r = d.iloc[-1]
        rows.append({"target": "lv2015 with --jobs 2 >= 1.6x faster than --jobs 1 (quiet machine)",
                     "measured": f"--jobs 1 {r['wall_jobs1_s']:.1f} s, --jobs 2 {r['wall_jobs2_s']:.1f} s: {r['speedup']:.2f}x "
                                 f"(medians of {int(r['rounds'])} alternated runs; load {r['loadavg_after'][0]:.1f} after)",
                     "met": bool(r["speedup"] >= 1.6), "limit": LIMITS["scaling"]})
    return rows


def _first_call_table(df) -> str:
    d = _pick(df, "FirstCall", "track_first_call") if len(df) else df
    if not len(d):
        return ""
    lines = ["| estimator | first-ever compile s (empty cache) | second process: first call s | second process: "
             "import of the estimator's module s | one fit s (20 000 samples) |", "|---|---|---|---|---|"]
    for _, r in d.iterrows():
        lines.append(f"| {r['param_estimator']} | {r['first_ever_s']:.2f} | {r['second_process_s']:.2f} | "
                     f"{r.get('second_process_module_s', math.nan):.2f} | {r['fit_s']:.3f} |")
    return "\n".join(lines)


def _study_budget(r) -> str:
    """The wall time's parts, measured separately: what an otherwise idle 2-core machine would need."""
    try:
        compute = r["replicates"] * (r["replicate_simulate_s"] + r["replicate_fits_s"]) / 2
        parts = r["imports_s"] + r["config_s"] + r["imports_s"] + compute + r["report_s"]
    except (KeyError, TypeError):
        return ""
    return (f" Parts measured separately in this run: parent imports {r['imports_s']:.1f} s + config {r['config_s']:.1f} s + "
            f"worker imports {r['imports_s']:.1f} s (in parallel) + {int(r['replicates'])} replicates x "
            f"{1e3 * (r['replicate_simulate_s'] + r['replicate_fits_s']):.0f} ms / 2 workers = {compute:.1f} s + report "
            f"{r['report_s']:.1f} s = {parts:.1f} s; the rest of the wall time is waiting for a core (load "
            f"average {r['loadavg_after'][0]:.1f} on 2 cores) and loky's process start.")


def _fmt_s(x):
    return "" if x is None or (isinstance(x, float) and math.isnan(x)) else (f"{x:.3g}" if x >= 1e-3 else f"{x:.2e}")


def _time_table(df, bench):
    d = df[(df["benchmark"] == bench) & (df["kind"] == "time")]
    if d.empty:
        return ""
    pcols = [c for c in d.columns if c.startswith("param_") and d[c].notna().any()]
    head = [c[6:] for c in pcols] + ["method", "median s", "min s", "repeats", "baseline", "baseline median s", "ratio"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for _, r in d.iterrows():
        vals = [str(int(r[c])) if c == "param_n" else str(r[c]) for c in pcols]
        vals += [r["method"], _fmt_s(r["median_s"]), _fmt_s(r["min_s"]), str(int(r["repeats"])),
                 str(r.get("baseline", "") if isinstance(r.get("baseline", ""), str) else ""),
                 _fmt_s(r.get("baseline_median_s", math.nan)),
                 "" if pd.isna(r.get("ratio", math.nan)) else f"{r['ratio']:.2f}"]
        lines.append("| " + " | ".join(vals) + " |")
    return "\n".join(lines)


def _slopes(df):
    out = []
    d = df[(df["kind"] == "time") & df.get("param_n", pd.Series(dtype=float)).notna()]
    keys = ["benchmark", "method"] + [c for c in d.columns if c.startswith("param_") and c != "param_n"]
    for key, g in d.groupby([k for k in keys if k in d.columns], dropna=False):
        g = g[g["param_n"] >= 1e5]
        if len(g) >= 2:
            out.append((" / ".join(str(k) for k in key if isinstance(k, str)), loglog_slope(g["param_n"], g["median_s"]),
                        int(g["param_n"].min()), int(g["param_n"].max())))
    return out


def plot(df: pd.DataFrame, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(13, 5.5), gridspec_kw={"width_ratios": [2, 1]})
    d = df[(df["kind"] == "time") & df["param_n"].notna()] if "param_n" in df else df.iloc[:0]
    i = 0
    for key, g in d.groupby(["benchmark", "method"] + [c for c in ("param_composite", "param_estimator") if c in d], dropna=False):
        g = g.sort_values("param_n")
        label = " ".join(str(k) for k in key if isinstance(k, str) and k != "time_fit").replace("time_", "")
        ls = "-" if key[0] in ("Generation", "AllanOverlapping", "AllanEngine") else ":"
        ax.loglog(g["param_n"], g["median_s"], ls, marker="o", ms=3, color=f"C{i % 10}", label=label)
        if "baseline_median_s" in g and g["baseline_median_s"].notna().any():
            gb = g[g["baseline_median_s"].notna()]
            ax.loglog(gb["param_n"], gb["baseline_median_s"], "--", marker="x", color=f"C{i % 10}", alpha=0.6,
                      label=f"baseline: {gb['baseline'].iloc[0]}")
        i += 1
    if len(d):
        n = np.array([d["param_n"].min(), d["param_n"].max()], float)
        ax.loglog(n, 1e-8 * n, "k-", lw=3, alpha=0.15, label="10 ns per sample (slope 1)")
    ax.set_xlabel("record length n (samples)")
    ax.set_ylabel("median wall time (s)")
    ax.set_title("cost against record length (dashed: same-run baselines)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=6, ncol=2)
    m = df[(df["kind"] == "peakmem") & (df["benchmark"] == "StreamingMemory")] if len(df) else df
    if len(m):
        m = m.sort_values("param_n")
        ax2.semilogx(m["param_n"], m["peak_rss_mb"], "o-", label="peak RSS (whole process)")
        ax2.semilogx(m["param_n"], m["rss_after_imports_mb"], "s--", label="RSS before the stream (imports, warm-up)")
        ax2.semilogx(m["param_n"], m["traced_peak_mb"], "^-", label="allocated by the stream (tracemalloc)")
        ax2.axhline(300, color="r", lw=1, alpha=0.5, label="300 MB target")
        ax2.set_ylim(0, max(350, float(m["peak_rss_mb"].max()) * 1.1))
    ax2.set_xlabel("streamed samples n")
    ax2.set_ylabel("MB")
    ax2.set_title("streaming path memory (flat in n)")
    ax2.grid(True, which="both", alpha=0.3)
    if len(m):
        ax2.legend(fontsize=7)
    fig.tight_layout()
    tmp = path.with_name(f".{path.stem}.{os.getpid()}.tmp.png")
    fig.savefig(tmp, dpi=110)
    plt.close(fig)
    os.replace(tmp, path)


def _online_table(df):
    d = df[(df["benchmark"].str.contains("OnlineKernels")) & (df["kind"] == "track")]
    if d.empty:
        return ""
    lines = ["| kernel | compiled kernel (samples/s) | NumPy per-sample reference (samples/s) | ratio |", "|---|---|---|---|"]
    for _, r in d.iterrows():
        for f in ("shakf", "nekf", "arma_em"):
            if pd.notna(r.get(f"{f}_ratio", math.nan)):
                lines.append(f"| {f} | {r[f'{f}_kernel_samples_per_s']:.3g} | {r[f'{f}_reference_samples_per_s']:.3g} | "
                             f"{r[f'{f}_ratio']:.0f} |")
    return "\n".join(lines)


def _memory_table(df):
    d = df[(df["kind"] == "peakmem") & (df["benchmark"] == "StreamingMemory")]
    if d.empty:
        return ""
    lines = ["| n | seconds | samples/s | peak RSS MB | RSS before stream MB | allocated by stream MB |", "|---|---|---|---|---|---|"]
    for _, r in d.sort_values("param_n").iterrows():
        lines.append(f"| {int(r['param_n'])} | {r['seconds']:.1f} | {r['samples_per_s']:.3g} | {r['peak_rss_mb']:.0f} | "
                     f"{r['rss_after_imports_mb']:.0f} | {r['traced_peak_mb']:.1f} |")
    return "\n".join(lines)


def write_outputs(cases, machine: dict, out: Path, quick: bool, seconds: float, notes: str = "", *,
                  json_out: bool = True) -> dict:
    """Write results.json, results.csv, scaling.png and README.md under ``out``; return the JSON payload.

    ``json_out=False`` leaves results.json as it is (``--report-only`` renders from it).
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    df = _frame(cases)
    tg = targets(df, quick)
    payload = {"quick": quick, "seconds": seconds, "machine": machine, "targets": tg,
               "cases": json.loads(df.to_json(orient="records"))}
    if json_out:
        (out / "results.json").write_text(json.dumps(payload, indent=1, default=str))
    df.to_csv(out / "results.csv", index=False)
    plot(df, out / "scaling.png")
    (out / "README.md").write_text(readme(df, tg, machine, quick, seconds, notes))
    return payload


#: the heading under the targets table that holds what limits each target (the rows link to it)
LIMITS_HEADING = "What limits them"


def targets_table(tg: list[dict]) -> list[str]:
    """The targets table, each row's limit a link to a numbered note, then the notes: each text once.

    >>> rows = [{"target": "a", "measured": "1", "met": True, "limit": "L"},
    ...         {"target": "b", "measured": "2", "met": None, "limit": "L"}]
    >>> print("\\n".join(targets_table(rows)))
    | target | measured | met | what limits it |
    |---|---|---|---|
    | a | 1 | yes | [1](#what-limits-them) |
    | b | 2 | n/a | [1](#what-limits-them) |
    <BLANKLINE>
    n/a: no target for this row, a quick run, or the size the target names was not run.
    <BLANKLINE>
    ### What limits them
    <BLANKLINE>
    1. L
    """
    anchor = "#" + LIMITS_HEADING.lower().replace(" ", "-")
    number: dict[str, int] = {}
    lines = ["| target | measured | met | what limits it |", "|---|---|---|---|"]
    for t in tg:
        k = number.setdefault(t["limit"], len(number) + 1)
        met = {True: "yes", False: "**no**", None: "n/a"}[t["met"]]
        lines.append(f"| {t['target']} | {t['measured']} | {met} | [{k}]({anchor}) |")
    lines += ["", "n/a: no target for this row, a quick run, or the size the target names was not run."]
    if number:
        lines += ["", f"### {LIMITS_HEADING}", ""] + [f"{k}. {text}" for text, k in number.items()]
    return lines


def _summary(tg: list[dict], quick: bool) -> str:
    """One sentence: how many targets are met."""
    if quick:
        return "A smoke run on tiny sizes: the figures check the plumbing and make no claims."
    met, missed = sum(t["met"] is True for t in tg), sum(t["met"] is False for t in tg)
    return (f"**{met} of {met + missed} targets met** in the last measurement of each ({missed} not met: **no** in "
            f"the table; {len(tg) - met - missed} rows without a verdict: n/a).")


def _runs(machine: dict, quick: bool, seconds: float) -> str:
    """Where and when the figures were measured."""
    text = (f"`python -m avbench.bench{' --quick' if quick else ''}` (last run {machine['when']}): "
            f"{machine['cpu_count']} cores ({machine['processor']}), load average {machine['loadavg_1_5_15']} at the "
            f"end (other work was running: figures are medians of interleaved repeats, and ratios compare runs made "
            f"in the same loop). numpy {machine['numpy']}, numba {machine['numba']} ({machine['numba_threads']} "
            f"threads), allantools {machine.get('allantools', '-')}." + ("" if machine.get("runs") else f" Total {seconds:.0f} s."))
    if machine.get("runs") or machine.get("earlier_run"):
        from avbench.bench.harness import run_history

        runs = run_history({"machine": machine})
        text += " The figures come from these runs (later ones replace the benchmarks they re-ran): " + "; ".join(
            f"{r['when']} ({', '.join(r['benchmarks'])}; load average {r['loadavg_1_5_15']} at its end"
            + (f"; {r['note']}" if r.get("note") else "") + ")" for r in runs) + "."
    return text


def _demote(md: str) -> str:
    """The Markdown with every heading one level lower (outside code fences)."""
    out, fenced = [], False
    for line in md.splitlines():
        if line.startswith("```"):
            fenced = not fenced
        out.append("#" + line if not fenced and line.startswith("#") else line)
    return "\n".join(out)


def readme(df: pd.DataFrame, tg: list[dict], machine: dict, quick: bool, seconds: float, notes: str = "") -> str:
    """README.md: the targets first (measured against each, what limits it), then the runs, the tables,
    and last the diary (``notes``: ``notes.md`` of the output folder, what was measured, tried and changed)."""
    md = [f"# avbench performance ({'quick smoke run: tiny sizes, no claims' if quick else 'full run'})", "",
          _summary(tg, quick), "", "## Targets", ""]
    md += targets_table(tg)
    md += ["", "## Runs and machine", "", _runs(machine, quick, seconds), "",
           "![cost against record length](scaling.png)", ""]
    for bench, title in (("Generation", "Generation: composite gyro vs raw normals (ratio = baseline / ours; >= 0.5 is the target)"),
                         ("AllanOverlapping", "Overlapping AV, octave taus, vs allantools oadev (ratio = speed-up)"),
                         ("Deviations", "Deviation family, octave taus, vs allantools (ratio = speed-up)"),
                         ("AllanEngine", "Non-overlapping and streaming AV"),
                         ("EstimatorScaling", "Estimators: fit time against n (ADIS16405_Y-like, 100 Hz, terms NBK)")):
        t = _time_table(df, bench)
        if t:
            md += [f"## {title}", "", t, ""]
    sl = _slopes(df)
    if sl:
        md += ["## Log-log slopes of cost against n (n >= 1e5; 1 = linear)", "", "| benchmark | slope | n range |", "|---|---|---|"]
        md += [f"| {k} | {s:.2f} | {a:.0e} .. {b:.0e} |" for k, s, a, b in sl] + [""]
    t = _online_table(df)
    if t:
        md += ["## Online filter kernels vs their NumPy per-sample references", "", t, ""]
    t = _memory_table(df)
    if t:
        md += ["## Streaming path memory (child process per n)", "", t, ""]
    t = _first_call_table(df)
    if t:
        md += ["## First call of each estimator (fresh processes; first fit minus a second fit of the same record)", "",
               "The first-ever call compiles the kernels and writes numba's disk cache; every later process (and every "
               "study worker) loads them from there.", "", t, ""]
    diary = [notes.strip()] if notes and notes.strip() else []
    if diary:
        md += ["## Diary", "", "What was measured, tried and changed, dated (the figures above are the current ones).", ""]
        md += ["\n\n".join(_demote(text) for text in diary), ""]
    return "\n".join(md) + "\n"
