"""Real static recordings: every method on every gyro and accelerometer axis, and the run-to-run
consistency table.

``python -m avbench.studies.real_runs --data DIR --out results/real`` (``DIR``: the folder holding
``adis16405-calgary/`` and ``mtig-cont-imu1/``; default: the environment variable ``AVBENCH_REAL_DATA``)

Reads (only if present; nothing here needs them) the six ADIS16405 runs
``adis16405-calgary/adis_16405_imu{1..6}.npz`` (gyro x, y, z in deg/s and accelerometer x, y, z in g,
100 Hz) and the MTi-G ``mtig-cont-imu1/cont_imu1.npz`` (one gyro axis, units not stated, taken as
rad/s, 100 Hz). The recordings are read in place, never copied, through the recordings pipeline of
``avbench estimate`` (:mod:`avbench.recordings`: reader, timing, SI units through
:mod:`avbench.noise_models.units`, gap-aware fits), so sensor and axis names and units come from the same
code. Writes to ``--out``:

``coefficients.csv``  one row per record x sensor x axis x method x coefficient: value and standard
                      error in the display units of :data:`avbench.noise_models.units.DISPLAY_UNITS` (gyro:
                      the papers' units; accelerometer: m/s/sqrt(h), ug, ...), the coefficient's
                      ``flag`` (its status, :data:`avbench.estimators.results.STATUSES`; the value is
                      the fit's own number whatever the flag), and the fit's ``poor_fit``
                      flag with its statistic, dof, p-value and the reference distribution the
                      p-value comes from (:mod:`avbench.estimators.allan.fit_check`) (5 significant digits);
``consistency.csv`` / ``consistency.md``  per ADIS sensor, axis, method and coefficient: mean over the
                      six runs, run-to-run standard deviation, the method's own median standard
                      error, their ratio, the number of runs with a value, and of poor fits;
``between_runs.csv`` / ``between_runs.md``  per ADIS sensor, axis, method with standard errors and
                      coefficient N, B, K: the random-effects between-run SD with its 95 % interval,
                      over the median SE, and the ``--inflate auto`` factor (:func:`between_runs`);
``adis16405_<sensor>_<axis>.png``  the six runs' Allan deviations with the median ``nnls_rel`` curve;
``mtig_cont_imu1_gyro_x.png``      the MTi-G curve with its ``nnls_rel`` fit.

Same sensor, same conditions: the runs share their true coefficients (to the extent the sensor is
stationary between runs), so the spread of a method's estimates across runs, against the standard
error it claims, is the one test of honesty real data give. ``--methods`` picks the methods,
``--skip-slow`` leaves out the MLE (about 25 s per axis). ``--slices`` runs instead the default
methods of ``avbench estimate`` on the first 30- and 60-minute slices (``--per-run`` for more) of the ADIS gyro axes
(the records robotics users make) and writes ``slices.csv`` (N, B, in range or not, flags) and
``slices.md`` (per method and length: share of slices with N in 1.9-3.0 deg/sqrt(h) and B in
15-80 deg/h, and values outside with no flag). ``--lines`` writes ``lines.csv`` / ``lines.md``: the
strongest spectral line of each axis in 0.3-3 Hz (frequency, amplitude, prominence): the
accelerometers' AV bump. ``--slice-coverage`` writes ``slice_coverage.csv`` / ``.md``: do the intervals of
30-minute slices of every ADIS gyro and accelerometer axis hold the whole run's value (:func:`slice_coverage`)?
``--within-run`` writes ``within_run.csv`` / ``.md``: per ADIS gyro axis, whether the
white-noise level is the same in every 30-minute window of the run (:func:`within_run`).
"""

from __future__ import annotations

import argparse
import math
import os
from pathlib import Path

import numpy as np
import pandas as pd

#: (record, group, file under --data, gyro sample units, accelerometer sample units, rate in Hz):
#: the units and rates the recordings' own READMEs state (the MTi-G's are not stated: rad/s assumed)
RECORDS = [(f"adis_16405_imu{i}", "adis16405", f"adis16405-calgary/adis_16405_imu{i}.npz", "deg/s", "g", 100.0)
           for i in range(1, 7)]
