"""Robust GMWM (M-estimated Allan variance) and the despiked GMWM (spikes left out) on contaminated gyros."""

import numpy as np
import pytest

from avbench import estimators
from conftest import mc_tolerance, real_recording
from avbench.estimators.robust.gmwm import GMWMRobust, hampel_outliers, m_scale, masked_allan_variance, robust_allan_variance, tuning
from avbench.noise_models import AngleRandomWalk, BiasInstability, GaussMarkov, Gyro, RateRandomWalk

DT = 0.1
NS = 200_000
G = Gyro(dt=DT, terms=[AngleRandomWalk(N=(2.4, "deg/sqrt(h)")), GaussMarkov(sigma=(40, "deg/h"), tc=20.0)])
#: an ADIS16405_X-like gyro (Miao et al. 2015 coefficients, flicker bias instability) at 10 Hz, 5.6 h
F = Gyro(dt=DT, terms=[AngleRandomWalk(N=(2.24, "deg/sqrt(h)")),
                       BiasInstability(B=(28.3, "deg/h"), tau_max=2 * NS * DT),
                       RateRandomWalk(K=(68.6, "deg/h^1.5"))])
#: gyro -> (GMWM latent model, coefficients checked)
CASES = {"gauss-markov": (G, "WN+GM", ("N", "B")), "flicker": (F, "WN+FL+RW", ("N", "B", "K"))}

MTIG, needs_mtig = real_recording("mtig-cont-imu1/cont_imu1.npz")


def spikes(x, rng, eps=0.05, size=10.0):
    """Additive outliers: a fraction ``eps`` of the samples get +-``size`` white-noise sigmas."""
    sw = np.std(np.diff(x)) / np.sqrt(2)
    y = x.copy()
    hit = rng.random(x.size) < eps
    y[hit] += size * sw * rng.choice([-1.0, 1.0], hit.sum())
    return y


@pytest.mark.parametrize("psi", ["huber", "biweight"])
def test_m_scale_is_fisher_consistent_and_has_its_efficiency(psi):
    # Var of the M-estimate of s^2 is 2 / (eff n) at the Gaussian: check the mean (consistency)
    # and the replicate variance against it
    from scipy import stats

    c, delta = tuning(psi, 0.6)
    R, n = 30, 20_000
    rng = np.random.default_rng(1)
    est = np.array([m_scale(rng.standard_normal(n), psi, 0.6) ** 2 for _ in range(R)])
    sd_theory = np.sqrt(2 / (0.6 * n))
    assert abs(est.mean() - 1) < 4 * sd_theory / np.sqrt(R)
    lo, hi = stats.chi2.ppf([0.001, 0.999], R - 1) / (R - 1)
    assert lo < est.var(ddof=1) / sd_theory**2 < hi


def test_tuning_rejects_bad_settings():
    with pytest.raises(ValueError, match="psi"):
        tuning("cauchy", 0.6)
    with pytest.raises(ValueError, match="eff"):
        tuning("huber", 1.5)
    with pytest.raises(ValueError, match="psi"):
        GMWMRobust(psi="x").fit(np.random.default_rng(0).standard_normal(50_000), 0.1)


def test_robust_av_resists_sparse_spikes_where_the_classical_av_does_not():
    x = G.simulate(200_000, np.random.default_rng(2))
    y = spikes(x, np.random.default_rng(3), eps=0.002, size=30.0)
    tau, m, rob = robust_allan_variance(y, DT, taus=[0.1, 0.2])
    _, _, clean = robust_allan_variance(x, DT, taus=[0.1, 0.2])
    classical = estimators.allan_variance(y, DT, taus=[0.1, 0.2]).avar
    truth = G.avar(tau)
    assert np.all(classical / truth > 2.0)  # 0.2 % spikes of 30 sigma more than double the AV
    # robust: the bias an M-scale keeps under 0.2-0.4 % of far outliers is ~ eps (Huber 1981, Ch. 5)
    assert np.all(np.abs(rob / clean - 1) < 0.03)


