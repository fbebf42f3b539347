"""Real static recordings: every method on every gyro axis, and the run-to-run consistency table.

``python -m studies.real_runs --data ../shared/data/real --out results/real``

Reads (only if present; nothing here needs them) the six ADIS16405 runs
``adis16405-calgary/adis_16405_imu{1..6}.npz`` (gyro columns 0-2 in deg/s, 100 Hz) and the MTi-G
``mtig-cont-imu1/cont_imu1.npz`` (one axis, taken as rad/s, 100 Hz). The recordings are read in
place, never copied. Writes to ``--out``:

``coefficients.csv``  one row per record x axis x method x coefficient: value and standard error
                      in the papers' units, ``nonphysical``, and the fit's ``poor_fit`` flag with
                      its statistic, dof and p-value (5 significant digits);
``consistency.csv`` / ``consistency.md``  per ADIS axis, method and coefficient: mean over the six
                      runs, run-to-run standard deviation, the method's own median standard error,
                      their ratio, the number of runs with a value, and of poor fits;
``adis16405_<axis>.png``  the six runs' Allan deviations with each default method's fitted curves;
``mtig_cont_imu1.png``    the MTi-G curve (classical and robust AV) with the fits.

Same sensor, same conditions: the runs share their true coefficients (to the extent the sensor is
stationary between runs), so the spread of a method's estimates across runs, against the standard
error it claims, is the one test of honesty real data give. ``--methods`` picks the methods,
``--skip-slow`` leaves out the MLE (about 25 s per axis).
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np
import pandas as pd

ADIS = [f"adis16405-calgary/adis_16405_imu{i}.npz" for i in range(1, 7)]
MTIG = "mtig-cont-imu1/cont_imu1.npz"
METHODS = ["ols", "ols_trimmed", "wls", "wls_edf", "slope_lines", "log_fit", "nnls_rel", "gmwm", "gmwm_robust",
           "gmwm_despiked", "mle"]
DT = 0.01
SIG = 5  # significant digits of the committed numbers


def _records(data: Path):
    """(record, axis, rate in rad/s) for every recording found under ``data``."""
    for rel in ADIS:
        p = data / rel
        if p.exists():
            x = np.load(p)["data"]
            for k, axis in enumerate("XYZ"):
                yield p.stem, axis, np.deg2rad(x[:, k])
    p = data / MTIG
    if p.exists():
        yield "mtig_cont_imu1", "X", np.asarray(np.load(p)["data"], dtype=float).ravel()


def _round(v):
    if v is None or not np.isfinite(v) or v == 0:
        return v
    return float(f"{v:.{SIG}g}")


def fit_all(data: Path, methods) -> pd.DataFrame:
    import estimators
    from noise_models.units import COEFFICIENTS, PAPER_UNITS, from_si

    rows = []
    for rec, axis, rate in _records(data):
        for name in methods:
            est = estimators.get(name).fit(rate, DT)
            d = est.diagnostics_
            se = d.get("std_err")
            for c in COEFFICIENTS:
                v = est.coefficients_[c]
                s = se.get(c, math.nan) if isinstance(se, pd.Series) else math.nan
                rows.append({
                    "record": rec, "axis": axis, "method": name, "coefficient": c, "unit": PAPER_UNITS[c],
                    "value": _round(from_si(c, v, PAPER_UNITS[c])),
                    "std_err": _round(from_si(c, s, PAPER_UNITS[c])) if np.isfinite(s) else math.nan,
                    "nonphysical": bool(est.nonphysical_[c]),
                    "poor_fit": bool(d.get("poor_fit", False)),
                    "fit_stat": _round(d.get("fit_stat", math.nan)),
                    "fit_dof": d.get("fit_dof", 0),
                    "fit_pvalue": _round(d.get("fit_pvalue", math.nan)),
                    "min_m": d.get("min_m", math.nan),
                })
            print(f"{rec} {axis} {name}: " + " ".join(
                f"{c}={from_si(c, est.coefficients_[c], PAPER_UNITS[c]):.4g}" for c in COEFFICIENTS)
                + f" poor_fit={d.get('poor_fit')}", flush=True)
    return pd.DataFrame(rows)


def consistency(df: pd.DataFrame) -> pd.DataFrame:
    """Run-to-run spread of each method's estimates on the six ADIS runs (module docstring)."""
    adis = df[df.record.str.startswith("adis")]
    out = []
    for (axis, method, coef), g in adis.groupby(["axis", "method", "coefficient"], sort=False):
        v = g["value"].to_numpy(dtype=float)
        ok = np.isfinite(v)
        if not ok.any():
            continue
        se = np.nanmedian(g["std_err"].to_numpy(dtype=float)) if np.isfinite(g["std_err"]).any() else math.nan
        sd = float(np.std(v[ok], ddof=1)) if ok.sum() > 1 else math.nan
        out.append({"axis": axis, "method": method, "coefficient": coef, "unit": g["unit"].iloc[0],
                    "n_runs": int(ok.sum()), "mean": _round(float(np.mean(v[ok]))), "run_sd": _round(sd),
                    "cv_pct": _round(100 * sd / abs(np.mean(v[ok]))) if np.mean(v[ok]) != 0 else math.nan,
                    "median_se": _round(se), "sd_over_se": _round(sd / se) if se and np.isfinite(se) else math.nan,
                    "poor_fits": int(g.drop_duplicates("record")["poor_fit"].sum())})
    return pd.DataFrame(out)


