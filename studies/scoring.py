"""Scores with uncertainty: interval coverage, RMSE/CRLB and bias/SE, and wins that survive a test.

From a study's tidy table (one row per gyro x replicate x estimator x coefficient, with the 95 %
``lower`` / ``upper`` bounds the runner records from each estimator's ``conf_int``):

``scores(tidy, crlb)``
    one row per gyro x estimator x coefficient, in SI (``unit`` names it): ``rmse``, ``bias`` (signed:
    mean - true; ``bias_pct`` the same over true, in %), ``std``, ``crlb`` (the
    Cramér-Rao std bound), ``rmse_over_crlb`` with its percentile bootstrap 95 % interval
    ``rmse_over_crlb_lo``/``_hi`` (the physical replicates resampled), ``bias_over_se`` (the bias over its own Monte Carlo
    standard error std/sqrt(M): |value| > 2 says the bias is real), ``bias_over_crlb``,
    ``coverage`` (share of replicates whose 95 % interval holds the truth, among those with an
    interval), ``coverage_lo``/``coverage_hi`` (Clopper-Pearson 95 % interval of that share),
    ``n_intervals``. std/CRLB alone is no score: a biased estimator can sit below the bound, which
    limits unbiased estimators only; ``note`` says so on every row with RMSE/CRLB below 1.
``paired_rmse_ratio(tidy, gyro, coefficient, a, b)``
    RMSE_a / RMSE_b on the replicates both have, with a bootstrap 95 % interval that resamples
    replicates (pairs kept together, Efron & Tibshirani 1993, Ch. 13).
``wins(tidy)``
    per gyro x coefficient, every pair of the estimators that compete there compared on the same
    replicates (``avbench.studies.paired.all_pairs``: sign-flip p-values, Holm over every pair of
    every cell of the study, so between identical estimators no win is declared anywhere in the
    study with probability above ``level``). The estimator with the lowest RMSE *wins* a cell only
    when it beats each other one; the estimators it does not beat are *tied* with it, named.
``render_scores(...)``
    ``scores.md``: the coverage table and the tested leaderboard.

Bootstrap resamples use ``numpy.random.default_rng(seed)`` with a fixed seed: the report is a pure
function of the tidy table.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
from scipy.special import betaincinv

from avbench.noise_models.units import COEFFICIENTS
from avbench.outputs import markdown_cell

__all__ = ["scores", "comparable", "paired_rmse_ratio", "wins", "render_scores", "crlb_table", "write_scores",
           "WIN_LEVEL"]

N_BOOT = 2000
#: family-wise level of the wins: the chance of any win between identical estimators in a study
WIN_LEVEL = 0.05
WIN_COLUMNS = ["gyro", "coefficient", "verdict", "best", "tied", "rival", "ratio", "lower", "upper", "p_holm",
               "n_pairs", "candidates"]


def _ok(d: pd.DataFrame) -> pd.DataFrame:
    return d[(d["failure"] == "") & ~d["nonphysical"] & np.isfinite(d["estimate"])]


def crlb_table(cfg) -> dict:
    """{(gyro label, coefficient): CRLB std (SI)} for the study's gyros (NaN where not covered)."""
    from avbench.estimators.likelihood.crlb import crlb

    out = {}
    for g in cfg.gyros:
        try:
            b = crlb(g.gyro, g.n_samples)
        except Exception:  # a model the bound does not cover
            continue
        for c in COEFFICIENTS:
            out[(g.label, c)] = float(b[c])
    return out


def _clopper_pearson(k: int, n: int, level=0.95):
    if n == 0:
        return math.nan, math.nan
    a = (1 - level) / 2
    # the beta quantile by scipy.special.betaincinv: the same bits as scipy.stats.beta.ppf (both Boost's; checked
    # for every k <= n < 600 at both levels), without importing scipy.stats (~0.7 s of every report;
    # results/bench/README.md)
    lo = 0.0 if k == 0 else betaincinv(k, n - k + 1, a)
    hi = 1.0 if k == n else betaincinv(k + 1, n - k, 1 - a)
    return float(lo), float(hi)


