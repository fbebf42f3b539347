"""GMWM with the sensor's filter given (``filter_tf``, a datasheet's time constant) instead of fitted: the
filter latent's tf is held, the fit counts one parameter fewer, and the record's unit changes nothing."""

import math
import warnings

import numpy as np
import pytest

from avbench import estimators
from avbench.noise_models import FilteredWhiteNoise, Gyro, RateRandomWalk

DT = 0.01
N, TF, K = 1e-3, 0.02, 3e-5
GYRO = Gyro(dt=DT, terms=[FilteredWhiteNoise(N=N, tf=TF), RateRandomWalk(K=K)])


def _fit(x, **settings):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return estimators.get("gmwm", model="FW+RW", min_m=1, **settings).fit(x, DT)


@pytest.mark.parametrize("bad", [0.0, -0.01, math.inf, math.nan, "5 ms", True])
def test_bad_filter_tf_is_named(bad):
    with pytest.raises(ValueError, match=r"'gmwm': filter_tf=.*: expected None or a finite number > 0"):
        estimators.get("gmwm", model="FW+RW", filter_tf=bad)


def test_filter_tf_needs_the_filter_latent():
    with pytest.raises(ValueError, match="filter_tf: .*has no FW"):
        estimators.get("gmwm", model="WN+GM+RW", filter_tf=0.005)
    for name in ("gmwm_filtered", "gmwm_despiked"):  # the real-sensor defaults take it
        assert estimators.get(name, filter_tf=0.005).get_params()["filter_tf"] == 0.005


def test_held_tf_is_the_given_one_and_costs_no_degree_of_freedom():
    x = GYRO.simulate(2**17, np.random.default_rng(5))
    free, held = _fit(x), _fit(x, filter_tf=TF)
    d, f = held.diagnostics_, free.diagnostics_
    assert d["params"]["FW.tf"] == pytest.approx(TF, rel=1e-7)
    assert d["filter_held"] == {"tf": TF} and "filter_held" not in f
    assert d["dof"] == f["dof"] + 1 and d["fit_dof"] == f["fit_dof"] + 1
    assert np.isfinite(held.std_err_["N"]) and np.isfinite(held.std_err_["K"])
    # the held value is a constraint: the fit cannot do better than the free one
    assert d["J_stat"] >= f["J_stat"] - 1e-9 * max(1.0, f["J_stat"])
    # the unit of the record changes only the unit of the rates
    milli = _fit(1000 * x, filter_tf=TF)
    assert milli.diagnostics_["params"]["FW.tf"] == pytest.approx(TF, rel=1e-7)
    np.testing.assert_allclose(milli.coefficients_[["N", "K"]], 1000 * held.coefficients_[["N", "K"]], rtol=1e-6)


def test_hansen_j_with_the_true_tf_held_has_its_degrees_of_freedom():
    """Held at the truth, J is chi^2 with k - 2 degrees of freedom (k scales; N and K estimated): its mean over
    records is that within 3 of its standard errors, sqrt(2 dof / R) = 0.28 at 300 records. Counting the held
    tf as estimated (k - 3) is 1 away, more than 3 of them: the test can fail."""
    reps = 300
    J, dof = [], set()
    for r in range(reps):
        d = _fit(GYRO.simulate(2**16, np.random.default_rng(100 + r)), filter_tf=TF).diagnostics_
        J.append(d["J_stat"])
        dof.add(d["dof"])
    (k2,) = dof
    assert abs(np.mean(J) - k2) <= 3 * math.sqrt(2 * k2 / reps), (np.mean(J), k2)


def test_screen_note_says_the_filter_was_given():
    from avbench.recordings.report import model_choice_notes

    notes = model_choice_notes({"filter_held": {"tf": 0.005}}, "gyro")
    assert "sensor filter held at tf = 5 ms (the filter_tf setting, not fitted)" in notes
