"""The time-and-frequency statistics beside the variances: PDEV, TTOTDEV, MTIE, TIE rms, the gap-resistant ADEV,
the three-cornered hat and the noise identification -- against allantools, published values, their NumPy
references and their exact expectations.

Tolerances: allantools 1e-9 relative (the same sums; MTIE is a max of exact differences: bit-equal);
Stable32's and SigmaTheta's printed digits (5 and 17 significant: 1e-4 and 1e-9); ensemble means within 4.5
standard errors over the replicates; an ensemble variance against its prediction within 4 standard errors of
a sample variance (its relative SE ~ sqrt(2/(R-1) + kurtosis excess / R)).
"""

from pathlib import Path

import numpy as np
import pytest

from avbench.estimators.allan import _tf_kernels as TK
from avbench.estimators.allan.deviations import deviation, phase_of
from avbench.estimators.allan.deviations_tf import gradev, mtie, three_cornered_hat, tie_rms
from avbench.estimators.allan.noise_id import b1_ratio_expected, lag1_acf, noise_id
from avbench.noise_models import exact_variances as ev
from avbench.noise_models import terms as T

allantools = pytest.importorskip("allantools")

DATA = Path(__file__).parent / "data"


def nbs_1000():
    n = [1234567890]
    for _ in range(999):
        n.append((16807 * n[-1]) % 2147483647)
    return np.array(n, dtype=float) / 2147483647


def random_rates(seed, n=3000):
    """White FM with a little random walk on top (a record whose types change with tau)."""
    rng = np.random.default_rng(seed)
    return rng.standard_normal(n) + np.cumsum(rng.standard_normal(n)) * 0.05


def all_terms():
    return [T.Quantization(2e-4), T.AngleRandomWalk(1e-3), T.BiasInstability(1e-3, tau_max=100.0), T.GaussMarkov(1e-3, 3.0),
            T.SecondOrderGaussMarkov(1e-4, 0.2), T.RateRandomWalk(3e-4), T.RateRamp(2e-5), T.Sinusoidal(1e-3, 0.37),
            T.FilteredWhiteNoise(1e-3, length=4), T.FilteredWhiteNoise(1e-3, tf=0.3), T.Resonance(1e-3, 0.8, 3.0)]


def _term_id(t):
    if isinstance(t, T.FilteredWhiteNoise):
        return "FilteredWhiteNoise_" + ("fir" if t.tf is None else "lowpass")
    return type(t).__name__


# -- PDEV and TTOTDEV (their allantools agreement: tests/test_deviations.py::test_equals_allantools) ----------------


def test_pdev_equals_sigmatheta_published_values():
    """SigmaTheta (the PVAR authors' software) on SP1065's 1000-point set, printed to 17 digits: the same
    N - 2m terms (allantools' M) down to the single term at AF 500."""
    t = np.loadtxt(DATA / "pdev_nbs1000_sigmatheta.txt", comments="#")
    r = deviation(nbs_1000(), 1.0, "pdev", t[:, 0], edf=False)
    assert r.m.tolist() == t[:, 0].astype(int).tolist() and r.J[-1] == 1
    np.testing.assert_allclose(r.deviation, t[:, 1], rtol=1e-9)


@pytest.mark.parametrize("n", [100, 5001, 20000])
def test_pvar_kernel_equals_numpy_reference_across_its_restarts(n):
    """The carried window sum, restarted from its definition every max(4096, 4m) steps, against np.convolve."""
    x, _, _ = phase_of(random_rates(n, n), 1.0)
    ms = np.array([1, 2, 3, 7, 64, 1000, 2300], dtype=np.int64)
    ms = ms[2 * ms < x.size]
    got = TK.pvar_sums(x, ms)
    for mi, g in zip(ms.tolist(), got):
        assert g == pytest.approx(TK.pvar_sum_numpy(x, mi), rel=1e-11, abs=1e-300)


def test_pvar_exact_value_has_vernottes_white_fm_limit():
    """PVAR = 3 h0 / (5 tau) for white FM at long tau (Vernotte et al. 2016), i.e. 6/5 of the AV N^2 / tau; the AV
    at m = 1."""
    arw = T.AngleRandomWalk(1e-3)
    m = np.array([1, 4096])
    got = ev.pvar([arw], m, 0.1)
    assert got[0] == pytest.approx(arw.avar(1, 0.1), rel=1e-12)
    assert got[1] == pytest.approx(1.2 * arw.avar(4096, 0.1), rel=1e-6)


