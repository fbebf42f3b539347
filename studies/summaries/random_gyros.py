"""Scores of a study whose gyros are drawn at random (``studies/random_gyros.toml``), over the gyros.

Efficiency (:func:`efficiency`), per estimator and coefficient over the gyros where the term is
present: each gyro's RMSE over its replicates in CRLB standard deviations (the CRLB of that gyro at
that record length), their median over the gyros with a bootstrap 95 % interval (the gyros
resampled), and the share of gyros at or below :data:`EFFICIENT` times the bound. With r replicates
a gyro's RMSE is the root of a mean of r squares: its median is about :math:`\\sqrt{1 - 2/(3r)}`
of the true RMSE for normal errors (0.94 at r = 6).

Coverage and error pooled over gyros and replicates (:func:`pooled`), per estimator and coefficient:

* present terms (true value > 0): the share of 95 % intervals holding the truth (with its
  Clopper-Pearson 95 % interval), the RMS of the error in CRLB standard deviations (the CRLB of that
  gyro at that record length, ``table.csv``) and the mean error in CRLB std (bias);
  the same split by the CRLB relative std of the coefficient (resolvable: < 0.3, or not);
  for B also split by the flicker memory ``tau_max`` below / above the record length;
* absent terms: the share of intervals whose lower bound is 0 (the interval holds the truth, 0).

The spread over the gyros (:func:`per_gyro_table`): the median, 90th percentile, max and share within
:data:`EFFICIENT` of the gyros' RMSE / CRLB, beside an efficient unbiased estimator's (chi2_r / r).

Usage::

    python -m avbench.studies.summaries.random_gyros studies/random_gyros.toml --out results/random_gyros

writes ``pooled.csv``, ``efficiency.csv``, ``per_gyro.csv`` and ``pooled.md`` in ``--out``.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd

__all__ = ["EFFICIENT", "efficiency", "per_gyro_table", "pooled", "main"]

#: RMSE / CRLB at or below which an estimator counts as efficient on a gyro
EFFICIENT = 1.25
#: bootstrap resamples of the gyros for the median's interval (seeded: the table depends on the data only)
N_BOOT = 2000


def _tau_max(cfg) -> dict:
    out = {}
    for g in cfg.gyros:
        for t in g.gyro.terms:
            if hasattr(t, "tau_max"):
                out[g.label] = float(t.tau_max)
    return out


def pooled(tidy: pd.DataFrame, crlb_rel: pd.DataFrame, tau_max: dict, record_s: float) -> pd.DataFrame:
    """One row per estimator x coefficient x subset (all / resolvable / ... ): see the module docstring.
    ``crlb_rel``: columns gyro, estimator, coefficient, crlb_rel (CRLB std / true value)."""
    from avbench.studies.scoring import _clopper_pearson

    d = tidy.merge(crlb_rel, on=["gyro", "estimator", "coefficient"], how="left")
    d = d[np.isfinite(d["lower"].astype(float)) | np.isfinite(d["true"].astype(float))]
    rows = []
    for (e, c), g in d.groupby(["estimator", "coefficient"], sort=False):
        present = g[np.isfinite(g["true"]) & (g["true"] > 0)]
        absent = g[~(np.isfinite(g["true"]) & (g["true"] > 0))]
        subsets = {"all present": present,
                   "CRLB rel < 0.3": present[present["crlb_rel"] < 0.3],
                   "CRLB rel >= 0.3": present[~(present["crlb_rel"] < 0.3)]}
        if c == "B":
            tm = present["gyro"].map(tau_max)
            subsets["tau_max < record"] = present[tm < record_s]
            subsets["tau_max >= record"] = present[tm >= record_s]
        for name, s in subsets.items():
            ok = np.isfinite(s["lower"]) & np.isfinite(s["upper"])
            hit = int(((s["lower"] <= s["true"]) & (s["true"] <= s["upper"]) & ok).sum())
            n = len(s)
            lo, hi = _clopper_pearson(hit, n)
            z = (s["estimate"] - s["true"]) / (s["crlb_rel"] * s["true"])
            z = z[np.isfinite(z)]
            rows.append(dict(estimator=e, coefficient=c, subset=name, n=n, coverage=hit / n if n else math.nan,
                             cov_lo=lo, cov_hi=hi, rmse_over_crlb=float(np.sqrt(np.mean(z**2))) if len(z) else math.nan,
                             bias_over_crlb=float(np.mean(z)) if len(z) else math.nan))
        if len(absent):
            k = int((absent["lower"] == 0).sum())
            lo, hi = _clopper_pearson(k, len(absent))
            rows.append(dict(estimator=e, coefficient=c, subset="absent: interval holds 0", n=len(absent),
                             coverage=k / len(absent), cov_lo=lo, cov_hi=hi, rmse_over_crlb=math.nan,
                             bias_over_crlb=math.nan))
    return pd.DataFrame(rows)


def _present_errors(tidy: pd.DataFrame, crlb_rel: pd.DataFrame) -> pd.DataFrame:
    """``tidy``'s rows of present terms with ``z2``: the squared error in CRLB standard deviations."""
    d = tidy.merge(crlb_rel, on=["gyro", "estimator", "coefficient"], how="left")
    d = d[np.isfinite(d["true"].astype(float)) & (d["true"] > 0)]
    return d.assign(z2=((d["estimate"] - d["true"]) / (d["crlb_rel"] * d["true"])) ** 2)


