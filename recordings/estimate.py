"""``avbench estimate``: noise coefficients of a static IMU recording -- every axis, every method.

Examples
--------
avbench estimate imu.bag --topic /imu --kalibr imu.yaml           # ROS 1 or ROS 2 bag: all 6 axes
avbench estimate rec.csv --units deg/s --method wls,gmwm          # one gyro column, time column 't'
avbench estimate log.csv --time t --gyro gx,gy,gz --accel ax,ay,az --units deg/s --accel-units g
avbench estimate rec.npy --fs 200 --units rad/s --json > coefs.json
avbench estimate run1.npz run2.npz --combine --fs 100 --units rad/s   # several runs, one fit
avbench estimate run*.npz --combine --inflate auto --kalibr imu.yaml  # + between-run spread, yaml inflated by it

The pipeline (``studies/recordings/``): read the file (CSV/text, NPY/NPZ, ROS 1/2 bag, PX4 ULog) ->
time stamps, jitter and gaps (``--fs`` only when the file has no time stamps, else a check) -> SI
units (from the format, or ``--units``/``--accel-units``: never guessed) -> every method on every
axis (gap-aware Allan variance) -> outputs.

Outputs (in ``--out DIR``, default the current directory, names prefixed with the input's stem):
``<stem>_<sensor>_av.png`` (ADEV of each axis, each method's curve, the first method's terms),
``<stem>_av.csv`` (the AV tables), ``<stem>_coefficients.csv`` and ``.json`` (per sensor, axis and
method: values in display and SI units, standard errors/intervals where the method has them, and a
flag per coefficient: ok / not modelled / non-physical / failed, plus poor fit), and with
``--kalibr FILE`` / ``--format allan_variance_ros`` a filter's ``imu.yaml``. Standard output gets
one table per sensor, or with ``--json`` only the JSON object. Any problem with the input or an
option ends with a one-line error (exit code 2) and nothing written.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pandas as pd

__all__ = ["add_parser", "run"]


def add_parser(subparsers):
    """Add the ``estimate`` sub-command to an ``argparse`` sub-parsers object."""
    import argparse

    s = subparsers.add_parser("estimate", help="fit the noise coefficients of a static IMU recording",
                              description=__doc__.split("\n\n")[0],
                              epilog=__doc__.split("Examples\n--------\n", 1)[1].split("\n\n")[0],
                              formatter_class=argparse.RawDescriptionHelpFormatter)
    s.add_argument("file", nargs="+", help="recording(s): .npy .npz .mat .csv .txt .dat .tsv .bag .ulg or a ROS 2 bag folder")
    s.add_argument("--fs", type=float, default=None,
                   help="sample rate in Hz (needed when the file has no time stamps; else only checked)")
    s.add_argument("--units", default=None, help="gyro sample units when the format does not say: rad/s, deg/s, deg/h, mrad/s")
    s.add_argument("--accel-units", default=None, help="accelerometer sample units when the format does not say: m/s^2, g, mg, ug")
    s.add_argument("--column", default=None, help="one gyro column of a table: name or 0-based index")
    s.add_argument("--gyro", default=None, help="gyro columns of a table (comma-separated names or indices), or the "
                   "gyro array(s) of an .npz/.mat by name")
    s.add_argument("--accel", default=None, help="accelerometer columns of a table, or array(s) of an .npz/.mat, comma-separated")
    s.add_argument("--time", default=None, help="time column (or .npz/.mat array) (default: one named t/time/timestamp "
                   "or with a time unit in its header; 'none' to ignore it)")
    s.add_argument("--time-units", default=None, choices=["s", "ms", "us", "ns"],
                   help="units of the time column (default: the header's [unit], else from the stamps' magnitude "
                        "and step, else s)")
    s.add_argument("--topic", default=None, help="sensor_msgs/Imu topic of a bag (default: the only one)")
    s.add_argument("--method", default=None,
                   help="comma-separated estimator names (avbench estimators; default: the methods safe on real records, "
                        "avbench.estimators.base.DEFAULT_METHODS)")
    s.add_argument("--set", action="append", default=[], metavar="METHOD.KEY=VALUE",
                   help="an estimator setting, e.g. gmwm.model=QN+WN+GM+RW (VALUE read as JSON if it parses)")
    s.add_argument("--combine", action="store_true",
                   help="pool several recordings of one sensor in one fit, test that they agree, and report the "
                        "between-run spread of each coefficient (the --filter-method fitted to each run alone; random effects)")
    s.add_argument("--kalibr", default=None, metavar="FILE", help="also write a Kalibr imu.yaml to FILE")
    s.add_argument("--format", default=None, choices=["kalibr", "allan_variance_ros"],
                   help="also write <stem>_imu.yaml in --out in this style")
    s.add_argument("--filter-method", default=None, help="method whose N and K go into the yaml (default: the first of --method)")
    s.add_argument("--inflate", default=None, metavar="F|F_NOISE,F_WALK|auto",
                   help="multiply the yaml's noise densities / random walks (default: no inflation); 'auto' (with --combine "
                        "and >= 3 recordings): by the between-run spread's 95 %% prediction limit over the mean")
    s.add_argument("--deviation", default=None, metavar="NAMES",
                   help="also draw and tabulate these deviations on each axis (comma-separated: oadev, hdev, ohdev, "
                        "mdev, tdev, totdev, mtotdev, htotdev, theo1, theobr), on the longest gap-free run; rows of "
                        "<stem>_av.csv by 'statistic' (alone: avbench deviations FILE)")
    s.add_argument("--json", action="store_true", help="print only the JSON object on stdout")
    s.add_argument("--out", default=".", help="output folder for the plots and tables (default: .)")
    s.add_argument("--title", default=None, help="plot title (default: the file name)")
    s.add_argument("--no-progress", action="store_true", help="no progress bars")
    s.set_defaults(func=run)
    return s


def _check_args(args):
    from avbench import estimators
    from avbench.recordings.filter_yaml import parse_inflate
    from avbench.recordings.timing import check_fs

    check_fs(args.fs)
    from avbench.estimators.base import DEFAULT_METHODS

    spec = ",".join(DEFAULT_METHODS) if args.method is None else str(args.method)
    methods = [m.strip() for m in spec.split(",") if m.strip()]
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
    if args.column is not None and args.gyro is not None:
        raise ValueError("--column: give either --column or --gyro, not both")
    if len(args.file) > 1 and not args.combine:
        raise ValueError(f"{len(args.file)} files given; expected one recording, or --combine to pool recordings of one sensor")
    inflate = parse_inflate(args.inflate)
    if inflate == "auto" and not (args.combine and len(args.file) >= 3):
        raise ValueError(f"--inflate auto: derives the factors from the spread between recordings; expected --combine "
                         f"with at least 3 recordings of one sensor, got {len(args.file)} file(s)")
    fm = args.filter_method or methods[0]
    if fm not in methods:
        raise ValueError(f"--filter-method {fm!r}: not among --method {', '.join(methods)}")
    if args.kalibr is not None:
        k = Path(args.kalibr)
        if k.is_dir():
            raise ValueError(f"--kalibr {args.kalibr!r}: is a folder; expected a file name for the imu.yaml")
        parent = k.parent
        while not parent.exists() and parent != parent.parent:
            parent = parent.parent
        if parent.exists() and not parent.is_dir():
            raise ValueError(f"--kalibr {args.kalibr!r}: {str(parent)!r} is not a folder; expected a file path")
    args.deviation = _check_deviation(getattr(args, "deviation", None))
    return methods, settings, fm, inflate


#: the deviations' cluster sizes stop where the terms summed reach this (Theo1 costs (N - m) m / 2 per tau)
DEVIATION_BUDGET = 5e9


def _check_deviation(spec):
    """--deviation: a list of the deviation family's names (None when not given)."""
    if spec is None:
        return None
    from avbench.estimators.allan.deviations import DEVIATION_NAMES

    names = [n.strip() for n in str(spec).split(",") if n.strip()]
    bad = [n for n in names if n not in DEVIATION_NAMES]
    if bad or not names:
        raise ValueError(f"--deviation: expected names among {', '.join(DEVIATION_NAMES)}, got {spec!r}")
    return names


