"""Convergence figures of the online filters, like Miao et al. 2014 Figs 6-8 / Miao et al. 2015 Figs 9-17.

One simulated record per set-up; every filter's estimate of each coefficient against the sample
index over the whole record (log scale: the transient the papers show and the end are both
visible), with the true value as a line.
``python -m avbench.studies.convergence_figure`` writes ``results/<study>/convergence_<gyro>.png`` for the
Miao et al. set-ups.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

__all__ = ["convergence_figure", "SETUPS", "main"]

_ADIS15 = {"N": [1.5, "deg/sqrt(h)"], "B": [20.0, "deg/h"], "K": [50.0, "deg/h^1.5"]}
_FOG15 = {
    "Q": [0.0082, "arcsec"], "N": [0.0007, "deg/sqrt(h)"], "B": [0.0827, "deg/h"],
    "K": [0.1752, "deg/h^1.5"], "R": [0.0547, "deg/h^2"],
}

#: (study folder, preset, terms, x0) of the papers' set-ups
SETUPS = [
    ("miao2014_adis16405", "ADIS16405_Y_2014", "NBK",
     {"N": [0.48, "deg/sqrt(h)"], "B": [20.8, "deg/h"], "K": [55.44, "deg/h^1.5"]}),
    ("miao2014_adis16405", "ADIS16405_X_50HZ", "NB", {"N": [1.25, "deg/sqrt(h)"], "B": [18.6, "deg/h"]}),
    ("miao2015_adis16405", "ADIS16405_X", "NBK", _ADIS15),
    ("miao2015_adis16405", "ADIS16405_Y", "NBK", _ADIS15),
    ("miao2015_adis16405", "ADIS16405_Z", "NBK", _ADIS15),
    ("miao2015_fog", "FOG1", "QNBKR", _FOG15),
    ("miao2015_fog", "FOG2", "QNBKR", _FOG15),
]

FILTERS = ("shakf", "nekf", "shakf_multitau", "nekf_multitau")


def convergence_figure(preset, terms, x0, out, *, n_samples=None, seed=0, filters=FILTERS, every=100):
    """Plot estimate vs sample index for each filter over the whole record; returns the path written.

    The sample index is on a log scale, so the transient (the papers show its first 20000 samples)
    and the end of the record are both visible; the value axis is scaled to the second half of
    the record and the truth, so a large start-up excursion does not flatten the end (values off
    the axis are clipped at its edge).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from avbench import estimators
    from avbench.estimators.base import IdentifiabilityWarning
    from avbench.noise_models import presets
    from avbench.noise_models.units import PAPER_UNITS, from_si
    from avbench.studies.figures import series_style

    g = presets.get(preset)
    n = n_samples or presets.info(preset).n_samples
    rate = g.simulate(n, np.random.default_rng(seed))
    truth = g.coefficients
    fig, axes = plt.subplots(len(terms), 1, figsize=(9.5, 2.3 * len(terms)), sharex=True, squeeze=False)
    fig.subplots_adjust(left=0.1, right=0.7, top=0.93, bottom=0.08, hspace=0.12)
    late = {c: [] for c in terms}
    for i, name in enumerate(filters):
        est = estimators.get(name, terms=terms, x0=x0, trajectory_every=every)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", IdentifiabilityWarning)
            est.fit(rate, g.dt)
        result = est.result()
        tr = result.trajectory
        tr = tr[tr.index > 0]
        for ax, c in zip(axes[:, 0], terms):
            unit = PAPER_UNITS[c] if c != "Q" else "arcsec"
            final = from_si(c, result.coefficients[c].fitted, unit)
            y = from_si(c, tr[c].to_numpy(), unit)
            late[c].append(y[tr.index >= n // 2])
            ax.plot(tr.index, y, lw=1, label=f"{name} (end {final:.4g})", **{**series_style(i), "linestyle": "-"})
    for ax, c in zip(axes[:, 0], terms):
        unit = PAPER_UNITS[c] if c != "Q" else "arcsec"
        t = from_si(c, truth[c], unit)
        ax.axhline(t, color="k", ls="--", lw=1, label="truth")
        vals = np.concatenate([v[np.isfinite(v)] for v in late[c]] + [np.array([t])])
        lo, hi = float(vals.min()), float(vals.max())
        pad = 0.15 * (hi - lo) if hi > lo else 0.1 * abs(t) or 1.0
        ax.set_ylim(lo - pad, hi + pad)
        ax.set_xscale("log")
        ax.set_ylabel(f"{c} ({unit})")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=6, loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0)
    axes[-1, 0].set_xlabel("sample index (log scale)")
    fig.suptitle(f"{preset}: online estimates over {n} samples (y axis: range of the second half)", fontsize=9)
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110, metadata={"Software": None})
    plt.close(fig)
    return out


def main(results="results"):
    for study, preset, terms, x0 in SETUPS:
        print(convergence_figure(preset, terms, x0, Path(results) / study / f"convergence_{preset}.png"))


if __name__ == "__main__":
    main()
