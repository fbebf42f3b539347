"""``avbench three-cornered-hat`` reads three records as one experiment: aligned on their common instants
(or refused naming the one that shares none), the same channel in each, three distinct units, outputs
never over an input, the units told apart by their paths."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from avbench.cli import main

FS = 100.0
N = 20_000
SIGMA = {"a": 1e-3, "b": 2e-3, "c": 3e-3}


def _write(folder, offsets, constant_x=(), t0=0.0, names=None):
    """Three CSVs of a common motion (a random walk far above the units' noises, so that it cancels only
    on common instants) plus each unit's white noise of SIGMA, on two axes; unit k starts ``offsets[k]``
    samples into the motion and its stamps say so."""
    rng = np.random.default_rng(11)
    extra = max(offsets)
    common = np.cumsum(rng.standard_normal((N + extra, 2)) * 2e-2, axis=0)
    paths = []
    for k, (unit, s) in enumerate(SIGMA.items()):
        o = offsets[k]
        x = common[o:o + N] + s * rng.standard_normal((N, 2))
        if unit in constant_x:
            x[:, 0] = 0.25
        t = t0 + (o + np.arange(N)) / FS
        p = folder / (names[k] if names else f"{unit}.csv")
        p.parent.mkdir(parents=True, exist_ok=True)
        np.savetxt(p, np.column_stack([t, x]), delimiter=",", fmt="%.12g", comments="", header="t [s],gx [rad/s],gy [rad/s]")
        paths.append(str(p))
    return paths


def _first_tau(out, stem="a"):
    t = pd.read_csv(out / f"{stem}_hat.csv")
    return t[t["m"] == 1].set_index("unit")


@pytest.mark.parametrize("offsets", [(0, 0, 0), (0, 1, 0), (0, 0, 5000), (3, 0, 7)],
                         ids=["together", "one sample", "50 s", "mixed"])
def test_each_units_deviation_is_within_its_interval_however_the_records_are_offset(offsets, tmp_path, capsys):
    """Records starting 0, 1 sample, 50 s (5000 samples) later: on the instants all three share, each
    unit's deviation at the shortest tau holds its true sigma within its 99.9 % interval (paired by
    index, the common motion does not cancel and every unit comes out ~10 times its sigma)."""
    files = _write(tmp_path, offsets)
    assert main(["three-cornered-hat", *files, "--confidence", "0.999", "--axis", "x", "--out", str(tmp_path)]) == 0
    first = _first_tau(tmp_path)
    for unit, s in SIGMA.items():
        row = first.loc[f"{unit}.csv"]
        assert row["lower_dev"] <= s <= row["upper_dev"], (unit, row.to_dict())
    out = capsys.readouterr().out
    if max(offsets):
        assert "the instants all three have" in out


def test_records_without_a_common_instant_are_refused_naming_the_one(tmp_path, capsys):
    """C recorded at another time (epoch stamps an hour later): refused, naming C, nothing written."""
    files = _write(tmp_path, (0, 0, 0))
    late = pd.read_csv(files[2])
    late.iloc[:, 0] += 3600.0
    late.to_csv(files[2], index=False)
    assert main(["three-cornered-hat", *files, "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert f"C ({files[2]}) shares no instant with the other two" in err
    assert not (tmp_path / "out").exists()  # the folder the refused command created is removed


def test_the_same_channel_is_read_in_each_and_a_skipped_axis_is_said(tmp_path, capsys):
    """B's x axis is constant (skipped on reading): without --axis the hat is of y in all three (never B's
    y beside A's x), the header says y, and B's skipped x is said."""
    files = _write(tmp_path, (0, 0, 0), constant_x=("b",))
    assert main(["three-cornered-hat", *files, "--confidence", "0.999", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "three-cornered hat of gyro y" in out
    assert "B (" in out and "constant" in out
    first = _first_tau(tmp_path)
    for unit, s in SIGMA.items():
        row = first.loc[f"{unit}.csv"]
        assert row["lower_dev"] <= s <= row["upper_dev"], (unit, row.to_dict())
    assert main(["three-cornered-hat", *files, "--axis", "x", "--out", str(tmp_path)]) == 2
    assert f"--axis x: B ({files[1]})" in capsys.readouterr().err


def test_the_same_file_twice_is_refused_naming_both(tmp_path, capsys):
    files = _write(tmp_path, (0, 0, 0))
    for trio, (i, j) in (([files[0], files[0], files[0]], (1, 0)), ([files[0], files[1], files[1]], (2, 1))):
        assert main(["three-cornered-hat", *trio, "--out", str(tmp_path)]) == 2
        err = capsys.readouterr().err
        assert f"{'ABC'[i]} ({trio[i]}) is the same file as {'ABC'[j]} ({trio[j]})" in err


def test_a_gap_is_refused_naming_the_recording(tmp_path, capsys):
    files = _write(tmp_path, (0, 0, 0))
    gappy = pd.read_csv(files[1])
    gappy = gappy.drop(index=range(5000, 5100))
    gappy.to_csv(files[1], index=False)
    assert main(["three-cornered-hat", *files, "--out", str(tmp_path)]) == 2
    assert f"B ({files[1]}) has 1 gap(s)" in capsys.readouterr().err


def test_three_recordings_of_one_name_are_told_apart(tmp_path, capsys):
    """imu.csv in three folders: three columns, each with its own values (by its folder)."""
    files = _write(tmp_path, (0, 0, 0), names=["u1/imu.csv", "u2/imu.csv", "u3/imu.csv"])
    assert main(["three-cornered-hat", *files, "--confidence", "0.999", "--axis", "x", "--out", str(tmp_path)]) == 0
    first = _first_tau(tmp_path, "imu")
    for k, s in enumerate(SIGMA.values()):
        row = first.loc[f"u{k + 1}/imu.csv"]
        assert row["lower_dev"] <= s <= row["upper_dev"]
    assert "u1/imu.csv" in capsys.readouterr().out


def test_no_output_is_written_over_an_input(tmp_path, capsys):
    """``three-cornered-hat a.csv b.csv a_hat.csv --out <their folder>``: refused, input C unchanged."""
    files = _write(tmp_path, (0, 0, 0), names=["a.csv", "b.csv", "a_hat.csv"])
    before = (tmp_path / "a_hat.csv").read_bytes()
    assert main(["three-cornered-hat", *files, "--out", str(tmp_path)]) == 2
    assert "is the input recording" in capsys.readouterr().err
    assert (tmp_path / "a_hat.csv").read_bytes() == before
