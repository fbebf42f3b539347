"""The deviation family (:mod:`avbench.estimators.allan.deviations`) on a recording's axes, for
``avbench deviations`` and ``avbench estimate --deviation``: each axis on its longest gap-free run,
the cost capped by :data:`DEVIATION_BUDGET`.
"""

from __future__ import annotations

import numpy as np

__all__ = ["DEVIATION_BUDGET", "parse_deviations", "longest_run", "check_deviations_feasible", "axis_deviations"]

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


def axis_deviations(x, dt, starts, names, taus="octave", intervals="exact", bias_corrected=False) -> dict:
    """{name: AllanResult} of one axis on its longest gap-free run (cost capped by DEVIATION_BUDGET terms);
    ``intervals`` and ``bias_corrected`` as :func:`avbench.estimators.allan.deviations.deviation` takes
    them (Stable32's intervals and bias-corrected values; PDEV has no Stable32 interval: its exact one)."""
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
    return out
