"""The deviation family: allantools and SP1065's published values, Stable32's published bounds and
bias-corrected values, kernels vs NumPy, exact values.

Tolerances: allantools agreement to 1e-9 relative (both compute the same sums);
SP1065's 1000-point values are printed to 7 significant digits (half a unit: <= 5e-7 relative, 1e-6
used); Stable32's to 5 (half a unit of the 5th digit: <= 5e-5 relative; 1e-4 used for the values and 3e-4
for the bounds, which it also computes with single-precision edf and its own chi^2 quantiles -- the
largest difference found is 1.9e-4, at edf ~ 4); ensemble means within 4 standard errors over the
replicates; ensemble variances within 4 standard errors of a sample variance of a chi^2-like statistic.
"""

import re
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from avbench.estimators.allan import _deviation_kernels as K
from avbench.estimators.allan.deviations import (KINDS, _canonical_gcov, _filters, deviation, edf_quadratic, edf_quadratics,
                                                  phase_of)
from avbench.estimators.allan.variance import edf_overlapping
from avbench.noise_models import exact_variances as ev
from avbench.noise_models import terms as T

allantools = pytest.importorskip("allantools")

STATS = ("hvar", "ohvar", "mvar", "tvar", "totvar", "mtotvar", "ttotvar", "htotvar", "pvar", "theo1")
AT = {"hvar": "hdev", "ohvar": "ohdev", "mvar": "mdev", "tvar": "tdev", "totvar": "totdev", "mtotvar": "mtotdev", "htotvar": "htotdev",
      "theo1": "theo1", "ttotvar": "ttotdev", "pvar": "pdev"}
#: the total variances whose allantools twins are pure-Python O(N m) loops (and whose windows cost 15m each)
WINDOWED = ("mtotvar", "ttotvar", "htotvar")
S32 = Path(__file__).parent / "data" / "stable32_phase_dat"


def nbs_1000():
    """SP1065's 1000-point test set: n_{i+1} = 16807 n_i mod 2147483647, n_0 = 1234567890, x = n / (2^31 - 1)."""
    n = [1234567890]
    for _ in range(999):
        n.append((16807 * n[-1]) % 2147483647)
    assert n[1:4] == [395529916, 1209410747, 633705974]  # the first values SP1065 prints
    return np.array(n, dtype=float) / 2147483647


DATA = {"random": np.random.default_rng(7).standard_normal(1200), "nbs1000": nbs_1000()}


@pytest.mark.parametrize("data", sorted(DATA))
@pytest.mark.parametrize("kind", STATS)
@pytest.mark.parametrize("taus", ["octave", "decade"])
def test_equals_allantools(data, kind, taus):
    y = DATA[data]
    if kind in WINDOWED:  # allantools' are pure-Python O(N m) loops per m: a shorter record
        y = y[:300]
    r = deviation(y, 1.0, kind, taus)
    tau_at, dev_at, _, _ = getattr(allantools, AT[kind])(y, rate=1.0, data_type="freq", taus=r.m.astype(float))
    # allantools drops a value of a single term (remove_small_ns: hvar's largest m); SP1065 eq. 18 defines it
    keep = r.J > 1 if kind == "hvar" else np.ones(r.m.size, bool)
    assert np.array_equal(tau_at, r.m[keep].astype(float))  # the same m (allantools labels Theo1 by m, not 0.75 m)
    assert np.max(np.abs(r.deviation[keep] / dev_at - 1)) <= 1e-9


# NIST SP 1065 (Riley 2008) section 12.4, p. 108: the 1000-point set at averaging factors 1, 10, 100, printed to
# 7 significant digits (TOTDEV: the doubly reflected form). allantools' tests/nbs14/test_nbs14_1000point.py carries
# the same values. HDEV is the non-overlapping Hadamard deviation (allantools hdev).
PUBLISHED = {
    "hvar": [2.943883e-01, 1.052754e-01, 3.910860e-02],
    "ohvar": [2.943883e-01, 9.581083e-02, 3.237638e-02],
    "mvar": [2.922319e-01, 6.172376e-02, 2.170921e-02],
    "tvar": [1.687202e-01, 3.563623e-01, 1.253382e00],
    "totvar": [2.922319e-01, 9.134743e-02, 3.406530e-02],
}
#: SP1065's MTOTDEV, TTOTDEV and HTOTDEV for the same set are printed divided by the square root of their
#: bias factor for white FM (the set is uniform white FM): MTOT 0.73, HTOT 0.995 (SP1065 section 5.2.11 and
#: 5.2.12 tables; Riley, "Confidence intervals and bias corrections for the Stable32 variance functions",
#: also in allantools' mtotdev/htotdev docstrings). HTOTDEV at factor 1 is OHDEV (no factor). avbench reports
#: the statistics as defined, without the factor (as allantools and Stable32's "no bias correction" runs).
PUBLISHED_BIAS_CORRECTED = {
    "mtotvar": ([2.418528e-01, 6.499161e-02, 2.287774e-02], [0.73, 0.73, 0.73]),
    "htotvar": ([2.943883e-01, 9.614787e-02, 3.058103e-02], [1.0, 0.995, 0.995]),
}
PUBLISHED_TTOTDEV = [1.396338e-01, 3.752293e-01, 1.320847e00]


@pytest.mark.parametrize("kind", sorted(PUBLISHED))
def test_sp1065_published_1000_point_values(kind):
    r = deviation(nbs_1000(), 1.0, kind, [1.0, 10.0, 100.0])
    assert r.m.tolist() == [1, 10, 100]
    np.testing.assert_allclose(r.deviation, PUBLISHED[kind], rtol=1e-6)


@pytest.mark.parametrize("kind", sorted(PUBLISHED_BIAS_CORRECTED))
def test_sp1065_published_bias_corrected_1000_point_values(kind):
    values, bias = PUBLISHED_BIAS_CORRECTED[kind]
    r = deviation(nbs_1000(), 1.0, kind, [1.0, 10.0, 100.0], edf=False)
    assert r.m.tolist() == [1, 10, 100]
    np.testing.assert_allclose(r.deviation / np.sqrt(bias), values, rtol=1e-6)
    if kind == "mtotvar":  # TTOTDEV = tau / sqrt(3) * MTOTDEV (SP1065 eq. 28)
        np.testing.assert_allclose(r.m / np.sqrt(3) * r.deviation / np.sqrt(0.73), PUBLISHED_TTOTDEV, rtol=1e-6)


