"""The ``avbench`` command.

Examples
--------
avbench presets                                  # the gyros of the papers
avbench simulate SRS2000 --hours 4 --seed 1      # simulate one, print its Allan deviation table
avbench simulate ADIS16405_Y --hours 1 --out y.npy
avbench studies                                  # the studies shipped with avbench
avbench run lv2015 --jobs 2                      # a packaged study by name -> ./results/lv2015/
avbench run my_study.toml --jobs 2               # your own study file
avbench check-estimator my_estimator.py:MyEstimator   # does it keep the estimator contract?
avbench table results/lv2015 --latex             # re-print a finished study's table
avbench estimate rec.csv --fs 100 --units deg/s --method wls,gmwm   # your own recording
avbench deviations rec.csv --fs 100 --units deg/s  # its ADEV, HDEV, MDEV, TOTDEV, Theo1, ... with intervals
avbench plan --preset ADIS16405_X --target 10    # how long to record for ±10 % on N, B, K
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from avbench.text import empty_is_none, plain_text

# Heavy libraries (numpy, pandas, the simulators and estimators) are imported inside the commands:
# `avbench --help` and every subcommand's help must start in a fraction of a second.

__all__ = ["main", "build_parser", "reader_options_parser"]


def _fail(msg: str) -> int:
    print(f"avbench: error: {msg}", file=sys.stderr)
    return 2


# -- presets / estimators -----------------------------------------------------------------------


def cmd_presets(args) -> int:
    import numpy as np

    from avbench.noise_models import presets
    from avbench.noise_models.units import PAPER_UNITS, from_si

    for name in presets.names():
        p = presets.info(name)
        g = p.gyro()
        coefs = ", ".join(
            f"{c} = {from_si(c, v, PAPER_UNITS[c]):.4g} {PAPER_UNITS[c]}"
            for c, v in g.coefficients.items()
            if np.isfinite(v)
        )
        print(f"{name:18s} {1 / p.dt:6.0f} Hz  {p.duration_s / 3600:.0f} h  {coefs}")
        if args.verbose:
            print(f"{'':18s} source: {p.source}")
            if p.units_note:
                print(f"{'':18s} note: {p.units_note}")
    return 0


def cmd_estimators(args) -> int:
    from avbench import estimators
    for name in estimators.names():
        try:
            cls = estimators.estimator_class(name)
        except ValueError as e:  # an installed plugin that does not import: say so, list the rest
            print(f"{name:16s} (cannot be loaded: {e})")
            continue
        where = "" if cls.__module__.startswith("avbench.") else f" [{cls.__module__}:{cls.__qualname__}]"
        print(f"{name:16s} {describe(cls)}{where}")
    return 0


def cmd_check_estimator(args) -> int:
    import json

    from avbench.estimators.contract import check_estimator, load_estimators

    settings = {}
    if args.settings:
        try:
            settings = json.loads(args.settings)
        except json.JSONDecodeError as e:
            raise ValueError(f"--settings: expected a JSON object, got {args.settings!r} ({e})") from None
        if not isinstance(settings, dict):
            raise ValueError(f"--settings: expected a JSON object of settings, got {args.settings!r}")
    classes = load_estimators(args.path)
    failed = 0
    for cls in classes:
        report = check_estimator(cls, raise_on_failure=False, settings=settings)
        print(report)
        failed += not report.ok
    return 1 if failed else 0


def describe(cls) -> str:
    """The one-line description of an estimator class: its docstring's first line, as plain text."""
    lines = (cls.__doc__ or "").strip().splitlines()
    return plain_text(lines[0].strip()) if lines else ""


def _plain_help(parser: argparse.ArgumentParser) -> None:
    """Strip reST markup from every help text, description and epilog of a parser and its subcommands."""
    for attr in ("description", "epilog", "usage"):
        if getattr(parser, attr, None):
            setattr(parser, attr, plain_text(getattr(parser, attr)))
    for action in parser._actions:
        if action.help and action.help is not argparse.SUPPRESS:
            action.help = plain_text(action.help)
        if isinstance(action, argparse._SubParsersAction):
            for choice in action._choices_actions:
                if choice.help:
                    choice.help = plain_text(choice.help)
            for sub in set(action.choices.values()):
                _plain_help(sub)


# -- simulate -----------------------------------------------------------------------------------


