"""The ``avbench estimate`` pipeline step by step (:mod:`avbench.recordings`): gap-aware Allan variance,
time stamps, readers, units, the Kalibr yaml, pooled recordings."""

from __future__ import annotations

import math

import numpy as np
import pytest

from avbench.estimators.allan.variance import allan_variance, allan_variance_gaps, skip_gaps
from avbench.noise_models import AngleRandomWalk, Gyro, RateRandomWalk
from avbench.noise_models.units import samples_to_si, to_si
from avbench.recordings import filter_yaml
from avbench.recordings.fit import agreement, fit_axis
from avbench.recordings.readers import read_recording
from avbench.recordings.timing import timing_of

# -- gap-aware Allan variance -------------------------------------------------------------------------


@pytest.mark.parametrize("overlapping", [True, False])
def test_one_run_is_the_ordinary_allan_variance(overlapping):
    x = np.random.default_rng(3).standard_normal(5000)
    a = allan_variance(x, 0.1, overlapping=overlapping)
    b = allan_variance_gaps(x, 0.1, [], overlapping=overlapping)
    np.testing.assert_array_equal(a.avar, b.avar)
    np.testing.assert_array_equal(a.J, b.J)
    np.testing.assert_allclose(a.edf, b.edf, rtol=1e-12)


def test_gaps_pool_the_runs_and_count_only_clusters_used():
    rng = np.random.default_rng(4)
    x, y = rng.standard_normal(3000), rng.standard_normal(1000)
    taus = [1.0, 600.0, 1000.0]
    g = allan_variance_gaps(np.concatenate([x, y]), 1.0, [3000], taus=taus, overlapping=False)
    a1, a2 = allan_variance(x, 1.0, taus=taus, overlapping=False), allan_variance(y, 1.0, taus=[1.0], overlapping=False)
    # m = 1: both runs; the squared differences are pooled, weighted by their number
    d1, d2 = a1.J[0] - 1, a2.J[0] - 1
    assert g.avar[0] == pytest.approx((a1.avar[0] * d1 + a2.avar[0] * d2) / (d1 + d2), rel=1e-12)
    assert g.J[0] == 1 + d1 + d2 and g.edf[0] == d1 + d2
    # m = 600 and 1000: only the first run holds two clusters
    assert g.avar[1] == pytest.approx(a1.avar[1], rel=1e-12) and g.J[1] == a1.J[1]
    assert g.avar[2] == pytest.approx(a1.avar[2], rel=1e-12) and g.edf[2] == a1.edf[2]


def test_gap_aware_av_is_unbiased_where_fill_and_ignore_are_not():
    """A gyro with angle and rate random walk, three gaps cutting 42 % of the record. Over 20 fixed
    seeds, the mean ratio to the exact AV of the generator must lie within 4 standard errors of 1
    at every octave tau for the gap-aware AV (13 correlated taus: a family-wise bound), while
    concatenating the runs ("ignore the gaps") and filling the gaps with the mean are each off by
    more than 4 standard errors somewhere (the bias walks on during the gap)."""
    g = Gyro(dt=0.1, terms=[AngleRandomWalk(N=1e-3), RateRandomWalk(K=1e-4)])
    n, R = 60_000, 20
    keep = np.ones(n, bool)
    for a, b in [(10_000, 20_000), (30_000, 40_000), (45_000, 50_000)]:
        keep[a:b] = False
    starts = np.flatnonzero(np.diff(np.flatnonzero(keep)) > 1) + 1
    ratios = {"gaps": [], "ignore": [], "fill": []}
    for r in range(R):
        x = g.simulate(n, np.random.default_rng(r))
        y = x[keep]
        av = allan_variance_gaps(y, 0.1, starts)
        exact = g.avar(av.tau)
        ratios["gaps"].append(av.avar / exact)
        ratios["ignore"].append(allan_variance(y, 0.1, taus=av.tau).avar / exact)
        ratios["fill"].append(allan_variance(np.where(keep, x, y.mean()), 0.1, taus=av.tau).avar / exact)
    z = {}
    for k, v in ratios.items():
        v = np.array(v)
        z[k] = (v.mean(0) - 1) / (v.std(0, ddof=1) / math.sqrt(R))
    assert np.all(np.abs(z["gaps"]) < 4), z["gaps"]
    assert np.max(np.abs(z["ignore"])) > 4, z["ignore"]
    assert np.max(np.abs(z["fill"])) > 4, z["fill"]


