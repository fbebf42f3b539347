"""Tests of the equivalent-ARMA recursive-EM estimator ``arma_em`` (Miao et al. 2015, §3)."""

from __future__ import annotations

import importlib
import math

import numpy as np
import pytest

from avbench import estimators
from avbench.estimators.online import _arma_em_kernels as K
from avbench.estimators.online._arma_em_reference import ek_run_reference
from avbench.estimators.online.arma_em import ArmaEM, EKFilter, coefficients_from_model, initial_model
from avbench.estimators.base import DivergenceWarning
from avbench.noise_models import AngleRandomWalk, GaussMarkov, Gyro, RateRandomWalk

crlb = importlib.import_module("avbench.estimators.likelihood.crlb").crlb

TRUTH = {"N": 1e-3, "B": 3e-4, "K": 1e-5}


def _scaled_model(terms, form="diagonal", tc=5.0, dt=0.01):
    A, C, Q, R = initial_model(TRUTH, tc, dt, terms, form)
    s = math.sqrt(R[0])
    return A, C / s, Q, R / s**2


def _simulate_ss(A, C, Q, R, n, rng):
    m = A.shape[0]
    L = np.linalg.cholesky(Q + 1e-300 * np.eye(m)) if np.all(np.diag(Q) > 0) else np.sqrt(np.maximum(Q, 0))
    x = np.zeros(m)
    y = np.empty(n)
    for t in range(n):
        y[t] = C @ x + math.sqrt(R[0]) * rng.standard_normal()
        x = A @ x + L @ rng.standard_normal(m)
    return y


# --- sufficient statistics: E-K filters vs Kalman smoother (Shumway & Stoffer) ------------------
@pytest.mark.parametrize("terms,form", [("NK", "eq63"), ("NB", "eq63"), ("NBK", "diagonal"), ("NBK", "eq63")])
def test_ek_statistics_equal_kalman_smoother(terms, form):
    from statsmodels.tsa.statespace.kalman_smoother import KalmanSmoother

    A, C, Q, R = _scaled_model(terms, form)
    m = A.shape[0]
    n = 300
    y = _simulate_ss(A, C, Q, R, n, np.random.default_rng(3))
    P0 = np.eye(m) / (C @ C)
    f = EKFilter(A.copy(), C.copy(), Q.copy(), R.copy())
    f.start(y[0], P0)
    f.run(y[1:], recursive=False, warmup=1, update_every=1, trace_every=0, exact_q=True)
    st = f.statistics()

    ks = KalmanSmoother(k_endog=1, k_states=m, design=C[None, :], obs_cov=R[None, :], transition=A,
                        selection=np.eye(m), state_cov=Q)
    ks.bind(y[:, None].copy())
    ks.initialize_known(np.zeros(m), P0)
    r = ks.smooth()
    xs, Ps, Pa = r.smoothed_state, r.smoothed_state_cov, r.smoothed_state_autocov
    second = [Ps[:, :, t] + np.outer(xs[:, t], xs[:, t]) for t in range(n)]
    expected = {
        "U0": sum(second),
        "U3": sum(second[1:]),
        "U2": sum(second[:-1]),
        # statsmodels: smoothed_state_autocov[:, :, t - 1] = Cov(x_t, x_{t-1} | Y)
        "U1": sum(Pa[:, :, t - 1] + np.outer(xs[:, t], xs[:, t - 1]) for t in range(1, n)),
        "T": xs @ y,
    }
    for key, val in expected.items():
        scale = np.max(np.abs(val))
        np.testing.assert_allclose(st[key], val, rtol=0, atol=1e-8 * scale, err_msg=key)
    assert st["k"] == n - 1
    assert math.isclose(st["syy"], float(y @ y), rel_tol=1e-12)
    # the filter's log-likelihood is the Kalman filter's
    assert math.isclose(f.loglik, float(r.llf), rel_tol=1e-9)