@pytest.mark.parametrize("kind", ["pvar", "ttotvar"])
@pytest.mark.parametrize("term", all_terms(), ids=_term_id)
def test_pvar_ttotvar_ensemble_mean_equals_exact_value(kind, term):
    n, reps, dt = 400, 40, 0.1
    m = np.array([1, 2, 8, 40]) if kind == "pvar" else np.array([1, 2, 8, 24])
    rng = np.random.default_rng(17)
    vals = np.array([deviation(term.simulate(n, dt, rng), dt, kind, m * dt, edf=False).avar for _ in range(reps)])
    truth = ev.KINDS[kind]([term], m, n, dt)
    if isinstance(term, T.RateRamp):  # deterministic: the value itself
        np.testing.assert_allclose(vals[0], truth, rtol=1e-8)
        return
    z = (vals.mean(axis=0) - truth) / (vals.std(axis=0, ddof=1) / np.sqrt(reps))
    assert np.all(np.abs(z) < 4.5), z


@pytest.mark.parametrize("term,noise", [(T.AngleRandomWalk(1e-3), "white_fm"), (T.RateRandomWalk(3e-4), "rw_fm")],
                         ids=["white_fm", "rw_fm"])
def test_pvar_edf_predicts_its_ensemble_variance(term, noise):
    n, reps, dt = 600, 200, 0.1
    m = np.array([4, 32])
    rng = np.random.default_rng(8)
    rs = [deviation(term.simulate(n, dt, rng), dt, "pvar", m * dt, noise=noise) for _ in range(reps)]
    vals = np.array([r.avar for r in rs])
    edf = rs[0].edf
    ratio = vals.var(axis=0, ddof=1) / (2 * ev.pvar([term], m, dt) ** 2 / edf)
    se = np.sqrt(2 / (reps - 1) + 12 / (edf * reps))
    assert np.all(np.abs(ratio - 1) < 4 * se), (ratio, se)


# -- MTIE and TIE rms ----------------------------------------------------------------------------------------------


@pytest.mark.parametrize("name,fn", [("mtie.txt", mtie), ("tierms.txt", tie_rms)], ids=["mtie", "tierms"])
def test_time_interval_errors_equal_stable32_published(name, fn):
    """Stable32's MTIE ("Fast": windows of AF + 1 phases) and TIE rms of PHASE.DAT (5 digits) and their counts."""
    t = np.loadtxt(DATA / "stable32_phase_dat" / name, comments="#", ndmin=2)
    r = fn(nbs_1000(), 1.0, t[:, 0])
    assert r.m.tolist() == t[:, 0].astype(int).tolist() and r.J.tolist() == t[:, 2].astype(int).tolist()
    np.testing.assert_allclose(r.value, t[:, 3], rtol=1e-4)


@pytest.mark.parametrize("taus", ["octave", "decade", "all"])
def test_time_interval_errors_equal_allantools(taus):
    w = random_rates(1, 1500)
    x, _, _ = phase_of(w, 0.5)
    for fn, at in ((mtie, allantools.mtie), (tie_rms, allantools.tierms)):
        r = fn(w, 0.5, taus)
        t_at, dev, _, _ = at(x, rate=2.0, data_type="phase", taus=r.tau)
        assert np.array_equal(t_at, r.tau)
        if fn is mtie:
            np.testing.assert_array_equal(r.value, dev)
        else:
            np.testing.assert_allclose(r.value, dev, rtol=1e-9)


@pytest.mark.parametrize("n", [2, 3, 17, 4097])
def test_mtie_sparse_table_equals_windows_one_by_one(n):
    x = np.cumsum(np.random.default_rng(n).standard_normal(n))
    ms = np.array([m for m in (1, 2, 3, 5, 8, 100, 2048, n - 1) if 1 <= m < n], dtype=np.int64)
    got = TK.mtie_max(x, ms[::-1].copy())[::-1]
    np.testing.assert_array_equal(got, [TK.mtie_numpy(x, int(m)) for m in ms])
    np.testing.assert_allclose(TK.tie_sums(x, ms), [TK.tie_sum_numpy(x, int(m)) for m in ms], rtol=1e-12)


