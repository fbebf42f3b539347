"""The random-gyro study: its config is the generator's output, and the pooled scores count right."""

import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

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


def _hits(n_gyros, seed, record_s):
    """Per coefficient, over gyros drawn as the study draws them (another seed): misses and trials of
    the 95 % intervals of ``whittle_debiased`` at its defaults (nobody tells it the terms) - present
    terms: the interval holds the truth; absent terms (R always): its lower bound is 0."""
    from avbench import estimators
    from avbench.noise_models import AngleRandomWalk, BiasInstability, Gyro, Quantization, RateRandomWalk

    make = {"Q": Quantization, "N": AngleRandomWalk, "K": RateRandomWalk}
    n = int(record_s / random_gyros.DT)
    out = {c: {"present": [0, 0], "absent": [0, 0]} for c in "QNBKR"}
    for i, (g, ss) in enumerate(zip(random_gyros.draw(seed, n_gyros), np.random.SeedSequence(seed).spawn(n_gyros))):
        terms = [make[c](**{c: g[c]}) for c in "QNK" if c in g]
        if "B" in g:
            terms.append(BiasInstability(B=g["B"], tau_max=g["tau_max"]))
        gyro = Gyro(dt=random_gyros.DT, terms=terms)
        e = estimators.get("whittle_debiased").fit(gyro.simulate(n, np.random.default_rng(ss)), random_gyros.DT)
        ci = e.conf_int()
        for c in "QNBKR":
            lo, hi = ci.loc[c, "lower"], ci.loc[c, "upper"]
            kind = "present" if c in g else "absent"
            hit = (lo <= g[c] <= hi) if c in g else lo == 0.0
            out[c][kind][0] += int(not hit)
            out[c][kind][1] += 1
    return out


def _check(out):
    """Present terms: coverage >= 0.90 (the target), absent terms' intervals hold 0 >= 0.95 of
    the time; each at the 99.9 % point of the binomial law of the misses."""
    from scipy import stats

    for c, d in out.items():
        for kind, p in (("present", 0.10), ("absent", 0.05)):
            miss, n = d[kind]
            if n:
                assert miss <= stats.binom.ppf(0.999, n, p), (c, kind, miss, n)


def test_defaults_cover_on_random_gyros_small():
    _check(_hits(n_gyros=8, seed=2330, record_s=1800.0))


@pytest.mark.slow
def test_defaults_cover_on_random_gyros_slow():
    out = _hits(n_gyros=200, seed=2331, record_s=random_gyros.RECORD_S)
    _check(out)
    assert all(out[c]["present"][1] > 50 for c in "QNBK")  # every coefficient drawn present often enough


def test_efficiency_takes_each_gyros_rmse_over_its_replicates_then_the_median():
    from avbench.studies.summaries.random_gyros import EFFICIENT, efficiency

    # CRLB std = 0.1 x true; errors in CRLB std: gyro a (3, 4) -> RMSE sqrt(12.5), b (1, 1) -> 1, c (0, 2) -> sqrt(2)
    tidy = pd.DataFrame({
        "gyro": ["a", "a", "b", "b", "c", "c", "d", "d"], "estimator": "E", "coefficient": "N",
        "true": [1.0, 1.0, 1.0, 1.0, 1.0, 1.0, math.nan, math.nan],
        "estimate": [1.3, 0.6, 1.1, 0.9, 1.0, 1.2, 0.1, 0.0]})
    crlb = pd.DataFrame({"gyro": ["a", "b", "c"], "estimator": "E", "coefficient": "N", "crlb_rel": 0.1})
    t = efficiency(tidy, crlb).iloc[0]
    assert (t["gyros"], t["records"]) == (3, 6)
    assert t["median"] == pytest.approx(math.sqrt(2))
    assert t["median_lo"] <= t["median"] <= t["median_hi"]
    assert t["share_efficient"] == pytest.approx(1 / 3) and EFFICIENT == 1.25


def test_per_gyro_table_spreads_each_gyros_rmse_over_the_gyros():
    from avbench.studies.summaries.random_gyros import per_gyro_table

    # CRLB std = 0.1 x true; errors in CRLB std per gyro: a (1, 1) -> 1, b (3, 4) -> sqrt(12.5),
    # c (0, 2) -> sqrt(2), d (1, -1) -> 1, e (0.5, 0.5) -> 0.5; f has no N (absent: left out)
    z = {"a": (1, 1), "b": (3, 4), "c": (0, 2), "d": (1, -1), "e": (0.5, 0.5)}
    tidy = pd.DataFrame(
        [dict(gyro=g, estimator="E", coefficient="N", true=1.0, estimate=1.0 + 0.1 * v) for g, vs in z.items()
         for v in vs] + [dict(gyro="f", estimator="E", coefficient="N", true=math.nan, estimate=0.1)] * 2)
    crlb = pd.DataFrame({"gyro": list(z), "estimator": "E", "coefficient": "N", "crlb_rel": 0.1})
    t = per_gyro_table(tidy, crlb, replicates=2).set_index("estimator")
    e = t.loc["E"]
    assert e["gyros"] == 5 and e["median"] == pytest.approx(1.0)
    # sorted 0.5, 1, 1, sqrt 2, sqrt 12.5: the 90th percentile interpolates 0.6 of the way from sqrt 2
    assert e["p90"] == pytest.approx(math.sqrt(2) + 0.6 * (math.sqrt(12.5) - math.sqrt(2)))
    assert e["max"] == pytest.approx(math.sqrt(12.5)) and e["share_efficient"] == pytest.approx(3 / 5)
    # two replicates: RMSE^2 / CRLB^2 ~ chi2_2 / 2, an exponential of mean 1
    r = t.loc["efficient (chi2_2/2)"]
    assert r["median"] == pytest.approx(math.sqrt(math.log(2)))
    assert r["p90"] == pytest.approx(math.sqrt(math.log(10)))
    assert r["share_efficient"] == pytest.approx(1 - math.exp(-1.25**2))
    assert r["max"] == pytest.approx(math.sqrt(-math.log(1 - 0.5 ** (1 / 5))))


def test_per_gyro_reference_row_matches_simulated_efficient_estimators():
    from avbench.studies.summaries.random_gyros import EFFICIENT, per_gyro_table

    # an unbiased estimator at the bound with normal errors, 6 replicates on each of n gyros
    n, r = 4000, 6
    z = np.random.default_rng(55).standard_normal((n, r))
    tidy = pd.DataFrame({"gyro": np.repeat(np.arange(n), r), "estimator": "E", "coefficient": "K",
                         "true": 1.0, "estimate": 1.0 + 0.1 * z.ravel()})
    crlb = pd.DataFrame({"gyro": np.arange(n), "estimator": "E", "coefficient": "K", "crlb_rel": 0.1})
    ref = per_gyro_table(tidy, crlb, replicates=r).set_index("estimator").loc[f"efficient (chi2_{r}/{r})"]
    per = np.sqrt(np.mean(z**2, axis=1))
    # the reference's quantiles hold the simulated gyros' shares within 4 binomial standard errors
    for level, value in ((0.5, ref["median"]), (0.9, ref["p90"]), (ref["share_efficient"], EFFICIENT)):
        assert abs(np.mean(per <= value) - level) < 4 * math.sqrt(level * (1 - level) / n)
    assert ref["share_efficient"] == pytest.approx(0.846, abs=0.001)