def _per_gyro(g: pd.DataFrame) -> np.ndarray:
    """Each gyro's RMSE / CRLB over its replicates (rows of one estimator x coefficient)."""
    return np.sqrt(g.groupby("gyro")["z2"].mean().dropna().to_numpy())


def efficiency(tidy: pd.DataFrame, crlb_rel: pd.DataFrame, seed: int = 0) -> pd.DataFrame:
    """One row per estimator x coefficient: over the gyros where the term is present, the median of
    each gyro's RMSE / CRLB (``median``, its bootstrap 95 % interval ``median_lo``, ``median_hi``),
    the share of gyros with RMSE / CRLB <= :data:`EFFICIENT` and the number of gyros and of records
    (module docstring)."""
    d = _present_errors(tidy, crlb_rel)
    rng = np.random.default_rng(seed)
    rows = []
    for (e, c), g in d.groupby(["estimator", "coefficient"], sort=False):
        per = _per_gyro(g)
        if not per.size:
            continue
        boot = np.median(per[rng.integers(0, per.size, (N_BOOT, per.size))], axis=1)
        rows.append(dict(estimator=e, coefficient=c, gyros=per.size, records=int(g["z2"].notna().sum()),
                         median=float(np.median(per)), median_lo=float(np.quantile(boot, 0.025)),
                         median_hi=float(np.quantile(boot, 0.975)),
                         share_efficient=float(np.mean(per <= EFFICIENT))))
    return pd.DataFrame(rows)


def per_gyro_table(tidy: pd.DataFrame, crlb_rel: pd.DataFrame, replicates: int) -> pd.DataFrame:
    """The spread over the gyros of each gyro's RMSE / CRLB, beside an efficient unbiased estimator's.

    One row per estimator x coefficient over the gyros where the term is present: the number of
    gyros, the median, 90th percentile and maximum of the gyros' RMSE / CRLB (over their replicates)
    and the share at or below :data:`EFFICIENT`. Then, per coefficient, the row ``efficient
    (chi2_r/r)``: an unbiased estimator at the bound with normal errors has RMSE^2 / CRLB^2 ~
    chi2_r / r over r replicates, so its median is sqrt(chi2_r.median / r), its 90th percentile
    sqrt(chi2_r.ppf(0.9) / r), its share P(chi2_r <= r EFFICIENT^2), and its max the median of the
    largest of that many gyros: sqrt(chi2_r.ppf(0.5^(1/gyros)) / r) (0.94, 1.33, 0.85 at r = 6).
    """
    from scipy import stats

    d = _present_errors(tidy, crlb_rel)
    chi2 = stats.chi2(replicates)
    rows, gyros = [], {}
    for (e, c), g in d.groupby(["estimator", "coefficient"], sort=False):
        per = _per_gyro(g)
        if not per.size:
            continue
        gyros[c] = max(gyros.get(c, 0), per.size)
        rows.append(dict(estimator=e, coefficient=c, gyros=per.size, median=float(np.median(per)),
                         p90=float(np.quantile(per, 0.9)), max=float(per.max()),
                         share_efficient=float(np.mean(per <= EFFICIENT))))
    for c, n in gyros.items():
        rows.append(dict(estimator=f"efficient (chi2_{replicates}/{replicates})", coefficient=c, gyros=n,
                         median=math.sqrt(chi2.median() / replicates),
                         p90=math.sqrt(chi2.ppf(0.9) / replicates),
                         max=math.sqrt(chi2.ppf(0.5 ** (1 / n)) / replicates),
                         share_efficient=float(chi2.cdf(replicates * EFFICIENT**2))))
    out = pd.DataFrame(rows, columns=["estimator", "coefficient", "gyros", "median", "p90", "max", "share_efficient"])
    order = {c: i for i, c in enumerate("QNBKR")}
    return out.sort_values("coefficient", key=lambda s: s.map(order), kind="stable").reset_index(drop=True)


