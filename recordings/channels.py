"""What every reader shares: the :class:`Recording` it returns, the units and sensor a column's header
states (:func:`header_unit`), time stamps in seconds (:func:`time_in_seconds`), and the choice of a
table's columns (:func:`choose_columns`). The rules are those of :mod:`avbench.recordings.readers`.
"""

from __future__ import annotations

import functools
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from avbench.recordings.time_units import TIME_SCALE, Stamps, check_time_units, stamps_in_seconds

__all__ = ["Channel", "Recording", "header_unit", "time_in_seconds", "TIME_NAMES", "split_names", "axis_label",
           "choose_columns", "numeric_array", "table_recording", "columns_recording", "set_time", "resolve_time",
           "listing", "KIND_WORDS", "samples_first"]

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
#: a unit in brackets at the end of a column name: ``w_RS_S_x [rad s^-1]``, ``acc (m/s^2)``
_BRACKET_UNIT = re.compile(r"^(.*?)\s*[\[(]\s*([^\[\]()]+?)\s*[\])]\s*$")
_UNIT_SPELLINGS = {"dps": "deg/s", "deg/sec": "deg/s", "degree/s": "deg/s", "degrees/s": "deg/s", "rps": "rad/s",
                   "rad/sec": "rad/s", "m/s2": "m/s^2", "m/s/s": "m/s^2", "m/sec^2": "m/s^2", "mps2": "m/s^2",
                   "sec": "s", "second": "s", "seconds": "s", "usec": "us", "msec": "ms", "nsec": "ns",
                   "deg/hr": "deg/h", "dph": "deg/h", "g0": "g"}
#: units of channels that are neither inertial nor time, read so that they are never taken for one:
#: magnetic flux density (G is gauss, g standard gravity) and temperature
_OTHER_UNITS = {"magnetic": ("G", "mG", "uG", "gauss", "Gs", "T", "mT", "uT", "nT"),
                "temperature": ("degC", "degF", "K")}
#: what a header's kind of unit says a column holds, in messages
KIND_WORDS = {"time": "a time", "gyro": "an angular rate", "accel": "an acceleration", "magnetic": "a magnetic field",
              "temperature": "a temperature"}
_LISTED = 8  #: names listed in a message before "..."


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
    time: np.ndarray | None = None  # seconds since the first stamp, one per sample
    time_origin: float | None = None  # the first stamp in seconds, on the file's own clock
    time_source: str | None = None  # e.g. "column 't'", "header stamps"
    topic: str | None = None
    notes: list[str] = field(default_factory=list)
    stamps: Stamps | None = None  # raw stamps until :func:`resolve_time` makes ``time`` of them
    time_resolution: float | None = None  # the stamps' resolution (s)
    rate: tuple[float, str] | None = None  # (Hz, what said it): a rate the file states (``fs``, ``dt``)

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
        known = listing(names) if names else f"indices 0..{n_cols - 1}"
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
                listed = listing(shown[i] for i in rest)
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


def samples_first(arr, path):
    """A 2-D (samples x columns) view of a 1-D or 2-D array: samples along its longer dimension (a record
    has more samples than columns; MATLAB and HDF5 store n x 3 as often as 3 x n)."""
    if arr.ndim == 1:
        arr = arr[:, None]
    if arr.ndim != 2:
        raise ValueError(f"{path}: expected a 1-D record or a 2-D (samples x columns) table, got shape {arr.shape}")
    if arr.shape[0] == 0 or arr.shape[1] == 0:
        raise ValueError(f"{path}: the record is empty")
    return arr.T if arr.shape[0] < arr.shape[1] else arr


def table_recording(path, fmt, arr, names, gyro, accel, time_column, time_units, time=None, time_what=None):
    """A Recording from a 1-D or 2-D numeric array (:func:`samples_first`; columns are views: no copy);
    ``time``: stamps kept beside the table (``time_what`` names them), used when no column is the time."""
    arr = samples_first(arr, path)
    names = names or []
    if names and len(names) != arr.shape[1]:
        raise ValueError(f"{path}: 'columns' names {len(names)} column(s) but the data has {arr.shape[1]}; "
                         "expected one name per column")
    t_idx, picks = choose_columns(path, names, arr.shape[1], gyro, accel, time_column)
    rec = columns_recording(path, fmt, [arr[:, i] for i in range(arr.shape[1])], names, t_idx, picks, time_units)
    if t_idx is None and time is not None:
        t = np.asarray(time)
        if t.shape != (arr.shape[0],):
            raise ValueError(f"{path}: the time array has shape {t.shape}; expected ({arr.shape[0]},), one per sample")
        set_time(rec, path, t, time_units, None, time_what or "the time array")
    return rec


def columns_recording(path, fmt, cols, names, t_idx, picks, time_units):
    """A Recording from columns (``picks``: [(index, sensor)]) with the units and sensor a header names."""
    n_cols = len(cols)
    label = (lambda i: names[i]) if names else (lambda i: f"column {i}")
    channels = []
    for i, sensor in picks:
        _, kind, unit = header_unit(label(i)) if names else (None, None, None)
        if kind is not None and kind != sensor:
            fix = {"gyro": "--gyro for it", "accel": "--accel for it", "time": "--time for it"}.get(
                kind, f"{'--gyro' if sensor == 'gyro' else '--accel'} to name {sensor} columns only")
            raise ValueError(f"{path}: column {label(i)!r} is chosen as {sensor} but its header says {unit} "
                             f"({KIND_WORDS[kind]}); expected {fix}")
        axis = axis_label(label(i), sensor) if names else ("x" if n_cols == 1 else str(i))
        channels.append(Channel(label(i), sensor, axis, cols[i], unit if kind == sensor else None))
    rec = Recording(Path(path), fmt, channels)
    if t_idx is not None:
        _, kind, unit = header_unit(label(t_idx)) if names else (None, None, None)
        set_time(rec, path, cols[t_idx], time_units, unit if kind == "time" else None, f"column {label(t_idx)!r}")
    return rec


