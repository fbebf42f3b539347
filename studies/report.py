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
import re
from pathlib import Path

import numpy as np
import pandas as pd

from avbench.noise_models.units import COEFFICIENTS, PAPER_UNITS, from_si
from avbench.outputs import TABLE_DIGITS, TIDY_DIGITS, atomic_write_text, markdown_cell

__all__ = ["summarize", "render_markdown", "render_latex", "write_report", "check_report", "read_summary",
           "read_tidy", "write_tidy", "timings"]

UNIT_LABEL = {
    "urad": "µrad",
    "arcsec": "arcsec",
    "deg": "deg",
    "deg/sqrt(h)": "deg/√h",
    "deg/h": "deg/h",
    "deg/h^1.5": "deg/h^1.5",
    "deg/h^2": "deg/h²",
}


def summarize(tidy: pd.DataFrame, units: dict | None = None, order: tuple | None = None) -> pd.DataFrame:
    """One row per gyro x estimator x coefficient (see the module docstring); absurd magnitudes give inf.

    ``order``: (gyro labels, estimator labels) as the config lists them; rows follow it (gyros and
    estimators not in it after, in the order they first appear). None: the order of appearance.
    """
    with np.errstate(over="ignore", invalid="ignore"):
        return _summarize(tidy, units, order)


def _summarize(tidy: pd.DataFrame, units: dict | None, order: tuple | None = None) -> pd.DataFrame:
    units = {**PAPER_UNITS, **(units or {})}
    rows = []
    corder = {c: i for i, c in enumerate(COEFFICIENTS)}
    for (g, e, c), d in tidy.groupby(["gyro", "estimator", "coefficient"], sort=False):
        u = units[c]
        true = from_si(c, float(d["true"].iloc[0]), u)
        ok = d[(d["failure"] == "") & ~d["nonphysical"] & np.isfinite(d["estimate"])]
        est = from_si(c, ok["estimate"].to_numpy(), u)
        mean = float(est.mean()) if est.size else math.nan
        std = float(est.std(ddof=1)) if est.size > 1 else math.nan
        rmse = float(np.sqrt(np.mean((est - true) ** 2))) if est.size and np.isfinite(true) else math.nan
        err = abs(mean - true) / true * 100 if np.isfinite(true) and true > 0 else math.nan
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
                "_o": corder[c],
            }
        )
    out = pd.DataFrame(rows)
    if out.empty:
        return out
    gyros, ests = order or ((), ())
    gorder = {g: i for i, g in enumerate(dict.fromkeys([*gyros, *tidy["gyro"]]))}
    eorder = {e: i for i, e in enumerate(dict.fromkeys([*ests, *tidy["estimator"]]))}
    out["_g"] = out["gyro"].map(gorder)
    out["_e"] = out["estimator"].map(eorder)
    out = out.sort_values(["_g", "_e", "_o"]).drop(columns=["_g", "_e", "_o"]).reset_index(drop=True)
    return out


def _fmt(x) -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "–"
    return f"{x:.4g}" if abs(x) >= 1e-3 and abs(x) < 1e5 else f"{x:.3e}"


_NOTE = (
    "Mean and std over the replicates with a physical estimate; error = |mean − true| / true × 100. "
    "'non-physical / failed' counts replicates where the fit gave no physical value (e.g. a negative "
    "AV-model coefficient, printed '–' by Lv et al. 2015) or failed (exception, divergence, non-finite). "
    "Units: the column headings' here and in `table.csv` (its `unit` column); SI in `tidy.csv` and "
    "`scores.csv` (their `unit` column)."
)