def test_skip_gaps_reaches_the_estimators_and_spares_other_arrays():
    x = np.random.default_rng(5).standard_normal(4000)
    other = x.copy()
    with skip_gaps(x, [1500, 3000]):  # runs of 1500, 1500, 1000: octave m up to 512
        assert allan_variance(x, 1.0).avar[-1] == allan_variance_gaps(x, 1.0, [1500, 3000]).avar[-1]
        assert allan_variance(x, 1.0).m.max() == 512
        assert allan_variance(other, 1.0).m.max() == 1024  # same values, another object: no gaps
    assert allan_variance(x, 1.0).m.max() == 1024


def test_fit_axis_skips_gaps_or_uses_the_longest_run():
    x = np.random.default_rng(6).standard_normal(6000) * 1e-3
    fits = fit_axis(x, 0.01, np.array([1000, 2500]), ["nnls_rel", "shakf"])
    assert fits["nnls_rel"].run is None and fits["nnls_rel"].error is None
    assert fits["shakf"].run == (2500, 3500)


@pytest.mark.parametrize("scale", [2.0**-700, 2.0**900])
def test_fits_scale_exactly_with_the_data(scale):
    """Records far from unit magnitude are fitted at unit magnitude (times a power of two): the
    estimates of x * 2^k are those of x times 2^k, to the last digit, however far apart the k."""
    x = np.random.default_rng(7).standard_normal(4000) * 2.0**-300
    ref = fit_axis(x, 0.01, [], ["nnls_rel"])["nnls_rel"].coefficients()
    got = fit_axis(x * scale, 0.01, [], ["nnls_rel"])["nnls_rel"].coefficients()
    assert ref["N"] > 0
    for c in ref:
        if math.isfinite(ref[c]):
            assert got[c] == ref[c] * scale, c


# -- time stamps --------------------------------------------------------------------------------------


def test_timing_rate_jitter_gaps_and_fs_conflict():
    rng = np.random.default_rng(8)
    t = np.arange(1000) * 0.01 + rng.uniform(-1e-4, 1e-4, 1000)
    t[600:] += 2.0
    tm = timing_of(t, None, 1000, "f")
    assert tm.dt == pytest.approx(0.01, rel=1e-3) and tm.starts.tolist() == [600]
    assert tm.gap_seconds[0] == pytest.approx(2.0, abs=1e-3)
    assert 0.003 < tm.jitter < 0.02  # uniform +-1 % of dt on both ends: std of the difference ~0.8 %
    assert timing_of(t, 100.5, 1000, "f").dt == tm.dt  # within 1 %: a check only
    with pytest.raises(ValueError, match="--fs 200: conflicts with the time stamps of f"):
        timing_of(t, 200.0, 1000, "f")
    with pytest.raises(ValueError, match="do not increase at sample 3"):
        timing_of(np.array([0.0, 1, 2, 2, 3]), None, 5, "f")
    with pytest.raises(ValueError, match="--fs: f has no time stamps"):
        timing_of(None, None, 10, "f")
    with pytest.raises(ValueError, match="at most 1e\\+09 Hz"):
        timing_of(None, 1e300, 10, "f")


# -- readers ------------------------------------------------------------------------------------------


def test_text_reader_finds_time_and_axes(tmp_path):
    x = np.random.default_rng(9).standard_normal((100, 6))
    f = tmp_path / "imu.csv"
    np.savetxt(f, np.column_stack([np.arange(100) * 0.01, x]), delimiter=",",
               header="time,gyro_x,gyro_y,gyro_z,acc_x,acc_y,acc_z", comments="")
    rec = read_recording(f)
    assert [(c.sensor, c.axis) for c in rec.channels] == [("gyro", a) for a in "xyz"] + [("accel", a) for a in "xyz"]
    np.testing.assert_allclose(rec.channels[4].values, x[:, 4], rtol=1e-15)
    assert rec.time_source.startswith("column 'time'")


