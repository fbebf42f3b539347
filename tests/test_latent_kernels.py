"""The compiled latent-model evaluations GMWM makes (the Gauss-Markov series; the filter's and the resonance's
central-difference gradients, the sinusoid's analytic one), the frequency grid the AV covariance keeps and the
line test kept per record: each gives bit for bit what it replaces (the resonance's its row-by-row ``avar``), or
is held to a reference derivative."""

import math

import numpy as np
import pytest

from avbench.estimators.allan import covariance
from avbench.noise_models import FilteredWhiteNoise, Resonance, Sinusoidal
from avbench.noise_models.latents import build_gyro
from avbench.noise_models.markov_terms import _gm_f_over_c2_numpy, _gm_f_over_c2_rows
from avbench.noise_models.term_base import FrequencyGrid, NoiseTerm


def _same(a, b):
    a, b = np.asarray(a), np.asarray(b)
    return a.shape == b.shape and np.array_equal(a.view(np.int64), b.view(np.int64))


def _sizes(rng):
    return np.unique(np.round(np.geomspace(1, 10 ** rng.uniform(1, 6), rng.integers(1, 20))).astype(np.int64))


def test_gauss_markov_rows_equal_the_numpy_series_bit_for_bit():
    rng = np.random.default_rng(5)
    for trial in range(600):
        m = _sizes(rng)
        if trial % 3:
            a_values = list(10 ** rng.uniform(-9, 1, 3))
        else:  # around the switch between the series and the expm1 form
            a_values = [f / (2 * m[rng.integers(m.size)] + 1) for f in (0.999999, 1.0, 1.000001)]
        rows = _gm_f_over_c2_rows(m, a_values)
        for row, a in zip(rows, a_values):
            assert _same(row, _gm_f_over_c2_numpy(m, a)), (m, a)


def test_filter_gradient_is_the_base_class_central_difference_bit_for_bit():
    rng = np.random.default_rng(7)
    for trial in range(300):
        dt = 10 ** rng.uniform(-3.5, -1)
        fw = FilteredWhiteNoise(N=10 ** rng.uniform(-5, 0), tf=dt * 10 ** rng.uniform(-2, 4))
        m = _sizes(rng)
        (v1, d1), (v0, d0) = fw.avar_shape_derivative(m, dt), NoiseTerm.avar_shape_derivative(fw, m, dt)
        assert _same(v1, v0) and _same(d1, d0)


def test_resonance_gradient_is_the_central_difference_of_avar_bit_for_bit():
    """The five AVs in one compiled call are those of ``avar``, row by row, at the steps ``gradient_steps``
    states (1e-4 where the longest cluster's phase turns less than 1e-2 within it)."""
    rng = np.random.default_rng(11)
    for trial in range(300):
        dt = 10 ** rng.uniform(-3.5, -1)
        f0 = 0.45 / dt * 10 ** rng.uniform(-5, 0)
        res = Resonance(sigma=10 ** rng.uniform(-4, 0), f0=f0,
                        tc=10 ** rng.uniform(math.log10(1 / (math.pi * f0)), 4))
        m = _sizes(rng)
        hf, ht = res.gradient_steps(m, dt)
        assert 0 < hf <= 1e-4 and 0 < ht <= 1e-4
        assert hf == 1e-4 or hf * 2 * math.pi * f0 * dt * m.max() == pytest.approx(1e-2)
        v1, d1 = res.avar_shape_gradient(m, dt)

        def at(f, tc):
            return Resonance(sigma=res.sigma, f0=f, tc=tc).avar(m, dt)

        d0 = [(at(f0 * math.exp(hf), res.tc) - at(f0 * math.exp(-hf), res.tc)) / (2 * hf),
              (at(f0, res.tc * math.exp(ht)) - at(f0, res.tc * math.exp(-ht))) / (2 * ht)]
        assert _same(v1, res.avar(m, dt)) and all(_same(a, b) for a, b in zip(d1, d0))


def test_resonance_gradient_follows_the_oscillation_at_long_taus():
    """A narrow resonance at 13 Hz sampled at 100 Hz, clusters to 2^17: its AV turns through ~1e5 radians of
    phase per unit of ln f0 at the longest, where a step of 1e-4 spans several oscillations. The gradient
    agrees with a Richardson-extrapolated difference of steps 1e-8 (its own error ~1e-8 of the AV's scale)
    to 1e-6 of the largest AV; the fixed step of 1e-4 misses it by the order of the derivative itself."""
    dt = 0.01
    res = Resonance(sigma=1e-3, f0=13.0, tc=3000.0)
    m = 2 ** np.arange(18)
    v, (df, dtc) = res.avar_shape_gradient(m, dt)

    def central(h, which):
        p = {"f0": res.f0, "tc": res.tc}
        up = Resonance(sigma=res.sigma, **{**p, which: p[which] * math.exp(h)}).avar(m, dt)
        down = Resonance(sigma=res.sigma, **{**p, which: p[which] * math.exp(-h)}).avar(m, dt)
        return (up - down) / (2 * h)

    scale = np.abs(v).max()
    for d, which in ((df, "f0"), (dtc, "tc")):
        ref = (4 * central(0.5e-8, which) - central(1e-8, which)) / 3
        assert np.all(np.abs(d - ref) <= 1e-6 * scale), which
    assert np.max(np.abs(central(1e-4, "f0") - df)) > 0.1 * np.max(np.abs(df[-4:]))