def _n_samples(args, dt: float, default_s: float) -> int:
    import numpy as np

    given = [x is not None for x in (args.hours, args.seconds, args.samples)]
    if sum(given) > 1:
        raise ValueError("give at most one of --hours, --seconds, --samples")
    if args.samples is not None:
        n = args.samples
    else:
        seconds = args.hours * 3600 if args.hours is not None else args.seconds if args.seconds is not None else default_s
        if not np.isfinite(seconds) or seconds <= 0:
            raise ValueError(f"record length: expected a positive duration, got {seconds!r} s")
        n = int(round(seconds / dt))
    if n < 16:
        raise ValueError(f"record length: {n} samples is too short (need at least 16)")
    need = n * SIMULATE_BYTES_PER_SAMPLE
    free = _available_memory()
    if free is not None and need > free:
        raise ValueError(
            f"record length: {n:,} samples need about {need / 2**30:.1f} GiB of memory to simulate and analyse, "
            f"and {free / 2**30:.1f} GiB are available; expected a shorter record"
        )
    return n


#: bytes of memory per simulated sample: the record (8) and the Allan-variance engine's cumulative
#: sum (8) and temporaries, with a margin
SIMULATE_BYTES_PER_SAMPLE = 32


def _available_memory() -> int | None:
    """Bytes of memory available now (MemAvailable), or None where the system does not say."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


#: the accelerometer of ``avbench simulate --imu``: a MEMS accelerometer of the ADIS16405's datasheet
#: class (velocity random walk 0.2 m/s/sqrt(h), in-run bias stability 0.2 mg, an acceleration random
#: walk of 0.03 m/s^2/sqrt(h)), SI, at rest with gravity on z
IMU_ACCEL = {"N": 0.2 / 60.0, "B": 0.2e-3 * 9.80665, "K": 0.03 / 60.0}


def _write_imu_csv(path, rate, gyro, n, rng) -> None:
    """A six-axis static IMU record as a CSV with its units in the header: the first gyro axis is
    ``rate``, the other two fresh draws of the same gyro, and three accelerometer axes of
    :data:`IMU_ACCEL` with standard gravity on z."""
    import numpy as np

    from avbench.noise_models import AngleRandomWalk, BiasInstability, Gyro, RateRandomWalk

    accel = Gyro(dt=gyro.dt, terms=[AngleRandomWalk(N=IMU_ACCEL["N"]),
                                    BiasInstability(B=IMU_ACCEL["B"], tau_max=max(n * gyro.dt, 100 * gyro.dt)),
                                    RateRandomWalk(K=IMU_ACCEL["K"])])
    cols = [np.arange(n) * gyro.dt, rate, gyro.simulate(n, rng), gyro.simulate(n, rng),
            accel.simulate(n, rng), accel.simulate(n, rng), accel.simulate(n, rng) + 9.80665]
    np.savetxt(path, np.column_stack(cols), delimiter=",", fmt="%.10g", comments="",
               header="t [s],gx [rad/s],gy [rad/s],gz [rad/s],ax [m/s^2],ay [m/s^2],az [m/s^2]")


def cmd_simulate(args) -> int:
    import numpy as np

    from avbench.estimators.allan.variance import allan_variance
    from avbench.noise_models import presets
    from avbench.noise_models.units import rate_to_si

    gyro = presets.get(args.preset)
    if args.seed < 0:
        raise ValueError(f"--seed: expected a non-negative integer, got {args.seed}")
    n = _n_samples(args, gyro.dt, presets.record_seconds(args.preset))
    out = Path(args.out) if args.out else None
    if out is not None:
        from avbench.outputs import prepare_out_dir

        if out.suffix not in (".npy", ".csv"):
            raise ValueError(f"--out: expected a .npy or .csv file name, got {args.out!r}")
        prepare_out_dir(out.parent, "--out", outputs=(out.name,))
    if args.imu and (out is None or out.suffix != ".csv"):
        raise ValueError("--imu: writes a six-axis CSV; expected --out FILE.csv")
    rng = np.random.default_rng(args.seed)
    rate = gyro.simulate(n, rng)
    av = allan_variance(rate, gyro.dt, taus=args.taus, overlapping=not args.non_overlapping)
    to_unit = 1.0 / rate_to_si(1.0, args.units)
    truth = np.sqrt(gyro.avar(av.tau)) * to_unit
    print(f"# {args.preset}: {n} samples at dt = {gyro.dt} s ({n * gyro.dt / 3600:.2f} h), seed {args.seed}")
    print(f"# {'overlapping' if av.overlapping else 'non-overlapping'} Allan deviation in {args.units}; "
          f"68 % chi^2 interval; exact ADEV of the generator")
    print(f"{'tau_s':>12} {'m':>9} {'J':>9} {'adev':>12} {'ci_low':>12} {'ci_high':>12} {'exact':>12} {'ratio':>7}")
    lo, hi = np.sqrt(av.ci_low) * to_unit, np.sqrt(av.ci_high) * to_unit
    for i in range(len(av)):
        a = av.adev[i] * to_unit
        print(
            f"{av.tau[i]:12.4g} {av.m[i]:9d} {av.J[i]:9d} {a:12.5g} {lo[i]:12.5g} "
            f"{hi[i]:12.5g} {truth[i]:12.5g} {a / truth[i]:7.3f}"
        )
    if out is not None:
        from avbench.outputs import tmp_name

        tmp = tmp_name(out).with_suffix(out.suffix)
        try:
            if args.imu:
                _write_imu_csv(tmp, rate, gyro, n, rng)
            elif out.suffix == ".npy":
                np.save(tmp, rate)
            else:
                np.savetxt(tmp, rate, header=f"rate_rad_s (dt = {gyro.dt} s, preset {args.preset}, seed {args.seed})")
            tmp.replace(out)
        finally:
            tmp.unlink(missing_ok=True)
        print(f"# wrote {n} samples ({'six axes, units in the header' if args.imu else 'rad/s'}) to {out}", file=sys.stderr)
    return 0


# -- studies ------------------------------------------------------------------------------------

#: files 'avbench run' writes into its --out (figures are named per gyro)
REPORT_FILES = ("tidy.csv", "table.csv", "table.md", "leaderboard.md", "meta.json", "timings.csv", "timings.md",
                "scores.csv", "scores.md", "report.html")


def cmd_studies(args) -> int:
    from avbench.studies import packaged

    for name in packaged.names():
        print(f"{name:22s} {packaged.description(name)}")
    return 0


def cmd_run(args) -> int:
    from avbench.studies.workers import started_early

    # local workers start now and import while this process reads the config
    with started_early(args.jobs if _local_pool_wanted(args) else None) as pool:
        code = _run(args)
    if pool is not None:  # the study is written: its idle workers are stopped now, not left to wind down
        pool.shutdown(wait=True, kill_workers=True)  # at this process's exit (~0.8 s on 2 workers)
    return code


def _run(args) -> int:
    from avbench.studies import packaged
    from avbench.studies.config import load_config
    from avbench.studies.runner import run_study

    overrides = {}
    if args.replicates is not None:
        overrides["replicates"] = args.replicates
    cfg = load_config(packaged.resolve(args.config), overrides)
    out = Path(args.out) if args.out else Path("results") / cfg.name
    from avbench.outputs import folder_lock, prepare_out_dir
    from avbench.studies.figure_files import figure_names

    inputs = [("the study file", cfg.path)] if cfg.path is not None else []
    inputs += [("the study's paper_table", cfg.paper_table)] if cfg.paper_table is not None else []
    figures = [n for label in (cfg.figure_gyros or [g.label for g in cfg.gyros]) for n in figure_names(label)]
    prepare_out_dir(out, "--out", [*REPORT_FILES, *figures], inputs=inputs)
    with folder_lock(out, "--out", f"avbench run {args.config}"):  # one run per output folder
        tidy = run_study(
            cfg,
            out=out,
            n_jobs=args.jobs,
            backend=args.backend,
            scheduler=args.scheduler,
            progress=not args.no_progress,
        )
        if args.html:  # after meta.json, and not among its outputs: the page embeds the avbench version
            from avbench.outputs import atomic_write_text
            from avbench.studies.html import study_page

            atomic_write_text(out / "report.html", study_page(out))
    print(tidy.attrs["table.md"])  # this run's own table, not what the folder holds now
    print(f"# results in {out}/ (tidy.csv, table.md, table.csv, leaderboard.md, figures; fit times in timings.md)", file=sys.stderr)
    return 0


def _local_pool_wanted(args) -> bool:
    """Local workers will be needed (valid --jobs other than 1, no dask backend asked for)."""
    jobs = args.jobs
    return (
        isinstance(jobs, int)
        and (jobs > 1 or -(os.cpu_count() or 1) <= jobs <= -1)
        and args.backend in (None, "loky")
        and not args.scheduler
    )


def cmd_table(args) -> int:
    from avbench.studies.report import read_summary, render_latex, render_markdown

    from avbench.outputs import TABLE_DIGITS

    summary, meta = read_summary(args.dir)  # ValueError for a foreign, corrupt or incomplete folder
    if args.latex:
        sys.stdout.write(render_latex(summary, meta))
    elif args.csv:  # as table.csv
        sys.stdout.write(summary.to_csv(index=False, float_format=f"%.{TABLE_DIGITS}g"))
    else:  # as table.md, byte for byte
        sys.stdout.write(render_markdown(summary, meta))
    return 0


def cmd_compare(args) -> int:
    from avbench.studies.compare import compare_study, render_comparison, write_comparison

    if not 0 < args.level < 1:
        raise ValueError(f"--level: expected a number in (0, 1), got {args.level}")
    cmp = compare_study(args.dir, args.a, args.b, level=args.level)  # ValueError: a foreign folder, an unknown label
    sys.stdout.write(render_comparison(cmp, args.a, args.b, args.level))
    if args.csv:
        write_comparison(cmp, Path(args.csv))
    return 0


# -- parser -------------------------------------------------------------------------------------


def reader_options_parser() -> argparse.ArgumentParser:
    """The options that say how to read a recording, given as ``parents`` to every command that reads
    one (``estimate``, ``deviations``): one definition, so their names, defaults and help cannot drift
    apart. Their dests are the keywords of :func:`avbench.recordings.load.load_recording`
    (``READER_OPTIONS`` there); a new parser per command, as argparse shares a parent's actions."""
    p = argparse.ArgumentParser(add_help=False)
    p.add_argument("--fs", type=float, default=None,
                   help="sample rate in Hz (needed without time stamps or a rate in the file; else a check, which "
                        "also chooses between two plausible time units)")
    p.add_argument("--units", default=None, help="gyro sample units when the format does not say: rad/s, deg/s, deg/h, mrad/s")
    p.add_argument("--accel-units", default=None, help="accelerometer sample units when the format does not say: m/s^2, "
                   "g, mg, ug (else from gravity for a static three-axis accelerometer)")
    p.add_argument("--column", default=None, help="one gyro column of a table: name or 0-based index")
    p.add_argument("--gyro", default=None, help="gyro columns of a table (comma-separated names or indices), or the "
                   "gyro array(s) of an .npz/.mat by name")
    p.add_argument("--accel", default=None, help="accelerometer columns of a table, or array(s) of an .npz/.mat, comma-separated")
    p.add_argument("--time", default=None, help="time column (or .npz/.mat array) (default: one named t/time/timestamp "
                   "or with a time unit in its header; 'none' to ignore it)")
    p.add_argument("--time-units", default=None, choices=["s", "ms", "us", "ns"],
                   help="units of the time column (default: the header's [unit], else the one unit giving an IMU's "
                        "rate, 1 Hz-32 kHz; two plausible units are refused)")
    p.add_argument("--topic", default=None, help="sensor_msgs/Imu topic of a bag (default: the only one)")
    return p


