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


def test_av_figure_leaves_no_corner_of_the_canvas_empty():
    """The axes take the figure's whole width (the legend sat beside them, leaving ~35 % of the canvas
    blank under it); the legend, below, lies wholly inside the canvas and ends near its foot, with as
    many rows as the fits need (4 and 17 fits)."""
    g = Gyro(dt=0.1, terms=[AngleRandomWalk(N=1e-3), RateRandomWalk(K=3e-5)])
    rate = g.simulate(4096, np.random.default_rng(0))
    for n in (4, 17):
        fig = av_figure(rate, g, {f"fit {i}": {"N": 1e-3, "K": 3e-5} for i in range(n)}, "t", unit="deg/h")
        fig.canvas.draw()
        box, legend = fig.bbox, fig.axes[0].get_legend().get_window_extent()
        assert fig.axes[0].get_window_extent().width >= 0.85 * box.width
        assert box.x0 <= legend.x0 and legend.x1 <= box.x1 and box.y0 <= legend.y0
        assert legend.y1 <= fig.axes[0].get_window_extent().y0  # under the axes, not over the data
        assert (legend.y0 - box.y0) / fig.dpi <= 0.4, (legend.y0 - box.y0) / fig.dpi  # inches left blank
        assert len(fig.axes[0].get_legend().get_texts()) == n + 2
        plt.close(fig)


def test_spread_figure_shows_every_estimator_place_and_keeps_zero_counts_apart():
    """An estimator that does not model a term keeps its place and tick label inside the axes, even at
    either end; neighbouring zero counts are drawn at different heights."""
    rows = []
    for r in range(6):
        rows.append(("g", r, "first", "N", 1e-3, 1e-3 * (1 + 0.1 * r), False, ""))
        for e in ("zero a", "zero b"):
            rows += [("g", r, e, "N", 1e-3, [0.0, 1e-5, 1e-1][r % 3], False, ""), ("g", r, e, "K", 3e-5, 3e-5, False, "")]
    tidy = pd.DataFrame(rows, columns=["gyro", "replicate", "estimator", "coefficient", "true", "estimate",
                                       "nonphysical", "failure"])
    fig = spread_figure(tidy, "g")
    n_ax, k_ax = fig.axes
    lo, hi = k_ax.get_xlim()
    assert lo < 0 < 2 < hi  # "first" (no K) at 0 has its place
    note = next(t for t in k_ax.texts if t.get_text() == "not modelled")
    assert lo < note.xy[0] < hi
    zeros = [t for t in n_ax.texts if t.get_text().endswith("×0")]
    assert len(zeros) == 2 and zeros[0].xyann[1] != zeros[1].xyann[1]
    plt.close(fig)


def test_crossover_figure_of_one_panel_holds_its_title_and_legend():
    """One panel (a study of one gyro with K): the figure is at least 7 in wide, and its title and
    legend lie inside the canvas (they were cut at 319 x 374 px)."""
    from avbench.studies.summaries.record_length import crossover_figure

    grid = np.geomspace(0.5, 96, 9)
    table = pd.DataFrame([dict(hours=h, gyro="a", coefficient="K", best_rel_rmse=0.5 / h, **{"rel_rmse[w]": 0.6 / h})
                          for h in (2.0, 24.0)])
    fig = crossover_figure(table, {"a": np.tile((0.5 * (grid / 2) ** -0.5)[:, None], (1, 5))}, grid, ["w"])
    fig.canvas.draw()
    box = fig.bbox
    assert fig.get_size_inches()[0] >= 7.0
    for artist in (fig._suptitle, fig.legends[0]):
        e = artist.get_window_extent()
        assert box.x0 <= e.x0 and e.x1 <= box.x1 and box.y0 <= e.y0 and e.y1 <= box.y1, artist
    plt.close(fig)
