"""Score term selection: how often an estimator picks the true set of terms, by record length.

An estimator that selects terms (``whittle`` with ``select=True``) reports a dropped term as 0, so the
chosen set of a replicate is the set of modelled coefficients with a finite estimate > 0. The true
set is the gyro's coefficients that are present. For each study (one record length) and gyro:
the share of replicates choosing exactly the true set (with its Clopper-Pearson 95 % interval), the
share that keep each true term, the share that add a term that is absent, and the largest CRLB
relative std of the present terms at that length (the target: >= 90 % wherever that is < 30 %;
``results/README.md``, model_selection).

Usage::

    python -m avbench.studies.summaries.selection studies/model_selection_30min.toml studies/model_selection_2h.toml \\
        studies/model_selection_8h.toml --out results/model_selection

reads ``results/<study name>/tidy.csv`` of each config (``--results`` to change the folder) and
writes ``selection.csv``, ``selection.md`` and ``selection.png`` (the exact-set share against the
record length, one panel per gyro) in ``--out``.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd

from avbench.noise_models.units import COEFFICIENTS

__all__ = ["selection_rates", "selection_figure", "main"]


def selection_rates(tidy: pd.DataFrame, crlb_rel: dict | None = None, length: str = "") -> pd.DataFrame:
    """One row per gyro x estimator: exact-set share, per-term keep/add shares, max CRLB rel. std."""
    from avbench.studies.scoring import _clopper_pearson

    crlb_rel = crlb_rel or {}
    rows = []
    for (g, e), d in tidy.groupby(["gyro", "estimator"], sort=False):
        truth = d.groupby("coefficient")["true"].first()
        true_set = {c for c in COEFFICIENTS if c in truth and np.isfinite(truth[c]) and truth[c] > 0}
        chosen = (d.assign(on=np.isfinite(d["estimate"]) & (d["estimate"] > 0))
                  .pivot_table(index="replicate", columns="coefficient", values="on", aggfunc="first")
                  .fillna(False).astype(bool))
        M = len(chosen)
        exact = sum(1 for _, r in chosen.iterrows() if {c for c in chosen.columns if r[c]} == true_set)
        lo, hi = _clopper_pearson(exact, M)
        row = {"length": length, "gyro": g, "estimator": e,
               "true_set": "".join(sorted(true_set, key=COEFFICIENTS.index)), "replicates": M,
               "exact": exact / M if M else math.nan, "exact_lo": lo, "exact_hi": hi}
        for c in COEFFICIENTS:
            if c in chosen.columns:
                row[f"keep_{c}" if c in true_set else f"add_{c}"] = float(chosen[c].mean())
        rel = [crlb_rel.get((g, c), math.nan) for c in true_set]
        row["max_crlb_rel"] = max(rel) if rel and all(np.isfinite(rel)) else math.nan
        rows.append(row)
    return pd.DataFrame(rows)


def _crlb_rel(cfg) -> dict:
    """{(gyro, coefficient): CRLB relative std} of the present terms (:func:`avbench.studies.scoring.crlb_table`)."""
    from avbench.studies.scoring import crlb_table

    truth = {g.label: g.gyro.coefficients for g in cfg.gyros}
    return {(g, c): b / truth[g][c] for (g, c), b in crlb_table(cfg).items()
            if np.isfinite(truth[g][c]) and truth[g][c] > 0}


def main(argv=None) -> int:
    from avbench.studies.report import finished_studies_parser, parse_finished, record_hours

    ap = finished_studies_parser("python -m avbench.studies.summaries.selection", __doc__.split("\n\n")[0], "results/model_selection")
    a, finished = parse_finished(ap, argv)
    frames = []
    for cfg, tidy in finished:
        length = f"{record_hours(cfg):g} h"
        frames.append(selection_rates(tidy, _crlb_rel(cfg), length))
    table = pd.concat(frames, ignore_index=True)
    table["target_applies"] = table["max_crlb_rel"] < 0.3
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    from avbench.outputs import TABLE_DIGITS, atomic_write_text

    atomic_write_text(out / "selection.csv", table.to_csv(index=False, float_format=f"%.{TABLE_DIGITS}g"))
    atomic_write_text(out / "selection.md", _render(table))
    from avbench.studies.figures import _save

    _save(selection_figure(table), out / "selection.png")
    print(f"wrote {out / 'selection.md'}")
    return 0


def selection_figure(t: pd.DataFrame):
    """Exact-set share (Clopper-Pearson 95 % bars) against the record length, a panel per gyro and a
    line per estimator; filled markers where the target applies (every present term's CRLB relative
    std < 0.3), open where it does not; the 90 % target dashed."""
    from avbench.studies.figures import plt, series_style

    t = t.assign(hours=t["length"].str.replace(" h", "", regex=False).astype(float))
    gyros = list(dict.fromkeys(t["gyro"]))
    ncol = min(5, len(gyros))
    nrow = math.ceil(len(gyros) / ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(2.6 * ncol, 2.4 * nrow + 0.6), sharex=True, sharey=True,
                             squeeze=False)
    hours = sorted(t["hours"].unique())
    for ax, g in zip(axes.flat, gyros):
        d = t[t["gyro"] == g]
        for i, (e, de) in enumerate(d.groupby("estimator", sort=False)):
            de = de.sort_values("hours")
            st = series_style(i)
            err = [de["exact"] - de["exact_lo"], de["exact_hi"] - de["exact"]]
            ax.errorbar(de["hours"], de["exact"], yerr=err, color=st["color"], lw=1, capsize=2, label=e)
            on = de["target_applies"].to_numpy(bool)
            ax.plot(de["hours"][on], de["exact"][on], "o", color=st["color"], ms=5)
            ax.plot(de["hours"][~on], de["exact"][~on], "o", mfc="white", color=st["color"], ms=5)
        ax.axhline(0.9, color="0.5", ls="--", lw=0.8)
        ax.set_xscale("log")
        ax.set_xticks(hours, [f"{h:g}" for h in hours])
        ax.xaxis.set_minor_locator(plt.NullLocator())
        ax.set_xlim(hours[0] / 1.6, hours[-1] * 1.6)
        ax.set_title(f"{g} ({d['true_set'].iloc[0]})", fontsize=8)
        ax.set_ylim(-0.03, 1.03)
        ax.tick_params(labelsize=7)
    for ax in axes.flat[len(gyros):]:
        ax.set_visible(False)
    for ax in axes[-1]:
        ax.set_xlabel("record length (h)", fontsize=8)
    for ax in axes[:, 0]:
        ax.set_ylabel("true set chosen", fontsize=8)
    fig.suptitle("Term selection: share of replicates choosing exactly the true terms (filled: target "
                 "applies; dashed: 90 %)", fontsize=9)
    fig.tight_layout()
    return fig


def _render(t: pd.DataFrame) -> str:
    from avbench.studies.scoring import _md_table

    cols = ["length", "gyro", "true_set", "replicates", "exact", "exact_lo", "exact_hi", "max_crlb_rel",
            "target_applies"]
    cols += [c for c in t.columns if c.startswith(("keep_", "add_"))]
    lines = ["# Term selection: share of replicates choosing exactly the true term set", "",
             "exact: share with the chosen set (coefficients estimated > 0) equal to the true set, with its "
             "Clopper-Pearson 95 % interval; keep_X / add_X: share keeping a true term / adding an absent one; "
             "max_crlb_rel: the largest CRLB relative std of the present terms at that length (the target, "
             ">= 90 % exact, applies where it is < 0.3).", ""]
    return "\n".join(lines + _md_table(t[cols])) + "\n"


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