@pytest.mark.parametrize("term", all_terms(), ids=_term_id)
def test_tie_mean_square_equals_its_exact_value(term):
    """TIE^2's ensemble mean against ``exact_variances.tie_ms`` (the mean rate's removal included, exact in n)."""
    n, reps, dt = 300, 60, 0.1
    m = np.array([1, 5, 40, 150])
    rng = np.random.default_rng(23)
    vals = np.array([tie_rms(term.simulate(n, dt, rng), dt, m * dt).value ** 2 for _ in range(reps)])
    truth = ev.tie_ms([term], m, n, dt)
    if isinstance(term, T.RateRamp):
        np.testing.assert_allclose(vals[0], truth, rtol=1e-8)
        return
    z = (vals.mean(axis=0) - truth) / (vals.std(axis=0, ddof=1) / np.sqrt(reps))
    assert np.all(np.abs(z) < 4.5), z


# -- gap-resistant ADEV --------------------------------------------------------------------------------------------


def test_gradev_equals_allantools_on_phase_with_gaps():
    x, _, _ = phase_of(random_rates(2), 1.0)
    x[np.random.default_rng(3).choice(x.size, 200, replace=False)] = np.nan
    x[1000:1100] = np.nan
    r = gradev(x, 1.0, "octave", data_type="phase")
    t_at, dev, _, ns = allantools.gradev(x, rate=1.0, data_type="phase", taus=r.tau)
    assert np.array_equal(t_at, r.tau) and r.J.tolist() == ns.astype(int).tolist()
    np.testing.assert_allclose(np.sqrt(r.avar), dev, rtol=1e-9)


def test_gradev_on_rates_keeps_the_windows_a_gap_does_not_touch():
    """Rate data: a second difference is kept when all its 2m samples are there -- the definition, term by term;
    without a gap it is the overlapping AV."""
    w = random_rates(4, 800)
    np.testing.assert_allclose(gradev(w, 0.5).avar, deviation(w, 0.5, "oavar").avar, rtol=1e-12)
    g = w.copy()
    g[[5, 300, 301, 640]] = np.nan
    r = gradev(g, 0.5, [0.5, 2.0, 16.0])
    for mi, v, K in zip(r.m.tolist(), r.avar, r.J):
        terms = []
        for i in range(g.size - 2 * mi + 1):
            win = g[i : i + 2 * mi]
            if np.all(np.isfinite(win)):
                terms.append((win[mi:].mean() - win[:mi].mean()) ** 2 / 2)
        assert K == len(terms) and v == pytest.approx(np.mean(terms), rel=1e-10)


def test_gradev_ensemble_mean_is_the_allan_variance():
    """Gaps remove terms, not bias: E[gradev] is the term's exact AV (here ARW and RRW together)."""
    terms = [T.AngleRandomWalk(1e-3), T.RateRandomWalk(3e-4)]
    n, reps, dt = 1000, 60, 0.1
    m = np.array([1, 4, 32])
    rng = np.random.default_rng(5)
    vals = []
    for _ in range(reps):
        w = sum(t.simulate(n, dt, rng) for t in terms)
        w[rng.choice(n, 10, replace=False)] = np.nan
        vals.append(gradev(w, dt, m * dt).avar)
    vals = np.array(vals)
    z = (vals.mean(axis=0) - ev.oavar(terms, m, dt)) / (vals.std(axis=0, ddof=1) / np.sqrt(reps))
    assert np.all(np.abs(z) < 4.5), z


# -- three-cornered hat ---------------------------------------------------------------------------------------------


