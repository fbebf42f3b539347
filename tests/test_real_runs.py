"""avbench.studies.real_runs plumbing on small generated recordings laid out like the real ones (no real data):
every gyro and accelerometer axis through the recordings pipeline, units per sensor, the
consistency table for both sensors, and one figure per sensor and axis."""

import math

import numpy as np
import pandas as pd
import pytest

from avbench.estimators.results import STATUSES
from avbench.noise_models.units import STANDARD_GRAVITY
from avbench.studies import real_runs

DT = 0.01
N_SAMPLES = 20_000
# white noise with known densities, in the files' units (deg/s for the gyro, g for the accelerometer)
GYRO_N = [2.0, 3.0, 4.0]  # deg/sqrt(h)
ACC_N = [0.1, 0.2, 0.3]  # m/s/sqrt(h)
COLUMNS = ["gyro_x_dps", "gyro_y_dps", "gyro_z_dps", "acc_x_g", "acc_y_g", "acc_z_g"]


def _white_sd(n_si):
    return n_si / math.sqrt(DT)  # white noise of density N has sample sd N / sqrt(dt)


@pytest.fixture(scope="module")
def layout(tmp_path_factory):
    root = tmp_path_factory.mktemp("real")
    (root / "adis16405-calgary").mkdir()
    (root / "mtig-cont-imu1").mkdir()
    rng = np.random.default_rng(2024)
    deg_per_rad = 180 / math.pi
    for i in (1, 2):
        cols = [rng.normal(0.4, _white_sd(math.radians(n) / 60) * deg_per_rad, N_SAMPLES) for n in GYRO_N]
        cols += [rng.normal(-1.0 if k == 2 else 0.0, _white_sd(n / 60) / STANDARD_GRAVITY, N_SAMPLES)
                 for k, n in enumerate(ACC_N)]
        np.savez(root / "adis16405-calgary" / f"adis_16405_imu{i}.npz", data=np.column_stack(cols), fs=100.0,
                 columns=np.array(COLUMNS))
    np.savez(root / "mtig-cont-imu1" / "cont_imu1.npz", data=rng.normal(0, _white_sd(math.radians(2) / 60), N_SAMPLES),
             fs=100.0, columns=np.array(["gyro_x"]))
    out = root / "out"
    assert real_runs.main(["--data", str(root), "--out", str(out), "--methods", "nnls_rel,slope_lines"]) == 0
    return root, out


def test_every_axis_of_both_sensors_with_its_units(layout):
    _, out = layout
    df = pd.read_csv(out / "coefficients.csv")
    got = df.groupby(["record", "sensor"])["axis"].unique().apply(sorted).to_dict()
    assert got == {("adis_16405_imu1", "gyro"): ["x", "y", "z"], ("adis_16405_imu1", "accel"): ["x", "y", "z"],
                   ("adis_16405_imu2", "gyro"): ["x", "y", "z"], ("adis_16405_imu2", "accel"): ["x", "y", "z"],
                   ("mtig_cont_imu1", "gyro"): ["x"]}
    units = df.drop_duplicates(["sensor", "coefficient"]).set_index(["sensor", "coefficient"])["unit"]
    assert units[("gyro", "N")] == "deg/sqrt(h)" and units[("gyro", "B")] == "deg/h"
    assert units[("accel", "N")] == "m/s/sqrt(h)" and units[("accel", "B")] == "ug"
    assert set(df["flag"]) <= set(STATUSES)
    assert "failed" not in set(df["flag"])


@pytest.mark.parametrize("sensor,column0,factor", [("gyro", 0, math.pi / 180), ("accel", 3, STANDARD_GRAVITY)])
def test_coefficients_are_the_estimator_on_the_si_samples_in_display_units(layout, sensor, column0, factor):
    # the same estimator on the file's columns converted by hand (deg/s -> rad/s, g -> m/s^2), its
    # N and B converted by hand to deg/sqrt(h), deg/h or m/s/sqrt(h), ug: equal to the 5 digits written
    from avbench import estimators
    root, out = layout
    df = pd.read_csv(out / "coefficients.csv")
    x = np.load(root / "adis16405-calgary" / "adis_16405_imu1.npz")["data"]
    to_display = {"gyro": {"N": 180 / math.pi * 60, "B": 180 / math.pi * 3600},
                  "accel": {"N": 60.0, "B": 1e6 / STANDARD_GRAVITY}}[sensor]
    for k, axis in enumerate("xyz"):
        est = estimators.get("slope_lines").fit(x[:, column0 + k] * factor, DT)
        for c in ("N", "B"):
            v = df[(df.record == "adis_16405_imu1") & (df.sensor == sensor) & (df.axis == axis)
                   & (df.method == "slope_lines") & (df.coefficient == c)]["value"].item()
            assert v == pytest.approx(est.coefficients_[c] * to_display[c], rel=1e-4), (sensor, axis, c)