#: ``avbench deviations``: the statistics drawn when --deviation is not given
DEVIATIONS_DEFAULT = "oadev,ohdev,mdev,totdev,htotdev,theo1"


def _add_deviations_parser(sub) -> None:
    """``avbench deviations FILE``: the reader options of ``avbench estimate``, then the statistics."""
    s = sub.add_parser(
        "deviations", help="the deviation family (ADEV, HDEV, MDEV, TOTDEV, Theo1, ...) of a recording, with intervals",
        description="Overlapping Allan, Hadamard, modified, time, total (plain, modified, Hadamard), Theo1 and TheoBR "
                    "deviations of every axis of a recording, each with its edf and chi^2 interval "
                    "(avbench.estimators.allan.deviations), on each axis' longest gap-free run. Writes "
                    "<stem>_deviations.csv (one row per statistic, axis and tau: the columns of avbench estimate's "
                    "<stem>_av.csv) and <stem>_<sensor>_deviations.png, and prints the deviations per axis.",
        epilog="examples:\n  avbench deviations rec.npy --fs 100 --units deg/s\n"
               "  avbench deviations imu.bag --sensor gyro --deviation oadev,ohdev,theobr --taus decade --out devs",
        formatter_class=argparse.RawDescriptionHelpFormatter, parents=[reader_options_parser()])
    s.add_argument("file", help="a recording: .npy .npz .mat .csv .txt .dat .tsv .bag .ulg or a ROS 2 bag folder")
    s.add_argument("--sensor", default=None, choices=["gyro", "accel"], help="only this sensor (default: every one in the file)")
    s.add_argument("--deviation", default=DEVIATIONS_DEFAULT, metavar="NAMES",
                   help=f"comma-separated: adev, oadev, hdev, ohdev, mdev, tdev, totdev, mtotdev, ttotdev, htotdev, "
                        f"pdev, theo1, theobr (default {DEVIATIONS_DEFAULT})")
    s.add_argument("--taus", default="octave", choices=["octave", "decade"], help="tau grid (default octave)")
    s.add_argument("--intervals", default="exact", choices=["exact", "stable32"],
                   help="exact: the edf of the statistic's filters under the AV's noise type (default); stable32: "
                        "Stable32's edf and noise identification, at its confidence factor")
    s.add_argument("--bias-corrected", action="store_true",
                   help="Stable32's bias-corrected MTOTDEV, TTOTDEV, HTOTDEV and Theo1 values")
    s.add_argument("--out", default=".", help="output folder (default: .)")
    s.add_argument("--title", default=None, type=empty_is_none,
                   help="plot title (default: the file name; --title '' for none)")
    s.add_argument("--no-progress", action="store_true", help="no progress bars")
    s.set_defaults(func=cmd_deviations)


