"""Convergence figures of the online filters, like Miao et al. 2014 Figs 6-8 / Miao et al. 2015 Figs 9-17.

One simulated record per set-up; every filter's estimate of each coefficient against the sample
index over the first ``n_show`` samples (the papers show 20000), with the true value as a line.
``python -m studies.convergence_figure`` writes ``results/<study>/convergence_<gyro>.png`` for the
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


def convergence_figure(preset, terms, x0, out, *, n_show=20_000, n_samples=None, seed=0,
                       filters=FILTERS, every=10):
    """Plot estimate vs sample index for each filter; returns the path written.

    The filters run over the whole record (``n_samples``, default the preset's paper length) so
    that the final value is also shown (text box); the plot shows the first ``n_show`` samples.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    import estimators
    from estimators.base import IdentifiabilityWarning
    from noise_models import presets
    from noise_models.units import PAPER_UNITS, from_si

    g = presets.get(preset)
    n = n_samples or presets.info(preset).n_samples
    rate = g.simulate(n, np.random.default_rng(seed))
    truth = g.coefficients
    fig, axes = plt.subplots(len(terms), 1, figsize=(7, 2.2 * len(terms)), sharex=True, squeeze=False)
    for name in filters:
        est = estimators.get(name, terms=terms, x0=x0, trajectory_every=every)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", IdentifiabilityWarning)
            est.fit(rate, g.dt)
        tr = est.diagnostics_["trajectory"]
        tr = tr[tr.index < n_show]
        for ax, c in zip(axes[:, 0], terms):
            unit = PAPER_UNITS[c] if c != "Q" else "arcsec"
            final = from_si(c, est.coefficients_[c], unit)
            ax.plot(tr.index, from_si(c, tr[c].to_numpy(), unit), lw=1, label=f"{name} (end {final:.4g})")
    for ax, c in zip(axes[:, 0], terms):
        unit = PAPER_UNITS[c] if c != "Q" else "arcsec"
        ax.axhline(from_si(c, truth[c], unit), color="k", ls="--", lw=1, label="truth")
        ax.set_ylabel(f"{c} ({unit})")
        ax.legend(fontsize=6, loc="best")
    axes[-1, 0].set_xlabel("sample index")
    fig.suptitle(f"{preset}: online estimates, first {n_show} of {n} samples", fontsize=9)
    fig.tight_layout()
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


def main(results="results"):
    for study, preset, terms, x0 in SETUPS:
        print(convergence_figure(preset, terms, x0, Path(results) / study / f"convergence_{preset}.png"))


if __name__ == "__main__":
    main()