def _longest_run(n, starts):
    """(start, stop) of the longest gap-free run of a record of ``n`` samples."""
    edges = np.concatenate(([0], np.asarray(starts, dtype=np.int64), [n]))
    k = int(np.argmax(np.diff(edges)))
    return int(edges[k]), int(edges[k + 1])


def _check_deviations_feasible(names, n, starts):
    """--deviation: refuse, before any fit, a statistic the longest run is too long for (TheoBR)."""
    if names:
        from avbench.estimators.allan.deviations import check_feasible

        a, b = _longest_run(n, starts)
        try:
            check_feasible(names, b - a)
        except ValueError as e:
            raise ValueError(f"--deviation: {e}") from None


def _deviations(x, dt, starts, names, taus="octave"):
    """{name: AllanResult} of one axis on its longest gap-free run (cost capped by DEVIATION_BUDGET terms)."""
    from avbench.estimators.allan.deviations import deviation

    a, b = _longest_run(len(x), starts)
    run = np.asarray(x[a:b], dtype=float)
    return {name: deviation(run, dt, name, taus, max_terms=DEVIATION_BUDGET) for name in names}


def _load(args, progress):
    """Read every file: [(Recording, Timing, [SensorRecord])]."""
    from avbench.recordings.readers import read_recording
    from avbench.recordings.sensors import to_si
    from avbench.recordings.timing import timing_of

    loaded = []
    gyro = args.gyro if args.gyro is not None else args.column
    for f in args.file:
        rec = read_recording(f, gyro=gyro, accel=args.accel, time_column=args.time, time_units=args.time_units,
                             topic=args.topic, progress=progress)
        timing = timing_of(rec.time, args.fs, rec.n_samples, rec.path)
        loaded.append((rec, timing, to_si(rec, args.units, args.accel_units)))
    return loaded


