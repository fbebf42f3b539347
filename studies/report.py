"""Paper-style tables and figures from a study's tidy results.

``summarize`` reduces the tidy table (one row per gyro x replicate x estimator x coefficient) to one
row per gyro x estimator x coefficient with, in the papers' units: true value, mean, error % =
|mean - true| / true x 100 (Lv et al. 2015's bracketed figure), standard deviation, RMSE, the
numbers of non-physical and failed replicates, the mean fit time, the Cramer-Rao standard-deviation
bound where it is available, and the paper's figures where the study names a paper table.
Means and standard deviations are over the replicates with a physical estimate, as in the papers.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import numpy as np
import pandas as pd

from noise_models.units import COEFFICIENTS, PAPER_UNITS, from_si

__all__ = ["summarize", "render_markdown", "render_latex", "write_report", "load_paper_table"]

UNIT_LABEL = {
    "urad": "µrad",
    "arcsec": "arcsec",
    "deg": "deg",
    "deg/sqrt(h)": "deg/√h",
    "deg/h": "deg/h",
    "deg/h^1.5": "deg/h^1.5",
    "deg/h^2": "deg/h²",
}


def summarize(tidy: pd.DataFrame, units: dict | None = None) -> pd.DataFrame:
    units = {**PAPER_UNITS, **(units or {})}
    rows = []
    order = {c: i for i, c in enumerate(COEFFICIENTS)}
    for (g, e, c), d in tidy.groupby(["gyro", "estimator", "coefficient"], sort=False):
        u = units[c]
        true = from_si(c, float(d["true"].iloc[0]), u)
        ok = d[(d["failure"] == "") & ~d["nonphysical"] & np.isfinite(d["estimate"])]
        est = from_si(c, ok["estimate"].to_numpy(), u)
        mean = float(est.mean()) if est.size else math.nan
        std = float(est.std(ddof=1)) if est.size > 1 else math.nan
        rmse = float(np.sqrt(np.mean((est - true) ** 2))) if est.size and np.isfinite(true) else math.nan
        err = abs(mean - true) / true * 100 if np.isfinite(true) and true > 0 else math.nan
        per_rep = d.groupby("replicate")["seconds"].first()
        rows.append(
            {
                "gyro": g,
                "estimator": e,
                "coefficient": c,
                "unit": u,
                "true": true,
                "mean": mean,
                "error_pct": err,
                "std": std,
                "rmse": rmse,
                "n": int(d["replicate"].nunique()),
                "n_ok": int(est.size),
                "n_nonphysical": int(d["nonphysical"].sum()),
                "n_failed": int((d["failure"] != "").sum()),
                "seconds_per_replicate": float(per_rep.mean()),
                "_o": order[c],
            }
        )
    out = pd.DataFrame(rows)
    if out.empty:
        return out
    gorder = {g: i for i, g in enumerate(dict.fromkeys(tidy["gyro"]))}
    eorder = {e: i for i, e in enumerate(dict.fromkeys(tidy["estimator"]))}
    out["_g"] = out["gyro"].map(gorder)
    out["_e"] = out["estimator"].map(eorder)
    out = out.sort_values(["_g", "_e", "_o"]).drop(columns=["_g", "_e", "_o"]).reset_index(drop=True)
    return out


def load_paper_table(path: Path) -> pd.DataFrame:
    """A paper's result table as long format: gyro, method, coefficient, mean, error_pct, std.

    Long tables (Lv et al. 2015) are read as they are. Wide tables (Miao et al. 2014, 2015: one row
    per gyro and coefficient, a column per method) are melted: a column ``<method>_mean``,
    ``<method>_indicator_pct`` or ``<method>_std`` gives that statistic of ``<method>``; any other
    numeric column (``allan_variance``, ``online``) is the mean of the method it names. The gyro
    is the ``gyro`` column, else ``fog`` (FOG number).
    """
    df = pd.read_csv(path, comment="#")
    if "method" in df.columns:
        need = {"gyro", "method", "coefficient", "mean"}
        if not need <= set(df.columns):
            raise ValueError(f"{path}: expected columns {sorted(need)} (long format), got {list(df.columns)}")
        return df
    gcol = next((c for c in ("gyro", "fog") if c in df.columns), None)
    if gcol is None or "coefficient" not in df.columns:
        raise ValueError(f"{path}: expected a 'gyro' (or 'fog') and a 'coefficient' column, got {list(df.columns)}")
    stats = {"_mean": "mean", "_indicator_pct": "error_pct", "_std": "std"}
    rows = []
    for _, r in df.iterrows():
        entries: dict = {}
        for col in df.columns:
            if col in (gcol, "coefficient") or not pd.api.types.is_numeric_dtype(df[col]) or col == "rate_hz":
                continue
            suffix = next((sfx for sfx in stats if col.endswith(sfx)), None)
            method, stat = (col[: -len(suffix)], stats[suffix]) if suffix else (col, "mean")
            entries.setdefault(method, {})[stat] = r[col]
        for method, vals in entries.items():
            rows.append({"gyro": str(r[gcol]), "method": method, "coefficient": r["coefficient"], **vals})
    return pd.DataFrame(rows)


def add_paper(summary: pd.DataFrame, paper: pd.DataFrame, gyro_map: dict, method_map: dict) -> pd.DataFrame:
    s = summary.copy()
    for col in ("paper_mean", "paper_error_pct", "paper_std"):
        s[col] = math.nan
    for i, r in s.iterrows():
        pg, pm = gyro_map.get(r["gyro"], r["gyro"]), method_map.get(r["estimator"])
        if pm is None:
            continue
        hit = paper[(paper["gyro"] == pg) & (paper["method"] == pm) & (paper["coefficient"] == r["coefficient"])]
        if len(hit):
            h = hit.iloc[0]
            s.at[i, "paper_mean"] = h["mean"]
            s.at[i, "paper_error_pct"] = h.get("error_pct", math.nan)
            s.at[i, "paper_std"] = h.get("std", math.nan)
    return s


def _fmt(x) -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "–"
    return f"{x:.4g}" if abs(x) >= 1e-3 and abs(x) < 1e5 else f"{x:.3e}"


def render_markdown(summary: pd.DataFrame, meta: dict | None = None) -> str:
    """One table per gyro in the papers' layout: rows = statistics per method, columns = coefficients."""
    meta = meta or {}
    out = []
    if meta.get("title"):
        out.append(f"# {meta['title']}\n")
    if meta.get("description"):
        out.append(meta["description"].strip() + "\n")
    for g, d in summary.groupby("gyro", sort=False):
        coefs = [c for c in COEFFICIENTS if c in set(d["coefficient"])]
        units = {c: d[d["coefficient"] == c]["unit"].iloc[0] for c in coefs}
        ginfo = meta.get("gyros", {}).get(g, {})
        head = f"## {g}"
        if ginfo:
            head += f" ({int(d['n'].max())} replicates of {ginfo.get('n_samples')} samples at dt = {ginfo.get('dt')} s)"
        out.append(head + "\n")
        cols = [f"{c} ({UNIT_LABEL.get(units[c], units[c])})" for c in coefs]
        out.append("| | " + " | ".join(cols) + " |")
        out.append("|---|" + "---|" * len(coefs))

        def cell(e, c, key):
            r = d[(d["estimator"] == e) & (d["coefficient"] == c)]
            return None if r.empty else r.iloc[0][key]

        true_cells = []
        for c in coefs:
            r = d[d["coefficient"] == c]
            true_cells.append(_fmt(r["true"].iloc[0]))
        out.append("| True value | " + " | ".join(true_cells) + " |")
        if "crlb_std" in d and np.isfinite(d["crlb_std"].astype(float)).any():
            out.append(
                "| CRLB std | "
                + " | ".join(_fmt(d[d["coefficient"] == c]["crlb_std"].iloc[0]) for c in coefs)
                + " |"
            )
        for e in dict.fromkeys(d["estimator"]):
            mean_cells, std_cells, bad_cells, paper_mean, paper_std = [], [], [], [], []
            has_paper = False
            for c in coefs:
                m, err, sd = cell(e, c, "mean"), cell(e, c, "error_pct"), cell(e, c, "std")
                if m is None:
                    mean_cells.append("")
                    std_cells.append("")
                    bad_cells.append("")
                else:
                    mean_cells.append(f"{_fmt(m)} ({err:.1f} %)" if err is not None and math.isfinite(err) else _fmt(m))
                    std_cells.append(_fmt(sd))
                    bad_cells.append(f"{int(cell(e, c, 'n_nonphysical'))} / {int(cell(e, c, 'n_failed'))}")
                pm = cell(e, c, "paper_mean") if "paper_mean" in d else None
                if pm is not None and math.isfinite(pm):
                    has_paper = True
                    pe = cell(e, c, "paper_error_pct")
                    paper_mean.append(f"{_fmt(pm)} ({pe:.1f} %)" if pe is not None and math.isfinite(pe) else _fmt(pm))
                    paper_std.append(_fmt(cell(e, c, "paper_std")))
                else:
                    paper_mean.append("")
                    paper_std.append("")
            out.append(f"| **{e}** mean (error) | " + " | ".join(mean_cells) + " |")
            out.append(f"| {e} std | " + " | ".join(std_cells) + " |")
            if any(b and b != "0 / 0" for b in bad_cells):
                out.append(f"| {e} non-physical / failed | " + " | ".join(bad_cells) + " |")
            if has_paper:
                out.append(f"| *paper* {e} mean (error) | " + " | ".join(paper_mean) + " |")
                out.append(f"| *paper* {e} std | " + " | ".join(paper_std) + " |")
        times = d.groupby("estimator", sort=False)["seconds_per_replicate"].first()
        out.append("")
        out.append("Fit time per replicate: " + ", ".join(f"{e} {t * 1e3:.0f} ms" for e, t in times.items()))
        out.append("")
    out.append(
        "Mean and std over the replicates with a physical estimate; error = |mean − true| / true × 100. "
        "'non-physical / failed' counts replicates where the fit gave no physical value (e.g. a negative "
        "AV-model coefficient, printed '–' by Lv et al. 2015) or failed (exception, divergence, non-finite)."
    )
    return "\n".join(out) + "\n"