def _markdown(df: pd.DataFrame) -> str:
    """A plain markdown table (no optional dependency)."""
    def cell(v):
        return "" if isinstance(v, float) and not np.isfinite(v) else str(v)

    lines = ["| " + " | ".join(df.columns) + " |", "|" + "---|" * len(df.columns)]
    lines += ["| " + " | ".join(cell(v) for v in row) + " |" for row in df.itertuples(index=False)]
    return "\n".join(lines) + "\n"


def _figures(data: Path, df: pd.DataFrame, out: Path, methods) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from estimators.allan import allan_variance
    from estimators.av_model import model_avar
    from noise_models.units import COEFFICIENTS, PAPER_UNITS, as_si

    k = 180 / math.pi * 3600  # rad/s -> deg/h
    curves: dict = {}
    for rec, axis, rate in _records(data):
        curves[(rec, axis)] = allan_variance(rate, DT, "octave", overlapping=True)
    for axis in "XYZ":
        keys = [key for key in curves if key[0].startswith("adis") and key[1] == axis]
        if not keys:
            continue
        fig, ax = plt.subplots(figsize=(7.5, 5.2))
        for i, key in enumerate(sorted(keys)):
            av = curves[key]
            ax.loglog(av.tau, av.adev * k, "o-", ms=3, lw=0.8, color=f"C{i}", label=key[0].replace("adis_16405_", ""))
        tau = np.logspace(-2, 3.5, 60)
        sub = df[(df.axis == axis) & (df.method == "nnls_rel") & df.record.str.startswith("adis")]
        if len(sub):
            med = sub.groupby("coefficient")["value"].median()
            coefs = {c: as_si(c, [float(med[c]), PAPER_UNITS[c]]) for c in COEFFICIENTS
                     if c in med and np.isfinite(med[c])}
            ax.loglog(tau, np.sqrt(model_avar(coefs, tau)) * k, "--k", lw=1.2,
                      label="nnls_rel, median coefficients of the six runs")
        ax.set_xlabel("τ (s)")
        ax.set_ylabel("Allan deviation (°/h)")
        ax.set_title(f"ADIS16405 gyro {axis}: six static runs of 2.8 h")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
        fig.savefig(out / f"adis16405_{axis}.png", dpi=100, bbox_inches="tight")
        plt.close(fig)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", default="../shared/data/real", help="folder holding the recordings (read in place)")
    ap.add_argument("--out", default="results/real", help="output folder")
    ap.add_argument("--methods", default=",".join(METHODS), help="comma-separated estimator names")
    ap.add_argument("--skip-slow", action="store_true", help="leave out the MLE")
    ap.add_argument("--tables-only", action="store_true",
                    help="do not fit: rebuild the consistency table and figures from OUT/coefficients.csv")
    args = ap.parse_args(argv)
    data, out = Path(args.data), Path(args.out)
    methods = [m for m in args.methods.split(",") if m and not (args.skip_slow and m == "mle")]
    if not any(True for _ in _records(data)):
        raise SystemExit(f"real_runs: no recordings found under {data} (expected {ADIS[0]} ... or {MTIG})")
    out.mkdir(parents=True, exist_ok=True)
    if args.tables_only:
        df = pd.read_csv(out / "coefficients.csv")
    else:
        df = fit_all(data, methods)
        df.to_csv(out / "coefficients.csv", index=False)
    cons = consistency(df)
    cons.to_csv(out / "consistency.csv", index=False)
    (out / "consistency.md").write_text(_markdown(cons))
    _figures(data, df, out, methods)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
