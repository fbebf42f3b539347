"""The shapes of files users have: EuRoC / TUM-VI / Kalibr CSV, named arrays in .npz, MATLAB
.mat v5 and v7.3, read into the same coefficients as the plain .npy of the same samples, with no flags
where the file states names and units; the first error names the root cause, from the file to the fit."""

from __future__ import annotations

import itertools
import json

import numpy as np
import pytest
from avbench.cli import main
from avbench.recordings.readers import header_unit, read_recording

N = 6_000
T0_NS = 1_403_636_579_758_555_392  # EuRoC MH_01's first stamp
GAP_AT = 3_500
HEADER = ("#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],w_RS_S_z [rad s^-1],"
          "a_RS_S_x [m s^-2],a_RS_S_y [m s^-2],a_RS_S_z [m s^-2]")


@pytest.fixture(scope="module")
def imu():
    """(ns stamps with a 5-sample gap, gyro n x 3 rad/s, accel n x 3 m/s^2): white noise, a random walk,
    gravity."""
    rng = np.random.default_rng(28)
    t = T0_NS + np.arange(N, dtype=np.int64) * 10_000_000
    t[GAP_AT:] += 50_000_000
    gyro = 2e-3 * rng.standard_normal((N, 3)) + np.cumsum(1e-5 * rng.standard_normal((N, 3)), axis=0)
    accel = 1e-2 * rng.standard_normal((N, 3)) + np.array([0.1, -0.2, 9.8])
    return t, gyro, accel


def _seconds(t):
    return (t - t[0]).astype(np.float64) * 1e-9  # what every reader makes of int64 ns stamps


