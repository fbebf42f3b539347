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


# -- the compiled normal equations -------------------------------------------------------------------

from avbench.estimators.curve_fits import _kernels as lsk  # noqa: E402
from avbench.estimators.curve_fits import least_squares as ls  # noqa: E402
from avbench.estimators.allan.variance import allan_variance, edf_overlapping  # noqa: E402

TERM_SETS = ["QNBKR", "QNB", "NBK", "NB", "K", "QR"]


def _grid(rng, n):
    return np.sort(rng.uniform(0.01, 5e3, n)) if rng.random() < 0.5 else np.arange(1, n + 1) * 0.1


def test_power_kernels_equal_their_numpy_references():
    rng = np.random.default_rng(25)
    for _ in range(20):
        n = int(rng.integers(1, 3000))
        tau, y, w2 = _grid(rng, n), rng.lognormal(size=n), rng.lognormal(size=n) ** 2
        for got, ref in zip(lsk.power_sums(tau, y, w2), lsk.power_sums_numpy(tau, y, w2)):
            np.testing.assert_allclose(got, ref, rtol=1e-12)
        terms = TERM_SETS[int(rng.integers(len(TERM_SETS)))]
        p, beta = ls._powers(terms), rng.normal(size=len(terms))
        scale = lsk.power_curve_numpy(tau, p, np.abs(beta))  # cancellation: compare with the terms' size
        assert np.all(np.abs(lsk.power_curve(tau, p, beta) - lsk.power_curve_numpy(tau, p, beta)) <= 1e-12 * scale)
        table, rule = rng.uniform(1, 100, (n, 2)), rng.integers(0, 2, len(terms))
        level, edf = np.empty(n), np.empty(n)
        s, r = lsk.edf_weighted_sums(tau, y, y, p, beta, table, rule, level, edf)
        s0, r0, level0, edf0 = lsk.edf_weighted_sums_numpy(tau, y, y, p, beta, table, rule)
        np.testing.assert_array_equal(edf, edf0)  # the same dominant column on every row
        np.testing.assert_allclose(level, level0, rtol=1e-13)
        np.testing.assert_allclose(s, s0, rtol=1e-12)
        np.testing.assert_allclose(r, r0, rtol=1e-12)


def _edf_of_rows_reference(av, beta, terms):
    """wls_edf's row edf the plain way (the design built, numpy's argmax, per-row edf): the reference the
    compiled normal equations are held to."""
    X = design_matrix(av.tau, terms)
    noise = np.array([ls._NOISE_OF_TERM[t] for t in terms], dtype=object)
    contrib = X * np.maximum(beta, 0)[None, :]
    model = contrib.sum(axis=1)
    column = contrib.argmax(axis=1)
    if av.overlapping:
        edf = edf_overlapping(av.m, av.n_samples, noise[column])
    else:
        edf = ls._edf_nonoverlapping(av.J, (noise == "white_pm")[column])
    return np.where(model > 0, model, av.avar), edf


@pytest.mark.parametrize("overlapping", [False, True])
def test_edf_of_rows_equals_its_plain_reference(overlapping):
    g = presets.get("VG951")
    x = g.simulate(20_000, np.random.default_rng(3))
    av = allan_variance(x, g.dt, taus="octave" if overlapping else "all", overlapping=overlapping)
    rng = np.random.default_rng(4)
    for terms in TERM_SETS:
        beta = rng.normal(size=len(terms)) * ls.solve_power_design(av.tau, av.avar, terms)
        level, edf = ls.edf_of_rows(av, beta, terms)
        level0, edf0 = _edf_of_rows_reference(av, beta, terms)
        np.testing.assert_array_equal(edf, edf0)
        np.testing.assert_allclose(level, level0, rtol=1e-13)


def test_normal_equations_agree_with_the_svd_of_the_design():
    """On the studies' grids (taus='all', 30 min to 24 h at 10 and 100 Hz) and weights (none, J, the edf
    weights of wls_edf) the equilibrated normal equations are well conditioned (cond(WXD^-1) <= 31, so
    kappa <= 1e3) and their Cholesky solution equals the SVD's (lstsq) within kappa x 3e-14, the bound of
    ``solve_normal``'s docstring (norm-wise, in the equilibrated coordinates)."""
    rng = np.random.default_rng(5)
    for n, dt in [(18_000, 0.1), (72_000, 0.1), (180_000, 0.01), (864_000, 0.1)]:
        m = np.arange(1, n // 2 + 1)
        tau, J = m * dt, (n // m).astype(float)
        for terms in ["QNB", "QNBKR"]:
            X = design_matrix(tau, terms)
            y = X @ (np.abs(rng.normal(size=len(terms))) / np.linalg.norm(X, axis=0)) * rng.lognormal(0, 0.3, tau.size)
            for w in [None, J, np.sqrt(J) / y]:
                Xw = X if w is None else X * w[:, None]
                d = np.linalg.norm(Xw, axis=0)
                kappa = np.linalg.cond(Xw / d) ** 2
                assert kappa < 1e3
                svd = ls._lstsq_equilibrated(Xw, y if w is None else y * w)
                got = ls.solve_power_design(tau, y, terms, w)
                assert np.linalg.norm((got - svd) * d) <= kappa * 3e-14 * np.linalg.norm(svd * d)
                np.testing.assert_array_equal(ls.solve_scaled(X, y, w), ls.solve_normal(Xw.T @ Xw, Xw.T @ (y if w is None else y * w)))


def test_ill_conditioned_normal_equations_fall_back_to_the_svd():
    tau = np.linspace(1.0, 2.0, 40)  # one octave: the five columns nearly dependent
    X = design_matrix(tau, "QNBKR")
    y = X @ np.array([3e-12, 1e-8, PLATEAU * 1e-10, 1e-13 / 3, 1e-18 / 2])
    w = 1 / y
    Xw = X * w[:, None]
    assert np.linalg.cond(Xw / np.linalg.norm(Xw, axis=0)) ** 2 > ls.MAX_GRAM_COND
    assert ls.solve_normal(Xw.T @ Xw, Xw.T @ (y * w)) is None  # not solved there
    np.testing.assert_array_equal(ls.solve_scaled(X, y, w), ls._lstsq_equilibrated(Xw, y * w))
    np.testing.assert_array_equal(ls.solve_power_design(tau, y, "QNBKR", w), ls._lstsq_equilibrated(Xw, y * w))
    # singular (a constant column twice): refused by the normal equations too
    G = np.ones((2, 2))
    assert ls.solve_normal(G, np.ones(2)) is None
