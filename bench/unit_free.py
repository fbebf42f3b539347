"""Whether ``avbench estimate``'s default methods give the same answer in any unit a record is handed in, on
the corpus of records users bring (:data:`avbench.bench.real_e2e.CASES`).

Each record is read as the command reads it (:func:`avbench.recordings.load.load_recording`, the case's
units and rate) and each axis fitted as the command fits it (:func:`avbench.recordings.fit.fit_axis`: the
default methods with their shared choices, on one thread), once in SI and once multiplied by each factor of
:data:`UNITS`; the fitted model's AV at the record's octave taus, divided back by the factor squared, is
compared with the SI fit's. :func:`largest_unit_move` is the largest difference over the taus and factors as
a share of the record's own AV there; an answer that does not depend on the unit keeps it within
:data:`TARGET` (round-off of the input moves it by ~1e-12; a fit whose end point depends on the last bits of
the record, by far more). The records answered not static are fitted anyway (as ``--fit-not-static``), the
question being the fit's.

``python -m avbench.bench.unit_free [CASE ...] [--out DIR]`` prints one row per record, axis and method and
writes ``unit_free.csv`` and ``unit_free.md`` (the finding first) in ``DIR`` (default ``results/bench``); a
real-data case needs ``$AVBENCH_REAL_DATA`` and is skipped without it.
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
from pathlib import Path

import numpy as np

__all__ = ["UNITS", "TARGET", "largest_unit_move", "measure_case", "main"]

#: the factors a record is handed in besides SI: degrees, thousandths, and a power of two (exact in binary)
UNITS = (180 / math.pi, 1e3, 2.0**-30)
#: the largest move of the fitted AV, as a share of the record's, that counts as the same answer
TARGET = 1e-6

#: the cases fitted: every case of the corpus whose record is a sensor at rest or fitted anyway (the flight
#: log and the 2-minute smoke record are answered without a fit)
CASES = ("consumer_10min_100Hz", "consumer_53min_rounded", "consumer_1h_100Hz", "adis_1h_100Hz",
         "consumer_2h_400Hz", "adis_stitched_2h_400Hz", "consumer_1h_100Hz_motion_fit")


def largest_unit_move(x, dt, starts=None, methods=None, units=UNITS) -> dict:
    """Per method, the largest ``|AV_c / c^2 - AV_1|`` over the octave taus of record ``x`` (sampled every
    ``dt`` s, segments starting at ``starts``) and the factors ``c`` of ``units``, as a share of the record's
    AV there; the methods fitted as ``avbench estimate`` fits an axis (default: its default methods).

    >>> x = np.random.default_rng(0).standard_normal(20_000) * 1e-3
    >>> moves = largest_unit_move(x, 0.01, methods=("gmwm",))
    >>> bool(moves["gmwm"] <= TARGET)
    True
    """
    from avbench.estimators.allan.variance import allan_variance
    from avbench.estimators.base import DEFAULT_METHODS
    from avbench.recordings.fit import fit_axis
    from avbench.recordings.fit_pool import one_thread

    methods = tuple(methods or DEFAULT_METHODS)
    starts = np.array([], dtype=np.int64) if starts is None else np.asarray(starts, dtype=np.int64)
    own = allan_variance(x, dt, taus="octave")
    base, worst = None, {}
    for c in (1.0, *units):
        with one_thread():
            fits = fit_axis(x * c, dt, starts, methods)
        av = {name: fit.result.model_avar(own.tau) / c**2 for name, fit in fits.items()}
        if base is None:
            base = av
            continue
        for name in av:
            worst[name] = max(worst.get(name, 0.0), float(np.max(np.abs(av[name] - base[name]) / own.avar)))
    return worst


def measure_case(case: str, folder: Path) -> list[dict]:
    """One row per axis and default method of the case's record: ``case``, ``channel``, ``method``,
    ``largest_move`` and ``same`` (within :data:`TARGET`)."""
    from avbench.bench.real_e2e import _write
    from avbench.cli import reader_options_parser
    from avbench.recordings.load import load_recording, reader_options_of

    path, options = _write(case, folder / f"{case}.npz")
    # the case's reader options read as the command reads them (its other options concern the fit's outputs)
    reader, _ = reader_options_parser().parse_known_args(options)
    rec = load_recording(path, **reader_options_of(reader))
    rows = []
    for sensor in rec.sensors:
        for axis, x in sensor.axes.items():
            moves = largest_unit_move(np.asarray(x, dtype=np.float64), rec.timing.dt, rec.timing.starts)
            for method, move in moves.items():
                rows.append({"case": case, "channel": f"{sensor.sensor} {axis}", "method": method,
                             "largest_move": move, "same": bool(move <= TARGET)})
                print(f"{case} {sensor.sensor} {axis} {method}: {move:.2g}", flush=True)
    return rows


def _markdown(df) -> str:
    worst = df.groupby("case", sort=False)["largest_move"].max()
    same = df.groupby("case", sort=False)["same"].all()
    lines = [f"# The same answer in every unit (x180/pi, x1e3, x2^-30; target <= {TARGET:g} of the record's AV)", "",
             f"**{int(same.sum())} of {same.size} records** give every default method's answer within the target on "
             f"every axis; {int(df['same'].sum())} of {len(df)} axis-methods.", "",
             "| record | largest move | every axis within the target |", "|---|---|---|"]
    lines += [f"| {c} | {worst[c]:.2g} | {'yes' if same[c] else '**no**'} |" for c in worst.index]
    lines += ["", "| record | channel | method | largest move |", "|---|---|---|---|"]
    lines += [f"| {r.case} | {r.channel} | {r.method} | {r.largest_move:.2g} |" for r in df.itertuples()]
    lines += ["", "`python -m avbench.bench.unit_free` (module docstring: how it is measured)."]
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    import pandas as pd

    from avbench.bench.real_e2e import available

    p = argparse.ArgumentParser(prog="python -m avbench.bench.unit_free", description=__doc__.split("\n\n")[0])
    p.add_argument("cases", nargs="*", help=f"cases of the corpus (default: {', '.join(CASES)})")
    p.add_argument("--out", default="results/bench", help="output folder (default results/bench)")
    args = p.parse_args(argv)
    cases = args.cases or list(CASES)
    unknown = [c for c in cases if c not in CASES]
    if unknown:
        p.error(f"unknown case(s) {', '.join(unknown)}: expected any of {', '.join(CASES)}")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for case in cases:
            if not available(case):
                print(f"{case}: skipped (needs $AVBENCH_REAL_DATA)", flush=True)
                continue
            rows += measure_case(case, Path(tmp))
    df = pd.DataFrame(rows, columns=["case", "channel", "method", "largest_move", "same"])
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    df.to_csv(out / "unit_free.csv", index=False, float_format="%.3g")
    (out / "unit_free.md").write_text(_markdown(df))
    print(f"wrote {out}/unit_free.csv, unit_free.md")
    return 0


if __name__ == "__main__":
    sys.exit(main())