def test_text_decimal_comma_with_semicolons_is_read_and_with_commas_refused(tmp_path):
    f = tmp_path / "eu.csv"
    f.write_text("t;gx\n" + "".join(f"{i / 100:.2f};{v:.6f}\n".replace(".", ",") for i, v in enumerate(np.linspace(-1, 1, 40))))
    rec = read_recording(f)
    np.testing.assert_allclose(rec.channels[0].values, np.round(np.linspace(-1, 1, 40), 6))
    g = tmp_path / "dc.csv"
    g.write_text("".join(f"0,{k:04d}\n" for k in range(123, 163)))
    with pytest.raises(ValueError, match="decimal commas"):
        read_recording(g)


def test_npz_columns_must_match(tmp_path):
    f = tmp_path / "a.npz"
    np.savez(f, data=np.zeros((40, 2)), columns=np.array(["a", "b", "c"]))
    with pytest.raises(ValueError, match="'columns' names 3 column"):
        read_recording(f)
    np.savez(f, data=np.zeros((40, 2)), columns=np.array("ab"))
    with pytest.raises(ValueError, match="'columns' is a 0-d array"):
        read_recording(f)


def test_readers_keep_their_public_names():
    """avbench.recordings.readers is the one entry point; the readers live by kind of file."""
    from avbench.recordings import readers

    for name in ("Channel", "Recording", "read_recording", "header_unit", "time_in_seconds", "TEXT_SUFFIXES",
                 "KNOWN_SUFFIXES"):
        assert hasattr(readers, name) and name in readers.__all__
    assert readers.Recording.__module__ == "avbench.recordings.channels"


# -- loading: read, time, SI in one call ---------------------------------------------------------------


def _csv(path, n=2000, seed=9):
    x = np.random.default_rng(seed).standard_normal((n, 2))
    np.savetxt(path, np.column_stack([np.arange(n) * 0.01, x]), delimiter=",",
               header="t [s],gx [deg/s],ax [g]", comments="")
    return x


def test_load_recording_gives_si_sensors_timing_and_notes(tmp_path):
    from avbench.recordings import load_recording

    x = _csv(tmp_path / "r.csv")
    loaded = load_recording(tmp_path / "r.csv")
    rec, timing, sensors = loaded  # a tuple too
    assert rec is loaded.recording and timing is loaded.timing and loaded.notes is rec.notes
    assert loaded.path == tmp_path / "r.csv"
    assert timing.fs == pytest.approx(100.0) and timing.n_gaps == 0
    assert [(s.sensor, s.unit_in, list(s.axes)) for s in sensors] == [("gyro", "deg/s", ["x"]), ("accel", "g", ["x"])]
    np.testing.assert_allclose(sensors[0].axes["x"], np.deg2rad(x[:, 0]), rtol=1e-12)
    np.testing.assert_allclose(sensors[1].axes["x"], x[:, 1] * 9.80665, rtol=1e-12)
    only = load_recording(tmp_path / "r.csv", column="gx", time="none", fs=50)
    assert [s.sensor for s in only.sensors] == ["gyro"] and only.timing.fs == 50.0
    with pytest.raises(ValueError, match="either --column or --gyro"):
        load_recording(tmp_path / "r.csv", column="gx", gyro="gx")
    with pytest.raises(ValueError, match="--fs: expected a positive"):
        load_recording(tmp_path / "r.csv", fs=-1)
    with pytest.raises(TypeError):
        load_recording(tmp_path / "r.csv", colum="gx")  # a misspelt option is no option


def test_pool_recordings_makes_file_boundaries_gaps(tmp_path):
    from avbench.recordings.load import load_recording, pool_recordings

    _csv(tmp_path / "a.csv", 1000, 1)
    _csv(tmp_path / "b.csv", 1500, 2)
    loaded = [load_recording(tmp_path / f) for f in ("a.csv", "b.csv")]
    timing, sensors = pool_recordings(loaded)
    assert timing.n_samples == 2500 and list(timing.starts) == [1000] and np.isnan(timing.gap_seconds[0])
    assert sensors[0].axes["x"].size == 2500
    np.testing.assert_array_equal(sensors[0].axes["x"][1000:], loaded[1].sensors[0].axes["x"])