def _combine(loaded):
    """One (timing, sensors) from several recordings: concatenated, file boundaries are gaps."""
    from avbench.recordings.sensors import SensorRecord
    from avbench.recordings.timing import FS_TOLERANCE, Timing

    rec0, t0, s0 = loaded[0]
    layout = [(s.sensor, tuple(s.axes)) for s in s0]
    for rec, t, s in loaded[1:]:
        if [(x.sensor, tuple(x.axes)) for x in s] != layout:
            raise ValueError(f"--combine: {rec.path} has other sensors/axes than {rec0.path}; expected recordings of one sensor")
        if abs(t.dt / t0.dt - 1) > FS_TOLERANCE:
            raise ValueError(f"--combine: {rec.path} is sampled at {t.fs:.6g} Hz, {rec0.path} at {t0.fs:.6g} Hz; "
                             "expected one sample rate")
    offsets = np.cumsum([0] + [t.n_samples for _, t, _ in loaded[:-1]])
    starts = np.concatenate([np.concatenate(([o] if o else [], t.starts + o)) for o, (_, t, _) in zip(offsets, loaded)])
    gaps = np.concatenate([np.concatenate(([np.nan] if o else [], t.gap_seconds)) for o, (_, t, _) in zip(offsets, loaded)])
    n = int(sum(t.n_samples for _, t, _ in loaded))
    timing = Timing(t0.dt, t0.source + f" ({len(loaded)} recordings pooled; file boundaries are gaps)", n,
                    starts.astype(np.int64), gaps, t0.jitter, t0.max_deviation)
    sensors = []
    for k, s in enumerate(s0):
        axes = {a: np.concatenate([np.asarray(sl[k].axes[a]) for _, _, sl in loaded]) for a in s.axes}
        sensors.append(SensorRecord(s.sensor, s.unit_in, axes, s.names))
    return timing, sensors


def _outputs(stem, sensors, args):
    names = [f"{stem}_{s.sensor}_av.png" for s in sensors] + [f"{stem}_av.csv", f"{stem}_coefficients.csv",
                                                             f"{stem}_coefficients.json"]
    if args.format:
        names.append(f"{stem}_imu.yaml")
    return names


