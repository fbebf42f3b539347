"""``avbench estimate``: fit the coefficients of a real static gyro recording with several methods.

Examples
--------
avbench estimate rec.csv --fs 100 --units deg/s --method wls,gmwm
avbench estimate imu.npz --fs 100 --column 0 --units deg/s --method nnls_rel,gmwm,mle --out results/x
avbench estimate rec.npy --fs 200 --method gmwm --json > coefs.json

Input files: ``.npy`` (1-D, or 2-D with ``--column INDEX``), ``.npz`` (the array ``data``, or the
only array; column names from an array ``columns`` if present), text (``.csv``, ``.txt``,
``.dat``: comma, semicolon, tab or blank separated; a first row that is not numeric is a header).
The record is converted from ``--units`` to rad/s (``noise_models.units.rate_to_si``).

Outputs (in ``--out DIR``, default the current directory, file names prefixed with the input's
stem): ``<stem>_av.png`` (overlapping octave Allan deviation with 68 % chi^2 bars and each method's
fitted curve), ``<stem>_av.csv`` (the AV table), ``<stem>_coefficients.csv`` and ``.json`` (in the
papers' units, ``noise_models.units.PAPER_UNITS``, and in SI). Standard output gets the
coefficient table, or with ``--json`` only the JSON object ``{method: {coef: {"value", "unit",
"si"}}}``. Any problem with the file (unreadable, empty, wrong shape, non-numeric or unknown
column, NaN/inf) is a ``ValueError`` with a message naming it; nothing is written then.
"""

from __future__ import annotations

import json
import math
import os
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

from studies import data_files

__all__ = ["add_parser", "run", "load_record", "fit_methods", "fitted_avar"]

_TEXT = {".csv", ".txt", ".dat", ".tsv"}


# -- reading ------------------------------------------------------------------------------------
def _select(arr: np.ndarray, names: list[str] | None, column, path) -> np.ndarray:
    """One column of a 1-D or 2-D array, by index or name."""
    if arr.ndim == 1:
        if column not in (None, 0, "0") and not (names and column in names):
            raise ValueError(f"{path}: --column {column!r} given, but the file holds a single column")
        return arr
    if arr.ndim != 2:
        raise ValueError(f"{path}: expected a 1-D record or a 2-D (samples x columns) table, got shape {arr.shape}")
    n_rows, n_cols = arr.shape
    if n_cols == 1 and column in (None, 0, "0"):
        return arr[:, 0]
    if column is None:
        shown = f" ({', '.join(names)})" if names else ""
        raise ValueError(f"{path}: {n_cols} columns{shown}; choose one with --column NAME|INDEX")
    if names and str(column) in names:
        return arr[:, names.index(str(column))]
    try:
        idx = int(column)
    except (TypeError, ValueError):
        known = ", ".join(names) if names else f"indices 0..{n_cols - 1}"
        raise ValueError(f"{path}: unknown column {column!r}; expected one of {known}") from None
    if not 0 <= idx < n_cols:
        raise ValueError(f"{path}: column index {idx} out of range; expected 0..{n_cols - 1}")
    return arr[:, idx]


def _numeric(arr, path, what="data"):
    arr = np.asarray(arr)
    if arr.dtype.kind not in "iuf":
        raise ValueError(f"{path}: {what} is not numeric (dtype {arr.dtype}); expected rate samples")
    return arr.astype(float)


def _delimiter(path: Path) -> str:
    """The separator of a text table, from its first data line: comma, semicolon, tab or blanks."""
    try:
        with open(path, encoding="utf-8", errors="strict") as fh:
            for line in fh:
                line = line.strip()
                if line and not line.startswith("#"):
                    break
            else:
                raise ValueError(f"{path}: the file is empty")
    except UnicodeDecodeError:
        raise ValueError(f"{path}: not a text file (cannot decode as UTF-8)") from None
    for sep in (",", ";", "\t"):
        if sep in line:
            return sep
    return r"\s+"


