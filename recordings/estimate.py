"""``avbench estimate``: noise coefficients of a static IMU recording -- every axis, every method.

Examples
--------
avbench estimate imu.bag --topic /imu --kalibr imu.yaml           # ROS 1 or ROS 2 bag: all 6 axes
avbench estimate rec.csv --units deg/s --method wls,gmwm          # one gyro column, time column 't'
avbench estimate log.csv --time t --gyro gx,gy,gz --accel ax,ay,az --units deg/s --accel-units g
avbench estimate rec.npy --fs 200 --units rad/s --json > coefs.json
avbench estimate run1.npz run2.npz --combine --fs 100 --units rad/s   # several runs, one fit
avbench estimate run*.npz --combine --inflate auto --kalibr imu.yaml  # + between-run spread, yaml inflated by it

The pipeline (:mod:`avbench.recordings`): read the file (CSV/text, NPY/NPZ, MATLAB, ROS 1/2 bag, PX4 ULog) ->
time stamps, jitter and gaps (``--fs`` only when the file has no time stamps, else a check) -> SI
units (from the format, or ``--units``/``--accel-units``: never guessed) -> every method on every
axis (gap-aware Allan variance) -> outputs.

Outputs (in ``--out DIR``, default the current directory, names prefixed with the input's stem made
safe for a file name: :func:`avbench.recordings.plan.output_stem`): ``<stem>_<sensor>_av.png`` (ADEV of
each axis, each method's curve, the first method's terms), ``<stem>_av.csv`` (the AV tables),
``<stem>_coefficients.csv`` and ``.json`` (per sensor, axis and method: values in display and SI units,
standard errors/intervals where the method has them, and a flag per coefficient: ok / not modelled /
non-physical / failed, plus poor fit), and with ``--kalibr FILE`` / ``--format allan_variance_ros`` a
filter's ``imu.yaml``. Standard output gets one table per sensor (a sensor whose values overflow the
display units is shown in SI), or with ``--json`` only the JSON object.

Every option (methods, ``--set`` settings by their declarations and relations, ``--inflate``,
``--deviation``, ``--title``) is checked before the file is read, and every output is planned and
checked before the first fit (:mod:`avbench.recordings.plan`): names, folders, no output over an input
or over another output. The outputs are written as one set (:func:`avbench.outputs.write_set`): an
interrupted run leaves the previous set or the new one. Any problem with the input or an option ends
with a one-line error (exit code 2) and nothing written.

From Python, :func:`estimate_file` fits one recording and returns the fits per sensor, axis and method;
the command reads with :func:`avbench.recordings.load.load_recording` and fits with :func:`fit_sensors`,
as :func:`estimate_file` does.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from avbench.text import empty_is_none

__all__ = ["add_parser", "run", "estimate_file", "fit_sensors", "check_title", "NOT_STATIC_EXIT"]

#: the exit code of a record answered as not static, nothing fitted (``--fit-not-static`` fits it)
NOT_STATIC_EXIT = 3


def add_parser(subparsers, parents):
    """Add the ``estimate`` sub-command to an ``argparse`` sub-parsers object; ``parents`` holds the parser
    of the reader options (:func:`avbench.cli.reader_options_parser`), shared with every command that
    reads a recording."""
    import argparse

    s = subparsers.add_parser("estimate", help="fit the noise coefficients of a static IMU recording",
                              description=__doc__.split("\n\n")[0],
                              epilog=__doc__.split("Examples\n--------\n", 1)[1].split("\n\n")[0],
                              formatter_class=argparse.RawDescriptionHelpFormatter, parents=list(parents))
    s.add_argument("file", nargs="+", help="recording(s): .npy .npz .mat .csv .txt .dat .tsv .bag .ulg or a ROS 2 bag folder")
    s.add_argument("--method", default=None,
                   help="comma-separated estimator names (avbench estimators; default: the methods safe on real records, "
                        "avbench.estimators.base.DEFAULT_METHODS)")
    s.add_argument("--set", action="append", default=[], metavar="METHOD.KEY=VALUE",
                   help="an estimator setting, e.g. gmwm.model=QN+WN+GM+RW (VALUE read as JSON if it parses)")
    s.add_argument("--combine", action="store_true",
                   help="pool several recordings of one sensor in one fit, test that they agree, and report the "
                        "between-run spread of each coefficient (the --filter-method fitted to each run alone; random effects)")
    s.add_argument("--kalibr", default=None, metavar="FILE", help="also write a Kalibr imu.yaml to FILE")
    s.add_argument("--format", default=None, metavar="NAME[,NAME...]",
                   help="also write the noise parameters in the file each filter stack reads, <stem>_<name>.<ext> in "
                        "--out: kalibr, allan_variance_ros, openvins, vins, orbslam3, basalt, gtsam, px4, matlab, "
                        "ros_imu_covariance (keys, units and conventions: docs/EXPORTS.md)")
    s.add_argument("--filter-rate", default=None, type=float, metavar="HZ",
                   help="the rate at which the filter receives the samples, where a stack needs a discrete value at "
                        "it (default: the record's rate; PX4: EKF2's prediction rate, default 100 Hz; the file says which)")
    s.add_argument("--html", action="store_true",
                   help="also write <stem>_report.html: one self-contained page (the record, the static check, the "
                        "figures, the coefficient tables, the fit checks and every exported file, ready to copy)")
    s.add_argument("--filter-method", default=None, help="method whose N and K go into the yaml (default: the first of --method)")
    s.add_argument("--inflate", default=None, metavar="F|F_NOISE,F_WALK|auto",
                   help="multiply the yaml's noise densities / random walks (default: no inflation); 'auto' (with --combine "
                        "and >= 3 recordings): by the between-run spread's 95 %% prediction limit over the mean")
    s.add_argument("--deviation", default=None, metavar="NAMES",
                   help="also draw and tabulate these deviations on each axis (comma-separated: oadev, hdev, ohdev, "
                        "mdev, tdev, totdev, mtotdev, ttotdev, htotdev, pdev, theo1, theobr), on the longest gap-free run; rows of "
                        "<stem>_av.csv by 'statistic' (alone: avbench deviations FILE)")
    s.add_argument("--fit-not-static", action="store_true",
                   help="fit a record the static check calls not static (default: it is answered with the verdict, "
                        "the figure and what to do, nothing fitted and no filter file written, exit code 3); the filter "
                        "files then say in their header that the record was not static")
    s.add_argument("--jobs", default=None, type=int, metavar="N",
                   help="processes fitting the axes, this one included (default: the cores, for a record of at least "
                        "2^17 samples; 1: none started); the numbers do not depend on it")
    s.add_argument("--json", action="store_true", help="print only the JSON object on stdout")
    s.add_argument("--out", default=".", help="output folder for the plots and tables (default: .)")
    s.add_argument("--title", default=None, type=empty_is_none,
                   help="plot title (default: the file name; --title '' for none)")
    s.add_argument("--no-progress", action="store_true", help="no progress bars")
    s.set_defaults(func=run)
    return s


def _methods(spec) -> list[str]:
    """Estimator names from a comma-separated string or a list (None: the default methods), each one
    registered, installed (entry point) or "package.module:Class"."""
    from avbench import estimators
    from avbench.estimators.base import DEFAULT_METHODS

    from avbench.estimators.base import BUILTIN

    if spec is None:
        spec = DEFAULT_METHODS
    items = str(spec).split(",") if isinstance(spec, str) else [str(m) for m in spec]
    methods = [m.strip() for m in items if m.strip()]
    if not methods:
        raise ValueError("--method: expected at least one estimator name")
    for m in methods:
        if m in BUILTIN:  # a built-in is there by construction: its module is imported by its first fit
            continue
        try:
            estimators.estimator_class(m)
        except ValueError as e:
            raise ValueError(f"--method: {e}") from None
    return methods


def _check_settings(settings: dict, option: str = "--set") -> None:
    """Every setting of every method checked before any work, as ``estimators.get`` checks them (unknown
    settings, each value and the relations between them: :func:`avbench.estimators.settings.validate_settings`);
    a ``ValueError`` naming ``option``."""
    from avbench import estimators

    for method, kw in settings.items():
        try:
            estimators.get(method, **kw)
        except ValueError as e:
            raise ValueError(f"{option}: {e}") from None


def check_title(title) -> None:
    """``--title``: a text matplotlib can draw (``$...$`` must be valid mathtext; ``\\$`` is a dollar sign)."""
    if title is None or "$" not in str(title):
        return
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure()
    FigureCanvasAgg(fig)
    fig.suptitle(str(title))
    try:
        fig.canvas.draw()
    except Exception as e:  # matplotlib's mathtext raises ValueError (and others) for a bad expression
        first = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
        raise ValueError(f"--title {title!r}: matplotlib cannot draw it ({first[:120]}); expected plain text, or "
                         "$...$ holding valid mathtext (\\$ for a dollar sign)") from None


def _check_args(args):
    from avbench.recordings.deviations import parse_deviations
    from avbench.recordings.filter_yaml import parse_inflate
    from avbench.recordings.load import check_reader_options, reader_options_of
    from avbench.recordings.plan import check_file_target

    check_reader_options(**reader_options_of(args))
    methods = _methods(args.method)
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
    _check_settings(settings)
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
        check_file_target(Path(args.kalibr), "--kalibr")
    if args.format:
        from avbench.recordings.exports import parse_names

        args.format = parse_names(args.format)
    if args.filter_rate is not None and not (math.isfinite(args.filter_rate) and args.filter_rate > 0):
        raise ValueError(f"--filter-rate: expected the filter's rate in Hz (a number > 0), got {args.filter_rate:g}")
    if getattr(args, "jobs", None) is not None and args.jobs < 1:
        raise ValueError(f"--jobs: expected a number of processes >= 1, got {args.jobs}")
    if args.filter_rate is not None and not args.format:
        raise ValueError("--filter-rate: sets the rate of the --format files; expected --format NAME as well")
    check_title(args.title)
    args.deviation = parse_deviations(getattr(args, "deviation", None))
    return methods, settings, fm, inflate


def fit_sensors(sensors, timing, methods, settings=None, progress=None, jobs=None) -> dict:
    """Every method on every axis of SI ``sensors`` timed by ``timing`` (gap-aware:
    :func:`avbench.recordings.fit.fit_axis`): ``{sensor: {axis: {method: MethodFit}}}``. ``progress``
    (a tqdm bar or None) is advanced once per fit; ``jobs``: processes fitting the axes
    (:func:`avbench.recordings.fit_pool.worker_count`; the numbers do not depend on it)."""
    from avbench.recordings.fit_pool import fit_axes, worker_count

    axes = [(s.sensor, a, x) for s in sensors for a, x in s.axes.items()]
    workers = worker_count(jobs, len(axes), timing.n_samples)
    fitted = fit_axes([(x, timing.dt, timing.starts, methods, settings) for _, _, x in axes], workers, progress)
    out: dict = {}
    for (sensor, a, _), fits in zip(axes, fitted):
        out.setdefault(sensor, {})[a] = fits
    return out


def estimate_file(path, methods=None, settings=None, fit_not_static=False, jobs=None, **reader_options) -> dict:
    """The noise coefficients of one recording: every method fitted to every axis, as ``avbench estimate``
    fits them, returned as ``{sensor: {axis: {method: MethodFit}}}``
    (:class:`avbench.recordings.fit.MethodFit`; coefficients in SI).

    ``path``: a recording in any format of :mod:`avbench.recordings.readers`; ``methods``: estimator
    names, a list or a comma-separated string (default: the methods safe on real records,
    :data:`avbench.estimators.base.DEFAULT_METHODS`); ``settings``: ``{method: {setting: value}}``;
    ``fit_not_static``: fit a record that the static check (:mod:`avbench.recordings.static`) calls not
    static (else that record raises :class:`~avbench.recordings.static.NotStaticError`, a ``ValueError``
    carrying the check, before any fit); ``jobs``: processes fitting the axes (default: the cores, for
    a record of at least 2^17 samples; the numbers do not depend on it);
    ``reader_options``: the keywords of :func:`avbench.recordings.load.load_recording` (``fs``,
    ``units``, ``accel_units``, ``column``, ``gyro``, ``accel``, ``time``, ``time_units``, ``topic``,
    ``progress``). A problem with the file, an option, a method or a setting is a ``ValueError``; a
    method failing on an axis is a fit flagged failed (its ``error``), as on the command line.

    >>> import tempfile
    >>> from pathlib import Path
    >>> import numpy as np
    >>> from avbench.recordings import estimate_file
    >>> rng = np.random.default_rng(1)
    >>> n, dt, sigma = 60_000, 0.01, 0.05                  # 10 min at 100 Hz, white noise of 0.05 deg/s
    >>> table = np.column_stack([np.arange(n) * dt, rng.normal(0.0, sigma, (n, 3))])
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     path = Path(folder) / "imu.csv"
    ...     np.savetxt(path, table, delimiter=",", header="t [s],gx [deg/s],gy [deg/s],gz [deg/s]", comments="")
    ...     fits = estimate_file(path, methods="wls")
    >>> sorted(fits["gyro"])
    ['x', 'y', 'z']
    >>> N = fits["gyro"]["x"]["wls"].coefficients()["N"]  # angle random walk, rad/sqrt(s)
    >>> print(f"{N / np.deg2rad(sigma * np.sqrt(dt)):.1f}")  # over its true value, sigma sqrt(dt)
    1.0
    """
    from avbench.recordings.load import load_recording

    methods = _methods(methods)
    settings = dict(settings or {})
    unknown = [m for m in settings if m not in methods]
    if unknown:
        raise ValueError(f"settings: method {unknown[0]!r} is not among the methods {', '.join(methods)}")
    _check_settings(settings, "settings")
    _, timing, sensors = load_recording(path, **reader_options)
    if not fit_not_static:
        from avbench.recordings.quality import judge_record
        from avbench.recordings.static import NotStaticError, static_check, verdict, what_to_do

        still = static_check(sensors, timing.dt, spikes=judge_record(sensors, timing.dt).spikes)
        if not still["static"]:
            raise NotStaticError(f"{path}: {verdict(still)}; "
                                 f"{what_to_do(still, timing.n_samples * timing.dt, 'fit_not_static=True')}", still)
    return fit_sensors(sensors, timing, methods, settings, jobs=jobs)


def _png(fig) -> bytes:
    """The PNG of a figure of :func:`avbench.recordings.figure.figure` (its own Agg canvas, no pyplot)."""
    import io

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    return buf.getvalue()


def _plan(args, stem, sensors, fitted: bool = True):
    """The outputs of ``avbench estimate`` (:class:`avbench.recordings.plan.OutputPlan`), each with its
    writer: a function of the results (a dict: ``pngs`` the figures per sensor, ``av_table``, ``tables``,
    ``data`` the JSON payload, ``yaml`` the Kalibr yaml's text, ``exports`` each ``--format`` file's
    ``(suffix, text)``, ``html`` the page). Without ``fitted`` (a record not static, not fitted): the
    figures, the AV table, the JSON and the page only -- no coefficients, no filter file."""
    from avbench.recordings.plan import OutputPlan

    plan = OutputPlan(Path(args.out))
    for s in sensors:
        plan.add(f"{stem}_{s.sensor}_av.png", lambda r, sensor=s.sensor: r["pngs"][sensor])
    plan.add(f"{stem}_av.csv", lambda r: r["av_table"].to_csv(index=False).encode("utf-8"))
    if fitted:
        plan.add(f"{stem}_coefficients.csv",
                 lambda r: pd.concat(dict(r["tables"]), names=["sensor"]).to_csv().encode("utf-8"))
    if args.format and fitted:
        from avbench.recordings.exports import FORMATS

        for name in args.format:
            plan.add(f"{stem}{FORMATS[name].suffix}", lambda r, name=name: r["exports"][name][1].encode("utf-8"))
    if getattr(args, "html", False):
        plan.add(f"{stem}_report.html", lambda r: r["html"].encode("utf-8"))
    if args.kalibr is not None and fitted:
        plan.add_path(args.kalibr, "--kalibr", lambda r: r["yaml"].encode("utf-8"))
    plan.add(f"{stem}_coefficients.json", lambda r: (json.dumps(r["data"], indent=2) + "\n").encode("utf-8"))
    return plan


def run(args) -> int:
    """Run ``avbench estimate`` (see the module docstring); returns the exit code."""
    from tqdm import tqdm

    from avbench.outputs import Interrupted
    from avbench.recordings import figure, filter_yaml, report
    from avbench.recordings.exports.base import not_static_lines
    from avbench.recordings.deviations import axis_deviations, check_deviations_feasible
    from avbench.recordings.fit import agreement, auto_inflation, between_runs, fit_axis, scaled_allan
    from avbench.recordings.load import load_recording, pool_recordings, reader_options_of
    from avbench.recordings.plan import output_stem
    from avbench.recordings.quality import file_lines as quality_file_lines

    methods, settings, filter_method, inflate = _check_args(args)
    progress = not args.no_progress and sys.stderr.isatty()
    loaded = [load_recording(f, progress=progress, **reader_options_of(args)) for f in args.file]
    rec = loaded[0].recording
    if len(loaded) > 1:
        timing, sensors = pool_recordings(loaded)
    else:
        timing, sensors = loaded[0].timing, loaded[0].sensors
    stem = output_stem(rec.path, args.column, len(loaded) > 1)
    if args.kalibr is not None or args.format:  # checked from the file to the fit: the yaml's needs before any fit
        filter_yaml.check_sensors([s.sensor for s in sensors], "--kalibr" if args.kalibr else "--format")
    plan = _plan(args, stem, sensors)
    inputs = [r.path for r, _, _ in loaded]
    out = plan.check(inputs)
    dt = timing.dt
    check_deviations_feasible(args.deviation, timing.n_samples, timing.starts)

    from avbench.recordings.static import static_check, verdict, what_to_do

    # the AV engine, asked once per axis: the static check, the yaml's bounds, the AV table and the figure use it
    all_avs = {s.sensor: {a: scaled_allan(x, dt, timing.starts) for a, x in s.axes.items()} for s in sensors}
    from avbench.recordings.quality import judge_record

    judged = judge_record(sensors, dt)  # what the record is, judged before the fits
    quality = judged.to_dict()
    still = static_check(sensors, dt, all_avs, judged.spikes)  # said before any fit; a spike is no motion
    fitting = still["static"] or args.fit_not_static
    if not still["static"]:
        advice = what_to_do(still, timing.n_samples * dt)
        if not args.json:
            print("# " + verdict(still) + (". The fits below assume rest: poor fits are expected." if fitting else
                                           ". " + advice[0].upper() + advice[1:] + "."), file=sys.stderr)
        if not fitting:
            plan = _plan(args, stem, sensors, fitted=False)
            out = plan.check(inputs)
            still["not_fitted"] = advice
    if fitting:
        n_fits = sum(len(s.axes) for s in sensors) * len(methods)
        with tqdm(total=n_fits, desc="fitting", unit="fit", disable=not progress, leave=False) as bar:
            fits = fit_sensors(sensors, timing, methods, settings, bar, jobs=args.jobs)
    else:
        fits = {s.sensor: {a: {} for a in s.axes} for s in sensors}
    notes = list(rec.notes) if len(loaded) == 1 else [f"{r.path.name}: {n}" for r, _, _ in loaded for n in r.notes]
    extra = {"format": rec.format, "topic": rec.topic, "time_source": rec.time_source, "notes": notes,
             "static_check": still, "record_quality": quality}
    if len(loaded) > 1 and fitting:
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
    if inflate == "auto" and fitting:
        from avbench.recordings.filter_yaml import KEYS

        inflate = {}
        for (sensor, coef), key in KEYS.items():
            per_axis = extra["between_runs"]["sensors"].get(sensor, {})
            fs_ = [auto_inflation(sp, coef) for sp in per_axis.values()]
            fs_ = [f for f in fs_ if f is not None]
            inflate[key] = max(fs_) if fs_ else 1.0
        extra["between_runs"]["inflate"] = inflate
    est = report.Estimate([r.path for r, _, _ in loaded], timing, sensors, fits, extra)

    # everything that can refuse is checked, and every output rendered, before anything is written
    yaml_text, exported = None, {}
    if fitting and (args.kalibr is not None or args.format):
        choices = filter_yaml.filter_choices(est.results(), filter_method, "--kalibr" if args.kalibr else "--format",
                                             all_avs)
        yaml_text = filter_yaml.kalibr_yaml(choices, timing.fs, rec.topic, filter_method,
                                            [r.path for r, _, _ in loaded], inflate, "kalibr",
                                            flags=quality_file_lines(quality))
        yaml_text = "".join(f"# {line}\n" for line in not_static_lines(still)) + yaml_text
        extra["filter_yaml"] = {"method": filter_method, "inflate": dict(inflate) if isinstance(inflate, dict) else list(inflate),
                               "values_si": {k: v for k, (v, _, _) in choices.items()},
                               "bounds": {k: why for k, (_, _, why) in choices.items() if why}}
    data = report.payload(est)
    tables = report.tables(est) if fitting else {}
    av_rows, figs, devs = [], {}, {}
    title = args.title if args.title is not None else rec.path.name.replace("$", r"\$")  # a file name is no mathtext
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
                devs.setdefault(s.sensor, {})[a] = axis_deviations(x, dt, timing.starts, args.deviation)
                frame.insert(0, "statistic", "oadev")
                for name, r in devs[s.sensor][a].items():
                    if r.kind == "avar":
                        continue  # oadev: the engine's rows above
                    f = r.to_frame()  # column "adev" holds the statistic's deviation
                    unit = f"{s.si_unit.split('/')[0]}" if r.kind in ("tvar", "ttotvar") else s.si_unit
                    av_rows.append(f.assign(statistic=name, sensor=s.sensor, axis=a,
                                            unit=f"variance ({unit})^2, deviation {unit}")[["statistic", *f.columns, "sensor", "axis", "unit"]])
            av_rows.append(frame)
        flags = {a: {m: f.result.fit_check.poor_fit for m, f in fits[s.sensor][a].items()} for a in s.axes}
        figs[s.sensor] = figure.figure(s, fits[s.sensor], avs, dt, title, flags, deviations=devs.get(s.sensor))
    if args.format and fitting:
        from avbench.recordings import exports

        exported = exports.render(est.results(), args.format, filter_method, timing.fs, args.filter_rate, inflate, rec.topic,
                                  [r.path for r, _, _ in loaded], avs=all_avs, flags=quality_file_lines(quality),
                                  static_check=still)
    screen = json.dumps(data) if args.json else _summary_text(est, rec, fitting)
    pngs = {k: _png(f) for k, f in figs.items()}
    results = {"pngs": pngs, "av_table": pd.concat(av_rows, ignore_index=True), "tables": tables, "data": data,
               "yaml": yaml_text, "exports": exported}
    if args.html:
        from avbench.recordings.html import recording_page

        pages = {name: (f"{stem}{suffix}", text) for name, (suffix, text) in exported.items()}
        panels = {s.sensor: {a: figure.figure(s, fits[s.sensor], all_avs[s.sensor], dt, title,
                                              {a: {m: f.result.fit_check.poor_fit for m, f in fits[s.sensor][a].items()}},
                                              deviations=devs.get(s.sensor), axes=[a]) for a in s.axes} for s in sensors}
        if fitting and args.kalibr is not None and "kalibr" not in pages:
            pages["kalibr"] = (Path(args.kalibr).name, yaml_text)
        try:
            from avbench.recordings import exports as exports_

            names = list(pages)
            values = exports_.tables(est.results(), names, filter_method, timing.fs, args.filter_rate, inflate,
                                     avs=all_avs) if names else None
            results["html"] = recording_page(est, panels, pages, title=title, tables=values)
        finally:
            import matplotlib.pyplot as plt

            for per_axis in panels.values():
                for f in per_axis.values():
                    plt.close(f)
    try:
        plan.write(results)
    except KeyboardInterrupt as e:  # SIGINT, or SIGTERM/SIGHUP (avbench.outputs.Interrupted), before the renames
        why = str(e) if isinstance(e, Interrupted) else "interrupted"
        print(f"avbench estimate: {why} before the outputs were put in place; nothing was written (the previous "
              f"outputs in {out} are unchanged)", file=sys.stderr)
        return 143 if "SIGTERM" in why else 130
    print(screen)
    print(f"avbench estimate: wrote {', '.join(o.name for o in plan.outputs)} (in {out})", file=sys.stderr)
    if not fitting:
        asked = ([f"--kalibr {args.kalibr}"] if args.kalibr is not None else []) + \
            ([f"--format {','.join(args.format)}"] if args.format else [])
        print("avbench estimate: the record is not static: nothing fitted" +
              (f", no filter file written ({'; '.join(asked)})" if asked else "") +
              "; --fit-not-static fits it anyway (exit code 3)", file=sys.stderr)
        return NOT_STATIC_EXIT
    return 0


def _say(lines: list, text: str) -> None:
    """A ``#`` line of the summary, wrapped at words to the screen's width."""
    from avbench.recordings.report import wrap

    lines.extend(wrap(text, "#   "))