RECORDS += [("mtig_cont_imu1", "mtig_cont_imu1", "mtig-cont-imu1/cont_imu1.npz", "rad/s", None, 100.0)]
METHODS = ["ols", "ols_trimmed", "wls", "wls_edf", "slope_lines", "log_fit", "nnls_rel", "nnls_rel_filtered", "gmwm",
           "gmwm_filtered",
           "gmwm_robust", "gmwm_despiked", "mle"]
SIG = 5  # significant digits of the committed numbers
#: the environment variable that says where the (optional, licensed) recordings are
DATA_ENV = "AVBENCH_REAL_DATA"
_GROUP = {r[0]: r[1] for r in RECORDS}


def _records(data: Path):
    """(record, sensor, axis, samples in SI, Timing) for every axis of every recording under ``data``,
    read by the recordings pipeline (:func:`avbench.recordings.readers.read_recording`,
    :func:`~avbench.recordings.timing.timing_of`, :func:`~avbench.recordings.sensors.to_si`)."""
    from avbench.recordings.readers import read_recording
    from avbench.recordings.sensors import to_si
    from avbench.recordings.timing import timing_of

    for name, _, rel, units, accel_units, fs in RECORDS:
        p = data / rel
        if not p.exists():
            continue
        rec = read_recording(p)
        timing = timing_of(rec.time, fs, rec.n_samples, rec.path)
        for s in to_si(rec, units, accel_units):
            for axis, x in s.axes.items():
                yield name, s.sensor, axis, x, timing


def _round(v, sig: int = SIG):
    """``v`` to ``sig`` significant digits (None, 0 and non-finite values as they are)."""
    if v is None or not np.isfinite(v) or v == 0:
        return v
    return float(f"{v:.{sig}g}")


def fit_all(data: Path, methods) -> pd.DataFrame:
    """Every method on every axis (:func:`avbench.recordings.fit.fit_axis`), one row per coefficient."""
    from avbench.noise_models.units import COEFFICIENTS, DISPLAY_UNITS, from_si
    from avbench.recordings.fit import fit_axis
    from avbench.recordings.report import coefficient_flags

    rows = []
    for rec, sensor, axis, x, timing in _records(data):
        units = DISPLAY_UNITS[sensor]
        for name, fit in fit_axis(x, timing.dt, timing.starts, methods).items():
            check, choice = fit.result.fit_check, fit.result.model_choice
            coefs, se, flags = fit.coefficients(), fit.std_errors(), coefficient_flags(fit)
            for c in COEFFICIENTS:
                s = se.get(c, math.nan)
                rows.append({
                    "record": rec, "sensor": sensor, "axis": axis, "method": name, "coefficient": c,
                    "unit": units[c], "value": _round(from_si(c, coefs[c], units[c], sensor)),
                    "std_err": _round(from_si(c, s, units[c], sensor)) if np.isfinite(s) else math.nan,
                    "flag": flags[c],
                    "poor_fit": bool(check.poor_fit),
                    "fit_stat": _round(check.stat),
                    "fit_dof": 0 if check.dof is None else check.dof,
                    "fit_pvalue": _round(check.pvalue),
                    "fit_reference": check.reference or "",
                    "min_m": choice.get("min_m", math.nan),
                })
            print(f"{rec} {sensor} {axis} {name}: " + (" ".join(
                f"{c}={from_si(c, coefs[c], units[c], sensor):.4g}" for c in COEFFICIENTS)
                + f" poor_fit={check.poor_fit}" if fit.error is None else f"failed ({fit.error})"), flush=True)
    return pd.DataFrame(rows)


#: the short records robotics users make: non-overlapping slices of these lengths (minutes)
SLICE_MINUTES = (30, 60)
#: plausible gyro values on the ADIS16405 (the six full runs agree on N 2.3-2.6 deg/sqrt(h) and B
#: 36-48 deg/h; the datasheet says 3 and 25)
SLICE_N_RANGE, SLICE_B_RANGE = (1.9, 3.0), (15.0, 80.0)


