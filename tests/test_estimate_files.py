"""``avbench estimate`` through a real subprocess: ROS 1 / ROS 2 bags with a gap to a Kalibr yaml, and
the input/output edges: each ends with exit code 2, a one-line error naming the file or
option and what was expected, and nothing written -- or, where the input is valid, a right answer."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

FS = 200.0
ENV = {**os.environ, "MPLBACKEND": "Agg"}


def avbench(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "avbench.cli", "estimate", *map(str, args)], capture_output=True,
                          text=True, cwd=cwd, env=ENV, timeout=600)


def _imu(n, seed):
    rng = np.random.default_rng(seed)
    gyro = 1e-3 * rng.standard_normal((n, 3))  # N = 1e-3 / sqrt(200) rad/sqrt(s)
    acc = np.array([0.0, 0.0, 9.81]) + 1e-2 * rng.standard_normal((n, 3))
    return gyro, acc


def write_imu_bag(path, kind, gyro, acc, t_ns, topic="/imu", frame_id="imu"):
    """A bag of sensor_msgs/Imu written by rosbags' own writer (ROS 2: sqlite3 storage)."""
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE if kind == "ros2" else Stores.ROS1_NOETIC)
    T = ts.types
    Imu = T["sensor_msgs/msg/Imu"]
    cov = np.zeros(9)
    if kind == "ros2":
        from rosbags.rosbag2 import Writer

        writer, ser = Writer(path, version=9), ts.serialize_cdr
    else:
        from rosbags.rosbag1 import Writer

        writer, ser = Writer(path), ts.serialize_ros1
    with writer:
        conn = writer.add_connection(topic, Imu.__msgtype__, typestore=ts)
        for i, t in enumerate(int(v) for v in t_ns):
            stamp = T["builtin_interfaces/msg/Time"](sec=t // 10**9, nanosec=t % 10**9)
            hdr = (T["std_msgs/msg/Header"](stamp=stamp, frame_id=frame_id) if kind == "ros2"
                   else T["std_msgs/msg/Header"](seq=i, stamp=stamp, frame_id=frame_id))
            V = T["geometry_msgs/msg/Vector3"]
            msg = Imu(header=hdr, orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
                      orientation_covariance=cov, angular_velocity=V(*gyro[i]), angular_velocity_covariance=cov,
                      linear_acceleration=V(*acc[i]), linear_acceleration_covariance=cov)
            writer.write(conn, t, ser(msg, Imu.__msgtype__))


@pytest.mark.parametrize("kind", ["ros2", "ros1"])
def test_bag_with_a_gap_to_kalibr_yaml(tmp_path, kind):
    pytest.importorskip("rosbags")
    yaml = pytest.importorskip("yaml")
    n = 3000
    gyro, acc = _imu(n, 1 if kind == "ros2" else 2)
    t = (1_700_000_000 * 10**9 + np.arange(n) * int(1e9 / FS)).astype(np.int64)
    t[1800:] += 2 * 10**9  # a 2 s gap (400 samples missing)
    bag = tmp_path / ("imu_bag" if kind == "ros2" else "imu.bag")
    write_imu_bag(bag, kind, gyro, acc, t)
    out, kal = tmp_path / "out", tmp_path / "cfg" / "imu.yaml"
    r = avbench(bag, "--topic", "/imu", "--kalibr", kal, "--method", "nnls_rel,ols", "--json", "--out", out)
    assert r.returncode == 0, r.stderr
    data = json.loads(r.stdout)
    assert data["timing"]["rate_hz"] == pytest.approx(FS) and len(data["timing"]["gaps"]) == 1
    assert data["timing"]["gaps"][0]["missing_s"] == pytest.approx(2.0, rel=1e-6)
    assert data["sensors"]["gyro"]["units_in"] == "rad/s" and data["sensors"]["accel"]["units_in"] == "m/s^2"
    # every axis: the estimator's own answer on the same samples with the gap skipped (the CLI adds
    # nothing and loses nothing), and the right order of magnitude (white noise of std s at 200 Hz:
    # N = s / sqrt(200); five free terms on 3000 samples split white noise between Q and N)
    from avbench import estimators
    from avbench.estimators.allan.variance import skip_gaps

    for sensor, arr, s in (("gyro", gyro, 1e-3), ("accel", acc, 1e-2)):
        axes = data["sensors"][sensor]["axes"]
        assert set(axes) == {"x", "y", "z"}
        for j, a in enumerate("xyz"):
            x = np.ascontiguousarray(arr[:, j])
            with skip_gaps(x, [1800]):
                direct = estimators.get("nnls_rel").fit(x, 1 / FS).coefficients_["N"]
            n_si = axes[a]["methods"]["nnls_rel"]["coefficients"]["N"]["si"]
            assert n_si == pytest.approx(direct, rel=1e-9)
            assert 0.5 < n_si / (s / math.sqrt(FS)) < 1.5
    k = yaml.safe_load(kal.read_text())
    for key in ("accelerometer_noise_density", "accelerometer_random_walk", "gyroscope_noise_density",
                "gyroscope_random_walk", "update_rate"):
        assert isinstance(k[key], float), (key, k[key])  # PyYAML (Kalibr's reader) sees numbers
    assert k["rostopic"] == "/imu" and k["update_rate"] == pytest.approx(FS)
    assert k["gyroscope_noise_density"] == max(a["methods"]["nnls_rel"]["coefficients"]["N"]["si"]
                                               for a in data["sensors"]["gyro"]["axes"].values())
    assert sorted(p.name for p in out.iterdir()) == sorted(
        [f"{bag.stem}_gyro_av.png", f"{bag.stem}_accel_av.png", f"{bag.stem}_av.csv",
         f"{bag.stem}_coefficients.csv", f"{bag.stem}_coefficients.json"])


@pytest.mark.parametrize("kind", ["ros2", "ros1"])
@pytest.mark.parametrize("frame_id", ["", "imu_link7", "base"])
def test_fast_bag_decoding_equals_rosbags_deserializer(tmp_path, kind, frame_id):
    """The vectorised decoding of sensor_msgs/Imu bytes gives what rosbags' deserializer gives, for
    frame ids whose lengths need different CDR padding."""
    pytest.importorskip("rosbags")
    from rosbags.highlevel import AnyReader

    from avbench.recordings.bags import _decode_imu, _deserialize_imu

    gyro, acc = _imu(50, 7)
    bag = tmp_path / ("b" if kind == "ros2" else "b.bag")
    write_imu_bag(bag, kind, gyro, acc, 1_700_000_000 * 10**9 + np.arange(50) * 5_000_123, frame_id=frame_id)
    with AnyReader([bag]) as reader:
        block = list(reader.messages())
        fast = _decode_imu([raw for _, _, raw in block], kind == "ros1")
        slow = _deserialize_imu(reader, block)
    assert fast is not None
    np.testing.assert_array_equal(fast[0], slow[0])
    np.testing.assert_array_equal(fast[1], slow[1])
    np.testing.assert_array_equal(slow[0], np.column_stack([gyro, acc]))


def test_bag_units_are_the_message_definition(tmp_path):
    pytest.importorskip("rosbags")
    gyro, acc = _imu(200, 3)
    bag = tmp_path / "b.bag"
    write_imu_bag(bag, "ros1", gyro, acc, np.arange(200) * 5_000_000 + 10**9)
    r = avbench(bag, "--units", "deg/s", "--out", tmp_path / "o")
    assert r.returncode == 2 and "--units deg/s" in r.stderr and "rad/s" in r.stderr
    r = avbench(bag, "--topic", "/nope", "--out", tmp_path / "o")
    assert r.returncode == 2 and "--topic '/nope'" in r.stderr and "/imu" in r.stderr
    assert not (tmp_path / "o").exists()


# -- the edges -----------------------------------------------------------------------------------------

X = np.random.default_rng(0).standard_normal(400)


def _fail(r, *words):
    assert r.returncode == 2, (r.returncode, r.stderr)
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("avbench: error: "), r.stderr
    for w in words:
        assert w in lines[0], (w, lines[0])
    assert r.stdout == ""


def _untouched(out):
    assert not out.exists() or not [p for p in out.iterdir()], list(out.iterdir())


@pytest.mark.parametrize("case", ["longer", "0-d"])
def test_npz_columns_edges(tmp_path, case):
    f = tmp_path / "r.npz"
    np.savez(f, data=X.reshape(200, 2), columns=np.array(["a", "b", "c"]) if case == "longer" else np.array("ab"))
    r = avbench(f, "--fs", "10", "--units", "rad/s", "--column", "a", "--out", tmp_path / "o")
    _fail(r, str(f), "'columns' names 3 column(s) but the data has 2" if case == "longer" else "'columns' is a 0-d array")
    _untouched(tmp_path / "o")


def test_input_kinds(tmp_path):
    fifo = tmp_path / "r.csv"
    os.mkfifo(fifo)
    _fail(avbench(fifo, "--fs", "10", "--units", "rad/s", "--out", tmp_path / "o"), str(fifo), "is a FIFO")
    folder = tmp_path / "d.csv"
    folder.mkdir()
    _fail(avbench(folder, "--fs", "10", "--units", "rad/s", "--out", tmp_path / "o"), str(folder), "is a folder")
    link = tmp_path / "l.csv"
    link.symlink_to(tmp_path / "gone.csv")
    _fail(avbench(link, "--fs", "10", "--units", "rad/s", "--out", tmp_path / "o"), str(link), "broken symbolic link")
    (tmp_path / "afile").write_text("1\n")
    under = tmp_path / "afile" / "r.csv"
    _fail(avbench(under, "--fs", "10", "--units", "rad/s", "--out", tmp_path / "o"), str(under), "is a file, not a folder"
          if False else "a parent of it is a file")
    _untouched(tmp_path / "o")


@pytest.fixture
def good(tmp_path):
    f = tmp_path / "r.csv"
    f.write_text("\n".join(f"{v:.6f}" for v in X) + "\n")
    return f


def test_out_edges(tmp_path, good):
    """``--out`` an existing file, under a file, on a read-only file system, and an output name taken
    by a folder. Tests run as root, for whom permission bits do not block writing: the read-only
    case uses /proc, a pseudo file system where nobody can create a folder."""
    base = ["--fs", "10", "--units", "rad/s", "--method", "nnls_rel"]
    afile = tmp_path / "afile"
    afile.write_text("keep me\n")
    _fail(avbench(good, *base, "--out", afile), "--out", str(afile), "expected a folder")
    _fail(avbench(good, *base, "--out", afile / "sub"), "--out", "is a file, not a folder")
    assert afile.read_text() == "keep me\n"
    ro = Path("/proc/avbench-estimate-test")
    _fail(avbench(good, *base, "--out", ro), "--out", str(ro))
    out = tmp_path / "out"
    (out / "r_coefficients.json").mkdir(parents=True)
    _fail(avbench(good, *base, "--out", out), "--out", "r_coefficients.json", "is a folder")
    assert sorted(p.name for p in out.iterdir()) == ["r_coefficients.json"]
    kal = tmp_path / "k"
    kal.mkdir()
    _fail(avbench(good, *base, "--kalibr", kal, "--out", tmp_path / "o2"), "--kalibr", "is a folder")
    _untouched(tmp_path / "o2")


def test_blank_line_is_not_dropped(tmp_path):
    f = tmp_path / "r.csv"
    rows = [f"{v:.6f}" for v in X]
    rows.insert(100, "")
    f.write_text("\n".join(rows) + "\n\n")  # a trailing blank line is harmless, one inside is not
    _fail(avbench(f, "--fs", "10", "--units", "rad/s", "--out", tmp_path / "o"), str(f), "line 101 is blank")
    _untouched(tmp_path / "o")


def test_decimal_comma_is_not_read_as_integers(tmp_path):
    f = tmp_path / "r.csv"
    f.write_text("".join(f"0,{abs(int(v * 1e4)) % 10000:04d}\n" for v in X))
    _fail(avbench(f, "--fs", "10", "--units", "rad/s", "--out", tmp_path / "o"), str(f), "decimal commas")
    _untouched(tmp_path / "o")


def test_fs_absurd(tmp_path, good):
    _fail(avbench(good, "--fs", "1e300", "--units", "rad/s", "--out", tmp_path / "o"), "--fs", "at most 1e+09 Hz")
    _untouched(tmp_path / "o")


def test_fs_conflicting_with_time_stamps(tmp_path):
    f = tmp_path / "r.csv"
    f.write_text("t,gx\n" + "".join(f"{i / 100:.2f},{v:.6f}\n" for i, v in enumerate(X)))
    _fail(avbench(f, "--fs", "200", "--units", "rad/s", "--out", tmp_path / "o"), "--fs 200", "100 Hz")
    _fail(avbench(f, "--out", tmp_path / "o"), "--units", "does not say the units")
    _untouched(tmp_path / "o")


@pytest.mark.parametrize("scale", [1e300, 1e-200])
def test_extreme_magnitudes_end_well(tmp_path, scale):
    """x * 1e300 must not crash and x * 1e-200 must not give zeros: N scales with the data."""
    rng = np.random.default_rng(1)
    x = 1e-3 * rng.standard_normal(4000)
    np.save(tmp_path / "ref.npy", x)
    np.save(tmp_path / "big.npy", x * scale)
    common = ["--fs", "100", "--units", "rad/s", "--method", "nnls_rel", "--json"]
    ref = avbench(tmp_path / "ref.npy", *common, "--out", tmp_path / "o1")
    got = avbench(tmp_path / "big.npy", *common, "--out", tmp_path / "o2")
    assert ref.returncode == 0 and got.returncode == 0, got.stderr
    n_ref = json.loads(ref.stdout)["sensors"]["gyro"]["axes"]["x"]["methods"]["nnls_rel"]["coefficients"]["N"]
    n_got = json.loads(got.stdout)["sensors"]["gyro"]["axes"]["x"]["methods"]["nnls_rel"]["coefficients"]["N"]
    assert n_ref["flag"] == n_got["flag"] == "no interval"  # an estimate; nnls_rel gives no interval
    assert n_got["si"] == pytest.approx(n_ref["si"] * scale, rel=1e-6)


def write_ulog(path, t_us, gyro, acc):
    """A minimal PX4 ULog (file header, flag bits, one format, one subscription, data messages) as the
    ULog file-format specification lays it out; no PX4 log ships with a package we can install."""
    import struct

    def msg(kind, payload):
        return struct.pack("<HB", len(payload), ord(kind)) + payload

    out = bytearray(b"ULog\x01\x12\x35" + bytes([1]) + struct.pack("<Q", int(t_us[0])))
    out += msg("B", bytes(16) + struct.pack("<3Q", 0, 0, 0))
    out += msg("F", b"sensor_combined:uint64_t timestamp;float[3] gyro_rad;float[3] accelerometer_m_s2;")
    out += msg("A", struct.pack("<BH", 0, 0) + b"sensor_combined")
    for i in range(len(t_us)):
        out += msg("D", struct.pack("<HQ3f3f", 0, int(t_us[i]), *gyro[i], *acc[i]))
    Path(path).write_bytes(bytes(out))


def test_px4_ulog(tmp_path):
    pytest.importorskip("pyulog")
    n = 2000
    gyro, acc = _imu(n, 4)
    t = 5_000_000 + np.arange(n) * 4000  # 250 Hz, in microseconds
    t[1200:] += 1_000_000
    f = tmp_path / "log.ulg"
    write_ulog(f, t, gyro.astype(np.float32), acc.astype(np.float32))
    r = avbench(f, "--method", "nnls_rel", "--json", "--out", tmp_path / "o")
    assert r.returncode == 0, r.stderr
    data = json.loads(r.stdout)
    assert data["timing"]["rate_hz"] == pytest.approx(250.0) and len(data["timing"]["gaps"]) == 1
    assert data["topic"] == "sensor_combined" and data["sensors"]["accel"]["units_in"] == "m/s^2"
    for sensor in ("gyro", "accel"):
        assert all(a["methods"]["nnls_rel"]["coefficients"]["N"]["flag"] == "no interval"
                   for a in data["sensors"][sensor]["axes"].values())
