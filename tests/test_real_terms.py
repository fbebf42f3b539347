"""The two terms of real sensors: sinusoidal noise (IEEE 952 Annex C) and the sensor's own filter.

Exact discrete AV against ensemble means (the tolerance from the replicates' standard error, as for
the other terms in test_noise_models.py), against the continuous IEEE 952 forms in their limit,
and against the closed forms derived in the docstrings.
"""

import math

import numpy as np
import pytest
from conftest import mc_tolerance

from avbench.estimators.allan.variance import allan_variance
from avbench.noise_models import (
    AngleRandomWalk,
    FilteredWhiteNoise,
    Gyro,
    Resonance,
    Sinusoidal,
    TERM_TYPES,
)
from avbench.noise_models.exact_avar import avar_from_autocovariance

DT = 0.01

TERMS = {
    "sine": Sinusoidal(A=1e-3, f0=1.7),
    "sine_fast": Sinusoidal(A=1e-3, f0=31.0),  # omega not small: discrete form matters
    "moving_average": FilteredWhiteNoise(N=1e-4, length=4),
    "fir": FilteredWhiteNoise(N=1e-4, taps=[1, 2, 3, 2, 1]),  # Bartlett window
    "lowpass": FilteredWhiteNoise(N=1e-4, tf=0.03),
    "resonance": Resonance(sigma=1e-3, f0=19.0, tc=0.3),  # the ADIS16405 gyro z's 17-21 Hz band
    "resonance_slow": Resonance(sigma=1e-3, f0=0.4, tc=5.0),  # (2m+1)|ln phi| < 1: the sum route
}


def mc_avar(gyro, n, R, seed, overlapping):
    vals = []
    for s in np.random.SeedSequence(seed).spawn(R):
        av = allan_variance(gyro.simulate(n, np.random.default_rng(s)), gyro.dt, "octave", overlapping=overlapping)
        vals.append(av.avar)
    keep = av.J >= 8
    return av.m[keep], np.array(vals)[:, keep]


@pytest.mark.parametrize("name", list(TERMS))
@pytest.mark.parametrize("overlapping", [False, True])
def test_exact_avar_matches_monte_carlo(name, overlapping):
    """Mean of the AV estimates over replicates equals the exact discrete AV (t-test, alpha 1e-4)."""
    gyro = Gyro(dt=DT, terms=[TERMS[name], AngleRandomWalk(N=1e-5)] if name.startswith("sine") else [TERMS[name]])
    m, vals = mc_avar(gyro, 4096, 150, seed=11 + overlapping, overlapping=overlapping)
    exact = gyro.avar(m * DT)
    dev = np.abs(vals.mean(axis=0) - exact)
    assert np.all(dev <= mc_tolerance(vals)), (name, m, vals.mean(0) / exact)


def test_the_test_can_fail_white_line_for_a_filter():
    """The unfiltered white line N^2/tau is measurably wrong at the first octaves of a filtered record."""
    gyro = Gyro(dt=DT, terms=[TERMS["moving_average"]])
    m, vals = mc_avar(gyro, 4096, 150, seed=13, overlapping=True)
    white = 1e-8 / (m * DT)
    assert np.abs(vals.mean(0)[0] - white[0]) > mc_tolerance(vals)[0]


def test_sinusoid_continuous_limit_is_ieee_952():
    """dt -> 0 at fixed tau: A^2 sin^4(m w/2)/(m^2 sin^2(w/2)) -> A^2 (sin^2(pi f tau)/(pi f tau))^2."""
    A, f = 2.0, 0.8
    tau = np.array([0.1, 0.37 / f, 0.9, 1.3, 2.5, 7.7])
    ieee = A**2 * (np.sin(np.pi * f * tau) ** 2 / (np.pi * f * tau)) ** 2
    errs = []
    for dt in (1e-2, 1e-3, 1e-4):
        m = np.rint(tau / dt)
        got = Sinusoidal(A, f).avar(m, dt)
        errs.append(np.max(np.abs(got - A**2 * (np.sin(np.pi * f * m * dt) ** 2 / (np.pi * f * m * dt)) ** 2)))
    assert errs[-1] < 1e-6 * A**2 and errs[0] > errs[1] > errs[2]  # converges
    np.testing.assert_allclose(Sinusoidal(A, f).avar(np.rint(tau / 1e-5), 1e-5), ieee, rtol=1e-5, atol=1e-9)
    # the peak of IEEE 952's curve, tau = 0.371 / f0, ADEV = 0.725 A
    t = np.linspace(0.05, 1.0, 20001) / f
    av = Sinusoidal(A, f).avar(np.rint(t / 1e-6), 1e-6)
    assert t[np.argmax(av)] * f == pytest.approx(0.371, abs=2e-3)
    assert math.sqrt(av.max()) / A == pytest.approx(0.7246, abs=1e-3)


