"""Paired tests of two estimators on the same replicates, and the family's Holm step.

The machinery of ``avbench compare`` (:mod:`avbench.studies.compare`) and of a study's wins
(:func:`avbench.studies.scoring.wins`): for two estimators on one gyro x coefficient, the errors
(estimate - true) on the replicates where both gave a physical estimate, and

* ``p``: the sign-flip permutation p-value of log(ratio) (A and B swapped within random pairs), valid
  whenever the two estimators' errors are exchangeable -- two identical estimators -- whatever their
  distribution. Swapping pairs changes log(ratio) monotonically with D = sum of (e_a^2 - e_b^2) over
  the pairs, so p is the share of the 2^n sign patterns s with |sum s_i d_i| >= |D|: counted exactly
  up to :data:`EXACT_PAIRS` pairs (half the signs against the other half, sorted). Above that, two
  valid p-values of the same test are joined by Bonferroni, p = 2 min(p_mc, p_bd): p_mc from
  :data:`N_FLIPS` random patterns, (hits + 1) / (N_FLIPS + 1) (Phipson & Smyth 2010), and p_bd, the
  Bentkus & Dzindzalieta (2015, Bernoulli 21:1231, Thm 1.1) bound P(|sum s_i d_i| >= x) <= 2 c*
  P(Z >= x / ||d||), c* = 1 / (4 P(Z >= sqrt 2)) = 3.178, which has no Monte Carlo floor: neither
  the exact nor the joined p stops short of a Holm step over thousands of comparisons;
  ``p_holm``: Holm's step-down adjustment over all the gyro x coefficient comparisons of the call,
  so the chance of declaring any winner between identical estimators is at most ``level``;
* ``detectable_ratio``: the RMSE ratio (< 1) found with 80 % power at the Holm level of the first step
  (``level`` / comparisons), from the bootstrap spread of log(ratio); NaN when the replicate count
  cannot reach that level at all (no p below 2 / 2^n with n pairs);
* ``verdict``: "A" or "B" (the lower RMSE, ``p_holm`` < ``level``, and no more replicates without a
  physical estimate than the other), "mixed" (a significant ratio for the side with more such
  replicates), "tie", or "too few" (fewer than 3 pairs).

:func:`all_pairs` compares every pair of the estimators listed per gyro x coefficient, Holm over
all of them. Resampling uses the ``rng`` it is handed: the result is a function of the rows and
the seed.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from avbench.noise_models.units import PAPER_UNITS, from_si

__all__ = ["all_pairs", "cell_arrays", "pair_row", "judge_family", "holm", "sign_flip_p", "N_BOOT", "EXACT_PAIRS",
           "N_FLIPS", "COLUMNS"]

N_BOOT = 2000
#: pairs up to which :func:`sign_flip_p` counts every sign pattern (2 x 2^15 half sums at 30)
EXACT_PAIRS = 30
#: random sign patterns of the Monte Carlo p-value above EXACT_PAIRS pairs
N_FLIPS = 20000
#: the smallest c with P(sum a_i s_i >= x) <= c P(Z >= x) for Rademacher s_i and sum a_i^2 <= 1
#: (Bentkus & Dzindzalieta 2015, Thm 1.1): 1 / (4 P(Z >= sqrt 2))
C_STAR = 1 / (2 * math.erfc(1.0))
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


def _sign_sums(d: np.ndarray) -> np.ndarray:
    """sum_i s_i d_i for every sign pattern s of ``d`` (2^len(d) values)."""
    sums = np.zeros(1)
    for x in d:
        sums = np.concatenate([sums + x, sums - x])
    return sums


def _gauss_tail(z: float) -> float:
    """P(Z >= z) for a standard normal Z."""
    return 0.5 * math.erfc(z / math.sqrt(2))


def sign_flip_p(sa: np.ndarray, sb: np.ndarray, rng=None) -> float:
    """Two-sided p-value of log(RMSE_a / RMSE_b) = 0 from the squared errors ``sa``, ``sb`` of the same
    replicates, each pair swapped with probability 1/2 (module docstring): exact up to
    :data:`EXACT_PAIRS` pairs; above, twice the smaller of the Monte Carlo p-value (``rng``, default
    ``numpy.random.default_rng(0)``) and the Bentkus-Dzindzalieta bound.

    >>> sign_flip_p(np.full(5, 1.0), np.full(5, 4.0))  # 2 of the 32 patterns reach |D| = 15
    0.0625
    """
    d = np.asarray(sa, float) - np.asarray(sb, float)
    scale = float(np.abs(d).sum())
    if not scale > 0:
        return 1.0
    t = abs(float(d.sum())) - 1e-10 * scale  # the observed pattern counted whatever the order of the sums
    if d.size > EXACT_PAIRS:
        rng = rng if rng is not None else np.random.default_rng(0)
        hits = 0
        for start in range(0, N_FLIPS, 2000):  # in blocks: 2000 x n signs at a time
            signs = 1.0 - 2.0 * (rng.random((min(2000, N_FLIPS - start), d.size)) < 0.5)
            hits += int(np.sum(np.abs(signs @ d) >= t))
        return min(1.0, 2 * min((hits + 1) / (N_FLIPS + 1), _bound_p(d, t)))
    h = d.size // 2
    x, y = np.sort(_sign_sums(d[:h])), np.sort(_sign_sums(d[h:]))  # sorted queries: a faster search
    hits = (y.size - np.searchsorted(y, t - x, side="left")) + np.searchsorted(y, -t - x, side="right")
    return float(hits.sum()) / 2.0 ** d.size


def _bound_p(d: np.ndarray, t: float) -> float:
    """The Bentkus-Dzindzalieta bound on P(|sum s_i d_i| >= t) over random signs s (module docstring)."""
    return 2 * C_STAR * _gauss_tail(t / float(np.sqrt(np.sum(d * d))))


def _reach(n: int) -> float:
    """The smallest p :func:`sign_flip_p` can give with ``n`` pairs (|D| <= sqrt(n) ||d||)."""
    return 2.0 ** (1 - n) if n <= EXACT_PAIRS else min(1.0, 4 * C_STAR * _gauss_tail(math.sqrt(n)))


def _physical(d: pd.DataFrame) -> pd.Series:
    return (d["failure"] == "") & ~d["nonphysical"] & np.isfinite(d["estimate"])


def cell_arrays(dd: pd.DataFrame, names) -> dict:
    """The rows ``dd`` of one gyro x coefficient as arrays over its replicates: per estimator of
    ``names``, (estimates, physical, present)."""
    reps = np.unique(dd["replicate"].to_numpy())
    pos = np.searchsorted(reps, dd["replicate"].to_numpy())
    phys, est, lab = _physical(dd).to_numpy(), dd["estimate"].to_numpy(float), dd["estimator"].to_numpy()
    out = {}
    for e in names:
        m = lab == e
        x, ok, present = np.full(reps.size, np.nan), np.zeros(reps.size, bool), np.zeros(reps.size, bool)
        x[pos[m]], ok[pos[m]], present[pos[m]] = est[m], phys[m], True
        out[e] = (x, ok, present)
    return out


def pair_row(cell: dict, a: str, b: str, gyro, c: str, true: float, unit: str, rng, n_boot: int) -> dict:
    """The comparison of ``a`` and ``b`` on one gyro x coefficient (``cell``: :func:`cell_arrays`; module
    docstring), before the family's Holm step."""
    (xa, oka, pa), (xb, okb, pb) = cell[a], cell[b]
    reps = pa | pb
    both = oka & okb
    ref = from_si(c, true, unit)
    err = {e: from_si(c, x[both], unit) - ref for e, x in ((a, xa), (b, xb))}
    n_pairs = int(both.sum())
    row = {"gyro": gyro, "coefficient": c, "unit": unit, "n": int(reps.sum()), "n_pairs": n_pairs,
           "n_bad_a": int((reps & ~oka).sum()), "n_bad_b": int((reps & ~okb).sum())}
    if n_pairs < 3:
        return {**row, **dict.fromkeys(COLUMNS[7:-1], math.nan), "verdict": "too few"}
    sa, sb = err[a] ** 2, err[b] ** 2
    idx = rng.integers(0, n_pairs, size=(n_boot, n_pairs))
    lr = _log_ratio(sa[idx], sb[idx])
    lr = lr[np.isfinite(lr)]
    bd = err[a][idx].mean(axis=1) - err[b][idx].mean(axis=1)
    q = [(1 - 0.95) / 2, (1 + 0.95) / 2]
    lo, hi = np.exp(np.quantile(lr, q)) if lr.size >= n_boot // 2 else (math.nan, math.nan)
    return {**row, "rmse_a": math.sqrt(sa.mean()), "rmse_b": math.sqrt(sb.mean()),
            "ratio": math.exp(float(_log_ratio(sa, sb))), "ratio_lo": float(lo), "ratio_hi": float(hi),
            "bias_a": float(err[a].mean()), "bias_b": float(err[b].mean()),
            "bias_diff": float(err[a].mean() - err[b].mean()),
            "bias_diff_lo": float(np.quantile(bd, q[0])), "bias_diff_hi": float(np.quantile(bd, q[1])),
            "p": sign_flip_p(sa, sb, rng), "_se": float(np.std(lr, ddof=1)) if lr.size > 1 else math.nan,
            "_reach": _reach(n_pairs)}