def run(args) -> int:
    """Run ``avbench estimate`` (see the module docstring); returns the exit code."""
    from tqdm import tqdm

    from avbench.outputs import atomic_write_bytes, atomic_write_text, prepare_out_dir
    from avbench.recordings import figure, filter_yaml, report
    from avbench.recordings.fit import agreement, auto_inflation, between_runs, fit_axis, scaled_allan

    methods, settings, filter_method, inflate = _check_args(args)
    progress = not args.no_progress and sys.stderr.isatty()
    loaded = _load(args, progress)
    rec = loaded[0][0]
    if len(loaded) > 1:
        timing, sensors = _combine(loaded)
    else:
        timing, sensors = loaded[0][1], loaded[0][2]
    column = args.column if args.column is not None else None
    stem = (rec.path.stem or rec.path.name) + (f"_{column}" if column is not None else "") + \
        ("_combined" if len(loaded) > 1 else "")
    if args.kalibr is not None or args.format:  # checked from the file to the fit: the yaml's needs before any fit
        filter_yaml.check_sensors([s.sensor for s in sensors], "--kalibr" if args.kalibr else "--format")
    out = prepare_out_dir(args.out, "--out", _outputs(stem, sensors, args))
    dt = timing.dt
    _check_deviations_feasible(args.deviation, timing.n_samples, timing.starts)

    from avbench.recordings.static import static_check

    # the AV engine, asked once per axis: the static check, the yaml's bounds, the AV table and the figure use it
    all_avs = {s.sensor: {a: scaled_allan(x, dt, timing.starts) for a, x in s.axes.items()} for s in sensors}
    still = static_check(sensors, dt, all_avs)  # said before the fits, which still run
    if not still["static"] and not args.json:
        print("# NOT STATIC: the record does not look like a sensor at rest -- " + "; ".join(still["reasons"][:4]) +
              ("; ..." if len(still["reasons"]) > 4 else "") + ". The fits below assume rest: poor fits are expected.",
              file=sys.stderr)
    n_fits = sum(len(s.axes) for s in sensors) * len(methods)
    fits: dict = {}
    with tqdm(total=n_fits, desc="fitting", unit="fit", disable=not progress, leave=False) as bar:
        for s in sensors:
            fits[s.sensor] = {a: fit_axis(x, dt, timing.starts, methods, settings, bar) for a, x in s.axes.items()}
    extra = {"format": rec.format, "topic": rec.topic, "time_source": rec.time_source, "notes": rec.notes,
             "static_check": still}
    if len(loaded) > 1:
        extra["combine"] = {}
        for s_i, s in enumerate(sensors):
            extra["combine"][s.sensor] = {
                a: agreement([(np.asarray(sl[s_i].axes[a]), t.starts) for _, t, sl in loaded], dt) for a in s.axes}
        # the between-run spread: the filter method on each recording alone, random effects per coefficient
        extra["between_runs"] = {"method": filter_method, "sensors": {}}
        with tqdm(total=sum(len(s.axes) for s in sensors) * len(loaded), desc="each run alone", unit="fit",
                  disable=not progress, leave=False) as bar_:
            for s_i, s in enumerate(sensors):
                extra["between_runs"]["sensors"][s.sensor] = {
                    a: between_runs([fit_axis(np.asarray(sl[s_i].axes[a]), dt, t.starts, [filter_method],
                                              {filter_method: settings.get(filter_method, {})}, bar_)
                                     for _, t, sl in loaded], filter_method) for a in s.axes}
    if inflate == "auto":
        from avbench.recordings.filter_yaml import KEYS

        inflate = {}
        for (sensor, coef), key in KEYS.items():
            per_axis = extra["between_runs"]["sensors"].get(sensor, {})
            fs_ = [auto_inflation(sp, coef) for sp in per_axis.values()]
            fs_ = [f for f in fs_ if f is not None]
            inflate[key] = max(fs_) if fs_ else 1.0
        extra["between_runs"]["inflate"] = inflate
    data = report.payload([r.path for r, _, _ in loaded], timing, sensors, fits, extra)

    # everything that can refuse is checked before anything is written
    yaml_text = None
    if args.kalibr is not None or args.format:
        choices = filter_yaml.filter_choices(data, filter_method, "--kalibr" if args.kalibr else "--format", all_avs)
        style = args.format or "kalibr"
        yaml_text = filter_yaml.kalibr_yaml(choices, timing.fs, rec.topic, filter_method,
                                            [r.path for r, _, _ in loaded], inflate, style)
        data["filter_yaml"] = {"method": filter_method, "inflate": dict(inflate) if isinstance(inflate, dict) else list(inflate),
                               "values_si": {k: v for k, (v, _, _) in choices.items()},
                               "bounds": {k: why for k, (_, _, why) in choices.items() if why}}
    tables = report.tables(data)
    av_rows, figs, devs = [], [], {}
    for s in sensors:
        avs = all_avs[s.sensor]
        for a, x in s.axes.items():
            av, scale = avs[a]
            frame = av.to_frame()
            with np.errstate(over="ignore", under="ignore"):
                for col in ("avar", "ci_low", "ci_high"):
                    frame[col] = frame[col] / scale / scale  # may overflow to inf for a record of 1e300: adev does not
                frame["adev"] = frame["adev"] / scale
            frame = frame.assign(sensor=s.sensor, axis=a, unit=f"avar ({s.si_unit})^2, adev {s.si_unit}")
            if args.deviation:
                devs.setdefault(s.sensor, {})[a] = _deviations(x, dt, timing.starts, args.deviation)
                frame.insert(0, "statistic", "oadev")
                for name, r in devs[s.sensor][a].items():
                    if r.kind == "avar":
                        continue  # oadev: the engine's rows above
                    f = r.to_frame()  # column "adev" holds the statistic's deviation
                    unit = f"{s.si_unit.split('/')[0]}" if r.kind == "tvar" else s.si_unit
                    av_rows.append(f.assign(statistic=name, sensor=s.sensor, axis=a,
                                            unit=f"variance ({unit})^2, deviation {unit}")[["statistic", *f.columns, "sensor", "axis", "unit"]])
            av_rows.append(frame)
        flags = {a: {m: data["sensors"][s.sensor]["axes"][a]["methods"][m]["poor_fit"] for m in methods} for a in s.axes}
        figs.append((s.sensor, figure.figure(s, fits[s.sensor], avs, dt, args.title or rec.path.name, flags,
                                             deviations=devs.get(s.sensor))))

    import io

    import matplotlib.pyplot as plt

    for sensor, fig in figs:
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=110, bbox_inches="tight")
        plt.close(fig)
        atomic_write_bytes(out / f"{stem}_{sensor}_av.png", buf.getvalue())
    atomic_write_text(out / f"{stem}_av.csv", pd.concat(av_rows, ignore_index=True).to_csv(index=False))
    long = pd.concat({k: v for k, v in tables.items()}, names=["sensor"])
    atomic_write_text(out / f"{stem}_coefficients.csv", long.to_csv())
    atomic_write_text(out / f"{stem}_coefficients.json", json.dumps(data, indent=2) + "\n")
    written = [f"{stem}_{s}_av.png" for s, _ in figs] + [f"{stem}_av.csv", f"{stem}_coefficients.csv/.json"]
    if args.format:
        atomic_write_text(out / f"{stem}_imu.yaml", yaml_text)
        written.append(f"{stem}_imu.yaml")
    if args.kalibr is not None:
        k = Path(args.kalibr)
        k.parent.mkdir(parents=True, exist_ok=True)
        atomic_write_text(k, yaml_text)

    if args.json:
        print(json.dumps(data))
    else:
        _print_summary(data, tables, timing, fits, rec)
    print(f"avbench estimate: wrote {', '.join(written)} in {out}" + (f"; {args.kalibr}" if args.kalibr else ""),
          file=sys.stderr)
    return 0