def cmd_deviations(args) -> int:
    """``avbench deviations FILE``: read as ``avbench estimate`` reads, compute, write CSV and plot as one
    planned set of outputs (:class:`avbench.recordings.plan.OutputPlan`)."""
    import io

    import pandas as pd

    from avbench.recordings import figure
    from avbench.recordings.deviations import axis_deviations, check_deviations_feasible, parse_deviations
    from avbench.recordings.load import check_reader_options, load_recording, reader_options_of
    from avbench.recordings.plan import OutputPlan, output_stem

    from avbench.recordings.estimate import check_title

    options = reader_options_of(args)
    check_reader_options(**options)
    check_title(args.title)
    names = parse_deviations(args.deviation)
    if args.intervals == "stable32" and "pdev" in names:
        raise ValueError("--intervals stable32: Stable32 gives no PDEV interval; expected --deviation without pdev, "
                         "or --intervals exact")
    rec, timing, sensors = load_recording(args.file, progress=not args.no_progress and sys.stderr.isatty(), **options)
    sensors = [s for s in sensors if args.sensor in (None, s.sensor)]
    if not sensors:
        raise ValueError(f"--sensor {args.sensor}: {rec.path} has no {args.sensor} channels")
    check_deviations_feasible(names, timing.n_samples, timing.starts)
    stem = output_stem(rec.path, args.column)
    plan = OutputPlan(Path(args.out))
    plan.add(f"{stem}_deviations.csv", lambda r: r["table"].to_csv(index=False).encode("utf-8"))
    for s in sensors:
        plan.add(f"{stem}_{s.sensor}_deviations.png", lambda r, sensor=s.sensor: r["pngs"][sensor])
    out = plan.check([rec.path])
    title = args.title if args.title is not None else rec.path.name.replace("$", r"\$")  # a file name is no mathtext
    from tqdm import tqdm

    from avbench.recordings.deviations import longest_run, screen

    rows, figs, shown, runs = [], [], {}, {}
    bar = tqdm(total=sum(len(s.axes) for s in sensors) * len(names), desc="deviations", unit="statistic",
               disable=args.no_progress or not sys.stderr.isatty(), leave=False)
    for s in sensors:
        devs = {a: axis_deviations(x, timing.dt, timing.starts, names, args.taus, args.intervals, args.bias_corrected,
                                   bar) for a, x in s.axes.items()}
        for a, d in devs.items():
            shown[(s.sensor, a)] = d
            lo, hi = longest_run(timing.n_samples, timing.starts)
            runs[(s.sensor, a)] = hi - lo
        for a, d in devs.items():
            for name, r in d.items():
                unit = s.si_unit.split("/")[0] if r.kind in ("tvar", "ttotvar") else s.si_unit
                f = r.to_frame()  # column "adev" holds the statistic's deviation
                rows.append(f.assign(statistic=name, sensor=s.sensor, axis=a,
                                     unit=f"variance ({unit})^2, deviation {unit}")[["statistic", *f.columns, "sensor", "axis", "unit"]])
        confidence = next(iter(next(iter(devs.values())).values())).confidence
        figs.append((s.sensor, figure.deviations_figure(s.sensor, s.si_unit, devs, title, confidence)))
    bar.close()
    table = pd.concat(rows, ignore_index=True).assign(note="")
    skipped = [{"sensor": c.sensor, "axis": c.axis or c.name, "note": note} for c in rec.channels
               for note in rec.notes if note.startswith(f"{c.sensor} {c.name}: ") and note.endswith("skipped")
               and args.sensor in (None, c.sensor)]
    if skipped:  # an axis left out is said in the CSV too: a row of its own, no statistic
        table = pd.concat([table, pd.DataFrame(skipped)], ignore_index=True)

    import matplotlib.pyplot as plt

    pngs = {}
    for sensor, fig in figs:
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=110, bbox_inches="tight")
        plt.close(fig)
        pngs[sensor] = buf.getvalue()
    plan.write({"table": table, "pngs": pngs})
    print(screen(shown, runs, f"# {rec.path.name}: {timing.n_samples} samples at {1 / timing.dt:.6g} Hz; deviations on "
                 "each axis' longest gap-free run, SI units (TDEV and TTOTDEV in rad or m/s); each cell: the deviation "
                 "[its chi^2 interval]; each value's edf is in the CSV"
                 + ("; Stable32's intervals" if args.intervals == "stable32" else "")
                 + ("; bias-corrected where Stable32 corrects" if args.bias_corrected else "")))
    from avbench.recordings.report import wrap

    for note in rec.notes:
        print("\n".join(wrap(f"# note: {note}", "#   ")))
    print(f"\n# wrote {', '.join(plan.names)} in {out}")
    return 0


