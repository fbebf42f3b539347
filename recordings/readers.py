"""Step 1: read a recording file into named channels, their sensor, their units and the time stamps.

One reader per container, behind the one call :func:`read_recording` (chosen by the file name):

* text ``.csv .txt .dat .tsv`` -- comma, semicolon, tab or blank separated, ``#`` comments, an
  optional header row (a first row none of whose cells is a number) or, as in EuRoC / TUM-VI /
  Kalibr files, a header in the last ``#`` comment line before the data (``#timestamp [ns],w_RS_S_x
  [rad s^-1],...``) when it splits into as many names as the data has columns. The separator is the one under
  which the first data lines split into equally many numeric cells and the header into as many names
  (:func:`_dialect`): a header's own spaces do not make columns. Parsed by pandas' C engine
  straight to float64 (an integer time column to int64: 1.4e18 ns stamps hold a 10 ms step exactly;
  ``bench/`` measures it against a bare ``pandas.read_csv``). A blank line
  between samples is an error (it is not silently dropped); so is a file that looks written with
  decimal commas (``0,0123``) under a comma separator; with ``;``/tab/blank separators decimal commas
  are read as such.
* ``.npy`` -- 1-D, or 2-D samples x columns; memory-mapped, so a large record is not copied.
* ``.npz`` -- the array ``data`` (column names from ``columns``, time stamps from ``t`` or ``time``),
  or named arrays (``gyro`` n x 3, ``accel`` n x 3, ``t``; any names with ``--gyro NAME``,
  ``--accel NAME``, ``--time NAME``): see :func:`_arrays_recording`.
* MATLAB ``.mat`` -- v4-v7 through ``scipy.io.loadmat``; v7.3 (HDF5) through ``h5py`` (``pip install
  avbench[mat73]``); variables (struct fields as ``struct.field``) are named arrays as in an ``.npz``.
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
accelerometer, a time unit the time column). A unit written as a name suffix (``gyro_x_dps``) is
only an axis label: units come from the format, a bracket, or the user, never guessed from a name.

**Time units** (:func:`time_in_seconds`): ``time_units`` when given; else the header's bracket; else,
for epoch stamps (first stamp >= 1e8), the unit that puts the first stamp between 1973 and 2286;
else, for integer stamps, the unit that makes the median step a rate between 5 Hz and 5 kHz (a
note says so); else seconds. Integer stamps are differenced as int64 before conversion.

For tables the channels are chosen with ``gyro``/``accel`` (names or 0-based indices); with neither, a
single column is a gyro, and headers named like ``gyro_x``/``gx``/``wx``/``w_RS_S_x``/``omega_x`` and
``acc_x``/``ax``/``a_RS_S_x``/``alpha_x`` are found. A column named ``t``, ``time``, ``timestamp`` or ``time_s`` (or chosen with ``time_column``) gives the
time stamps. Every problem is a ``ValueError`` whose message starts with the file name.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from avbench.recordings import files as data_files

__all__ = ["Channel", "Recording", "read_recording", "TEXT_SUFFIXES", "KNOWN_SUFFIXES"]

TEXT_SUFFIXES = (".csv", ".txt", ".dat", ".tsv")
KNOWN_SUFFIXES = (".npy", ".npz", ".mat", *TEXT_SUFFIXES, ".bag", ".db3", ".mcap", ".ulg")
_TIME_NAMES = {"t", "time", "timestamp", "time_s", "times", "t_s"}
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


def _split(spec) -> list[str]:
    if spec is None:
        return []
    if isinstance(spec, list | tuple):
        return [str(s) for s in spec]
    return [s.strip() for s in str(spec).split(",") if s.strip()]


def _axis_label(name: str, sensor: str) -> str:
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


def _choose_columns(path, names: list[str], n_cols: int, gyro, accel, time_column):
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
            t_idx = next((i for i, b in enumerate(bases) if b.lower() in _TIME_NAMES), None)
    picks = [(_resolve(path, names, n_cols, s, "--gyro/--column", bases), "gyro") for s in _split(gyro)]
    picks += [(_resolve(path, names, n_cols, s, "--accel", bases), "accel") for s in _split(accel)]
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


def _numeric(arr, path, what="data"):
    arr = np.asarray(arr)
    if arr.dtype.kind not in "iuf":
        raise ValueError(f"{path}: {what} is not numeric (dtype {arr.dtype}); expected samples")
    return arr


def _table_recording(path, fmt, arr, names, gyro, accel, time_column, time_units, time=None):
    """A Recording from a 1-D or 2-D numeric array (columns are views: no copy)."""
    if arr.ndim == 1:
        arr = arr[:, None]
    if arr.ndim != 2:
        raise ValueError(f"{path}: expected a 1-D record or a 2-D (samples x columns) table, got shape {arr.shape}")
    if arr.shape[0] == 0 or arr.shape[1] == 0:
        raise ValueError(f"{path}: the record is empty")
    names = names or []
    t_idx, picks = _choose_columns(path, names, arr.shape[1], gyro, accel, time_column)
    rec = _columns_recording(path, fmt, [arr[:, i] for i in range(arr.shape[1])], names, t_idx, picks, time_units)
    if t_idx is None and time is not None:
        t = np.asarray(time)
        if t.shape != (arr.shape[0],):
            raise ValueError(f"{path}: the time array has shape {t.shape}; expected ({arr.shape[0]},), one per sample")
        _set_time(rec, path, t, time_units, None, "array 't'")
    return rec


def _columns_recording(path, fmt, cols, names, t_idx, picks, time_units):
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
        axis = _axis_label(label(i), sensor) if names else ("x" if n_cols == 1 else str(i))
        channels.append(Channel(label(i), sensor, axis, cols[i], unit if kind == sensor else None))
    rec = Recording(Path(path), fmt, channels)
    if t_idx is not None:
        _, kind, unit = header_unit(label(t_idx)) if names else (None, None, None)
        _set_time(rec, path, cols[t_idx], time_units, unit if kind == "time" else None, f"column {label(t_idx)!r}")
    return rec


def _set_time(rec, path, t, time_units, declared, what):
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


# -- text -----------------------------------------------------------------------------------------
def _first_lines(path, k=20):
    """(number of leading comment/blank lines, the first k data lines, the last leading comment line or None)."""
    lead, lines, comment = 0, [], None
    try:
        with open(path, encoding="utf-8", errors="strict") as fh:
            for line in fh:
                s = line.strip()
                if not lines and (not s or s.startswith("#")):
                    lead += 1
                    comment = s if s else comment
                    continue
                lines.append(s)
                if len(lines) >= k:
                    break
    except UnicodeDecodeError:
        raise ValueError(f"{path}: not a text file (cannot decode as UTF-8)") from None
    except OSError as e:
        raise ValueError(f"{path}: cannot read ({e.strerror or e})") from None
    if not lines:
        raise ValueError(f"{path}: the file is empty")
    return lead, lines, comment


_LEADING_ZERO_INT = re.compile(r"^[+-]?0\d+$")
_INT = re.compile(r"^[+-]?\d+$")


#: candidate separators, in the order of preference among those that fit (see :func:`_dialect`)
_SEPARATORS = (";", "\t", ",", r"\s+")


def _split_cells(line, sep):
    return re.split(sep, line.strip()) if sep == r"\s+" else line.split(sep)


def _is_number(cell, decimal) -> bool:
    s = cell.strip()
    if decimal == ",":
        if "." in s:
            return False
        s = s.replace(",", ".")
    try:
        float(s)
    except ValueError:
        return False
    return True


def _fitting_dialects(lines):
    """Every (separator, decimal mark, number of columns) under which the first lines are a table:
    each data line splits into the same number k of numeric cells and a header row (a first row none of
    whose cells is a number) into k names. The header's own structure decides with the data: a
    one-column file whose header holds a space (``gyro x [deg/s]``) is one column, not two."""
    rows = [ln for ln in lines if ln and not ln.startswith("#")]
    out = []
    for sep in _SEPARATORS:
        cells = [_split_cells(ln, sep) for ln in rows]
        for decimal in ((".",) if sep == "," else (".", ",")):
            header = _is_header(cells[0], decimal)
            data = cells[1:] if header else cells
            if not data:
                continue
            k = len(data[0])
            if any(len(c) != k for c in data) or (header and len(cells[0]) != k):
                continue
            if all(_is_number(c, decimal) for row in data for c in row):
                out.append((sep, decimal, k))
                break
    return out


def _is_header(cells, decimal) -> bool:
    """A header row: none of its cells is a number (with this decimal mark, or as ``nan``/``inf``)."""
    return data_files.is_header_row(cells) and not (decimal == "," and any(_is_number(c, ",") for c in cells))


def _dialect(path, lines):
    """(separator, decimal mark) of a text table from its first data lines.

    The rule: the separators under which the first lines form a table (:func:`_fitting_dialects`),
    the most columns first, then ``;``, tab, ``,``, blanks; a decimal comma only where ``,`` is not
    the separator. A file that fits none (an empty field, a text cell) gets the reading of its first
    line, so that pandas' error or the checks after it name the faulty line.
    """
    fits = _fitting_dialects(lines)
    if fits:
        k_max = max(k for _, _, k in fits)
        sep, decimal, _ = next(f for f in fits if f[2] == k_max)
        if sep == ",":
            _decimal_comma_check(path, lines)
        return sep, decimal
    first = lines[0]
    for sep in (";", "\t"):
        if sep in first:
            return sep, ("," if any("," in c for ln in lines[1:] or lines for c in ln.split(sep)) else ".")
    if "," in first:
        _decimal_comma_check(path, lines)
        return ",", "."
    if any("," in c for ln in lines[1:] or lines for c in ln.split()):
        return r"\s+", ","
    return r"\s+", "."


def _decimal_comma_check(path, lines):
    """Refuse a comma-separated table that looks written with decimal commas (every cell an integer,
    some with a leading zero: ``0,0123``)."""
    data = [ln for ln in lines if ln and not ln.startswith("#")]
    cells = [c.strip() for ln in data[1:] or data for c in ln.split(",")]
    if cells and all(_INT.match(c) for c in cells) and any(_LEADING_ZERO_INT.match(c) for c in cells):
        raise ValueError(f"{path}: looks written with decimal commas ({data[-1]!r}); expected '.' as the decimal "
                         "mark with ',' separators (or ';'/tab separated columns with decimal commas)")


def _read_text(path, gyro, accel, time_column, time_units):
    import pandas as pd

    lead, lines, last_comment = _first_lines(path)
    sep, decimal = _dialect(path, lines)
    cells = _split_cells(lines[0], sep)
    header = _is_header(cells, decimal)
    names = [c.strip() for c in cells] if header else None
    if names is None and last_comment is not None:  # EuRoC / TUM-VI: "#timestamp [ns],w_RS_S_x [rad s^-1],..."
        k = len(_split_cells(lines[0], sep))
        cand = [c.strip() for c in _split_cells(last_comment.lstrip("#").strip(), sep)]
        if k > 1 and len(cand) == k and all(cand) and _is_header(cand, decimal):
            names = cand
    n_cols = len(names) if names else len(_split_cells(lines[1] if header and len(lines) > 1 else lines[0], sep))
    try:  # the time column, to read it as int64 when it holds integers; a bad choice is said after parsing
        t_idx = _choose_columns(path, names or [], n_cols, gyro, accel, time_column)[0]
    except ValueError:
        t_idx = None
    dtype = np.float64
    if t_idx is not None and _integer_column(lines[int(header):], sep, t_idx):
        key = names[t_idx] if names else t_idx
        dtype = {(nm if names else j): np.float64 for j, nm in enumerate(names or range(n_cols))}
        dtype[key] = np.int64
    try:
        try:
            df = pd.read_csv(path, sep=sep, decimal=decimal, header=None, skiprows=lead + int(header), comment="#",
                             skip_blank_lines=False, engine="c", dtype=dtype, names=names)
        except (ValueError, OverflowError):
            if dtype is np.float64:
                raise
            df = pd.read_csv(path, sep=sep, decimal=decimal, header=None, skiprows=lead + int(header), comment="#",
                             skip_blank_lines=False, engine="c", dtype=np.float64, names=names)
    except pd.errors.EmptyDataError:
        raise ValueError(f"{path}: a header but no samples" if header else f"{path}: the file is empty") from None
    except (ValueError, pd.errors.ParserError) as e:
        raise _explain_text_error(path, lead + int(header), sep, decimal, e) from None
    except UnicodeDecodeError:
        raise ValueError(f"{path}: not a text file (cannot decode as UTF-8)") from None
    except OSError as e:
        raise ValueError(f"{path}: cannot read ({e.strerror or e})") from None
    if df.shape[0] == 0:
        raise ValueError(f"{path}: a header but no samples" if header else f"{path}: the file is empty")
    df = _trailing_blank_rows(path, df, lead + int(header))
    if df.shape[1] != n_cols:
        raise ValueError(f"{path}: {df.shape[1]} columns where the first lines have {n_cols}; expected one table")
    arr_cols = [df.iloc[:, i].to_numpy() for i in range(df.shape[1])]
    nm = names or []
    label = (lambda i: nm[i]) if nm else (lambda i: f"column {i}")
    for i in range(n_cols):  # the file's own faults first, then the choice of columns
        if arr_cols[i].dtype.kind == "f":
            _blank_line_check(path, arr_cols[i], lead + int(header), label(i))
    t_idx, picks = _choose_columns(path, nm, n_cols, gyro, accel, time_column)
    return _columns_recording(path, "text", arr_cols, nm, t_idx, picks, time_units)


def _integer_column(lines, sep, j) -> bool:
    """True if cell ``j`` of every one of the first data lines is an integer (read it as int64)."""
    rows = [_split_cells(ln, sep) for ln in lines if ln and not ln.startswith("#")]
    return bool(rows) and all(len(r) > j and _INT.match(r[j].strip()) for r in rows)


def _trailing_blank_rows(path, df, skip):
    """Drop blank lines at the very end of the file (and only there)."""
    nan_rows = df.isna().all(axis=1).to_numpy()
    if not nan_rows[-1]:
        return df
    k = len(nan_rows) - np.argmin(nan_rows[::-1]) if not nan_rows.all() else 0
    with open(path, encoding="utf-8") as fh:
        tail = fh.read().splitlines()[skip + k:]
    if all(not ln.strip() for ln in tail):
        return df.iloc[:k]
    return df


def _blank_line_check(path, col, skip, label):
    """Say *why* a column holds NaN where the file has a blank line (instead of a NaN sample)."""
    bad = np.flatnonzero(np.isnan(col))
    if bad.size == 0:
        return
    i = int(bad[0])
    with open(path, encoding="utf-8") as fh:
        for k, line in enumerate(fh):
            if k == skip + i:
                if not line.strip():
                    raise ValueError(f"{path}: line {k + 1} is blank (sample {i} of {label}); expected one sample "
                                     "per line -- remove the blank line or mark the gap with time stamps")
                if line.strip().startswith("#"):
                    raise ValueError(f"{path}: line {k + 1} is a comment between samples (sample {i} of {label}); "
                                     "expected comments only before the data")
                if "," in line or ";" in line or "\t" in line:
                    raise ValueError(f"{path}: line {k + 1} has an empty field (sample {i} of {label}); "
                                     "expected a number in every field")
                break


def _explain_text_error(path, skip, sep, decimal, err):
    """A one-line message for a table pandas could not read as float64 (found by a slow re-read)."""
    import pandas as pd

    try:
        df = pd.read_csv(path, sep=sep, decimal=decimal, header=None, skiprows=skip, comment="#",
                         skip_blank_lines=False, engine="python", dtype=str)
    except (pd.errors.ParserError, ValueError) as e:
        return ValueError(f"{path}: cannot parse as a text table ({str(e).splitlines()[0][:200]})")
    except UnicodeDecodeError:
        return ValueError(f"{path}: not a text file (cannot decode as UTF-8)")
    for j in range(df.shape[1]):
        col = df.iloc[:, j]
        vals = pd.to_numeric(col, errors="coerce")
        bad = vals.isna() & col.notna() & (col.astype(str).str.strip().str.lower() != "nan")
        if bad.any():
            i = int(np.flatnonzero(bad.to_numpy())[0])
            return ValueError(f"{path}: column {j} is not numeric (row {i}: {col.iloc[i]!r}); expected samples")
    return ValueError(f"{path}: cannot parse as a text table ({str(err).splitlines()[0][:200]})")


# -- NumPy ----------------------------------------------------------------------------------------
def _read_npy(path, gyro, accel, time_column, time_units):
    arr = _numeric(data_files.load_npy(path, mmap=True), path)
    return _table_recording(path, "npy", arr, None, gyro, accel, time_column, time_units)


def _read_npz(path, gyro, accel, time_column, time_units):
    z = data_files.load_npz(path)
    keys = list(z)
    time_key = next((k for k in ("t", "time") if k in keys), None)
    if "data" in keys:
        arr = z["data"]
    else:
        arrays = [k for k in keys if k not in ("columns", "fs", time_key)]
        named = [x for x in (*_split(gyro), *_split(accel), *_split(time_column)) if x in keys]
        if len(arrays) != 1 or named:  # named arrays; a single array's columns are chosen as a table's
            return _arrays_recording(path, "npz", z, gyro, accel, time_column, time_units)
        arr = z[arrays[0]]
    arr = _numeric(arr, path)
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
        time = _numeric(z[time_key], path, f"'{time_key}'")
    return _table_recording(path, "npz", arr, names, gyro, accel, time_column, time_units, time)


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
        for nm in _split(spec):
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
        t_name = next((k for k in usable if k.lower() in _TIME_NAMES), None)
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
                axis = _axis_label(k, sensor) if singles > 1 else "x"
            else:
                axis = "xyz"[j] if x.shape[1] <= 3 else str(j)
            channels.append(Channel(k if x.shape[1] == 1 else f"{k}[{j}]", sensor, axis, x[:, j]))
    rec = Recording(Path(path), fmt, channels)
    if t_name is not None:
        t = np.asarray(arrays[t_name]).reshape(-1)
        if t.size != n:
            raise ValueError(f"{path}: the time variable {_describe(t_name, arrays[t_name])} has {t.size} stamps for "
                             f"{n} samples; expected one per sample")
        _set_time(rec, path, t, time_units, None, f"variable {t_name!r}")
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


def _read_mat(path, gyro, accel, time_column, time_units):
    return _arrays_recording(path, "mat", _mat_arrays(path), gyro, accel, time_column, time_units)


# -- ROS bags ---------------------------------------------------------------------------------------
_IMU_TYPES = ("sensor_msgs/msg/Imu", "sensor_msgs/Imu")


def _bag_path(path: Path) -> Path:
    if path.is_dir() or path.suffix == ".bag":
        return path
    return path.parent  # a ROS 2 storage file: the bag is its folder


def _read_bag(path, topic, progress):
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
        t, rec.time_source = stamp, "header stamps"
    else:
        t, rec.time_source = recv, "bag receive times (every header stamp is zero)"
        rec.notes.append("header stamps are all zero; the bag's receive times are used")
    order = np.argsort(t, kind="stable")
    if np.any(order != np.arange(k)):
        rec.notes.append("messages were not in time order; sorted by time stamp")
        out, t = out[order], t[order]
    rec.time = (t - t[0]).astype(np.float64) * 1e-9
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
def _read_ulog(path, progress):
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
    rec = Recording(Path(path), "ulog", [], topic="sensor_combined", time_source="timestamp (us)")
    t = np.asarray(d["timestamp"], dtype=np.int64)
    rec.time = (t - t[0]).astype(np.float64) * 1e-6
    for i, axis in enumerate("xyz"):
        rec.channels.append(Channel(f"gyro_rad[{i}]", "gyro", axis, np.asarray(d[f"gyro_rad[{i}]"], dtype=np.float64), "rad/s"))
    for i, axis in enumerate("xyz"):
        rec.channels.append(Channel(f"accelerometer_m_s2[{i}]", "accel", axis,
                                    np.asarray(d[f"accelerometer_m_s2[{i}]"], dtype=np.float64), "m/s^2"))
    return rec


# -- entry point ------------------------------------------------------------------------------------
def read_recording(path, *, gyro=None, accel=None, time_column=None, time_units=None, topic=None,
                   progress=False) -> Recording:
    """Read ``path`` (any format of the module docstring) into a :class:`Recording`.

    ``gyro``/``accel``: column names or indices (comma-separated string or list) of a table;
    ``time_column``: the time column (``"none"`` to ignore one); ``time_units``: s, ms, us or ns
    (None: from the file, see :func:`time_in_seconds`);
    ``topic``: the ``sensor_msgs/Imu`` topic of a bag.
    """
    p = Path(path)
    is_bag = p.suffix.lower() in (".bag", ".db3", ".mcap") or (p.is_dir() and (p / "metadata.yaml").is_file())
    if is_bag:
        data_files.check_path_kind(p, allow_dir=True)
        rec = _read_bag(p, topic, progress)
    else:
        p = data_files.check_file(p)
        suffix = p.suffix.lower()
        if suffix == ".npy":
            rec = _read_npy(p, gyro, accel, time_column, time_units)
        elif suffix == ".npz":
            rec = _read_npz(p, gyro, accel, time_column, time_units)
        elif suffix == ".mat":
            rec = _read_mat(p, gyro, accel, time_column, time_units)
        elif suffix in TEXT_SUFFIXES:
            rec = _read_text(p, gyro, accel, time_column, time_units)
        elif suffix == ".ulg":
            rec = _read_ulog(p, progress)
        else:
            raise ValueError(f"{p}: unknown file type {suffix!r}; expected one of {', '.join(KNOWN_SUFFIXES)} "
                             "or a ROS 2 bag folder")
    if topic is not None and rec.format not in ("ros1", "ros2"):
        raise ValueError(f"--topic: {p} is not a ROS bag; expected --topic only with a bag")
    if rec.n_samples == 0:
        raise ValueError(f"{p}: the record is empty")
    return rec
