"""Two estimators of one study compared on the same replicates, with a verdict that holds its level.

For every gyro x coefficient both estimate (a coefficient of the gyro, true value > 0), on the
replicates of the study (each simulated once and fitted by both: a paired design):

* ``n_bad_a`` / ``n_bad_b``: replicates where each gave no physical estimate (non-physical or failed).
  They are counted on both sides and never dropped from one side only: the error statistics use the
  ``n_pairs`` replicates where both gave one, and a side with more such fits cannot be the verdict's
  winner (it is "mixed" instead);
* ``rmse_a``, ``rmse_b`` and ``ratio`` = RMSE_a / RMSE_b over those pairs, with a percentile bootstrap
  interval (replicates resampled with their pair, Efron & Tibshirani 1993, Ch. 13);
* ``bias_a``, ``bias_b`` (signed: mean estimate - true) and ``bias_diff`` = bias_a - bias_b with its
  bootstrap interval, in the table's unit (``unit``);
* ``p``, ``p_holm``, ``detectable_ratio`` and ``verdict``: the paired test of :mod:`avbench.studies.paired`
  (a sign-flip permutation test of the RMSE ratio, Holm's step over all the gyro x coefficient
  comparisons of the call, so the chance of declaring any winner between identical estimators is at
  most ``level``).

``compare_study(folder, a, b)`` reads a finished study folder (its ``tidy.csv`` and ``meta.json``).
Resampling uses ``numpy.random.default_rng(seed)``: the result is a function of the rows and the seed.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd

from avbench.noise_models.units import COEFFICIENTS, PAPER_UNITS
from avbench.studies.paired import COLUMNS, N_BOOT, cell_arrays, judge_family, pair_row

__all__ = ["compare", "compare_study", "render_comparison", "write_comparison"]


def _check_labels(tidy: pd.DataFrame, names) -> None:
    known = set(tidy["estimator"])
    for e in names:
        if e not in known:
            raise ValueError(f"estimator {e!r} is not in this study; expected one of {sorted(known)}")


def compare(tidy: pd.DataFrame, a: str, b: str, units: dict | None = None, level: float = 0.05,
            n_boot: int = N_BOOT, seed: int = 0) -> pd.DataFrame:
    """One row per gyro x coefficient that ``a`` and ``b`` both estimate (module docstring); errors in
    the papers' units (``units`` overrides per coefficient, as a study's ``[study] units``)."""
    units = {**PAPER_UNITS, **(units or {})}
    _check_labels(tidy, (a, b))
    if a == b:
        raise ValueError(f"compare two different estimators, got {a!r} twice")
    rng = np.random.default_rng(seed)
    rows = []
    d = tidy[tidy["estimator"].isin([a, b])]
    for (g, c), dd in d.groupby(["gyro", "coefficient"], sort=False):
        true = float(dd["true"].iloc[0])
        if np.isfinite(true) and true > 0 and set(dd["estimator"]) == {a, b}:
            rows.append(pair_row(cell_arrays(dd, (a, b)), a, b, g, c, true, units[c], rng, n_boot))
    if not rows:
        return pd.DataFrame(columns=COLUMNS)
    out = judge_family(rows, level)
    order = {c: i for i, c in enumerate(COEFFICIENTS)}
    gorder = {g: i for i, g in enumerate(dict.fromkeys(tidy["gyro"]))}
    out = out.assign(_g=out["gyro"].map(gorder), _o=out["coefficient"].map(order))
    out = out.sort_values(["_g", "_o"], kind="stable")
    return out[COLUMNS].reset_index(drop=True)


def compare_study(folder, a: str, b: str, level: float = 0.05, seed: int = 0) -> pd.DataFrame:
    """:func:`compare` on a finished study folder (rows in the config's gyro order, its units)."""
    from avbench.studies.report import check_report, read_tidy

    meta = check_report(folder)
    tidy = read_tidy(folder)
    gyros = list(meta.get("gyros", {}))
    if gyros:
        rank = {g: i for i, g in enumerate(gyros)}
        tidy = tidy.sort_values("gyro", key=lambda s: s.map(rank).fillna(len(rank)), kind="stable")
    return compare(tidy, a, b, meta.get("units"), level=level, seed=seed)


def _f(x, digits=4) -> str:
    return "–" if x is None or (isinstance(x, float) and not math.isfinite(x)) else f"{x:.{digits}g}"


def render_comparison(cmp: pd.DataFrame, a: str, b: str, level: float = 0.05) -> str:
    """Markdown: one row per gyro x coefficient, then what the columns mean."""
    lines = [f"# {a} (A) against {b} (B)", "",
             "| gyro | coef. | unit | pairs | no estimate A / B | RMSE A | RMSE B | RMSE A / B [95 % CI] | "
             "bias A | bias B | bias A − B [95 % CI] | p (Holm) | detectable ratio | verdict |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for _, r in cmp.iterrows():
        lines.append(
            f"| {r['gyro']} | {r['coefficient']} | {r['unit']} | {r['n_pairs']} of {r['n']} | "
            f"{r['n_bad_a']} / {r['n_bad_b']} | {_f(r['rmse_a'])} | {_f(r['rmse_b'])} | "
            f"{_f(r['ratio'], 3)} [{_f(r['ratio_lo'], 3)}, {_f(r['ratio_hi'], 3)}] | {_f(r['bias_a'])} | "
            f"{_f(r['bias_b'])} | {_f(r['bias_diff'])} [{_f(r['bias_diff_lo'])}, {_f(r['bias_diff_hi'])}] | "
            f"{_f(r['p'], 2)} ({_f(r['p_holm'], 2)}) | {_f(r['detectable_ratio'], 3)} | {r['verdict']} |")
    n = int(np.isfinite(cmp["p"]).sum()) if len(cmp) else 0
    lines += ["", f"Errors are estimate − true (signed), over the replicates where both gave a physical estimate "
              f"('pairs'); 'no estimate' counts each side's non-physical or failed fits. p: sign-flip "
              f"permutation test of the RMSE ratio (exact for exchangeable errors); Holm-adjusted over the {n} "
              f"comparisons, verdict at level {level:g}: the side with the lower RMSE wins only with p (Holm) < "
              f"{level:g} and no more replicates without an estimate ('mixed' otherwise). Detectable ratio: the "
              "RMSE ratio found with 80 % power at the first Holm step ('–': too few replicates to reach it)."]
    return "\n".join(lines) + "\n"


def write_comparison(cmp: pd.DataFrame, path: Path) -> None:
    """The comparison as CSV (6 significant digits; ``unit`` names the errors' and biases' unit)."""
    from avbench.outputs import TABLE_DIGITS, atomic_write_text

    atomic_write_text(Path(path), cmp.to_csv(index=False, float_format=f"%.{TABLE_DIGITS}g"))