def test_sp1065_published_1000_point_allan_deviations():
    """ADEV and OADEV of the same table, from the AV engine (the deviation family's 'oavar')."""
    from avbench.estimators.allan.variance import allan_variance

    for overlapping, values in ((False, [2.922319e-01, 9.965736e-02, 3.897804e-02]),
                                (True, [2.922319e-01, 9.159953e-02, 3.241343e-02])):
        r = allan_variance(nbs_1000(), 1.0, [1.0, 10.0, 100.0], overlapping)
        assert r.m.tolist() == [1, 10, 100]
        np.testing.assert_allclose(r.deviation, values, rtol=1e-6)


def test_theo1_1000_point_values_of_stable32():
    """SP1065 prints no Theo1 for the 1000-point set; allantools' NBS14 test carries Stable32's (v1.60, no bias
    correction, 5 digits) at m = 10, 100, 1000 (tau = 0.75 m)."""
    r = deviation(nbs_1000(), 1.0, "theo1", 0.75 * np.array([10.0, 100.0, 1000.0]), edf=False)
    assert r.m.tolist() == [10, 100, 1000]
    np.testing.assert_allclose(r.deviation, [1.0757e-01, 3.1789e-02, 5.0524e-03], rtol=5e-5)


def stable32_table(name):
    """Rows of one of Stable32's PHASE.DAT tables (tests/data/stable32_phase_dat/README.md)."""
    return np.loadtxt(S32 / name, comments="#", ndmin=2)


def test_phase_dat_is_the_nbs_set_integrated():
    """PHASE.DAT (Stable32's sample file, the tables' input) is SP1065's 1000-point set as phase, mean removed:
    the tables' headers print its maximum, minimum and average (7 digits)."""
    x, _, _ = phase_of(nbs_1000(), 1.0)
    assert x.size == 1001
    np.testing.assert_allclose([x.max(), x.min(), x.mean()], [4.356529, -4.707879, -5.403683e-01], rtol=1e-6)


#: (table, deviation name, bias-corrected): every table of PHASE.DAT whose rows print bounds
STABLE32_BOUNDS = [("adev_octave.txt", "adev", False), ("oadev_octave.txt", "oadev", False), ("mdev_octave.txt", "mdev", False),
                   ("tdev_octave.txt", "tdev", False), ("hdev_octave.txt", "hdev", False), ("ohdev_octave.txt", "ohdev", False),
                   ("totdev_octave.txt", "totdev", False), ("mtotdev_octave.txt", "mtotdev", False),
                   ("mtotdev_decade.txt", "mtotdev", False), ("ttotdev_octave.txt", "ttotdev", False),
                   ("ttotdev_decade.txt", "ttotdev", False), ("htotdev_octave_bias_corrected.txt", "htotdev", True),
                   ("theo1_octave_bias_corrected.txt", "theo1", True)]


@pytest.mark.parametrize("name,kind,bias", STABLE32_BOUNDS, ids=[t[0] for t in STABLE32_BOUNDS])
def test_intervals_equal_stable32(name, kind, bias):
    """Every value and bound Stable32 prints for PHASE.DAT, at its noise type (the Alpha column; Theo1's from its
    own run ratio AVAR/Theo1) and confidence factor 0.683, with ``intervals="stable32"``."""
    t = stable32_table(name)
    m, alpha = t[:, 0].astype(int), t[:, 3].astype(int)
    theo1 = kind == "theo1"
    r = deviation(nbs_1000(), 1.0, kind, m * (0.75 if theo1 else 1.0), intervals="stable32", bias_corrected=bias,
                  noise="auto" if theo1 else alpha)
    assert r.m.tolist() == m.tolist() and r.alpha.tolist() == alpha.tolist()
    np.testing.assert_allclose(r.deviation, t[:, 5], rtol=1e-4)
    lo, hi = np.sqrt(r.ci_low), np.sqrt(r.ci_high)
    np.testing.assert_allclose(lo, t[:, 4], rtol=3e-4)
    np.testing.assert_allclose(hi, t[:, 6], rtol=3e-4)


#: Stable32's HTOTDEV and TOTDEV on the BIPM Sr87 phase record (1253 points), copied from allantoolkit's
#: tests/assets/Sr87/phase/{octave,decade}/{htotdev,totdev}.txt (github.com/amv213/allantoolkit): AF, Alpha, lower
#: bound, deviation, upper bound. Rows with alpha = 1 and HTOTDEV's below AF 16 use the total-variance fallback.
SR87_N = 1253
SR87 = {
    "htotvar": [(1, -1, 8.0946e-17, 8.2651e-17, 8.4469e-17), (2, -2, 7.5923e-17, 7.8025e-17, 8.0313e-17),
                (4, -1, 8.8264e-17, 9.1349e-17, 9.4785e-17), (8, 0, 8.5090e-17, 8.8938e-17, 9.3364e-17),
                (10, 0, 8.1805e-17, 8.5915e-17, 9.0718e-17), (16, 0, 7.8591e-17, 8.3165e-17, 8.8649e-17),
                (32, 0, 6.4085e-17, 6.9376e-17, 7.6241e-17), (100, 1, 4.4525e-17, 4.7680e-17, 5.1617e-17),
                (200, -1, 2.2752e-17, 2.8300e-17, 4.1983e-17), (400, -1, 1.1419e-17, 1.5213e-17, 3.1436e-17)],
    "totvar": [(1, -1, 8.8689e-17, 9.0304e-17, 9.2011e-17), (2, -2, 8.6445e-17, 8.8930e-17, 9.1644e-17),
               (10, 0, 9.2942e-17, 9.7582e-17, 1.0300e-16), (100, 1, 4.2698e-17, 4.5724e-17, 4.9499e-17),
               (200, -1, 2.0582e-17, 2.5261e-17, 3.5911e-17), (512, 0, 1.4893e-17, 1.9264e-17, 3.3449e-17)],
}