def _adis_slices(data: Path, minutes, first_minute: float, per_run: int, methods, settings=None,
                 sensors=("gyro",)):
    """(record, sensor, axis, minutes, k, samples, {method: MethodFit}) for the methods fitted (as ``avbench
    estimate`` fits, :func:`avbench.recordings.fit.fit_axis`) on slice k of every ADIS axis of the ``sensors``:
    for each length in ``minutes``, ``per_run`` non-overlapping slices of it, the first starting ``first_minute``
    minutes in (as many as the run holds)."""
    from avbench.recordings.fit import fit_axis

    for rec, sensor, axis, x, timing in _records(data):
        if _GROUP[rec] != "adis16405" or sensor not in sensors:
            continue
        first = int(round(first_minute * 60 / timing.dt))
        for mins in minutes:
            n = int(round(mins * 60 / timing.dt))
            for k in range(per_run):
                lo = first + k * n
                if lo + n > x.size:
                    break
                starts = timing.starts[(timing.starts > lo) & (timing.starts < lo + n)] - lo
                yield (rec, sensor, axis, mins, k, n,
                       fit_axis(np.asarray(x[lo:lo + n]), timing.dt, starts, methods, settings))


def slices(data: Path, methods, minutes=SLICE_MINUTES, per_run: int = 1, settings=None) -> pd.DataFrame:
    """The given methods on the first ``per_run`` non-overlapping ``minutes``-long slices of every ADIS
    gyro axis (the first: a user's record starts when the sensor is switched on).

    One row per record x axis x length x slice x method: N (deg/sqrt(h)), B (deg/h), whether each lies
    in :data:`SLICE_N_RANGE` / :data:`SLICE_B_RANGE`, the upper 95 % bound of a value flagged "not
    resolved" (``N_upper``, ``B_upper``: the interval is [0, upper]), the coefficient flags and the poor-fit flag,
    and ``unflagged_outside``: a value outside its range given as an estimate (a status of
    :data:`~avbench.estimators.results.VALUE_STATUSES`) on a fit not flagged poor (what must not happen).
    """
    from avbench.estimators.results import VALUE_STATUSES
    from avbench.noise_models.units import from_si
    from avbench.recordings.report import coefficient_flags

    rows = []
    for rec, _, axis, mins, k, _, fits in _adis_slices(data, minutes, 0.0, per_run, methods, settings):
        for name, fit in fits.items():
            check = fit.result.fit_check
            c, flags = fit.coefficients(), coefficient_flags(fit)
            N = from_si("N", c["N"], "deg/sqrt(h)")
            B = from_si("B", c["B"], "deg/h")
            poor = bool(check.poor_fit) or fit.error is not None
            n_in = bool(SLICE_N_RANGE[0] <= N <= SLICE_N_RANGE[1])
            b_in = bool(SLICE_B_RANGE[0] <= B <= SLICE_B_RANGE[1])
            bound = {k: fit.result.coefficients[k].upper for k in ("N", "B")}
            upper = {k: _round(from_si(k, bound[k], u)) if flags[k] == "not resolved" and bound[k] is not None
                     else math.nan for k, u in (("N", "deg/sqrt(h)"), ("B", "deg/h"))}
            rows.append({"record": rec, "axis": axis, "minutes": mins, "slice": k, "method": name,
                         "N": _round(N), "B": _round(B), "N_in_range": n_in, "B_in_range": b_in,
                         "N_upper": upper["N"], "B_upper": upper["B"],
                         "N_flag": flags["N"], "B_flag": flags["B"], "poor_fit": poor,
                         "fit_pvalue": _round(check.pvalue),
                         "unflagged_outside": bool(((not n_in and flags["N"] in VALUE_STATUSES) or
                                                    (not b_in and flags["B"] in VALUE_STATUSES)) and not poor)})
            print(f"{rec} {axis} {mins} min #{k} {name}: N={N:.3g} B={B:.3g} poor_fit={poor}", flush=True)
    return pd.DataFrame(rows)


