"""Message logs of an IMU: ROS 1 ``.bag`` and ROS 2 bag folders (``sensor_msgs/Imu`` through ``rosbags``)
and PX4 ULog (``sensor_combined`` through ``pyulog``). Units are fixed by the message definition
(rad/s, m/s^2); the rules are those of :mod:`avbench.recordings.readers`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from avbench.recordings.channels import Channel, Recording
from avbench.recordings.time_units import Stamps

__all__ = ["read_bag", "read_ulog", "BAG_SUFFIXES"]

#: suffixes of a bag file (a ROS 2 bag is a folder holding ``metadata.yaml`` and its storage files)
BAG_SUFFIXES = (".bag", ".db3", ".mcap")

# -- ROS bags ---------------------------------------------------------------------------------------
_IMU_TYPES = ("sensor_msgs/msg/Imu", "sensor_msgs/Imu")


def _bag_path(path: Path) -> Path:
    if path.is_dir() or path.suffix == ".bag":
        return path
    return path.parent  # a ROS 2 storage file: the bag is its folder


def read_bag(path, topic, progress):
    try:
        from rosbags.highlevel import AnyReader
    except ImportError:
        raise ValueError(f"{path}: reading ROS bags needs the 'rosbags' package; expected it installed "
                         "(pip install 'avbench[ros]')") from None
    from tqdm import tqdm

    bag = _bag_path(Path(path))
    try:
        reader = AnyReader([bag])
        reader.open()
    except Exception as e:  # rosbags raises its own error classes for every kind of broken bag
        raise ValueError(f"{path}: not a readable ROS bag ({str(e).splitlines()[0][:200] if str(e) else type(e).__name__})") from None
    try:
        imu = [c for c in reader.connections if c.msgtype in _IMU_TYPES]
        topics = sorted({c.topic for c in imu})
        if not topics:
            found = ", ".join(sorted({f"{c.topic} ({c.msgtype})" for c in reader.connections})) or "no topics"
            raise ValueError(f"{path}: no sensor_msgs/Imu topic; found {found}")
        if topic is None:
            if len(topics) > 1:
                raise ValueError(f"{path}: {len(topics)} sensor_msgs/Imu topics ({', '.join(topics)}); choose one with --topic")
            topic = topics[0]
        elif topic not in topics:
            raise ValueError(f"--topic {topic!r}: not a sensor_msgs/Imu topic of {path}; expected one of {', '.join(topics)}")
        conns = [c for c in imu if c.topic == topic]
        n = sum(c.msgcount for c in conns)
        out = np.empty((n, 6))
        stamp = np.empty(n, dtype=np.int64)
        recv = np.empty(n, dtype=np.int64)
        ros1 = bag.suffix == ".bag"
        k = 0
        block: list = []

        def flush():
            nonlocal k
            m = len(block)
            fast = _decode_imu([raw for _, _, raw in block], ros1)
            if fast is None or not _same_as_deserialized(reader, block[0], fast, ros1):
                fast = _deserialize_imu(reader, block)
            out[k:k + m], stamp[k:k + m] = fast
            recv[k:k + m] = [t for _, t, _ in block]
            k += m
            block.clear()

        with tqdm(total=n, desc=f"reading {topic}", unit="msg", disable=not progress, leave=False) as bar:
            for item in reader.messages(connections=conns):
                block.append(item)
                if len(block) == 1 << 16:
                    flush()
                    bar.update(1 << 16)
            if block:
                flush()
    finally:
        reader.close()
    out, stamp, recv = out[:k], stamp[:k], recv[:k]
    if k == 0:
        raise ValueError(f"{path}: topic {topic} holds no messages")
    rec = Recording(Path(path), "ros1" if bag.suffix == ".bag" else "ros2", [], topic=topic)
    if np.any(stamp != 0):
        t, what = stamp, "header stamps"
    else:
        t, what = recv, "bag receive times (every header stamp is zero)"
        rec.notes.append("header stamps are all zero; the bag's receive times are used")
    order = np.argsort(t, kind="stable")
    if np.any(order != np.arange(k)):
        rec.notes.append("messages were not in time order; sorted by time stamp")
        out, t = out[order], t[order]
    rec.stamps = Stamps(t, what, "ns", "the format")
    for j, (sensor, axis) in enumerate([("gyro", "x"), ("gyro", "y"), ("gyro", "z"),
                                        ("accel", "x"), ("accel", "y"), ("accel", "z")]):
        unit = "rad/s" if sensor == "gyro" else "m/s^2"
        field_name = "angular_velocity" if sensor == "gyro" else "linear_acceleration"
        rec.channels.append(Channel(f"{field_name}.{axis}", sensor, axis, np.ascontiguousarray(out[:, j]), unit))
    return rec


def _deserialize_imu(reader, block):
    """(values (m, 6), header stamps in ns) of sensor_msgs/Imu messages through rosbags' deserializer."""
    vals = np.empty((len(block), 6))
    st = np.empty(len(block), dtype=np.int64)
    for i, (conn, _, raw) in enumerate(block):
        msg = reader.deserialize(raw, conn.msgtype)
        w, a = msg.angular_velocity, msg.linear_acceleration
        vals[i] = (w.x, w.y, w.z, a.x, a.y, a.z)
        st[i] = int(msg.header.stamp.sec) * 1_000_000_000 + int(msg.header.stamp.nanosec)
    return vals, st