def leaderboard(summary: pd.DataFrame) -> str:
    """Who wins where: per coefficient, each estimator over all gyros of the study.

    Only gyros that have the coefficient count. Columns: the number of gyros on which the
    estimator has the lowest RMSE (among those with a
    physical estimate in at least half the replicates), the median over gyros of the absolute error %, of the
    relative std (std / true), of std / CRLB, the share of replicates without a physical estimate,
    and the median fit time per replicate.
    """
    s = summary[np.isfinite(summary["true"]) & (summary["true"] > 0)].copy()  # gyros that have the term
    s["rel_rmse"] = s["rmse"] / s["true"]
    s["rel_std_pct"] = s["std"] / s["true"] * 100
    s["bad_share"] = (s["n_nonphysical"] + s["n_failed"]) / s["n"]
    if "std_over_crlb" not in s:
        s["std_over_crlb"] = math.nan
    ok = s[(s["n_ok"] >= np.ceil(s["n"] / 2)) & np.isfinite(s["rel_rmse"])]
    winners = ok.loc[ok.groupby(["gyro", "coefficient"])["rel_rmse"].idxmin()]
    out = ["# Who wins where", ""]
    out.append(leaderboard.__doc__.split("\n\n")[1].strip().replace("\n    ", " "))
    out.append("")
    for c in [c for c in COEFFICIENTS if c in set(s["coefficient"])]:
        d = s[s["coefficient"] == c]
        wins = winners[winners["coefficient"] == c]["estimator"].value_counts()
        g = d.groupby("estimator", sort=False)
        table = pd.DataFrame(
            {
                "gyros": g["gyro"].nunique(),
                "lowest RMSE on": wins.reindex(g.size().index).fillna(0).astype(int),
                "median abs. error %": g["error_pct"].median().round(1),
                "median std %": g["rel_std_pct"].median().round(1),
                "median std / CRLB": g["std_over_crlb"].median().round(2),
                "no estimate %": (g["bad_share"].mean() * 100).round(0),
                "time / replicate (s)": g["seconds_per_replicate"].median().round(3),
            }
        ).sort_values(["lowest RMSE on", "median std %"], ascending=[False, True])
        out.append(f"## {c}")
        out.append("")
        out.append("| estimator | " + " | ".join(table.columns) + " |")
        out.append("|---|" + "---|" * len(table.columns))
        for e, r in table.iterrows():
            cells = ["–" if pd.isna(v) else (str(int(v)) if k in ("gyros", "lowest RMSE on", "no estimate %") else f"{v:g}")
                     for k, v in r.items()]
            out.append(f"| {e} | " + " | ".join(cells) + " |")
        out.append("")
    return "\n".join(out) + "\n"


