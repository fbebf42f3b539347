"""Figures of a study: the AV curve of one replicate with every fit, and the spread of estimates."""

from __future__ import annotations

import os
from pathlib import Path

import matplotlib
import matplotlib.ticker

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from avbench.estimators.allan.variance import allan_variance  # noqa: E402
from avbench.estimators.allan.model import model_avar  # noqa: E402
from avbench.noise_models.units import COEFFICIENTS, PAPER_UNITS, from_si  # noqa: E402
from avbench.studies.seeding import replicate_rng  # noqa: E402

__all__ = ["av_figure", "spread_figure", "render_figure", "study_figures", "series_style"]

_LINESTYLES = ("--", "-.", ":", (0, (5, 1, 1, 1, 1, 1)), (0, (8, 2)))
#: the AV figure: height of its axes (inches) and columns of the legend under them
AXES_HEIGHT_IN = 3.6
LEGEND_COLUMNS = 4


def series_style(i: int) -> dict:
    """Colour and line style of series ``i``: every series of a figure gets its own combination
    (ten colours, then the same colours with the next line style)."""
    return {"color": f"C{i % 10}", "linestyle": _LINESTYLES[(i // 10) % len(_LINESTYLES)]}


def _save(fig, path: Path) -> Path:
    tmp = path.with_name(f".{path.stem}.{os.getpid()}.tmp.png")
    # no version stamp in the file: the same figure from another matplotlib release stays byte-equal
    # where the drawing is
    fig.savefig(tmp, dpi=110, metadata={"Software": None})
    plt.close(fig)
    os.replace(tmp, path)
    return path


def _finite_positive(y) -> np.ndarray:
    y = np.asarray(y, dtype=float)
    return np.where(np.isfinite(y) & (y > 0), y, np.nan)


def av_figure(rate, gyro, fits: dict, title: str, unit: str = "deg/h"):
    """Empirical overlapping ADEV (octave, 68 % chi^2 bars), the exact truth, and each fit, in ``unit``
    (a rate unit: the tables' unit of B)."""
    av = allan_variance(rate, gyro.dt, "octave", overlapping=True)
    scale = float(from_si("B", 1.0, unit))
    # the legend sits under the axes in LEGEND_COLUMNS columns, the figure as tall as its rows need:
    # the axes keep the whole width and no corner of the canvas is left empty
    rows = -(-(len(fits) + 2) // LEGEND_COLUMNS)
    legend_h = 0.19 * rows + 0.2  # inches: a row at 8 pt, and the data entry's second line
    height = AXES_HEIGHT_IN + 0.95 + legend_h
    fig, ax = plt.subplots(figsize=(9.0, height))
    fig.subplots_adjust(left=0.09, right=0.98, bottom=(0.55 + legend_h) / height, top=1 - 0.4 / height)
    with np.errstate(all="ignore"):  # absurd magnitudes overflow to inf: drawn as gaps, never an error
        adev = _finite_positive(av.adev * scale)
        lo = np.sqrt(_finite_positive(av.ci_low)) * scale
        hi = np.sqrt(_finite_positive(av.ci_high)) * scale
        yerr = np.nan_to_num(np.vstack([adev - lo, hi - adev]), nan=0.0, posinf=0.0).clip(min=0)
        if np.isfinite(adev).any():
            ax.errorbar(av.tau, adev, yerr=yerr, fmt="o", ms=3, color="k",
                        label="replicate 0 (overlapping AV,\n68 % χ² interval)")
        tau = np.unique(np.rint(np.logspace(0, np.log10(av.m.max()), 80)).astype(int)) * gyro.dt
        try:
            if getattr(gyro, "has_exact_avar", True):
                truth = np.sqrt(_finite_positive(gyro.avar(tau))) * scale
            else:  # a term declares no exact AV
                truth = np.full(tau.shape, np.nan)
                ax.plot([], [], " ", label="exact AV unavailable (a term declares none)")
        except (OverflowError, FloatingPointError):  # e.g. N = 1e200: N**2 is beyond float64
            truth = np.full(tau.shape, np.nan)
        if np.isfinite(truth).any():
            ax.plot(tau, truth, "k-", lw=2, alpha=0.4, label="exact AV of the generator")
        for i, (label, coefs) in enumerate(fits.items()):
            model = np.sqrt(_finite_positive(model_avar(coefs, tau))) * scale
            if np.isfinite(model).any():
                ax.plot(tau, model, lw=1.4, label=label, **series_style(i))
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("τ (s)")
    ax.set_ylabel(f"Allan deviation ({unit})")
    ax.set_title(title)
    ax.grid(True, which="both", alpha=0.3)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.5 / (height * ax.get_position().height)),
                  ncol=LEGEND_COLUMNS, borderaxespad=0.0, frameon=False)
    return fig


def spread_figure(tidy: pd.DataFrame, gyro_label: str):
    """Estimate / truth per coefficient and estimator, over the replicates (box plots).

    Each tick label says how many replicates gave no physical estimate (non-physical, failed or
    non-finite) out of how many, so that a box drawn from few replicates is seen as such.
    """
    dg = tidy[tidy["gyro"] == gyro_label]
    with np.errstate(all="ignore"):
        ratio = (dg["estimate"] / dg["true"]).to_numpy(dtype=float)
    usable = np.isfinite(ratio) & np.isfinite(dg["true"].to_numpy(dtype=float))
    d, ratio = dg[usable], ratio[usable]
    coefs = [c for c in COEFFICIENTS if c in set(dg[np.isfinite(dg["true"])]["coefficient"])]
    ests = list(dict.fromkeys(dg["estimator"]))
    fig, axes = plt.subplots(1, max(1, len(coefs)), figsize=(3.4 * max(1, len(coefs)), 4.6), squeeze=False)
    for ax, c in zip(axes[0], coefs):
        sel = (d["coefficient"] == c).to_numpy()
        data = [ratio[sel & (d["estimator"] == e).to_numpy()] for e in ests]
        pos = [i for i, x in enumerate(data) if x.size]
        if pos:
            ax.boxplot([data[i] for i in pos], positions=pos, widths=0.6, showfliers=True)
        ax.axhline(1.0, color="k", lw=1, alpha=0.5)
        labels = []
        for e, x in zip(ests, data):
            n_all = int(((dg["coefficient"] == c) & (dg["estimator"] == e)).sum())
            missing = n_all - x.size
            labels.append(f"{e} ({missing}/{n_all} none)" if missing else e)
        ax.set_xticks(range(len(ests)))
        ax.set_xticklabels(labels, rotation=60, ha="right", fontsize=7)
        ax.set_xlim(-0.6, len(ests) - 0.4)  # every estimator's place, those without a box too
        ax.set_title(f"{c}: estimate / true")
        allv = np.concatenate([x for x in data if x.size]) if pos else np.ones(1)
        allv = allv[allv > 0]
        if allv.size and allv.max() / allv.min() > 5:  # wide spread: log scale, ticks at 1, 2, 5 x 10^k
            ax.set_yscale("log")  # (at 10^k alone beyond three decades, where 1-2-5 would crowd)
            subs = (1.0, 2.0, 5.0) if allv.max() / allv.min() <= 1e3 else (1.0,)
            ax.yaxis.set_major_locator(matplotlib.ticker.LogLocator(subs=subs, numticks=12))
            ax.yaxis.set_major_formatter(matplotlib.ticker.FuncFormatter(lambda v, _: f"{v:g}"))
            ax.yaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
            bottom = ax.get_ylim()[0]
            for i, x in enumerate(data):  # zero estimates have no place on a log axis: marked at its foot
                zeros = int(np.sum(x == 0))
                if zeros:
                    ax.plot([i], [bottom], "v", color="C3", ms=7, clip_on=False)
                    ax.annotate(f"{zeros}×0", (i, bottom), xytext=(0, 6 + 8 * (i % 2)), textcoords="offset points",
                                ha="center", fontsize=7, color="C3")  # neighbours staggered: never overlaid
        for i, x in enumerate(data):  # an estimator that does not model the term: said, not a bare gap
            if not x.size and not ((dg["coefficient"] == c) & (dg["estimator"] == ests[i])).any():
                ax.annotate("not modelled", (i, 0.5), xycoords=("data", "axes fraction"), rotation=90,
                            ha="center", va="center", fontsize=7, color="0.4")
        ax.grid(True, axis="y", which="both", alpha=0.3)
    fig.suptitle(f"{gyro_label}  (tick labels: replicates without a physical estimate / all; "
                 "red ▼: zero estimates, below a log axis)")
    fig.tight_layout()
    return fig


def render_figure(cfg, tidy: pd.DataFrame, kind: str, gi: int, path: Path) -> Path:
    """Draw and save one figure of :func:`avbench.studies.figure_files.figure_jobs` (``tidy`` may
    hold only that gyro's rows)."""
    g = cfg.gyros[gi]
    if kind == "spread":
        return _save(spread_figure(tidy, g.label), path)
    d0 = tidy[(tidy["gyro"] == g.label) & (tidy["replicate"] == 0)]
    fits = {e: dict(zip(de["coefficient"], de["estimate"])) for e, de in d0.groupby("estimator", sort=False)}
    rate = g.gyro.simulate(g.n_samples, replicate_rng(cfg.seed, gi, 0))
    unit = {**PAPER_UNITS, **(getattr(cfg, "units", None) or {})}["B"]
    return _save(av_figure(rate, g.gyro, fits, f"{cfg.name}: {g.label}", unit), path)


def study_figures(cfg, tidy: pd.DataFrame, out: Path) -> list[Path]:
    """The AV and spread figures of every gyro in ``cfg.figure_gyros`` (default all); the paths written."""
    from avbench.studies.figure_files import figure_jobs

    return [render_figure(cfg, tidy, kind, gi, path) for kind, gi, path in figure_jobs(cfg, tidy, out)]
