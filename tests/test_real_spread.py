"""avbench.studies.real_runs_spread: the run-to-run spread of N and B on simulated ADIS16405 gyros, the
default methods against the plain-model configuration (results/real/spread.md). No real data needed:
the simulation reads the committed axis models (results/real/spread_models.csv)."""

import math
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from avbench.studies import real_runs_spread as rs

RESULTS = Path(__file__).resolve().parent.parent / "results" / "real"


@pytest.fixture(scope="module")
def models():
    return pd.read_csv(RESULTS / "spread_models.csv")


def test_median_model_keeps_a_majority_latent_and_takes_medians():
    runs = [(f"r{i}", {"FW.N": n, "FW.tf": 0.005, "GM.sigma": 2e-4, "GM.tc": tc, "RW.K": 1e-5})
            for i, (n, tc) in enumerate([(1.0, 10.0), (2.0, 30.0), (4.0, 20.0)])]
    runs[0][1].update({"RS.sigma": 5e-3, "RS.f0": 19.0, "RS.tc": 0.3})
    runs[1][1].update({"RS.sigma": 7e-3, "RS.f0": 21.0, "RS.tc": 0.2})
    runs[2][1]["SN.A"], runs[2][1]["SN.f0"] = 1e-3, 0.5  # held by 1 of 3: left out
    got = rs.median_model({"z": runs}).set_index(["latent", "parameter"])
    assert list(dict.fromkeys(got.index.get_level_values(0))) == ["FW", "GM", "RW", "RS"]
    assert got.loc[("FW", "N"), "value"] == 2.0 and got.loc[("GM", "tc"), "value"] == 20.0
    assert got.loc[("RS", "sigma"), "value"] == pytest.approx(6e-3) and got.loc[("RS", "sigma"), "runs"] == 2


def test_committed_models_are_the_medians_of_their_runs(models):
    for r in models.itertuples():
        vals = [float(v) for v in r.per_run.split()]
        assert len(vals) == r.runs and 2 * r.runs > 6
        assert r.value == pytest.approx(np.median(vals), rel=1e-4), (r.axis, r.latent, r.parameter)
    # the axis model reproduces what it was fitted to: the coefficients the six-run table reports
    cons = pd.read_csv(RESULTS / "consistency.csv")
    cons = cons[(cons.sensor == "gyro") & (cons.method == "gmwm_filtered")].set_index(["axis", "coefficient"])
    truth = rs.truth_table(models)
    for axis in rs.AXES:
        # N: the median of six values within the six-run spread of their mean; B likewise (medians of sigma)
        for c in ("N", "B"):
            assert abs(truth[(axis, c)] - cons.loc[(axis, c), "mean"]) < 1.5 * cons.loc[(axis, c), "run_sd"], (axis, c)


def test_summary_statistics_hold_on_known_normal_values():
    # 400 replicates of two fits with known means and SDs: the CV's and the paired difference's bootstrap
    # standard errors must match their normal-theory values (CV / sqrt(2 (n-1)) for a CV well below 1)
    rng = np.random.default_rng(5)
    n = 400
    common = rng.standard_normal(n)
    a = 40.0 + 4.0 * common                                    # CV 10 %
    b = 40.0 + 4.0 * (0.6 * common + 0.8 * rng.standard_normal(n)) * 0.8  # CV 8 %, correlation 0.6
    rows = [{"axis": "z", "replicate": r, "fit": f, "coefficient": "B", "unit": "deg/h", "value": v, "std_err": 4.0,
             "flag": "ok", "poor_fit": False, "failed": False}
            for r in range(n) for f, v in (("gmwm_filtered", a[r]), ("gmwm", b[r]))]
    df = pd.DataFrame(rows)
    s = rs.summary(df).set_index("fit")
    for fit, cv in (("gmwm_filtered", 10.0), ("gmwm", 8.0)):
        se = cv / math.sqrt(2 * (n - 1))
        assert abs(s.loc[fit, "cv_pct"] - cv) < 4 * se
        assert s.loc[fit, "cv_se"] == pytest.approx(se, rel=0.2)
        assert s.loc[fit, "cv6_expected_pct"] == pytest.approx(0.9515 * s.loc[fit, "cv_pct"], rel=1e-3)
    p = rs.paired(df, coefs=("B",)).iloc[0]
    # Var(s_a - s_b) for bivariate normal: (sa^2 + sb^2 - 2 rho^2 sa sb) / (2 (n - 1)), in CV units
    se_diff = math.sqrt((10.0**2 + 8.0**2 - 2 * 0.6**2 * 10.0 * 8.0) / (2 * (n - 1)))
    assert p["diff_se"] == pytest.approx(se_diff, rel=0.2)
    assert p["diff_low"] < p["diff_pct"] < p["diff_high"]
    assert abs(p["diff_pct"] - 2.0) < 4 * se_diff
    assert p["correlation"] == pytest.approx(0.6, abs=0.1)
    # a value flagged "not resolved" counts in "all" (as consistency.csv counts it) and not in "both ok"
    df.loc[(df.fit == "gmwm") & (df.replicate == 0), ["value", "flag"]] = [400.0, "not resolved"]
    all_, ok = rs.paired(df, coefs=("B",)).iloc[0], rs.paired(df, coefs=("B",), ok_only=True).iloc[0]
    assert (all_["values"], ok["values"]) == ("all", "both ok")
    assert ok["replicates"] == n - 1 and all_["cv_plain_pct"] > 2 * ok["cv_plain_pct"]
    assert ok["cv_plain_pct"] == pytest.approx(p["cv_plain_pct"], rel=0.05)