def _below_bound_note(rmse_over_crlb: float, bias_over_se: float) -> str:
    if not rmse_over_crlb < 1:
        return ""
    return (f"below the Cramér-Rao bound (bias/SE {bias_over_se:.2g}): the bound limits unbiased estimators "
            "only, so this is no efficiency beyond it")


def _rmse_ratio_interval(x: np.ndarray, true: float, bound: float, n_boot=N_BOOT, seed=0, level=0.95):
    """Percentile bootstrap interval of RMSE / bound over the replicates ``x`` (resampled)."""
    if x.size < 3 or not bound > 0 or not np.isfinite(true):
        return math.nan, math.nan
    idx = np.random.default_rng(seed).integers(0, x.size, size=(n_boot, x.size))
    r = np.sqrt(np.mean((x[idx] - true) ** 2, axis=1)) / bound
    lo, hi = np.quantile(r, [(1 - level) / 2, (1 + level) / 2])
    return float(lo), float(hi)


def scores(tidy: pd.DataFrame, crlb: dict | None = None) -> pd.DataFrame:
    """Per gyro x estimator x coefficient scores in SI (module docstring)."""
    from avbench.noise_models.units import si_units

    crlb = crlb or {}
    si = si_units()
    rows = []
    for (g, e, c), d in tidy.groupby(["gyro", "estimator", "coefficient"], sort=False):
        true = float(d["true"].iloc[0])
        ok = _ok(d)
        x = ok["estimate"].to_numpy()
        M = x.size
        bias = float(x.mean() - true) if M and np.isfinite(true) else math.nan
        std = float(x.std(ddof=1)) if M > 1 else math.nan
        rmse = float(np.sqrt(np.mean((x - true) ** 2))) if M and np.isfinite(true) else math.nan
        bound = crlb.get((g, c), math.nan)
        cov_k = cov_n = 0
        if {"lower", "upper"} <= set(d.columns) and np.isfinite(true):
            iv = d[np.isfinite(d["lower"]) & np.isfinite(d["upper"])]
            cov_n = len(iv)
            cov_k = int(((iv["lower"] <= true) & (true <= iv["upper"])).sum())
        lo, hi = _clopper_pearson(cov_k, cov_n)
        r_lo, r_hi = _rmse_ratio_interval(x, true, bound)
        ratio = rmse / bound if bound > 0 else math.nan
        bias_se = bias / (std / math.sqrt(M)) if M > 1 and std > 0 else math.nan
        rows.append({
            "gyro": g, "estimator": e, "coefficient": c, "unit": si[c], "true": true,
            "n": int(d["replicate"].nunique()), "n_ok": M, "bias": bias,
            "bias_pct": bias / true * 100 if true > 0 else math.nan, "std": std, "rmse": rmse, "crlb": bound,
            "rmse_over_crlb": ratio, "rmse_over_crlb_lo": r_lo, "rmse_over_crlb_hi": r_hi,
            "bias_over_se": bias_se,
            "bias_over_crlb": bias / bound if bound > 0 else math.nan,
            "coverage": cov_k / cov_n if cov_n else math.nan, "coverage_lo": lo, "coverage_hi": hi,
            "n_intervals": cov_n, "note": _below_bound_note(ratio, bias_se),
        })
    return pd.DataFrame(rows)


def comparable(sc: pd.DataFrame) -> pd.DataFrame:
    """The rows of :func:`scores` that compete for best: a present coefficient, and a physical estimate
    in at least half the replicates (the rule of :func:`wins`)."""
    return sc[np.isfinite(sc["true"]) & (sc["true"] > 0) & (sc["n_ok"] >= np.ceil(sc["n"] / 2))
              & np.isfinite(sc["rmse"])]