def test_three_cornered_hat_equals_allantools_where_positive_and_keeps_negative_estimates():
    rng = np.random.default_rng(9)
    a, b, c = (s * rng.standard_normal(5000) for s in (0.3, 1.0, 1.2))
    h = three_cornered_hat(a, b, c, 1.0, "oadev", "octave")
    ph = lambda z: phase_of(z, 1.0)[0]  # noqa: E731
    _, dev_a, _, _ = allantools.three_cornered_hat_phase(ph(a - b), ph(b - c), ph(c - a), 1.0, h.tau, allantools.oadev)
    pos = h.avar[0] > 0
    np.testing.assert_allclose(h.deviation[0, pos], dev_a[pos], rtol=1e-9)
    assert np.all(dev_a[~pos] == 0)  # allantools' zero; ours the estimate, no deviation, an upper bound
    neg = ~pos
    if neg.any():
        assert np.all(np.isnan(h.deviation[0, neg])) and np.all(h.ci_low[0, neg] == 0) and np.all(h.ci_high[0, neg] >= 0)
    np.testing.assert_allclose(h.avar.sum(axis=0), 0.5 * h.pair_avar.sum(axis=0), rtol=1e-12)
    assert set(h.to_frame()["sensor"]) == {"a", "b", "c"}


def test_three_cornered_hat_mean_and_error_bar_match_the_ensemble():
    """Three independent gyros: each estimate's ensemble mean is its own exact AV, and its ensemble variance the
    error-bar formula's (at the true variances; the formula's plug-in form is what a single run reports)."""
    terms = [T.AngleRandomWalk(1e-3), T.AngleRandomWalk(2e-3), T.AngleRandomWalk(2.5e-3)]
    n, reps, dt = 2000, 300, 0.1
    m = np.array([2, 16])
    rng = np.random.default_rng(13)
    est, edf = [], None
    for _ in range(reps):
        h = three_cornered_hat(*(t.simulate(n, dt, rng) for t in terms), dt, "oadev", m * dt, noise="white_fm")
        est.append(h.avar)
        edf = h.edf
    est = np.array(est)  # (reps, 3, T)
    truth = np.array([t.avar(m, dt) for t in terms])
    z = (est.mean(axis=0) - truth) / (est.std(axis=0, ddof=1) / np.sqrt(reps))
    assert np.all(np.abs(z) < 4.5), z
    S = truth
    pred = 2.0 / edf * (S**2 + 0.5 * (S[0] * S[1] + S[0] * S[2] + S[1] * S[2]))
    ratio = est.var(axis=0, ddof=1) / pred
    se = np.sqrt(2 / (reps - 1) + 12 / (edf * reps))
    assert np.all(np.abs(ratio - 1) < 4 * se), (ratio, se)


# -- noise identification --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("data", ["phase", "rate"])
@pytest.mark.parametrize("term", [T.Quantization(1e-3), T.AngleRandomWalk(1e-3), T.BiasInstability(1e-3, tau_max=1e4),
                                  T.RateRandomWalk(1e-3)], ids=lambda t: type(t).__name__)
def test_noise_id_equals_allantools_autocorrelation(term, data):
    w = term.simulate(4000, 1.0, np.random.default_rng(31))
    r = noise_id(w, 1.0, [1.0, 2.0, 4.0, 16.0, 64.0], data=data, kind="hvar")
    x, _, _ = phase_of(w, 1.0)
    for mi, a, est, d in zip(r.m.tolist(), r.alpha, r.estimate, r.d):
        got = allantools.autocorr_noise_id(x if data == "phase" else w, mi, data_type=data.replace("rate", "freq"),
                                           dmin=0, dmax=3)
        assert (got[0], got[2]) == (a, d) and est == pytest.approx(got[1], rel=1e-9, abs=1e-12)


@pytest.mark.parametrize("term,alpha", [(T.Quantization(1e-3), 2), (T.AngleRandomWalk(1e-3), 0),
                                        (T.RateRandomWalk(1e-3), -2)], ids=["white_pm", "white_fm", "rw_fm"])
def test_noise_id_finds_the_type_of_pure_noise(term, alpha):
    """The rounded type right in 19 of 20 records; the unrounded estimate's mean within the rounding bin (it is
    biased where decimation leaves the differenced phase correlated: -2.37 for RW FM at m = 4)."""
    rng = np.random.default_rng(37)
    ids = [noise_id(term.simulate(4000, 1.0, rng), 1.0, [1.0, 4.0]) for _ in range(20)]
    est = np.array([r.estimate for r in ids])
    assert np.all(np.abs(est.mean(axis=0) - alpha) < 0.45), est.mean(axis=0)
    assert np.mean(np.array([r.alpha for r in ids]) == alpha) >= 0.95


