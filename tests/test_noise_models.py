"""Generators: exact discrete AV against Monte Carlo means, streaming, presets, bad input."""

import math

import numpy as np
import pytest
from conftest import mc_tolerance

from avbench.estimators.allan.variance import allan_variance
from avbench.noise_models import (
    AngleRandomWalk,
    BiasInstability,
    GaussMarkov,
    Gyro,
    Quantization,
    RateRamp,
    RateRandomWalk,
    SecondOrderGaussMarkov,
    presets,
)
from avbench.noise_models.exact_avar import avar_from_autocovariance
from avbench.noise_models.terms import B_EQUIV_OVER_SIGMA

PLATEAU = 2 * math.log(2) / math.pi
DT = 0.01

TERMS = {
    "quantization": Quantization(Q=1e-5),
    "arw": AngleRandomWalk(N=1e-4),
    "rrw": RateRandomWalk(K=1e-5),
    "gm_short": GaussMarkov(sigma=1e-3, tc=0.05),  # Tc = 5 dt: the discrete formula matters
    "gm_long": GaussMarkov(sigma=1e-3, tc=20.0),
    "flicker": BiasInstability(B=1e-4, tau_max=20.0),
    "sogm": SecondOrderGaussMarkov(R=1e-4, w0=2.0),
}


def mc_avar(gyro, n, R, seed, overlapping=False, max_m=None):
    ss = np.random.SeedSequence(seed).spawn(R)
    vals = []
    for s in ss:
        x = gyro.simulate(n, np.random.default_rng(s))
        av = allan_variance(x, gyro.dt, "octave", overlapping=overlapping)
        vals.append(av.avar)
    vals = np.array(vals)
    keep = av.J >= 8 if max_m is None else av.m <= max_m
    return av.m[keep], vals[:, keep]


@pytest.mark.parametrize("name", list(TERMS))
@pytest.mark.parametrize("overlapping", [False, True])
def test_term_exact_avar_matches_monte_carlo(name, overlapping):
    """Mean of the AV estimates over replicates equals the exact discrete AV (t-test, alpha 1e-4)."""
    gyro = Gyro(dt=DT, terms=[TERMS[name]])
    m, vals = mc_avar(gyro, 4096, 150, seed=1 + overlapping)
    exact = gyro.avar(m * DT)
    dev = np.abs(vals.mean(axis=0) - exact)
    assert np.all(dev <= mc_tolerance(vals)), (name, m, vals.mean(0) / exact)


def test_the_test_can_fail_continuous_formulas_at_small_m():
    """At m = 1 the continuous formulas are measurably wrong; the MC test would catch them."""
    B = 1e-4
    gyro = Gyro(dt=DT, terms=[BiasInstability(B=B, tau_max=20.0)])
    m, vals = mc_avar(gyro, 4096, 150, seed=3)
    wrong = np.full(len(m), PLATEAU * B**2)  # the plateau constant used as truth
    assert np.abs(vals.mean(0)[0] - wrong[0]) > mc_tolerance(vals)[0]
    K = 1e-3
    gyro = Gyro(dt=1.0, terms=[RateRandomWalk(K=K)])
    m, vals = mc_avar(gyro, 4096, 150, seed=4)
    continuous = K**2 * m / 3.0  # without the point-sampling correction K^2 dt^2 / (6 tau)
    assert np.abs(vals.mean(0)[0] - continuous[0]) > mc_tolerance(vals)[0]


def test_ramp_is_exact():
    g = Gyro(dt=0.1, terms=[RateRamp(R=1e-6)])
    x = g.simulate(1000, np.random.default_rng(0))
    av = allan_variance(x, 0.1, "octave", overlapping=False)
    np.testing.assert_allclose(av.avar, g.avar(av.tau), rtol=1e-9)


def test_flicker_discrete_values_from_spec():
    """SPEC: AV(1) = 2B^2/pi exactly; m = 2, 4, 8, 16 at 1.154, 1.050, 1.015, 1.005 of the plateau."""
    b = BiasInstability(B=1.0, tau_max=1e6)  # long memory: the ideal 1/f values
    av = b.avar([1, 2, 4, 8, 16], dt=1.0) / PLATEAU
    assert av[0] == pytest.approx((2 / math.pi) / PLATEAU, rel=1e-3)
    np.testing.assert_allclose(av[1:], [1.154, 1.050, 1.015, 1.005], atol=6e-4)


