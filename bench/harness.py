"""A small asv-style runner: parameterised benchmark classes, medians, same-run baselines.

A benchmark class has asv's shape -- ``params`` (a list of value lists), ``param_names``,
``setup(*p)`` (raise ``NotImplementedError`` to skip a combination), ``time_*``, ``peakmem_*``,
``track_*`` methods -- plus three things of ours:

``quick_params``
    the parameter lists of the ``--quick`` run (tiny sizes, for CI; no timing claims);
``baselines``
    ``{"time_x": ("baseline_x", "what the baseline is")}``: the baseline method is timed in the same
    loop as the benchmark, alternating with it, so both see the same machine load; the row carries
    both medians and their ratio baseline / ours (> 1: ours is faster);
``budget_s``
    if one run of a ``time_*`` method takes longer than this, larger ``n`` (the last parameter) are
    skipped for the same other parameters ("as far as time allows").

``peakmem_*`` methods return a dict (they measure in a child process themselves); ``track_*``
methods return a number or a dict.
"""

from __future__ import annotations

import itertools
import math
import os
import platform
import sys
import time
from dataclasses import dataclass, field

import numpy as np

__all__ = ["Case", "run_class", "machine_info", "median_times", "load_cases"]


@dataclass
class Case:
    """One benchmark method at one parameter combination."""

    benchmark: str
    method: str
    params: dict
    kind: str  # "time", "peakmem", "track"
    result: dict = field(default_factory=dict)

    def as_row(self) -> dict:
        return {"benchmark": self.benchmark, "method": self.method, "kind": self.kind, **{f"param_{k}": v for k, v in self.params.items()}, **self.result}


def median_times(fns, repeats: int, budget_s: float = float("inf")) -> list[list[float]]:
    """Wall times of each function in ``fns``, run alternately ``repeats`` times.

    Stops after the first round if any function took longer than ``budget_s``.
    """
    times: list[list[float]] = [[] for _ in fns]
    for r in range(repeats):
        for i, fn in enumerate(fns):
            t0 = time.perf_counter()
            fn()
            times[i].append(time.perf_counter() - t0)
        if r == 0 and max(t[0] for t in times) > budget_s:
            break
    return times


def _grid(cls, quick: bool):
    params = getattr(cls, "quick_params", None) if quick else None
    params = params if params is not None else getattr(cls, "params", [[]])
    if params and not isinstance(params[0], list | tuple):
        params = [params]
    names = list(getattr(cls, "param_names", [f"p{i}" for i in range(len(params))]))
    return names, list(itertools.product(*params)) if params else [()]


def run_class(cls, quick: bool = False, log=print) -> list[Case]:
    """Run every ``time_*``, ``peakmem_*`` and ``track_*`` method of ``cls`` over its grid."""
    names, grid = _grid(cls, quick)
    repeats = getattr(cls, "quick_repeats", 2) if quick else getattr(cls, "repeats", 5)
    budget = getattr(cls, "budget_s", float("inf"))
    baselines = getattr(cls, "baselines", {})
    methods = [m for m in sorted(dir(cls)) if m.split("_")[0] in ("time", "peakmem", "track")]
    cases: list[Case] = []
    over_budget: set = set()
    last_time: dict = {}  # (method, other params) -> (n, seconds of one run)
    for p in grid:
        bench = cls()
        pd_ = dict(zip(names, p))
        others = tuple(v for k, v in pd_.items() if k != "n")
        n = pd_.get("n")
        wanted = [m for m in methods if (m, others) not in over_budget and not _predicted_over(last_time.get((m, others)), n, budget)]
        if not wanted:
            continue
        try:
            bench.setup(*p)
        except NotImplementedError:
            continue
        try:
            for m in wanted:
                kind = m.split("_")[0]
                case = Case(cls.__name__, m, pd_, kind)
                t0 = time.perf_counter()
                if kind == "time":
                    fns = [lambda m=m: getattr(bench, m)(*p)]
                    base = baselines.get(m)
                    if base is not None and getattr(bench, base[0] + "_available", lambda *a: True)(*p):
                        fns.append(lambda b=base[0]: getattr(bench, b)(*p))
                    reps = bench.repeats_for(*p) if hasattr(bench, "repeats_for") and not quick else repeats
                    times = median_times(fns, reps, budget)
                    if n is not None:
                        last_time[(m, others)] = (n, float(np.min(times[0])))
                    case.result = {"median_s": float(np.median(times[0])), "min_s": float(np.min(times[0])), "repeats": len(times[0])}
                    if len(fns) > 1:
                        tb = float(np.median(times[1]))
                        case.result.update({"baseline": base[1], "baseline_median_s": tb, "ratio": tb / case.result["median_s"]})
                    if max(times[0]) > budget:
                        over_budget.add((m, others))
                elif kind == "peakmem":
                    case.result = dict(getattr(bench, m)(*p))
                else:
                    v = getattr(bench, m)(*p)
                    case.result = dict(v) if isinstance(v, dict) else {"value": float(v)}
                cases.append(case)
                log(f"  {cls.__name__}.{m} {pd_}: {_short(case.result)}  ({time.perf_counter() - t0:.1f} s)")
        finally:
            teardown = getattr(bench, "teardown", None)
            if teardown is not None:
                teardown(*p)
    return cases