def paper_layout(summary: pd.DataFrame, meta: dict | None = None):
    """The papers' layout, one table per gyro: yields (gyro, heading, column labels, rows).

    Rows are (kind, label, cells) with kind "true", "crlb", "mean", "std", "bad", "paper_mean" or
    "paper_std"; cells are formatted strings, one per coefficient column. Markdown and LaTeX are
    both drawn from this, so they show the same numbers.
    """
    meta = meta or {}
    for g, d in summary.groupby("gyro", sort=False):
        coefs = [c for c in COEFFICIENTS if c in set(d["coefficient"])]
        units = {c: d[d["coefficient"] == c]["unit"].iloc[0] for c in coefs}
        ginfo = meta.get("gyros", {}).get(g, {})
        head = str(g)
        if ginfo:
            head += f" ({int(d['n'].max())} replicates of {ginfo.get('n_samples')} samples at dt = {ginfo.get('dt')} s)"
        cols = [f"{c} ({UNIT_LABEL.get(units[c], units[c])})" for c in coefs]

        first = {}  # (estimator, coefficient) -> its first row, looked up instead of filtering d per cell
        for _, row in d.iterrows():
            first.setdefault((row["estimator"], row["coefficient"]), row)

        def cell(e, c, key):
            r = first.get((e, c))
            return None if r is None or key not in d.columns else r[key]

        def with_error(m, err):
            return f"{_fmt(m)} ({err:.1f} %)" if err is not None and math.isfinite(err) else _fmt(m)

        rows = [("true", "True value", [_fmt(d[d["coefficient"] == c]["true"].iloc[0]) for c in coefs])]
        if "crlb_std" in d and np.isfinite(d["crlb_std"].astype(float)).any():
            rows.append(("crlb", "CRLB std", [_fmt(d[d["coefficient"] == c]["crlb_std"].iloc[0]) for c in coefs]))
        for e in dict.fromkeys(d["estimator"]):
            mean, std, bad, pmean, pstd = [], [], [], [], []
            for c in coefs:
                m = cell(e, c, "mean")
                if m is None:
                    mean.append(""), std.append(""), bad.append("")
                else:
                    mean.append(with_error(m, cell(e, c, "error_pct")))
                    std.append(_fmt(cell(e, c, "std")))
                    bad.append(f"{int(cell(e, c, 'n_nonphysical'))} / {int(cell(e, c, 'n_failed'))}")
                pm = cell(e, c, "paper_mean")
                if pm is not None and math.isfinite(pm):
                    pmean.append(with_error(pm, cell(e, c, "paper_error_pct")))
                    pstd.append(_fmt(cell(e, c, "paper_std")))
                else:
                    pmean.append(""), pstd.append("")
            rows += [("mean", f"{e} mean (error)", mean), ("std", f"{e} std", std)]
            if any(b and b != "0 / 0" for b in bad):
                rows.append(("bad", f"{e} non-physical / failed", bad))
            if any(pmean):
                rows += [("paper_mean", f"paper {e} mean (error)", pmean), ("paper_std", f"paper {e} std", pstd)]
        yield g, head, cols, rows


def render_markdown(summary: pd.DataFrame, meta: dict | None = None) -> str:
    """One table per gyro in the papers' layout: rows = statistics per method, columns = coefficients."""
    meta = meta or {}
    out = []
    if meta.get("title"):
        out.append(f"# {meta['title']}\n")
    if meta.get("description"):
        out.append(meta["description"].strip() + "\n")
    for g, head, cols, rows in paper_layout(summary, meta):
        out.append(f"## {head}\n")
        truth_curve = meta.get("gyros", {}).get(g, {}).get("truth_curve")
        if truth_curve:
            out.append(f"Truth curve (exact Allan variance) {truth_curve}; the true coefficients "
                       "below are those the terms declare.\n")
        out.append("| | " + " | ".join(cols) + " |")
        out.append("|---|" + "---|" * len(cols))
        for kind, label, cells in rows:
            if kind == "mean":
                label = "**" + label.replace(" mean (error)", "** mean (error)")
            elif kind.startswith("paper"):
                label = label.replace("paper ", "*paper* ", 1)
            out.append(f"| {markdown_cell(label)} | " + " | ".join(map(markdown_cell, cells)) + " |")
        out.append("")
    out += _against_paper(summary, meta)
    out.append(_NOTE + " Fit times: `timings.md` beside this file (measured on the machine that ran the study; "
               "not part of the compared results).")
    return "\n".join(out) + "\n"


#: a unit as LaTeX (text mode; exponents as math superscripts)
UNIT_TEX = {
    "urad": r"$\mu$rad",
    "deg/sqrt(h)": r"deg/$\sqrt{\mathrm{h}}$",
    "deg/h^1.5": r"deg/h$^{1.5}$",
    "deg/h^2": r"deg/h$^{2}$",
}