def _read_text(path: Path, column):
    try:
        df = pd.read_csv(path, sep=_delimiter(path), engine="python", header=None, comment="#",
                         skip_blank_lines=True, dtype=str)
    except pd.errors.EmptyDataError:
        raise ValueError(f"{path}: the file is empty") from None
    except (pd.errors.ParserError, UnicodeDecodeError) as e:
        raise ValueError(f"{path}: cannot parse as a text table ({e})") from None
    if df.empty:
        raise ValueError(f"{path}: the file is empty")
    names = None
    if data_files.is_header_row(df.iloc[0].tolist()):  # a header row ("nan"/"inf" are numbers)
        names = [str(v).strip() for v in df.iloc[0]]
        df = df.iloc[1:].reset_index(drop=True)
        df.columns = names
        if df.empty:
            raise ValueError(f"{path}: a header but no samples")
    if df.shape[1] == 1:
        col = df.iloc[:, 0]
        label = names[0] if names else "column 0"
        if column not in (None, 0, "0") and not (names and column in names):
            raise ValueError(f"{path}: --column {column!r} given, but the file holds a single column")
    else:
        if column is None:
            shown = f" ({', '.join(names)})" if names else ""
            raise ValueError(f"{path}: {df.shape[1]} columns{shown}; choose one with --column NAME|INDEX")
        if names and str(column) in names:
            col, label = df[str(column)], str(column)
        else:
            try:
                idx = int(column)
            except (TypeError, ValueError):
                known = ", ".join(names) if names else f"indices 0..{df.shape[1] - 1}"
                raise ValueError(f"{path}: unknown column {column!r}; expected one of {known}") from None
            if not 0 <= idx < df.shape[1]:
                raise ValueError(f"{path}: column index {idx} out of range; expected 0..{df.shape[1] - 1}")
            col, label = df.iloc[:, idx], (names[idx] if names else f"column {idx}")
    values = pd.to_numeric(col, errors="coerce")
    bad = values.isna() & col.notna() & (col.astype(str).str.strip().str.lower() != "nan")
    if bad.any():
        i = int(np.flatnonzero(bad.to_numpy())[0])
        raise ValueError(f"{path}: {label} is not numeric (row {i}: {col.iloc[i]!r}); expected rate samples")
    return values.to_numpy(dtype=float)


def load_record(path, column=None) -> np.ndarray:
    """The rate samples of one column of a ``.npy``, ``.npz`` or text file (see module docstring)."""
    path = data_files.check_file(path)
    suffix = path.suffix.lower()
    if suffix == ".npy":
        x = _select(_numeric(data_files.load_npy(path), path), None, column, path)
    elif suffix == ".npz":
        z = data_files.load_npz(path)
        keys = list(z)
        if "data" in keys:
            arr = z["data"]
        else:
            arrays = [k for k in keys if k not in ("columns", "fs")]
            if len(arrays) != 1:
                raise ValueError(f"{path}: expected an array 'data' or a single array, found {keys}")
            arr = z[arrays[0]]
        names = [str(c) for c in z["columns"]] if "columns" in keys else None
        x = _select(_numeric(arr, path), names, column, path)
    elif suffix in _TEXT:
        x = _read_text(path, column)
    else:
        raise ValueError(f"{path}: unknown file type {suffix!r}; expected .npy, .npz, .csv, .txt, .dat or .tsv")
    if x.size == 0:
        raise ValueError(f"{path}: the record is empty")
    bad = ~np.isfinite(x)
    if bad.any():
        raise ValueError(
            f"{path}: {int(bad.sum())} non-finite sample(s) (NaN/inf), the first at index {int(np.flatnonzero(bad)[0])}; "
            "expected a gap-free record"
        )
    if x.size < 16:
        raise ValueError(f"{path}: {x.size} samples; expected at least 16")
    return x


# -- fitting ------------------------------------------------------------------------------------
def fit_methods(rate, dt, methods, settings=None) -> dict:
    """Fit each registered estimator in ``methods`` to ``rate`` (rad/s); returns name -> estimator.

    ``settings`` maps a method name to its settings (``estimators.get(name, **settings)``).
    """
    import estimators

    settings = settings or {}
    out = {}
    for name in methods:
        t0 = time.perf_counter()
        est = estimators.get(name, **settings.get(name, {})).fit(rate, dt)
        est.seconds_ = time.perf_counter() - t0
        out[name] = est
    return out


