"""A study's figures speak the tables' language: the AV in the tables' rate unit with its interval
level stated, log spread panels with labelled ticks, zero estimates and not-modelled terms marked."""

from __future__ import annotations

import numpy as np
import pandas as pd

from avbench.noise_models import AngleRandomWalk, Gyro, RateRandomWalk
from avbench.studies.figures import av_figure, plt, spread_figure


def test_av_figure_in_the_tables_unit():
    g = Gyro(dt=0.1, terms=[AngleRandomWalk(N=1e-3), RateRandomWalk(K=3e-5)])
    rate = g.simulate(4096, np.random.default_rng(0))
    fig = av_figure(rate, g, {"fit": {"N": 1e-3, "K": 3e-5}}, "t", unit="deg/h")
    ax = fig.axes[0]
    assert ax.get_ylabel() == "Allan deviation (deg/h)"
    assert any("68 %" in t.get_text() for t in ax.get_legend().get_texts())
    truth = ax.get_lines()[-2].get_ydata()  # the exact AV, then the fit
    tau = ax.get_lines()[-2].get_xdata()
    np.testing.assert_allclose(truth, np.sqrt(g.avar(tau)) * 180 / np.pi * 3600, rtol=1e-12)
    plt.close(fig)


def test_spread_figure_marks_zeros_and_terms_not_modelled():
    rows = []
    for r in range(10):
        for e, n_est in (("wide", [0.0, 1e-4, 1e-2][r % 3]), ("fine", 1e-3 * (1 + 0.01 * r))):
            rows.append(("g", r, e, "N", 1e-3, n_est, False, ""))
        rows.append(("g", r, "fine", "K", 3e-5, 3e-5, False, ""))
    tidy = pd.DataFrame(rows, columns=["gyro", "replicate", "estimator", "coefficient", "true", "estimate",
                                       "nonphysical", "failure"])
    fig = spread_figure(tidy, "g")
    n_ax, k_ax = fig.axes
    assert n_ax.get_yscale() == "log"
    texts = [t.get_text() for t in n_ax.texts]
    assert "4×0" in texts  # replicates 0, 3, 6, 9 gave 0: below the log axis, marked
    labels = [t.get_text() for t in n_ax.get_yticklabels() if t.get_text()]
    assert len(labels) >= 3
    assert "not modelled" in [t.get_text() for t in k_ax.texts]  # "wide" has no K
    plt.close(fig)