def test_gauss_markov_closed_form_agrees_with_autocovariance_route():
    for tc, dt in [(0.05, 0.01), (20.0, 0.01), (1e4, 0.001)]:
        g = GaussMarkov(sigma=2.0, tc=tc)
        m = np.unique(np.logspace(0, 4, 30).astype(int))
        generic = avar_from_autocovariance(g.autocovariance(np.arange(2 * m.max() + 1), dt), m)
        np.testing.assert_allclose(g.avar(m, dt), generic, rtol=1e-8)


def test_gauss_markov_limits_and_b_equiv():
    g = GaussMarkov(sigma=1.0, tc=100.0)
    tau = np.logspace(-1, 4, 2000)
    av = g.avar(np.rint(tau / 0.01), 0.01)
    peak = np.argmax(av)
    assert tau[peak] / 100.0 == pytest.approx(1.8926, rel=0.01)
    assert math.sqrt(av[peak]) == pytest.approx(0.6174, rel=1e-3)
    assert g.coefficients()["B"] == pytest.approx(B_EQUIV_OVER_SIGMA)
    assert B_EQUIV_OVER_SIGMA == pytest.approx(0.9294, abs=1e-4)
    # tau << Tc: RRW with K^2 = 2 sigma^2 / Tc; tau >> Tc: ARW with N^2 = 2 sigma^2 Tc
    assert g.avar([100], 0.01)[0] / (2 / 100.0 * 1.0 / 3) == pytest.approx(1, rel=0.01)
    assert g.avar([10_000_000], 0.01)[0] * 1e5 / (2 * 100.0) == pytest.approx(1, rel=0.01)


def test_second_order_gm_imitates_ramp_for_short_tau():
    """AV -> R^2 tau^2 / 2 for tau << 1/w0; the first correction is of order w0 tau."""
    w0 = 0.01
    s = SecondOrderGaussMarkov(R=1.0, w0=w0)
    tau = np.array([1, 10, 100, 1000]) * 0.01
    ratio = s.avar(tau / 0.01, 0.01) / (tau**2 / 2)
    assert np.all(np.abs(ratio - 1) <= w0 * tau + 1e-9)
    assert abs(ratio[-1] - 1) > 0.1 * w0 * tau[-1]  # and it does depart from the ramp


@pytest.mark.parametrize("name", list(TERMS) + ["ramp"])
def test_streaming_is_bit_identical(name):
    term = TERMS.get(name, RateRamp(R=1e-6))
    other = RateRamp(R=1e-6) if name == "arw" else AngleRandomWalk(N=1e-4)
    g = Gyro(dt=DT, terms=[term, other])
    one = g.simulate(70_001, np.random.default_rng(5))
    for chunk in (1, 999, 65_536, 100_000):
        if chunk == 1:
            parts = list(g.stream(3000, np.random.default_rng(5), chunk_size=1))
            assert np.array_equal(np.concatenate(parts), one[:3000])
            continue
        parts = list(g.stream(70_001, np.random.default_rng(5), chunk_size=chunk))
        assert all(len(p) <= chunk for p in parts)
        assert np.array_equal(np.concatenate(parts), one)


def test_replicate_streams_independent_of_order():
    g = presets.get("SRS2000")
    ss = np.random.SeedSequence(7).spawn(3)
    a = [g.simulate(5000, np.random.default_rng(s)) for s in ss]
    ss2 = np.random.SeedSequence(7).spawn(3)
    b = [g.simulate(5000, np.random.default_rng(s)) for s in reversed(ss2)][::-1]
    for x, y in zip(a, b):
        assert np.array_equal(x, y)
    assert not np.array_equal(a[0], a[1])


def test_presets_documented_and_consistent():
    for name in presets.names():
        p = presets.info(name)
        g = presets.get(name)
        assert p.source and g.dt == p.dt and g.name == name
        coefs = g.coefficients
        for c, (v, u) in p.coefficients.items():
            from avbench.noise_models.units import to_si

            assert coefs[c] == pytest.approx(to_si(c, v, u))
        tau = np.array([1, 2, 4]) * g.dt
        np.testing.assert_allclose(g.avar(tau), np.sum([t.avar([1, 2, 4], g.dt) for t in g.terms], axis=0))
    assert presets.get("ADIS16405_X_50HZ").dt == 0.02
    assert presets.record_seconds("FOG1") == 3 * 3600


@pytest.mark.parametrize("name", ["SRS2000", "VG951", "CRG20"])
def test_preset_avar_matches_monte_carlo(name):
    g = presets.get(name)
    m, vals = mc_avar(g, 4096, 40, seed=11)
    assert np.all(np.abs(vals.mean(0) - g.avar(m * g.dt)) <= mc_tolerance(vals))


