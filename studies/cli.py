"""The ``avbench`` command.

Examples
--------
avbench presets                                  # the gyros of the papers
avbench simulate SRS2000 --hours 4 --seed 1      # simulate one, print its Allan deviation table
avbench simulate ADIS16405_Y --hours 1 --out y.npy
avbench run studies/lv2015.toml --jobs 2         # a Monte Carlo study -> results/lv2015/
avbench table results/lv2015 --latex             # re-print a finished study's table
avbench estimate rec.csv --fs 100 --units deg/s --method wls,gmwm   # your own recording
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

# Heavy libraries (numpy, pandas, the simulators and estimators) are imported inside the commands:
# `avbench --help` and every subcommand's help must start in a fraction of a second.

__all__ = ["main", "build_parser"]


def _fail(msg: str) -> int:
    print(f"avbench: error: {msg}", file=sys.stderr)
    return 2


# -- presets / estimators -----------------------------------------------------------------------


def cmd_presets(args) -> int:
    import numpy as np

    from noise_models import presets
    from noise_models.units import PAPER_UNITS, from_si

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
    import estimators

    for name in estimators.names():
        cls = estimators.estimator_class(name)
        doc = (cls.__doc__ or "").strip().splitlines()[0] if cls.__doc__ else ""
        print(f"{name:16s} {doc}")
    return 0


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
    return n


def cmd_simulate(args) -> int:
    import numpy as np

    from estimators.allan import allan_variance
    from noise_models import presets
    from noise_models.units import rate_to_si

    gyro = presets.get(args.preset)
    n = _n_samples(args, gyro.dt, presets.record_seconds(args.preset))
    out = Path(args.out) if args.out else None
    if out is not None and out.suffix not in (".npy", ".csv"):
        raise ValueError(f"--out: expected a .npy or .csv file name, got {args.out!r}")
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
        out.parent.mkdir(parents=True, exist_ok=True)
        tmp = out.with_name(out.name + ".tmp" + out.suffix)
        if out.suffix == ".npy":
            np.save(tmp, rate)
        else:
            np.savetxt(tmp, rate, header=f"rate_rad_s (dt = {gyro.dt} s, preset {args.preset}, seed {args.seed})")
        tmp.replace(out)
        print(f"# wrote {n} samples (rad/s) to {out}", file=sys.stderr)
    return 0


# -- studies ------------------------------------------------------------------------------------


def cmd_run(args) -> int:
    from studies.workers import started_early

    # local workers start now and import while this process reads the config
    with started_early(args.jobs if _local_pool_wanted(args) else None):
        return _run(args)


def _run(args) -> int:
    from studies.config import load_config
    from studies.runner import run_study

    overrides = {}
    if args.replicates is not None:
        overrides["replicates"] = args.replicates
    cfg = load_config(args.config, overrides)
    out = Path(args.out) if args.out else Path("results") / cfg.name
    run_study(
        cfg,
        out=out,
        n_jobs=args.jobs,
        backend=args.backend,
        scheduler=args.scheduler,
        progress=not args.no_progress,
    )
    print((out / "table.md").read_text())
    print(f"# results in {out}/ (tidy.parquet, table.md, table.csv, figures)", file=sys.stderr)
    return 0


def _local_pool_wanted(args) -> bool:
    """Local workers will be needed (valid --jobs other than 1, no dask backend asked for)."""
    import os

    jobs = args.jobs
    return (
        isinstance(jobs, int)
        and (jobs > 1 or -(os.cpu_count() or 1) <= jobs <= -1)
        and args.backend in (None, "loky")
        and not args.scheduler
    )


def cmd_table(args) -> int:
    import json

    import pandas as pd

    from studies.report import render_latex, render_markdown

    d = Path(args.dir)
    if not (d / "table.csv").is_file():
        raise ValueError(f"{d}: no table.csv here; expected the output folder of 'avbench run'")
    summary = pd.read_csv(d / "table.csv")
    meta = json.loads((d / "meta.json").read_text()) if (d / "meta.json").is_file() else {}
    if args.latex:
        print(render_latex(summary))
    elif args.csv:
        print(summary.to_csv(index=False))
    else:
        print(render_markdown(summary, meta))
    return 0


# -- parser -------------------------------------------------------------------------------------


def build_parser() -> argparse.ArgumentParser:
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
    s.set_defaults(func=cmd_simulate)

    s = sub.add_parser("run", help="run a Monte Carlo study from a TOML config")
    s.add_argument("config", help="study TOML file (e.g. studies/lv2015.toml)")
    s.add_argument("--jobs", "-j", type=int, default=1, help="parallel workers (default 1; -1 = all cores)")
    s.add_argument("--out", help="output folder (default results/<study name>)")
    s.add_argument("--backend", choices=["loky", "dask"], help="execution backend (default: the config's, else loky)")
    s.add_argument("--scheduler", help="dask scheduler address tcp://HOST:PORT (backend dask)")
    s.add_argument("--replicates", type=int, help="override the number of replicates")
    s.add_argument("--no-progress", action="store_true", help="no progress bar")
    s.set_defaults(func=cmd_run)

    s = sub.add_parser("table", help="re-print a finished study's table")
    s.add_argument("dir", help="a study's output folder")
    g = s.add_mutually_exclusive_group()
    g.add_argument("--latex", action="store_true", help="LaTeX")
    g.add_argument("--csv", action="store_true", help="CSV")
    s.set_defaults(func=cmd_table)

    try:
        from studies import estimate

        estimate.add_parser(sub)
    except ImportError:
        pass
    try:
        import bench.__main__ as bench_main

        bench_main.add_parser(sub)
    except (ImportError, AttributeError):
        pass
    return p


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 0
    try:
        return int(args.func(args) or 0)
    except (ValueError, FileNotFoundError) as e:
        return _fail(str(e))
    except Exception as e:
        from studies.runner import StudyError

        if isinstance(e, StudyError):  # workers kept dying, cluster unreachable, ...: no traceback
            return _fail(str(e))
        raise
    except KeyboardInterrupt:
        print("avbench: interrupted; finished blocks are saved, rerun the same command to resume", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
