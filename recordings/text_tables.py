"""Text tables (``.csv .txt .dat .tsv``), read by their structure:

* **Encoding.** UTF-8, a leading byte-order mark (Excel's "CSV UTF-8") dropped.
* **Fields.** Lines split as RFC 4180 says: fields in double quotes may hold the separator, and the
  quotes are not part of the field (R's ``write.csv`` quotes every header name); with blank
  separators, quoted fields may hold blanks.
* **Dialect** (:func:`_dialect`): the separator and decimal mark under which the first data lines split
  into equally many numeric fields and a header row into as many names; the most fields first, then
  ``;``, tab, ``,``, blanks; a decimal comma only where ``,`` is not the separator.
* **Shape.** Every line has as many fields as the first data line, and a header as many names: a
  header with one name fewer than the fields (a table written with its row index) is refused, never
  read with the first field as an index and every name shifted onto the next column.
* **Decimal commas under comma separators** (:func:`_decimal_comma_check`) are refused whatever the
  exponent: a table whose fields hold no ``.`` and are all integers or digits with an exponent
  (``5e-03``, only after an integer field), some of them a fraction's marks (a leading zero, ``0123``,
  or an exponent), was written as ``0,0123`` or ``1,5e-03``.

Parsed by pandas' C parser straight to float64 (an integer time column to int64), with a one-line
message naming the line for every fault of the file. The other rules are those of
:mod:`avbench.recordings.readers`.
"""

from __future__ import annotations

import csv
import re
import shlex

import numpy as np

from avbench.recordings import files as data_files
from avbench.recordings.channels import choose_columns, columns_recording

__all__ = ["read_text"]


#: the encoding of text tables: UTF-8, its byte-order mark (if any) dropped
ENCODING = "utf-8-sig"


def _first_lines(path, k=100):
    """(number of leading comment/blank lines, the first k data lines, the last leading comment line or None)."""
    lead, lines, comment = 0, [], None
    try:
        with open(path, encoding=ENCODING, errors="strict") as fh:
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
_FRACTION_EXP = re.compile(r"^\d+[eE][+-]?\d+$")  # the fraction of 1,5e-03 after the comma


#: candidate separators, in the order of preference among those that fit (see :func:`_dialect`)
_SEPARATORS = (";", "\t", ",", r"\s+")