# --- compiled kernel vs plain NumPy reference --------------------------------------------------
@pytest.mark.parametrize("terms,exact_q", [("NK", False), ("NB", True), ("NBK", False), ("NBK", True)])
def test_kernel_equals_reference(terms, exact_q):
    A, C, Q, R = _scaled_model(terms, "eq63" if terms == "NBK" else "diagonal")
    y = _simulate_ss(A, C, Q, R, 400, np.random.default_rng(7))
    # start away from the truth so that the recursive M-step moves the parameters
    filters = [EKFilter(A.copy(), 1.3 * C, 0.5 * Q + 1e-3 * np.diag(np.diag(Q) == 0), 0.8 * R) for _ in range(2)]
    traces = []
    for f, run in zip(filters, (K.ek_run, ek_run_reference)):
        f.start(y[0], np.eye(f.m))
        m = f.m
        trace = np.empty((40, 2 + 2 * m * m + m))
        ntr = run(y[1:], f.A, f.C, f.Q, f.R, f.x, f.P, f.a, f.b, f.d, f.aT, f.bT, f.sc, f.ic, True, 20, 1,
                  10, trace, exact_q)
        traces.append(trace[:ntr])
    f1, f2 = filters
    assert f1.ic[K.I_UPDATES] > 300 and np.array_equal(f1.ic, f2.ic)
    for name in ("A", "C", "Q", "R", "x", "P", "a", "b", "d", "aT", "bT", "sc"):
        np.testing.assert_allclose(getattr(f1, name), getattr(f2, name), rtol=1e-9, atol=1e-12, err_msg=name)
    np.testing.assert_allclose(traces[0], traces[1], rtol=1e-9, atol=1e-14)


def test_estimator_engines_agree():
    y = _simulate_ss(*_scaled_model("NK"), 300, np.random.default_rng(1))
    kw = dict(terms="NK", x0={"N": 2e-3, "K": 3e-5}, warmup=20, trace_every=50)
    a = ArmaEM(**kw).fit(y, 0.01)
    b = ArmaEM(engine="reference", **kw).fit(y, 0.01)
    np.testing.assert_allclose(a.coefficients_.to_numpy(), b.coefficients_.to_numpy(), rtol=1e-9)
    np.testing.assert_allclose(a.diagnostics_["trajectory"].to_numpy(), b.diagnostics_["trajectory"].to_numpy(),
                               rtol=1e-9)


# --- mapping back to N, B, K -------------------------------------------------------------------
@pytest.mark.parametrize("terms", ["NK", "NB", "NBK"])
def test_mapping_roundtrip_and_similarity_invariance(terms):
    dt, tc = 0.01, 50.0
    A, C, Q, R = initial_model(TRUTH, tc, dt, terms, "diagonal")
    c, bad, extra = coefficients_from_model(A, C, Q, R, dt, terms)
    for t in terms:
        assert not bad[t]
        assert math.isclose(c[t], TRUTH[t], rel_tol=1e-9), t
    if "B" in terms:
        assert math.isclose(extra["tc"], tc, rel_tol=1e-9)
    rng = np.random.default_rng(0)
    for _ in range(5):  # any change of state coordinates gives the same coefficients
        T = rng.standard_normal(A.shape) + 3 * np.eye(A.shape[0])
        Ti = np.linalg.inv(T)
        c2, _, _ = coefficients_from_model(T @ A @ Ti, C @ Ti, T @ Q @ T.T, R, dt, terms)
        for t in terms:
            assert math.isclose(c2[t], c[t], rel_tol=1e-6), t


def test_mapping_eq63_matches_within_euler_error():
    # eq. 63 is an Euler discretisation: its GM pole is 1 - dt/tc instead of exp(-dt/tc), an
    # O(dt/tc) relative error on tc and B
    dt, tc = 0.01, 50.0
    c, bad, extra = coefficients_from_model(*initial_model(TRUTH, tc, dt, "NBK", "eq63"), dt, "NBK")
    assert not any(bad.values())
    for t in "NBK":
        assert math.isclose(c[t], TRUTH[t], rel_tol=2 * dt / tc), t
    assert math.isclose(extra["tc"], tc, rel_tol=2 * dt / tc)


def test_mapping_flags_nonphysical():
    A = np.array([[0.5, -0.5], [0.5, 0.5]])  # complex eigenvalues: no RRW / GM reading
    c, bad, _ = coefficients_from_model(A, np.ones(2), np.eye(2), [1.0], 0.01, "NBK")
    assert bad["B"] and bad["K"] and not bad["N"]
    c, bad, _ = coefficients_from_model(np.array([[1.2]]), np.ones(1), np.eye(1), [1.0], 0.01, "NB")
    assert bad["B"] and math.isnan(c["B"])