def test_estimate_file_docstring_example_runs():
    import doctest
    import time

    from avbench.recordings import estimate

    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS)
    (test,) = doctest.DocTestFinder().find(estimate.estimate_file, "estimate_file", globs={})
    t0 = time.perf_counter()
    result = runner.run(test)
    assert result.failed == 0 and result.attempted > 5
    assert time.perf_counter() - t0 < 10  # about a second; a generous bound on a busy machine


def test_estimate_file_refuses_unknown_methods_and_settings(tmp_path):
    from avbench.recordings import estimate_file

    _csv(tmp_path / "r.csv")
    with pytest.raises(ValueError, match="--method"):
        estimate_file(tmp_path / "r.csv", methods=["no_such_method"])
    with pytest.raises(ValueError, match="'gmwm' is not among the methods"):
        estimate_file(tmp_path / "r.csv", methods="wls", settings={"gmwm": {}})
    fits = estimate_file(tmp_path / "r.csv", methods="wls", column="gx")
    assert list(fits) == ["gyro"] and list(fits["gyro"]["x"]) == ["wls"]


# -- units and the filter yaml -------------------------------------------------------------------------


def test_accelerometer_units():
    assert samples_to_si(1.0, "g", "accel") == 9.80665
    assert to_si("N", 1.0, "m/s/sqrt(h)", "accel") == pytest.approx(1 / 60)
    assert to_si("B", 1.0, "ug", "accel") == pytest.approx(9.80665e-6)
    with pytest.raises(ValueError, match="unknown unit 'deg/h' for accel coefficient B"):
        to_si("B", 1.0, "deg/h", "accel")
    x = np.ones(3)
    assert samples_to_si(x, "rad/s") is x  # no copy for a factor of one


def _payload(values):
    """``{sensor: {axis: {"m": FitResult}}}`` with these (N, K), None for a term not modelled."""
    from avbench.estimators.results import Coefficient, FitResult

    def coef(name, v):
        return Coefficient(name, "ok", value=v) if v is not None else Coefficient(name, "not modelled")

    def axis(n, k):
        return {"m": FitResult(method="m", coefficients={"N": coef("N", n), "K": coef("K", k)})}
    return {s: {a: axis(*values[s][a]) for a in values[s]} for s in values}


def test_kalibr_values_take_the_largest_axis_and_refuse_gaps_in_the_model():
    data = _payload({"gyro": {"x": (1e-4, 1e-6), "y": (2e-4, 5e-7)}, "accel": {"x": (1e-3, 1e-5)}})
    v = filter_yaml.filter_values(data, "m")
    assert v["gyroscope_noise_density"] == (2e-4, "y") and v["gyroscope_random_walk"] == (1e-6, "x")
    text = filter_yaml.kalibr_yaml(v, 200.0, "/imu", "m", ["b"], inflate=(2.0, 10.0))
    import yaml

    y = yaml.safe_load(text)
    assert y["gyroscope_noise_density"] == pytest.approx(4e-4) and y["gyroscope_random_walk"] == pytest.approx(1e-5)
    assert y["rostopic"] == "/imu" and y["update_rate"] == 200
    with pytest.raises(ValueError, match="--kalibr: m gives no K for gyro axis x"):
        filter_yaml.filter_values(_payload({"gyro": {"x": (1e-4, None)}, "accel": {"x": (1e-3, 1e-5)}}), "m")
    with pytest.raises(ValueError, match="no accelerometer channels"):
        filter_yaml.filter_values(_payload({"gyro": {"x": (1e-4, 1e-6)}}), "m")
    with pytest.raises(ValueError, match="--inflate"):
        filter_yaml.parse_inflate("0")


# -- several recordings ---------------------------------------------------------------------------------


def test_agreement_of_recordings():
    g = Gyro(dt=0.01, terms=[AngleRandomWalk(N=1e-3)])
    a, b = g.simulate(20_000, np.random.default_rng(10)), g.simulate(20_000, np.random.default_rng(11))
    same = agreement([(a, []), (b, [])], 0.01)
    assert same["agree"] and same["p_value"] > 0.01
    other = agreement([(a, []), (2 * b, [])], 0.01)  # four times the AV
    assert other["agree"] is False and other["p_value"] < 1e-6
