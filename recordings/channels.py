"""What every reader shares: the :class:`Recording` it returns, the units and sensor a column's header
states (:func:`header_unit`), time stamps in seconds (:func:`time_in_seconds`), and the choice of a
table's columns (:func:`choose_columns`). The rules are those of :mod:`avbench.recordings.readers`.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

__all__ = ["Channel", "Recording", "header_unit", "time_in_seconds", "TIME_NAMES", "split_names", "axis_label",
           "choose_columns", "numeric_array", "table_recording", "columns_recording", "set_time"]

#: column (or array) names read as the time stamps
TIME_NAMES = {"t", "time", "timestamp", "time_s", "times", "t_s"}
#: a unit written after the axis in a column name (``gyro_x_dps``, ``acc_x_g``): recognised for the axis
#: label only -- the units still come from the format or the user, never from a name
_UNIT_SUFFIX = r"(?:[_ .\-](?:dps|degs|deg_s|rps|rads|rad_s|g|mg|ug|mps2|ms2|m_s2))?"
_GYRO_RE = re.compile(r"^(gyro|gyr|g|w|omega|wx|wy|wz|angular_velocity)[_ .\-\[]?([xyz012])\]?" + _UNIT_SUFFIX
                      + r"$|gyro.*[_ .\-]?([xyz])$"
                      + r"|^(?:w|omega|gyr|angular_velocity|ang_vel)[_ .\-].*[_ .\-]([xyz])$", re.I)
_ACCEL_RE = re.compile(r"^(accel|acc|a|alpha|linear_acceleration|accelerometer)[_ .\-\[]?([xyz012])\]?" + _UNIT_SUFFIX
                       + r"$|acc.*[_ .\-]?([xyz])$"
                       + r"|^(?:a|alpha|linear_acceleration|lin_acc)[_ .\-].*[_ .\-]([xyz])$", re.I)
_TIME_SCALE = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
#: a unit in brackets at the end of a column name: ``w_RS_S_x [rad s^-1]``, ``acc (m/s^2)``
_BRACKET_UNIT = re.compile(r"^(.*?)\s*[\[(]\s*([^\[\]()]+?)\s*[\])]\s*$")
_UNIT_SPELLINGS = {"dps": "deg/s", "deg/sec": "deg/s", "degree/s": "deg/s", "degrees/s": "deg/s", "rps": "rad/s",
                   "rad/sec": "rad/s", "m/s2": "m/s^2", "m/s/s": "m/s^2", "m/sec^2": "m/s^2", "mps2": "m/s^2",
                   "sec": "s", "second": "s", "seconds": "s", "usec": "us", "msec": "ms", "nsec": "ns",
                   "deg/hr": "deg/h", "dph": "deg/h", "g0": "g"}
#: epoch stamps: the first stamp in seconds lies between these (1973 and 2286)
_EPOCH_S = (1e8, 1e10)
#: integer stamps that are not epoch stamps: the unit whose median step makes a rate in this range (Hz)
_STEP_RATE = (5.0, 5e3)


@dataclass
class Channel:
    """One column of samples: ``sensor`` is "gyro" or "accel", ``unit`` the unit the format defines
    (None when the file does not say), ``axis`` a short label (x, y, z or the column name)."""

    name: str
    sensor: str
    axis: str
    values: np.ndarray
    unit: str | None = None


@dataclass
class Recording:
    """What a reader found in a file (samples in the file's own units)."""

    path: Path
    format: str
    channels: list[Channel]
    time: np.ndarray | None = None  # seconds, one per sample
    time_source: str | None = None  # e.g. "column 't'", "header stamps"
    topic: str | None = None
    notes: list[str] = field(default_factory=list)

    @property
    def n_samples(self) -> int:
        return int(self.channels[0].values.size) if self.channels else 0


def split_names(spec) -> list[str]:
    if spec is None:
        return []
    if isinstance(spec, list | tuple):
        return [str(s) for s in spec]
    return [s.strip() for s in str(spec).split(",") if s.strip()]


def axis_label(name: str, sensor: str) -> str:
    name = header_unit(name)[0]
    m = (_GYRO_RE if sensor == "gyro" else _ACCEL_RE).match(name)
    if m:
        letter = next((g for g in m.groups()[1:] if g), None)
        if letter:
            return {"0": "x", "1": "y", "2": "z"}.get(letter.lower(), letter.lower())
    return name


def _resolve(path, names: list[str], n_cols: int, spec: str, option: str, bases=()) -> int:
    if spec in names:
        return names.index(spec)
    if spec in bases and list(bases).count(spec) == 1:  # a name given without its bracketed unit
        return list(bases).index(spec)
    try:
        idx = int(spec)
    except ValueError:
        known = ", ".join(names) if names else f"indices 0..{n_cols - 1}"
        raise ValueError(f"{path}: unknown column {spec!r} ({option}); expected one of {known}") from None
    if not 0 <= idx < n_cols:
        raise ValueError(f"{path}: column index {idx} out of range ({option}); expected 0..{n_cols - 1}")
    return idx


def choose_columns(path, names: list[str], n_cols: int, gyro, accel, time_column):
    """(time index or None, [(index, sensor)]) for a table with ``names`` (auto names if none).

    A name's bracketed unit (:func:`header_unit`) says its sensor before its name does."""
    shown = names if names else [f"column {i}" for i in range(n_cols)]
    parsed = [header_unit(nm) for nm in names]
    bases = [b for b, _, _ in parsed]
    kinds = [k for _, k, _ in parsed]
    if time_column is not None and str(time_column).lower() == "none":
        t_idx = None
    elif time_column is not None:
        t_idx = _resolve(path, names, n_cols, str(time_column), "--time", bases)
    else:
        t_idx = next((i for i, k in enumerate(kinds) if k == "time"), None)
        if t_idx is None:
            t_idx = next((i for i, b in enumerate(bases) if b.lower() in TIME_NAMES), None)
    picks = [(_resolve(path, names, n_cols, s, "--gyro/--column", bases), "gyro") for s in split_names(gyro)]
    picks += [(_resolve(path, names, n_cols, s, "--accel", bases), "accel") for s in split_names(accel)]
    if not picks:
        rest = [i for i in range(n_cols) if i != t_idx]
        if len(rest) == 1:
            picks = [(rest[0], "gyro")]
        else:
            def sensor_of(i):
                if kinds[i] in ("gyro", "accel"):
                    return kinds[i]
                if kinds[i] is None and _GYRO_RE.match(bases[i]):
                    return "gyro"
                if kinds[i] is None and _ACCEL_RE.match(bases[i]):
                    return "accel"
                return None

            found = [(i, sensor_of(i)) for i in rest] if names else []
            picks = [(i, k) for i, k in found if k == "gyro"] + [(i, k) for i, k in found if k == "accel"]
            if not picks:
                listed = ", ".join(shown[i] for i in rest)
                raise ValueError(f"{path}: {len(rest)} columns ({listed}); choose them with --gyro COLS and/or "
                                 "--accel COLS (or one with --column NAME|INDEX)")
    idx = [i for i, _ in picks]
    if len(set(idx)) != len(idx) or t_idx in idx:
        raise ValueError(f"{path}: a column is chosen twice (--time/--gyro/--accel/--column)")
    return t_idx, picks


def numeric_array(arr, path, what="data"):
    arr = np.asarray(arr)
    if arr.dtype.kind not in "iuf":
        raise ValueError(f"{path}: {what} is not numeric (dtype {arr.dtype}); expected samples")
    return arr


def table_recording(path, fmt, arr, names, gyro, accel, time_column, time_units, time=None):
    """A Recording from a 1-D or 2-D numeric array (columns are views: no copy)."""
    if arr.ndim == 1:
        arr = arr[:, None]
    if arr.ndim != 2:
        raise ValueError(f"{path}: expected a 1-D record or a 2-D (samples x columns) table, got shape {arr.shape}")
    if arr.shape[0] == 0 or arr.shape[1] == 0:
        raise ValueError(f"{path}: the record is empty")
    names = names or []
    t_idx, picks = choose_columns(path, names, arr.shape[1], gyro, accel, time_column)
    rec = columns_recording(path, fmt, [arr[:, i] for i in range(arr.shape[1])], names, t_idx, picks, time_units)
    if t_idx is None and time is not None:
        t = np.asarray(time)
        if t.shape != (arr.shape[0],):
            raise ValueError(f"{path}: the time array has shape {t.shape}; expected ({arr.shape[0]},), one per sample")
        set_time(rec, path, t, time_units, None, "array 't'")
    return rec


def columns_recording(path, fmt, cols, names, t_idx, picks, time_units):
    """A Recording from columns (``picks``: [(index, sensor)]) with the units and sensor a header names."""
    n_cols = len(cols)
    label = (lambda i: names[i]) if names else (lambda i: f"column {i}")
    channels = []
    for i, sensor in picks:
        _, kind, unit = header_unit(label(i)) if names else (None, None, None)
        if kind is not None and kind != sensor:
            raise ValueError(f"{path}: column {label(i)!r} is chosen as {sensor} but its header says {unit} "
                             f"({'a time' if kind == 'time' else 'an angular rate' if kind == 'gyro' else 'an acceleration'}); "
                             f"expected {'--gyro' if kind == 'gyro' else '--accel' if kind == 'accel' else '--time'} for it")
        axis = axis_label(label(i), sensor) if names else ("x" if n_cols == 1 else str(i))
        channels.append(Channel(label(i), sensor, axis, cols[i], unit if kind == sensor else None))
    rec = Recording(Path(path), fmt, channels)
    if t_idx is not None:
        _, kind, unit = header_unit(label(t_idx)) if names else (None, None, None)
        set_time(rec, path, cols[t_idx], time_units, unit if kind == "time" else None, f"column {label(t_idx)!r}")
    return rec


def set_time(rec, path, t, time_units, declared, what):
    rec.time, unit, how = time_in_seconds(path, t, time_units, declared, what)
    rec.time_source = f"{what} ({unit}, from {how})"
    if how.startswith("its integer step") or how.startswith("the magnitude"):
        rec.notes.append(f"{what} read in {unit}: inferred from {how}")


def _time_scale(units) -> float:
    try:
        return _TIME_SCALE[units]
    except KeyError:
        raise ValueError(f"--time-units: expected one of {', '.join(_TIME_SCALE)}, got {units!r}") from None


def header_unit(name: str) -> tuple[str, str | None, str | None]:
    """(name without its unit, kind, unit) of a column name ending in a bracketed unit: kind is
    "gyro", "accel" or "time" and unit its avbench spelling (``[rad s^-1]`` -> ("gyro", "rad/s"),
    ``[m s^-2]`` -> ("accel", "m/s^2"), ``[ns]`` -> ("time", "ns")); (name, None, None) when there
    is no bracket or its unit is none of these (``[degC]``)."""
    from avbench.noise_models.units import SAMPLE_UNITS

    base = name.strip().lstrip("#").strip()
    m = _BRACKET_UNIT.match(base)
    if not m:
        return base, None, None
    u = m.group(2).strip().lower().replace("°", "deg").replace("µ", "u").replace("μ", "u")
    u = re.sub(r"\b(degrees|degree)\b", "deg", u)
    u = re.sub(r"\b(radians|radian)\b", "rad", u)
    u = re.sub(r"\s*\*\s*|\s+", " ", u)
    u = re.sub(r" ?\b(s|sec)\s*\^?\s*-1$", "/s", u)
    u = re.sub(r" ?\b(s|sec)\s*\^?\s*-2$", "/s^2", u)
    u = re.sub(r" ?\b(h|hr)\s*\^?\s*-1$", "/h", u)
    u = u.replace(" ", "")
    u = _UNIT_SPELLINGS.get(u, u)
    for kind, units in (("time", tuple(_TIME_SCALE)), ("gyro", SAMPLE_UNITS["gyro"]), ("accel", SAMPLE_UNITS["accel"])):
        if u in units:
            return m.group(1).strip(), kind, u
    return base, None, None


def time_in_seconds(path, t, time_units=None, declared=None, what="the time column"):
    """(seconds since the first stamp as float64, the unit used, how it was chosen) for raw stamps ``t``.

    The unit: ``time_units`` (the user's) if given, else ``declared`` (the file's header), else the
    rule of the module docstring (epoch magnitude, then the step of integer stamps, then seconds).
    Integer stamps are differenced in int64 first, so 1.4e18 ns keep every nanosecond."""
    t = np.asarray(t)
    if t.ndim != 1 or t.size == 0:
        raise ValueError(f"{path}: {what} has shape {t.shape}; expected one time stamp per sample")
    if t.dtype.kind not in "iuf":
        raise ValueError(f"{path}: {what} is not numeric (dtype {t.dtype}); expected time stamps")
    integer = t.dtype.kind in "iu"
    if time_units is not None:
        unit, how = time_units, "--time-units"
        _time_scale(unit)
    elif declared is not None:
        unit, how = declared, "the header"
    else:
        unit, how = _infer_time_unit(t, integer)
    rel = (t - t[0]) if integer else t
    return np.asarray(rel, dtype=np.float64) * _time_scale(unit), unit, how


def _infer_time_unit(t, integer):
    t0 = abs(float(t[0]))
    finite = np.isfinite(t0)
    if finite and t0 >= _EPOCH_S[0]:
        for u, f in _TIME_SCALE.items():
            if _EPOCH_S[0] <= t0 * f < _EPOCH_S[1]:
                return u, f"the magnitude of its epoch stamps ({t0:.4g})"
    whole = integer or (t.size > 1 and bool(np.all(np.isfinite(t[:1000])) and np.all(t[:1000] == np.round(t[:1000]))))
    if whole and t.size > 1:
        d = np.diff(t[: min(t.size, 10001)])
        step = float(np.median(d))
        if step > 0:
            for u, f in _TIME_SCALE.items():
                if _STEP_RATE[0] <= 1.0 / (step * f) < _STEP_RATE[1]:
                    return u, f"its integer step ({step:.6g} -> {1 / (step * f):.6g} Hz; --time-units to override)"
    return "s", "the default (seconds)"