# --- streaming -----------------------------------------------------------------------------
def test_partial_fit_chunks_equal_one_call():
    y = _simulate_ss(*_scaled_model("NBK"), 3000, np.random.default_rng(5))
    kw = dict(x0={"N": 2e-3, "B": 1e-4, "K": 3e-5}, tc0=5.0, trace_every=100)
    one = ArmaEM(**kw).partial_fit(y[:500], 0.01).partial_fit(y[500:], 0.01)
    many = ArmaEM(**kw).partial_fit(y[:500], 0.01)
    for lo, hi in [(500, 501), (501, 1234), (1234, 1234), (1234, 3000)]:
        many.partial_fit(y[lo:hi], 0.01)
    np.testing.assert_array_equal(one.coefficients_.to_numpy(), many.coefficients_.to_numpy())
    np.testing.assert_array_equal(one.diagnostics_["trajectory"].to_numpy(),
                                  many.diagnostics_["trajectory"].to_numpy())
    assert one.diagnostics_["n_samples"] == 3000
    # fit is a fresh start: same as one partial_fit of the whole record
    a = ArmaEM(**kw).fit(y, 0.01)
    b = ArmaEM(**kw).partial_fit(y[:100], 0.01).reset().partial_fit(y, 0.01)
    np.testing.assert_array_equal(a.coefficients_.to_numpy(), b.coefficients_.to_numpy())


# --- numerical robustness (a divergence at sample 2791 of the test above) -------------------------
_GYRO_NBK = dict(N=1e-3, sigma=3e-4 / 0.9294, tc=5.0, K=1e-5)


def _gyro_nbk(dt=0.01):
    p = _GYRO_NBK
    return Gyro(dt=dt, terms=[AngleRandomWalk(N=p["N"]), GaussMarkov(sigma=p["sigma"], tc=p["tc"]),
                              RateRandomWalk(K=p["K"])])


def _fit_quietly(est, y, dt, chunks=None):
    """Fit (or feed in ``chunks``) with DivergenceWarning as an error; returns the estimator."""
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error", DivergenceWarning)
        if chunks is None:
            return est.fit(y, dt)
        for lo, hi in zip(chunks[:-1], chunks[1:]):
            est.partial_fit(y[lo:hi], dt)
        return est


@pytest.mark.parametrize("mode", ["recursive", "online", "batch"])
def test_no_divergence_over_seeds_short_records(mode):
    """60 short records (3000 samples) of a valid N + GM + K model, starts up to 100x off.

    With the isotropic prior I/CC', 7 of 50 such records (the start of the test above) diverge:
    eq. 29's x_0 x_0'/k term inflates Q by ~1e8, and the M-step then produces an explosive, nearly
    unobservable mode whose covariance grows like lambda^2k until rounding makes A P A' + Q
    indefinite (the module docstring of ``avbench.estimators.online.arma_em``).
    """
    g = _gyro_nbk()
    truth = {"N": 1e-3, "B": 3e-4, "K": 1e-5}
    settings = {"recursive": {}, "online": {}, "batch": dict(recursive=False, passes=3)}[mode]
    for seed in range(60):
        rng = np.random.default_rng(3000 + seed)
        y = g.simulate(3000, rng)
        if seed % 3 == 0:  # the start of test_partial_fit_chunks_equal_one_call, 5-30x off here
            y = y * 10.0
            x0, tc0 = {"N": 2e-3, "B": 1e-4, "K": 3e-5}, 5.0
        elif seed % 3 == 1:  # log-uniform within two decades of the truth
            x0 = {c: v * 10 ** rng.uniform(-2, 2) for c, v in truth.items()}
            tc0 = 5.0 * 10 ** rng.uniform(-1, 1)
        else:  # the default start (Allan-variance fit of the record)
            x0, tc0 = None, None
        est = ArmaEM(x0=x0, tc0=tc0, trace_every=0, **settings)
        chunks = [0, 500, 1700, 3000] if mode == "online" else None
        est = _fit_quietly(est, y, g.dt, chunks)
        d = est.diagnostics_
        assert est.result().failure is None and d["n_samples"] == 3000, (seed, d.get("failure"))
        # no explosive mode (eigenvalues of a nearly defective 2x2 A are known to ~eps/gap ~ 1e-11)
        assert np.max(np.abs(np.linalg.eigvals(d["A"]))) <= 1.0 + 1e-8, seed
        assert np.all(np.linalg.eigvalsh(est._filter.P) > 0), seed