def _summary_text(est, rec, fitted: bool = True) -> str:
    """The screen of ``avbench estimate``: the record, its notes, the coefficient tables with their
    footnotes (:func:`avbench.recordings.report.screen`), the fit times and the between-run checks; no
    line wider than :data:`avbench.recordings.report.SCREEN_WIDTH`. Rendered before the outputs are
    written, so that nothing the screen shows can fail after them."""
    from avbench.recordings import report

    lines: list[str] = []
    timing, fits = est.timing, est.fits
    src = ", ".join(map(str, est.sources))
    joins = int(np.isnan(timing.gap_seconds).sum())  # --combine: file boundaries
    gaps = (f", {timing.n_gaps - joins} gap(s) ({np.nansum(timing.gap_seconds):.3g} s missing)" if timing.n_gaps - joins else "") + \
        (f", {joins} file boundary(ies) treated as gaps" if joins else "")
    jit = f", jitter {timing.jitter:.2%} of dt" if timing.jitter is not None else ""
    _say(lines, f"# {src}: {timing.n_samples} samples at {timing.fs:.6g} Hz ({timing.n_samples * timing.dt / 3600:.2f} h) "
         f"from {timing.source}{jit}{gaps}" + (f"; topic {rec.topic}" if rec.topic else ""))
    for note in est.notes:
        _say(lines, f"# note: {note}")
    still = est.extra.get("static_check")
    if still is not None and not still["static"]:
        if not fitted:
            _say(lines, "# NOT STATIC: " + "; ".join(still["reasons"]))
            _say(lines, "# " + still["not_fitted"][0].upper() + still["not_fitted"][1:] + ".")
            return "\n".join(lines)
        _say(lines, "# NOT STATIC: " + "; ".join(still["reasons"]) + " -- the fits assume a sensor at rest; "
             "a POOR FIT below is expected for this reason")
    from avbench.recordings.quality import screen_lines

    lines += screen_lines(est.extra.get("record_quality"))
    lines.append(report.screen(est))
    times = [(f.seconds, f"{sensor} {axis} {name}") for sensor, per_axis in fits.items()
             for axis, per_method in per_axis.items() for name, f in per_method.items()]
    if times:
        slowest = max(times)
        _say(lines, f"# fits: {sum(t for t, _ in times):.1f} s in all; the slowest {slowest[1]} {slowest[0]:.1f} s")
    if "combine" in est.extra:
        for sensor, per_axis in est.extra["combine"].items():
            for axis, a in per_axis.items():
                verdict = "agree" if a["agree"] else ("DISAGREE" if a["agree"] is not None else "not testable")
                p = f"p = {a['p_value']:.3g}" if a["p_value"] is not None else a["note"]
                _say(lines, f"# recordings {verdict} on {sensor} {axis} ({p})")
    if "between_runs" in est.extra:
        _between_runs_text(lines, est.extra["between_runs"], est)
    return "\n".join(lines)