def _render(t: pd.DataFrame, eff: pd.DataFrame, per: pd.DataFrame) -> str:
    from avbench.studies.scoring import _md_table

    lines = ["# Gyros drawn at random: scores over the gyros", "",
             "## Efficiency: each gyro's RMSE / CRLB over its replicates, median over the gyros", "",
             "median: of the gyros' RMSE / CRLB where the term is present, with its bootstrap 95 % interval "
             f"(gyros resampled); share <= {EFFICIENT}: the share of gyros whose RMSE is within {EFFICIENT} "
             "times the Cramer-Rao bound.", ""] + _md_table(eff) + [
             "", "## Per gyro: the spread of each gyro's RMSE / CRLB", "",
             "Over the gyros where the term is present: median, 90th percentile (p90) and max of each gyro's "
             f"RMSE / CRLB over its replicates, and the share <= {EFFICIENT}; the row 'efficient' is an unbiased "
             "estimator at the bound with normal errors (its max: the median of the largest of that many gyros).",
             ""] + _md_table(per) + [
             "", "## Coverage and error pooled over gyros and replicates", "",
             "coverage: share of 95 % intervals holding the truth (absent terms: holding 0, i.e. lower bound 0), "
             "with its Clopper-Pearson 95 % interval; rmse_over_crlb, bias_over_crlb: error in CRLB standard "
             "deviations of each gyro (RMS, mean); CRLB rel: the coefficient's CRLB relative std.", ""]
    return "\n".join(lines + _md_table(t)) + "\n"


def main(argv=None) -> int:
    from avbench.outputs import atomic_write_text as write_text
    from avbench.studies.report import finished_studies_parser, parse_finished

    ap = finished_studies_parser("python -m avbench.studies.summaries.random_gyros",
                                 "Pooled coverage and RMSE/CRLB of a random-gyro study.", "results/random_gyros")
    a, done = parse_finished(ap, argv)
    cfg, tidy = done[0]
    table = pd.read_csv(Path(a.results) / cfg.name / "table.csv")
    table["crlb_rel"] = table["crlb_std"] / table["true"]
    crlb_rel = table[["gyro", "estimator", "coefficient", "crlb_rel"]]
    record_s = max(g.n_samples * g.gyro.dt for g in cfg.gyros)
    t = pooled(tidy, crlb_rel, _tau_max(cfg), record_s)
    eff = efficiency(tidy, crlb_rel)
    per = per_gyro_table(tidy, crlb_rel, cfg.replicates)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    write_text(out / "pooled.csv", t.to_csv(index=False, float_format="%.6g"))
    write_text(out / "efficiency.csv", eff.to_csv(index=False, float_format="%.6g"))
    write_text(out / "per_gyro.csv", per.to_csv(index=False, float_format="%.6g"))
    write_text(out / "pooled.md", _render(t, eff, per))
    print(_render(t, eff, per))
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