def judge_family(rows: list[dict], level: float) -> pd.DataFrame:
    """The family ``rows`` of :func:`pair_row` with ``p_holm`` (Holm over all of them), the detectable
    ratio and the verdict (module docstring)."""
    from scipy.special import ndtri

    out = pd.DataFrame(rows)
    for col in ("_se", "_reach", "p"):
        if col not in out:
            out[col] = math.nan
    out["p_holm"] = holm(out["p"])
    family = int(np.isfinite(out["p"]).sum())
    alpha1 = level / max(family, 1)
    z = ndtri(1 - alpha1 / 2) + ndtri(POWER)
    out["detectable_ratio"] = np.where(out["_reach"] <= alpha1, np.exp(-z * out["_se"]), math.nan)
    verdicts = []
    few = out["verdict"].eq("too few") if "verdict" in out else pd.Series(False, index=out.index)
    for r, too_few in zip(out.itertuples(index=False), few):
        if too_few:
            verdicts.append("too few")
        elif not r.p_holm < level:
            verdicts.append("tie")
        else:
            lower, other = ("A", "B") if r.ratio < 1 else ("B", "A")
            bad = {"A": r.n_bad_a, "B": r.n_bad_b}
            verdicts.append(lower if bad[lower] <= bad[other] else "mixed")
    out["verdict"] = verdicts
    return out.drop(columns=["_se", "_reach"])