def _add_hat_parser(sub) -> None:
    """``avbench three-cornered-hat A B C``: each unit's own deviation from three recordings made together."""
    s = sub.add_parser(
        "three-cornered-hat", help="each of three sensors' own deviation from three recordings made together",
        description="The three-cornered hat: three units recorded side by side (three gyros on one table) see the "
                    "same motion; the pairwise differences cancel it, and each unit's own variance follows from the "
                    "three pairwise variances (avbench.recordings.hat). The records are put on the instants all three have (by "
                    "their time stamps; without stamps their first samples are one instant) and the same axis is "
                    "read in each. A negative estimate (a unit too quiet to be "
                    "seen beside the others at that tau) is kept, with an upper bound. Writes <stem>_hat.csv (one row "
                    "per unit and tau) and prints each unit's deviation.",
        epilog="example:\n  avbench three-cornered-hat a.csv b.csv c.csv --units deg/s --sensor gyro --axis z",
        formatter_class=argparse.RawDescriptionHelpFormatter, parents=[reader_options_parser()])
    s.add_argument("files", nargs=3, metavar="FILE", help="three recordings of the same instants and rate")
    s.add_argument("--sensor", default=None, choices=["gyro", "accel"], help="the sensor (default: the first)")
    s.add_argument("--axis", default=None, help="the axis (default: the first, e.g. x)")
    s.add_argument("--deviation", default="oadev", choices=["oadev", "mdev", "ohdev", "totdev"],
                   help="the statistic of each pair (default oadev)")
    s.add_argument("--taus", default="octave", choices=["octave", "decade"], help="tau grid (default octave)")
    s.add_argument("--confidence", type=float, default=0.683, help="interval level (default 0.683, one sigma)")
    s.add_argument("--out", default=".", help="output folder (default: .)")
    s.set_defaults(func=cmd_hat)


