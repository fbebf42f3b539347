"""The filter yaml from short records: 30-minute slices of the six ADIS16405 runs against the full runs.

``python -m avbench.studies.yaml_slices --data DIR --out results/real`` (``DIR``: the folder holding
``adis16405-calgary/``; default: the environment variable ``AVBENCH_REAL_DATA``).

For each run and its first (``--slices K``: first K non-overlapping) 30-minute (``--minutes``) slice(s), the pipeline
of ``avbench estimate --kalibr`` (reader, SI units, gap-aware fits of the yaml's method, the payload, the AV of every
axis, :func:`avbench.recordings.filter_yaml.filter_choices`) gives the yaml's four values; the full run (2.8 h) gives
its own yaml and the method's estimate per axis with its 95 % interval.

* The random walks (``gyroscope_random_walk``, ``accelerometer_random_walk``, :func:`check`): a slice's yaml value
  is never below the full run's largest per-axis estimate by more than the slice's stated uncertainty (zero for a
  bound, which is already the upper end of its interval; the distance to the upper end of the interval for an
  estimate).
* The noise densities (``gyroscope_noise_density``, ``accelerometer_noise_density``,
  :func:`check_noise_density`): white noise is the one term every record of more than a few minutes resolves,
  so a noise density is never written from a bound (on the slices and on the full run), and a slice's is within
  :data:`NOISE_DENSITY_TOLERANCE` of the full run's yaml value.

Writes ``yaml_slices.csv`` (one row per run x slice x key; the full run's own rows have ``slice`` ``"full"``) and
``yaml_slices.md``.
"""

from __future__ import annotations

import argparse
import math
import os
from pathlib import Path

import numpy as np
import pandas as pd

__all__ = ["yaml_rows", "check", "check_noise_density", "main", "RUNS", "MINUTES", "METHOD", "NOISE_DENSITY_TOLERANCE"]

RUNS = [f"adis16405-calgary/adis_16405_imu{i}.npz" for i in range(1, 7)]
MINUTES = 30
METHOD = "gmwm_filtered"  #: the yaml's method under avbench estimate's defaults (the first default method)
_KEYS = {"gyroscope_random_walk": ("gyro", "K"), "accelerometer_random_walk": ("accel", "K"),
         "gyroscope_noise_density": ("gyro", "N"), "accelerometer_noise_density": ("accel", "N")}
#: the random walks' keys (:func:`check`) and the noise densities' (:func:`check_noise_density`)
_RW_KEYS = ("gyroscope_random_walk", "accelerometer_random_walk")
_ND_KEYS = ("gyroscope_noise_density", "accelerometer_noise_density")
#: a slice's noise density lies within this relative distance of the full run's (a filter tuned with it is neither
#: over- nor under-confident by more than the usual factor users inflate with; the white level of these runs
#: moves by a few per cent within a run)
NOISE_DENSITY_TOLERANCE = 0.25


def _results_and_avs(sensors, dt, starts, method):
    from avbench.recordings.fit import fit_axis, scaled_allan

    results = {s.sensor: {a: {m: f.result for m, f in fit_axis(x, dt, starts, [method]).items()}
                          for a, x in s.axes.items()} for s in sensors}
    avs = {s.sensor: {a: scaled_allan(x, dt, starts) for a, x in s.axes.items()} for s in sensors}
    return results, avs


def yaml_rows(data_root: Path, minutes: float = MINUTES, method: str = METHOD, runs=RUNS,
              max_slices: int | None = None, full_rows: bool = False) -> pd.DataFrame:
    """One row per run x slice x yaml key (SI): the slice's yaml value, whether it is a bound and why, its
    stated upper end, the full run's largest per-axis estimate (``full_run_max_si``) and the full run's own yaml
    value (``full_yaml_si``); with ``full_rows`` the full run's own rows (``slice`` "full") first."""
    from avbench.recordings.filter_yaml import filter_choices
    from avbench.recordings.readers import read_recording
    from avbench.recordings.sensors import SensorRecord, to_si

    rows = []
    for rel in runs:
        p = Path(data_root) / rel
        if not p.exists():
            continue
        print(f"{rel}: full run and {max_slices or 'every'} slice(s)", flush=True)
        sensors = to_si(read_recording(p), "deg/s", "g")
        dt = 0.01
        starts = np.zeros(0, dtype=np.int64)
        full, full_avs = _results_and_avs(sensors, dt, starts, method)
        full_max = {}
        for key, (sensor, coef) in _KEYS.items():
            vals = [per[method].coefficients[coef].value for per in full[sensor].values()]
            vals = [v for v in vals if math.isfinite(v)]
            full_max[key] = max(vals) if vals else math.nan
        n = next(iter(sensors[0].axes.values())).size
        full_choices = filter_choices(full, method, "--kalibr", full_avs)
        if full_rows:
            rows += _rows(Path(rel).stem, "full", n * dt / 60, full, full_choices, method, full_max, full_choices)
        w = int(round(minutes * 60 / dt))
        k_slices = n // w if max_slices is None else min(n // w, max_slices)
        for k in range(k_slices):
            part = [SensorRecord(s.sensor, s.unit_in, {a: x[k * w:(k + 1) * w] for a, x in s.axes.items()}, s.names)
                    for s in sensors]
            data, avs = _results_and_avs(part, dt, starts, method)
            choices = filter_choices(data, method, "--kalibr", avs)
            rows += _rows(Path(rel).stem, k, minutes, data, choices, method, full_max, full_choices)
    return pd.DataFrame(rows)