def set_time(rec, path, t, time_units, declared, what):
    """Keep the raw stamps ``t`` of ``rec`` with what the file says of their unit (``declared``: a header's
    bracket); :func:`resolve_time` turns them into seconds once the whole file is read."""
    check_time_units(time_units)
    rec.stamps = Stamps(np.asarray(t), what, declared, "the header" if declared is not None else None)


@functools.lru_cache(maxsize=1)
def _unit_table() -> dict[str, tuple[str, str]]:
    """spelling -> (kind, unit) of every unit a header may state."""
    from avbench.noise_models.units import SAMPLE_UNITS

    table = {u: ("time", u) for u in TIME_SCALE}
    for kind in ("gyro", "accel"):
        table.update({u: (kind, u) for u in SAMPLE_UNITS[kind]})
    for alias, unit in _UNIT_SPELLINGS.items():
        table[alias] = table[unit]
    for kind, units in _OTHER_UNITS.items():
        table.update({u: (kind, u) for u in units})
    return table


def _match_unit(u: str) -> tuple[str, str] | None:
    """(kind, unit) of a normalised unit spelling: its exact (case-sensitive) spelling if known, else the
    one unit it spells whatever the case; None where the case would decide between units (``MG``: mg or mG)."""
    table = _unit_table()
    if u in table:
        return table[u]
    found = {v for k, v in table.items() if k.lower() == u.lower()}
    return found.pop() if len(found) == 1 else None


def header_unit(name: str) -> tuple[str, str | None, str | None]:
    """(name without its unit, kind, unit) of a column name ending in a bracketed unit: kind is
    "gyro", "accel", "time", "magnetic" or "temperature" and unit its avbench spelling (``[rad s^-1]`` ->
    ("gyro", "rad/s"), ``[m s^-2]`` -> ("accel", "m/s^2"), ``[ns]`` -> ("time", "ns"), ``[G]`` ->
    ("magnetic", "G"), ``[degC]`` -> ("temperature", "degC")); (name, None, None) when there is no
    bracket or its unit is none of these. Units are matched case-sensitively where case carries meaning
    (``g`` is standard gravity, ``G`` gauss; ``mg`` vs ``mG``), case-insensitively elsewhere (``RAD/S``)."""
    base = name.strip().lstrip("#").strip()
    m = _BRACKET_UNIT.match(base)
    if not m:
        return base, None, None
    u = m.group(2).strip().replace("°", "deg").replace("µ", "u").replace("μ", "u")
    u = re.sub(r"\b(degrees|degree)\b", "deg", u, flags=re.I)
    u = re.sub(r"\b(radians|radian)\b", "rad", u, flags=re.I)
    u = re.sub(r"\s*\*\s*|\s+", " ", u)
    u = re.sub(r" ?\b(s|sec)\s*\^?\s*-1$", "/s", u, flags=re.I)
    u = re.sub(r" ?\b(s|sec)\s*\^?\s*-2$", "/s^2", u, flags=re.I)
    u = re.sub(r" ?\b(h|hr)\s*\^?\s*-1$", "/h", u, flags=re.I)
    u = u.replace(" ", "")
    found = _match_unit(u)
    if found is None:
        return base, None, None
    return m.group(1).strip(), found[0], found[1]


def time_in_seconds(path, t, time_units=None, declared=None, what="the time column", fs=None):
    """(seconds since the first stamp as float64, the unit used, how it was chosen) for raw stamps ``t``.

    The unit: ``time_units`` (the user's) if given, else ``declared`` (the file's header, held to the
    rates an IMU samples at), else the plausibility rule of :mod:`avbench.recordings.time_units`
    (``fs``, if given, chooses between two plausible units). Integer stamps are differenced in int64
    first, so 1.4e18 ns keep every nanosecond."""
    stamps = Stamps(np.asarray(t), what, declared, "the header" if declared is not None else None)
    seconds, unit, how, _, _ = stamps_in_seconds(path, stamps, time_units, (fs, "--fs") if fs else None)
    return seconds, unit, how


def resolve_time(rec, time_units=None, fs=None) -> None:
    """Turn ``rec.stamps`` (raw, as the file holds them) into ``rec.time`` in seconds, with the unit's
    source in ``rec.time_source``, the stamps' resolution in ``rec.time_resolution`` and any inference in
    ``rec.notes``. ``fs`` (``--fs``), else the rate the file states, chooses between two plausible units."""
    if rec.stamps is None:
        return
    hint = (fs, "--fs") if fs else rec.rate
    seconds, unit, how, q, notes = stamps_in_seconds(rec.path, rec.stamps, time_units, hint)
    rec.time = seconds
    rec.time_origin = float(rec.stamps.values[0]) * TIME_SCALE[unit]
    rec.time_resolution = q
    rec.time_source = f"{rec.stamps.what} ({unit}, from {how})"
    rec.notes.extend(notes)
    rec.stamps = None


def listing(names, limit: int = _LISTED) -> str:
    """Names for a message: all of them, or the first ``limit`` and how many there are."""
    names = list(names)
    if len(names) <= limit:
        return ", ".join(names)
    return ", ".join(names[:limit]) + f", ... ({len(names)} in all)"
