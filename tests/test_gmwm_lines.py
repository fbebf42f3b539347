"""Spectral lines in GMWM's default model: the test for a hidden periodicity
(avbench.estimators.selection.lines), GMWM's lines="auto" (a sinusoid SN added on that evidence) and
min_m="adequate".

The line test must hold its level on broadband records (colored noise: its p-values are conservative,
the fraction below 0.05 is at most the binomial 99.9 % limit for 5 %), find a sinusoid where there is
one, and gmwm_filtered (lines="auto") must add SN on that evidence only.
"""

import math

import numpy as np
import pytest
from scipy.stats import binom

from avbench import estimators
from avbench.estimators.selection.lines import strongest_line
from avbench.noise_models import (AngleRandomWalk, FilteredWhiteNoise, GaussMarkov, Gyro, RateRandomWalk,
                                  Sinusoidal)

DT = 0.01


def _broadband():
    return Gyro(dt=DT, terms=[FilteredWhiteNoise(N=1e-3, tf=0.02), GaussMarkov(sigma=5e-4, tc=2.0),
                              RateRandomWalk(K=2e-6)])


def test_line_test_holds_its_level_on_broadband_records():
    g, reps = _broadband(), 120
    rng = np.random.default_rng(5)
    p = np.array([strongest_line(g.simulate(20_000, rng), DT).p_value for _ in range(reps)])
    assert np.all((p >= 0) & (p <= 1))
    assert np.count_nonzero(p < 0.05) <= binom.ppf(0.999, reps, 0.05)


def test_line_test_finds_a_sinusoid():
    a, f0, n = 2e-3, 4.3, 100_000  # searched from 10 * 8 * 32 / T = 2.56 Hz
    g = Gyro(dt=DT, terms=list(_broadband().terms) + [Sinusoidal(a, f0)])
    line = strongest_line(g.simulate(n, np.random.default_rng(6)), DT)
    assert line.p_value < 1e-6
    assert abs(line.f0 - f0) <= 2.0 / (n * DT)
    assert line.amplitude == pytest.approx(a, rel=0.1)
    with pytest.raises(Exception):
        strongest_line(np.zeros((3, 3)), DT).p_value  # not a 1-D record: None has no p_value


def test_gmwm_filtered_adds_a_sinusoid_on_evidence_only():
    n = 100_000
    base = _broadband()
    with_line = Gyro(dt=DT, terms=list(base.terms) + [Sinusoidal(3e-3, 3.3)])  # 2.56 Hz and up are searched on 1000 s
    e = estimators.get("gmwm_filtered").fit(with_line.simulate(n, np.random.default_rng(8)), DT)
    lt = e.diagnostics_["line_test"]
    assert lt["included"] and lt["significant"]
    assert e.diagnostics_["params"]["SN.f0"] == pytest.approx(3.3, rel=0.05)
    assert lt["f0_at_bound"] is False  # a pure tone: the fitted f0 inside its window around the line
    assert not e.diagnostics_["poor_fit"]
    plain = estimators.get("gmwm_filtered").fit(base.simulate(n, np.random.default_rng(9)), DT)
    assert not plain.diagnostics_["line_test"]["included"]
    assert "SN.A" not in plain.diagnostics_["params"]
    kept = estimators.get("gmwm_filtered", lines="model").fit(with_line.simulate(n, np.random.default_rng(8)), DT)
    assert "SN.A" not in kept.diagnostics_["params"]  # lines="model": the model as given


def test_sinusoid_frequency_on_its_bound_is_reported(monkeypatch):
    # a window of 1e-9 around the line (at least 0.1 % wide, Sinusoidal.fit_shape_bounds): any fitted f0 lies on its edge
    import avbench.estimators.selection.lines as lines_module

    x = Gyro(dt=DT, terms=list(_broadband().terms) + [Sinusoidal(3e-3, 3.3)]).simulate(100_000, np.random.default_rng(8))
    monkeypatch.setattr(lines_module, "LINE_FREQUENCY_FACTOR", 1.0 + 1e-9)
    lt = estimators.get("gmwm_filtered").fit(x, DT).diagnostics_["line_test"]
    assert lt["f0_at_bound"] is True


def test_adequate_cutoff_keeps_every_scale_when_the_model_fits():
    x = _broadband().simulate(200_000, np.random.default_rng(10))
    e = estimators.get("gmwm", model="FW+GM+RW", min_m="adequate").fit(x, DT)
    assert e.diagnostics_["min_m"] == 1 and len(e.diagnostics_["scale_choice"]) == 1
    with pytest.raises(ValueError, match="min_m"):
        estimators.get("gmwm", min_m="best").fit(x, DT)
    # a model that misses the middle of the curve is not rescued by fitting only its long end
    g = Gyro(dt=0.1, terms=[AngleRandomWalk(N=1e-3), GaussMarkov(sigma=3e-4, tc=20.0), RateRandomWalk(K=3e-6)])
    wrong = estimators.get("gmwm", model="WN+RW", min_m="adequate").fit(g.simulate(200_000, np.random.default_rng(11)),
                                                                         0.1).diagnostics_
    assert wrong["poor_fit"]
    assert 2 * len(wrong["tau"]) >= wrong["scale_choice"][0]["n_scales"]
    with pytest.raises(ValueError, match="lines"):
        estimators.get("gmwm", lines="yes").fit(x, DT)


@pytest.mark.slow
@pytest.mark.timeout(3600)  # 60 fits with a sinusoid: ~5 min on a quiet machine, over 10 at load 10
@pytest.mark.parametrize("with_line", [False, True])
def test_default_fit_check_false_alarms_stay_nominal(with_line):
    """gmwm_filtered at its defaults (lines="auto", min_m="adequate") on 60 simulated records of a filtered
    gyro (with and without a sinusoid): the poor-fit check (level 0.01) flags at most the binomial 99.9 %
    limit of 60 x 0.01 -- choosing SN and the cut-off by evidence does not inflate its false alarms."""
    reps, n = 60, 100_000
    terms = list(_broadband().terms) + ([Sinusoidal(3e-3, 3.3)] if with_line else [])
    g = Gyro(dt=DT, terms=terms)
    flagged, included = 0, 0
    for s in np.random.SeedSequence(2024).spawn(reps):
        e = estimators.get("gmwm_filtered").fit(g.simulate(n, np.random.default_rng(s)), DT)
        flagged += bool(e.diagnostics_["poor_fit"])
        included += bool(e.diagnostics_["line_test"]["included"])
    print(f"with_line={with_line}: {flagged}/{reps} flagged, SN included on {included}/{reps}")
    assert flagged <= binom.ppf(0.999, reps, 0.01)
    assert included == (reps if with_line else 0) or (not with_line and included <= binom.ppf(0.999, reps, 0.001))