def _rows(run, k, minutes, data, choices, method, full_max, full_choices) -> list[dict]:
    """The rows of one yaml (``choices``: :func:`~avbench.recordings.filter_yaml.filter_choices` of the fits
    ``data``, ``{sensor: {axis: {method: FitResult}}}``) against the full run's (``full_max``, ``full_choices``)."""
    out = []
    for key, (sensor, coef) in _KEYS.items():
        v, axis, why = choices[key]
        upper = v if why else (data[sensor][axis][method].coefficients[coef].upper or v)
        out.append({"run": run, "slice": k, "minutes": minutes, "key": key, "axis": axis,
                    "yaml_si": v, "bound": bool(why), "why": why or "", "stated_upper_si": upper,
                    "full_run_max_si": full_max[key], "full_yaml_si": full_choices[key][0]})
    return out


def check(rows: pd.DataFrame) -> pd.Series:
    """True where the slice's yaml value, plus its stated uncertainty, reaches the full run's value (the random
    walks' check)."""
    return rows["stated_upper_si"] >= rows["full_run_max_si"] * (1 - 1e-12)


def check_noise_density(rows: pd.DataFrame) -> pd.Series:
    """True where a noise density is an estimate, not a bound, and lies within :data:`NOISE_DENSITY_TOLERANCE` of
    the full run's yaml value (the noise densities' check; NaN on other rows).

    >>> rows = pd.DataFrame({"key": ["gyroscope_noise_density"] * 3 + ["gyroscope_random_walk"],
    ...                      "yaml_si": [1.0, 1.3, 1.0, 1.0], "bound": [False, False, True, False],
    ...                      "full_yaml_si": [1.1, 1.0, 1.0, 1.0]})
    >>> check_noise_density(rows).tolist()
    [True, False, False, nan]
    """
    rel = (rows["yaml_si"] / rows["full_yaml_si"] - 1.0).abs()
    ok = ~rows["bound"].astype(bool) & (rel <= NOISE_DENSITY_TOLERANCE)
    return ok.where(rows["key"].isin(_ND_KEYS))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", default=os.environ.get("AVBENCH_REAL_DATA"))
    ap.add_argument("--out", default="results/real")
    ap.add_argument("--minutes", type=float, default=MINUTES)
    ap.add_argument("--slices", type=int, default=1,
                    help="slices per run, from its start (default 1: the first 30 minutes, as a user records)")
    a = ap.parse_args(argv)
    if not a.data:
        raise SystemExit("--data: expected the folder of the real recordings (or AVBENCH_REAL_DATA)")
    rows = yaml_rows(Path(a.data), a.minutes, max_slices=a.slices, full_rows=True)
    rows["holds"] = check(rows).where(~rows["key"].isin(_ND_KEYS), check_noise_density(rows)).astype(bool)
    rows["yaml_over_full"] = rows["yaml_si"] / rows["full_run_max_si"]
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    rows.to_csv(out / "yaml_slices.csv", index=False, float_format="%.5g")
    lines = [f"# The filter yaml from {a.minutes:g}-minute slices of the six ADIS16405 runs ({METHOD})", "",
             "`python -m avbench.studies.yaml_slices --data $AVBENCH_REAL_DATA --out results/real"
             f"{'' if a.minutes == MINUTES else f' --minutes {a.minutes:g}'}"
             f"{'' if a.slices == 1 else f' --slices {a.slices}'}` ({a.slices} slice(s) per run, from its start)", "",
             "| key | slices | bounds | holds (yaml + its uncertainty >= full run) | yaml / full run: min, median, max |",
             "|---|---|---|---|---|"]
    sl = rows[rows["slice"] != "full"]
    for key, g in sl[sl["key"].isin(_RW_KEYS)].groupby("key"):
        r = g["yaml_over_full"]
        lines.append(f"| {key} | {len(g)} | {int(g['bound'].sum())} | {int(g['holds'].sum())} of {len(g)} | "
                     f"{r.min():.3g}, {r.median():.3g}, {r.max():.3g} |")
    lines += ["", "| noise density | records | bounds | holds (an estimate, within "
              f"{100 * NOISE_DENSITY_TOLERANCE:g} % of the full run's) | yaml / full run's yaml: min, median, max |",
              "|---|---|---|---|---|"]
    for (key, full), g in rows[rows["key"].isin(_ND_KEYS)].groupby(["key", rows["slice"] == "full"]):
        r = g["yaml_si"] / g["full_yaml_si"]
        lines.append(f"| {key} ({'full runs' if full else f'{a.minutes:g}-minute slices'}) | {len(g)} | "
                     f"{int(g['bound'].sum())} | {int(g['holds'].sum())} of {len(g)} | "
                     f"{r.min():.3g}, {r.median():.3g}, {r.max():.3g} |")
    (out / "yaml_slices.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
