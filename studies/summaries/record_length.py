"""What a longer record buys: where K and R become estimable, and the accuracy targets, by length.

Reads studies of the same gyros at different record lengths (``grand_comparison_2h`` and
``grand_comparison_24h``) from their tidy tables and writes, in ``--out``:

``record_length.csv`` / ``.md``
    per record length, gyro and present coefficient: the Cramér-Rao relative std (CRLB std over
    the true value; none for the deterministic ramp R), the estimator with the lowest RMSE among
    those with a physical estimate in at least half the replicates (as in ``avbench.studies.scoring.wins``),
    its RMSE over the true value and over the CRLB, and the relative RMSE of each compared
    estimator (``--estimators``). The K rows also give the record length at which the CRLB
    relative std of K falls below 30 % (the selection target's threshold) and 50 %.
``targets.csv`` / ``.md``
    the accuracy targets of the study plan, each with a 95 % interval from the replicates:
    (1) on every gyro and each present Q, N, B, the best estimator's RMSE <= 1.2 CRLB;
    (2) ``whittle`` (every configured variant) within 1.3 CRLB, with |bias| < 0.3 CRLB, for every
    present coefficient whose CRLB relative std is < 50 %, on the gyros whose bias instability is
    flicker noise. RMSE/CRLB intervals: percentile bootstrap over replicates (``N_BOOT`` draws,
    fixed seed); bias/CRLB intervals: +-1.96 Monte Carlo standard errors. ``met`` is judged on the
    point value; ``clear`` says whether the interval lies on the same side of the threshold.
``crossover.png``
    relative RMSE of K (and of R where present) against the record length, one panel per gyro: the
    CRLB relative std as a curve (the longest study's gyro; R has none), the compared estimators'
    measured relative RMSE at each length, the 30 % and 100 % lines.

Usage::

    python -m avbench.studies.summaries.record_length studies/grand_comparison_2h.toml studies/grand_comparison_24h.toml \\
        --out results/record_length
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd

from avbench.studies.report import record_hours

__all__ = ["length_table", "targets_table", "crlb_curve", "crossover_figure", "main"]

N_BOOT = 2000
#: registered estimators compared by default (every configured variant of each)
DEFAULT_COMPARED = ("whittle", "gmwm", "mle", "wls_edf", "slope_lines")
#: thresholds of the targets
BEST_QNB_MAX = 1.2
WHITTLE_MAX = 1.3
WHITTLE_BIAS_MAX = 0.3
WHITTLE_CRLB_REL_MAX = 0.5
#: CRLB relative std levels at which the record length of K is reported
K_LEVELS = (0.3, 0.5)


def _has_flicker(gyro) -> bool:
    return any(type(t).__name__ == "BiasInstability" for t in gyro.terms)


def length_table(tidy: pd.DataFrame, cfg, compared: list[str], bounds: dict) -> pd.DataFrame:
    """Per gyro x present coefficient of one study: CRLB relative std, best estimator, relative RMSEs
    (``bounds``: the study's :func:`avbench.studies.scoring.crlb_table`)."""
    from avbench.studies.scoring import comparable, scores

    sc = scores(tidy, bounds)
    sc = sc[np.isfinite(sc["true"]) & (sc["true"] > 0)]
    ok = comparable(sc)
    rows = []
    for (g, c), d in sc.groupby(["gyro", "coefficient"], sort=False):
        true = float(d["true"].iloc[0])
        ranked = ok[(ok["gyro"] == g) & (ok["coefficient"] == c)].sort_values("rmse")
        best = ranked.iloc[0] if len(ranked) else None
        row = {"hours": record_hours(cfg), "gyro": g, "coefficient": c, "crlb_rel": float(d["crlb"].iloc[0]) / true,
               "best": "" if best is None else best["estimator"],
               "best_rel_rmse": math.nan if best is None else float(best["rmse"]) / true,
               "best_rmse_over_crlb": math.nan if best is None else float(best["rmse_over_crlb"])}
        rmse = ranked.set_index("estimator")["rmse"]
        for e in compared:
            row[f"rel_rmse[{e}]"] = float(rmse[e]) / true if e in rmse.index else math.nan
        rows.append(row)
    return pd.DataFrame(rows)


def _ok_errors(tidy, gyro, estimator, coefficient) -> np.ndarray:
    """Estimate - truth over the replicates with a physical estimate."""
    from avbench.studies.scoring import _ok

    ok = _ok(tidy[(tidy["gyro"] == gyro) & (tidy["estimator"] == estimator) & (tidy["coefficient"] == coefficient)])
    return (ok["estimate"] - ok["true"]).to_numpy(float)


def _rmse_interval(err: np.ndarray, seed: int) -> tuple[float, float]:
    if err.size < 3:
        return math.nan, math.nan
    rng = np.random.default_rng(seed)
    boot = np.sqrt((err[rng.integers(0, err.size, size=(N_BOOT, err.size))] ** 2).mean(axis=1))
    lo, hi = np.quantile(boot, [0.025, 0.975])
    return float(lo), float(hi)


def targets_table(tidy: pd.DataFrame, cfg, lengths: pd.DataFrame, bounds: dict) -> pd.DataFrame:
    """The two accuracy targets of one study (module docstring), one row per checked cell."""
    names = {e.label: e.name for e in cfg.estimators}
    flicker = {g.label: _has_flicker(g.gyro) for g in cfg.gyros}
    rows = []

    def check(target, g, c, e, limit):
        err = _ok_errors(tidy, g, e, c)
        bound = bounds.get((g, c), math.nan)
        if not err.size or not bound > 0:
            return
        ratio = math.sqrt(float(np.mean(err ** 2))) / bound
        lo, hi = (v / bound for v in _rmse_interval(err, seed=len(rows)))
        bias = float(err.mean()) / bound
        se = float(err.std(ddof=1)) / math.sqrt(err.size) / bound if err.size > 1 else math.nan
        row = {"hours": record_hours(cfg), "target": target, "gyro": g, "coefficient": c, "estimator": e,
               "replicates": err.size, "rmse_over_crlb": ratio, "rmse_lo": lo, "rmse_hi": hi,
               "limit": limit, "bias_over_crlb": bias, "bias_lo": bias - 1.96 * se, "bias_hi": bias + 1.96 * se}
        # each criterion: (met on the point value, interval wholly on that side)
        crit = [(ratio <= limit, hi <= limit if ratio <= limit else lo > limit)]
        if target == "whittle":
            inside = abs(bias) < WHITTLE_BIAS_MAX
            lo_b, hi_b = row["bias_lo"], row["bias_hi"]
            crit.append((inside, max(abs(lo_b), abs(hi_b)) < WHITTLE_BIAS_MAX if inside
                         else lo_b >= WHITTLE_BIAS_MAX or hi_b <= -WHITTLE_BIAS_MAX))
        met = all(m for m, _ in crit)
        row["met"] = met
        row["clear"] = all(sure for _, sure in crit) if met else any(sure for ok, sure in crit if not ok)
        rows.append(row)

    for _, r in lengths.iterrows():
        g, c = r["gyro"], r["coefficient"]
        if c in ("Q", "N", "B") and r["best"]:
            check("best_QNB", g, c, r["best"], BEST_QNB_MAX)
        if flicker.get(g) and np.isfinite(r["crlb_rel"]) and r["crlb_rel"] < WHITTLE_CRLB_REL_MAX:
            for e in (lab for lab, n in names.items() if n == "whittle"):
                check("whittle", g, c, e, WHITTLE_MAX)
    return pd.DataFrame(rows)


def crlb_curve(gyro, hours) -> np.ndarray:
    """CRLB relative std of every coefficient of ``gyro`` at each record length (rows: lengths;
    columns Q, N, B, K, R)."""
    from avbench.estimators.likelihood.crlb import crlb
    from avbench.noise_models.units import COEFFICIENTS

    truth = gyro.coefficients
    out = np.full((len(hours), len(COEFFICIENTS)), math.nan)
    for i, h in enumerate(hours):
        b = crlb(gyro, int(round(h * 3600 / gyro.dt)))
        for j, c in enumerate(COEFFICIENTS):
            if np.isfinite(truth[c]) and truth[c] > 0:
                out[i, j] = b[c] / truth[c]
    return out


def _crossing(hours, rel, level) -> float:
    """Record length (h) at which a decreasing relative std falls to ``level`` (log-log interpolation)."""
    rel = np.asarray(rel, float)
    below = np.flatnonzero(rel <= level)
    if not below.size:
        return math.nan
    i = below[0]
    if i == 0:
        return float(hours[0]) if rel[0] == level else math.nan
    x0, x1, y0, y1 = np.log(hours[i - 1]), np.log(hours[i]), np.log(rel[i - 1]), np.log(rel[i])
    return float(np.exp(x0 + (np.log(level) - y0) * (x1 - x0) / (y1 - y0)))


def crossover_figure(table: pd.DataFrame, curves: dict, grid, compared: list[str]):
    """Relative RMSE of K and R against record length, one panel per gyro x coefficient."""
    import matplotlib.ticker

    from avbench.studies.figures import plt, series_style

    plain = matplotlib.ticker.FuncFormatter(lambda v, _: f"{v:g}")
    cells = [(g, c) for c in ("K", "R") for g in dict.fromkeys(table["gyro"])
             if ((table["gyro"] == g) & (table["coefficient"] == c)).any()]
    ncol = min(4, len(cells))
    nrow = math.ceil(len(cells) / ncol)
    # at least 7 in wide: the title and the legend below the panels fit however few panels there are
    fig, axes = plt.subplots(nrow, ncol, figsize=(max(2.9 * ncol, 7.0), 2.5 * nrow + (0.9 if ncol > 2 else 1.4)),
                             sharex=True, squeeze=False)
    hours = sorted(table["hours"].unique())
    col = {"K": 3, "R": 4}
    for ax, (g, c) in zip(axes.flat, cells):
        d = table[(table["gyro"] == g) & (table["coefficient"] == c)].sort_values("hours")
        if g in curves and np.isfinite(curves[g][:, col[c]]).any():
            ax.plot(grid, curves[g][:, col[c]], color="k", lw=1.6, label="CRLB rel. std")
        for i, e in enumerate(compared):
            y = d[f"rel_rmse[{e}]"].to_numpy(float)
            st = series_style(i)
            ax.plot(d["hours"], y, "o-", color=st["color"], lw=0.9, ms=4, label=e)
        ax.plot(d["hours"], d["best_rel_rmse"], "*", color="k", ms=8, mfc="none", label="best (lowest RMSE)")
        for lvl in (0.3, 1.0):
            ax.axhline(lvl, color="0.5", ls="--" if lvl < 1 else ":", lw=0.8)
        ax.set_xscale("log")
        ax.set_yscale("log")
        lo, hi = ax.get_ylim()
        ax.set_ylim(min(lo, 0.2), max(hi, 1.5))
        ax.yaxis.set_major_locator(matplotlib.ticker.LogLocator(subs=(1.0, 3.0), numticks=7))
        for axis in (ax.xaxis, ax.yaxis):
            axis.set_major_formatter(plain)
            axis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        ax.set_title(f"{c}, {g}" + ("" if c != "R" else " (no CRLB: deterministic)"), fontsize=8)
        ax.tick_params(labelsize=7)
    for ax in axes.flat[len(cells):]:
        ax.set_visible(False)
    for ax in axes[-1]:
        ax.set_xlabel("record length (h)", fontsize=8)
        ticks = sorted({*hours, *(h for h in (0.5, 8, 96) if grid[0] <= h <= grid[-1])})
        ax.set_xticks(ticks, [f"{h:g}" for h in ticks])
    for ax in axes[:, 0]:
        ax.set_ylabel("RMSE / true value", fontsize=8)
    handles, labels = axes.flat[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=min(4, len(labels)), fontsize=7, frameon=False)
    title = ("Where K and R become estimable: relative RMSE against record length "
             "(dashed 30 %, dotted 100 %; curve: Cramér-Rao bound)")
    fig.suptitle(title if ncol > 2 else title.replace(" against", "\nagainst"), fontsize=9)
    fig.tight_layout(rect=(0, 0.09 if nrow < 3 else 0.06, 1, 1))
    return fig


def _render(table: pd.DataFrame, targets: pd.DataFrame, k_lengths: pd.DataFrame) -> str:
    from avbench.studies.scoring import _md_table

    out = ["# Record length: what a longer record buys", "",
           "crlb_rel: Cramér-Rao relative std (CRLB std / true value; – for the deterministic ramp R); best: the "
           "estimator with the lowest RMSE (physical estimates in at least half the replicates); best_rel_rmse: its "
           "RMSE / true value; rel_rmse[e]: the same for estimator e (– where it has too few physical estimates).",
           ""]
    for c in ("K", "R", "B", "N", "Q"):
        t = table[table["coefficient"] == c].sort_values(["gyro", "hours"])
        if len(t):
            out += [f"## {c}", ""] + _md_table(t.drop(columns="coefficient")) + [""]
    if len(k_lengths):
        out += ["## Record length at which the CRLB relative std of K falls to 30 % and 50 %", ""]
        out += _md_table(k_lengths) + [""]
    out += ["## Targets", "",
            f"best_QNB: on every gyro and each present Q, N, B, the lowest-RMSE estimator's RMSE <= {BEST_QNB_MAX} "
            f"CRLB. whittle: each whittle variant within {WHITTLE_MAX} CRLB and |bias| < {WHITTLE_BIAS_MAX} CRLB "
            f"for every present coefficient with CRLB relative std < {WHITTLE_CRLB_REL_MAX:.0%}, on the gyros whose "
            "bias instability is flicker noise. Intervals: 95 % (bootstrap over replicates for RMSE, +-1.96 SE "
            "for the bias); met: on the point value; clear: the interval is on the same side of the threshold.", ""]
    if len(targets):
        summary = (targets.assign(clear_miss=~targets["met"] & targets["clear"])
                   .groupby(["hours", "target"]).agg(cells=("met", "size"), met=("met", "sum"),
                                                     clearly_missed=("clear_miss", "sum")).reset_index())
        out += _md_table(summary) + [""]
        out += _md_table(targets) + [""]
    return "\n".join(out)


def main(argv=None) -> int:
    from avbench.outputs import TABLE_DIGITS, atomic_write_text
    from avbench.studies.report import finished_studies_parser, parse_finished

    ap = finished_studies_parser("python -m avbench.studies.summaries.record_length", __doc__.split("\n\n")[0],
                                 "results/record_length")
    ap.add_argument("--estimators", nargs="*", default=None,
                    help="estimator labels compared (default: every variant of " + ", ".join(DEFAULT_COMPARED) + ")")
    a, finished = parse_finished(ap, argv)
    cfgs, tidies = (list(x) for x in zip(*finished))
    labels = [set(e.label for e in c.estimators) for c in cfgs]
    if a.estimators is None:
        compared = [e.label for e in cfgs[0].estimators if e.name in DEFAULT_COMPARED
                    and all(e.label in s for s in labels)]
    else:
        missing = [e for e in a.estimators if not all(e in s for s in labels)]
        if missing:
            ap.error(f"--estimators: {', '.join(missing)} not in every study; expected labels from "
                     f"{', '.join(sorted(set.intersection(*labels)))}")
        compared = list(a.estimators)
    from avbench.studies.scoring import crlb_table

    bounds = [crlb_table(c) for c in cfgs]  # once per study, for both tables
    lengths = [length_table(t, c, compared, b) for t, c, b in zip(tidies, cfgs, bounds)]
    table = pd.concat(lengths, ignore_index=True)
    targets = pd.concat([targets_table(t, c, ln, b) for t, c, ln, b in zip(tidies, cfgs, lengths, bounds)],
                        ignore_index=True)
    # the CRLB against record length, from the longest study's gyros (their flicker memory covers it)
    longest = max(cfgs, key=record_hours)
    grid = np.geomspace(0.5, 4 * record_hours(longest), 13)
    with_kr = set(table.loc[table["coefficient"].isin(["K", "R"]), "gyro"])
    curves = {g.label: crlb_curve(g.gyro, grid) for g in longest.gyros if g.label in with_kr}
    k_lengths = pd.DataFrame([{"gyro": g, **{f"hours_at_{lvl:.0%}": _crossing(grid, cur[:, 3], lvl)
                                             for lvl in K_LEVELS}}
                              for g, cur in curves.items() if np.isfinite(cur[:, 3]).any()])
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    fmt = f"%.{TABLE_DIGITS}g"
    atomic_write_text(out / "record_length.csv", table.to_csv(index=False, float_format=fmt))
    atomic_write_text(out / "targets.csv", targets.to_csv(index=False, float_format=fmt))
    atomic_write_text(out / "record_length.md", _render(table, targets, k_lengths))
    from avbench.studies.figures import _save

    _save(crossover_figure(table, curves, grid, compared), out / "crossover.png")
    print(f"wrote {out / 'record_length.md'}")
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