#: the real-data test of an interval (``--slice-coverage``): 30-minute slices from the middle of each run,
#: after the first 20 minutes (warm-up left out), four per run
COVERAGE_SLICE = {"minutes": 30, "first_minute": 20, "per_run": 4}
#: the coefficients whose slice intervals are held against the whole run's value
COVERAGE_COEFFICIENTS = ("N", "B", "K")
#: the sensors whose slices the coverage study fits
COVERAGE_SENSORS = ("gyro", "accel")


def slice_coverage(data: Path, methods, whole: pd.DataFrame, minutes=COVERAGE_SLICE["minutes"],
                   first_minute=COVERAGE_SLICE["first_minute"], per_run=COVERAGE_SLICE["per_run"],
                   sensors=COVERAGE_SENSORS) -> pd.DataFrame:
    """Does a short record's interval hold the whole run's value? (the plainest real-data test of an interval)

    Each method on ``per_run`` non-overlapping ``minutes``-long slices of every ADIS axis of the ``sensors``
    (gyros and accelerometers), the first starting ``first_minute`` minutes in; for N, B, K the interval
    ``avbench estimate`` shows
    (:func:`avbench.recordings.report.shown_interval`: the 95 % interval, or [0, upper] where the record
    does not resolve the coefficient) against
    the same method's value on the whole run (``whole``: ``coefficients.csv``, where that value is "ok").
    One row per record x sensor x axis x slice x method x coefficient: ``value``, ``lower``, ``upper``, ``whole``
    (display units of the sensor), ``flag``, ``holds`` (None where either side has no number), the fit's
    ``poor_fit`` and ``sensor`` (the last column: the gyro rows keep the columns they had).

    For a calibrated interval of a stationary sensor the expected share is a little above ``level``: the
    whole run contains the slice, so the difference of the two estimates varies less than the slice's
    own (share ~ P(|Z| < 1.96 / sqrt(1 - minutes / run length)) = 0.97 for 30 of 167 minutes).
    """
    from avbench.noise_models.units import DISPLAY_UNITS, from_si
    from avbench.recordings.report import shown_interval

    ref = whole.set_index(["record", "sensor", "axis", "method", "coefficient"])
    rows = []
    for rec, sensor, axis, mins, k, n, fits in _adis_slices(data, (minutes,), first_minute, per_run, methods,
                                                            sensors=sensors):
        for name, fit in fits.items():
            c = fit.coefficients()
            for coef in COVERAGE_COEFFICIENTS:
                unit = DISPLAY_UNITS[sensor][coef]
                lower, upper = shown_interval(fit.result.coefficients[coef], unit, sensor) or (math.nan, math.nan)
                key = (rec, sensor, axis, name, coef)
                w = float(ref.loc[key, "value"]) if key in ref.index and ref.loc[key, "flag"] == "ok" else math.nan
                holds = bool(lower <= w <= upper) if np.isfinite([lower, upper, w]).all() else None
                rows.append({"record": rec, "axis": axis, "start_min": first_minute + k * minutes,
                             "method": name, "coefficient": coef, "unit": unit,
                             "value": _round(from_si(coef, c[coef], unit, sensor)), "lower": _round(lower),
                             "upper": _round(upper), "whole": _round(w), "flag": fit.result.coefficients[coef].status, "holds": holds,
                             "poor_fit": bool(fit.result.fit_check.poor_fit) or fit.error is not None,
                             "sensor": sensor})
            print(f"{rec} {sensor} {axis} {first_minute + k * minutes} min {name}: "
                  + " ".join(f"{r['coefficient']}={r['value']} [{r['lower']}, {r['upper']}] whole {r['whole']}"
                             for r in rows[-len(COVERAGE_COEFFICIENTS):]), flush=True)
    return pd.DataFrame(rows)


