"""Reading recordings given on the command line: every problem a ``ValueError`` naming the file.

Small shared helpers for the readers of ``avbench estimate`` (:mod:`avbench.recordings.readers`), for the
cases where NumPy's own errors do not name the file or are misleading:

* :func:`check_file` -- missing path (or a broken link), a folder, a FIFO/socket/device, an
  unreadable or empty file; :func:`check_path_kind` the same for a path that may be a folder
  (a ROS 2 bag);
* :func:`load_npy` / :func:`load_npz` -- a corrupt or non-NumPy file (NumPy raises a ValueError
  about "pickled (object) data" without the file name), an archive that is not a zip;
* :func:`check_distinct` -- the same file given twice where several recordings are read together
  (``--combine``, the three-cornered hat), naming both places;
* :func:`is_header_row` -- a first text row is a header only if none of its cells is a number,
  counting ``nan``/``inf`` spellings as numbers (a record starting with NaN must be rejected as
  non-finite, not silently read as a column named "nan").
"""

from __future__ import annotations

import os
import stat
import zipfile
from pathlib import Path

import numpy as np

__all__ = ["check_file", "check_path_kind", "check_distinct", "load_npy", "load_npz", "is_header_row"]

_NONFINITE_WORDS = {"nan", "+nan", "-nan", "inf", "+inf", "-inf", "infinity", "+infinity", "-infinity"}


_EXPECTED = "expected a recording file (.npy, .npz, .mat, .csv, .txt, .dat, .tsv, .bag, .ulg) or a ROS 2 bag folder"


def check_path_kind(path, allow_dir: bool = False, expected: str = _EXPECTED) -> Path:
    """``path`` as a Path if it is a readable regular file (or, with ``allow_dir``, a readable
    folder); else a ValueError saying what it is (missing, a broken link, a FIFO, a socket, a device,
    a folder, unreadable)."""
    path = Path(path)
    try:
        st = path.stat()
    except FileNotFoundError:
        if path.is_symlink():
            raise ValueError(f"{path}: a broken symbolic link (its target does not exist); {expected}") from None
        raise ValueError(f"{path}: no such file") from None
    except NotADirectoryError:
        raise ValueError(f"{path}: no such file (a parent of it is a file, not a folder)") from None
    except OSError as e:
        raise ValueError(f"{path}: cannot read ({e.strerror or e})") from None
    mode = st.st_mode
    if not (stat.S_ISDIR(mode) or stat.S_ISREG(mode)):
        from avbench.outputs import _kind  # the one naming of file kinds ("a FIFO", "a socket", ...)

        kind = _kind(mode)
        raise ValueError(f"{path}: is {kind}{' (named pipe)' if kind == 'a FIFO' else ''}; {expected}")
    if stat.S_ISDIR(mode):
        if not allow_dir:
            raise ValueError(f"{path}: is a folder; {expected}")
        try:
            os.listdir(path)
        except OSError as e:
            raise ValueError(f"{path}: cannot read the folder ({e.strerror or e})") from None
        return path
    try:
        with open(path, "rb") as fh:
            fh.read(1)
    except OSError as e:
        raise ValueError(f"{path}: cannot read ({e.strerror or e})") from None
    return path


def check_file(path) -> Path:
    """``path`` as a Path if it is a non-empty, readable regular file; else a ValueError saying what it is."""
    path = check_path_kind(path)
    if path.stat().st_size == 0:
        raise ValueError(f"{path}: the file is empty")
    return path


def load_npy(path, mmap: bool = False) -> np.ndarray:
    """The array of a ``.npy`` file (never unpickles; memory-mapped read-only with ``mmap``, so a large
    record costs no copy); a corrupt file is a ValueError naming it."""
    path = check_file(path)
    try:
        return np.load(path, allow_pickle=False, mmap_mode="r" if mmap else None)
    except Exception as e:  # ValueError (bad header / object array), OSError, EOFError, ...
        raise ValueError(f"{path}: not a readable .npy array ({_reason(e)})") from None


def load_npz(path) -> dict[str, np.ndarray]:
    """All arrays of a ``.npz`` archive, read eagerly; a corrupt archive is a ValueError naming it."""
    path = check_file(path)
    try:
        z = np.load(path, allow_pickle=False)
        if not isinstance(z, np.lib.npyio.NpzFile):
            raise ValueError("a single .npy array, not an .npz archive")
        with z:
            return {k: z[k] for k in z.files}
    except Exception as e:  # zipfile.BadZipFile, ValueError, OSError, EOFError, KeyError, ...
        raise ValueError(f"{path}: not a readable .npz archive ({_reason(e)})") from None


def is_header_row(cells) -> bool:
    """True if no cell of a first text row reads as a number (``nan``/``inf`` count as numbers)."""
    for c in cells:
        s = str(c).strip()
        if s.lower() in _NONFINITE_WORDS:
            return False
        try:
            float(s)
        except ValueError:
            continue
        return False
    return True


def _reason(e: BaseException) -> str:
    if isinstance(e, zipfile.BadZipFile):
        return "not a zip archive"
    text = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
    if "pickled" in text or "allow_pickle" in text:
        return "not a NumPy file, or one holding Python objects, which are never loaded"
    return text[:200]


def check_distinct(paths, whos=None, expected: str = "distinct recordings, each once") -> None:
    """Refuse the same file (by path, link or hard link) given twice among ``paths``; ``whos`` names each
    place in the message (default ``recording k (path)``)."""
    whos = whos or [f"recording {k + 1} ({p})" for k, p in enumerate(paths)]
    for i in range(len(paths)):
        for j in range(i):
            try:
                same = os.path.samefile(paths[i], paths[j])
            except OSError:
                same = os.path.realpath(paths[i]) == os.path.realpath(paths[j])
            if same:
                raise ValueError(f"{whos[i]} is the same file as {whos[j]}; expected {expected}")
