"""Step 1: read a recording file into named channels, their sensor, their units and the time stamps.

One reader per container, behind the one call :func:`read_recording` (chosen by the file name); each
lives in the module of what it reads -- :mod:`~avbench.recordings.text_tables`,
:mod:`~avbench.recordings.arrays` (npy, npz, mat), :mod:`~avbench.recordings.bags` (ROS bags, PX4 ULog) --
and :mod:`~avbench.recordings.channels` holds what they share (:class:`Recording`, header units, time stamps):

* text ``.csv .txt .dat .tsv`` -- read by their structure (:mod:`~avbench.recordings.text_tables`): UTF-8
  with or without a byte-order mark, RFC 4180 quoting, comma, semicolon, tab or blank separated, ``#``
  comments, an optional header row (a first row none of whose cells is a number) or, as in EuRoC /
  TUM-VI / Kalibr files, a header in the last ``#`` comment line before the data (``#timestamp
  [ns],w_RS_S_x [rad s^-1],...``) when it splits into as many names as the data has columns. The
  separator is the one under which the first data lines split into equally many numeric cells and the
  header into as many names: a header's own spaces do not make columns. Every line must have as many
  fields as the first data line and the header as many names (a header one name short, a row index
  without a name, is refused, never shifted). Parsed by pandas' C engine straight to float64 (an
  integer time column to int64: 1.4e18 ns stamps hold a 10 ms step exactly; ``bench/`` measures it
  against a bare ``pandas.read_csv``). A blank line between samples is an error (it is not silently
  dropped); so is a file written with decimal commas (``0,0123``, ``1,5e-03``) under a comma
  separator; with ``;``/tab/blank separators decimal commas are read as such.
* ``.npy`` -- 1-D, or 2-D samples x columns in either orientation (samples along the longer
  dimension); memory-mapped, so a large record is not copied.
* ``.npz`` and MATLAB ``.mat`` -- v4-v7 through ``scipy.io.loadmat``; v7.3 (HDF5) through ``h5py``
  (``pip install avbench[mat73]``); one rule for both (:mod:`~avbench.recordings.arrays`): a ``data``
  table (names from ``columns``), or arrays named like a gyro / an accelerometer at the top level or
  in a struct (``imu.gyro``), in either orientation, with their time array (``t``, ``imu.t``) and a
  stated rate (``fs``, ``rate``, ``dt``); any names with ``--gyro NAME``, ``--accel NAME``, ``--time NAME``.
* ROS 1 ``.bag`` and ROS 2 bag folders (``metadata.yaml`` with ``.db3``/``.mcap``) -- ``sensor_msgs/Imu``
  messages of one topic through the ``rosbags`` package (``pip install avbench[ros]``): gyro x, y, z
  from ``angular_velocity`` (rad/s) and accelerometer x, y, z from ``linear_acceleration`` (m/s^2),
  units fixed by the message definition (REP 145), time from the header stamps (the bag's receive
  times when every header stamp is zero).
* PX4 ULog ``.ulg`` -- the ``sensor_combined`` topic through ``pyulog`` (``pip install avbench[px4]``):
  ``gyro_rad[0..2]`` (rad/s), ``accelerometer_m_s2[0..2]`` (m/s^2), time from ``timestamp`` (us).

**Units from a header.** A unit in brackets at the end of a column name (``[rad s^-1]``, ``[deg/s]``,
``(m/s^2)``, ``[g]``, ``[ns]``, ...; :func:`header_unit`) is the file stating it: it sets the column's unit
(a contradicting ``--units`` is an error) and its sensor (an angular rate is a gyro, an acceleration an
accelerometer, a time unit the time column; a magnetic field ``[G]`` or a temperature ``[degC]`` is
neither, and never chosen as one). Case decides where it carries meaning (``g`` standard gravity, ``G``
gauss). A unit written as a name suffix (``gyro_x_dps``) is only an axis label: units come from the
format, a bracket, the user, or -- for a static accelerometer's three axes -- gravity
(:mod:`~avbench.recordings.sensors`); never from a name.

**Time units** (:mod:`~avbench.recordings.time_units`): ``time_units`` when given; else the format's
(bags: ns, ULog: us); else the header's bracket; else the one unit that makes the stamps' interval a
rate an IMU samples at (1 Hz to 32 kHz), an epoch date or ``--fs`` choosing between two, a refusal
naming ``--time-units`` where neither does. A wrapping 16- or 32-bit counter is unwrapped. Integer
stamps are differenced as int64 before conversion.

For tables the channels are chosen with ``gyro``/``accel`` (names or 0-based indices); with neither, a
single column is a gyro, and headers named like ``gyro_x``/``gx``/``wx``/``w_RS_S_x``/``omega_x`` and
``acc_x``/``ax``/``a_RS_S_x``/``alpha_x`` are found. A column named ``t``, ``time``, ``timestamp`` or ``time_s`` (or chosen with ``time_column``) gives the
time stamps. Every problem is a ``ValueError`` whose message starts with the file name.
"""