def slice_coverage_summary(df: pd.DataFrame) -> pd.DataFrame:
    """Per method, sensor and coefficient: axis-slices with both numbers, how many intervals hold the whole run's
    value (share, Clopper-Pearson 95 % interval), the median interval's half-width and the median distance of the
    slice's value from the whole run's, both relative to the whole run's value (rows without a ``sensor`` are
    gyro rows)."""
    from avbench.studies.scoring import _clopper_pearson

    df = df.assign(sensor=df["sensor"].fillna("gyro")) if "sensor" in df else df.assign(sensor="gyro")
    out = []
    for (m, sensor, c), g in df.groupby(["method", "sensor", "coefficient"], sort=False):
        g = g[g["holds"].notna()]
        n, k = len(g), int(g["holds"].astype(bool).sum())
        lo, hi = _clopper_pearson(k, n)
        half = ((g["upper"] - g["lower"]) / 2 / g["whole"]).median() if n else math.nan
        dist = ((g["value"] - g["whole"]).abs() / g["whole"]).median() if n else math.nan
        out.append({"method": m, "sensor": sensor, "coefficient": c, "axis_slices": n, "hold": k,
                    "share": _round(k / n if n else math.nan, 3), "share_lo": _round(lo, 3), "share_hi": _round(hi, 3),
                    "not_resolved": int((g["flag"] == "not resolved").sum()),
                    "median_half_width_pct": _round(100 * half, 3), "median_distance_pct": _round(100 * dist, 3)})
    return pd.DataFrame(out)


#: the within-run test: ``window_min``-minute windows of ``batch_min``-minute batches, from ``first_minute`` on
#: (the warm-up left out, as the slice coverage), the AV at ``tau_s`` (in the white-noise region, past the
#: sensor's filter) as the white level's measure
WITHIN_RUN = {"window_min": 30.0, "batch_min": 3.0, "first_minute": 20.0, "tau_s": 0.08}


def within_run(data: Path, window_min=WITHIN_RUN["window_min"], batch_min=WITHIN_RUN["batch_min"],
               first_minute=WITHIN_RUN["first_minute"], tau_s=WITHIN_RUN["tau_s"]) -> pd.DataFrame:
    """Is the white-noise level the same all through a run? (why a slice's interval of N misses the whole run)

    Every ADIS gyro axis from ``first_minute`` on, cut into ``batch_min``-minute batches, grouped into
    consecutive ``window_min``-minute windows (complete ones only); in each batch the overlapping AV at
    ``tau_s``. A one-way analysis of variance of the batches' AVs by window: F = (between-window mean
    square) / (within-window mean square) ~ F(W - 1, W (B - 1)) if the level is the same in every window
    (the batches' AVs are independent to a good approximation: they share no cluster). One row per axis:
    ``windows``, ``n_drift_pct`` (the SD over the windows of N ~ sqrt(AV), relative to its mean),
    ``sampling_pct`` (what the within-window spread alone gives it), ``F``, ``p_value`` and ``trend_r``
    (correlation of the batches' AVs with time).
    """
    from scipy import stats

    from avbench.estimators.allan.variance import allan_variance

    rows = []
    for rec, sensor, axis, x, timing in _records(data):
        if _GROUP[rec] != "adis16405" or sensor != "gyro":
            continue
        x = np.asarray(x, dtype=float)
        dt = timing.dt
        L = int(round(batch_min * 60 / dt))
        per = int(round(window_min / batch_min))
        first = int(round(first_minute * 60 / dt))
        W = (x.size - first) // (L * per)
        if W < 2:
            continue
        tau = [round(tau_s / dt) * dt]
        av = np.array([allan_variance(x[first + k * L:first + (k + 1) * L], dt, taus=tau, overlapping=True).avar[0]
                       for k in range(W * per)]).reshape(W, per)
        means, within = av.mean(axis=1), av.var(axis=1, ddof=1).mean()
        F = per * means.var(ddof=1) / within
        n_level = np.sqrt(means)
        rows.append({"record": rec, "axis": axis, "windows": W,
                     "n_drift_pct": _round(100 * n_level.std(ddof=1) / n_level.mean()),
                     "sampling_pct": _round(100 * 0.5 * math.sqrt(within / per) / means.mean()),
                     "F": _round(F), "p_value": _round(float(stats.f.sf(F, W - 1, W * (per - 1)))),
                     "trend_r": _round(float(np.corrcoef(np.arange(av.size), av.ravel())[0, 1]), 3)})
    return pd.DataFrame(rows)


