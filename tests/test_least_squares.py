"""Least-squares AV fits: exact recovery on exact curves, and accuracy regressions on the
Lv et al. (2015) protocol. Bounds come from the paper's Table 2 and from the Monte Carlo
statistics of our own replicates (F and chi^2 quantiles, Student-t standard errors)."""

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from avbench import estimators
from avbench import studies
from avbench.estimators.allan.model import PLATEAU, design_matrix
from avbench.estimators.curve_fits.least_squares import solve_scaled
from avbench.noise_models import presets
from avbench.noise_models.units import PAPER_UNITS, to_si

LS = ["ols", "ols_trimmed", "wls", "wls_edf"]


def test_solver_recovers_exact_beta():
    tau = np.logspace(-2, 4, 40)
    beta = np.array([3e-12, 1e-8, PLATEAU * 1e-10, 1e-13 / 3, 1e-18 / 2])
    X = design_matrix(tau, "QNBKR")
    y = X @ beta
    np.testing.assert_allclose(solve_scaled(X, y), beta, rtol=1e-8)
    np.testing.assert_allclose(solve_scaled(X, y, 1 / y), beta, rtol=1e-8)


def test_trimmed_keeps_values_with_error_at_most_40pct():
    g = presets.get("VG951")
    x = g.simulate(20_000, np.random.default_rng(0))
    e = estimators.get("ols_trimmed", terms="QNB").fit(x, g.dt)
    av, used = e.diagnostics_["allan"], e.diagnostics_["used"]
    np.testing.assert_array_equal(used, 100 / np.sqrt(2 * (av.J - 1)) <= 40)
    assert used.sum() == np.sum(av.J >= 5)  # 100/sqrt(2(J-1)) <= 40  <=>  J >= 4.125


def test_negative_beta_is_flagged_not_clipped():
    # pure white noise: the fitted Q and B columns go negative on some records
    rng = np.random.default_rng(1)
    seen = False
    for _ in range(20):
        x = rng.standard_normal(4000)
        e = estimators.get("ols", terms="QNB").fit(x, 1.0)
        beta = e.diagnostics_["beta"]
        for c in "QB":
            assert e.nonphysical_[c] == (beta[c] < 0)
            assert np.isnan(e.coefficients_[c]) == (beta[c] < 0)
            seen |= beta[c] < 0
    assert seen


def _lv_protocol(gyro_name, R, seed):
    g = presets.get(gyro_name)
    n = presets.info(gyro_name).n_samples
    coefs = {k: [] for k in LS}
    betas = {k: [] for k in LS}
    for s in np.random.SeedSequence(seed).spawn(R):
        x = g.simulate(n, np.random.default_rng(s))
        for k in LS:
            e = estimators.get(k, terms="QNB", taus="all", overlapping=False).fit(x, g.dt)
            coefs[k].append(e.coefficients_)
            betas[k].append(e.diagnostics_["beta"])
    av = e.diagnostics_["allan"]  # the grid is the same for every replicate
    return g, av, {k: pd.DataFrame(v) for k, v in coefs.items()}, {k: pd.DataFrame(v) for k, v in betas.items()}


def _paper(gyro, method):
    from avbench.studies.papers import load_paper_table

    path = Path(studies.__file__).parent / "paper_tables" / "lv2015_tables_2_4_6.csv"  # shipped with the package
    t = load_paper_table(path)
    t = t[(t.gyro == gyro) & (t.method == method)].set_index("coefficient")
    return {c: (t.loc[c, "error_pct"], to_si(c, t.loc[c, "std"], PAPER_UNITS[c])) for c in "QNB"}


def _check_lv(gyro_name, R, seed):
    g, av, res, betas = _lv_protocol(gyro_name, R, seed)
    paper = _paper(gyro_name, "wls")
    wls, ols = res["wls"], res["ols"]
    for c in "QN":
        # 1. Lv et al.'s claim: WLS is more stable than OLS on all AV values (F test, level 1e-3)
        a, b = ols[c].dropna(), wls[c].dropna()
        assert len(a) >= 4 and len(b) == R
        F = a.var(ddof=1) / b.var(ddof=1)
        assert F > stats.f.ppf(0.999, len(a) - 1, len(b) - 1), (c, F)
    for c in "QNB":
        # 2. WLS spread no worse than the paper's (chi^2 upper quantile for R - 1 dof)
        v = wls[c].to_numpy()
        assert v.std(ddof=1) <= paper[c][1] * np.sqrt(stats.chi2.ppf(0.999, R - 1) / (R - 1)), c
    # 3. the linear fits are unbiased for their noise-free limit: beta-hat is linear in the AV
    #    values and E[AV-hat] is the generator's exact AV, so mean(beta-hat) = fit(exact AV)
    X = design_matrix(av.tau, "QNB")
    y = g.avar(av.tau)
    limits = {
        "ols": solve_scaled(X, y),
        "ols_trimmed": solve_scaled(X[av.J >= 5], y[av.J >= 5]),
        "wls": solve_scaled(X, y, av.J.astype(float)),
    }
    for k, lim in limits.items():
        b = betas[k].to_numpy()
        half = stats.t.ppf(1 - 1e-4, R - 1) * b.std(axis=0, ddof=1) / np.sqrt(R)
        assert np.all(np.abs(b.mean(axis=0) - lim) <= half), (k, b.mean(axis=0) / lim)


def test_lv2015_srs2000_small():
    _check_lv("SRS2000", R=6, seed=2015)


@pytest.mark.slow
@pytest.mark.parametrize("gyro", ["SRS2000", "VG951", "CRG20"])
def test_lv2015_protocol_slow(gyro):
    _check_lv(gyro, R=30, seed=2016)