def paired_rmse_ratio(tidy, gyro, coefficient, a, b, n_boot=N_BOOT, seed=0, level=0.95):
    """(ratio, lower, upper): RMSE of ``a`` over RMSE of ``b`` on their common physical replicates,
    with a paired bootstrap interval (replicates resampled with replacement)."""
    d = tidy[(tidy["gyro"] == gyro) & (tidy["coefficient"] == coefficient)]
    ea = _ok(d[d["estimator"] == a]).set_index("replicate")
    eb = _ok(d[d["estimator"] == b]).set_index("replicate")
    common = ea.index.intersection(eb.index)
    if len(common) < 3:
        return math.nan, math.nan, math.nan
    sa = ((ea.loc[common, "estimate"] - ea.loc[common, "true"]) ** 2).to_numpy()
    sb = ((eb.loc[common, "estimate"] - eb.loc[common, "true"]) ** 2).to_numpy()
    ratio = math.sqrt(sa.mean() / sb.mean()) if sb.mean() > 0 else math.nan
    rng = np.random.default_rng(seed)
    idx = rng.integers(0, len(common), size=(n_boot, len(common)))
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.sqrt(sa[idx].mean(axis=1) / sb[idx].mean(axis=1))
    r = r[np.isfinite(r)]
    if r.size < n_boot // 2:
        return ratio, math.nan, math.nan
    lo, hi = np.quantile(r, [(1 - level) / 2, (1 + level) / 2])
    return ratio, float(lo), float(hi)


def wins(tidy: pd.DataFrame, level: float = WIN_LEVEL, n_boot=N_BOOT, seed=0) -> pd.DataFrame:
    """Per gyro x coefficient (module docstring): ``best`` (the lowest RMSE among the estimators with a
    physical estimate in at least half the replicates), ``verdict`` "win" (it beats every other one),
    "tie" (``tied``: the others it does not beat, a tuple) or "alone" (no other competes);
    ``rival``: the other estimator closest to it (the largest Holm p-value; among the tied ones when
    there is a tie, so "mixed" pairs count), with the paired RMSE
    ratio best / rival, its bootstrap 95 % interval (``lower``, ``upper``), ``p_holm`` and the pairs
    it rests on; ``candidates``: how many competed. ``attrs["pairs"]``: every pair's comparison."""
    from avbench.studies.paired import all_pairs

    sc = comparable(scores(tidy))
    ranked = {k: list(d.sort_values("rmse", kind="stable")["estimator"])
              for k, d in sc.groupby(["gyro", "coefficient"], sort=False)}
    pairs = all_pairs(tidy, {k: v for k, v in ranked.items() if len(v) > 1}, level=level, n_boot=n_boot, seed=seed)
    rows = []
    for (g, c), names in ranked.items():
        best = names[0]
        row = {"gyro": g, "coefficient": c, "best": best, "tied": (), "rival": "", "ratio": math.nan,
               "lower": math.nan, "upper": math.nan, "p_holm": math.nan, "n_pairs": 0, "candidates": len(names)}
        if len(names) < 2:
            rows.append({**row, "verdict": "alone"})
            continue
        mine = pairs[(pairs["gyro"] == g) & (pairs["coefficient"] == c) & (pairs["a"] == best)]
        tied = tuple(r["b"] for _, r in mine.iterrows() if r["verdict"] != "A")
        held = mine[mine["b"].isin(tied)] if tied else mine  # the rival: one that holds the best to a tie
        rival = held.sort_values("p_holm", ascending=False, kind="stable", na_position="first").iloc[0]
        rows.append({**row, "verdict": "tie" if tied else "win", "tied": tied, "rival": rival["b"],
                     "ratio": rival["ratio"], "lower": rival["ratio_lo"], "upper": rival["ratio_hi"],
                     "p_holm": rival["p_holm"], "n_pairs": int(rival["n_pairs"])})
    out = pd.DataFrame(rows, columns=WIN_COLUMNS)
    out.attrs["pairs"] = pairs
    out.attrs["level"] = level
    return out


def _md_table(df: pd.DataFrame) -> list[str]:
    out = ["| " + " | ".join(df.columns) + " |", "|" + "---|" * len(df.columns)]
    for _, r in df.iterrows():
        out.append("| " + " | ".join("–" if (isinstance(v, float) and not np.isfinite(v)) else
                                      (f"{v:.3g}" if isinstance(v, float) else markdown_cell(v)) for v in r) + " |")
    return out