@pytest.mark.slow
@pytest.mark.parametrize("name", presets.names())
def test_preset_avar_matches_monte_carlo_slow(name):
    g = presets.get(name)
    m, vals = mc_avar(g, 1 << 16, 60, seed=12, overlapping=True)
    assert np.all(np.abs(vals.mean(0) - g.avar(m * g.dt)) <= mc_tolerance(vals))


@pytest.mark.parametrize(
    "make, msg",
    [
        (lambda: AngleRandomWalk(N=-1.0), "non-negative"),
        (lambda: AngleRandomWalk(N=float("nan")), "non-negative"),
        (lambda: Quantization(Q=(1.0, "parsec")), "unknown unit"),
        (lambda: GaussMarkov(sigma=1.0, tc=0.0), "tc"),
        (lambda: Gyro(dt=0.0, terms=[AngleRandomWalk(N=1.0)]), "dt"),
        (lambda: Gyro(dt=-1.0, terms=[AngleRandomWalk(N=1.0)]), "dt"),
        (lambda: Gyro(dt=0.1, terms=[]), "at least one"),
        (lambda: Gyro(dt=0.1, terms=[GaussMarkov(1.0, 1.0), BiasInstability(B=1.0)]), "both report"),
        (lambda: presets.get("SRS3000"), "unknown preset"),
        (lambda: Gyro(dt=0.1, terms=[AngleRandomWalk(N=1.0)]).avar([0.15]), "multiples of dt"),
        (lambda: Gyro(dt=0.1, terms=[AngleRandomWalk(N=1.0)]).simulate(-5, 0), "non-negative integer"),
        (lambda: Gyro(dt=0.1, terms=[AngleRandomWalk(N=1.0)]).simulate(5, "seed"), "rng"),
    ],
)
def test_bad_input(make, msg):
    with pytest.raises(ValueError, match=msg):
        make()


def _every_builtin_term():
    from avbench.noise_models import FilteredWhiteNoise, Resonance, Sinusoidal

    return [*TERMS.values(), RateRamp(R=1e-6), Sinusoidal(A=1e-3, f0=3.0),
            FilteredWhiteNoise(N=1e-4, length=5), FilteredWhiteNoise(N=1e-4, taps=[1, 3, 1]),
            FilteredWhiteNoise(N=1e-4, tf=0.03), Resonance(sigma=1e-3, f0=7.0, tc=0.4)]


def test_noise_term_is_an_abstract_base_every_term_fills():
    """A term that leaves out a declaration of the interface (here the autocovariance) cannot be made;
    every built-in term type is one of the terms checked below."""
    from avbench.noise_models import TERM_TYPES, NoiseTerm

    class NoAutocovariance(NoiseTerm):
        def _params(self):
            return {}

        def avar(self, m, dt):
            return np.zeros(len(m))

        def psd(self, f, dt):
            return np.zeros(len(f))

        def stream(self, dt, rng):
            raise AssertionError

    with pytest.raises(TypeError, match="autocovariance"):
        NoAutocovariance()

    class NoTruth(NoiseTerm):  # a user's term that says it has no exact statistics is made, and says so when asked
        has_exact_avar = False

        def _params(self):
            return {}

        def stream(self, dt, rng):
            raise AssertionError

    with pytest.raises(ValueError, match="NoTruth: no exact psd"):
        NoTruth().psd(np.ones(2), 0.1)
    assert {type(t).__name__ for t in _every_builtin_term()} == set(TERM_TYPES)


@pytest.mark.parametrize("term", _every_builtin_term(), ids=repr)
def test_autocovariance_takes_an_array_of_lags_and_gives_back_the_exact_av(term):
    """One signature: integer lags of any shape (r(-k) = r(k)) to the rate autocovariance there, whose AV
    is the term's exact AV; a term that is not stationary says so."""
    m = np.array([1, 2, 3, 7, 40])
    lags = np.arange(2 * m.max() + 1)
    if not term.stationary:
        with pytest.raises(ValueError, match="not stationary"):
            term.autocovariance(lags, DT)
        return
    r = term.autocovariance(lags, DT)
    assert r.shape == lags.shape
    grid = term.autocovariance(np.array([[3, -3], [0, 5]]), DT)
    np.testing.assert_array_equal(grid, [[r[3], r[3]], [r[0], r[5]]])
    scale = float(np.max(np.abs(term.avar(m, DT))))
    # a deterministic term's AV is its mean's (phase_mean): its random part, the autocovariance, is 0
    expected = np.zeros(m.size) if hasattr(term, "phase_mean") else term.avar(m, DT)
    np.testing.assert_allclose(avar_from_autocovariance(r, m), expected, rtol=1e-9, atol=1e-12 * scale)