def _against_paper(summary: pd.DataFrame, meta: dict) -> list[str]:
    """The spreads against the paper's (the range of paper std / our std over the cells both give)
    and the departures the paper table explains, as lines of ``table.md``."""
    if "paper_std" not in summary.columns:
        return []
    with np.errstate(divide="ignore", invalid="ignore"):
        r = (summary["paper_std"].astype(float) / summary["std"].astype(float)).to_numpy()
    r = r[np.isfinite(r) & (r > 0)]
    out = []
    if r.size:
        out.append(f"**Against the paper.** Over the {r.size} cells where both give a standard deviation, the "
                   f"paper's is {r.min():.3g}–{r.max():.3g}× ours (median {np.median(r):.3g}×).")
    notes = [n.removeprefix("Departure:").strip() for n in meta.get("paper_notes", [])]
    out += [n[:1].upper() + n[1:] for n in notes if n]
    return [" ".join(out) + "\n"] if out else []


def _tex(text: str) -> str:
    repl = {"\\": r"\textbackslash{}", "&": r"\&", "%": r"\%", "$": r"\$", "#": r"\#", "_": r"\_",
            "{": r"\{", "}": r"\}", "~": r"\textasciitilde{}", "^": r"\^{}", "µ": r"$\mu$", "√": r"$\surd$",
            "²": r"$^{2}$", "–": "--", "−": "$-$", "×": r"$\times$"}
    return "".join(repl.get(ch, ch) for ch in str(text))


def _tex_cell(text: str) -> str:
    """A table cell as LaTeX: 8.587e-05 as $8.587\\times 10^{-5}$."""
    return re.sub(r"(-?\d(?:\.\d+)?)e([+-]\d+)", lambda m: f"${m[1]}\\times 10^{{{int(m[2])}}}$", _tex(text))


def _tex_unit(unit: str) -> str:
    return UNIT_TEX.get(unit) or _tex(UNIT_LABEL.get(unit, unit))


def _tex_record(n: int, dt: float) -> str:
    return f"{n:,} samples at $\\Delta t = {dt:g}$~s ({n * dt / 3600:.3g}~h)"


def _tex_caption(summary: pd.DataFrame, meta: dict) -> str:
    """The caption: the study, its replicates, seed and records, what each row means, and where a paper
    table is attached, its spreads against ours and the departures it explains (as in ``table.md``)."""
    parts = [_tex(meta.get("title") or "Study") + "."]
    if meta.get("description"):
        parts.append(_tex(meta["description"].strip().rstrip(".")) + ".")
    reps = int(summary["n"].max()) if len(summary) else 0
    groups: dict = {}  # (samples, dt) -> gyros
    for g, info in meta.get("gyros", {}).items():
        if info.get("n_samples") and info.get("dt"):
            groups.setdefault((info["n_samples"], info["dt"]), []).append(_tex(g))
    if len(groups) == 1:
        records = "records: " + _tex_record(*next(iter(groups)))
    elif groups and len(groups) <= 3:
        records = "records: " + "; ".join(f"{', '.join(gs)}: {_tex_record(*k)}" for k, gs in groups.items())
    else:
        records = "each gyro's record in its heading" if groups else ""
    parts.append(f"{reps} replicates" + (f" (seed {meta['seed']})" if meta.get("seed") is not None else "")
                 + (f"; {records}" if records else "") + ".")
    parts.append("Mean and std over the replicates with a physical estimate; error "
                 "$= |\\bar{x} - x_0| / x_0 \\times 100$; CRLB std: the Cram\\'er-Rao bound on the standard deviation "
                 "of an unbiased estimator for the record length; non-physical / failed: replicates whose fit gave "
                 "no physical value or failed; paper rows in italics.")
    parts += [_tex(line.replace("**", "").strip()) for line in _against_paper(summary, meta)]
    return " ".join(parts)


#: gyros per LaTeX ``table`` float (a float taller than a page cannot be set)
LATEX_GYROS_PER_TABLE = 6