def _split_cells(line, sep):
    """The fields of one line under ``sep`` (RFC 4180 quoting; blanks: quoted fields may hold blanks)."""
    line = line.strip()
    if '"' not in line:
        return re.split(sep, line) if sep == r"\s+" else line.split(sep)
    if sep == r"\s+":
        try:
            return shlex.split(line, posix=True)
        except ValueError:  # an unbalanced quote: split as written, the checks after it name the line
            return re.split(sep, line)
    return next(csv.reader([line], delimiter=sep, quotechar='"')) if line else [""]


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
    the separator. A file that fits none (an empty field, a text cell, a header that names the fields
    wrongly) gets the reading of its first data line, so that the checks after it name the faulty line.
    """
    fits = _fitting_dialects(lines)
    if fits:
        k_max = max(k for _, _, k in fits)
        sep, decimal, _ = next(f for f in fits if f[2] == k_max)
        if sep == ",":
            _decimal_comma_check(path, lines)
        return sep, decimal
    first = lines[0]
    if len(lines) > 1 and data_files.is_header_row(re.split(r"[;,\s]+", first.strip())):
        first = lines[1]  # the header row's own separators do not decide
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
    """Refuse a comma-separated table written with decimal commas (the rule of the module docstring):
    ``0,0123`` and ``1,5e-03`` split at their decimal comma."""
    data = [ln for ln in lines if ln and not ln.startswith("#")]
    rows = [[c.strip() for c in _split_cells(ln, ",")] for ln in data]
    rows = [r for r in rows if not data_files.is_header_row(r)] or rows
    marks = False
    for r in rows:
        for j, c in enumerate(r):
            if _FRACTION_EXP.match(c):
                if j == 0 or not _INT.match(r[j - 1]):
                    return
                marks = True
            elif not _INT.match(c):
                return
            elif j > 0 and _LEADING_ZERO_INT.match(c):
                marks = True
    if marks:
        raise ValueError(f"{path}: looks written with decimal commas ({data[-1]!r}); expected '.' as the decimal "
                         "mark with ',' separators (or ';'/tab separated columns with decimal commas)")


def _shape_check(path, lead, rows, names, header):
    """Every first data line has as many fields as the first; a header as many names (see the module
    docstring). ``rows``: the fields of the first lines (the header's first when ``header``)."""
    data = rows[1:] if header else rows
    first = next((i for i, r in enumerate(data) if r != [""] and not r[0].startswith("#")), None)
    if first is None:
        return
    k = len(data[first])
    line0 = lead + int(header) + first + 1
    for i, r in enumerate(data):
        if r == [""] or r[0].startswith("#") or len(r) == k:
            continue
        line = lead + int(header) + i + 1
        raise ValueError(f"{path}: cannot parse as a text table: line {line} has {len(r)} field(s) where line "
                         f"{line0} has {k}; expected the same number of fields on every line")
    if names is not None and len(names) != k:
        what = ("a header with no name for the first field (a row index?)" if len(names) == k - 1 else
                "one name per field")
        raise ValueError(f"{path}: the header names {len(names)} column(s) but line {line0} has {k} fields; expected "
                         f"{what} -- fix the header, or remove the index column")


def read_text(path, gyro, accel, time_column, time_units):
    import pandas as pd

    lead, lines, last_comment = _first_lines(path)
    sep, decimal = _dialect(path, lines)
    rows = [_split_cells(ln, sep) for ln in lines]
    header = _is_header(rows[0], decimal)
    names = [c.strip() for c in rows[0]] if header else None
    if names is None and last_comment is not None:  # EuRoC / TUM-VI: "#timestamp [ns],w_RS_S_x [rad s^-1],..."
        k = len(rows[0])
        cand = [c.strip() for c in _split_cells(last_comment.lstrip("#").strip(), sep)]
        if k > 1 and len(cand) == k and all(cand) and _is_header(cand, decimal):
            names = cand
    _shape_check(path, lead, rows, names if header else None, header)
    n_cols = len(names) if names else len(rows[1] if header and len(rows) > 1 else rows[0])
    try:  # the time column, to read it as int64 when it holds integers; a bad choice is said after parsing
        t_idx = choose_columns(path, names or [], n_cols, gyro, accel, time_column)[0]
    except ValueError:
        t_idx = None
    dtype = np.float64
    if t_idx is not None and _integer_column(lines[int(header):], sep, t_idx):
        dtype = {j: np.float64 for j in range(n_cols)}
        dtype[t_idx] = np.int64
    options = dict(sep=sep, decimal=decimal, header=None, skiprows=lead + int(header), comment="#",
                   skip_blank_lines=False, engine="c", encoding=ENCODING, quotechar='"')
    try:
        try:
            df = pd.read_csv(path, dtype=dtype, **options)
        except (ValueError, OverflowError):
            if dtype is np.float64:
                raise
            df = pd.read_csv(path, dtype=np.float64, **options)
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
            _blank_line_check(path, arr_cols[i], lead + int(header), label(i), sep, n_cols)
    t_idx, picks = choose_columns(path, nm, n_cols, gyro, accel, time_column)
    return columns_recording(path, "text", arr_cols, nm, t_idx, picks, time_units)


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
    with open(path, encoding=ENCODING) as fh:
        tail = fh.read().splitlines()[skip + k:]
    if all(not ln.strip() for ln in tail):
        return df.iloc[:k]
    return df


def _blank_line_check(path, col, skip, label, sep, n_cols):
    """Say *why* a column holds NaN where the file has a blank line, a comment, an empty field or a line
    with fewer fields (instead of a NaN sample)."""
    bad = np.flatnonzero(np.isnan(col))
    if bad.size == 0:
        return
    i = int(bad[0])
    with open(path, encoding=ENCODING) as fh:
        for k, line in enumerate(fh):
            if k == skip + i:
                if not line.strip():
                    raise ValueError(f"{path}: line {k + 1} is blank (sample {i} of {label}); expected one sample "
                                     "per line -- remove the blank line or mark the gap with time stamps")
                if line.strip().startswith("#"):
                    raise ValueError(f"{path}: line {k + 1} is a comment between samples (sample {i} of {label}); "
                                     "expected comments only before the data")
                fields = _split_cells(line.split("#", 1)[0], sep)
                if len(fields) < n_cols:
                    raise ValueError(f"{path}: cannot parse as a text table: line {k + 1} has {len(fields)} field(s) "
                                     f"where the table has {n_cols}; expected the same number of fields on every line")
                if any(not f.strip() for f in fields):
                    raise ValueError(f"{path}: line {k + 1} has an empty field (sample {i} of {label}); "
                                     "expected a number in every field")
                break


def _explain_text_error(path, skip, sep, decimal, err):
    """A one-line message for a table pandas could not read as float64 (found by a slow re-read)."""
    import pandas as pd

    try:
        df = pd.read_csv(path, sep=sep, decimal=decimal, header=None, skiprows=skip, comment="#",
                         skip_blank_lines=False, engine="python", dtype=str, encoding=ENCODING, quotechar='"')
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
            return ValueError(f"{path}: line {skip + i + 1}: column {j} is not numeric ({col.iloc[i]!r}); expected "
                              "samples, as many fields on every line as on the first")
    return ValueError(f"{path}: cannot parse as a text table ({str(err).splitlines()[0][:200]})")