@pytest.mark.parametrize("latents, values", [
    (("FW", "GM", "RW", "RS"), [1e-3, 0.004, 1e-4, 80.0, 1e-6, 1e-3, 7.0, 1.5]),
    (("QN", "WN", "FL", "RW"), [1e-5, 1e-3, 1e-4, 1e-6]),
])
def test_spectra_on_a_kept_grid_equal_those_on_the_plain_array(latents, values):
    dt = 0.01
    gyro = build_gyro(latents, values, dt, 7200.0)
    w = (np.arange(50_000) + 0.5) * (np.pi / 50_000)
    f = w / (2 * np.pi * dt)
    grid = FrequencyGrid(f)
    for term in gyro.terms:
        plain, first, again = term.psd(f, dt), term.psd(grid, dt), term.psd(grid, dt)
        assert type(first) is np.ndarray and _same(first, plain) and _same(again, plain)
    assert type(grid * 2.0) is np.ndarray and grid[:10]._kept is None
    kept = [a for v in grid._kept.values() for a in (v if isinstance(v, tuple) else (v,))]
    assert kept and not any(a.flags.writeable for a in kept)  # no spectrum can write into the grid's values


def test_covariance_on_the_kept_grid_is_the_one_computed_afresh(monkeypatch):
    dt = 0.01
    gyro = build_gyro(("FW", "GM", "RW", "RS"), [1e-3, 0.004, 1e-4, 80.0, 1e-6, 1e-3, 7.0, 1.5], dt, 7200.0)
    m = np.unique(np.round(np.geomspace(1, 20_000, 14))).astype(float)
    n_grid = covariance._grid_size(m, 8, 1 << 21)
    covariance._GRIDS.clear()
    kept, again = covariance._direct(gyro, m, n_grid), covariance._direct(gyro, m, n_grid)
    monkeypatch.setattr(covariance, "GAIN_CACHE_BYTES", 0)  # nothing kept: gains and frequencies afresh
    assert _same(kept, covariance._direct(gyro, m, n_grid)) and _same(again, kept)


def _sinusoid_avar_long(amplitude, w, m):
    """The sinusoid's AV (``Sinusoidal.avar``'s formula) in extended precision at angular step ``w``."""
    w, m = np.longdouble(w), m.astype(np.longdouble)
    return np.longdouble(amplitude) ** 2 * np.sin(m * w / 2) ** 4 / (m * m * np.sin(w / 2) ** 2)


def test_sinusoid_derivative_is_the_analytic_one():
    """d avar / d ln f0 of the sinusoid is analytic: its value is ``avar``'s bit for bit, and the derivative
    agrees to 1e-8 of the largest AV with a Richardson-extrapolated central difference in extended precision
    (steps 1e-6 and 5e-7 in ln f0: truncation ~(h m omega)^4, round-off ~1e-19 / h of the AV), up to the
    Nyquist frequency and a longest cluster's phase m omega of 1e5, where the AV's oscillation in f0 defeats a
    step of 1e-4 (beyond it the float64 phase itself, rounded to ~1e-16 m omega, moves the AV by more)."""
    if np.finfo(np.longdouble).eps > 1e-18:
        pytest.skip("no extended precision on this platform")
    rng = np.random.default_rng(13)
    for trial in range(200):
        dt = 10 ** rng.uniform(-3.5, -1)
        f0 = 0.5 / dt * (1 - 1e-9 if trial % 10 == 0 else 10 ** rng.uniform(-5, -1e-4))
        sn = Sinusoidal(A=10 ** rng.uniform(-4, 0), f0=f0)
        m = _sizes(rng)
        m = m[m * 2 * math.pi * f0 * dt <= 1e5]
        v, d = sn.avar_shape_derivative(m, dt)
        assert _same(v, sn.avar(m, dt))
        w = np.longdouble(2 * math.pi * f0 * dt)

        def central(h):
            h = np.longdouble(h)
            return (_sinusoid_avar_long(sn.A, w * np.exp(h), m)
                    - _sinusoid_avar_long(sn.A, w * np.exp(-h), m)) / (2 * h)

        ref = (4 * central(0.5e-6) - central(1e-6)) / 3
        assert np.all(np.abs(d - ref) <= 1e-8 * np.abs(v).max()), (trial, f0, m)


def test_the_line_test_is_kept_per_record():
    from avbench.estimators.selection import lines

    x = np.random.default_rng(3).standard_normal(2**15)
    first = lines.strongest_line(x, 0.01)
    assert lines.strongest_line(x.copy(), 0.01) is first  # the same samples: the kept result
    assert lines.strongest_line(x, 0.01, (1.0, 20.0)) != first  # another band: computed
    y = x.copy()
    y[100] += 1e-12
    assert lines.strongest_line(y, 0.01) is not first
    assert lines.strongest_line.__wrapped__(x, 0.01) == first  # the kept value is the one computed afresh


def test_the_kernel_multiplies_complex_numbers_as_numpy_does_here():
    from avbench.noise_models._term_kernels import _cmul_py, numpy_complex_product

    fused = numpy_complex_product()
    assert fused in (True, False)  # one of the two forms the resonance kernel knows (else NumPy's own route)
    x, y = complex(0.3, -1.7), complex(1.1, 0.9)
    plain = complex(*_cmul_py(x.real, x.imag, y.real, y.imag, False))
    assert plain == complex(x.real * y.real - x.imag * y.imag, x.real * y.imag + x.imag * y.real)
    assert complex(*_cmul_py(x.real, x.imag, y.real, y.imag, fused)) == (np.array([x]) * np.array([y]))[0]