def test_sinusoid_closed_form_agrees_with_autocovariance_route():
    s = Sinusoidal(A=3.0, f0=7.3)
    m = np.unique(np.logspace(0, 3.5, 40).astype(int))
    generic = avar_from_autocovariance(s.autocovariance(np.arange(2 * m.max() + 1), DT), m)
    np.testing.assert_allclose(s.avar(m, DT), generic, rtol=1e-7, atol=1e-12 * 9)
    assert s.spectral_lines(DT) == [(7.3, 4.5)]
    assert s.coefficients() == {}


def test_resonance_closed_form_autocovariance_and_spectrum():
    """The closed form equals the extended-precision autocovariance route; no power at f = 0 (the
    autocovariance sums to 0, the spectrum vanishes there), the spectrum integrates to sigma^2 and
    peaks at f0; the AV falls as 1/tau^2 beyond the band; f0 -> 0 and tc -> oo are not a bias."""
    m = np.unique(np.r_[1, 2, 3, 5, 8, 16, 33, 64, 128, 1000, 4096])
    for term in (TERMS["resonance"], TERMS["resonance_slow"], Resonance(2.0, 45.0, 0.05)):
        r = term.autocovariance(np.arange(2 * m.max() + 1), DT)
        np.testing.assert_allclose(term.avar(m, DT), avar_from_autocovariance(r, m), rtol=1e-10, atol=1e-16 * term.sigma**2)
        assert r[0] == pytest.approx(term.sigma**2, rel=1e-14)
    t = TERMS["resonance"]
    assert abs(2 * t.autocovariance(np.arange(200_001), DT).sum() - t.sigma**2) < 1e-12 * t.sigma**2
    f = np.linspace(1e-6, 0.5 / DT, 400001)
    p = t.psd(f, DT)
    integral = np.trapezoid(p, f) if hasattr(np, "trapezoid") else np.trapz(p, f)
    assert integral == pytest.approx(t.sigma**2, rel=1e-5)
    assert p[0] < 1e-12 * p.max() and f[np.argmax(p)] == pytest.approx(19.0, abs=0.05)
    big = np.array([4096, 8192])
    av = t.avar(big, DT)
    assert av[0] / av[1] == pytest.approx(4.0, rel=0.02)  # 1/tau^2: nothing of N or B
    # the term's own stream has the stationary variance and the autocovariance
    x = Gyro(dt=DT, terms=[t]).simulate(2**18, np.random.default_rng(5))
    acf = np.array([np.dot(x[: x.size - k], x[k:]) / (x.size - k) for k in range(6)])
    np.testing.assert_allclose(acf, t.autocovariance(np.arange(6), DT), atol=6 * t.sigma**2 * math.sqrt(2 * 0.3 / DT / x.size))


def test_filter_closed_forms_and_continuous_limits():
    N = 1e-3
    # moving average: AV = (N^2/tau)(1 - (L^2-1)/(2 L m)) for m >= L, and the autocovariance route agrees
    for L in (1, 3, 8):
        t = FilteredWhiteNoise(N=N, length=L)
        m = np.array([1, 2, L, L + 1, 5 * L, 100 * L])
        generic = avar_from_autocovariance(t.autocovariance(np.arange(2 * m.max() + 1), DT), m)
        np.testing.assert_allclose(t.avar(m, DT), generic, rtol=1e-10)
        big = m[m >= L]
        np.testing.assert_allclose(t.avar(big, DT), N**2 / (big * DT) * (1 - (L * L - 1) / (2 * L * big)), rtol=1e-12)
    # first-order low-pass, dt -> 0 at fixed T: (N^2/tau)[1 - (T/(2tau))(3 - 4e^{-tau/T} + e^{-2tau/T})]
    T = 0.05
    tau = np.array([0.01, 0.05, 0.2, 1.0, 10.0])
    x = tau / T
    cont = N**2 / tau * (1 - (3 - 4 * np.exp(-x) + np.exp(-2 * x)) / (2 * x))
    got = FilteredWhiteNoise(N=N, tf=T).avar(np.rint(tau / 1e-5), 1e-5)
    np.testing.assert_allclose(got, cont, rtol=2e-3)
    # the long-tau AV is the white line: the filter has unit DC gain
    for name in ("moving_average", "fir", "lowpass"):
        assert TERMS[name].avar([10**6], DT)[0] * 1e6 * DT / 1e-8 == pytest.approx(1, rel=1e-4)


