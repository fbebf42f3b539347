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
* ``p``: the sign-flip permutation p-value of log(ratio) (A and B swapped within random pairs): exact
  when the two estimators' errors are exchangeable -- two identical estimators -- whatever their
  distribution; ``p_holm``: Holm's step-down adjustment over all the gyro x coefficient comparisons
  of the call, so the chance of declaring any winner between identical estimators is at most ``level``;
* ``detectable_ratio``: the RMSE ratio (< 1) found with 80 % power at the Holm level of the first step
  (``level`` / comparisons), from the bootstrap spread of log(ratio); NaN when the replicate count
  cannot reach that level at all (a sign-flip test of n pairs has no p below 2 / 2^n);
* ``verdict``: "A" or "B" (the lower RMSE, ``p_holm`` < ``level``, and no more replicates without a
  physical estimate than the other), "mixed" (a significant ratio for the side with more such
  replicates), "tie", or "too few" (fewer than 3 pairs).

``compare_study(folder, a, b)`` reads a finished study folder (its ``tidy.csv`` and ``meta.json``).
Resampling uses ``numpy.random.default_rng(seed)``: the result is a function of the rows and the seed.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd

from avbench.noise_models.units import COEFFICIENTS, PAPER_UNITS, from_si

__all__ = ["compare", "compare_study", "holm", "sign_flip_p", "render_comparison", "N_BOOT", "N_PERM"]

N_BOOT = 2000
N_PERM = 4000
#: power at which ``detectable_ratio`` is found
POWER = 0.8
COLUMNS = ["gyro", "coefficient", "unit", "n", "n_pairs", "n_bad_a", "n_bad_b", "rmse_a", "rmse_b", "ratio",
           "ratio_lo", "ratio_hi", "bias_a", "bias_b", "bias_diff", "bias_diff_lo", "bias_diff_hi", "p", "p_holm",
           "detectable_ratio", "verdict"]


def holm(p) -> np.ndarray:
    """Holm's (1979) step-down adjusted p-values (NaN kept as NaN, not counted)."""
    p = np.asarray(p, float)
    out = np.full(p.shape, np.nan)
    ok = np.flatnonzero(np.isfinite(p))
    m = ok.size
    if not m:
        return out
    order = ok[np.argsort(p[ok], kind="stable")]
    adj = np.maximum.accumulate((m - np.arange(m)) * p[order])
    out[order] = np.minimum(adj, 1.0)
    return out


def _log_ratio(sa: np.ndarray, sb: np.ndarray) -> np.ndarray:
    with np.errstate(divide="ignore", invalid="ignore"):
        return 0.5 * (np.log(sa.mean(axis=-1)) - np.log(sb.mean(axis=-1)))


def sign_flip_p(sa: np.ndarray, sb: np.ndarray, n_perm: int = N_PERM, rng=None) -> float:
    """Two-sided p-value of log(RMSE_a / RMSE_b) = 0 from the squared errors ``sa``, ``sb`` of the same
    replicates: each pair swapped with probability 1/2 (all 2^n swaps when n <= 12), p = share of
    swaps whose |log ratio| reaches the observed one (the observed counted: never 0)."""
    n = sa.size
    t = abs(float(_log_ratio(sa, sb)))
    if n <= 12:
        flips = ((np.arange(2 ** n)[:, None] >> np.arange(n)) & 1).astype(bool)
        extra = 0
    else:
        rng = rng if rng is not None else np.random.default_rng(0)
        flips = rng.random((n_perm, n)) < 0.5
        extra = 1
    a = np.where(flips, sb, sa)
    b = np.where(flips, sa, sb)
    stat = np.abs(_log_ratio(a, b))
    hits = int(np.sum(stat >= t * (1 - 1e-12)))
    return (hits + extra) / (flips.shape[0] + extra)


def _physical(d: pd.DataFrame) -> pd.Series:
    return (d["failure"] == "") & ~d["nonphysical"] & np.isfinite(d["estimate"])