def render_latex(summary: pd.DataFrame, meta: dict | None = None) -> str:
    """One captioned ``table`` (booktabs) holding :func:`render_markdown`'s tables, one ``tabular`` per
    gyro headed by its name; the caption states the replicates, the seed, each record's length and
    sampling interval, and the rows' definitions. The cells are :func:`paper_layout`'s, so the numbers
    equal ``table.md``'s. Needs ``\\usepackage{booktabs}``. A float cannot break across pages, so a study
    of more than :data:`LATEX_GYROS_PER_TABLE` gyros continues in further ``table`` floats, each
    captioned "(continued)"."""
    meta = meta or {}
    units = dict(zip(summary["coefficient"], summary["unit"])) if len(summary) else {}
    name = re.sub(r"[^A-Za-z0-9]+", "-", str(meta.get("title", "study")).removeprefix("Study ")).strip("-")
    out = ["% needs \\usepackage{booktabs}", "\\begin{table}", "\\centering", "\\small",
           f"\\caption{{{_tex_caption(summary, meta)}}}", f"\\label{{tab:{name or 'study'}}}"]
    for i, (g, _, cols, rows) in enumerate(paper_layout(summary, meta)):
        coefs = [c.split(" ", 1)[0] for c in cols]
        if i and i % LATEX_GYROS_PER_TABLE == 0:
            part = i // LATEX_GYROS_PER_TABLE + 1
            out += ["\\end{table}", "", "\\begin{table}", "\\centering", "\\small",
                    f"\\caption{{{_tex(meta.get('title') or 'Study')} (continued).}}",
                    f"\\label{{tab:{name or 'study'}-{part}}}"]
        elif i:
            out.append("\\par\\medskip")
        out.append("\\begin{tabular}{l" + "r" * len(cols) + "}")
        out.append("\\toprule")
        info = meta.get("gyros", {}).get(g, {})
        record = f" ({_tex_record(info['n_samples'], info['dt'])})" if info.get("n_samples") and info.get("dt") else ""
        out.append(f"\\multicolumn{{{len(cols) + 1}}}{{l}}{{\\textbf{{{_tex(g)}}}{record}}} \\\\")
        out.append("\\midrule")
        out.append(" & " + " & ".join(f"{c} ({_tex_unit(units.get(c, ''))})" for c in coefs) + r" \\")
        out.append("\\midrule")
        for kind, label, cells in rows:
            if kind.startswith("paper"):
                line = f"\\textit{{{_tex(label)}}} & " + " & ".join(f"\\textit{{{_tex_cell(x)}}}" if x else ""
                                                                  for x in cells)
            elif kind == "mean":
                line = f"\\textbf{{{_tex(label)}}} & " + " & ".join(_tex_cell(x) for x in cells)
            else:
                line = f"{_tex(label)} & " + " & ".join(_tex_cell(x) for x in cells)
            out.append(line + r" \\")
        out.append("\\bottomrule")
        out.append("\\end{tabular}")
    out.append("\\end{table}")
    return "\n".join(out) + "\n"