def test_a_short_replicate_is_reproducible_and_fits_every_configuration(models):
    fits = {k: rs.FITS[k] for k in ("gmwm_filtered", "gmwm")}
    one = pd.DataFrame(rs.replicate_rows(models, "x", 3, fits, n_samples=1 << 15))
    two = pd.DataFrame(rs.replicate_rows(models, "x", 3, fits, n_samples=1 << 15))
    cols = ["fit", "coefficient", "value", "std_err", "flag", "min_m"]
    pd.testing.assert_frame_equal(one[cols], two[cols])
    assert set(one.fit) == set(fits) and not one.failed.any()
    assert list(one[one.fit == "gmwm"].coefficient) == ["N", "B", "K"]


def test_unknown_axis_is_named(models):
    with pytest.raises(ValueError, match="axis 'w'"):
        rs.model_gyro(models, "w")


@pytest.mark.slow
def test_committed_replicates_regenerate(models):
    # replicate 0 of every axis, full length, against the committed spread_fits.csv: nnls_rel (closed form)
    # to the digits written, the GMWM fits (an optimiser's end point) to 1 % of their spread over replicates
    committed = pd.read_csv(RESULTS / "spread_fits.csv")
    spread = pd.read_csv(RESULTS / "spread.csv").set_index(["axis", "fit", "coefficient"])["sd"]
    for axis in rs.AXES:
        got = pd.DataFrame(rs.replicate_rows(models, axis, 0)).set_index(["fit", "coefficient"])["value"]
        want = committed[(committed.axis == axis) & (committed.replicate == 0)].set_index(["fit", "coefficient"])["value"]
        assert set(got.index) == set(want.index)
        for key, v in want.items():
            if not np.isfinite(v):
                assert not np.isfinite(got[key])
                continue
            tol = 1e-5 * abs(v) if key[0] == "nnls_rel" else 0.01 * spread.get((axis, *key), abs(v))
            assert abs(got[key] - v) <= tol + 1e-12, (axis, key, got[key], v)


