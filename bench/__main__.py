"""``python -m avbench.bench [--quick] [--out DIR]`` (also ``avbench bench ...``).

Runs the benchmark classes of :mod:`avbench.bench.suite` and writes README.md (targets, tables, notes),
results.json, results.csv and scaling.png under ``--out``: by default ``results/bench`` for a full
run, and a new temporary folder for ``--quick`` (tiny sizes, about a minute; the CI smoke test, its
figures make no claims), so a smoke run never overwrites the committed benchmark unless asked to
with an explicit ``--out``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

__all__ = ["add_parser", "run", "main", "output_folder"]

#: where a full run writes (the committed benchmark)
FULL_OUT = "results/bench"


def output_folder(args) -> Path:
    """``--out`` if given; else a new temporary folder for ``--quick``, and ``results/bench`` for a
    full run (or ``--report-only``, which rewrites it)."""
    if getattr(args, "out", None):
        return Path(args.out)
    if args.quick and not getattr(args, "report_only", False):
        import tempfile

        return Path(tempfile.mkdtemp(prefix="avbench-bench-quick-"))
    return Path(FULL_OUT)


def _arguments(p: argparse.ArgumentParser) -> argparse.ArgumentParser:
    p.add_argument("--quick", action="store_true", help="tiny sizes, < 1 minute (smoke test; no timing claims)")
    p.add_argument("--out", help=f"output folder (default {FULL_OUT} for a full run, a new temporary folder for --quick)")
    p.add_argument("--only", help="comma-separated benchmark class names to run (default: all)")
    p.add_argument("--notes", help="a Markdown file whose text is added as the README's diary, after the tables "
                                   "(default: notes.md in the output folder, if there is one)")
    p.add_argument("--report-only", action="store_true",
                   help="rewrite README.md, results.csv and scaling.png from --out/results.json; run nothing")
    p.add_argument("--merge", action="store_true",
                   help="keep the other benchmarks' results already in --out/results.json (with --only)")
    return p


def add_parser(sub) -> None:
    """Register the ``bench`` subcommand on an argparse subparsers object (used by ``avbench``)."""
    p = sub.add_parser("bench", help="run the performance benchmarks (python -m avbench.bench)",
                       description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    _arguments(p)
    p.set_defaults(func=run)


def _notes(args) -> str:
    """The text of ``--notes``, else of ``notes.md`` in the output folder (kept beside the results, so
    that a re-run or ``--report-only`` keeps the notes of earlier runs), else nothing."""
    path = Path(args.notes) if getattr(args, "notes", None) else Path(args.out) / "notes.md"
    return path.read_text() if getattr(args, "notes", None) or path.is_file() else ""


def run(args) -> int:
    from avbench.bench import harness, report, suite

    args.out = str(output_folder(args))
    from avbench.outputs import prepare_out_dir

    outputs = ["README.md", "results.csv", "scaling.png"] + ([] if getattr(args, "report_only", False) else ["results.json"])
    prepare_out_dir(args.out, "--out", outputs, inputs=[("the --notes file", args.notes)] if args.notes else [])
    if getattr(args, "report_only", False):
        import json

        prev = json.loads((Path(args.out) / "results.json").read_text())
        cases = harness.load_cases(Path(args.out) / "results.json")
        report.write_outputs(cases, prev["machine"], Path(args.out), prev["quick"], prev["seconds"], _notes(args),
                             json_out=False)
        print(f"rewrote {args.out}/README.md, results.csv, scaling.png")
        return 0
    t0 = time.perf_counter()
    chosen = suite.classes(args.quick)
    if getattr(args, "only", None):
        names = {s.strip() for s in args.only.split(",")}
        chosen = [c for c in chosen if c.__name__ in names]
    cases = []
    for cls in chosen:
        print(f"{cls.__name__}", flush=True)
        cases += harness.run_class(cls, quick=args.quick, log=lambda s: print(s, flush=True))
    machine = harness.machine_info()
    if getattr(args, "merge", False):
        old = Path(args.out) / "results.json"
        kept = harness.load_cases(old, exclude={c.__name__ for c in chosen})
        if kept:
            import json

            prev = json.loads(old.read_text())
            machine["runs"] = harness.run_history(prev) + [
                {"when": machine["when"], "loadavg_1_5_15": machine["loadavg_1_5_15"],
                 "benchmarks": sorted(c.__name__ for c in chosen)}]
        cases = kept + cases
    payload = report.write_outputs(cases, machine, Path(args.out), args.quick, time.perf_counter() - t0, _notes(args))
    for t in payload["targets"]:
        print(f"{t['target']}: {t['measured']} (met: {t['met']})")
    print(f"wrote {args.out}/README.md, results.json, results.csv, scaling.png")
    return 0


def main(argv=None) -> int:
    from avbench.text import plain_text

    p = _arguments(argparse.ArgumentParser(prog="python -m avbench.bench", description=plain_text(__doc__),
                                           formatter_class=argparse.RawDescriptionHelpFormatter))
    return run(p.parse_args(argv))


if __name__ == "__main__":
    sys.exit(main())