def fitted_avar(est, tau, dt) -> np.ndarray:
    """The AV curve a fitted estimator stands for: the exact AV of its latent model for ``gmwm`` and
    ``mle`` (Gauss-Markov bump, not a plateau), the five-term model curve otherwise."""
    from estimators.av_model import model_avar
    from estimators.gmwm import build_gyro

    p = est.diagnostics_.get("params")
    if est.name in ("gmwm", "mle") and isinstance(p, dict):
        lat, vals = [], []
        pick = {"QN": ["Q"], "WN": ["N"], "GM": ["sigma", "tc"], "RW": ["K"]}
        for latent, keys in pick.items():
            full = [f"{latent}.{k}" if est.name == "gmwm" else k for k in keys]
            if all(k in p for k in full) and all(p[k] > 0 for k in full):
                lat.append(latent)
                vals += [p[k] for k in full]
        if np.isfinite(est.coefficients_["R"]) and est.coefficients_["R"] > 0:
            lat.append("DR")
            vals.append(est.coefficients_["R"])
        if lat:
            return build_gyro(tuple(lat), vals, dt).avar(tau)
    c = est.coefficients_
    return model_avar({k: v for k, v in c.items() if np.isfinite(v)}, tau)


# -- output -------------------------------------------------------------------------------------
def _table(fits) -> pd.DataFrame:
    from noise_models.units import COEFFICIENTS, PAPER_UNITS, from_si

    rows = {}
    for name, est in fits.items():
        rows[name] = {f"{c} ({PAPER_UNITS[c]})": from_si(c, est.coefficients_[c], PAPER_UNITS[c]) for c in COEFFICIENTS}
    return pd.DataFrame.from_dict(rows, orient="index")


def _json(fits) -> dict:
    from noise_models.units import COEFFICIENTS, PAPER_UNITS, SI_UNITS, from_si

    def num(v):
        return None if not np.isfinite(v) else float(v)

    out = {}
    for name, est in fits.items():
        se = est.diagnostics_.get("std_err")
        out[name] = {}
        for c in COEFFICIENTS:
            v = est.coefficients_[c]
            entry = {"value": num(from_si(c, v, PAPER_UNITS[c])), "unit": PAPER_UNITS[c], "si": num(v),
                     "si_unit": SI_UNITS[c]}
            if isinstance(se, pd.Series) and np.isfinite(se.get(c, np.nan)):
                entry["std_err_si"] = float(se[c])
            out[name][c] = entry
    return out


def _figure(rate, dt, fits, units, title):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from estimators.allan import allan_variance
    from noise_models.units import rate_to_si

    k = 1.0 / rate_to_si(1.0, units)
    av = allan_variance(rate, dt, "octave", overlapping=True)
    fig, ax = plt.subplots(figsize=(7.5, 5.2))
    ax.errorbar(av.tau, av.adev * k, yerr=[(av.adev - np.sqrt(av.ci_low)) * k, (np.sqrt(av.ci_high) - av.adev) * k],
                fmt="o", ms=3, color="k", label="overlapping ADEV (68 % χ²)")
    tau = np.unique(np.rint(np.logspace(0, np.log10(av.m.max()), 80)).astype(int)) * dt
    for i, (name, est) in enumerate(fits.items()):
        curve = fitted_avar(est, tau, dt)
        if np.any(curve > 0):
            ax.loglog(tau, np.sqrt(np.where(curve > 0, curve, np.nan)) * k, "--", color=f"C{i}", label=name)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("τ (s)")
    ax.set_ylabel(f"Allan deviation ({units})")
    ax.set_title(title)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    return fig, av


def _write_atomic(path: Path, write) -> None:
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp{path.suffix}")
    write(tmp)
    os.replace(tmp, path)


