"""Array containers: ``.npy`` (memory-mapped), ``.npz`` and MATLAB ``.mat`` (v4-v7 through scipy, v7.3
through h5py), read by one rule whatever the container (:func:`container_recording`):

* **Names.** A container is a set of named arrays; a MATLAB struct's fields are named ``struct.field``
  (its *last name* is ``field``). Arrays are samples x axes in either orientation (samples along the
  longer dimension: :func:`~avbench.recordings.channels.samples_first`).
* **A table.** An array whose last name is ``data`` (with its ``columns`` names, if any), or the only
  sample array of a container with no array named like a sensor, is a table: its columns are chosen as
  a text table's (``--gyro 0,1,2``, ``--column a``, names like ``gyro_x``).
* **Named sensors.** Otherwise arrays whose last name is a gyro's (``gyro``, ``omega``,
  ``angular_velocity``, ...) or an accelerometer's (``accel``, ``acc``, ``specific_force``, ...) are
  the sensors, whether at the top level or in a struct; ``--gyro NAME`` / ``--accel NAME`` choose by
  full or (unique) last name. One-letter names (``a``, ``w``) are never guessed.
* **Time.** The array ``--time NAME``, else the one whose last name is a time name (``t``, ``time``,
  ``timestamp``, ...), preferring the one beside the sensors (``imu.t`` for ``imu.gyro``).
* **A stated rate.** A scalar whose last name is a rate (``fs``, ``rate``, ``sample_rate``, ... in Hz)
  or an interval (``dt``, ``sample_time``, ... in s) is the rate the file states
  (:attr:`~avbench.recordings.channels.Recording.rate`), preferring the one beside the sensors;
  :func:`~avbench.recordings.timing.timing_of` holds it against the stamps and ``--fs``.

Any doubt (two gyro-like arrays, no sensor at all, two time arrays) is an error listing what was found,
each array with its shape (at most :data:`~avbench.recordings.channels._LISTED` of them).
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

from avbench.recordings import files as data_files
from avbench.recordings.channels import (TIME_NAMES, Channel, Recording, axis_label, listing, numeric_array,
                                         set_time, split_names, table_recording)

__all__ = ["read_npy", "read_npz", "read_mat", "container_recording", "GYRO_NAMES", "ACCEL_NAMES", "RATE_NAMES",
           "INTERVAL_NAMES"]

#: last names of a gyro's array
GYRO_NAMES = re.compile(r"(gyro|gyr|gyros|gyroscope|omega|angular_velocity|ang_vel|rates|wm)", re.I)
#: last names of an accelerometer's array
ACCEL_NAMES = re.compile(r"(accel|acc|accelerometer|accels|alpha|linear_acceleration|lin_acc|specific_force)", re.I)
#: last names of a scalar stating the sample rate (Hz)
RATE_NAMES = ("fs", "fs_hz", "rate", "rate_hz", "sample_rate", "samplerate", "sampling_rate", "sampling_frequency")
#: last names of a scalar stating the sample interval (s)
INTERVAL_NAMES = ("dt", "dt_s", "sample_time", "sample_interval", "sampling_interval", "sampling_time")


def read_npy(path, gyro, accel, time_column, time_units):
    arr = numeric_array(data_files.load_npy(path, mmap=True), path)
    return table_recording(path, "npy", arr, None, gyro, accel, time_column, time_units)


def read_npz(path, gyro, accel, time_column, time_units):
    return container_recording(path, "npz", data_files.load_npz(path), gyro, accel, time_column, time_units)


def read_mat(path, gyro, accel, time_column, time_units):
    return container_recording(path, "mat", _mat_arrays(path), gyro, accel, time_column, time_units)


# -- the one rule ----------------------------------------------------------------------------------
def _last(name: str) -> str:
    return name.rpartition(".")[2]


def _parent(name: str) -> str:
    return name.rpartition(".")[0]


def _describe(name, a) -> str:
    a = np.asarray(a)
    return f"{name} ({'x'.join(map(str, a.shape)) or 'scalar'} {a.dtype})"


def _is_samples(a) -> bool:
    a = np.asarray(a)
    return a.dtype.kind in "iuf" and a.ndim in (1, 2) and a.size >= 2


def _as_samples(a):
    """A 2-D (samples x axes) view of a 1-D or 2-D array, samples along its longer dimension."""
    a = np.asarray(a)
    if a.ndim == 1:
        return a[:, None]
    return a.T if a.shape[0] < a.shape[1] else a


def _nearest(names, near: set[str]):
    """The names in the struct of ``near`` (the sensors' struct) if any, else all of them."""
    close = [k for k in names if _parent(k) in near]
    return close or list(names)


def _stated_rate(path, arrays, near: set[str]) -> tuple[float, str] | None:
    """(Hz, what) of the scalar stating the rate (see the module docstring); None if none."""
    found = []
    for k, v in arrays.items():
        a = np.asarray(v)
        if a.size != 1 or a.dtype.kind not in "iuf":
            continue
        last = _last(k).lower()
        value = float(a.reshape(-1)[0])
        if last in RATE_NAMES:
            found.append((k, value, value))
        elif last in INTERVAL_NAMES:
            found.append((k, 1.0 / value if value > 0 and math.isfinite(value) else math.nan, value))
    if not found:
        return None
    found = [f for f in found if f[0] in _nearest([f[0] for f in found], near)]
    for k, hz, raw in found:
        if not (math.isfinite(hz) and hz > 0):
            raise ValueError(f"{path}: variable {k!r} = {raw!r} is not a sample rate; expected a positive number "
                             f"(or remove it and give --fs)")
    hz0 = found[0][1]
    if any(abs(hz / hz0 - 1.0) > 1e-6 for _, hz, _ in found):
        said = ", ".join(f"{k} = {raw:g}" for k, _, raw in found)
        raise ValueError(f"{path}: its variables state different rates ({said}); expected one rate")
    return hz0, f"variable {found[0][0]!r}"


def _resolve(path, arrays, usable, spec, option, listed) -> str:
    """The array named ``spec`` (a full name, or a last name that only one array has)."""
    if spec in arrays:
        name = spec
    else:
        by_last = [k for k in arrays if _last(k) == spec]
        if len(by_last) != 1:
            raise ValueError(f"{path}: no variable {spec!r} ({option}); found {listed}")
        name = by_last[0]
    if name not in usable:
        raise ValueError(f"{path}: variable {_describe(name, arrays[name])} ({option}) is not a 1-D or 2-D "
                         f"numeric array; expected samples (found {listed})")
    return name


def container_recording(path, fmt, arrays: dict, gyro, accel, time_column, time_units):
    """A Recording from a container's named arrays by the rule of the module docstring."""
    usable = {k: v for k, v in arrays.items() if _is_samples(v)}
    listed = listing([_describe(k, v) for k, v in arrays.items()]) or "no variables"
    no_time = time_column is not None and str(time_column).lower() == "none"
    specs = split_names(gyro) + split_names(accel)
    by_name = [s for s in specs if s in arrays or sum(_last(k) == s for k in arrays) == 1]
    data_keys = [k for k in usable if _last(k) == "data"]
    sensors_named = [k for k in usable if GYRO_NAMES.fullmatch(_last(k)) or ACCEL_NAMES.fullmatch(_last(k))]
    anonymous = [k for k in usable if _last(k).lower() not in TIME_NAMES and _last(k) != "columns"]
    table = None
    if not by_name:
        if len(data_keys) == 1:
            table = data_keys[0]
        elif not sensors_named and len(anonymous) == 1:
            table = anonymous[0]
    if table is not None:
        return _table(path, fmt, arrays, usable, table, gyro, accel, time_column, time_units, listed, no_time)
    if specs and not by_name and not usable:
        raise ValueError(f"{path}: no variable {specs[0]!r} (--gyro/--accel); found {listed}")

    g = [_resolve(path, arrays, usable, s, "--gyro", listed) for s in split_names(gyro)]
    a = [_resolve(path, arrays, usable, s, "--accel", listed) for s in split_names(accel)]
    if not g and not a:
        g = [k for k in usable if GYRO_NAMES.fullmatch(_last(k))]
        a = [k for k in usable if ACCEL_NAMES.fullmatch(_last(k))]
        if not g and not a:
            raise ValueError(f"{path}: no variable named like a gyro or accelerometer; found {listed}; "
                             "choose them with --gyro NAME and/or --accel NAME (and --time NAME)")
        if len(g) > 1 or len(a) > 1:
            raise ValueError(f"{path}: more than one gyro-like or accelerometer-like variable "
                             f"({', '.join(g + a)}); found {listed}; choose with --gyro NAME / --accel NAME")
    near = {_parent(k) for k in g + a}
    t_name = None
    if time_column is not None and not no_time:
        t_name = _resolve(path, arrays, usable, str(time_column), "--time", listed)
    elif not no_time:
        times = _nearest([k for k in usable if _last(k).lower() in TIME_NAMES and k not in g + a], near)
        if len(times) > 1:
            raise ValueError(f"{path}: more than one time-like variable ({', '.join(times)}); found {listed}; "
                             "choose with --time NAME (or --time none)")
        t_name = times[0] if times else None
    chosen = [(k, "gyro") for k in g] + [(k, "accel") for k in a]
    if len({k for k, _ in chosen} | ({t_name} if t_name else set())) != len(chosen) + (1 if t_name else 0):
        raise ValueError(f"{path}: a variable is chosen twice (--time/--gyro/--accel)")
    channels = []
    n = None
    for k, sensor in chosen:
        x = _as_samples(arrays[k])
        if n is None:
            n = x.shape[0]
        elif x.shape[0] != n:
            raise ValueError(f"{path}: {_describe(k, arrays[k])} has {x.shape[0]} samples but "
                             f"{chosen[0][0]} has {n}; expected arrays of one length")
        singles = sum(1 for c, sn in chosen if sn == sensor and _as_samples(arrays[c]).shape[1] == 1)
        for j in range(x.shape[1]):
            if x.shape[1] == 1:
                axis = axis_label(_last(k), sensor) if singles > 1 else "x"
            else:
                axis = "xyz"[j] if x.shape[1] <= 3 else str(j)
            channels.append(Channel(k if x.shape[1] == 1 else f"{k}[{j}]", sensor, axis, x[:, j]))
    rec = Recording(Path(path), fmt, channels, rate=_stated_rate(path, arrays, near))
    if t_name is not None:
        t = np.asarray(arrays[t_name]).reshape(-1)
        if t.size != n:
            raise ValueError(f"{path}: the time variable {_describe(t_name, arrays[t_name])} has {t.size} stamps for "
                             f"{n} samples; expected one per sample")
        set_time(rec, path, t, time_units, None, f"variable {t_name!r}")
    return rec


def _table(path, fmt, arrays, usable, key, gyro, accel, time_column, time_units, listed, no_time):
    """A table array (``data`` or the only array): columns chosen as a text table's, ``columns`` beside
    it naming them, a time array beside it giving the stamps."""
    near = {_parent(key)}
    names = None
    cols = [k for k in arrays if _last(k) == "columns" and _parent(k) in near]
    if cols:
        c = np.asarray(arrays[cols[0]])
        if c.ndim != 1:
            raise ValueError(f"{path}: 'columns' is a {c.ndim}-d array; expected a 1-D array of column names")
        names = [str(v) for v in c]
    time = None
    what = None
    if time_column is not None and not no_time and (names is None or str(time_column) not in names):
        try:
            what = _resolve(path, arrays, usable, str(time_column), "--time", listed)
        except ValueError:
            what = None  # a column index or name: the table's own
        if what is not None:
            time_column = "none"
    elif not no_time:
        times = _nearest([k for k in usable if _last(k).lower() in TIME_NAMES], near)
        if len(times) > 1:
            raise ValueError(f"{path}: more than one time-like variable ({', '.join(times)}); found {listed}; "
                             "choose with --time NAME (or --time none)")
        what = times[0] if times else None
    if what is not None:
        time = numeric_array(arrays[what], path, f"{what!r}").reshape(-1)
    rec = table_recording(path, fmt, numeric_array(arrays[key], path), names, gyro, accel, time_column, time_units,
                          time, f"variable {what!r}" if what else None)
    rec.rate = _stated_rate(path, arrays, near)
    return rec


# -- MATLAB ----------------------------------------------------------------------------------------
def _mat_arrays(path) -> dict:
    """The variables of a MATLAB file (struct fields flattened to ``struct.field``): v4-v7 through
    scipy.io, v7.3 (HDF5) through h5py (optional: ``pip install 'avbench[mat73]'``)."""
    with open(path, "rb") as fh:
        head = fh.read(128)
    if head.startswith(b"MATLAB 7.3") or _is_hdf5(path):
        try:
            import h5py
        except ImportError:
            raise ValueError(f"{path}: a MATLAB v7.3 (HDF5) file; reading it needs the 'h5py' package, expected "
                             "it installed (pip install 'avbench[mat73]'), or save with -v7") from None
        out = {}
        try:
            with h5py.File(path, "r") as f:
                def visit(name, obj):
                    if isinstance(obj, h5py.Dataset) and not name.startswith("#") and \
                            obj.attrs.get("MATLAB_class", b"double") not in (b"char", b"cell", b"struct"):
                        out[name.replace("/", ".")] = obj[()]
                f.visititems(visit)
        except OSError as e:
            raise ValueError(f"{path}: not a readable MATLAB v7.3 file ({e})") from None
        return out
    import scipy.io

    try:
        m = scipy.io.loadmat(path, simplify_cells=True)
    except Exception as e:  # scipy raises ValueError/TypeError/MatReadError for broken files
        raise ValueError(f"{path}: not a readable MATLAB file ({str(e).splitlines()[0][:200] if str(e) else type(e).__name__})") from None
    out = {}

    def flat(prefix, v):
        if isinstance(v, dict):
            for k, x in v.items():
                flat(f"{prefix}.{k}" if prefix else k, x)
        elif isinstance(v, np.ndarray | int | float):
            out[prefix] = np.asarray(v)
    for k, v in m.items():
        if not k.startswith("__"):
            flat(k, v)
    return out


def _is_hdf5(path) -> bool:
    with open(path, "rb") as fh:
        for off in (0, 512, 1024, 2048):
            fh.seek(off)
            if fh.read(8) == b"\x89HDF\r\n\x1a\n":
                return True
    return False