def test_white_noise_density_comes_back(layout):
    # and on the simulated white noise N is the one simulated: a coarse check (slope lines read N off
    # the one octave whose slope is nearest -1/2, which on white noise may be a long, imprecise one;
    # fixed seed), enough to catch a units slip (a factor >= 1.7); the exact check is the test above
    _, out = layout
    df = pd.read_csv(out / "coefficients.csv")
    sub = df[(df.method == "slope_lines") & (df.coefficient == "N") & (df.record == "adis_16405_imu1")]
    for sensor, truth in (("gyro", GYRO_N), ("accel", ACC_N)):
        for axis, n in zip("xyz", truth):
            v = sub[(sub.sensor == sensor) & (sub.axis == axis)]["value"].item()
            assert abs(v / n - 1) < 0.2, (sensor, axis, v, n)
    v = df[(df.record == "mtig_cont_imu1") & (df.method == "slope_lines") & (df.coefficient == "N")]["value"].item()
    assert abs(v / 2.0 - 1) < 0.2  # the MTi-G file is taken as rad/s


def test_consistency_table_and_figures_for_both_sensors(layout):
    _, out = layout
    cons = pd.read_csv(out / "consistency.csv")
    assert set(cons["sensor"]) == {"gyro", "accel"}
    row = cons[(cons.sensor == "accel") & (cons.axis == "z") & (cons.method == "nnls_rel") & (cons.coefficient == "N")]
    assert row["n_runs"].item() == 2 and row["unit"].item() == "m/s/sqrt(h)"
    pngs = sorted(p.name for p in out.glob("*.png"))
    assert pngs == sorted([f"adis16405_{s}_{a}.png" for s in ("gyro", "accel") for a in "xyz"]
                          + ["mtig_cont_imu1_gyro_x.png"])


def test_tables_only_rebuilds_the_same_table(layout, tmp_path):
    root, out = layout
    before = (out / "consistency.csv").read_text()
    assert real_runs.main(["--data", str(root), "--out", str(out), "--tables-only"]) == 0
    assert (out / "consistency.csv").read_text() == before


def test_no_recordings_is_a_clear_error(tmp_path):
    with pytest.raises(SystemExit, match="no recordings found"):
        real_runs.main(["--data", str(tmp_path), "--out", str(tmp_path / "o")])


def test_slices_and_spectral_lines(layout, tmp_path):
    """--slices: the methods on slices, N and B judged against the plausible ranges, nothing outside
    unflagged counted; --lines: an injected 0.55 Hz sinusoid of 800 ug is found with its amplitude."""
    root, _ = layout
    sl = real_runs.slices(root, ["nnls_rel"], minutes=(1,), per_run=2)
    assert len(sl) == 2 * 3 * 2 and set(sl["minutes"]) == {1}  # 2 runs x 3 gyro axes x 2 slices
    # the generated gyros have N = 2, 3, 4 deg/sqrt(h): 4 lies outside 1.9-3.0
    assert not sl[sl.axis == "z"]["N_in_range"].any()
    for c in ("N", "B"):  # a value the record does not resolve carries its upper bound, and only such a value
        unresolved = sl[f"{c}_flag"] == "not resolved"
        assert (sl[f"{c}_upper"].notna() == unresolved).all() and (sl[f"{c}_upper"][unresolved] > 0).all()
    summary = real_runs.slice_summary(sl)
    assert summary["records"].sum() == len(sl)
    # the sinusoid
    data = tmp_path / "lines"
    (data / "adis16405-calgary").mkdir(parents=True)
    rng = np.random.default_rng(5)
    t = np.arange(N_SAMPLES) * DT
    cols = [rng.normal(0, 0.01, N_SAMPLES) for _ in range(3)]
    cols += [rng.normal(0, 1e-3, N_SAMPLES) + (800e-6 * np.sin(2 * np.pi * 0.55 * t + 1.0) if k == 0 else 0)
             for k in range(3)]
    np.savez(data / "adis16405-calgary" / "adis_16405_imu1.npz", data=np.column_stack(cols), fs=100.0,
             columns=np.array(COLUMNS))
    lines = real_runs.spectral_lines(data).set_index(["sensor", "axis"])
    acc_x = lines.loc[("accel", "x")]
    assert acc_x["f0_hz"] == pytest.approx(0.55, abs=0.005) and acc_x["amplitude"] == pytest.approx(800, rel=0.1)
    assert acc_x["prominence"] > 10 * lines.loc[("accel", "y")]["prominence"]