def _predicted_over(last, n, budget) -> bool:
    """Skip a larger n when linear extrapolation from the last size predicts > 4x the budget."""
    if last is None or n is None or not math.isfinite(budget):
        return False
    n0, t0 = last
    return t0 * n / n0 > 4 * budget


def _short(result: dict) -> str:
    parts = []
    for k in ("median_s", "baseline_median_s", "ratio", "peak_rss_mb", "value"):
        if k in result:
            parts.append(f"{k}={result[k]:.4g}")
    return " ".join(parts) or str(result)[:120]


def machine_info() -> dict:
    """What the figures depend on: CPU count, load, library versions, BLAS/numba threading."""
    import numba
    import scipy

    try:
        load = os.getloadavg()
    except OSError:  # pragma: no cover
        load = (float("nan"),) * 3
    info = {
        "when": time.strftime("%Y-%m-%d %H:%M:%S %Z"),
        "python": sys.version.split()[0],
        "platform": platform.platform(),
        "processor": platform.processor() or platform.machine(),
        "cpu_count": os.cpu_count(),
        "loadavg_1_5_15": [round(x, 2) for x in load],
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "numba": numba.__version__,
        "numba_threads": numba.get_num_threads(),
    }
    for var in ("OPENBLAS_CORETYPE", "OPENBLAS_L2_SIZE", "OMP_NUM_THREADS", "NUMBA_NUM_THREADS"):
        if os.environ.get(var):
            info[var] = os.environ[var]
    try:
        import allantools

        info["allantools"] = getattr(allantools, "__version__", "?")
    except ImportError:  # pragma: no cover
        pass
    return info


def load_cases(path, exclude=frozenset()) -> list[Case]:
    """The cases of an earlier run's results.json (flat rows back to Case), minus ``exclude``d classes."""
    import json
    from pathlib import Path

    path = Path(path)
    if not path.is_file():
        return []
    cases = []
    for row in json.loads(path.read_text())["cases"]:
        if row["benchmark"] in exclude:
            continue
        params = {k[6:]: v for k, v in row.items() if k.startswith("param_") and v is not None}
        result = {k: v for k, v in row.items() if not k.startswith("param_") and k not in ("benchmark", "method", "kind") and v is not None}
        cases.append(Case(row["benchmark"], row["method"], params, row["kind"], result))
    return cases


def run_history(payload: dict) -> list[dict]:
    """The runs whose figures a results.json holds: when, load, which benchmarks (oldest first)."""
    m = payload.get("machine", {})
    if m.get("runs"):
        return list(m["runs"])
    runs = []
    if m.get("earlier_run"):
        e = m["earlier_run"]
        runs.append({"when": e.get("when"), "loadavg_1_5_15": e.get("loadavg_1_5_15"), "benchmarks": ["all"]})
        runs.append({"when": m.get("when"), "loadavg_1_5_15": m.get("loadavg_1_5_15"), "benchmarks": m.get("rerun", [])})
    else:
        runs.append({"when": m.get("when"), "loadavg_1_5_15": m.get("loadavg_1_5_15"), "benchmarks": ["all"]})
    return runs