def _between_runs_text(lines, br, est):
    from avbench.noise_models.units import from_si

    lines.append("")
    _say(lines, f"## between-run spread ({br['method']} on each recording alone; random effects, DerSimonian & Laird 1986)")
    for sensor, per_axis in br["sensors"].items():
        for axis, per_coef in per_axis.items():
            for c, r in per_coef.items():
                if r["tau"] is None:
                    continue
                unit = est.units(sensor)[c]  # the unit of the sensor's coefficient table

                def d(v):
                    return from_si(c, v, unit, sensor)

                lo, hi = r["tau_ci"]
                pred = (f"; a new run: {d(r['prediction'][0]):.4g} to {d(r['prediction'][1]):.4g}"
                        if r["prediction"] is not None else "")
                cv = f" (CV {100 * r['cv']:.3g} %)" if r["cv"] is not None else ""
                _say(lines, f"# {sensor} {axis} {c}: mean {d(r['mean']):.4g} +- {d(r['mean_se']):.2g} {unit} over "
                     f"{r['k']} runs; between-run SD {d(r['tau']):.3g}{cv}, 95 % interval {d(lo):.3g} to {d(hi):.3g}{pred}")
    if "inflate" in br:
        _say(lines, "# --inflate auto: " + ", ".join(f"{k} x {v:.3g}" for k, v in br["inflate"].items()))