def test_slice_coverage_holds_the_whole_runs_value_against_its_interval(layout):
    """--slice-coverage: each slice's interval against the whole run's value, on the gyro and the accelerometer
    axes. White noise of known N: the truth as the "whole run" value is held by N's 95 % intervals in most of
    the 12 axis-slices of each sensor (binomial: 9 or more of 12 at 0.95 has probability 0.998), a value twice
    the truth by none; a coefficient with no whole-run value gives no verdict."""
    root, _ = layout
    rows = [{"record": f"adis_16405_imu{i}", "sensor": sensor, "axis": a, "method": "whittle_debiased",
             "coefficient": "N", "value": n, "flag": "ok"}
            for sensor, truth in (("gyro", GYRO_N), ("accel", ACC_N)) for i in (1, 2) for a, n in zip("xyz", truth)]
    whole = pd.DataFrame(rows)
    sc = real_runs.slice_coverage(root, ["whittle_debiased"], whole, minutes=1, first_minute=0.5, per_run=2)
    assert list(sc.columns[:-1]) == ["record", "axis", "start_min", "method", "coefficient", "unit", "value", "lower",
                                     "upper", "whole", "flag", "holds", "poor_fit"] and sc.columns[-1] == "sensor"
    for sensor, unit in (("gyro", "deg/sqrt(h)"), ("accel", "m/s/sqrt(h)")):
        n_rows = sc[(sc.coefficient == "N") & (sc.sensor == sensor)]
        assert len(n_rows) == 2 * 3 * 2 and n_rows["holds"].notna().all() and set(n_rows["unit"]) == {unit}
        assert n_rows["holds"].astype(bool).sum() >= 9, sensor
    assert sc[sc.coefficient != "N"]["holds"].isna().all()  # no whole-run value: no verdict
    summary = real_runs.slice_coverage_summary(sc).set_index(["sensor", "coefficient"])
    for sensor in ("gyro", "accel"):
        row = summary.loc[(sensor, "N")]
        assert row["axis_slices"] == 12 and row["share_lo"] <= row["share"]
    doubled = whole.assign(value=whole["value"] * 2)
    wrong = real_runs.slice_coverage(root, ["whittle_debiased"], doubled, minutes=1, first_minute=0.5, per_run=2)
    assert not wrong[wrong.coefficient == "N"]["holds"].astype(bool).any()
    gyro_only = real_runs.slice_coverage(root, ["whittle_debiased"], whole, minutes=1, first_minute=0.5, per_run=2,
                                         sensors=("gyro",))
    assert set(gyro_only["sensor"]) == {"gyro"} and len(gyro_only) == len(sc) // 2


def test_within_run_finds_a_level_that_moves_and_not_one_that_stays(tmp_path):
    """--within-run: a white-noise gyro of constant level passes the analysis of variance on every axis (six
    tests at p > 1e-4: a false alarm has probability < 1e-3), one whose level steps up by 10 % halfway
    through fails it (p < 1e-6) with a positive trend."""
    data = tmp_path / "wr"
    (data / "adis16405-calgary").mkdir(parents=True)
    rng = np.random.default_rng(8)
    n = 60_000
    step = np.where(np.arange(n) < n // 2, 1.0, 1.1)
    for i, gain in ((1, None), (2, step)):
        cols = [rng.normal(0, 0.01, n) * (gain if (gain is not None and k == 0) else 1.0) for k in range(3)]
        cols += [rng.normal(0, 1e-3, n) for _ in range(3)]
        np.savez(data / "adis16405-calgary" / f"adis_16405_imu{i}.npz", data=np.column_stack(cols), fs=100.0,
                 columns=np.array(COLUMNS))
    wr = real_runs.within_run(data, window_min=1.0, batch_min=0.1, first_minute=0.0).set_index(["record", "axis"])
    assert len(wr) == 6 and (wr["windows"] == 10).all()
    moved = wr.loc[("adis_16405_imu2", "x")]
    assert moved["p_value"] < 1e-6 and moved["trend_r"] > 0 and moved["n_drift_pct"] > 3 * moved["sampling_pct"]
    assert (wr.drop(("adis_16405_imu2", "x"))["p_value"] > 1e-4).all()