def cmd_hat(args) -> int:
    import pandas as pd

    from avbench.recordings.hat import hat_of_recordings, hat_table
    from avbench.recordings.load import check_reader_options, reader_options_of
    from avbench.recordings.plan import OutputPlan, output_stem

    if not 0 < args.confidence < 1:
        raise ValueError(f"--confidence: expected a level between 0 and 1, got {args.confidence}")
    options = reader_options_of(args)
    check_reader_options(**options)
    name = f"{output_stem(args.files[0])}_hat.csv"
    plan = OutputPlan(Path(args.out))
    plan.add(name, lambda table: table.to_csv(index=False).encode("utf-8"))
    out = plan.check(args.files)  # never over an input, before any reading
    run = hat_of_recordings(args.files, sensor=args.sensor, axis=args.axis, kind=args.deviation,
                            taus=args.taus, confidence=args.confidence, **options)
    hat, labels = run.hat, run.labels
    table = hat_table(hat, run.sensor_record, labels)
    plan.write(table)
    from avbench.recordings.report import wrap

    print("\n".join(wrap(f"# three-cornered hat of {run.sensor_record.sensor} {run.axis} ({args.deviation}, "
                          f"{hat.n_samples} samples at {1 / run.dt:.6g} Hz): each unit's own deviation in "
                          f"{run.sensor_record.si_unit}; '< x': not seen beside the other two, x its upper bound; "
                          "'negative': below zero beyond its error bar (the noises are not independent, or a unit "
                          "is far quieter)", "#   ")))
    for note in run.notes:
        print("\n".join(wrap(f"# note: {note}", "#   ")))
    wide = table.assign(shown=[f"{d:.4g}" if not neg else (f"< {u:.3g}" if u > 0 else "negative")
                               for d, u, neg in zip(table["deviation"], table["upper_dev"], table["negative"])])
    with pd.option_context("display.width", 100):
        print(wide.pivot_table(index="tau", columns="unit", values="shown", aggfunc="first", sort=True)[labels]
              .to_string())
    print(f"# wrote {name} in {out}")
    return 0