def spectral_lines(data: Path, band=(0.3, 3.0)) -> pd.DataFrame:
    """The strongest spectral line of every axis in ``band`` (Hz): the accelerometers' AV bump.

    :func:`avbench.estimators.selection.lines.strongest_line` (the line test GMWM's ``lines="auto"``
    uses): Hann periodogram of the whole record, the peak over the median of the neighbouring
    frequencies (``prominence``), the line's amplitude A = sqrt(2 variance) from the periodogram's
    excess there, and the test's ``p_value`` (the evidence that the peak is a line, not broadband noise).
    """
    from avbench.estimators.selection.lines import strongest_line
    from avbench.noise_models.units import DISPLAY_UNITS, from_si

    rows = []
    for rec, sensor, axis, x, timing in _records(data):
        if timing.starts.size:
            continue  # a record with gaps: not one periodogram
        line = strongest_line(x, timing.dt, band, floor=False)
        if line is None:
            continue
        unit = DISPLAY_UNITS[sensor]["B"]
        rows.append({"record": rec, "sensor": sensor, "axis": axis, "f0_hz": _round(line.f0),
                     "amplitude": _round(from_si("B", line.amplitude, unit, sensor)), "unit": unit,
                     "prominence": _round(line.prominence), "p_value": _round(line.p_value)})
    return pd.DataFrame(rows)


def slice_summary(df: pd.DataFrame) -> pd.DataFrame:
    """Per method and slice length: records, share with N and B both in range, share in range or
    flagged "not resolved" (an interval instead of a value), poor fits, values outside unflagged."""
    both = df.N_in_range & df.B_in_range
    answered = (df.N_in_range | (df.N_flag == "not resolved")) & (df.B_in_range | (df.B_flag == "not resolved"))
    g = df.assign(both=both, answered=answered).groupby(["method", "minutes"], sort=False)
    return pd.DataFrame({"records": g.size(), "in_range_pct": (100 * g["both"].mean()).round(1),
                         "in_range_or_not_resolved_pct": (100 * g["answered"].mean()).round(1),
                         "poor_fit": g["poor_fit"].sum(), "unflagged_outside": g["unflagged_outside"].sum()}).reset_index()


def consistency(df: pd.DataFrame) -> pd.DataFrame:
    """Run-to-run spread of each method's estimates on the six ADIS runs (module docstring)."""
    adis = df[df.record.map(_GROUP) == "adis16405"]
    out = []
    for (sensor, axis, method, coef), g in adis.groupby(["sensor", "axis", "method", "coefficient"], sort=False):
        v = g["value"].to_numpy(dtype=float)
        ok = np.isfinite(v)
        if not ok.any():
            continue
        se = np.nanmedian(g["std_err"].to_numpy(dtype=float)) if np.isfinite(g["std_err"]).any() else math.nan
        sd = float(np.std(v[ok], ddof=1)) if ok.sum() > 1 else math.nan
        out.append({"sensor": sensor, "axis": axis, "method": method, "coefficient": coef, "unit": g["unit"].iloc[0],
                    "n_runs": int(ok.sum()), "mean": _round(float(np.mean(v[ok]))), "run_sd": _round(sd),
                    "cv_pct": _round(100 * sd / abs(np.mean(v[ok]))) if np.mean(v[ok]) != 0 else math.nan,
                    "median_se": _round(se), "sd_over_se": _round(sd / se) if se and np.isfinite(se) else math.nan,
                    "poor_fits": int(g.drop_duplicates("record")["poor_fit"].sum())})
    return pd.DataFrame(out)