@pytest.mark.parametrize("n", [200_000, pytest.param(2_000_000, marks=pytest.mark.slow)])
@pytest.mark.parametrize("start", ["paper", "default", "test"])
def test_no_divergence_long_records(n, start):
    """Long records (small default, 2e6 samples slow) with the paper's start, the default start and
    the start of the chunk test: no divergence, covariance positive definite at the end."""
    from avbench.noise_models import presets

    if start == "test":
        g, kw = _gyro_nbk(), dict(x0={"N": 2e-3, "B": 1e-4, "K": 3e-5}, tc0=5.0)
    else:
        g = presets.get("ADIS16405_Y")
        kw = {} if start == "default" else dict(x0={"N": [1.5, "deg/sqrt(h)"], "B": [20, "deg/h"],
                                                     "K": [50, "deg/h^1.5"]})
    y = g.simulate(n, np.random.default_rng(n % 97 + len(start)))
    est = _fit_quietly(ArmaEM(trace_every=0, **kw), y, g.dt)
    assert est.result().failure is None
    assert np.all(np.linalg.eigvalsh(est._filter.P) > 0)
    assert np.isfinite(est.coefficients_["N"]) and abs(est.coefficients_["N"] / g.coefficients["N"] - 1) < 0.05


def test_prior_covariance_is_the_accumulated_model_covariance():
    from avbench.estimators.online.arma_em import prior_covariance

    A, _, Q, _ = initial_model(TRUTH, 5.0, 0.01, "NBK", "eq63")
    for h in (1, 2, 3, 16, 777):
        S, Ak = np.zeros((2, 2)), np.eye(2)
        for _ in range(h):
            S, Ak = S + Ak @ Q @ Ak.T, A @ Ak
        np.testing.assert_allclose(prior_covariance(A, Q, h), S, rtol=1e-12, atol=0)


@pytest.mark.parametrize("A", [[[1.02, 0.3], [0.0, 0.9]], [[0.5, 2.0], [-1.0, 0.9]], [[1.001, 0.0], [0.0, 1.002]],
                               [[-1.3, 0.1], [0.2, 0.4]], [[0.99, 0.01], [0.0, 0.98]], [[1.5]], [[0.7]]])
def test_clip_spectrum_kernel_equals_reference(A):
    from avbench.estimators.online._arma_em_reference import clip_spectrum_reference

    A = np.array(A, float)
    lam = np.linalg.eigvals(A)
    ref, changed = clip_spectrum_reference(A)
    out = A.copy()
    assert K._clip_spectrum(out) == changed == bool(np.any(np.abs(lam) > 1))
    np.testing.assert_allclose(out, ref, rtol=1e-12, atol=1e-15)
    new = np.linalg.eigvals(out)
    assert np.all(np.abs(new) <= 1 + 1e-12)
    if changed and np.all(np.isreal(lam)):  # real eigenvalues: clipped, eigenvectors kept
        np.testing.assert_allclose(np.sort(new.real), np.sort(np.clip(lam.real, -1, 1)), atol=1e-12)


# --- recovery --------------------------------------------------------------------------------
def _z_scores(gyro, n, seed, terms, x0, **settings):
    y = gyro.simulate(n, np.random.default_rng(seed))
    est = ArmaEM(terms=terms, x0=x0, trace_every=0, **settings).fit(y, gyro.dt)
    bound, truth = crlb(gyro, n), gyro.coefficients
    return {t: (est.coefficients_[t] - truth[t]) / bound[t] for t in terms}, est


@pytest.mark.parametrize("settings", [dict(recursive=False, passes=20, exact_q=True), dict(exact_q=True)])
def test_recovery_white_plus_random_walk(settings):
    """N + K, 20000 samples: each estimate within 4 Cramer-Rao standard deviations of the truth.

    Batch EM converges to the maximum-likelihood estimate, asymptotically efficient; the single
    recursive pass is held to the same bound (on a record where the start matters little).
    The probability that an efficient estimate lands beyond 4 sigma is 6e-5 per coefficient.
    """
    gyro = Gyro(dt=0.1, terms=[AngleRandomWalk(N=1e-3), RateRandomWalk(K=1e-5)])
    z, est = _z_scores(gyro, 20_000, 11, "NK", {"N": 2e-3, "K": 3e-5}, **settings)
    assert est.result().failure is None
    assert abs(z["N"]) < 4 and abs(z["K"]) < 4, z


def test_recovery_white_plus_gauss_markov():
    gyro = Gyro(dt=0.1, terms=[AngleRandomWalk(N=1e-3), GaussMarkov(sigma=2e-3, tc=20.0)])
    z, est = _z_scores(gyro, 20_000, 12, "NB", {"N": 2e-3, "B": 1e-3}, tc0=5.0, recursive=False,
                       passes=20, exact_q=True)
    assert abs(z["N"]) < 4 and abs(z["B"]) < 4, z
    assert abs(est.diagnostics_["tc"] / 20.0 - 1) < 0.5


