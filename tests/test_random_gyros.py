"""The random-gyro study: its config is the generator's output, and the pooled scores count right."""

import math
from pathlib import Path

import numpy as np
import pandas as pd

from avbench.studies import random_gyros
from avbench.studies.summaries.random_gyros import pooled

ROOT = Path(__file__).resolve().parents[1]


def test_committed_config_is_the_generators_output():
    assert (ROOT / "studies" / "random_gyros.toml").read_text() == random_gyros.config_text()


def test_draw_is_within_the_stated_ranges_and_has_both_flicker_memories():
    gs = random_gyros.draw()
    assert len(gs) == random_gyros.N_GYROS
    for g in gs:
        assert random_gyros.N_RANGE[0] <= g["N"] <= random_gyros.N_RANGE[1]
        for c, (lo, hi) in random_gyros.RATIOS.items():
            if c in g:
                assert lo <= g[c] / g["N"] <= hi
    tm = np.array([g["tau_max"] for g in gs if "B" in g])
    assert (tm < random_gyros.RECORD_S).any() and (tm > random_gyros.RECORD_S).any()


def test_pooled_counts_hits_and_zero_lower_bounds():
    tidy = pd.DataFrame({
        "gyro": ["a", "b", "c", "a", "b"], "estimator": "E", "coefficient": ["N", "N", "N", "K", "K"],
        "true": [1.0, 1.0, 1.0, math.nan, 2.0], "estimate": [1.1, 0.5, 1.0, 0.1, 2.0],
        "lower": [0.9, 0.6, 0.95, 0.0, 1.0], "upper": [1.2, 0.7, 1.05, 0.3, 3.0]})
    crlb = pd.DataFrame({"gyro": ["a", "b", "c", "b"], "estimator": "E", "coefficient": ["N", "N", "N", "K"],
                         "crlb_rel": [0.1, 0.1, 0.1, 0.5]})
    t = pooled(tidy, crlb, {}, 7200.0).set_index(["coefficient", "subset"])
    assert t.loc[("N", "all present"), "coverage"] == 2 / 3
    assert t.loc[("N", "all present"), "rmse_over_crlb"] == np.sqrt((1 + 25 + 0) / 3)
    assert t.loc[("K", "absent: interval holds 0"), "coverage"] == 1.0
    assert t.loc[("K", "CRLB rel >= 0.3"), "n"] == 1