def _print_summary(data, tables, timing, fits, rec):
    from avbench.recordings import report

    src = ", ".join(data["sources"])
    joins = int(np.isnan(timing.gap_seconds).sum())  # --combine: file boundaries
    gaps = (f", {timing.n_gaps - joins} gap(s) ({np.nansum(timing.gap_seconds):.3g} s missing)" if timing.n_gaps - joins else "") + \
        (f", {joins} file boundary(ies) treated as gaps" if joins else "")
    jit = f", jitter {timing.jitter:.2%} of dt" if timing.jitter is not None else ""
    print(f"# {src}: {timing.n_samples} samples at {timing.fs:.6g} Hz ({timing.n_samples * timing.dt / 3600:.2f} h) "
          f"from {timing.source}{jit}{gaps}" + (f"; topic {rec.topic}" if rec.topic else ""))
    for note in rec.notes:
        print(f"# note: {note}")
    still = data.get("static_check")
    if still is not None and not still["static"]:
        print("# NOT STATIC: " + "; ".join(still["reasons"]) + " -- the fits assume a sensor at rest; "
              "a POOR FIT below is expected for this reason")
    screen = report.screen_tables(data)
    print("# each coefficient: value [95 % interval]; '< x': not resolved by this record, x its upper 95 % bound; "
          "'(+- s)': a standard error only; '-': not in the method's model")
    for sensor, table in tables.items():
        sd = data["sensors"][sensor]
        print(f"\n## {sensor} (samples in {sd['units_in']}): {', '.join(f'{c} = {n}' for c, n in sd['terms'].items())}")
        with pd.option_context("display.width", 250, "display.max_columns", 20, "display.max_colwidth", 120):
            print(screen[sensor].to_string())
    for sensor, per_axis in fits.items():
        for axis, per_method in per_axis.items():
            for name, f in per_method.items():
                md = data["sensors"][sensor]["axes"][axis]["methods"][name]
                extra = [f"failed: {md['failure']}"] if md["failure"] else []
                if md["poor_fit"]:
                    extra.append("POOR FIT: the model misses the AV curve beyond its intervals" +
                                 (" (the record does not look static: see NOT STATIC above)"
                                  if still is not None and not still["static"] else ""))
                extra += md["warnings"][:2]
                print(f"# {sensor} {axis} {name}: {f.seconds:.1f} s" + (f"; {'; '.join(extra)}" if extra else ""))
    if "combine" in data:
        for sensor, per_axis in data["combine"].items():
            for axis, a in per_axis.items():
                verdict = "agree" if a["agree"] else ("DISAGREE" if a["agree"] is not None else "not testable")
                p = f"p = {a['p_value']:.3g}" if a["p_value"] is not None else a["note"]
                print(f"# recordings {verdict} on {sensor} {axis} ({p})")
    if "between_runs" in data:
        _print_between_runs(data)