def _render_wins(w: pd.DataFrame) -> list[str]:
    """The wins section of ``scores.md``: one row per gyro x coefficient, then the wins per coefficient."""
    pairs = w.attrs.get("pairs", pd.DataFrame())
    level = w.attrs.get("level", WIN_LEVEL)
    out = ["", "## Wins (all pairs tested on the same replicates, Holm over the study)", "",
           f"Every pair of the estimators that compete on a gyro x coefficient (a physical estimate in at least "
           f"half the replicates) is compared on the replicates both fitted: a sign-flip permutation test of "
           f"their RMSE ratio, Holm-adjusted over all {len(pairs)} pairs of the study, so between estimators "
           f"that do not differ no win is declared anywhere in it with probability above {level:g}. The best "
           "(lowest RMSE) wins only when it beats every other one at that level; the ones it does not beat are "
           "tied with it (tied: separated by ';'). rival: the one closest to it (largest Holm p; of the tied "
           "ones, in a tie), with RMSE(best) / RMSE(rival) and the pair's own paired bootstrap 95 % interval "
           "(not adjusted: it can exclude 1 where the Holm p does not reach the level); pairs: the replicates "
           "both fitted.", ""]
    if not len(pairs):
        return out[:3] + ["One estimator competes on each gyro x coefficient: no pair to test."]
    shown = w[["gyro", "coefficient", "verdict", "best", "tied", "rival", "ratio", "lower", "upper", "p_holm",
               "n_pairs"]].rename(columns={"p_holm": "p (Holm)", "n_pairs": "pairs"})
    shown["tied"] = shown["tied"].map("; ".join)
    out += _md_table(shown)
    counts = w[w["verdict"] == "win"].groupby(["coefficient", "best"]).size().rename("wins").reset_index()
    out += ["", "### Tested wins per coefficient", ""]
    out += _md_table(counts) if len(counts) else ["(no win survives the paired tests)"]
    return out


def render_scores(sc: pd.DataFrame, w: pd.DataFrame) -> str:
    """Markdown: coverage and efficiency per gyro x estimator x coefficient, and tested wins."""
    out = ["# Scores with uncertainty", "",
           "RMSE/CRLB with its bootstrap 95 % interval (lo, hi), and bias/SE (the signed bias over its Monte "
           "Carlo standard error; |bias/SE| > 2: a real bias). The Cramér-Rao bound limits unbiased estimators "
           "only: a row below it says so ('below_bound') and is listed under the table. "
           "coverage = share of replicates whose 95 % interval (the estimator's `conf_int`) holds the truth, "
           "with its Clopper-Pearson 95 % interval; '–' where the estimator gives no interval.", ""]
    s = sc[np.isfinite(sc["true"]) & (sc["true"] > 0)].copy()
    below = s["note"] != ""
    s["below_bound"] = np.where(below, "yes", "")
    cols = ["gyro", "estimator", "coefficient", "rmse_over_crlb", "rmse_over_crlb_lo", "rmse_over_crlb_hi", "below_bound",
            "bias_over_se", "bias_over_crlb", "coverage", "coverage_lo", "coverage_hi", "n_intervals"]
    out += _md_table(s[cols])
    if below.any():
        out += ["", "Below the Cramér-Rao bound: the bound limits unbiased estimators only, so a biased "
                "estimator can sit below it; these rows show bias, not efficiency beyond the bound:", ""]
        out += [f"- {r['gyro']} / {r['estimator']} / {r['coefficient']}: RMSE/CRLB {r['rmse_over_crlb']:.3g}, "
                f"bias/SE {r['bias_over_se']:.3g}" for _, r in s[below].iterrows()]
    out += _render_wins(w)
    return "\n".join(out) + "\n"


def write_scores(tidy: pd.DataFrame, out, bounds: dict, w: pd.DataFrame) -> list:
    """Write ``scores.csv`` (6 significant digits) and ``scores.md`` beside the study's tables (a hook
    of ``write_report``, which passes the study's :func:`crlb_table` and :func:`wins`); returns their
    paths."""
    from pathlib import Path

    from avbench.outputs import TABLE_DIGITS, atomic_write_text

    out = Path(out)
    sc = scores(tidy, bounds)
    atomic_write_text(out / "scores.csv", sc.to_csv(index=False, float_format=f"%.{TABLE_DIGITS}g"))
    atomic_write_text(out / "scores.md", render_scores(sc, w))
    return [out / "scores.csv", out / "scores.md"]