def render_latex(summary: pd.DataFrame) -> str:
    cols = ["gyro", "estimator", "coefficient", "unit", "true", "mean", "error_pct", "std", "n_nonphysical", "n_failed"]
    return summary[cols].to_latex(index=False, float_format=lambda x: f"{x:.4g}", na_rep="--")


def _crlb_column(cfg, summary: pd.DataFrame) -> pd.DataFrame:
    s = summary.copy()
    s["crlb_std"] = math.nan
    try:
        from estimators import crlb
    except ImportError:
        return s
    for gspec in cfg.gyros:
        try:
            bound = crlb(gspec.gyro, gspec.n_samples)
        except Exception:  # a model the bound does not cover: leave NaN
            continue
        for c in COEFFICIENTS:
            sel = (s["gyro"] == gspec.label) & (s["coefficient"] == c)
            if sel.any() and np.isfinite(bound.get(c, math.nan)):
                s.loc[sel, "crlb_std"] = from_si(c, float(bound[c]), s.loc[sel, "unit"].iloc[0])
    s["std_over_crlb"] = s["std"] / s["crlb_std"]
    return s


def _atomic_text(path: Path, text: str) -> None:
    tmp = path.with_name(path.name + f".{os.getpid()}.tmp")
    tmp.write_text(text)
    os.replace(tmp, path)