def between_runs(df: pd.DataFrame) -> pd.DataFrame:
    """Per ADIS sensor, axis, method and coefficient: the between-run spread of the six runs by random
    effects (:func:`avbench.recordings.fit.random_effects`, DerSimonian & Laird 1986, as
    ``avbench estimate --combine``), for methods that give standard errors: the between-run SD tau
    with its 95 % Q-profile interval, the mean, tau over the median within-run SE, and the
    ``--inflate auto`` factor (95 % prediction limit of a new run over the mean)."""
    from avbench.recordings.fit import random_effects

    adis = df[df.record.map(_GROUP) == "adis16405"]
    out = []
    for (sensor, axis, method, coef), g in adis.groupby(["sensor", "axis", "method", "coefficient"], sort=False):
        y, se = g["value"].to_numpy(dtype=float), g["std_err"].to_numpy(dtype=float)
        ok = np.isfinite(y) & np.isfinite(se) & (se > 0)
        if ok.sum() < 3 or coef not in ("N", "B", "K"):
            continue
        r = random_effects(y[ok], se[ok])
        out.append({"sensor": sensor, "axis": axis, "method": method, "coefficient": coef, "unit": g["unit"].iloc[0],
                    "n_runs": r["k"], "mean": _round(r["mean"]), "tau": _round(r["tau"]),
                    "tau_low": _round(r["tau_ci"][0]), "tau_high": _round(r["tau_ci"][1]),
                    "tau_over_se": _round(r["tau"] / float(np.median(se[ok]))),
                    "inflate_auto": _round(max(1.0, r["prediction"][1] / r["mean"])) if r["mean"] > 0 else math.nan})
    return pd.DataFrame(out)


def _markdown(df: pd.DataFrame) -> str:
    """A plain markdown table (no optional dependency)."""
    def cell(v):
        return "" if isinstance(v, float) and not np.isfinite(v) else str(v)

    lines = ["| " + " | ".join(df.columns) + " |", "|" + "---|" * len(df.columns)]
    lines += ["| " + " | ".join(cell(v) for v in row) + " |" for row in df.itertuples(index=False)]
    return "\n".join(lines) + "\n"