@pytest.mark.slow
@pytest.mark.parametrize("seed", [21, 22])
def test_recovery_nbk_adis_like_long_record(seed):
    """N + GM + K at ADIS16405-X levels (Miao et al. 2015, Table 2), 5 h at 100 Hz, batch EM."""
    from avbench.noise_models.units import to_si

    N, B, Kc = to_si("N", 2.2378, "deg/sqrt(h)"), to_si("B", 28.3271, "deg/h"), to_si("K", 68.5726, "deg/h^1.5")
    gyro = Gyro(dt=0.01, terms=[AngleRandomWalk(N=N), GaussMarkov.from_bias_instability(B, 200.0),
                                RateRandomWalk(K=Kc)])
    x0 = {"N": [1.5, "deg/sqrt(h)"], "B": [20, "deg/h"], "K": [50, "deg/h^1.5"]}
    z, est = _z_scores(gyro, 1_800_000, seed, "NBK", x0, recursive=False, passes=6, exact_q=True)
    assert est.result().failure is None
    assert all(abs(v) < 4 for v in z.values()), z


def test_default_x0_from_allan_variance():
    gyro = Gyro(dt=0.1, terms=[AngleRandomWalk(N=1e-3), RateRandomWalk(K=1e-5)])
    y = gyro.simulate(20_000, np.random.default_rng(2))
    est = ArmaEM(terms="NK", exact_q=True, trace_every=0).fit(y, 0.1)
    assert est.result().failure is None
    assert abs(est.coefficients_["N"] / 1e-3 - 1) < 4 / math.sqrt(2 * 20_000)


# --- interface, bad input, failures ------------------------------------------------------------
def test_registered_and_clonable():
    assert "arma_em" in estimators.names()
    est = estimators.get("arma_em", terms="NK", passes=2)
    assert est.clone().get_params() == est.get_params()


@pytest.mark.parametrize(
    "settings,match",
    [
        (dict(terms="QNBK"), "quantization"),
        (dict(terms="NBKR"), "rate ramp"),
        (dict(terms="BK"), "supports"),
        (dict(terms="NX"), "subset"),
        (dict(x0={"N": 1e-3}), "x0"),
        (dict(terms="NK", x0={"N": 1e-3, "K": -1.0}), "non-negative"),
        (dict(terms="NK", x0={"N": 1e-3, "K": 0.0}), "positive"),
        (dict(tc0=-3.0), "tc0"),
        (dict(passes=0), "passes"),
        (dict(warmup=1.5), "warmup"),
        (dict(init_form="canonical"), "init_form"),
        (dict(engine="cuda"), "engine"),
        (dict(recursive="yes"), "recursive"),
    ],
)
def test_bad_settings(settings, match):
    y = np.random.default_rng(0).standard_normal(100)
    with pytest.raises(ValueError, match=match):
        ArmaEM(**settings).fit(y, 0.01)
    with pytest.raises(ValueError, match=match):  # streaming use checks them too
        ArmaEM(**settings).partial_fit(y, 0.01)


def test_bad_data():
    est = ArmaEM(terms="NK", x0={"N": 1e-3, "K": 1e-5})
    with pytest.raises(ValueError, match="non-finite"):
        est.fit(np.r_[np.zeros(20), np.nan], 0.01)
    with pytest.raises(ValueError, match="dt"):
        est.fit(np.zeros(100), -1)
    est.partial_fit(np.random.default_rng(0).standard_normal(100), 0.01)
    with pytest.raises(ValueError, match="same sample interval"):
        est.partial_fit(np.zeros(10), 0.02)
    with pytest.raises(ValueError, match="chunk"):
        est.partial_fit(np.zeros((2, 2)), 0.01)


def test_failure_reported_with_sample_index():
    # the batch M-step on a constant record (which fit refuses before any filter runs: the filter's own
    # check is reached through _fit) gives R = 0 and must be refused
    with pytest.warns(DivergenceWarning, match="sample"):
        coefs, _, diag, parts = ArmaEM(terms="NK", x0={"N": 1e-3, "K": 1e-5}, recursive=False)._fit(np.full(200, 0.25),
                                                                                                     0.01)
    assert "M-step" in parts.failure and "sample 199" in parts.failure
    assert all(np.isnan(coefs[c]) for c in "NK")
    # a singular predicted covariance inside the kernel: reported, not raised
    f = EKFilter(np.zeros((1, 1)), np.ones(1), np.zeros((1, 1)), np.ones(1))
    f.start(0.0, np.zeros((1, 1)))
    f.run(np.ones(5), recursive=False, warmup=1, update_every=1, trace_every=0)
    assert f.status == K.FAIL_SINGULAR_PRED and f.ic[K.I_FAIL_INDEX] == 1
