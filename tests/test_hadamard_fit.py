"""wls_edf_hadamard: its model against the exact Hadamard variance, and its blindness to a rate ramp."""

import numpy as np
import pytest

from avbench import estimators
from avbench.estimators.curve_fits.hadamard import hadamard_model
from avbench.noise_models import exact_variances as ev
from avbench.noise_models import terms as T


@pytest.mark.parametrize(
    "term,coefs,m,rtol",
    [
        (T.Quantization(3e-5), {"Q": 3e-5}, [1, 2, 16, 1000], 1e-12),  # exact at every m
        (T.AngleRandomWalk(1e-3), {"N": 1e-3}, [1, 2, 16, 1000], 1e-12),  # exact at every m
        (T.RateRandomWalk(2e-5), {"K": 2e-5}, [64, 1000], 1e-3),  # + discrete term O(1/m^2)
        (T.BiasInstability(1e-4, tau_max=2000.0), {"B": 1e-4}, [64, 512], 5e-3),  # continuous plateau
    ],
)
def test_model_is_the_exact_hadamard_variance(term, coefs, m, rtol):
    m = np.array(m)
    np.testing.assert_allclose(hadamard_model(coefs, m * 0.1), ev.ohvar([term], m, 0.1), rtol=rtol)


def test_a_rate_ramp_changes_nothing():
    dt, n = 0.01, 200_000
    g = [T.AngleRandomWalk(6.5e-4), T.BiasInstability(1.4e-4, tau_max=500.0), T.RateRandomWalk(5e-5)]
    rng = np.random.default_rng(1)
    w = sum(t.simulate(n, dt, rng) for t in g)
    ramp = T.RateRamp(1e-6).simulate(n, dt, rng)
    a = estimators.get("wls_edf_hadamard").fit(w, dt)
    b = estimators.get("wls_edf_hadamard").fit(w + ramp, dt)
    assert np.isfinite(a.coefficients_[["N", "B"]]).all()
    np.testing.assert_allclose(b.coefficients_[list("QNBK")], a.coefficients_[list("QNBK")], rtol=1e-6, equal_nan=True)
    av = estimators.get("wls_edf", terms="QNBK", taus="octave", overlapping=True)
    assert abs(av.fit(w + ramp, dt).coefficients_["K"] / av.fit(w, dt).coefficients_["K"] - 1) > 0.1


def test_asking_for_r_is_an_error():
    with pytest.raises(ValueError, match="rate ramp"):
        estimators.get("wls_edf_hadamard", terms="QNBKR").fit(np.random.default_rng(0).standard_normal(5000), 0.1)