def _figures(data: Path, df: pd.DataFrame, out: Path) -> list[str]:
    """One figure per group (ADIS16405, MTi-G), sensor and axis: every run's overlapping ADEV (in the
    display unit of B) with the ``nnls_rel`` model of the runs' median coefficients."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from avbench.estimators.allan.model import model_avar
    from avbench.noise_models.units import COEFFICIENTS, DISPLAY_UNITS, from_si, to_si
    from avbench.recordings.fit import scaled_allan

    curves: dict = {}
    for rec, sensor, axis, x, timing in _records(data):
        av, scale = scaled_allan(x, timing.dt, timing.starts)
        curves.setdefault((_GROUP[rec], sensor, axis), []).append((rec, av.tau, av.adev / scale))
    written = []
    for (group, sensor, axis), runs in curves.items():
        unit = DISPLAY_UNITS[sensor]["B"]  # ADEV shown in the unit of the bias instability
        k = from_si("B", 1.0, unit, sensor)
        fig, ax = plt.subplots(figsize=(7.5, 5.2))
        for i, (rec, tau, adev) in enumerate(sorted(runs, key=lambda r: r[0])):
            ax.loglog(tau, adev * k, "o-", ms=3, lw=0.8, color=f"C{i}", label=rec.replace("adis_16405_", ""))
        tau = np.logspace(-2, 3.5, 60)
        recs = [r[0] for r in runs]
        sub = df[(df.sensor == sensor) & (df.axis == axis) & (df.method == "nnls_rel") & df.record.isin(recs)]
        if len(sub):
            med = sub.groupby("coefficient")["value"].median()
            coefs = {c: to_si(c, float(med[c]), DISPLAY_UNITS[sensor][c], sensor) for c in COEFFICIENTS
                     if c in med and np.isfinite(med[c])}
            ax.loglog(tau, np.sqrt(model_avar(coefs, tau)) * k, "--k", lw=1.2,
                      label="nnls_rel" + (f", median coefficients of the {len(recs)} runs" if len(recs) > 1 else ""))
        ax.set_xlabel("τ (s)")
        ax.set_ylabel(f"Allan deviation ({unit})")
        what = "six static runs of 2.8 h" if len(recs) == 6 else f"{len(recs)} static run(s)"
        ax.set_title(f"{'ADIS16405' if group == 'adis16405' else 'XSens MTi-G'} {sensor} {axis}: {what}")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
        name = f"{group}_{sensor}_{axis}.png"
        fig.savefig(out / name, dpi=100, bbox_inches="tight")
        plt.close(fig)
        written.append(name)
    return written


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", default=os.environ.get(DATA_ENV),
                    help=f"folder holding adis16405-calgary/ and mtig-cont-imu1/ (read in place; default: ${DATA_ENV})")
    ap.add_argument("--out", default="results/real", help="output folder")
    ap.add_argument("--methods", default=",".join(METHODS), help="comma-separated estimator names")
    ap.add_argument("--skip-slow", action="store_true", help="leave out the MLE")
    ap.add_argument("--tables-only", action="store_true",
                    help="do not fit: rebuild the consistency table and figures from OUT/coefficients.csv")
    ap.add_argument("--slices", action="store_true",
                    help="instead: the default methods (or --methods) on 30- and 60-minute slices of the ADIS gyro "
                         "axes; writes OUT/slices.csv and OUT/slices.md")
    ap.add_argument("--per-run", type=int, default=1, help="with --slices: slices of each length per run (default 1)")
    ap.add_argument("--slice-coverage", action="store_true",
                    help="instead: do the default methods' (or --methods) intervals from 30-minute slices of the ADIS "
                         "gyro and accelerometer axes hold the whole run's value (from OUT/coefficients.csv)? writes "
                         "OUT/slice_coverage.csv and OUT/slice_coverage.md")
    ap.add_argument("--sensors", default=",".join(COVERAGE_SENSORS),
                    help="with --slice-coverage: the sensors whose slices are fitted (default: gyro,accel)")
    ap.add_argument("--within-run", action="store_true",
                    help="instead: is the white-noise level the same all through each ADIS gyro run? (30-minute "
                         "windows, analysis of variance; OUT/within_run.csv and OUT/within_run.md)")
    ap.add_argument("--lines", action="store_true",
                    help="instead: the strongest spectral line of each axis in 0.3-3 Hz (OUT/lines.csv)")
    args = ap.parse_args(argv)
    if not args.data:
        raise SystemExit(f"real_runs: give --data DIR (the folder of the recordings) or set {DATA_ENV}")
    data, out = Path(args.data), Path(args.out)
    methods = [m for m in args.methods.split(",") if m and not (args.skip_slow and m == "mle")]
    if not any((data / r[2]).exists() for r in RECORDS):
        raise SystemExit(f"real_runs: no recordings found under {data} "
                         f"(expected {RECORDS[0][2]} ... or {RECORDS[-1][2]})")
    out.mkdir(parents=True, exist_ok=True)
    if args.within_run:
        wr = within_run(data)
        wr.to_csv(out / "within_run.csv", index=False)
        (out / "within_run.md").write_text(_markdown(wr))
        return 0
    if args.lines:
        lines = spectral_lines(data)
        lines.to_csv(out / "lines.csv", index=False)
        (out / "lines.md").write_text(_markdown(lines))
        return 0
    if args.slices:
        from avbench.estimators.base import DEFAULT_METHODS

        chosen = methods if args.methods != ",".join(METHODS) else list(DEFAULT_METHODS)
        sl = slices(data, chosen, per_run=args.per_run)
        sl.to_csv(out / "slices.csv", index=False)
        (out / "slices.md").write_text(_markdown(slice_summary(sl)))
        return 0
    if args.slice_coverage:
        from avbench.estimators.base import DEFAULT_METHODS

        chosen = methods if args.methods != ",".join(METHODS) else list(DEFAULT_METHODS)
        sensors = tuple(v for v in args.sensors.split(",") if v)
        sc = slice_coverage(data, chosen, pd.read_csv(out / "coefficients.csv"), sensors=sensors)
        sc.to_csv(out / "slice_coverage.csv", index=False)
        (out / "slice_coverage.md").write_text(_markdown(slice_coverage_summary(sc)))
        return 0
    if args.tables_only:
        df = pd.read_csv(out / "coefficients.csv")
    else:
        df = fit_all(data, methods)
        df.to_csv(out / "coefficients.csv", index=False)
    cons = consistency(df)
    cons.to_csv(out / "consistency.csv", index=False)
    br = between_runs(df)
    br.to_csv(out / "between_runs.csv", index=False)
    (out / "between_runs.md").write_text(_markdown(br))
    (out / "consistency.md").write_text(_markdown(cons))
    _figures(data, df, out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
