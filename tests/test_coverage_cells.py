"""The cell count of a coverage study (``studies/summaries/coverage_cells.py``)."""

import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from avbench.studies.summaries.coverage_cells import ABSENT_HOLDS_ZERO, BAND, MAX_ABS_BIAS, cells, render

ROOT = Path(__file__).resolve().parents[1]


def _cell(gyro, coef, true, n, hits):
    """n rows of one cell whose interval holds ``true`` (or, true absent, 0) in ``hits`` of them."""
    t = math.nan if true is None else true
    lower = np.where(np.arange(n) < hits, 0.0 if true is None else 0.5 * t, 0.1 if true is None else 1.5 * t)
    return pd.DataFrame({"gyro": gyro, "estimator": "E", "coefficient": coef, "true": t, "estimate": 1.0,
                         "lower": lower, "upper": 10.0 if true is None else 2.0 * t})


@pytest.mark.parametrize("hits, bias, ok", [(95, 0.0, True), (93, 0.49, True), (97, -0.49, True),
                                            (92, 0.0, False), (98, 0.0, False), (95, 0.5, False), (95, -0.6, False)])
def test_present_cell_needs_the_band_and_a_small_bias(hits, bias, ok):
    tidy = _cell("g", "N", 1.0, 100, hits)
    scores = pd.DataFrame({"gyro": ["g"], "estimator": ["E"], "coefficient": ["N"], "bias_over_crlb": [bias]})
    t = cells(tidy, scores)
    assert t["kind"].tolist() == ["present"] and t["share"].iloc[0] == hits / 100
    assert t["ok"].iloc[0] == ok
    assert t["share_lo"].iloc[0] <= hits / 100 <= t["share_hi"].iloc[0]


@pytest.mark.parametrize("hits, ok", [(95, True), (99, True), (100, True), (94, False), (80, False)])
def test_absent_cell_needs_zero_held_at_least_at_the_rules_rate(hits, ok):
    """An absent term's boundary interval holds 0 at 0.975 nominally: above the band is right there."""
    t = cells(_cell("g", "Q", None, 100, hits), pd.DataFrame(columns=["gyro", "estimator", "coefficient",
                                                                       "bias_over_crlb"]))
    assert t["kind"].tolist() == ["absent"] and t["ok"].iloc[0] == ok
    assert np.isnan(t["bias_over_crlb"].iloc[0])


def test_rule_constants_are_the_targets_of_coverage_defaults():
    assert BAND == (0.93, 0.97) and MAX_ABS_BIAS == 0.5 and ABSENT_HOLDS_ZERO == 0.95


def test_committed_coverage_defaults_count():
    """The committed study's cells.csv is what the rule gives on its tidy.csv and scores.csv, 30 cells
    (10 presets x Q, N, B), and at least 27 of them meet the target."""
    d = ROOT / "results" / "coverage_defaults"
    tidy = pd.read_csv(d / "tidy.csv")
    t = cells(tidy, pd.read_csv(d / "scores.csv"))
    assert len(t) == 30
    committed = pd.read_csv(d / "cells.csv")
    assert committed["ok"].tolist() == t["ok"].tolist()
    np.testing.assert_allclose(committed["share"], t["share"], rtol=1e-5)
    assert (d / "cells.md").read_text() == render(t)
    assert int(t["ok"].sum()) >= 27
