"""The filter yaml from a short record: a random walk the record does not resolve is written as the
upper end of its interval, said to be a bound, with the record length that would resolve it."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from avbench.estimators.allan.variance import allan_variance
from avbench.recordings import filter_yaml


def _entry(si, flag="ok", ci=None, reason="record", name="K"):
    """A coefficient as a fit gives it (:class:`avbench.estimators.results.Coefficient`): an estimate of 0,
    or one whose interval reaches zero, is "not resolved" (reason "zero", "interval"), as FitResult says."""
    from avbench.estimators.results import Coefficient, unresolved_reason

    why = unresolved_reason(si, None, ci) if flag == "ok" and si is not None else None
    if why is not None:
        flag, reason = "not resolved", why
    ok = flag == "ok"
    return Coefficient(name=name, status=flag, value=si if ok else np.nan, fitted=np.nan if si is None else si,
                       interval=None if ci is None else tuple(ci), reason=None if ok else reason)


def _payload(gyro_k: dict, poor=False):
    """``{sensor: {axis: {"m": FitResult}}}`` with these random walks K of the gyro's axes."""
    from avbench.estimators.results import FitCheck, FitResult

    def axis(k, n=None):
        n = n or _entry(1e-3, ci=(0.9e-3, 1.1e-3), name="N")
        return {"m": FitResult(method="m", coefficients={"N": n, "K": k}, fit_check=FitCheck(poor))}
    return {"gyro": {a: axis(k) for a, k in gyro_k.items()}, "accel": {"x": axis(_entry(1e-4, ci=(0.5e-4, 2e-4)))}}


def test_resolved_values_are_kept_and_unresolved_ones_become_their_upper_bound():
    data = _payload({"x": _entry(2e-5, ci=(1e-5, 3e-5)), "y": _entry(None, "not resolved", ci=(0, 4e-5)),
                     "z": _entry(0.0, ci=(0.0, 5e-6))})
    ch = filter_yaml.filter_choices(data, "m")
    v, axis, why = ch["gyroscope_random_walk"]
    assert (v, axis) == (4e-5, "y") and "not resolved" in why
    v, axis, why = ch["accelerometer_random_walk"]
    assert (v, axis, why) == (1e-4, "x", None)
    text = filter_yaml.kalibr_yaml(ch, 100.0, None, "m", ["r.csv"])
    assert "# gyroscope_random_walk: a BOUND, not an estimate -- axis y not resolved" in text
    assert "accelerometer_random_walk: a BOUND" not in text


def test_an_interval_reaching_zero_or_a_poor_fit_gives_the_upper_end():
    ch = filter_yaml.filter_choices(_payload({"x": _entry(2e-5, ci=(0.0, 6e-5))}), "m")
    assert ch["gyroscope_random_walk"][0] == 6e-5 and "reaches zero" in ch["gyroscope_random_walk"][2]
    ch = filter_yaml.filter_choices(_payload({"x": _entry(2e-5, ci=(1e-5, 7e-5))}, poor=True), "m")
    assert ch["gyroscope_random_walk"][0] == 7e-5 and "poor" in ch["gyroscope_random_walk"][2]
    # a resolved noise density stays the estimate under a poor fit (it is read where the AV pins it); one whose
    # interval reaches zero is still a bound
    assert ch["gyroscope_noise_density"] == (1e-3, "x", None)
    assert ch["accelerometer_noise_density"] == (1e-3, "x", None)
    zero_n = _payload({"x": _entry(2e-5, ci=(1e-5, 3e-5))})
    zero_n["gyro"]["x"]["m"].coefficients["N"] = _entry(1e-3, ci=(0.0, 2e-3), name="N")
    v, _, why = filter_yaml.filter_choices(zero_n, "m")["gyroscope_noise_density"]
    assert v == 2e-3 and "reaches zero" in why


def test_without_an_interval_the_av_bounds_it_and_the_bound_holds():
    """A zero K with no interval: the bound the AV allows (K^2 tau / 3 <= AV at its 95 % chi^2 upper
    limit), which lies above the true K of the simulated record, and the length that would resolve it."""
    rng = np.random.default_rng(7)
    dt, n, N, K = 0.01, 180_000, 1e-3, 2e-5
    x = N / np.sqrt(dt) * rng.standard_normal(n) + np.cumsum(K * np.sqrt(dt) * rng.standard_normal(n))
    av = allan_variance(x, dt, "octave")
    data = _payload({"x": _entry(0.0)})
    ch = filter_yaml.filter_choices(data, "m", avs={"gyro": {"x": (av, 1.0)}})
    v, _, why = ch["gyroscope_random_walk"]
    assert v >= K and "the bound the AV allows" in why and ("would resolve it" in why or "resolving it needs" in why)
    assert filter_yaml.av_bound("K", av) == v


_REAL = pytest.mark.skipif(not os.environ.get("AVBENCH_REAL_DATA"),
                           reason="AVBENCH_REAL_DATA is not set: the real ADIS runs are optional")


