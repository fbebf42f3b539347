"""Tests of the online filters shakf, nekf and their multitau extensions.

Tolerances: the compiled kernels against the NumPy reference to round-off; convergence against
the standard error of the recursive AV the filters track (white noise: Var(AV_hat)/AV^2 = 3/n for
the non-overlapping tau0 AV, so rel.sd(N_hat) = sqrt(3/n)/2), and across replicates against
the replicates' own standard error.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from avbench import estimators
from avbench.estimators import DivergenceWarning, IdentifiabilityWarning
from avbench.estimators.online._reference import nekf_reference, shakf_reference
from avbench.estimators.allan.variance import recursive_avar
from avbench.noise_models import AngleRandomWalk, Gyro, RateRandomWalk, presets

DT = 0.01
N_TRUE = 1e-4  # rad/s^0.5 -> white rate std N/sqrt(dt) = 1e-3 rad/s
ONLINE = ["shakf", "nekf", "shakf_multitau", "nekf_multitau"]


def white(n, seed):
    return N_TRUE / math.sqrt(DT) * np.random.default_rng(seed).standard_normal(n)


def adis(n, seed):
    g = presets.get("ADIS16405_Y")
    return g, g.simulate(n, np.random.default_rng(seed))


def fit_quiet(name, rate, dt=DT, **settings):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IdentifiabilityWarning)
        return estimators.get(name, **settings).fit(rate, dt)


# -- compiled kernels == NumPy reference --------------------------------------------------------
@pytest.mark.parametrize("m", [None, [1, 2, 4, 8]])
@pytest.mark.parametrize("adapt", ["qQrR", "qQR"])
def test_shakf_kernel_matches_reference(m, adapt):
    g, rate = adis(1500, 1)
    x0 = {c: 0.7 * g.coefficients[c] for c in "NBK"}
    name, extra = ("shakf", {}) if m is None else ("shakf_multitau", {"m": m})
    est = fit_quiet(name, rate, g.dt, terms="NBK", x0=x0, adapt=adapt, Q0=1e-6, trajectory_every=1, **extra)
    cfg = est._cfg
    traj, code, _, _ = shakf_reference(
        rate, est._zinv, est._A, cfg["m"], np.ones(3), cfg["P0"], cfg["Q0"],
        np.full(len(cfg["m"]), 1.0), cfg["b"], cfg["adapt_flags"],
    )
    assert code == 0 and est.result().failure is None
    got = est.diagnostics_["trajectory"].to_numpy() / est._c_ref
    np.testing.assert_allclose(got, traj, rtol=1e-9, atol=0)


@pytest.mark.parametrize("m", [None, [1, 4]])
def test_nekf_kernel_matches_reference(m):
    g, rate = adis(400, 2)
    x0 = {c: 1.3 * g.coefficients[c] for c in "NBK"}
    name, extra = ("nekf", {}) if m is None else ("nekf_multitau", {"m": m})
    est = fit_quiet(name, rate, g.dt, terms="NBK", x0=x0, p=4, lambda_scale=0.1, seed=3,
                    trajectory_every=1, **extra)
    st = est._state
    nq, p = 3, 4
    rng = np.random.default_rng(3)
    xa0 = np.concatenate([np.ones(nq), rng.standard_normal(p * nq), 0.1 * rng.standard_normal(nq * p)])
    n = len(xa0)
    P0 = np.diag(np.r_[np.full(nq, 0.25), np.full(n - nq, est._cfg["wP0"])])
    traj, code, _, _ = nekf_reference(rate, est._zinv, est._A, est._cfg["m"], xa0, P0, st["Qbar"], st["Rbar"], nq, p)
    assert code == 0
    got = est.diagnostics_["trajectory"].to_numpy() / est._c_ref
    # the augmented covariance is ill-conditioned (cond ~1e11): round-off differences grow slowly
    np.testing.assert_allclose(got, traj, rtol=1e-7, atol=0)


def _gp_plain(G, P):
    """``M = G P`` as the plain loop sums it: over ``e`` in order from +0.0, zeros of ``G`` skipped."""
    nq, n = G.shape
    M = np.zeros((nq, n))
    for a in range(nq):
        for e in range(n):
            if G[a, e] != 0.0:
                M[a] += G[a, e] * P[e]
    return M


@settings(max_examples=60, deadline=None)
@given(nq=st.integers(1, 5), n=st.integers(1, 70), seed=st.integers(0, 2**32 - 1),
       zeros=st.floats(0.0, 0.9), special=st.sampled_from(["none", "inf", "nan"]))
def test_nekf_register_blocked_product_is_the_plain_loop_bit_for_bit(nq, n, seed, zeros, special):
    """``_gp_rows`` (register blocks of 32/16/4 columns, the last one overlapping) gives the
    bits of the plain ordered sum for every width, exact zeros of G skipped even against
    infinite or NaN entries of P."""
    from avbench.estimators.online._kernels import _gp_rows

    rng = np.random.default_rng(seed)
    G = rng.standard_normal((nq, n)) * 10.0 ** rng.integers(-8, 8, (nq, n))
    G[rng.random((nq, n)) < zeros] = 0.0
    P = rng.standard_normal((n, n)) * 10.0 ** rng.integers(-8, 8, (n, n))
    if special != "none":
        P[rng.integers(n), rng.integers(n)] = np.inf if special == "inf" else np.nan
    M = np.full((nq, n), -7.0)
    _gp_rows(G, P, M, nq, n)
    assert M.tobytes() == _gp_plain(G, P).tobytes()


# -- streaming ----------------------------------------------------------------------------------
@pytest.mark.parametrize("name", ONLINE)
@pytest.mark.parametrize("x0", [None, "given"])
def test_chunked_equals_one_shot(name, x0):
    g, rate = adis(12_000, 4)
    settings = dict(terms="NBK", x0_samples=5000, trajectory_every=7)
    if x0:
        settings["x0"] = {c: g.coefficients[c] for c in "NBK"}
    if "multitau" in name:
        settings["m"] = 6
    one = fit_quiet(name, rate, g.dt, **settings)
    est = estimators.get(name, **settings)
    cuts = np.sort(np.random.default_rng(0).choice(np.arange(1, rate.size), 9, replace=False))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IdentifiabilityWarning)
        for chunk in np.split(rate, cuts):
            est.partial_fit(chunk, g.dt)
    np.testing.assert_array_equal(est.current_coefficients().to_numpy(), one.coefficients_.to_numpy())
    np.testing.assert_array_equal(est.diagnostics_["trajectory"].to_numpy(), one.diagnostics_["trajectory"].to_numpy())
    np.testing.assert_array_equal(est.diagnostics_["trajectory"].index, one.diagnostics_["trajectory"].index)


def test_streaming_waits_for_x0_window_and_flush_starts_it():
    rate = white(3000, 5)
    est = estimators.get("shakf", terms="N", x0_samples=5000)
    est.partial_fit(rate[:2000], DT)
    assert np.isnan(est.current_coefficients()["N"])
    est.partial_fit(rate[2000:], DT).flush()
    one = estimators.get("shakf", terms="N", x0_samples=5000).fit(rate, DT)
    assert est.current_coefficients()["N"] == one.coefficients_["N"]


def test_trajectory_off_and_decimated():
    rate = white(1000, 6)
    off = estimators.get("nekf", terms="N", x0={"N": N_TRUE}, trajectory_every=0).fit(rate, DT)
    assert off.result().trajectory is None
    default = estimators.get("shakf", terms="N", x0={"N": N_TRUE}).fit(white(2500, 8), DT)
    assert list(default.diagnostics_["trajectory"].index) == [999, 1999]  # decimated by default
    dec = estimators.get("nekf", terms="N", x0={"N": N_TRUE}, trajectory_every=100).fit(rate, DT)
    assert list(dec.diagnostics_["trajectory"].index) == list(range(99, 1000, 100))
    assert dec.diagnostics_["trajectory"]["N"].iloc[-1] == dec.coefficients_["N"]


# -- convergence --------------------------------------------------------------------------------
N_SAMPLES = 200_000
REL_SE = 0.5 * math.sqrt(3.0 / N_SAMPLES)  # rel.sd of sqrt(tau0 AV) for white noise


@pytest.mark.parametrize("name,settings", [("shakf", {"adapt": "qQR"}), ("nekf", {})])
@pytest.mark.parametrize("start", [0.5, 2.0])
def test_single_white_term_converges_to_truth(name, settings, start):
    rate = white(N_SAMPLES, 7)
    est = estimators.get(name, terms="N", x0={"N": start * N_TRUE}, trajectory_every=0, **settings).fit(rate, DT)
    n_hat = est.coefficients_["N"]
    # it tracks the recursive AV it measures ...
    z = recursive_avar(rate, 1)[-1]
    assert abs(n_hat / math.sqrt(z * DT) - 1) < 0.1 * REL_SE
    # ... which is within a few standard errors of the truth
    assert abs(n_hat / N_TRUE - 1) < 4 * REL_SE


def test_faithful_shakf_measurement_mean_absorbs_the_initial_error():
    """With eq 3.18 (adapt 'r') the split between h(x) and r is set by the first samples."""
    rate = white(N_SAMPLES, 7)
    est = estimators.get("shakf", terms="N", x0={"N": 0.5 * N_TRUE}, trajectory_every=0).fit(rate, DT)
    n_hat = est.coefficients_["N"]
    assert abs(n_hat / N_TRUE - 1) > 20 * REL_SE  # biased far beyond the sampling error
    # but h(x) + r still tracks the measured AV
    z = est.diagnostics_["avar"][0]
    h = n_hat**2 / DT
    r = est.diagnostics_["r"][0] * z / (z * est._zinv[0])  # r is in scaled units
    assert abs((h + r) / z - 1) < 1e-3


@pytest.mark.parametrize("name", ["shakf_multitau", "nekf_multitau"])
def test_multitau_recovers_N_and_K(name):
    N, K = 1e-4, 1.7e-5  # crossover tau = sqrt(3) N / K ~ 10 s
    g = Gyro(dt=DT, terms=[AngleRandomWalk(N=N), RateRandomWalk(K=K)])
    reps = 6
    est = np.array(
        [
            estimators.get(name, terms="NK", m=14, x0={"N": 2 * N, "K": 0.5 * K}, trajectory_every=0)
            .fit(g.simulate(200_000, np.random.default_rng(100 + i)), DT)
            .coefficients_[["N", "K"]]
            .to_numpy()
            / [N, K]
            for i in range(reps)
        ]
    )
    mean, se = est.mean(axis=0), est.std(axis=0, ddof=1) / math.sqrt(reps)
    # no failures, and the mean within 3 standard errors (plus 2 % for the finite-n filter lag)
    assert np.all(np.isfinite(est))
    assert np.all(np.abs(mean - 1) < 3 * se + 0.02), (mean, se)
    # and they move from the 2x / 0.5x start: N is found to well within 1 %
    assert abs(mean[0] - 1) < 0.01


@pytest.mark.slow
@pytest.mark.parametrize("name", ["shakf_multitau", "nekf_multitau"])
def test_multitau_monte_carlo_adis(name):
    g = presets.get("ADIS16405_Y")
    truth = g.coefficients
    reps = 8
    out = []
    for i in range(reps):
        rate = g.simulate(presets.info("ADIS16405_Y").n_samples, np.random.default_rng(200 + i))
        est = fit_quiet(name, rate, g.dt, terms="NBK", m=17, trajectory_every=0)
        out.append((est.coefficients_[["N", "K"]] / truth[["N", "K"]]).to_numpy())
    out = np.array(out)
    mean, se = out.mean(axis=0), out.std(axis=0, ddof=1) / math.sqrt(reps)
    assert np.all(np.abs(mean - 1) < 3 * se + 0.05), (mean, se)


# -- divergence, warnings, bad input ------------------------------------------------------------
def test_divergence_is_reported_not_raised():
    g, rate = adis(20_000, 8)
    est = estimators.get("nekf", terms="NBK", x0={c: g.coefficients[c] for c in "NBK"},
                         weights_Q0=0.0, Q0=0.0, pd_check_every=1)
    with pytest.warns(DivergenceWarning):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", IdentifiabilityWarning)
            est.fit(rate, g.dt)
    fail = est.diagnostics_["failure"]
    assert fail.startswith("sample ") and "positive definite" in fail
    at = int(fail.split()[1].rstrip(":"))
    assert 0 < at < rate.size
    assert est.coefficients_.isna().all()
    assert np.isfinite(est.diagnostics_["last_good"][["N", "B", "K"]]).all()
    assert est.diagnostics_["trajectory"].index.max() < at


def test_starting_values_beyond_float64_from_the_data_are_refused():
    """1e200 data are fitted in power-of-two units (Estimator.fit); x0 = 1 rad/s^0.5 is then ~1e-200
    of the data's scale, whose square underflows: a clear error naming x0, not a warning storm."""
    rate = 1e200 * np.random.default_rng(9).standard_normal(100)
    est = estimators.get("shakf", terms="N", x0={"N": 1.0})
    with pytest.raises(ValueError, match="x0: the initial coefficients"):
        est.fit(rate, DT)
    # with starting values of the data's own scale it runs and scales with the data
    est = estimators.get("shakf", terms="N", x0={"N": 1e200 * 0.1}).fit(rate, DT)
    small = estimators.get("shakf", terms="N", x0={"N": 0.1}).fit(rate / 1e200, DT)
    assert est.coefficients_["N"] / 1e200 == pytest.approx(small.coefficients_["N"], rel=1e-9)