def leaderboard(summary: pd.DataFrame, wins: pd.DataFrame | None = None) -> str:
    """Who wins where: per coefficient, each estimator over all gyros of the study.

    Only gyros that have the coefficient count. A *tested win* is a gyro on which the estimator has
    the lowest RMSE (among those with a physical estimate in at least half the replicates) and beats
    each other such estimator in a paired test on the same replicates, Holm-adjusted over every pair
    of the study (studies.scoring.wins: between identical estimators a win anywhere in the study has
    probability at most 0.05); *tied for best* counts gyros where it has the lowest RMSE without
    beating every other one, or is one of those the lowest does not beat, or competes alone. Then
    the medians over gyros of RMSE / CRLB (the Cramer-Rao bound for the record length), of the
    absolute bias over SE (the bias over its Monte Carlo standard error std / sqrt(replicates): above
    ~2 the bias is real), of the absolute error of the mean %, and the share of replicates without a
    physical estimate (fit times: timings.md; the tests, their intervals and the ties: scores.md).

    ``wins``: the paired comparisons of :func:`avbench.studies.scoring.wins` (none: no tested wins).
    """
    s = summary[np.isfinite(summary["true"]) & (summary["true"] > 0)].copy()  # gyros that have the term
    s["bad_share"] = (s["n_nonphysical"] + s["n_failed"]) / s["n"]
    crlb = s["crlb_std"] if "crlb_std" in s else pd.Series(math.nan, index=s.index)
    with np.errstate(divide="ignore", invalid="ignore"):
        s["rmse_over_crlb"] = s["rmse"] / crlb
        s["abs_bias_over_se"] = (s["mean"] - s["true"]).abs() / (s["std"] / np.sqrt(s["n_ok"]))
    w = wins if wins is not None else pd.DataFrame(columns=["coefficient", "best", "tied", "verdict"])
    out = ["# Who wins where", ""]
    out.append(" ".join(line.strip() for line in leaderboard.__doc__.split("\n\n")[1].splitlines()))
    out.append("")
    for c in [c for c in COEFFICIENTS if c in set(s["coefficient"])]:
        d = s[s["coefficient"] == c]
        wc = w[w["coefficient"] == c]
        g = d.groupby("estimator", sort=False)
        idx = g.size().index

        won = wc[wc["verdict"] == "win"]["best"].value_counts().reindex(idx).fillna(0).astype(int)
        unsettled = wc[wc["verdict"] != "win"]
        tied = pd.Series([e for best, others in zip(unsettled["best"], unsettled["tied"]) for e in (best, *others)],
                         dtype=object)
        tied = tied.value_counts().reindex(idx).fillna(0).astype(int)

        table = pd.DataFrame(
            {
                "gyros": g["gyro"].nunique(),
                "tested wins": won,
                "tied for best": tied,
                "median RMSE / CRLB": g["rmse_over_crlb"].median().round(2),
                "median abs. bias / SE": g["abs_bias_over_se"].median().round(1),
                "median abs. error %": g["error_pct"].median().round(1),
                "no estimate %": (g["bad_share"].mean() * 100).round(0),
            }
        )
        table["_r"] = table["median RMSE / CRLB"].fillna(np.inf)
        table = table.sort_values(["tested wins", "tied for best", "_r"], ascending=[False, False, True]).drop(columns="_r")
        out.append(f"## {c}")
        out.append("")
        out.append("| estimator | " + " | ".join(table.columns) + " |")
        out.append("|---|" + "---|" * len(table.columns))
        ints = ("gyros", "tested wins", "tied for best", "no estimate %")
        for e, r in table.iterrows():
            cells = ["–" if pd.isna(v) else (str(int(v)) if k in ints else f"{v:g}") for k, v in r.items()]
            out.append(f"| {markdown_cell(e)} | " + " | ".join(cells) + " |")
        out.append("")
    return "\n".join(out) + "\n"


def _crlb_column(bounds: dict, summary: pd.DataFrame) -> pd.DataFrame:
    """``crlb_std`` (the Cramer-Rao bound, in each row's unit) and ``std_over_crlb`` from ``bounds``
    (:func:`avbench.studies.scoring.crlb_table`: {(gyro, coefficient): bound in SI})."""
    s = summary.copy()
    s["crlb_std"] = math.nan
    for (g, c), b in bounds.items():
        sel = (s["gyro"] == g) & (s["coefficient"] == c)
        if sel.any() and np.isfinite(b):
            s.loc[sel, "crlb_std"] = from_si(c, float(b), s.loc[sel, "unit"].iloc[0])
    s["std_over_crlb"] = s["std"] / s["crlb_std"]
    return s


#: the file written last: its presence says the report is complete, and it lists every output with
#: its SHA-256, so a folder whose report was interrupted (or edited) is recognised as such
MARKER = "meta.json"
TIDY_FILE = "tidy.csv"


def write_tidy(tidy: pd.DataFrame, out: Path) -> Path:
    """The tidy per-replicate table (no timings) as CSV at :data:`TIDY_DIGITS` significant digits, with
    a ``unit`` column after ``coefficient``: the SI unit of its row's ``true``, ``estimate``,
    ``std_err``, ``lower`` and ``upper``."""
    from avbench.noise_models.units import si_units

    path = Path(out) / TIDY_FILE
    cols = [c for c in tidy.columns if c not in ("seconds", "unit")]
    table = tidy[cols].copy()
    table.insert(cols.index("coefficient") + 1, "unit", tidy["coefficient"].map(si_units()))
    atomic_write_text(path, table.to_csv(index=False, float_format=f"%.{TIDY_DIGITS}g"))
    return path


