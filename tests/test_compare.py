"""``avbench compare``: paired intervals, non-physical fits counted on both sides, and verdicts whose
false-win rate between two identical estimators is at their level."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy.stats import binom

from avbench.cli import main
from avbench.studies.compare import compare
from avbench.studies.paired import holm, sign_flip_p

ROOT = Path(__file__).resolve().parents[1]
TRUE = {"N": 1e-3, "K": 1e-5}


def _tidy(rng, replicates=30, gyros=3, scale_a=1.0, bad=0.1) -> pd.DataFrame:
    """Two estimators of every gyro x coefficient: estimate = true (1 + 0.1 (shared + own)), the
    shared part the same record's (a paired design); a fit non-physical with probability ``bad``."""
    rows = []
    for g in range(gyros):
        for c, t in TRUE.items():
            shared = rng.standard_normal(replicates)
            for e, s in (("A", scale_a), ("B", 1.0)):
                own = rng.standard_normal(replicates)
                flag = rng.random(replicates) < bad
                for r in range(replicates):
                    rows.append((f"g{g}", r, e, c, t, t * (1 + 0.1 * s * (shared[r] + own[r])), bool(flag[r]), ""))
    return pd.DataFrame(rows, columns=["gyro", "replicate", "estimator", "coefficient", "true", "estimate",
                                       "nonphysical", "failure"])


def test_holm_matches_statsmodels():
    from statsmodels.stats.multitest import multipletests

    p = np.random.default_rng(1).random(17) ** 3
    assert holm(p) == pytest.approx(multipletests(p, method="holm")[1], rel=1e-12)
    assert np.isnan(holm([0.01, np.nan])[1]) and holm([0.01, np.nan])[0] == pytest.approx(0.01)


def test_sign_flip_p_is_exact_for_few_pairs():
    """With n <= 12 pairs every one of the 2^n swaps is counted: the smallest p is 2 / 2^n."""
    sa, sb = np.full(5, 1.0), np.full(5, 4.0)
    assert sign_flip_p(sa, sb) == pytest.approx(2 / 32)


@pytest.mark.parametrize("n", [1, 2, 7, 16])
def test_sign_flip_p_counts_every_pattern(n):
    """Up to EXACT_PAIRS pairs, p is the share of all 2^n sign patterns reaching |D| (counted here by
    brute force), ties included."""
    rng = np.random.default_rng(n)
    sa, sb = rng.random(n), rng.random(n)
    sb[0] = sa[0] + 0.5  # a pair whose swap alone moves D
    d = sa - sb
    patterns = 1 - 2 * ((np.arange(2 ** n)[:, None] >> np.arange(n)) & 1)
    assert sign_flip_p(sa, sb) == pytest.approx(np.mean(np.abs(patterns @ d) >= abs(d.sum()) * (1 - 1e-9)), abs=0)


def test_sign_flip_bound_holds_above_the_exact_count():
    """The Bentkus-Dzindzalieta bound is never below the exact p-value (the exact one computed here from
    the binomial law of equal |d|: D = |d| (2 k - n), k ~ Bin(n, 1/2)), the case that attains it."""
    from avbench.studies.paired import EXACT_PAIRS, _bound_p

    n = EXACT_PAIRS + 9
    for k_obs in range(n // 2 + 1, n + 1):  # sa > sb in k_obs pairs
        d = np.where(np.arange(n) < k_obs, 1.0, -1.0)
        exact = min(1.0, 2 * binom.sf(k_obs - 1, n, 0.5))  # |2k - n| >= 2 k_obs - n, both tails
        assert exact <= _bound_p(d, abs(d.sum())), k_obs


def test_sign_flip_p_above_the_exact_count_holds_its_level():
    """Above EXACT_PAIRS pairs (Monte Carlo and bound joined by Bonferroni): with exchangeable errors
    (two estimators drawn from one heavy-tailed law) p <= 0.05 in at most the binomial 99.9 % upper
    end of 5 % of 400 trials, and a clearly better estimator (RMSE ratio 0.6, 60 pairs) gives p < 1e-3."""
    rng = np.random.default_rng(11)
    trials = 400
    small = sum(sign_flip_p(rng.standard_t(3, 45) ** 2, rng.standard_t(3, 45) ** 2, rng) <= 0.05
                for _ in range(trials))
    assert small <= binom.isf(5e-4, trials, 0.05), small
    assert sign_flip_p((0.6 * rng.standard_normal(60)) ** 2, rng.standard_normal(60) ** 2, rng) < 1e-3


def test_false_win_rate_of_identical_estimators_is_at_the_level():
    """Families of 3 gyros x 2 coefficients, both estimators drawn from one distribution (10 % of fits
    non-physical on each side): the share of families with any verdict other than a tie is within the
    binomial 99.9 % range of the level (Holm keeps the family-wise rate at or below it; the sign-flip
    test is exact here, so it is not far below either: 6 nearly independent tests give 0.049)."""
    rng = np.random.default_rng(2026)
    families, level = 400, 0.05
    declared = 0
    for _ in range(families):
        cmp = compare(_tidy(rng), "A", "B", level=level, n_boot=50, seed=int(rng.integers(1 << 30)))
        declared += bool((cmp["verdict"] != "tie").any())
    lo, hi = binom.ppf(5e-4, families, level), binom.isf(5e-4, families, level)
    assert lo <= declared <= hi, f"{declared} of {families} families declared a winner; expected {lo:g}..{hi:g}"


def test_a_better_estimator_wins_and_bad_fits_count_on_both_sides():
    rng = np.random.default_rng(7)
    tidy = _tidy(rng, scale_a=0.3, bad=0.0)
    cmp = compare(tidy, "A", "B")
    assert (cmp["verdict"] == "A").all() and (cmp["ratio_hi"] < 1).all()
    assert ((cmp["ratio_lo"] <= cmp["ratio"]) & (cmp["ratio"] <= cmp["ratio_hi"])).all()
    assert (cmp["detectable_ratio"] < 1).all()
    # A's three largest errors of g0/N made non-physical: counted for A, the pairs lose them on both sides
    sel = (tidy["gyro"] == "g0") & (tidy["coefficient"] == "N") & (tidy["estimator"] == "A")
    worst = (tidy.loc[sel, "estimate"] - 1e-3).abs().nlargest(3).index
    tidy.loc[worst, "nonphysical"] = True
    row = compare(tidy, "A", "B").iloc[0]
    assert (row["n_bad_a"], row["n_bad_b"], row["n_pairs"], row["n"]) == (3, 0, 27, 30)
    assert row["verdict"] == "mixed"  # lower RMSE, but more replicates without an estimate
    assert set(cmp["unit"]) == {"deg/sqrt(h)", "deg/h^1.5"}


def test_compare_command_on_a_committed_study(capsys, tmp_path):
    assert main(["compare", str(ROOT / "results" / "lv2015"), "wls", "ols", "--csv", str(tmp_path / "c.csv")]) == 0
    out = capsys.readouterr().out
    srs_n = next(ln for ln in out.splitlines() if ln.startswith("| SRS2000 | N |"))
    assert "| 25 of 30 | 0 / 5 |" in srs_n and "[" in srs_n  # OLS's 5 non-physical N counted, intervals printed
    csv = pd.read_csv(tmp_path / "c.csv")
    assert {"unit", "ratio_lo", "ratio_hi", "bias_diff_lo", "p_holm", "n_bad_a", "n_bad_b"} <= set(csv.columns)
    assert main(["compare", str(ROOT / "results" / "lv2015"), "wls", "nope"]) == 2