def write_report(cfg, tidy: pd.DataFrame, out: Path) -> pd.DataFrame:
    """table.csv, table.md, meta.json and figures for a study; returns the summary."""
    out = Path(out)
    summary = _crlb_column(cfg, summarize(tidy, getattr(cfg, 'units', None)))
    if cfg.paper_table is not None and Path(cfg.paper_table).is_file():
        paper = load_paper_table(cfg.paper_table)
        gmap = {g.label: g.paper_gyro for g in cfg.gyros if g.paper_gyro}
        mmap = {e.label: e.paper_method for e in cfg.estimators if e.paper_method}
        summary = add_paper(summary, paper, gmap, mmap)
    meta = {
        "title": f"Study {cfg.name}",
        "description": cfg.description,
        "seed": cfg.seed,
        "replicates": cfg.replicates,
        "result_key": cfg.result_key(),
        "gyros": {g.label: {"n_samples": g.n_samples, "dt": g.gyro.dt} for g in cfg.gyros},
        "paper_table": os.path.basename(str(cfg.paper_table)) if cfg.paper_table else None,
    }
    tmp = out / ("table.csv." + str(os.getpid()) + ".tmp")
    summary.to_csv(tmp, index=False)
    os.replace(tmp, out / "table.csv")
    _atomic_text(out / "meta.json", json.dumps(meta, indent=2))
    _atomic_text(out / "table.md", render_markdown(summary, meta))
    if len(cfg.gyros) > 1 or len(cfg.estimators) > 1:
        _atomic_text(out / "leaderboard.md", leaderboard(summary))
    if "lower" in tidy.columns:  # coverage, RMSE/CRLB, bias/SE and tested wins (studies.scoring)
        from studies.scoring import write_scores

        write_scores(cfg, tidy, out)
    from studies.figures import study_figures

    study_figures(cfg, tidy, out)
    return summary