def compare(tidy: pd.DataFrame, a: str, b: str, units: dict | None = None, level: float = 0.05,
            n_boot: int = N_BOOT, n_perm: int = N_PERM, seed: int = 0) -> pd.DataFrame:
    """One row per gyro x coefficient that ``a`` and ``b`` both estimate (module docstring); errors in
    the papers' units (``units`` overrides per coefficient, as a study's ``[study] units``)."""
    from scipy.stats import norm

    units = {**PAPER_UNITS, **(units or {})}
    known = set(tidy["estimator"])
    for e in (a, b):
        if e not in known:
            raise ValueError(f"estimator {e!r} is not in this study; expected one of {sorted(known)}")
    if a == b:
        raise ValueError(f"compare two different estimators, got {a!r} twice")
    rng = np.random.default_rng(seed)
    rows = []
    d = tidy[tidy["estimator"].isin([a, b])]
    for (g, c), dd in d.groupby(["gyro", "coefficient"], sort=False):
        true = float(dd["true"].iloc[0])
        if not (np.isfinite(true) and true > 0) or set(dd["estimator"]) != {a, b}:
            continue
        u = units[c]
        side = {e: x.set_index("replicate") for e, x in dd.groupby("estimator")}
        reps = side[a].index.union(side[b].index)
        ok = {e: _physical(side[e]).reindex(reps, fill_value=False) for e in (a, b)}
        both = reps[(ok[a] & ok[b]).to_numpy()]
        err = {e: from_si(c, side[e].loc[both, "estimate"].to_numpy(float), u) - from_si(c, true, u) for e in (a, b)}
        row = {"gyro": g, "coefficient": c, "unit": u, "n": len(reps), "n_pairs": len(both),
               "n_bad_a": int((~ok[a]).sum()), "n_bad_b": int((~ok[b]).sum())}
        nan = dict.fromkeys(COLUMNS[7:-1], math.nan)
        if len(both) < 3:
            rows.append({**row, **nan, "verdict": "too few"})
            continue
        sa, sb = err[a] ** 2, err[b] ** 2
        idx = rng.integers(0, len(both), size=(n_boot, len(both)))
        lr = _log_ratio(sa[idx], sb[idx])
        lr = lr[np.isfinite(lr)]
        bd = err[a][idx].mean(axis=1) - err[b][idx].mean(axis=1)
        q = [(1 - 0.95) / 2, (1 + 0.95) / 2]
        lo, hi = np.exp(np.quantile(lr, q)) if lr.size >= n_boot // 2 else (math.nan, math.nan)
        reach = 2.0 ** (1 - len(both)) if len(both) <= 12 else 1 / (n_perm + 1)
        rows.append({**row, "rmse_a": math.sqrt(sa.mean()), "rmse_b": math.sqrt(sb.mean()),
                     "ratio": math.exp(float(_log_ratio(sa, sb))), "ratio_lo": float(lo), "ratio_hi": float(hi),
                     "bias_a": float(err[a].mean()), "bias_b": float(err[b].mean()),
                     "bias_diff": float(err[a].mean() - err[b].mean()),
                     "bias_diff_lo": float(np.quantile(bd, q[0])), "bias_diff_hi": float(np.quantile(bd, q[1])),
                     "p": sign_flip_p(sa, sb, n_perm, rng), "_se": float(np.std(lr, ddof=1)) if lr.size > 1 else math.nan,
                     "_reach": reach})
    out = pd.DataFrame(rows)
    if out.empty:
        return pd.DataFrame(columns=COLUMNS)
    for col in ("_se", "_reach", "p"):
        if col not in out:
            out[col] = math.nan
    out["p_holm"] = holm(out["p"])
    family = int(np.isfinite(out["p"]).sum())
    alpha1 = level / max(family, 1)
    z = norm.ppf(1 - alpha1 / 2) + norm.ppf(POWER)
    out["detectable_ratio"] = np.where(out["_reach"] <= alpha1, np.exp(-z * out["_se"]), math.nan)
    verdicts = []
    for _, r in out.iterrows():
        if r.get("verdict") == "too few":
            verdicts.append("too few")
            continue
        if not r["p_holm"] < level:
            verdicts.append("tie")
            continue
        lower, other = ("A", "B") if r["ratio"] < 1 else ("B", "A")
        bad = {"A": r["n_bad_a"], "B": r["n_bad_b"]}
        verdicts.append(lower if bad[lower] <= bad[other] else "mixed")
    out["verdict"] = verdicts
    order = {c: i for i, c in enumerate(COEFFICIENTS)}
    out["_o"] = out["coefficient"].map(order)
    gorder = {g: i for i, g in enumerate(dict.fromkeys(tidy["gyro"]))}
    out["_g"] = out["gyro"].map(gorder)
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