def read_tidy(folder) -> pd.DataFrame:
    """The tidy table of a finished study folder (``failure`` is "" on success)."""
    nan = ["nan", "NaN", ""]
    d = pd.read_csv(Path(folder) / TIDY_FILE, keep_default_na=False,
                    na_values={c: nan for c in ("true", "estimate", "std_err", "lower", "upper",
                                                "evidence_lr", "evidence_p")})
    d["failure"] = d["failure"].astype(str)
    d["nonphysical"] = d["nonphysical"].astype(str).str.lower().eq("true")
    return d


def record_hours(cfg) -> float:
    """The study's record length in hours (its longest gyro record)."""
    return max(g.n_samples * g.gyro.dt for g in cfg.gyros) / 3600


def finished_studies_parser(prog: str, description: str, default_out: str):
    """Command-line parser of the summaries that read finished studies (``avbench.studies.summaries.selection``,
    ``avbench.studies.summaries.record_length``): the study configs, ``--results`` and ``--out``."""
    import argparse

    ap = argparse.ArgumentParser(prog=prog, description=description)
    ap.add_argument("configs", nargs="+", help="study TOML files, one per record length")
    ap.add_argument("--results", default="results", help="folder holding results/<study name> (default results)")
    ap.add_argument("--out", default=default_out, help=f"output folder (default {default_out})")
    return ap


def parse_finished(ap, argv=None):
    """``(args, [(config, tidy), ...])`` from a :func:`finished_studies_parser`; a config or tidy
    table that cannot be read is a usage error (exit status 2, naming it)."""
    a = ap.parse_args(argv)
    try:
        return a, [read_finished(path, a.results) for path in a.configs]
    except ValueError as e:
        ap.error(str(e))


def read_finished(config_path, results="results"):
    """``(config, tidy table)`` of the finished study configured in ``config_path``, read from
    ``<results>/<study name>``; ``ValueError`` (naming the config or the missing table and the
    command that makes it) if either cannot be read."""
    from avbench.studies.config import ConfigError, load_config

    try:
        cfg = load_config(config_path)
    except (ConfigError, OSError) as e:
        raise ValueError(str(e)) from None
    folder = Path(results) / cfg.name
    if not (folder / TIDY_FILE).is_file():
        raise ValueError(f"{folder / TIDY_FILE}: not found; run 'avbench run {config_path}' first")
    return cfg, read_tidy(folder)


def timings(tidy: pd.DataFrame) -> pd.DataFrame:
    """Fit time per replicate of each gyro x estimator (median, mean, max seconds)."""
    per = tidy.groupby(["gyro", "estimator", "replicate"], sort=False)["seconds"].first().reset_index()
    t = per.groupby(["gyro", "estimator"], sort=False)["seconds"].agg(["median", "mean", "max", "count"])
    return t.rename(columns={"count": "replicates"}).assign(unit="s").reset_index()


def render_timings(t: pd.DataFrame, meta: dict) -> str:
    lines = [f"# Fit times: {meta.get('title', '')}", "",
             "Seconds per replicate, measured on the machine that ran the study (not part of the compared "
             "results; not committed).", "",
             "| gyro | estimator | median s | mean s | max s | replicates |", "|---|---|---|---|---|---|"]
    for _, r in t.iterrows():
        lines.append(f"| {markdown_cell(r['gyro'])} | {markdown_cell(r['estimator'])} | {r['median']:.3g} | {r['mean']:.3g} | {r['max']:.3g} "
                     f"| {int(r['replicates'])} |")
    return "\n".join(lines) + "\n"


def _sha256(path: Path) -> str:
    import hashlib

    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def _truth_curve(gyro) -> dict:
    """``{"truth_curve": reason}`` when the gyro has a term without an exact AV, else nothing."""
    missing = [type(t).__name__ for t in gyro.terms if not getattr(t, "has_exact_avar", True)]
    if not missing:
        return {}
    return {"truth_curve": f"unavailable: term {', '.join(missing)} has no exact Allan variance"}