# -- command --------------------------------------------------------------------------------------
def add_parser(subparsers):
    """Add the ``estimate`` sub-command to an ``argparse`` sub-parsers object."""
    s = subparsers.add_parser("estimate", help="fit the coefficients of a real static gyro recording",
                              description=__doc__.split("\n\n")[0])
    s.add_argument("file", help="recording: .npy, .npz, .csv, .txt, .dat, .tsv")
    s.add_argument("--fs", type=float, required=True, help="sample rate in Hz")
    s.add_argument("--column", default=None, help="column name or 0-based index (for tables)")
    s.add_argument("--units", default="rad/s", help="rate units of the file (rad/s, deg/s, deg/h, mrad/s)")
    s.add_argument("--method", default="nnls_rel,gmwm", help="comma-separated estimator names (avbench estimators)")
    s.add_argument("--set", action="append", default=[], metavar="METHOD.KEY=VALUE",
                   help="an estimator setting, e.g. gmwm.model=QN+WN+GM+RW (VALUE read as JSON if it parses)")
    s.add_argument("--json", action="store_true", help="print only a JSON object of the coefficients on stdout")
    s.add_argument("--out", default=".", help="output folder for the plot and tables (default: .)")
    s.add_argument("--title", default=None, help="plot title (default: the file name)")
    s.set_defaults(func=run)
    return s


def _check_args(args):
    import estimators
    from noise_models.units import rate_to_si

    if not (math.isfinite(args.fs) and args.fs > 0):
        raise ValueError(f"--fs: expected a positive sample rate in Hz, got {args.fs!r}")
    rate_to_si(1.0, args.units)  # raises for an unknown unit
    methods = [m.strip() for m in str(args.method).split(",") if m.strip()]
    if not methods:
        raise ValueError("--method: expected at least one estimator name")
    for m in methods:  # registered, installed (entry point) or "package.module:Class"
        try:
            estimators.estimator_class(m)
        except ValueError as e:
            raise ValueError(f"--method: {e}") from None
    settings: dict = {}
    for item in args.set:
        key, eq, value = str(item).partition("=")
        method, dot, setting = key.partition(".")
        if not (eq and dot and method and setting):
            raise ValueError(f"--set: expected METHOD.KEY=VALUE, got {item!r}")
        if method not in methods:
            raise ValueError(f"--set: method {method!r} is not among --method {', '.join(methods)}")
        try:
            parsed = json.loads(value)
        except json.JSONDecodeError:
            parsed = value
        settings.setdefault(method, {})[setting] = parsed
    for method, kw in settings.items():
        estimators.get(method, **kw)  # unknown settings raise here, before any work
    return methods, settings


def run(args) -> int:
    """Run ``avbench estimate`` (see the module docstring); returns the exit code."""
    from noise_models.units import rate_to_si

    methods, settings = _check_args(args)
    path = Path(args.file)
    rate = rate_to_si(load_record(path, args.column), args.units)
    dt = 1.0 / args.fs
    fits = fit_methods(rate, dt, methods, settings)
    label = f"{path.name}" + (f" [{args.column}]" if args.column is not None else "")
    fig, av = _figure(rate, dt, fits, args.units, args.title or label)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    stem = path.stem + (f"_{args.column}" if args.column is not None else "")
    table = _table(fits)
    payload = _json(fits)
    k = 1.0 / rate_to_si(1.0, args.units)
    avt = av.to_frame().assign(adev_units=av.adev * k)
    _write_atomic(out / f"{stem}_av.png", lambda p: fig.savefig(p, dpi=110, bbox_inches="tight"))
    import matplotlib.pyplot as plt

    plt.close(fig)
    _write_atomic(out / f"{stem}_av.csv", lambda p: avt.to_csv(p, index=False))
    _write_atomic(out / f"{stem}_coefficients.csv", lambda p: table.to_csv(p, index_label="method"))
    _write_atomic(out / f"{stem}_coefficients.json",
                  lambda p: p.write_text(json.dumps(payload, indent=2) + "\n"))
    if args.json:
        print(json.dumps(payload))
    else:
        print(f"# {label}: {rate.size} samples at {args.fs:g} Hz ({rate.size / args.fs / 3600:.2f} h), "
              f"rate units {args.units}")
        with pd.option_context("display.float_format", "{:.4g}".format, "display.width", 160):
            print(table.to_string())
        for name, est in fits.items():
            fail = est.diagnostics_.get("failure")
            extra = f"; {fail}" if fail else ""
            print(f"# {name}: {est.seconds_:.1f} s{extra}")
    print(f"avbench estimate: wrote {stem}_av.png, _av.csv, _coefficients.csv/.json in {out}", file=sys.stderr)
    return 0
