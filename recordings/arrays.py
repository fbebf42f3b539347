"""Array containers: ``.npy`` (memory-mapped), ``.npz`` (a ``data`` table or named arrays) and MATLAB
``.mat`` (v4-v7 through scipy, v7.3 through h5py); named arrays are chosen by
:func:`_arrays_recording`. The rules are those of :mod:`avbench.recordings.readers`.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from avbench.recordings import files as data_files
from avbench.recordings.channels import (TIME_NAMES, Channel, Recording, axis_label, numeric_array, set_time,
                                         split_names, table_recording)

__all__ = ["read_npy", "read_npz", "read_mat"]


def read_npy(path, gyro, accel, time_column, time_units):
    arr = numeric_array(data_files.load_npy(path, mmap=True), path)
    return table_recording(path, "npy", arr, None, gyro, accel, time_column, time_units)


def read_npz(path, gyro, accel, time_column, time_units):
    z = data_files.load_npz(path)
    keys = list(z)
    time_key = next((k for k in ("t", "time") if k in keys), None)
    if "data" in keys:
        arr = z["data"]
    else:
        arrays = [k for k in keys if k not in ("columns", "fs", time_key)]
        named = [x for x in (*split_names(gyro), *split_names(accel), *split_names(time_column)) if x in keys]
        if len(arrays) != 1 or named:  # named arrays; a single array's columns are chosen as a table's
            return _arrays_recording(path, "npz", z, gyro, accel, time_column, time_units)
        arr = z[arrays[0]]
    arr = numeric_array(arr, path)
    names = None
    if "columns" in keys:
        c = z["columns"]
        if c.ndim != 1:
            raise ValueError(f"{path}: 'columns' is a {c.ndim}-d array; expected a 1-D array of column names")
        n_cols = arr.shape[1] if arr.ndim == 2 else 1
        if c.size != n_cols:
            raise ValueError(f"{path}: 'columns' names {c.size} column(s) but the data has {n_cols}; "
                             "expected one name per column")
        names = [str(v) for v in c]
    time = None
    if time_key is not None and (time_column is None or str(time_column).lower() != "none"):
        time = numeric_array(z[time_key], path, f"'{time_key}'")
    return table_recording(path, "npz", arr, names, gyro, accel, time_column, time_units, time)


# -- named arrays (npz, MATLAB) -------------------------------------------------------------------
def _describe(name, a) -> str:
    a = np.asarray(a)
    return f"{name} ({'x'.join(map(str, a.shape)) or 'scalar'} {a.dtype})"


def _as_samples(a):
    """A 2-D (samples x axes) view of a 1-D or 2-D array, samples along its longer dimension (MATLAB
    users store 3 x n as often as n x 3; HDF5 stores a MATLAB n x 3 as 3 x n); None if not such."""
    a = np.asarray(a)
    if a.dtype.kind not in "iuf" or a.ndim not in (1, 2) or a.size < 2:
        return None
    if a.ndim == 1:
        return a[:, None]
    return a.T if a.shape[0] < a.shape[1] else a


def _arrays_recording(path, fmt, arrays: dict, gyro, accel, time_column, time_units):
    """A Recording from named arrays (an ``.npz`` without ``data``, a MATLAB file's variables).

    ``gyro``/``accel``: array names (comma-separated; each a 1-D array or an n x k one, whose columns
    are the axes x, y, z); ``time_column``: the time array. Without them, arrays named like a gyro
    (``gyro``, ``omega``, ``angular_velocity``, ...) or an accelerometer (``accel``, ``acc``,
    ``alpha``, ...) and a time array (``t``, ``time``, ``timestamp``) are found; any doubt is an
    error listing every variable found with its shape. One-letter names (``a``, ``w``) are never
    guessed."""
    usable = {k: v for k, v in arrays.items() if _as_samples(v) is not None}
    listing = ", ".join(_describe(k, v) for k, v in arrays.items()) or "no variables"

    def pick(spec, option):
        out = []
        for nm in split_names(spec):
            if nm not in arrays:
                raise ValueError(f"{path}: no variable {nm!r} ({option}); found {listing}")
            if nm not in usable:
                raise ValueError(f"{path}: variable {_describe(nm, arrays[nm])} ({option}) is not a 1-D or 2-D "
                                 f"numeric array; expected samples (found {listing})")
            out.append(nm)
        return out

    g, a = pick(gyro, "--gyro"), pick(accel, "--accel")
    if time_column is not None and str(time_column).lower() == "none":
        t_name = None
    elif time_column is not None:
        (t_name,) = pick(time_column, "--time") or [None]
    else:
        t_name = next((k for k in usable if k.lower() in TIME_NAMES), None)
    if not g and not a:
        stem = {k: re.sub(r"^.*\.", "", k) for k in usable if k != t_name}  # a struct's field: its last name
        g = [k for k, b in stem.items() if re.fullmatch(r"(gyro|gyr|gyros|gyroscope|omega|angular_velocity|ang_vel|"
                                                          r"rates|wm)", b, re.I)]
        a = [k for k, b in stem.items() if re.fullmatch(r"(accel|acc|accelerometer|accels|alpha|linear_acceleration|"
                                                          r"lin_acc|specific_force)", b, re.I)]
        if not g and not a:
            cand = [k for k in usable if k != t_name and k.lower() not in ("fs", "dt", "rate_hz")]
            if len(cand) == 1 and _as_samples(arrays[cand[0]]).shape[1] == 1:
                g = cand
            else:
                raise ValueError(f"{path}: no variable named like a gyro or accelerometer; found {listing}; "
                                 "choose them with --gyro NAME and/or --accel NAME (and --time NAME)")
        if len(g) > 1 or len(a) > 1:
            raise ValueError(f"{path}: more than one gyro-like or accelerometer-like variable "
                             f"({', '.join(g + a)}); found {listing}; choose with --gyro NAME / --accel NAME")
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
                axis = axis_label(k, sensor) if singles > 1 else "x"
            else:
                axis = "xyz"[j] if x.shape[1] <= 3 else str(j)
            channels.append(Channel(k if x.shape[1] == 1 else f"{k}[{j}]", sensor, axis, x[:, j]))
    rec = Recording(Path(path), fmt, channels)
    if t_name is not None:
        t = np.asarray(arrays[t_name]).reshape(-1)
        if t.size != n:
            raise ValueError(f"{path}: the time variable {_describe(t_name, arrays[t_name])} has {t.size} stamps for "
                             f"{n} samples; expected one per sample")
        set_time(rec, path, t, time_units, None, f"variable {t_name!r}")
    return rec


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


def read_mat(path, gyro, accel, time_column, time_units):
    return _arrays_recording(path, "mat", _mat_arrays(path), gyro, accel, time_column, time_units)