def test_asymptotic_standard_errors_follow_efficient_gmm(models):
    """``--asymptotic``: efficient GMM's large-sample standard errors. More octaves never cost precision (a
    moment added to an efficient GMM cannot raise any parameter's variance); a filter the octaves cannot see
    (tf 0.05 dt) gives the model with it the same B and N precision as the plain white-noise model on the
    same scales; and the committed table is what the function computes."""
    a = rs.asymptotic(models, ("x",)).set_index("design")
    own = [d for d in rs.ASYMPTOTIC_DESIGNS if rs.ASYMPTOTIC_DESIGNS[d][0] == "axis"]
    m_of = {d: rs.ASYMPTOTIC_DESIGNS[d][1] for d in own}
    by_m = sorted(own, key=m_of.get)
    for fewer, more in zip(by_m[1:], by_m[:-1]):  # more scales on the left
        for c in ("se_B_pct", "se_N_pct"):
            assert a.at[more, c] <= a.at[fewer, c] * (1 + 1e-9), (more, fewer, c)
    tiny = models.copy()
    tiny.loc[(tiny.axis == "x") & (tiny.parameter == "tf"), "value"] = 0.05 * rs.DT
    t = rs.asymptotic(tiny, ("x",)).set_index("design")
    same = t.loc["default model, m >= 16"], t.loc["WN+GM+RW, m >= 16 (plain)"]
    assert same[0]["se_B_pct"] == pytest.approx(same[1]["se_B_pct"], rel=1e-3)
    assert same[0]["se_N_pct"] > same[1]["se_N_pct"]  # N shares the white level with tf's (flat) column
    committed = RESULTS / "spread_asymptotic.csv"
    if committed.exists():
        c = pd.read_csv(committed)
        got = rs.asymptotic(models, tuple(dict.fromkeys(c.axis)))
        np.testing.assert_allclose(got[["se_B_pct", "se_N_pct"]], c[["se_B_pct", "se_N_pct"]], rtol=1e-4)


def test_variants_are_known_fits_and_the_held_tf_is_the_axis_models(models):
    """``--variants``: every paired label is a fit of the study; the tf-held variant gives the first default
    method the axis model's own filter time constant (a function of the model table and the axis)."""
    labels = set(rs.FITS) | set(rs.VARIANTS)
    assert all(a in labels and b in labels for a, b in rs.VARIANT_PAIRS)
    for axis in ("x", "y"):
        name, settings = rs.VARIANTS["gmwm_filtered_tf_held"](models, axis)
        tf = models[(models.axis == axis) & (models.parameter == "tf")]["value"].item()
        assert name == "gmwm_filtered" and settings == {"filter_tf": tf}


#: what ``--tables-only`` reads (the fits, the axis models, the real runs' CVs) and what it writes from them
TABLE_INPUTS = ("spread_models.csv", "spread_fits.csv", "spread_variants_fits.csv", "consistency.csv")
TABLE_OUTPUTS = ("spread.csv", "spread.md", "spread_paired.csv", "spread_variants.csv", "spread_variants.md")


def test_tables_only_regenerates_the_committed_tables_from_the_committed_fits(tmp_path):
    """A clone holds the fits, not the shards: ``--tables-only`` (and with ``--variants``) reads the committed
    fit tables, leaves them as they are, and writes the committed summary tables byte for byte."""
    for name in TABLE_INPUTS:
        shutil.copy(RESULTS / name, tmp_path / name)
    assert rs.main(["--out", str(tmp_path), "--tables-only"]) == 0
    assert rs.main(["--out", str(tmp_path), "--tables-only", "--variants"]) == 0
    for name in TABLE_INPUTS + TABLE_OUTPUTS:
        assert (tmp_path / name).read_bytes() == (RESULTS / name).read_bytes(), name
    assert not (tmp_path / "_shards").exists()


def test_tables_only_prefers_the_shards_and_names_what_is_missing(tmp_path):
    """Shards present: the fit table is written from them (CPU seconds left out) and the tables from it (one
    axis's shards: that axis's committed rows, every statistic being per axis); neither shards nor a fit
    table: an error naming both."""
    committed = pd.read_csv(RESULTS / "spread_fits.csv")
    part = committed[committed.axis == "x"].reset_index(drop=True)
    shards = tmp_path / "_shards" / "spread"
    shards.mkdir(parents=True)
    for r, g in part.groupby("replicate"):
        g.assign(cpu_s=1.0).to_csv(shards / f"x_{r:04d}.csv", index=False)
    for name in ("spread_models.csv", "consistency.csv"):
        shutil.copy(RESULTS / name, tmp_path / name)
    assert rs.main(["--out", str(tmp_path), "--tables-only"]) == 0
    pd.testing.assert_frame_equal(pd.read_csv(tmp_path / "spread_fits.csv"), part)
    for name in ("spread.csv", "spread_paired.csv"):
        want = pd.read_csv(RESULTS / name)
        pd.testing.assert_frame_equal(pd.read_csv(tmp_path / name), want[want.axis == "x"].reset_index(drop=True))
    with pytest.raises(SystemExit, match=r"no shards under .*variants and no .*spread_variants_fits\.csv"):
        rs.main(["--out", str(tmp_path), "--tables-only", "--variants"])
