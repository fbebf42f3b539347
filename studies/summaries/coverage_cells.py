"""The count of a coverage study: the preset x Q/N/B cells that meet the coverage target.

``studies/coverage_defaults.toml`` fits every preset with the recommended estimator's defaults (no
true terms told). Its target: "93-97 % coverage in >= 27 of the 30 preset x Q/N/B cells and
|bias| < 0.5 CRLB-std there". Ten presets x three coefficients are 30 cells; on five of them (the
ADIS16405 presets) the true Q is 0, the term is absent. The rule, applied to every study alike
(``results/README.md``, coverage_defaults, has the counts):

* **present cell** (true value > 0): the share of 95 % intervals holding the truth is in
  [0.93, 0.97] *and* the mean error is below 0.5 CRLB standard deviations in magnitude
  (``scores.csv``'s ``coverage`` and ``bias_over_crlb``, the CRLB of the preset at the record's
  length);
* **absent cell** (true value 0): the share of intervals holding 0 (lower bound 0) is at least
  0.95 -- the target's own criterion for absent terms ("≥ 95 % of intervals of absent terms
  containing 0", as for the random gyros). The symmetric band around 0.95 does not apply there: a
  profile-likelihood interval on [0, inf) of a variance whose truth is the boundary 0 holds it with
  probability 1/2 + 0.95/2 = 0.975 (its statistic follows the 1/2 chi^2_0 + 1/2 chi^2_1 law, Self &
  Liang 1987), so an interval that is right there covers 0 at 0.975, above the band; and there is no
  CRLB standard deviation at 0 to scale a bias by (an estimate >= 0 of a 0 is biased upwards by
  construction).

Each share is given with its Clopper-Pearson 95 % interval.

Usage::

    python -m avbench.studies.summaries.coverage_cells studies/coverage_defaults.toml --out results/coverage_defaults

writes ``cells.csv`` and ``cells.md`` in ``--out``.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd

__all__ = ["cells", "main", "BAND", "MAX_ABS_BIAS", "ABSENT_HOLDS_ZERO"]

#: coverage band of a present cell
BAND = (0.93, 0.97)
#: largest |mean error| of a present cell, in CRLB standard deviations
MAX_ABS_BIAS = 0.5
#: smallest share of intervals holding 0 of an absent cell
ABSENT_HOLDS_ZERO = 0.95


def cells(tidy: pd.DataFrame, scores: pd.DataFrame, coefficients="QNB") -> pd.DataFrame:
    """One row per gyro x estimator x coefficient in ``coefficients``: ``kind`` (present / absent),
    ``n``, ``share`` (coverage, or the share holding 0), its Clopper-Pearson ``share_lo``,
    ``share_hi``, ``bias_over_crlb`` (present cells) and ``ok`` by the rule of the module docstring."""
    from avbench.studies.scoring import _clopper_pearson

    rows = []
    d = tidy[tidy["coefficient"].isin(list(coefficients))]
    for (g, e, c), s in d.groupby(["gyro", "estimator", "coefficient"], sort=True):
        true = s["true"].astype(float)
        present = bool(np.all(np.isfinite(true) & (true > 0)))
        lo_b, hi_b = s["lower"].astype(float), s["upper"].astype(float)
        n = len(s)
        if present:
            hit = int(((lo_b <= true) & (true <= hi_b)).sum())
            sc = scores[(scores["gyro"] == g) & (scores["estimator"] == e) & (scores["coefficient"] == c)]
            bias = float(sc["bias_over_crlb"].iloc[0]) if len(sc) else math.nan
            share = hit / n
            ok = BAND[0] <= share <= BAND[1] and abs(bias) < MAX_ABS_BIAS
        else:
            hit = int((lo_b == 0.0).sum())
            bias = math.nan
            share = hit / n
            ok = share >= ABSENT_HOLDS_ZERO
        lo, hi = _clopper_pearson(hit, n)
        rows.append(dict(gyro=g, estimator=e, coefficient=c, kind="present" if present else "absent", n=n,
                         share=share, share_lo=lo, share_hi=hi, bias_over_crlb=bias, ok=bool(ok)))
    return pd.DataFrame(rows)


def render(t: pd.DataFrame) -> str:
    from avbench.studies.scoring import _md_table

    lines = ["# Cells meeting the coverage target", "",
             f"present cell: coverage in [{BAND[0]}, {BAND[1]}] and |bias| < {MAX_ABS_BIAS} CRLB std; "
             f"absent cell (true value 0): the interval holds 0 in >= {ABSENT_HOLDS_ZERO} of the records "
             "(a boundary interval's nominal rate is 0.975; `studies/summaries/coverage_cells.py`). "
             "share_lo, share_hi: Clopper-Pearson 95 % interval of the share.", ""]
    for e, s in t.groupby("estimator", sort=False):
        lines.append(f"**{e}: {int(s['ok'].sum())} of {len(s)} cells meet the target** "
                     f"({int(s[s['kind'] == 'present']['ok'].sum())} of {int((s['kind'] == 'present').sum())} present, "
                     f"{int(s[s['kind'] == 'absent']['ok'].sum())} of {int((s['kind'] == 'absent').sum())} absent).")
        lines.append("")
    return "\n".join(lines + _md_table(t)) + "\n"


def main(argv=None) -> int:
    from avbench.outputs import atomic_write_text as write_text
    from avbench.studies.report import finished_studies_parser, parse_finished

    ap = finished_studies_parser("python -m avbench.studies.summaries.coverage_cells",
                                 "Cells of a coverage study meeting the coverage target (present: coverage in the band, small bias; absent: the interval holds 0).", "results/coverage_defaults")
    a, done = parse_finished(ap, argv)
    cfg, tidy = done[0]
    scores = pd.read_csv(Path(a.results) / cfg.name / "scores.csv")
    t = cells(tidy, scores)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    write_text(out / "cells.csv", t.to_csv(index=False, float_format="%.6g"))
    write_text(out / "cells.md", render(t))
    print(render(t))
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
