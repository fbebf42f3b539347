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

from estimators.allan import allan_variance  # noqa: E402
from estimators.av_model import model_avar  # noqa: E402
from noise_models.units import COEFFICIENTS  # noqa: E402

__all__ = ["av_figure", "spread_figure", "study_figures"]


def _save(fig, path: Path) -> None:
    tmp = path.with_name(f".{path.stem}.{os.getpid()}.tmp.png")
    fig.savefig(tmp, dpi=110)
    plt.close(fig)
    os.replace(tmp, path)


def av_figure(rate, gyro, fits: dict, title: str):
    """Empirical overlapping ADEV (octave, 68 % chi^2 bars), the exact truth, and each fit."""
    av = allan_variance(rate, gyro.dt, "octave", overlapping=True)
    fig, ax = plt.subplots(figsize=(7, 5))
    ax.errorbar(
        av.tau,
        av.adev,
        yerr=[av.adev - np.sqrt(av.ci_low), np.sqrt(av.ci_high) - av.adev],
        fmt="o",
        ms=3,
        color="k",
        label="replicate 0 (overlapping AV)",
    )
    tau = np.unique(np.rint(np.logspace(0, np.log10(av.m.max()), 80)).astype(int)) * gyro.dt
    if getattr(gyro, "has_exact_avar", True):
        ax.loglog(tau, np.sqrt(gyro.avar(tau)), "k-", lw=2, alpha=0.4, label="exact AV of the generator")
    else:
        ax.plot([], [], " ", label="exact AV unavailable (a term declares none)")
    for i, (label, coefs) in enumerate(fits.items()):
        model = model_avar(coefs, tau)
        if np.any(model > 0):
            ax.loglog(tau, np.sqrt(np.where(model > 0, model, np.nan)), "--", color=f"C{i}", label=label)
    ax.set_xlabel("τ (s)")
    ax.set_ylabel("Allan deviation (rad/s)")
    ax.set_title(title)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    return fig


def spread_figure(tidy: pd.DataFrame, gyro_label: str):
    """Estimate / truth per coefficient and estimator, over the replicates (box plots)."""
    d = tidy[(tidy["gyro"] == gyro_label) & np.isfinite(tidy["estimate"]) & np.isfinite(tidy["true"])]
    coefs = [c for c in COEFFICIENTS if c in set(d["coefficient"])]
    ests = list(dict.fromkeys(tidy[tidy["gyro"] == gyro_label]["estimator"]))
    fig, axes = plt.subplots(1, max(1, len(coefs)), figsize=(3.2 * max(1, len(coefs)), 4.2), squeeze=False)
    for ax, c in zip(axes[0], coefs):
        dc = d[d["coefficient"] == c]
        data = [(dc[dc["estimator"] == e]["estimate"] / dc[dc["estimator"] == e]["true"]).to_numpy() for e in ests]
        pos = [i for i, x in enumerate(data) if x.size]
        if pos:
            ax.boxplot([data[i] for i in pos], positions=pos, widths=0.6, showfliers=True)
        ax.axhline(1.0, color="k", lw=1, alpha=0.5)
        ax.set_xticks(range(len(ests)))
        ax.set_xticklabels(ests, rotation=60, ha="right", fontsize=7)
        ax.set_title(f"{c}: estimate / true")
        allv = np.concatenate([x for x in data if x.size]) if pos else np.ones(1)
        allv = allv[allv > 0]
        if allv.size and allv.max() / allv.min() > 5:  # wide spread: log scale, no minor labels
            ax.set_yscale("log")
            ax.yaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        ax.grid(True, axis="y", which="both", alpha=0.3)
    fig.suptitle(gyro_label)
    fig.tight_layout()
    return fig


def study_figures(cfg, tidy: pd.DataFrame, out: Path) -> None:
    from studies.runner import replicate_rng

    out = Path(out)
    wanted = cfg.figure_gyros or tuple(g.label for g in cfg.gyros)
    for gi, g in enumerate(cfg.gyros):
        if g.label not in wanted:
            continue
        d0 = tidy[(tidy["gyro"] == g.label) & (tidy["replicate"] == 0)]
        if d0.empty:
            continue
        fits = {}
        for e, de in d0.groupby("estimator", sort=False):
            fits[e] = dict(zip(de["coefficient"], de["estimate"]))
        rate = g.gyro.simulate(g.n_samples, replicate_rng(cfg.seed, gi, 0))
        safe = "".join(ch if ch.isalnum() or ch in "-_" else "_" for ch in g.label)
        _save(av_figure(rate, g.gyro, fits, f"{cfg.name}: {g.label}"), out / f"av_{safe}.png")
        _save(spread_figure(tidy, g.label), out / f"spread_{safe}.png")