@pytest.mark.parametrize("kind", sorted(SR87))
def test_total_variance_edf_equals_stable32_on_a_second_record(kind):
    """Stable32's bounds on another record, from its printed deviation and noise type: the edf of
    ``stable32_edf`` (the total-variance fits, and the Table 5 AV edf + 2 where they do not apply)."""
    from avbench.estimators.allan.stable32 import stable32_edf, stable32_interval

    m, alpha, lo, dev, hi = (np.array(c) for c in zip(*SR87[kind]))
    bounds = np.sqrt(stable32_interval(dev**2, stable32_edf(kind, m, SR87_N, alpha), 0.683))
    np.testing.assert_allclose(bounds[0], lo, rtol=3e-4)
    np.testing.assert_allclose(bounds[1], hi, rtol=3e-4)


def test_avbench_exact_intervals_are_not_stable32s():
    """The default (exact Gaussian edf, the type from the AV slope) differs from Stable32's by design; its edf is
    the one the ensemble tests below hold to the data."""
    t = stable32_table("totdev_octave.txt")
    r = deviation(nbs_1000(), 1.0, "totdev", t[:, 0], noise="white_fm")
    assert type(r).__name__ == "AllanResult" and np.max(np.abs(np.sqrt(r.ci_low) / t[:, 4] - 1)) > 3e-3


@pytest.mark.parametrize("name,kind", [("mtotdev_all_bias_corrected.txt", "mtotdev"), ("ttotdev_all_bias_corrected.txt", "ttotdev"),
                                       ("theo1_decade_alpha0.txt", "theo1")])
def test_bias_corrected_values_equal_stable32(name, kind):
    """Stable32's bias-corrected MTOTDEV and TTOTDEV at every AF (B = 0.73 at alpha 0, 0.83 at alpha 1 in these
    rows) and its Theo1 at a given alpha = 0 (nominal ratio 1: the statistic as defined); HTOTDEV's and the
    bias-removed Theo1's are in ``test_intervals_equal_stable32``."""
    t = stable32_table(name)
    m, alpha = t[:, 0].astype(int), t[:, 3].astype(int)
    theo1 = kind == "theo1"
    r = deviation(nbs_1000(), 1.0, kind, m * (0.75 if theo1 else 1.0), bias_corrected=True, noise=alpha, edf=False)
    assert r.m.tolist() == m.tolist()
    np.testing.assert_allclose(r.deviation, t[:, 5], rtol=1e-4)
    if not theo1:
        assert set(alpha.tolist()) == {0, 1}
        raw = deviation(nbs_1000(), 1.0, kind, m * 1.0, edf=False)
        np.testing.assert_allclose(r.avar / raw.avar, 1.0 / np.where(alpha == 0, 0.73, 0.83), rtol=1e-12)


def test_stable32_result_is_an_allan_result_with_its_noise_types():
    from avbench.estimators.allan.stable32 import Stable32Result
    from avbench.estimators.allan.variance import AllanResult

    r = deviation(nbs_1000(), 1.0, "ohdev", "octave", intervals="stable32")
    assert isinstance(r, Stable32Result) and isinstance(r, AllanResult)
    frame = r.to_frame()
    np.testing.assert_array_equal(frame["ci_low"], r.ci_low)
    assert np.all(r.ci_low < r.avar) and np.all(r.avar < r.ci_high) and np.all(r.bias == 1.0)
    with pytest.raises(ValueError, match="intervals"):
        deviation(nbs_1000(), 1.0, "ohdev", intervals="stable31")
    with pytest.raises(ValueError, match="PDEV"):
        deviation(nbs_1000(), 1.0, "pdev", intervals="stable32")
    with pytest.raises(ValueError, match="noise"):
        deviation(nbs_1000(), 1.0, "ohdev", noise="flicker_pm")  # the exact edf knows four types


@pytest.mark.parametrize("name,kind", [("oadev_octave.txt", "oavar"), ("hdev_octave.txt", "hvar"), ("mtotdev_all_bias_corrected.txt", "mtotvar"),
                                       ("htotdev_octave_bias_corrected.txt", "htotvar"), ("totdev_octave.txt", "totvar")])
