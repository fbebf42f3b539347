"""``avbench plan``: how long to record, printed per coefficient, with the figure of precision against length.

The gyro comes from a preset (``--preset``), from datasheet numbers (``--N "0.15 deg/sqrt(h)" --B "5 deg/h"
--K "2 deg/h^1.5" --rate 200``), or from a short pilot record (``--pilot rec.csv`` with the reader options of
``avbench estimate``). :mod:`avbench.studies.planner` does the arithmetic; this module reads the command line
and renders the plan. It imports numpy only when the command runs, so ``avbench --help`` stays light.
"""

from __future__ import annotations

__all__ = ["add_parser", "run"]

HELP = "how long to record: the record length at which each coefficient is known to ±X %%"

_DATASHEET = (("Q", "urad"), ("N", "deg/sqrt(h)"), ("B", "deg/h"), ("K", "deg/h^1.5"))


def add_parser(sub, parents=()):
    s = sub.add_parser("plan", help=HELP, parents=list(parents), description=(
        "The record length at which each coefficient's 95 % interval is within ±TARGET % of its value: the "
        "Cramér-Rao bound of the exact model at that length, times the recommended estimator's measured "
        "efficiency (whittle_debiased on 200 gyros drawn outside the presets). Give a preset, datasheet "
        "coefficients with their units, or a short pilot record."))
    src = s.add_mutually_exclusive_group()
    src.add_argument("--preset", help="a preset gyro (see 'avbench presets')")
    src.add_argument("--pilot", metavar="FILE", help="a short static record: its fitted coefficients are planned for "
                                                      "(read as 'avbench estimate' reads it)")
    for c, unit in _DATASHEET:
        s.add_argument(f"--{c}", metavar="'VALUE UNIT'",
                       help=f"datasheet {c} with its unit (e.g. '1.2 {unit}'; a bare number is in {unit})")
    s.add_argument("--rate", type=float, help="sample rate in Hz of the record to plan (datasheet numbers: required; "
                                              "a preset or pilot: default its own)")
    s.add_argument("--target", type=float, default=10.0, help="the precision wanted, ± percent at 95 %% (default 10)")
    s.add_argument("--coefficients", help="plan for these coefficients only, comma-separated (default: every one present)")
    s.add_argument("--duration", help="also print the precision a record of this length gives (e.g. 2h, 30min)")
    s.add_argument("--check", type=int, nargs="?", const=40, default=None, metavar="RECORDS",
                   help="simulate RECORDS records (default 40) of the planned length, fit them, and report the share "
                        "within the target")
    s.add_argument("--seed", type=int, default=0, help="seed of --check's records (default 0)")
    s.add_argument("--jobs", "-j", type=int, default=1, help="parallel workers for --check (default 1)")
    s.add_argument("--figure", metavar="FILE.png", help="write the figure of precision against record length")
    s.set_defaults(func=run)
    return s


def _quantity(c: str, text: str, unit: str) -> float:
    from avbench.noise_models.units import to_si, units_for

    parts = str(text).replace(",", " ").split(None, 1)
    try:
        value = float(parts[0])
    except (ValueError, IndexError):
        raise ValueError(f"--{c}: expected a number and a unit, e.g. '1.2 {unit}', got {text!r}") from None
    given = parts[1].strip() if len(parts) > 1 else unit
    if given not in units_for(c):
        raise ValueError(f"--{c}: unknown unit {given!r}: expected one of {', '.join(units_for(c))}")
    if not value > 0:
        raise ValueError(f"--{c}: expected a positive value, got {text!r}")
    return to_si(c, value, given)


def _gyros(args):
    """[(label, gyro, notes)] from the command line."""
    from avbench.noise_models import presets
    from avbench.noise_models.gyro import Gyro

    datasheet = {c: getattr(args, c) for c, _ in _DATASHEET if getattr(args, c) is not None}
    if args.preset is not None:
        if datasheet:
            raise ValueError("--preset: give a preset or datasheet coefficients, not both")
        g = presets.get(args.preset)
        if args.rate is not None:
            g = Gyro(dt=1.0 / args.rate, terms=g.terms, name=g.name)
        return [(args.preset, g, [])]
    if args.pilot is not None:
        if datasheet:
            raise ValueError("--pilot: give a pilot record or datasheet coefficients, not both")
        from avbench.recordings.load import reader_options_of
        from avbench.studies.planner import gyros_from_pilot

        out = []
        for a in gyros_from_pilot(args.pilot, **reader_options_of(args)):
            notes = [f"{c} not resolved by the pilot" + (f" (below {_shown(c, ub, a.sensor)})" if ub else "")
                     + ": record longer, or give its datasheet value" for c, ub in a.unresolved.items()]
            if a.gyro is not None and args.rate is not None:
                a = type(a)(a.sensor, a.axis, Gyro(dt=1.0 / args.rate, terms=a.gyro.terms, name=a.gyro.name),
                            a.unresolved)
            out.append((f"{a.sensor} {a.axis}", a.gyro, notes))
        return out
    if not datasheet:
        raise ValueError("plan: give --preset NAME, --pilot FILE, or datasheet coefficients (--N, --B, --K, --Q) "
                         "with --rate")
    if args.rate is None or not args.rate > 0:
        raise ValueError("--rate: datasheet coefficients need the sample rate of the record to plan, in Hz")
    coefs = {c: _quantity(c, v, dict(_DATASHEET)[c]) for c, v in datasheet.items()}
    return [("datasheet", Gyro.from_coefficients(coefs, 1.0 / args.rate), [])]