def test_identifiability_warning_only_for_underdetermined_models():
    rate = white(2000, 10)
    with pytest.warns(IdentifiabilityWarning, match="single tau0"):
        estimators.get("shakf", terms="NB", x0={"N": N_TRUE, "B": 1e-5}).fit(rate, DT)
    with warnings.catch_warnings():
        warnings.simplefilter("error", IdentifiabilityWarning)
        estimators.get("shakf", terms="N", x0={"N": N_TRUE}).fit(rate, DT)
        estimators.get("nekf_multitau", terms="NB", m=4, x0={"N": N_TRUE, "B": 1e-5}).fit(rate, DT)


@pytest.mark.parametrize(
    "name,settings,match",
    [
        ("shakf", {"b": 1.5}, "b=1.5: expected a finite number >= 0 and <= 1"),
        ("shakf", {"adapt": "qx"}, "adapt"),
        ("shakf", {"terms": "NZ"}, "terms"),
        ("shakf", {"terms": "NB", "x0": {"N": 1e-4}}, "missing"),
        ("shakf", {"terms": "N", "x0": {"N": 0.0}}, "x0=.*: expected None or a mapping .* > 0 .*N: 0, expected a positive"),
        ("shakf", {"terms": "N", "x0": {"N": [1.0, "furlong"]}}, "unit"),
        ("shakf", {"terms": "NB", "P0": [1.0, 2.0, 3.0]}, "P0"),
        ("shakf", {"terms": "N", "R0": -1.0}, "R0"),
        ("shakf_multitau", {"terms": "N", "m": [0, 2]}, "cluster sizes"),
        ("nekf", {"terms": "N", "p": 0}, "p=0: expected an integer >= 1"),
        ("nekf", {"terms": "N", "seed": -1}, "seed=-1: expected an integer >= 0"),
        ("nekf", {"terms": "N", "weights_Q0": "maybe"}, "weights_Q0"),
        ("shakf", {"terms": "NB", "Q0": [[1.0, 2.0], [0.0, 1.0]]}, "Q0=.*symmetric"),
        ("shakf_multitau", {"terms": "N", "m": 3, "R0": [1.0, 2.0]}, "R0: expected a positive number or 3"),
        ("shakf_multitau", {"terms": "N", "m": [1, 2, 2]}, "distinct"),
        ("nekf", {"terms": "N", "seed": 1.5}, "seed"),
        ("nekf", {"terms": "N", "trajectory_every": -1}, "trajectory_every"),
    ],
)
def test_bad_settings_raise_clear_errors(name, settings, match):
    with pytest.raises(ValueError, match=match):
        estimators.get(name, **settings).fit(white(100, 11), DT)
    # streaming use (partial_fit, without Estimator.fit) checks them too
    with pytest.raises(ValueError, match=match):
        estimators.get(name).set_params(**settings).partial_fit(white(100, 11), DT)


def test_partial_fit_rejects_changed_dt_and_bad_chunks():
    est = estimators.get("shakf", terms="N", x0={"N": N_TRUE})
    est.partial_fit(white(100, 12), DT)
    with pytest.raises(ValueError, match="dt"):
        est.partial_fit(white(100, 13), 2 * DT)
    with pytest.raises(ValueError, match="non-finite"):
        est.partial_fit(np.array([0.0, np.nan]), DT)


def test_clone_and_registry():
    for name in ONLINE:
        est = estimators.get(name, terms="N")
        assert est.online and est.clone().get_params() == est.get_params()