def test_noise_identification_equals_stable32_where_it_uses_the_lag1_acf(name, kind):
    """Stable32 identifies the type by the lag-1 autocorrelation where the decimated phase has >= 30 points (AF <=
    33 here): its Alpha column there is ours. (Below 30 points it turns to B1 and R(n):
    ``test_noise_identification_equals_stable32_on_every_row_of_its_runs``.)"""
    from avbench.estimators.allan.noise_id import noise_id

    t = stable32_table(name)
    m = t[:, 0].astype(int)
    acf = -(-1001 // m) >= 30
    r = noise_id(nbs_1000(), 1.0, m[acf] * 1.0, kind=kind)
    assert np.all(r.method == "acf") and r.alpha.tolist() == t[acf, 3].astype(int).tolist()


#: every PHASE.DAT table with Stable32's noise type per AF, and the statistic whose identification it used
NOISE_TABLES = {"adev_octave.txt": "avar", "oadev_octave.txt": "oavar", "mdev_octave.txt": "mvar", "tdev_octave.txt": "tvar",
                "hdev_octave.txt": "hvar", "ohdev_octave.txt": "ohvar", "totdev_octave.txt": "totvar",
                "mtotdev_octave.txt": "mtotvar", "mtotdev_decade.txt": "mtotvar", "ttotdev_octave.txt": "ttotvar",
                "ttotdev_decade.txt": "ttotvar", "htotdev_octave_bias_corrected.txt": "htotvar",
                "mtotdev_all_bias_corrected.txt": "mtotvar", "ttotdev_all_bias_corrected.txt": "ttotvar"}
#: the rows where ours differ (noise_id module docstring): B1 within 2 % of a boundary, and TOTDEV at AF 128 (256 kept)
NOISE_DEPARTURES = {("totdev_octave.txt", 128), ("totdev_octave.txt", 256)} | {
    (t, m) for t in ("mtotdev_all_bias_corrected.txt", "ttotdev_all_bias_corrected.txt") for m in (75, 93, 113)}


def test_noise_identification_equals_stable32_on_every_row_of_its_runs():
    """Each run's types at its own AF grid (B1 decides up to half the largest AF, the previous type is kept
    beyond): equal to Stable32's Alpha column on every row of every PHASE.DAT run but the eight listed."""
    from avbench.estimators.allan.noise_id import noise_id

    differ, b1_rows = set(), 0
    for name, kind in NOISE_TABLES.items():
        t = stable32_table(name)
        m = t[:, 0].astype(int)
        r = noise_id(nbs_1000(), 1.0, m * 1.0, kind=kind)
        assert r.m.tolist() == m.tolist()
        b1_rows += int(np.sum(r.method != "acf"))
        differ |= {(name, int(mi)) for mi, a, b in zip(m, r.alpha, t[:, 3].astype(int)) if a != b}
    assert b1_rows == 278 and differ == NOISE_DEPARTURES


def _av_sum(x, m):
    k = max(x.size - 2 * m, 0)
    return float(np.sum((x[2 * m : 2 * m + k] - 2 * x[m : m + k] + x[:k]) ** 2))


@pytest.mark.parametrize("m", [1, 2, 3, 7, 50, 333])
def test_kernels_equal_numpy_references(m):
    x, _, _ = phase_of(np.random.default_rng(m).standard_normal(1200), 0.1)
    ms = np.array([1, m, 2 * m], dtype=np.int64)
    ms = ms[3 * ms < x.size]
    av_ref = [_av_sum(x, int(mi)) for mi in ms]
    for block in (7, 4096, x.size):
        h, a = K.ohvar_sums(x, ms, block)
        np.testing.assert_allclose(h, [K.ohvar_sum_numpy(x, int(mi)) for mi in ms], rtol=1e-12)
        np.testing.assert_allclose(a, av_ref, rtol=1e-12)
    for block in (3, 70, K.BLOCK_MVAR, x.size):  # one chain (< 64 steps a block) and four; blocked, one pass
        mv, a = K.mvar_sums_blocked(x, ms, block)
        np.testing.assert_allclose(mv, [K.mvar_sum_numpy(x, int(mi)) for mi in ms], rtol=1e-11)
        np.testing.assert_allclose(a, av_ref, rtol=1e-12)
    ms = np.array([1, m, 2 * m], dtype=np.int64)
    av_ref = [_av_sum(x, int(mi)) for mi in ms]
    for block in (7, 4096):
        tot, a = K.totvar_sums(x, ms, block)
        np.testing.assert_allclose(tot, [K.totvar_sum_numpy(x, int(mi)) for mi in ms], rtol=1e-12)
        np.testing.assert_allclose(a, av_ref, rtol=1e-12)
    if m % 2 == 0 or m == 1:
        me = 2 * max(1, m // 2)
        for block in (5, K.THEO1_BLOCK, x.size):
            assert K.theo1_sum(x, me, block) == pytest.approx(K.theo1_sum_numpy(x, me), rel=1e-12)


def test_blocked_mvar_equals_reference_on_every_grid():
    """Octave, irregular and 'all'-like grids (many taus: one pass per m), down to a single term (3m = N)."""
    x, _, _ = phase_of(np.random.default_rng(3).standard_normal(3000), 0.1)
    for ms in ([1, 2, 4, 8, 16, 32, 64, 128, 256, 512, 1000], [4, 64, 512], [2], list(range(1, 200))):
        ms = np.array(ms, dtype=np.int64)
        got, av = K.mvar_sums(x, ms)
        np.testing.assert_allclose(got, [K.mvar_sum_numpy(x, int(mi)) for mi in ms], rtol=1e-11)
        np.testing.assert_allclose(av, [_av_sum(x, int(mi)) for mi in ms], rtol=1e-12)


@pytest.mark.parametrize("m", [1, 2, 3, 5, 16])
def test_total_window_kernel_equals_matrix_reference(m):
    """MTOTVAR/HTOTVAR's compiled windows (running sums) against the explicit 6m x 3m filter matrix."""
    v = np.random.default_rng(m).standard_normal(200)
    x = np.concatenate(([0.0], np.cumsum(v)))
    for data, phase in ((x, True), (v, False), (v + 5.0 + 0.01 * np.arange(v.size), False)):
        assert K.total_window_sums(data, m, phase) == pytest.approx(K.total_window_sums_numpy(data, m, phase), rel=1e-11)


def test_htotvar_is_blind_to_a_constant_rate_and_a_ramp():
    w = np.random.default_rng(2).standard_normal(600)
    a = deviation(w, 0.1, "htotvar", edf=False)
    b = deviation(w + 3.0 + 0.05 * np.arange(w.size), 0.1, "htotvar", edf=False)
    np.testing.assert_allclose(b.avar, a.avar, rtol=1e-9)


def test_theobr_is_its_definition_on_allantools_values():
    """TheoBR (Howe & Tasset 2004, SP1065): [mean_i AV(9+3i) / Theo1(12+4i)] Theo1(m), i <= floor(0.1N/3 - 3).

    allantools has no TheoBR: the ratio is rebuilt from allantools' own oadev and theo1 at those m.
    """
    y = DATA["random"][:600]
    N = y.size + 1
    k = int(np.floor(0.1 * N / 3 - 3))
    i = np.arange(k + 1)
    _, av, _, _ = allantools.oadev(y, rate=1.0, data_type="freq", taus=(9.0 + 3 * i))
    _, th, _, _ = allantools.theo1(y, rate=1.0, data_type="freq", taus=(12.0 + 4 * i))
    ratio = np.mean(av**2 / th**2)
    r = deviation(y, 1.0, "theobr", "octave")
    _, th_m, _, _ = allantools.theo1(y, rate=1.0, data_type="freq", taus=r.m.astype(float))
    np.testing.assert_allclose(r.avar, ratio * th_m**2, rtol=1e-9)
    np.testing.assert_allclose(r.tau, 0.75 * r.m)
    with pytest.raises(ValueError, match="N >= 90"):
        deviation(y[:88], 1.0, "theobr")
    deviation(y[:89], 1.0, "theobr")  # N = 90: k = 0


@pytest.mark.parametrize("term", [T.AngleRandomWalk(1e-3), T.RateRandomWalk(3e-4), T.Sinusoidal(1e-3, 0.37),
                                  T.FilteredWhiteNoise(1e-3, tf=0.3), T.Resonance(1e-3, 0.8, 3.0)],
                         ids=lambda t: type(t).__name__)
def test_theobr_ensemble_mean_equals_its_first_order_value(term):
    """E[TheoBR] against the ratio of exact expectations; the O(1/edf) bias of the ratio (its k + 1 Theo1
    values at N = 1001 have edf in the hundreds) is far below the standard error of 60 replicates."""
    n, reps, dt = 1000, 60, 0.1
    m = np.array([8, 64, 400])
    rng = np.random.default_rng(21)
    vals = np.array([deviation(term.simulate(n, dt, rng), dt, "theobr", 0.75 * m * dt, edf=False).avar
                     for _ in range(reps)])
    truth = ev.theobr([term], m, n, dt)
    z = (vals.mean(axis=0) - truth) / (vals.std(axis=0, ddof=1) / np.sqrt(reps))
    assert np.all(np.abs(z) < 4.5), z


def all_terms():
    return [
        T.Quantization(2e-4),
        T.AngleRandomWalk(1e-3),
        T.BiasInstability(1e-3, tau_max=100.0),
        T.GaussMarkov(1e-3, 3.0),
        T.SecondOrderGaussMarkov(1e-4, 0.2),
        T.RateRandomWalk(3e-4),
        T.RateRamp(2e-5),
        T.Sinusoidal(1e-3, 0.37),
        T.FilteredWhiteNoise(1e-3, length=4),
        T.FilteredWhiteNoise(1e-3, tf=0.3),
        T.Resonance(1e-3, 0.8, 3.0),
    ]


def _term_id(t):
    return repr(t).split("(")[0] + ("" if not isinstance(t, T.FilteredWhiteNoise) else
                                    "_fir" if t.tf is None else "_lowpass")


@pytest.mark.parametrize("term", all_terms(), ids=_term_id)
def test_generalized_covariance_gives_back_each_terms_exact_av(term):
    m = np.array([1, 2, 3, 10, 64, 500])
    np.testing.assert_allclose(ev.oavar([term], m, 0.1), term.avar(m, 0.1), rtol=1e-10)


def test_hadamard_is_blind_to_a_ramp():
    ramp = T.RateRamp(1e-3)
    w = ramp.simulate(4000, 0.1, np.random.default_rng(0))
    r = deviation(w, 0.1, "ohvar", "octave")
    x, _, _ = phase_of(w, 0.1)
    rounding = (32 * np.finfo(float).eps * np.max(np.abs(x)) / r.tau) ** 2  # 8 |x| per third difference, x4
    assert np.all(r.avar <= rounding)
    assert np.all(np.abs(ev.ohvar([ramp], r.m, 0.1)) <= 1e-12 * ramp.avar(r.m, 0.1))
    # ... while the AV and the modified AV see it (R^2 tau^2 / 2 and its modified form)
    assert np.all(ev.mvar([ramp], r.m[:4], 0.1) > 0)


def _ensemble(term, n, reps, dt, kind, m, seed):
    rng = np.random.default_rng(seed)
    taus = m * dt * (0.75 if kind == "theo1" else 1.0)
    vals = np.array([deviation(term.simulate(n, dt, rng), dt, kind, taus, noise="white_fm").avar for _ in range(reps)])
    return vals


def _check_mean(term, kind, n, reps, seed, m):
    dt = 0.1
    vals = _ensemble(term, n, reps, dt, kind, m, seed)
    truth = ev.KINDS[kind]([term], m, n, dt)
    se = vals.std(axis=0, ddof=1) / np.sqrt(reps)
    z = (vals.mean(axis=0) - truth) / se
    assert np.all(np.abs(z) < 4.5), (kind, type(term).__name__, z)


STATIONARY_OR_WALK = [t for t in all_terms() if not isinstance(t, T.RateRamp)]


@pytest.mark.parametrize("kind", STATS)
@pytest.mark.parametrize("term", STATIONARY_OR_WALK, ids=_term_id)
def test_ensemble_mean_equals_exact_value(term, kind):
    _check_mean(term, kind, 400, 40, 11, np.array([2, 8, 40]) if kind not in WINDOWED else np.array([1, 2, 8, 24]))


@pytest.mark.slow
@pytest.mark.parametrize("kind", STATS)
@pytest.mark.parametrize("term", STATIONARY_OR_WALK, ids=_term_id)
def test_ensemble_mean_equals_exact_value_slow(term, kind):
    m = np.array([2, 16, 128, 1000]) if kind not in WINDOWED else np.array([1, 2, 16, 64])
    _check_mean(term, kind, 4000, 400, 12, m)


@pytest.mark.parametrize("kind", STATS)
def test_ramp_value_is_exact(kind):
    ramp = T.RateRamp(2e-5)
    m = np.array([2, 8, 40])
    got = deviation(ramp.simulate(600, 0.1, np.random.default_rng(0)), 0.1, kind,
                    m * 0.1 * (0.75 if kind == "theo1" else 1.0)).avar
    truth = ev.KINDS[kind]([ramp], m, 600, 0.1)
    if kind in ("hvar", "ohvar", "htotvar"):  # all blind to a ramp: their exact value is 0 up to rounding
        assert np.all(np.abs(truth) <= 1e-12 * ramp.avar(m, 0.1))
        x, _, _ = phase_of(ramp.simulate(600, 0.1, np.random.default_rng(0)), 0.1)
        assert np.all(got <= (32 * np.finfo(float).eps * np.max(np.abs(x)) / (m * 0.1)) ** 2)
    else:
        np.testing.assert_allclose(got, truth, rtol=1e-8)


@pytest.mark.parametrize("noise,tol", [("white_pm", 0.03), ("white_fm", 0.03), ("rw_fm", 0.06)])
def test_quadratic_form_edf_agrees_with_sp1065_table_5_for_the_av(noise, tol):
    """The exact Gaussian edf of the overlapping AV against SP1065's independent fitted formulas."""
    n = 1000
    for m in (1, 4, 16, 64):  # T/tau >= 16: beyond, the table's fits and the exact edf part (rw_fm 3.14 vs 2.81 at m = 200)
        if noise == "rw_fm" and m < 16:
            continue
        got = edf_quadratic("oavar", m, n + 1 - 2 * m, noise)
        assert got == pytest.approx(float(edf_overlapping([m], n, noise)[0]), rel=tol)


@pytest.mark.parametrize("n", [100, 1000, 100_000])
def test_flicker_fm_edf_at_m1_grows_with_the_record(n):
    """SP1065 Table 5 gives flicker FM at m = 1 its own formula, 2 (N-2)^2 / (2.3 N - 4.9); a common copy
    (the project's SPEC, allantools) drops the square and gets an edf below 1 for every N, which made the
    first point of a real sensor's AV (flat at tau = dt behind its filter: read as flicker FM) carry a
    95 % interval of a factor ~20 and almost no weight wherever the engine's edf weights it."""
    got = edf_quadratic("oavar", 1, n - 1, "flicker_fm")
    assert got > 0.8 * n
    assert got == pytest.approx(float(edf_overlapping([1], n, "flicker_fm")[0]), rel=0.03)


def _edf_reference(kind, m, K, noise):
    """The quadratic-form edf of one filter in plain NumPy (module docstring of ``deviations``): the filter's
    autocorrelation from its taps, rho = A * G densely over every lag, the K-sum by ``np.sum``."""
    pos, coef, _ = _filters(kind, m)
    pos, coef = pos[0], coef[0]
    A1 = np.zeros(int(pos.max()) + 1)
    lag = pos[:, None] - pos[None, :]
    np.add.at(A1, lag[lag >= 0], (coef[:, None] * coef[None, :])[lag >= 0])
    if K < 1:
        return 1.0
    if m > 64 and noise != "white_pm":
        return _edf_reference(kind, 64, max(1, int(round(K * 64 / m))), noise)
    P = A1.size
    kmax = min(K - 1, 8 * (P - 1) + 50 if noise == "flicker_fm" else P - 1)
    A = np.concatenate((A1[:0:-1], A1))
    G = _canonical_gcov(noise, np.arange(-(P - 1), kmax + P))
    rho = np.array([A @ G[k : k + 2 * P - 1] for k in range(kmax + 1)])
    var = 2.0 / K**2 * (K * rho[0] ** 2 + 2 * np.sum((K - np.arange(1, kmax + 1)) * rho[1:] ** 2))
    return float(K) if not var > 0 else max(2 * rho[0] ** 2 / var, 1.0)


@settings(max_examples=60, deadline=None)
@given(kind=st.sampled_from(["oavar", "totvar", "ohvar", "hvar", "mvar", "tvar"]), m=st.integers(1, 300),
       K=st.integers(0, 10**7), noise=st.sampled_from(["white_pm", "white_fm", "flicker_fm", "rw_fm"]))
def test_compiled_edf_equals_its_numpy_reference(kind, m, K, noise):
    """The compiled edf of the single-filter statistics (rho from the filter's nonzero lags, the K-sum in
    order) against the dense NumPy form: the same exact integers for white PM / white FM / RW FM before the
    K-sum, flicker FM's logarithms and both sums' order apart (round-off: 1e-13)."""
    assert edf_quadratics(kind, [m], [K], [noise])[0] == pytest.approx(_edf_reference(kind, m, K, noise), rel=1e-13)


def test_edf_quadratics_is_edf_quadratic_at_every_point_and_names_a_bad_noise():
    m, Kk = np.array([1, 2, 64, 65, 1000, 4]), np.array([10**6, 5, 0, 3000, 10**5, 7])
    noise = ["white_fm", "rw_fm", "flicker_fm", "white_pm", "flicker_fm", "white_pm"]
    for kind in ("ohvar", "mvar", "theo1", "mtotvar"):
        mm = m + (m % 2) if kind == "theo1" else np.minimum(m, 20)
        got = edf_quadratics(kind, mm, Kk, noise)
        assert got.tolist() == [edf_quadratic(kind, int(a), int(b), c) for a, b, c in zip(mm, Kk, noise)]
    np.testing.assert_array_equal(K.filter_acf(K.MODIFIED, 7), ev.mvar_filter_acf(7))
    with pytest.raises(ValueError, match="noise: expected white_pm.*'pink'"):
        edf_quadratics("ohvar", [4], [100], ["pink"])


@pytest.mark.parametrize(
    "kind,term,noise",
    [("ohvar", T.AngleRandomWalk(1e-3), "white_fm"), ("mvar", T.AngleRandomWalk(1e-3), "white_fm"),
     ("theo1", T.AngleRandomWalk(1e-3), "white_fm"), ("totvar", T.AngleRandomWalk(1e-3), "white_fm"),
     ("ohvar", T.RateRandomWalk(3e-4), "rw_fm"), ("totvar", T.RateRandomWalk(3e-4), "rw_fm"),
     ("mtotvar", T.AngleRandomWalk(1e-3), "white_fm"), ("htotvar", T.AngleRandomWalk(1e-3), "white_fm"),
     ("mtotvar", T.RateRandomWalk(3e-4), "rw_fm"), ("htotvar", T.RateRandomWalk(3e-4), "rw_fm")],
)
def test_edf_predicts_the_ensemble_variance(kind, term, noise):
    """Var(estimate) = 2 E^2 / edf, checked on 300 replicates (SE of a sample variance incl. kurtosis)."""
    n, reps, dt = 600, 200, 0.1
    m = np.array([4, 32])
    rng = np.random.default_rng(5)
    taus = m * dt * (0.75 if kind == "theo1" else 1.0)
    res = [deviation(term.simulate(n, dt, rng), dt, kind, taus, noise=noise) for _ in range(reps)]
    vals = np.array([r.avar for r in res])
    edf = res[0].edf
    truth = ev.KINDS[kind]([term], m, n, dt)
    ratio = vals.var(axis=0, ddof=1) / (2 * truth**2 / edf)
    se = np.sqrt(2 / (reps - 1) + 12 / (edf * reps))
    assert np.all(np.abs(ratio - 1) < 4 * se), (ratio, se)


def test_quadratic_form_edf_of_the_av_predicts_its_ensemble_variance_rw_fm():
    """Where it and SP1065 Table 5 part (RW FM, m = 16-64 at N = 1001: 5 %), the ensemble decides."""
    from avbench.estimators.allan.variance import allan_variance

    n, reps, dt, term = 1000, 400, 0.1, T.RateRandomWalk(3e-4)
    m = np.array([16, 64])
    rng = np.random.default_rng(9)
    vals = np.array([allan_variance(term.simulate(n, dt, rng), dt, m * dt).avar for _ in range(reps)])
    edf = np.array([edf_quadratic("oavar", int(mi), n + 1 - 2 * int(mi), "rw_fm") for mi in m])
    ratio = vals.var(axis=0, ddof=1) / (2 * term.avar(m, dt) ** 2 / edf)
    se = np.sqrt(2 / (reps - 1) + 12 / (edf * reps))
    assert np.all(np.abs(ratio - 1) < 4 * se), (ratio, se)


@pytest.mark.parametrize("term,noise", [(T.AngleRandomWalk(1e-3), "white_fm"), (T.RateRandomWalk(3e-4), "rw_fm")],
                         ids=["white_fm", "rw_fm"])
def test_hvar_edf_predicts_its_ensemble_variance(term, noise):
    """The non-overlapping Hadamard variance's edf (the m = 1 OHVAR edf of the decimated phase, K terms)
    against the variance of 400 values; the tolerance from the sampling spread of a sample variance."""
    n, reps, dt = 2000, 400, 0.1
    m = np.array([4, 16])
    rng = np.random.default_rng(5)
    rs = [deviation(term.simulate(n, dt, rng), dt, "hvar", m * dt, noise=noise) for _ in range(reps)]
    vals = np.array([r.avar for r in rs])
    edf = rs[0].edf
    truth = ev.KINDS["hvar"]([term], m, n, dt)
    ratio = vals.var(axis=0, ddof=1) / (2 * truth**2 / edf)
    se = np.sqrt(2 / (reps - 1) + 12 / (edf * reps))
    assert np.all(np.abs(ratio - 1) < 4 * se), (ratio, se, edf)


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("n", [16, 17, 18, 19, 20, 33])
def test_every_value_on_the_all_grid_is_finite_and_has_terms(kind, n):
    """Down to the largest m each definition allows (tvar had one m with no term: an infinite value)."""
    if kind == "theobr":
        n = 95
    r = deviation(np.random.default_rng(n).standard_normal(n), 1.0, kind, "all", edf=False)
    assert np.all(r.J >= 1) and np.all(np.isfinite(r.avar)) and np.all(r.avar > 0), (r.m, r.J, r.avar)


def test_bad_input_is_named():
    with pytest.raises(ValueError, match="kind"):
        deviation(np.zeros(100), 1.0, "adevv")
    with pytest.raises(ValueError, match="taus"):
        deviation(np.random.default_rng(0).standard_normal(30), 1.0, "ohvar", [100.0])
    assert set(STATS) < set(KINDS)


def test_answer_does_not_depend_on_the_unit():
    w = np.random.default_rng(3).standard_normal(900)
    for kind in STATS:
        a, b = deviation(w, 0.1, kind), deviation(w * 180 / np.pi, 0.1, kind)
        np.testing.assert_allclose(b.avar, a.avar * (180 / np.pi) ** 2, rtol=1e-10)
        np.testing.assert_allclose(b.edf, a.edf)


def test_values_only_skip_the_edf():
    w = np.random.default_rng(4).standard_normal(700)
    for kind in STATS:
        a, b = deviation(w, 0.1, kind), deviation(w, 0.1, kind, edf=False)
        np.testing.assert_array_equal(a.avar, b.avar)
        assert np.all(np.isnan(b.edf)) and np.all(np.isfinite(a.edf))


def test_estimate_draws_and_tabulates_deviations(tmp_path, capsys):
    import pandas as pd

    from avbench.cli import main

    f = tmp_path / "rec.npy"
    np.save(f, np.random.default_rng(0).standard_normal(20_000) * 0.01)
    out = tmp_path / "out"
    assert main(["estimate", str(f), "--fs", "100", "--units", "deg/s", "--method", "nnls_rel", "--json",
                 "--deviation", "oadev,ohdev,mdev,tdev,totdev,theo1", "--out", str(out)]) == 0
    table = pd.read_csv(out / "rec_av.csv")
    assert set(table["statistic"]) == {"oadev", "ohdev", "mdev", "tdev", "totdev", "theo1"}
    x = np.load(f) * np.pi / 180
    mine = table[table["statistic"] == "mdev"]
    np.testing.assert_allclose(mine["avar"], deviation(x, 0.01, "mvar").avar, rtol=1e-12)
    assert (out / "rec_gyro_av.png").stat().st_size > 0
    assert main(["estimate", str(f), "--fs", "100", "--units", "deg/s", "--deviation", "adev2", "--out", str(out)]) != 0
    assert "--deviation" in capsys.readouterr().err


def test_max_terms_bounds_the_cost():
    from avbench.estimators.allan.deviations import terms_per_tau

    w = np.random.default_rng(6).standard_normal(3000)
    full = deviation(w, 0.1, "theo1", edf=False)
    budget = 2e6
    cut = deviation(w, 0.1, "theo1", edf=False, max_terms=budget)
    assert 0 < cut.m.size < full.m.size
    np.testing.assert_array_equal(cut.avar, full.avar[: cut.m.size])
    assert np.sum(terms_per_tau("theo1", cut.m, 3001)) <= budget < np.sum(terms_per_tau("theo1", full.m[: cut.m.size + 1], 3001))
    with pytest.raises(ValueError, match="max_terms"):
        deviation(w, 0.1, "theo1", max_terms=10)


def test_deviations_command_writes_csv_and_plot(tmp_path, capsys):
    import pandas as pd

    from avbench.cli import main

    f = tmp_path / "rec.npy"
    np.save(f, np.random.default_rng(1).standard_normal(4000) * 0.01)
    out = tmp_path / "out"
    assert main(["deviations", str(f), "--fs", "100", "--units", "deg/s", "--deviation", "oadev,ohdev,mtotdev,tdev",
                 "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "ohdev" in printed and "mtotdev" in printed
    flat = " ".join(printed.replace("\n#   ", " ").split())
    assert "each value's edf is in the CSV" in flat and "'edf' the equivalent" not in flat
    for name in ("oadev", "ohdev", "mtotdev", "tdev"):  # each statistic's interval, and where and why it stops
        assert f"{name} [68.3 %]" in printed and re.search(rf"^# {name} stops at \S+ s: ", printed, re.M), name
    first = re.search(r"^0\.01\s+(\S+) \[(\S+), (\S+)\]", printed, re.M)
    v, lo, hi = (float(first.group(k).rstrip("]")) for k in (1, 2, 3))
    assert lo < v < hi
    table = pd.read_csv(out / "rec_deviations.csv")
    assert list(dict.fromkeys(table["statistic"])) == ["oadev", "ohdev", "mtotdev", "tdev"]
    x = np.load(f) * np.pi / 180
    for name, kind in (("ohdev", "ohvar"), ("mtotdev", "mtotvar")):
        np.testing.assert_allclose(table.loc[table["statistic"] == name, "avar"], deviation(x, 0.01, kind).avar, rtol=1e-12)
    assert (table.loc[table["statistic"] == "tdev", "unit"] == "variance (rad)^2, deviation rad").all()
    assert (out / "rec_gyro_deviations.png").stat().st_size > 0
    assert main(["deviations", str(f), "--fs", "100", "--units", "deg/s", "--deviation", "hdev2", "--out", str(out)]) == 2
    assert "--deviation" in capsys.readouterr().err
    assert main(["deviations", str(f), "--fs", "100", "--units", "deg/s", "--sensor", "accel", "--out", str(out)]) == 2
    assert "--sensor accel" in capsys.readouterr().err
    long = tmp_path / "long.npy"  # TheoBR's bias ratio is refused up front on a long record, naming why
    np.save(long, np.random.default_rng(2).standard_normal(20_000) * 0.01)
    assert main(["deviations", str(long), "--fs", "100", "--units", "deg/s", "--deviation", "theobr",
                 "--out", str(tmp_path / "o2")]) == 2
    assert "theobr" in capsys.readouterr().err and not (tmp_path / "o2" / "long_deviations.csv").exists()


def test_a_statistic_says_why_it_stops():
    from avbench.recordings.deviations import stop_reason

    w = np.random.default_rng(4).standard_normal(3000)
    full = deviation(w, 0.1, "mtotvar")
    assert "the longest tau its definition allows on a run of 3000 samples" in stop_reason("mtotdev", full, 3000)
    cut = deviation(w, 0.1, "mtotvar", max_terms=2e6)
    assert cut.m.size < full.m.size
    assert "would take it past 2e+06 terms summed" in stop_reason("mtotdev", cut, 3000, budget=2e6)


@pytest.mark.parametrize("n", [16, 17, 31, 1200, 1201, 4095, 4096, 4099, 8191, 4096 * 3 + 5, 70001, 2**17 + 6, 2**19 + 3])
def test_hvar_octave_block_sums_equal_the_decimated_references(n):
    """The block-sum pass (blocks of 2m from pairs of blocks of m) against SP1065 eq. 18 on the decimated
    phase and the non-overlapping AV's sum of squared differences of adjacent cluster sums."""
    w = np.random.default_rng(n).standard_normal(n) + 3.0
    x, _, _ = phase_of(w, 1.0)
    levels = (n // 3).bit_length()
    buf = np.full(K.hvar_octave_buffer_size(n), np.nan)  # the work array's contents must not matter
    h, a, total = K.hvar_octave_sums(w, levels, buf)
    assert total == pytest.approx(float(np.sum(w)), rel=1e-12)
    for lev in range(levels):
        m = 1 << lev
        assert h[lev] == pytest.approx(K.hvar_sum_numpy(x, m), rel=1e-12)
        i = np.arange(0, n - 2 * m + 1, max(m // 2, 1))  # the AV's terms at starts that are multiples of m/2
        assert i.size == K.hvar_octave_av_terms(n, levels)[lev]
        assert a[lev] == pytest.approx(float(np.sum((x[i + 2 * m] - 2 * x[i + m] + x[i]) ** 2)), rel=1e-12)
    # the octave path of ``deviation`` and its any-grid path give the same values (and edf for one noise type)
    m = np.array([1 << lev for lev in range(levels)])
    octave = deviation(w, 1.0, "hvar", "octave", noise="white_fm")
    other = deviation(w, 1.0, "hvar", np.concatenate((m, [3])).astype(float), noise="white_fm")  # not all 2^k
    keep = np.isin(other.m, octave.m)
    np.testing.assert_allclose(other.avar[keep], octave.avar, rtol=1e-12)
    np.testing.assert_array_equal(other.edf[keep], octave.edf)


@pytest.mark.parametrize("term,noise", [(T.AngleRandomWalk(1e-3), "white_fm"), (T.RateRandomWalk(3e-4), "rw_fm"),
                                        (T.Quantization(1e-4), "white_pm")], ids=["white_fm", "rw_fm", "white_pm"])
def test_hvar_identifies_the_noise_type_from_its_own_block_sums(term, noise):
    """hvar's edf with noise="auto" (the type read from the non-overlapping AV of its block sums) equals
    its edf given the true type wherever the slope is trusted with room (>= 64 clusters)."""
    n, dt = 1 << 14, 0.1
    w = term.simulate(n, dt, np.random.default_rng(11))
    auto = deviation(w, dt, "hvar", "octave")
    told = deviation(w, dt, "hvar", "octave", noise=noise)
    keep = n // auto.m >= 64
    np.testing.assert_array_equal(auto.edf[keep], told.edf[keep])


@pytest.mark.parametrize("n", [16, 17, 100, 1201])
def test_mvar_box_sums_equal_the_exactly_rounded_definition(n):
    """The octave box-sum kernel against SP1065 eq. 14 summed with math.fsum (block edges: blocks of 7 and
    64 start indices against boxes up to 256 wide; one block; the record's end), and against the chain."""
    import math

    rng = np.random.default_rng(n)
    x, _, _ = phase_of(rng.standard_normal(n) + np.cumsum(rng.standard_normal(n)) * 0.1 + 50.0, 0.1)
    N = x.size
    levels = min(9, (N // 3).bit_length())
    ref, ref_av = [], []
    for lev in range(levels):
        m = 1 << lev
        v = [math.fsum(x[j + 2 * m : j + 3 * m]) - 2 * math.fsum(x[j + m : j + 2 * m]) + math.fsum(x[j : j + m])
             for j in range(N - 3 * m + 1)]
        ref.append(math.fsum(np.square(v)))
        ref_av.append(_av_sum(x, m))
    for block in (7, 64, K.BLOCK_MVAR_BOX, N):
        got, av = K.mvar_sums_box_octaves(x, levels, block)
        np.testing.assert_allclose(got, ref, rtol=1e-13)
        np.testing.assert_allclose(av, ref_av, rtol=1e-12)
    chain, _ = K.mvar_sums_blocked(x, (1 << np.arange(levels)).astype(np.int64))
    np.testing.assert_allclose(chain, ref, rtol=1e-11)


@pytest.mark.parametrize("taus", ["octave", "decade"])
def test_hvar_names_a_non_finite_sample(taus):
    """hdev's octave pass tests finiteness in its own read of the record: a NaN or an infinity is still
    named (index), as by every other statistic."""
    for bad in (np.nan, np.inf):
        w = np.random.default_rng(1).standard_normal(500)
        w[123] = bad
        with pytest.raises(ValueError, match="non-finite.*index 123"):
            deviation(w, 0.1, "hdev", taus)