def test_robust_gmwm_equals_gmwm_on_clean_data_within_its_errors():
    x = G.simulate(200_000, np.random.default_rng(4))
    a = estimators.get("gmwm", model="WN+GM").fit(x, DT)
    b = estimators.get("gmwm_robust", model="WN+GM").fit(x, DT)
    for c in ("N", "B"):
        se = b.diagnostics_["std_err"][c]
        assert abs(b.coefficients_[c] - a.coefficients_[c]) < 3 * se, c


def test_hampel_outliers_finds_the_spikes():
    x = G.simulate(100_000, np.random.default_rng(5))
    y = spikes(x, np.random.default_rng(6), eps=0.05, size=10.0)
    out, t = hampel_outliers(y)
    hit = y != x
    assert t == 5.0  # a clear gap between the Gaussian bulk and spikes of 10 sigma: no need to raise it
    assert (out & hit).sum() / hit.sum() > 0.99  # spikes of 10 sigma are found
    assert (out & ~hit).sum() / (~hit).sum() < 1e-3  # clean samples are left alone
    assert hampel_outliers(x)[0].mean() < 1e-4


def test_hampel_outliers_leaves_a_heavy_tailed_bulk_alone():
    # iid white noise, half of it 8 times wider (a scale mixture, like the MTi-G record) plus 0.05 %
    # gross errors of 100: only the gross errors are separated from the bulk by a gap
    rng = np.random.default_rng(7)
    n = 200_000
    x = rng.standard_normal(n) * np.where(rng.random(n) < 0.5, 1.0, 8.0)
    gross = rng.random(n) < 5e-4
    x[gross] += 100.0 * rng.choice([-1.0, 1.0], gross.sum())
    out, t = hampel_outliers(x)
    assert t > 5.0
    assert (out & gross).sum() / gross.sum() > 0.95
    assert (out & ~gross).sum() < 0.2 * gross.sum()
    fixed, _ = hampel_outliers(x, gap_tol=None)  # the fixed 5-sigma rule cuts into the bulk
    assert fixed.mean() > 0.05


def test_masked_av_white_gain_is_exact():
    # white noise with a random mask: E[masked AV] = gain * sigma^2 / m at every scale
    R, n = 30, 50_000
    taus = [1.0, 2.0, 4.0, 64.0, 1024.0]
    ratio = []
    for seed in range(R):
        rng = np.random.default_rng(seed)
        x = rng.standard_normal(n)
        out = rng.random(n) < 0.1
        _, m, av, gain, _ = masked_allan_variance(x, 1.0, out, taus)
        ratio.append(av * m / gain)
    ratio = np.array(ratio)
    assert np.all(gain[:1] == 1.0) and np.all(gain[1:] > 1.0)
    assert np.all(np.abs(ratio.mean(axis=0) - 1) < mc_tolerance(ratio))
    # nothing left out: the classical overlapping AV
    x = np.random.default_rng(0).standard_normal(20_000)
    _, m, av, gain, _ = masked_allan_variance(x, 0.1, np.zeros(x.size, bool), "octave")
    ref = estimators.allan_variance(x, 0.1, "octave")
    assert np.array_equal(m, ref.m) and np.allclose(av, ref.avar, rtol=1e-10) and np.all(gain == 1.0)
    with pytest.raises(ValueError, match="outliers"):
        masked_allan_variance(x, 0.1, np.zeros(5, bool))


def test_masked_differences_compiled_equal_the_numpy_expressions_bit_for_bit():
    """The compiled pass, its Python reference and the NumPy slices it stands for give the same bits, on
    masks with runs of left-out samples long enough to empty whole clusters."""
    from avbench.estimators.robust import _kernels

    rng = np.random.default_rng(7)
    n = 5_000
    x = rng.standard_normal(n) * 3e-4 + 1e-3
    keep = ~((rng.random(n) < 0.05) | (np.convolve(rng.random(n) < 0.004, np.ones(40), "same") > 0))
    S = np.concatenate(([0.0], np.cumsum(np.where(keep, x - x[keep].mean(), 0.0))))
    C = np.concatenate(([0], np.cumsum(keep, dtype=np.int64)))
    for m in (1, 2, 3, 16, 37, 64, 1024, 2499, 2500, 2600):
        c1, c2 = C[m:-m] - C[: -2 * m], C[2 * m :] - C[m:-m]
        ok = (c1 > 0) & (c2 > 0)
        d_np = (S[2 * m :] - S[m:-m])[ok] / c2[ok] - (S[m:-m] - S[: -2 * m])[ok] / c1[ok]
        g_np = 1.0 / c1[ok] + 1.0 / c2[ok]
        for fn in (_kernels.masked_differences, _kernels.masked_differences_py):
            d, g = np.full(n, np.nan), np.full(n, np.nan)
            k = fn(S, C, m, d, g)
            assert k == d_np.size and np.array_equal(d[:k], d_np) and np.array_equal(g[:k], g_np)
    assert 0 < np.count_nonzero(~keep) < n // 4