@pytest.fixture(scope="module")
def slice_rows():
    from avbench.studies.yaml_slices import check, yaml_rows

    rows = yaml_rows(Path(os.environ["AVBENCH_REAL_DATA"]), max_slices=1)
    if rows.empty:
        pytest.skip("the ADIS16405 runs are not under AVBENCH_REAL_DATA")
    return rows.assign(holds=check(rows))


@pytest.mark.slow
@_REAL
def test_thirty_minute_slices_gyro_random_walk_never_falls_below_the_full_runs(slice_rows):
    """On the first 30-minute slice of each of the six ADIS16405 runs, the yaml's gyro random walk plus
    its stated uncertainty reaches the full run's largest per-axis estimate (results/real/yaml_slices.md;
    ~15 min)."""
    g = slice_rows[slice_rows["key"] == "gyroscope_random_walk"]
    assert len(g) == 6 and g["holds"].all(), g.to_string()


@pytest.mark.slow
@_REAL
def test_thirty_minute_slices_accel_random_walk_never_falls_below_the_full_runs(slice_rows):
    """The same for the accelerometer's random walk (results/real/yaml_slices.md): a value below the
    full run's is only ever an estimate whose interval reaches it, and a bound says so. The closest: run 6, whose
    first 30 minutes' bound 4.59e-4 lies 1.3 % above the full run's largest accelerometer K, 4.53e-4 (x; 1.3 %
    below it before the intervals took the misfit's Birge ratio: the full runs read the slow ~150 s bias drift,
    which one bias term cannot take, as random walk)."""
    a = slice_rows[slice_rows["key"] == "accelerometer_random_walk"]
    assert len(a) == 6 and a["holds"].all(), a.to_string()
    assert (a.loc[a["bound"], "why"].str.len() > 0).all()  # every bound carries its reason (the yaml's comment)
    below = a[a["yaml_si"] < a["full_run_max_si"]]
    assert (~below["bound"]).all() and (below["stated_upper_si"] > below["yaml_si"]).all(), below.to_string()


@pytest.mark.slow
@_REAL
@pytest.mark.parametrize("minutes", [30, 60])
def test_noise_densities_are_estimates_within_a_quarter_of_the_full_runs(minutes):
    """On the first 30- and 60-minute slice of each ADIS16405 run and on the full runs, neither noise density of
    the yaml is a bound, and each slice's is within NOISE_DENSITY_TOLERANCE (25 %) of the full run's
    (results/real/yaml_slices.md; ~10 min each)."""
    from avbench.studies.yaml_slices import _ND_KEYS, check_noise_density, yaml_rows

    rows = yaml_rows(Path(os.environ["AVBENCH_REAL_DATA"]), minutes, max_slices=1, full_rows=True)
    if rows.empty:
        pytest.skip("the ADIS16405 runs are not under AVBENCH_REAL_DATA")
    nd = rows[rows["key"].isin(_ND_KEYS)]
    assert len(nd) == 24 and not nd["bound"].any(), nd[nd["bound"]].to_string()
    assert check_noise_density(nd).all(), nd.to_string()


# -- the printed table ------------------------------------------------------------------------------
def test_shown_value_by_flag():
    from avbench.estimators.results import Coefficient
    from avbench.recordings.report import shown_value

    h = np.pi / 180 / 3600  # 1 deg/h in rad/s
    e = Coefficient("B", "ok", value=2.0 * h, interval=(1.0 * h, 3.0 * h))
    assert shown_value(e, "deg/h", "gyro") == "2 [1, 3]"
    assert shown_value(Coefficient("B", "not resolved", interval=(0.0, 4.0 * h), reason="record"), "deg/h",
                       "gyro") == "< 4"
    assert shown_value(Coefficient("B", "not resolved", reason="record"), "deg/h", "gyro") == "not resolved"
    assert shown_value(Coefficient("B", "ok", value=2.0 * h, std_err=0.5 * h), "deg/h", "gyro") == "2 (+- 0.5)"
    assert shown_value(Coefficient("B", "not modelled"), "deg/h", "gyro") == "-"
    assert shown_value(Coefficient("B", "ok", value=2.0 * h), "deg/h", "gyro") == "2 (no interval)"
    assert shown_value(e, "rad/s", "gyro") == f"{2.0 * h:.3g} [{1.0 * h:.3g}, {3.0 * h:.3g}]"


def test_a_poor_fit_takes_the_larger_of_its_interval_and_the_av_bound():
    rng = np.random.default_rng(8)
    dt, n = 0.01, 60_000
    x = 1e-3 / np.sqrt(dt) * rng.standard_normal(n) + np.cumsum(5e-5 * np.sqrt(dt) * rng.standard_normal(n))
    av = allan_variance(x, dt, "octave")
    tight = _payload({"x": _entry(1e-7, ci=(1e-8, 2e-7))}, poor=True)  # a poor model's interval far too low
    v, _, why = filter_yaml.filter_choices(tight, "m", avs={"gyro": {"x": (av, 1.0)}})["gyroscope_random_walk"]
    assert v == filter_yaml.av_bound("K", av) > 2e-7 and "the bound the AV allows is larger" in why
    v, _, why = filter_yaml.filter_choices(tight, "m")["gyroscope_random_walk"]  # without the AV: the interval
    assert v == 2e-7 and "poor" in why