def all_pairs(tidy: pd.DataFrame, candidates: dict, units: dict | None = None, level: float = 0.05,
              n_boot: int = N_BOOT, seed: int = 0) -> pd.DataFrame:
    """Every pair of the estimators ``candidates[(gyro, coefficient)]`` (in the order listed: ``a``
    before ``b``) compared as :func:`compare` compares two, Holm over all the pairs of all the cells:
    the chance that any verdict other than a tie is declared between identical estimators anywhere
    in the call is at most ``level``. Columns ``a``, ``b`` and those of :func:`compare`."""
    units = {**PAPER_UNITS, **(units or {})}
    rng = np.random.default_rng(seed)
    rows = []
    by_cell = {k: d for k, d in tidy.groupby(["gyro", "coefficient"], sort=False)}
    for (g, c), names in candidates.items():
        dd = by_cell[(g, c)]
        cell, true = cell_arrays(dd, names), float(dd["true"].iloc[0])
        for i, a in enumerate(names):
            for b in names[i + 1:]:
                rows.append({"a": a, "b": b, **pair_row(cell, a, b, g, c, true, units[c], rng, n_boot)})
    if not rows:
        return pd.DataFrame(columns=["a", "b", *COLUMNS])
    return judge_family(rows, level)[["a", "b", *COLUMNS]]
