"""The Whittle Cramér-Rao bound against the closed forms of SPEC "The accuracy limit"."""

import math

import numpy as np
import pytest

from avbench.estimators.likelihood.crlb import crlb, spectral_density, whittle_information
from avbench.noise_models import (
    AngleRandomWalk,
    BiasInstability,
    GaussMarkov,
    Gyro,
    Quantization,
    RateRamp,
    RateRandomWalk,
    SecondOrderGaussMarkov,
)

DT = 0.01
N = 1e-3


@pytest.mark.parametrize("n", [16, 5001, 100_000])
def test_white_alone_is_exact(n):
    # var(N_hat)/N^2 = 1/(2n): every d log S/d log N = 2, so I = (n/2) * 4 / N^2 exactly
    c = crlb(Gyro(dt=DT, terms=[AngleRandomWalk(N=N)]), n)
    assert c["N"] / N == pytest.approx(1 / math.sqrt(2 * n), rel=1e-12)
    assert c.drop("N").isna().all()
    assert list(c.index) == ["Q", "N", "B", "K", "R"]


def test_white_plus_random_walk_closed_form():
    # regime: lambda = K^2 dt^2 / N^2 << 1 and K T / N >> 1. The closed form replaces the sum over
    # Fourier frequencies by an integral; its first corrections are O(N / (K T)) and O(sqrt(lambda)),
    # here 1e-3: allow ten times that.
    K, n = 1e-4, 1_000_000
    T = n * DT
    assert K**2 * DT**2 / N**2 < 1e-5 and N / (K * T) <= 1e-3
    c = crlb(Gyro(dt=DT, terms=[AngleRandomWalk(N=N), RateRandomWalk(K=K)]), n)
    assert c["K"] / K == pytest.approx(math.sqrt(2 * N / (K * T)), rel=0.01)
    assert c["N"] / N == pytest.approx(1 / math.sqrt(2 * n), rel=0.01)


def test_white_plus_flicker_closed_form():
    # With w_c = B^2 dt / N^2 (rad/sample, the white/flicker crossover) and w_1 = 2 pi / n, the
    # closed form holds to first order in w_1/w_c, w_c/pi and the N-B cross-information
    # 2 w_c ln^2(pi/w_c) / pi (~4 % here); allow 5 %.
    B, n = 3e-4, 4_000_000
    T = n * DT
    wc = B**2 * DT / N**2
    assert 2 * math.pi / n / wc < 0.01 and 2 * wc * math.log(math.pi / wc) ** 2 / math.pi < 0.05
    c = crlb(Gyro(dt=DT, terms=[AngleRandomWalk(N=N), BiasInstability(B=B)]), n)
    assert c["B"] / B == pytest.approx(math.sqrt(math.pi / 2) * N / (B * math.sqrt(T)), rel=0.05)


def test_gauss_markov_reports_b_equiv_and_scales_with_n():
    gm = GaussMarkov(sigma=1e-4, tc=50.0)
    g = Gyro(dt=DT, terms=[AngleRandomWalk(N=N), gm])
    c1, c4 = crlb(g, 250_000), crlb(g, 1_000_000)
    assert c1[["N", "B"]].notna().all() and c1[["Q", "K", "R"]].isna().all()
    # a Whittle bound is O(1/sqrt(n)) once the record is long against Tc (T = 50 Tc here)
    ratio = (c1 / c4)[["N", "B"]]
    assert np.allclose(ratio, 2.0, rtol=0.15)
    # B = 0.9294 sigma: the bound on B is that on sigma times 0.9294 -- check via the information
    names, values, info = whittle_information(g, 250_000)
    j = names.index((1, "sigma"))
    std_log_sigma = math.sqrt(np.linalg.inv(info)[j, j])
    assert c1["B"] == pytest.approx(gm.coefficients()["B"] * std_log_sigma, rel=1e-12)


def test_five_term_model_and_ramp():
    terms = [
        Quantization(Q=1e-6),
        AngleRandomWalk(N=N),
        GaussMarkov(sigma=1e-4, tc=100.0),
        RateRandomWalk(K=1e-6),
        SecondOrderGaussMarkov(R=1e-7, w0=1e-3),
    ]
    c = crlb(Gyro(dt=DT, terms=terms), 200_000)
    assert (c > 0).all() and np.isfinite(c).all()
    # a deterministic ramp has no spectrum: its bound is NaN, the others are unchanged
    with_ramp = crlb(Gyro(dt=DT, terms=[AngleRandomWalk(N=N), RateRamp(R=1e-7)]), 10_000)
    assert math.isnan(with_ramp["R"])
    assert with_ramp["N"] / N == pytest.approx(1 / math.sqrt(2 * 10_000), rel=1e-12)


def test_spectral_density_is_the_sum_of_the_terms():
    terms = [AngleRandomWalk(N=N), RateRandomWalk(K=1e-6)]
    f = np.array([0.01, 1.0, 50.0])
    s = spectral_density(Gyro(dt=DT, terms=terms), f)
    assert np.allclose(s, terms[0].psd(f, DT) + terms[1].psd(f, DT), rtol=1e-14)


@pytest.mark.parametrize("bad", [10, 100.0, True, "1000"])
def test_bad_n_samples(bad):
    with pytest.raises(ValueError, match="n_samples"):
        crlb(Gyro(dt=DT, terms=[AngleRandomWalk(N=N)]), bad)


def test_ramp_only_has_nothing_to_bound():
    with pytest.raises(ValueError, match="no stochastic term"):
        crlb(Gyro(dt=DT, terms=[RateRamp(R=1e-7)]), 1000)