def test_despiked_leaves_in_samples_whose_removal_moves_no_av_value_by_min_shift():
    """A Gaussian record's tail samples past 5 sigma are found; leaving them out would move the AV by less
    than ``min_shift`` standard errors, so they are left in and the fit is GMWM's, bit for bit; with
    ``min_shift=0`` they are left out and the fit moves; one spike of 40 sigma is left out by the default."""
    from avbench.estimators.robust.gmwm import largest_shift

    x = np.random.default_rng(11).standard_normal(1 << 18)
    a = estimators.get("gmwm", model="WN+GM").fit(x, 0.01)
    b = estimators.get("gmwm_despiked", model="WN+GM").fit(x, 0.01)
    c = estimators.get("gmwm_despiked", model="WN+GM", min_shift=0.0).fit(x, 0.01)
    found = int(hampel_outliers(x)[0].sum())
    assert found > 0
    assert b.extras_["outliers_left_in"] == found and b.extras_["outlier_fraction"] == 0.0
    assert 0 < b.extras_["outlier_shift"] <= 0.29
    assert a.coefficients_.equals(b.coefficients_)
    assert c.extras_["outlier_fraction"] == found / x.size and c.extras_["outliers_left_in"] == 0
    assert not a.coefficients_.equals(c.coefficients_)
    # the shift reported is the largest move of a matched AV value, in its standard errors (the fit sees the
    # record scaled: equal to rounding)
    out = hampel_outliers(x)[0]
    wv = estimators.get("gmwm")._wavelet_variance(x, 0.01)
    _, m, av, _, _ = masked_allan_variance(x, 0.01, out, "octave")
    ok = x.size // wv.m >= 8
    se = wv.avar * np.sqrt(2 / wv.edf)
    assert b.extras_["outlier_shift"] == pytest.approx(np.max(np.abs(av - wv.avar)[ok] / se[ok]), rel=1e-12)
    assert largest_shift(wv, m, av, x.size, 8) == pytest.approx(b.extras_["outlier_shift"], rel=1e-9)
    spiky = x.copy()
    spiky[1000] += 40.0
    d = estimators.get("gmwm_despiked", model="WN+GM").fit(spiky, 0.01)
    assert d.extras_["outlier_shift"] > 1 and d.extras_["outlier_fraction"] == (found + 1) / x.size


def test_min_shift_default_keeps_a_95_interval_at_94_percent():
    """The default ``min_shift`` b is the largest shift, in standard errors, that keeps a 95 % interval's
    coverage Phi(1.96 - b) - Phi(-1.96 - b) at or above 0.94 (two digits)."""
    from scipy.special import ndtr

    from avbench.estimators.robust.gmwm import GMWMDespiked

    b = GMWMDespiked().min_shift
    cover = lambda b: ndtr(1.959964 - b) - ndtr(-1.959964 - b)  # noqa: E731
    assert cover(b) >= 0.94 > cover(b + 0.01)


def test_despiked_equals_gmwm_on_clean_data():
    x = G.simulate(100_000, np.random.default_rng(8))
    a = estimators.get("gmwm", model="WN+GM").fit(x, DT)
    # nothing left out: exactly GMWM
    b = estimators.get("gmwm_despiked", model="WN+GM", threshold=8.0).fit(x, DT)
    assert b.diagnostics_["outlier_fraction"] == 0.0
    assert a.coefficients_.equals(b.coefficients_)
    # the default 5 sigma leaves out a few 1e-5 of a Gaussian record: a small fraction of an SE
    b = estimators.get("gmwm_despiked", model="WN+GM").fit(x, DT)
    assert b.diagnostics_["outlier_fraction"] < 1e-4
    for c in ("N", "B"):
        assert abs(b.coefficients_[c] - a.coefficients_[c]) < 0.1 * a.diagnostics_["std_err"][c], c