from __future__ import annotations

from pathlib import Path

from avbench.recordings import files as data_files
from avbench.recordings.arrays import read_mat, read_npy, read_npz
from avbench.recordings.bags import BAG_SUFFIXES, read_bag, read_ulog
from avbench.recordings.channels import Channel, Recording, header_unit, resolve_time, time_in_seconds
from avbench.recordings.text_tables import read_text

__all__ = ["Channel", "Recording", "read_recording", "header_unit", "time_in_seconds", "TEXT_SUFFIXES",
           "KNOWN_SUFFIXES"]

TEXT_SUFFIXES = (".csv", ".txt", ".dat", ".tsv")
KNOWN_SUFFIXES = (".npy", ".npz", ".mat", *TEXT_SUFFIXES, *BAG_SUFFIXES, ".ulg")


def read_recording(path, *, gyro=None, accel=None, time_column=None, time_units=None, topic=None,
                   progress=False, fs=None) -> Recording:
    """Read ``path`` (any format of the module docstring) into a :class:`Recording`, its time stamps in
    seconds (:func:`~avbench.recordings.channels.resolve_time`).

    ``gyro``/``accel``: column names or indices (comma-separated string or list) of a table;
    ``time_column``: the time column (``"none"`` to ignore one); ``time_units``: s, ms, us or ns
    (None: from the file, see :mod:`avbench.recordings.time_units`); ``topic``: the ``sensor_msgs/Imu``
    topic of a bag; ``fs``: the user's rate, which chooses between two plausible time units.
    """
    p = Path(path)
    is_bag = p.suffix.lower() in BAG_SUFFIXES or (p.is_dir() and (p / "metadata.yaml").is_file())
    if is_bag:
        data_files.check_path_kind(p, allow_dir=True)
        rec = read_bag(p, topic, progress)
    else:
        p = data_files.check_file(p)
        suffix = p.suffix.lower()
        if suffix == ".npy":
            rec = read_npy(p, gyro, accel, time_column, time_units)
        elif suffix == ".npz":
            rec = read_npz(p, gyro, accel, time_column, time_units)
        elif suffix == ".mat":
            rec = read_mat(p, gyro, accel, time_column, time_units)
        elif suffix in TEXT_SUFFIXES:
            rec = read_text(p, gyro, accel, time_column, time_units)
        elif suffix == ".ulg":
            rec = read_ulog(p, progress)
        else:
            raise ValueError(f"{p}: unknown file type {suffix!r}; expected one of {', '.join(KNOWN_SUFFIXES)} "
                             "or a ROS 2 bag folder")
    if topic is not None and rec.format not in ("ros1", "ros2"):
        raise ValueError(f"--topic: {p} is not a ROS bag; expected --topic only with a bag")
    if rec.n_samples == 0:
        raise ValueError(f"{p}: the record is empty")
    resolve_time(rec, time_units, fs)
    return rec