def test_psd_integrates_to_the_variance_and_is_the_autocovariance_transform():
    f = np.linspace(1e-6, 0.5 / DT, 200001)
    for name in ("moving_average", "fir", "lowpass"):
        t = TERMS[name]
        var = np.trapezoid(t.psd(f, DT), f) if hasattr(np, "trapezoid") else np.trapz(t.psd(f, DT), f)
        assert var == pytest.approx(t.autocovariance(np.array([0]), DT)[0], rel=1e-4), name
        assert t.psd([1e-9], DT)[0] == pytest.approx(2 * 1e-8, rel=1e-6)  # white level at f -> 0


def test_streaming_and_config_names():
    for name, term in TERMS.items():
        g = Gyro(dt=DT, terms=[term, Sinusoidal(1e-4, 0.3)] if name != "sine" else [term])
        one = g.simulate(9001, np.random.default_rng(3))
        parts = list(g.stream(9001, np.random.default_rng(3), chunk_size=1000))
        assert np.array_equal(np.concatenate(parts), one), name
    assert TERM_TYPES["Sinusoidal"] is Sinusoidal and TERM_TYPES["FilteredWhiteNoise"] is FilteredWhiteNoise
    assert TERM_TYPES["Resonance"] is Resonance


@pytest.mark.parametrize(
    "make, msg",
    [
        (lambda: Sinusoidal(1.0, 60.0).avar([1], DT), "Nyquist"),
        (lambda: Sinusoidal(0.0, 1.0), "A: expected a positive amplitude"),
        (lambda: Sinusoidal(1.0, -1.0), "f0"),
        (lambda: FilteredWhiteNoise(N=1e-4), "exactly one filter"),
        (lambda: Resonance(1.0, 50.0, 0.3).avar([1], DT), "Nyquist"),
        (lambda: Resonance(0.0, 5.0, 0.3), "sigma"),
        (lambda: Resonance(1.0, 5.0, -0.3), "tc"),
        (lambda: FilteredWhiteNoise(N=1e-4, length=2, tf=0.1), "exactly one filter"),
        (lambda: FilteredWhiteNoise(N=1e-4, length=0), "length"),
        (lambda: FilteredWhiteNoise(N=1e-4, taps=[1, -1]), "taps"),
        (lambda: Gyro(dt=DT, terms=[AngleRandomWalk(1e-4), FilteredWhiteNoise(N=1e-4, length=2)]), "coefficient N"),
    ],
)
def test_bad_input(make, msg):
    with pytest.raises(ValueError, match=msg):
        make()


def test_crlb_of_the_real_sensor_terms():
    """A FIR filter has no shape parameter: N's bound is white noise's, 1/sqrt(2n) relative; a
    first-order low-pass adds its tc (the bound can only grow); a sinusoid is left out."""
    from avbench.estimators.likelihood.crlb import crlb

    n = 5000
    white = crlb(Gyro(dt=DT, terms=[AngleRandomWalk(N=1e-3)]), n)["N"]
    assert crlb(Gyro(dt=DT, terms=[FilteredWhiteNoise(N=1e-3, length=4)]), n)["N"] == pytest.approx(white, rel=1e-9)
    assert crlb(Gyro(dt=DT, terms=[FilteredWhiteNoise(N=1e-3, tf=0.03)]), n)["N"] > white * 1.01
    with_sine = crlb(Gyro(dt=DT, terms=[AngleRandomWalk(N=1e-3), Sinusoidal(1e-3, 0.5)]), n)
    assert with_sine["N"] == pytest.approx(white, rel=1e-12)
    # a resonance: its sigma, frequency and tc are nuisance parameters; N's bound can only grow
    with_rs = crlb(Gyro(dt=DT, terms=[AngleRandomWalk(N=1e-3), Resonance(5e-3, 20.0, 0.3)]), n)
    assert with_rs["N"] > white * (1 + 1e-6) and list(with_rs.dropna().index) == ["N"]