def _print_between_runs(data):
    from avbench.noise_models.units import DISPLAY_UNITS, from_si

    br = data["between_runs"]
    print(f"\n## between-run spread ({br['method']} on each recording alone; random effects, DerSimonian & Laird 1986)")
    for sensor, per_axis in br["sensors"].items():
        for axis, per_coef in per_axis.items():
            for c, r in per_coef.items():
                if r["tau"] is None:
                    continue
                unit = DISPLAY_UNITS[sensor][c]

                def d(v):
                    return from_si(c, v, unit, sensor)

                lo, hi = r["tau_ci"]
                pred = (f"; a new run: {d(r['prediction'][0]):.4g} to {d(r['prediction'][1]):.4g}"
                        if r["prediction"] is not None else "")
                cv = f" (CV {100 * r['cv']:.3g} %)" if r["cv"] is not None else ""
                print(f"# {sensor} {axis} {c}: mean {d(r['mean']):.4g} +- {d(r['mean_se']):.2g} {unit} over {r['k']} runs; "
                      f"between-run SD {d(r['tau']):.3g}{cv}, 95 % interval {d(lo):.3g} to {d(hi):.3g}{pred}")
    if "inflate" in br:
        print("# --inflate auto: " + ", ".join(f"{k} x {v:.3g}" for k, v in br["inflate"].items()))
