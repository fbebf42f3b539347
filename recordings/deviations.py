"""The deviation family (:mod:`avbench.estimators.allan.deviations`) on a recording's axes, for
``avbench deviations`` and ``avbench estimate --deviation``: each axis on its longest gap-free run,
the cost capped by :data:`DEVIATION_BUDGET`; the screen of ``avbench deviations`` (:func:`screen`):
each statistic's value with its interval, and where and why each statistic stops (:func:`stop_reason`).
"""

from __future__ import annotations

import numpy as np

__all__ = ["DEVIATION_BUDGET", "parse_deviations", "longest_run", "check_deviations_feasible", "axis_deviations",
           "stop_reason", "screen"]

#: the deviations' cluster sizes stop where the terms summed reach this (Theo1 costs (N - m) m / 2 per tau)
DEVIATION_BUDGET = 5e9


def parse_deviations(spec) -> list[str] | None:
    """--deviation: a list of the deviation family's names (None when not given)."""
    if spec is None:
        return None
    from avbench.estimators.allan.deviations import DEVIATION_NAMES

    names = [n.strip() for n in str(spec).split(",") if n.strip()]
    bad = [n for n in names if n not in DEVIATION_NAMES]
    if bad or not names:
        raise ValueError(f"--deviation: expected names among {', '.join(DEVIATION_NAMES)}, got {spec!r}")
    return names


def longest_run(n, starts) -> tuple[int, int]:
    """(start, stop) of the longest gap-free run of a record of ``n`` samples."""
    edges = np.concatenate(([0], np.asarray(starts, dtype=np.int64), [n]))
    k = int(np.argmax(np.diff(edges)))
    return int(edges[k]), int(edges[k + 1])


def check_deviations_feasible(names, n, starts) -> None:
    """--deviation: refuse, before any fit, a statistic the longest run is too long for (TheoBR)."""
    if names:
        from avbench.estimators.allan.deviations import check_feasible

        a, b = longest_run(n, starts)
        try:
            check_feasible(names, b - a)
        except ValueError as e:
            raise ValueError(f"--deviation: {e}") from None


def axis_deviations(x, dt, starts, names, taus="octave", intervals="exact", bias_corrected=False,
                    progress=None) -> dict:
    """{name: AllanResult} of one axis on its longest gap-free run (cost capped by DEVIATION_BUDGET terms);
    ``intervals`` and ``bias_corrected`` as :func:`avbench.estimators.allan.deviations.deviation` takes
    them (Stable32's intervals and bias-corrected values; PDEV has no Stable32 interval: its exact one);
    ``progress``: a tqdm bar (or None) advanced once per statistic."""
    from avbench.estimators.allan.deviations import deviation

    a, b = longest_run(len(x), starts)
    run = np.asarray(x[a:b], dtype=float)
    out = {}
    for name in names:
        kw = {}
        if intervals != "exact" and name != "pdev":
            kw["intervals"] = intervals
        if bias_corrected:
            kw["bias_corrected"] = bias_corrected
        out[name] = deviation(run, dt, name, taus, max_terms=DEVIATION_BUDGET, **kw)
        if progress is not None:
            progress.update(1)
    return out


def stop_reason(name: str, result, n_run: int, budget: float = DEVIATION_BUDGET) -> str:
    """Why statistic ``name`` stops at its last tau on a run of ``n_run`` samples (``result``: its AllanResult):
    the next tau of its grid would take the cost past ``budget`` terms
    (:func:`avbench.estimators.allan.deviations.terms_per_tau`), or the statistic's own definition allows no
    longer tau on this run."""
    from avbench.estimators.allan.deviations import DEVIATION_NAMES, terms_per_tau

    m = np.asarray(result.m, dtype=np.int64)
    tau = float(result.tau[-1])
    step = m[-1] / m[-2] if m.size > 1 else 2.0
    nxt = int(round(m[-1] * step))
    cost = float(np.sum(terms_per_tau(DEVIATION_NAMES[name], np.r_[m, nxt], n_run + 1)))
    if cost > budget:
        return (f"{name} stops at {tau:.3g} s: its next tau ({nxt * result.dt:.3g} s) would take it past "
                f"{budget:.3g} terms summed (the cost cap of avbench's deviations)")
    return f"{name} stops at {tau:.3g} s: the longest tau its definition allows on a run of {n_run} samples"


def _cell(dev: float, lo: float, hi: float) -> str:
    return f"{dev:.4g} [{lo:.3g}, {hi:.3g}]" if np.isfinite(dev) else "-"


def screen(devs: dict, n_runs: dict, header: str) -> str:
    """The screen of ``avbench deviations``: ``header`` (wrapped), then per sensor and axis a table -- a row
    per tau, a column per statistic, each cell the deviation and its interval (the results' confidence)
    -- and a line per statistic saying where and why it stops (:func:`stop_reason`). ``devs``:
    ``{(sensor, axis): {name: AllanResult}}``; ``n_runs``: ``{(sensor, axis): samples of the run used}``."""
    import pandas as pd

    from avbench.recordings.report import SCREEN_WIDTH, wrap

    lines = wrap(header, "#   ")
    for (sensor, axis), per_name in devs.items():
        lines += ["", f"## {sensor} {axis}"]
        groups: dict = {}  # statistics on the same taus share a table (Theo1's are 0.75 m dt)
        for name, r in per_name.items():
            groups.setdefault(tuple(float(f"{t:.4g}") for t in r.tau), []).append(name)
        for taus, group in groups.items():
            cols = {}
            for name in group:
                r = per_name[name]
                dev = np.sqrt(np.asarray(r.avar, float))
                lo, hi = np.sqrt(np.clip(r.ci_low, 0, None)), np.sqrt(np.clip(r.ci_high, 0, None))
                cols[f"{name} [{100 * r.confidence:.3g} %]"] = [_cell(*v) for v in zip(dev, lo, hi)]
            wide = pd.DataFrame(cols, index=pd.Index(taus, name="tau (s)"))
            lines += wide.to_string(na_rep="-", line_width=SCREEN_WIDTH).splitlines() + [""]
        for name, r in per_name.items():
            lines += wrap("# " + stop_reason(name, r, n_runs[(sensor, axis)]), "#   ")
    return "\n".join(lines)