def write_report(cfg, tidy: pd.DataFrame, out: Path, executor=None) -> pd.DataFrame:
    """tidy.csv, table.csv, table.md, leaderboard.md, figures and (last) meta.json; returns the summary
    (``attrs["table.md"]``: the text of table.md).

    The set changes as one: the marker ``meta.json`` is removed first and written last with the
    SHA-256 of every output, so an interrupted report is recognised (:func:`check_report`) instead
    of being read as a mix of two runs. Fit times go to ``timings.md`` / ``timings.csv``, outside
    the compared set.

    ``executor``: a pool of local worker processes (``concurrent.futures``; the study's own, which
    share this disk) that draws the figures, one task per figure, while this process writes the
    tables; the same figures, drawn by the same code from the same rows. ``None``: drawn here.
    """
    out = Path(out)
    (out / MARKER).unlink(missing_ok=True)  # incomplete from here until the new marker is written
    from avbench.studies.scoring import crlb_table, wins, write_scores

    # every output is computed from tidy.csv as stored (TIDY_DIGITS), so the tables are a function of
    # the committed file: re-rendering a committed tidy.csv reproduces them byte for byte
    written = [write_tidy(tidy, out)]
    stored = read_tidy(out)
    if "seconds" in tidy:
        stored["seconds"] = tidy["seconds"].to_numpy()
    tidy = stored
    drawing = _start_figures(cfg, tidy, out, executor) if executor is not None else None

    # computed once, for the tables and the scores, at the 12 digits meta.json keeps (the digits a
    # machine's linear algebra decides; the tables re-rendered from meta.json then equal these)
    bounds = {k: float(f"{b:.12g}") for k, b in crlb_table(cfg).items()}
    order = ([g.label for g in cfg.gyros], [e.label for e in cfg.estimators])
    summary = _crlb_column(bounds, summarize(tidy, getattr(cfg, "units", None), order))
    if cfg.paper_table is not None:  # validated by the config: a missing table is a ConfigError there
        from avbench.studies.papers import add_paper, load_paper_table, paper_notes

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
        "gyros": {g.label: {"n_samples": g.n_samples, "dt": g.gyro.dt, **_truth_curve(g.gyro)} for g in cfg.gyros},
        "paper_table": os.path.basename(str(cfg.paper_table)) if cfg.paper_table else None,
        "estimators": order[1],
        "units": dict(getattr(cfg, "units", None) or {}),
        # the Cramer-Rao std bounds in SI at full precision: the tables re-rendered from tidy.csv need them
        "crlb": {g: {c: b for (gg, c), b in bounds.items() if gg == g and np.isfinite(b)} for g in order[0]},
    }
    if cfg.paper_table is not None:
        meta["paper_notes"] = paper_notes(cfg.paper_table)
    from avbench.studies.provenance import environment, provenance

    meta["provenance"] = provenance(cfg)  # the code, versions and resolved config behind the rows
    atomic_write_text(out / "environment.json", json.dumps(environment(), indent=2) + "\n")
    atomic_write_text(out / "table.csv", summary.to_csv(index=False, float_format=f"%.{TABLE_DIGITS}g"))
    summary.attrs["table.md"] = render_markdown(summary, meta)  # what the command prints: this run's own table
    atomic_write_text(out / "table.md", summary.attrs["table.md"])
    written += [out / "table.csv", out / "table.md"]
    w = wins(tidy)  # the paired bootstrap comparisons, once, for the leaderboard and the scores
    if len(cfg.gyros) > 1 or len(cfg.estimators) > 1:
        atomic_write_text(out / "leaderboard.md", leaderboard(summary, w))
        written.append(out / "leaderboard.md")
    if "lower" in tidy.columns:  # coverage, RMSE/CRLB, bias/SE and tested wins (avbench.studies.scoring)
        written += write_scores(tidy, out, bounds, w)
    if "seconds" in tidy:
        t = timings(tidy)
        atomic_write_text(out / "timings.csv", t.to_csv(index=False, float_format="%.4g"))
        atomic_write_text(out / "timings.md", render_timings(t, meta))
    if drawing is None:
        from avbench.studies.figures import study_figures

        written += study_figures(cfg, tidy, out)
    else:
        written += _finish(drawing)
    meta["outputs"] = {p.name: _sha256(p) for p in sorted(written, key=lambda p: p.name)}
    atomic_write_text(out / MARKER, json.dumps(meta, indent=2) + "\n")
    return summary