#: the one-line help of ``avbench estimate`` in the list of commands (as in avbench.recordings.estimate.add_parser)
ESTIMATE_HELP = "fit the noise coefficients of a static IMU recording"


def _command(argv) -> str | None:
    """The subcommand named in ``argv`` (its first positional word), if any."""
    return next((a for a in argv if not a.startswith("-")), None)


def build_parser(argv=None) -> argparse.ArgumentParser:
    """The ``avbench`` parser; given ``argv``, commands other than the one it names are only listed."""
    p = argparse.ArgumentParser(
        prog="avbench",
        description=(
            "Benchmark estimators of gyro Allan-variance noise coefficients (Q, N, B, K, R) on "
            "simulated gyros whose coefficients are known exactly."
        ),
        epilog=__doc__.split("Examples\n--------\n", 1)[1],
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    sub = p.add_subparsers(dest="command", metavar="COMMAND")

    s = sub.add_parser("presets", help="list the papers' gyros")
    s.add_argument("-v", "--verbose", action="store_true", help="also print each preset's source and unit notes")
    s.set_defaults(func=cmd_presets)

    s = sub.add_parser("estimators", help="list the registered estimators")
    s.set_defaults(func=cmd_estimators)

    s = sub.add_parser("simulate", help="simulate a preset gyro and print its Allan deviation table")
    s.add_argument("preset", help="preset name (see 'avbench presets')")
    s.add_argument("--hours", type=float, help="record length in hours (default: the paper's)")
    s.add_argument("--seconds", type=float, help="record length in seconds")
    s.add_argument("--samples", type=int, help="record length in samples")
    s.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    s.add_argument("--taus", default="octave", choices=["octave", "decade", "all"], help="tau grid (default octave)")
    s.add_argument("--non-overlapping", action="store_true", help="non-overlapping AV (default: overlapping)")
    s.add_argument("--units", default="deg/h", choices=["rad/s", "deg/s", "deg/h"], help="ADEV units (default deg/h)")
    s.add_argument("--out", help="also write the samples (rad/s) to FILE.npy or FILE.csv")
    s.add_argument("--imu", action="store_true",
                   help="with --out FILE.csv: a six-axis static IMU record instead (three gyro axes of the preset, "
                        "three accelerometer axes of a MEMS accelerometer with gravity on z; units in the header)")
    s.set_defaults(func=cmd_simulate)

    s = sub.add_parser("check-estimator", help="check an estimator against the estimator contract")
    s.add_argument(
        "path",
        help="a registered name (wls), an import path (my_pkg.my_module:MyEstimator), "
        "FILE.py:Class, or FILE.py (every estimator defined in it)",
    )
    s.add_argument("--settings", help='settings as a JSON object, e.g. \'{"terms": "NK"}\' (default: the defaults)')
    s.set_defaults(func=cmd_check_estimator)

    s = sub.add_parser("studies", help="list the studies shipped with avbench (run one by name)")
    s.set_defaults(func=cmd_studies)

    s = sub.add_parser("run", help="run a Monte Carlo study from a TOML config")
    s.add_argument("config", help="study TOML file, or the name of a packaged study (see 'avbench studies')")
    s.add_argument("--jobs", "-j", type=int, default=1, help="parallel workers (default 1; -1 = all cores)")
    s.add_argument("--out", help="output folder (default results/<study name>)")
    s.add_argument("--backend", choices=["loky", "dask"], help="execution backend (default: the config's, else loky)")
    s.add_argument("--scheduler", help="dask scheduler address tcp://HOST:PORT (backend dask)")
    s.add_argument("--replicates", type=int, help="override the number of replicates")
    s.add_argument("--no-progress", action="store_true", help="no progress bar")
    s.add_argument("--html", action="store_true",
                   help="also write report.html: the table, leaderboard, scores and figures on one self-contained page")
    s.set_defaults(func=cmd_run)

    s = sub.add_parser("table", help="re-print a finished study's table")
    s.add_argument("dir", help="a study's output folder")
    g = s.add_mutually_exclusive_group()
    g.add_argument("--latex", action="store_true", help="LaTeX")
    g.add_argument("--csv", action="store_true", help="CSV")
    s.set_defaults(func=cmd_table)

    s = sub.add_parser("compare", help="compare two estimators of a finished study, paired over its replicates")
    s.add_argument("dir", help="a study's output folder")
    s.add_argument("a", help="an estimator label of the study (A)")
    s.add_argument("b", help="another estimator label (B)")
    s.add_argument("--level", type=float, default=0.05, help="family-wise level of the verdicts (default 0.05)")
    s.add_argument("--csv", help="also write the comparison as CSV to this file")
    s.set_defaults(func=cmd_compare)

    if argv is None or _command(argv) == "estimate":
        from avbench.recordings import estimate  # imports numpy and pandas: only when its parser is needed

        estimate.add_parser(sub, parents=[reader_options_parser()])
    else:  # the same entry in the list of commands, without importing it
        sub.add_parser("estimate", help=ESTIMATE_HELP)
    _add_deviations_parser(sub)
    _add_hat_parser(sub)
    from avbench.studies import plan_report  # numpy is imported only when the command runs

    plan_report.add_parser(sub, parents=[reader_options_parser()])
    try:
        import avbench.bench.__main__ as bench_main
        bench_main.add_parser(sub)
    except (ImportError, AttributeError):
        pass
    _plain_help(p)
    return p


#: the commands that write a set of files into the folder ``--out`` (``run`` locks its folder itself, in
#: :func:`avbench.studies.runner.run_study`, which also creates it)
WRITES_INTO_OUT = ("estimate", "deviations", "three-cornered-hat")


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    parser = build_parser(argv)
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 0
    empty = _empty_values(parser, args)
    if empty:
        return _fail(f"{empty}: expected a value, got an empty string")
    try:
        if args.command in WRITES_INTO_OUT:  # one writer per output folder, a new one included
            from avbench.outputs import locked_new_folder

            with locked_new_folder(args.out, "--out", " ".join(["avbench", *argv])[:200]):
                return int(args.func(args) or 0)
        return int(args.func(args) or 0)
    except BrokenPipeError:  # the reader went away (e.g. '| head'): not an error of ours
        try:
            sys.stdout = open(os.devnull, "w")
        except OSError:
            pass
        return 0
    except (ValueError, OSError) as e:  # bad input, an unreadable or unwritable path: one line, exit 2
        return _fail(_one_line(e))
    except MemoryError:
        return _fail("out of memory; use a shorter record or fewer replicates per block")
    except RecursionError:
        return _fail("input nested too deeply to read")
    except Exception as e:
        from avbench.studies.runner import StudyError

        if isinstance(e, StudyError):  # workers kept dying, cluster unreachable, ...: no traceback
            return _fail(str(e))
        raise
    except KeyboardInterrupt:
        print("avbench: interrupted; finished blocks are saved, rerun the same command to resume", file=sys.stderr)
        return 130


def _empty_values(parser: argparse.ArgumentParser, args) -> str | None:
    """The first option or argument of the command given as an empty (or blank) string, as its name in
    the usage (``--format``, ``FILE``): every command refuses them alike, before any work, except an
    option typed :func:`empty_is_none` (an empty value there asks for none)."""
    command = next(sub.choices[args.command] for sub in parser._subparsers._group_actions)
    for a in command._actions:
        if a.type is empty_is_none:
            continue
        value = getattr(args, a.dest, None)
        if any(isinstance(v, str) and not v.strip() for v in (value if isinstance(value, list) else [value])):
            return max(a.option_strings, key=len) if a.option_strings else (a.metavar or a.dest)
    return None


def _one_line(e: BaseException) -> str:
    """An exception as the one line a user reads; OSErrors name the path and the system's reason."""
    if isinstance(e, OSError) and e.filename is not None and e.strerror:
        return f"{e.filename}: {e.strerror}"
    return str(e) if str(e) else type(e).__name__


if __name__ == "__main__":
    sys.exit(main())