def test_b1_and_rn_tell_the_types_apart():
    """Below 30 points (Stable32's B1 and R(n)): at 16 averages the types white FM / RW FM and white PM are told
    apart in most records; B1's expectation has the closed forms of Howe et al. 2000 (Table 3)."""
    assert b1_ratio_expected(16, -1) == 1.0 and b1_ratio_expected(16, 1) == 8.0
    assert b1_ratio_expected(16, 2) == pytest.approx(16 * 17 / 6)
    rng = np.random.default_rng(41)
    for term, alpha in ((T.AngleRandomWalk(1e-3), 0), (T.RateRandomWalk(1e-3), -2), (T.Quantization(1e-3), 2)):
        got = [noise_id(term.simulate(1600, 1.0, rng), 1.0, [100.0]) for _ in range(40)]
        assert all(r.method[0] in ("b1", "rn") for r in got)
        assert np.mean([r.alpha[0] == alpha for r in got]) >= 0.6, (type(term).__name__, [r.alpha[0] for r in got])


@pytest.mark.parametrize("n", [30, 31, 1000, 100_003])
def test_noise_id_and_gradev_kernels_equal_their_numpy_references(n):
    """The compiled detrend (normal equations in a centred, scaled index), lag-1 sums and gradev pass against
    numpy.polyfit, the plain sums and the boolean-mask form."""
    rng = np.random.default_rng(n)
    z = np.cumsum(np.cumsum(rng.standard_normal(n))) + 1e3
    for deg in (1, 2):
        a, b = TK.detrend(z, deg), TK.detrend_numpy(z, deg)
        assert np.max(np.abs(a - b)) <= 1e-10 * np.max(np.abs(b))
        assert TK.lag1_acf(a) == pytest.approx(TK.lag1_acf_numpy(b), rel=1e-9)
    x = np.cumsum(rng.standard_normal(n))
    x[rng.choice(n, n // 20, replace=False)] = np.nan
    ms = np.array([1, 2, 7, n // 3], dtype=np.int64)
    sums, cnt = TK.gradev_sums(x, ms, np.zeros(1, dtype=np.int64), False)
    for mi, sm, c in zip(ms.tolist(), sums, cnt):
        ref = TK.gradev_sum_numpy(x, mi)
        assert c == ref[1] and sm == pytest.approx(ref[0], rel=1e-12)


def test_lag1_acf_is_riley_greenhalls_eq_2():
    z = np.random.default_rng(0).standard_normal(50)
    c = z - z.mean()
    assert lag1_acf(z) == pytest.approx(np.sum(c[:-1] * c[1:]) / np.sum(c * c), rel=1e-14)
    with pytest.raises(ValueError, match="kind"):
        noise_id(z, 1.0, kind="adevv")


def test_three_cornered_hat_command_recovers_each_units_noise(tmp_path):
    """``avbench three-cornered-hat``: three simulated gyros sharing a common motion, white noises of
    1, 2 and 3 mrad/s; at the shortest tau each unit's deviation is its own sigma within its error bar
    (4 standard errors of the variance), the common motion cancelled."""
    import pandas as pd

    from avbench.cli import main

    rng = np.random.default_rng(5)
    n = 40_000
    common = np.cumsum(rng.standard_normal(n)) * 1e-3
    sig = {"a": 1e-3, "b": 2e-3, "c": 3e-3}
    for k, s in sig.items():
        np.save(tmp_path / f"{k}.npy", common + s * rng.standard_normal(n))
    files = [str(tmp_path / f"{k}.npy") for k in sig]
    assert main(["three-cornered-hat", *files, "--fs", "100", "--units", "rad/s", "--out", str(tmp_path)]) == 0
    t = pd.read_csv(tmp_path / "a_hat.csv")
    first = t[t["m"] == 1].set_index("unit")
    for k, s in sig.items():
        row = first.loc[f"{k}.npy"]
        assert abs(row["avar"] - s**2) < 4 * row["std_err"], (k, row["avar"], s**2, row["std_err"])
    assert main(["three-cornered-hat", *files[:2], files[0], "--fs", "50", "--units", "rad/s", "--sensor", "accel",
                 "--out", str(tmp_path)]) == 2