def _decode_imu(raws, ros1: bool):
    """The same as :func:`_deserialize_imu`, vectorised over messages of one length (one frame_id
    length), straight from the bytes: ROS 1 packs fields without padding; ROS 2 is CDR (4-byte
    encapsulation header, little endian, float64 aligned to 8 from the end of that header). None when
    the bytes are not laid out as expected; the caller then deserializes message by message."""
    L = len(raws[0])
    if any(len(r) != L for r in raws) or L < 16:
        return None
    first = raws[0]
    if ros1:
        pos = 16 + int.from_bytes(first[12:16], "little")
        base = 0
    else:
        if first[:2] != b"\x00\x01":  # CDR little endian
            return None
        pos = 16 + int.from_bytes(first[12:16], "little")
        base = 4
        pos = base + -(-(pos - base) // 8) * 8
    if L != pos + 37 * 8:  # orientation 4 + cov 9, angular velocity 3 + cov 9, acceleration 3 + cov 9
        return None
    buf = np.frombuffer(b"".join(raws), dtype=np.uint8).reshape(len(raws), L)
    ang, lin = pos + 13 * 8, pos + 25 * 8
    vals = np.concatenate([np.ascontiguousarray(buf[:, ang:ang + 24]).view("<f8"),
                           np.ascontiguousarray(buf[:, lin:lin + 24]).view("<f8")], axis=1)
    off = 4 if ros1 else base  # ROS 1: seq (uint32) comes first; ROS 2: the stamp right after the CDR header
    sec = np.ascontiguousarray(buf[:, off:off + 4]).view("<u4" if ros1 else "<i4")[:, 0].astype(np.int64)
    nsec = np.ascontiguousarray(buf[:, off + 4:off + 8]).view("<u4")[:, 0].astype(np.int64)
    return vals, sec * 1_000_000_000 + nsec


def _same_as_deserialized(reader, item, fast, ros1) -> bool:
    """Check the vectorised decoding against rosbags' deserializer on the block's first message."""
    vals, st = _deserialize_imu(reader, [item])
    return bool(np.array_equal(vals[0], fast[0][0]) and st[0] == fast[1][0])


# -- PX4 ULog ---------------------------------------------------------------------------------------
def read_ulog(path, progress):
    try:
        from pyulog import ULog
    except ImportError:
        raise ValueError(f"{path}: reading PX4 ULog needs the 'pyulog' package; expected it installed "
                         "(pip install 'avbench[px4]')") from None
    try:
        log = ULog(str(path), message_name_filter_list=["sensor_combined"])
    except Exception as e:  # pyulog raises plain Exceptions for malformed logs
        raise ValueError(f"{path}: not a readable PX4 ULog ({str(e).splitlines()[0][:200] if str(e) else type(e).__name__})") from None
    sets = log.data_list  # only sensor_combined was read
    if not sets:
        raise ValueError(f"{path}: no sensor_combined topic in the log; expected PX4's combined IMU topic")
    d = sets[0].data
    need = [f"gyro_rad[{i}]" for i in range(3)] + [f"accelerometer_m_s2[{i}]" for i in range(3)]
    missing = [k for k in need + ["timestamp"] if k not in d]
    if missing:
        raise ValueError(f"{path}: sensor_combined lacks {', '.join(missing)}")
    rec = Recording(Path(path), "ulog", [], topic="sensor_combined")
    rec.stamps = Stamps(np.asarray(d["timestamp"], dtype=np.int64), "timestamp", "us", "the format")
    for i, axis in enumerate("xyz"):
        rec.channels.append(Channel(f"gyro_rad[{i}]", "gyro", axis, np.asarray(d[f"gyro_rad[{i}]"], dtype=np.float64), "rad/s"))
    for i, axis in enumerate("xyz"):
        rec.channels.append(Channel(f"accelerometer_m_s2[{i}]", "accel", axis,
                                    np.asarray(d[f"accelerometer_m_s2[{i}]"], dtype=np.float64), "m/s^2"))
    return rec