def test_despiked_rejects_bad_settings():
    x = G.simulate(20_000, np.random.default_rng(0))
    for kw, name in (({"half_window": 0}, "half_window"), ({"threshold": -1.0}, "threshold"),
                     ({"gap_tol": 2.0}, "gap_tol")):
        with pytest.raises(ValueError, match=name):
            estimators.get("gmwm_despiked", model="WN+GM", **kw).fit(x, DT)


def _relative_changes(case, seeds, methods):
    """Per replicate and method: contaminated / clean fit - 1 for the case's coefficients, the
    contamination being 5 % of the samples with +-10 white-noise sigmas."""
    gyro, model, coefs = CASES[case]
    rel = {name: [] for name in methods}
    for seed in seeds:
        rng = np.random.default_rng(seed)
        x = gyro.simulate(NS, rng)
        y = spikes(x, rng, eps=0.05, size=10.0)
        for name in methods:
            clean = estimators.get(name, model=model).fit(x, DT).coefficients_
            cont = estimators.get(name, model=model).fit(y, DT).coefficients_
            rel[name].append([cont[c] / clean[c] - 1 for c in coefs])
    return {name: np.array(v) for name, v in rel.items()}


def _assert_target(rel, alpha):
    """The brief's target: despiked N, B (and K) within 5 % of the clean fit beyond the replicate
    error (the mean's confidence bound inside the band); classical N off by more than 100 %."""
    d, g = rel["gmwm_despiked"], rel["gmwm"]
    assert np.all(np.abs(d.mean(axis=0)) + mc_tolerance(d, alpha) < 0.05), (d.mean(axis=0), mc_tolerance(d, alpha))
    assert g[:, 0].mean() - mc_tolerance(g, alpha)[0] > 1.0, g.mean(axis=0)


@pytest.mark.parametrize("case", list(CASES))
def test_despiked_gmwm_keeps_its_coefficients_under_5pct_outliers(case):
    # six replicates: the 99 % bound of the mean change inside +-5 % (replacing the spikes by the
    # running median instead moved B by +16 % on the Gauss-Markov gyro, 20 times its SE)
    _assert_target(_relative_changes(case, range(6), ("gmwm", "gmwm_despiked")), alpha=0.01)


@pytest.mark.slow
@pytest.mark.parametrize("case", list(CASES))
def test_despiked_gmwm_keeps_its_coefficients_under_5pct_outliers_monte_carlo(case):
    rel = _relative_changes(case, range(100, 116), ("gmwm", "gmwm_despiked"))
    _assert_target(rel, alpha=1e-4)


def _mtig():
    return np.asarray(np.load(MTIG)["data"], dtype=float).ravel()


@pytest.mark.slow
@needs_mtig
def test_robust_fits_are_plausible_on_the_contaminated_mtig():
    # The MTi-G's white noise is an iid heavy-tailed scale mixture with 0.03 % gross errors
    # (avbench.estimators.robust.gmwm, "The MTi-G record"): the despiked fit leaves out only the gross errors
    # (the gap rule), so N drops by the few % they carry and B stays; the fit passes its check.
    from avbench.noise_models.units import from_si

    x = _mtig()
    ref = estimators.get("gmwm").fit(x, 0.01)
    fits = {name: estimators.get(name, **kw).fit(x, 0.01)
            for name, kw in (("gmwm_despiked", {}), ("gmwm_robust", {"min_m": "auto"}))}
    for name, est in fits.items():
        n = from_si("N", est.coefficients_["N"], "deg/sqrt(h)")
        b = from_si("B", est.coefficients_["B"], "deg/h")
        assert 1.3 < n < 2.2 and 5.0 < b < 100.0, (name, n, b)
        assert est.coefficients_["N"] < ref.coefficients_["N"], name
        assert not est.diagnostics_["poor_fit"], name
    assert fits["gmwm_despiked"].diagnostics_["outlier_fraction"] < 1e-3