def _draw_figure(cfg, tidy: pd.DataFrame, kind: str, gi: int, path: Path) -> Path:
    """One figure, in a worker process (it imports matplotlib there, not in the study's process)."""
    cfg.import_plugins()
    from avbench.studies.figures import render_figure

    return render_figure(cfg, tidy, kind, gi, path)


def _start_figures(cfg, tidy: pd.DataFrame, out: Path, executor) -> list:
    """Submit every figure of the report to ``executor``, each with its gyro's rows only."""
    from avbench.studies.figure_files import figure_jobs
    from avbench.studies.workers import submit

    return [submit(executor, _draw_figure, cfg, tidy[tidy["gyro"] == cfg.gyros[gi].label], kind, gi, path)
            for kind, gi, path in figure_jobs(cfg, tidy, out)]


def _finish(futures: list) -> list[Path]:
    """The paths the figure tasks wrote; the first error raised (the other tasks cancelled)."""
    try:
        return [f.result() for f in futures]
    except BaseException:
        for f in futures:
            f.cancel()
        raise


def check_report(folder) -> dict:
    """The ``meta.json`` of a complete study report in ``folder``; ValueError saying what is wrong."""
    d = Path(folder)
    if not d.is_dir():
        raise ValueError(f"{d}: not a folder; expected the output folder of 'avbench run'")
    marker = d / MARKER
    if not marker.is_file():
        if (d / "table.csv").exists() or (d / "_shards").is_dir():
            raise ValueError(f"{d}: the report is incomplete (no {MARKER}: interrupted while it was written); "
                             "rerun the same 'avbench run' command to finish it")
        raise ValueError(f"{d}: no {MARKER} here; expected the output folder of 'avbench run'")
    try:
        meta = json.loads(marker.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise ValueError(f"{marker}: unreadable or not JSON ({e}); expected the {MARKER} 'avbench run' writes") from None
    if not isinstance(meta, dict) or not isinstance(meta.get("outputs"), dict):
        raise ValueError(f"{marker}: no 'outputs' list; expected the {MARKER} of a complete report "
                         "(a report from an older avbench: rerun the study)")
    for name, digest in meta["outputs"].items():
        p = d / str(name)
        if not p.is_file():
            raise ValueError(f"{d}: {name} is missing; the report is incomplete (rerun the study)")
        if _sha256(p) != digest:
            raise ValueError(f"{d}: {name} does not belong to this report (changed after it was written, or "
                             "an interrupted rerun); rerun the study")
    return meta


def read_summary(folder) -> tuple[pd.DataFrame, dict]:
    """(summary, meta) of a complete report, at full precision: the summary recomputed from ``tidy.csv``
    as :func:`write_report` computed it (the bounds from ``meta.json``, the paper's figures from
    ``table.csv``), so that every table rendered from it equals ``table.md``. A report without the
    bounds in its ``meta.json`` gives ``table.csv`` as it is. ValueError naming the file and what was
    expected."""
    summary, meta = _read_table_csv(folder)
    if "crlb" not in meta or not (Path(folder) / TIDY_FILE).is_file():
        return summary, meta
    full = summarize(read_tidy(folder), meta.get("units"), (list(meta.get("gyros", {})), meta.get("estimators", [])))
    bounds = {(g, c): b for g, d in meta["crlb"].items() for c, b in d.items()}
    full = _crlb_column(bounds, full)
    paper = [c for c in ("paper_mean", "paper_error_pct", "paper_std") if c in summary.columns]
    if paper:
        key = ["gyro", "estimator", "coefficient"]
        full = full.merge(summary[key + paper].astype({"gyro": str, "estimator": str}), on=key, how="left")
    return full, meta


def _read_table_csv(folder) -> tuple[pd.DataFrame, dict]:
    meta = check_report(folder)
    path = Path(folder) / "table.csv"
    try:
        summary = pd.read_csv(path)
    except Exception as e:
        raise ValueError(f"{path}: unreadable ({type(e).__name__}: {str(e).splitlines()[0][:200]})") from None
    need = {"gyro", "estimator", "coefficient", "unit", "true", "mean", "error_pct", "std", "n",
            "n_nonphysical", "n_failed"}
    missing = sorted(need - set(summary.columns))
    if missing:
        raise ValueError(f"{path}: missing column(s) {missing}; expected the table.csv 'avbench run' writes")
    return summary, meta
