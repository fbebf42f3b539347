"""Pooled scores of a study whose gyros are drawn at random, one replicate each (``studies/random_gyros.toml``).

Every replicate is a different gyro, so the per-gyro scores of ``scores.md`` rest on one record
each; here they are pooled over the gyros, per estimator and coefficient:

* present terms (true value > 0): the share of 95 % intervals holding the truth (with its
  Clopper-Pearson 95 % interval), the RMS of the error in CRLB standard deviations (the CRLB of that
  gyro at that record length, ``table.csv``) and the mean error in CRLB std (bias);
  the same split by the CRLB relative std of the coefficient (resolvable: < 0.3, or not);
  for B also split by the flicker memory ``tau_max`` below / above the record length;
* absent terms: the share of intervals whose lower bound is 0 (the interval holds the truth, 0).

Usage::

    python -m avbench.studies.summaries.random_gyros studies/random_gyros.toml --out results/random_gyros

writes ``pooled.csv`` and ``pooled.md`` in ``--out``.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd

__all__ = ["pooled", "main"]


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


def _render(t: pd.DataFrame) -> str:
    from avbench.studies.scoring import _md_table

    lines = ["# Gyros drawn at random: scores pooled over the gyros (one replicate each)", "",
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
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    write_text(out / "pooled.csv", t.to_csv(index=False, float_format="%.6g"))
    write_text(out / "pooled.md", _render(t))
    print(_render(t))
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