def _write_euroc(path, t, gyro, accel, header=HEADER, extra_line=None):
    rows = [f"{t[i]}," + ",".join(repr(float(v)) for v in (*gyro[i], *accel[i])) for i in range(len(t))]
    if extra_line is not None:
        rows.insert(len(rows) // 2, extra_line)
    path.write_text(header + "\n" + "\n".join(rows) + "\n")
    return path


def _estimate(args, capsys):
    assert main(["estimate", *map(str, args), "--method", "wls", "--json", "--no-progress"]) == 0, capsys.readouterr().err
    return json.loads(capsys.readouterr().out)


def _coefficients(payload):
    """[(sensor, axis number, coefficient, SI value)] (axis labels differ between shapes: x or 1)."""
    return [(s, i, c, e["si"]) for s, sd in payload["sensors"].items() for i, ad in enumerate(sd["axes"].values())
            for c, e in ad["methods"]["wls"]["coefficients"].items()]


@pytest.fixture(scope="module")
def reference(imu, tmp_path_factory):
    """The plain .npy of the same samples (time in s, seconds from the same int64 difference), every
    column named by hand."""
    t, gyro, accel = imu
    d = tmp_path_factory.mktemp("ref")
    f = d / "plain.npy"
    np.save(f, np.column_stack([_seconds(t), gyro, accel]))
    return f, d


def _pipeline(path, units=None, accel_units=None, **read):
    """The steps of avbench estimate up to the fits (read, timing, SI, wls on every axis), without the
    figures: [(sensor, axis number, coefficient, SI value)] and the gaps."""
    from avbench.recordings.fit import fit_axis
    from avbench.recordings.sensors import to_si
    from avbench.recordings.timing import timing_of

    rec = read_recording(path, **read)
    timing = timing_of(rec.time, None, rec.n_samples, rec.path)
    out = []
    for s in to_si(rec, units, accel_units):
        for i, x in enumerate(s.axes.values()):
            coefs = fit_axis(x, timing.dt, timing.starts, ["wls"])["wls"].coefficients()
            out += [(s.sensor, i, c, v) for c, v in coefs.items()]
    return out, timing.starts.tolist()


def test_every_shape_gives_the_plain_npy_coefficients(imu, reference, tmp_path, capsys):
    t, gyro, accel = imu
    f, d = reference
    want, gaps = _pipeline(f, "rad/s", "m/s^2", time_column=0, gyro="1,2,3", accel="4,5,6")
    assert gaps == [GAP_AT]
    assert any(v for *_, v in want)

    euroc = _write_euroc(tmp_path / "imu0.csv", t, gyro, accel)
    got = _estimate([euroc, "--out", tmp_path / "o1"], capsys)  # no flag: the file states names and units
    assert [g["before_sample"] for g in got["timing"]["gaps"]] == [GAP_AT]
    assert [v if v is not None else None for *_, v in _coefficients(got)] == \
        [v if np.isfinite(v) else None for *_, v in want]
    # the table written beside the JSON: every coefficient the method gives with an interval is shown with it
    import pandas as pd

    table = pd.read_csv(tmp_path / "o1" / "imu0_coefficients.csv", index_col=[0, 1, 2, 3], keep_default_na=False)
    for sensor, sd in got["sensors"].items():
        for axis, ad in sd["axes"].items():
            for c, e in ad["methods"]["wls"]["coefficients"].items():
                cell = table.loc[(sensor, axis, "wls", c), "shown"]
                if e["flag"] == "ok" and e.get("interval_si") and e["interval_si"][0] > 0:
                    assert cell.endswith("]") and " [" in cell, cell
                elif e["flag"] == "not modelled":
                    assert cell == "-"

    npz = tmp_path / "named.npz"
    np.savez(npz, gyro=gyro, accel=accel, t=_seconds(t))
    assert _same(_pipeline(npz, "rad/s", "m/s^2"), (want, gaps))
    npz2 = tmp_path / "other_names.npz"
    np.savez(npz2, w=gyro.T.copy(), f=accel, stamps=_seconds(t))  # 3 x n, names a user chose
    assert _same(_pipeline(npz2, "rad/s", "m/s^2", gyro="w", accel="f", time_column="stamps"), (want, gaps))

    import scipy.io

    mat = tmp_path / "imu_v5.mat"
    scipy.io.savemat(mat, {"imu": {"gyro": gyro, "accel": accel}, "t": _seconds(t)[:, None]})
    assert _same(_pipeline(mat, "rad/s", "m/s^2"), (want, gaps))


def _same(a, b) -> bool:
    """Equal lists of coefficients (NaN equal to NaN) and equal gaps."""
    (ca, ga), (cb, gb) = a, b
    return ga == gb and len(ca) == len(cb) and all(
        x[:3] == y[:3] and (x[3] == y[3] or (np.isnan(x[3]) and np.isnan(y[3]))) for x, y in zip(ca, cb))


def test_mat_v73_through_h5py(imu, reference, tmp_path):
    h5py = pytest.importorskip("h5py", reason="h5py is not installed: MATLAB v7.3 files need pip install 'avbench[mat73]'")
    t, gyro, accel = imu
    f, d = reference
    want = _pipeline(f, "rad/s", "m/s^2", time_column=0, gyro="1,2,3", accel="4,5,6")
    mat = tmp_path / "imu_v73.mat"
    with h5py.File(mat, "w", userblock_size=512) as h:  # as MATLAB writes it: HDF5 after a 512-byte header,
        for name, a in (("gyro", gyro), ("accel", accel), ("t", _seconds(t)[:, None])):  # arrays transposed
            ds = h.create_dataset(name, data=np.ascontiguousarray(a.T))
            ds.attrs["MATLAB_class"] = np.bytes_(b"double")
    with open(mat, "r+b") as fh:
        fh.write(b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Wed Nov 25 04:00:00 2026 HDF5 schema 1.00 .")
    assert _same(_pipeline(mat, "rad/s", "m/s^2"), want)


def test_ambiguous_variables_are_listed(tmp_path):
    x = np.zeros((100, 3))
    p = tmp_path / "two.npz"
    np.savez(p, gyro=x, omega=x, t=np.arange(100.0))
    with pytest.raises(ValueError, match=r"more than one gyro-like.*found gyro \(100x3 float64\), omega \(100x3"):
        read_recording(p)
    p2 = tmp_path / "anon.npz"
    np.savez(p2, foo=x, bar=x)
    with pytest.raises(ValueError, match=r"no variable named like a gyro.*foo \(100x3 float64\).*--gyro NAME"):
        read_recording(p2)
    with pytest.raises(ValueError, match=r"no variable 'baz' \(--gyro\); found foo"):
        read_recording(p2, gyro="baz")


@pytest.mark.parametrize("spelling, kind, unit", [
    ("[rad s^-1]", "gyro", "rad/s"), ("[rad/s]", "gyro", "rad/s"), ("(deg/s)", "gyro", "deg/s"), ("[°/s]", "gyro", "deg/s"),
    ("[dps]", "gyro", "deg/s"), ("[m s^-2]", "accel", "m/s^2"), ("[m/s2]", "accel", "m/s^2"), ("[g]", "accel", "g"),
    ("[mg]", "accel", "mg"), ("[ns]", "time", "ns"), ("[µs]", "time", "us"), ("[s]", "time", "s"), ("[degC]", "temperature", "degC"),
    ("[G]", "magnetic", "G"), ("[mG]", "magnetic", "mG"), ("[RAD/S]", "gyro", "rad/s"), ("[MG]", None, None),
    ("[furlong]", None, None)])
def test_header_units(spelling, kind, unit):
    assert header_unit(f"name_x {spelling}")[1:] == (kind, unit)


# -- the first error names the root cause ----------------------------------------------------------
#: defects from the file to the fit, each with the words its message must hold
DEFECTS = ["file", "column", "time", "units", "yaml"]
WORDS = {"file": "field(s) where the table has 7", "column": "unknown column 'nosuch'",
         "time": "time stamps", "units": "defines its gyro samples in rad/s", "yaml": "no accelerometer channels"}


@pytest.mark.parametrize("defects", [c for k in range(1, 6) for c in itertools.combinations(DEFECTS, k)],
                         ids=lambda c: "+".join(c))
def test_first_error_is_the_earliest_defect(imu, tmp_path, capsys, defects):
    t, gyro, accel = imu
    n = 300
    f = _write_euroc(tmp_path / "imu0.csv", t[:n], gyro[:n], accel[:n],
                     extra_line="1,2" if "file" in defects else None)
    gyro_cols = "w_RS_S_x,w_RS_S_y,w_RS_S_z" + (",nosuch" if "column" in defects else "")
    args = ["estimate", str(f), "--gyro", gyro_cols, "--kalibr", str(tmp_path / "imu.yaml"),
            "--out", str(tmp_path / "o"), "--no-progress", "--method", "wls"]
    if "yaml" not in defects:
        args += ["--accel", "a_RS_S_x,a_RS_S_y,a_RS_S_z"]
    if "time" in defects:
        args += ["--time-units", "s"]  # ns stamps read as seconds: 1e7 s apart
    if "units" in defects:
        args += ["--units", "deg/s"]
    assert main(args) == 2
    err = capsys.readouterr().err
    first = next(d for d in DEFECTS if d in defects)
    assert WORDS[first] in err, (first, err)
    assert not (tmp_path / "imu.yaml").exists()


def test_the_benchmark_record_reads_with_no_flag(tmp_path):
    """bench/estimate_e2e's EuRoC-style CSV: names, units and ns stamps from its header alone."""
    from avbench.bench.estimate_e2e import write_euroc
    from avbench.recordings.sensors import to_si
    from avbench.recordings.timing import timing_of

    f = write_euroc(tmp_path / "imu0.csv", 30 / 3600, 100.0)
    rec = read_recording(f)
    assert [(c.sensor, c.axis, c.unit) for c in rec.channels] == \
        [("gyro", a, "rad/s") for a in "xyz"] + [("accel", a, "m/s^2") for a in "xyz"]
    timing = timing_of(rec.time, None, rec.n_samples, rec.path)
    assert rec.n_samples == 3000 and timing.dt == pytest.approx(0.01, rel=1e-12) and timing.n_gaps == 0
    assert [s.sensor for s in to_si(rec)] == ["gyro", "accel"]