def _shown(c, v, sensor="gyro"):
    from avbench.noise_models.units import DISPLAY_UNITS, from_si

    unit = DISPLAY_UNITS[sensor][c]
    return f"{from_si(c, v, unit, sensor):.3g} {unit}"


def run(args) -> int:
    import math

    from avbench.studies import planner

    if not (0.0 < args.target < 100.0):
        raise ValueError(f"--target: expected a percentage between 0 and 100, got {args.target!r}")
    duration = planner.parse_duration(args.duration) if args.duration is not None else None
    target = args.target / 100.0
    plans = []
    for label, gyro, notes in _gyros(args):
        sensor = "accel" if label.startswith("accel") else "gyro"
        print(f"# {label}: {gyro.name or ''} at {1 / gyro.dt:.6g} Hz" if gyro is not None else f"# {label}")
        for n in notes:
            print(f"#   {n}")
        if gyro is None:
            print("#   no coefficient to plan for")
            continue
        wanted = None
        if args.coefficients is not None:
            wanted = [c.strip() for c in args.coefficients.split(",") if c.strip()]
            if not wanted:
                raise ValueError("--coefficients: expected a comma-separated list such as N,B")
        p = planner.plan(gyro, target, wanted)
        plans.append((label, p))
        print(f"#   each coefficient within ±{args.target:g} % at 95 % by {planner.RECOMMENDED} "
              f"(Cramér-Rao bound x its measured efficiency)")
        head = f"  {'coef':4s}  {'value':>22s}  {'record length':>14s}  {'samples':>12s}"
        if duration is not None:
            head += f"  {'±% at ' + planner.format_duration(duration):>14s}"
        print(head)
        at = planner.precision_at(gyro, max(2, round(duration / gyro.dt)), p.coefficients) if duration else {}
        for c in p.coefficients:
            line = (f"  {c:4s}  {_shown(c, gyro.coefficients[c], sensor):>22s}  "
                    f"{_length(p, c):>14s}  "
                    f"{p.samples[c]:12.4g}")
            if duration is not None:
                line += f"  {100 * at[c]:13.3g}%"
            print(line)
        note = " (extrapolated past the bound's exact range)" if any(p.extrapolated.values()) else ""
        print(f"#   record at least {planner.format_duration(p.record_samples * p.dt)} "
              f"({p.longest} needs the longest){note}")
        if args.check is not None:
            n = p.record_samples
            if n > planner.N_EXACT:
                print(f"#   --check: the planned record ({n:.3g} samples) is too long to simulate here; skipped")
                continue
            res = planner.check_plan(p, records=args.check, seed=args.seed, jobs=args.jobs, progress=True)
            for c in p.coefficients:
                lo, hi = res.interval[c]
                failed = f", {res.failed[c]} not resolved" if res.failed[c] else ""
                print(f"#   check {c}: {res.met[c]}/{res.records} records within ±{args.target:g} % "
                      f"({100 * res.share(c):.0f} %, 95 % interval {100 * lo:.0f}-{100 * hi:.0f} %{failed})")
    if args.figure and plans:
        _figure(plans, target, args.figure)
        print(f"# wrote {args.figure}")
    return 0 if plans else 2


def _length(p, c) -> str:
    """The planned length as printed: ``~`` where extrapolated, ``<=`` where the shortest length planned already
    meets the target."""
    from avbench.studies import planner

    mark = "~" if p.extrapolated[c] else ("<= " if p.samples[c] <= planner.N_MIN else "")
    return mark + planner.format_duration(p.seconds(c))


def _figure(plans, target, path) -> None:
    """Relative precision (95 % half-width) against record length, one panel per plan, the target and each
    coefficient's planned length marked; written atomically as a PNG."""
    import io

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    from avbench.outputs import atomic_write_bytes
    from avbench.studies import planner

    fig, axes = plt.subplots(1, len(plans), figsize=(6.0 * len(plans), 4.2), squeeze=False)
    for ax, (label, p) in zip(axes[0], plans):
        hours = p.curve.index.to_numpy(float) * p.dt / 3600.0
        for c in p.coefficients:
            line, = ax.loglog(hours, 100 * p.curve[c].to_numpy(float), marker="o", ms=3, label=c)
            ax.axvline(p.seconds(c) / 3600.0, color=line.get_color(), ls=":", lw=1)
        ax.axhline(100 * target, color="k", lw=1, ls="--", label=f"±{100 * target:g} %")
        ax.set_xlabel("record length (h)")
        ax.set_ylabel("95 % interval half-width (% of the value)")
        ax.set_title(f"{label}: {planner.RECOMMENDED}", fontsize=10)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=9)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    plt.close(fig)
    atomic_write_bytes(path, buf.getvalue())
