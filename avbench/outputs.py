"""Output paths of every command: checked before any work, written whole.

One way for all commands (``avbench run``, ``estimate``, ``simulate``, ``bench``) to validate an
``--out`` and to write into it (inputs are checked by :func:`avbench.recordings.files.check_path_kind`):

* :func:`prepare_out_dir` refuses, with one line naming the option, the path and what was expected,
  an ``--out`` that is an existing file, lies under a file, cannot be created or written (a read-only
  file system, a missing permission), or where one of the command's output names is taken by a
  folder or a special file; only then does it create the folder;
* :func:`atomic_write_text` / :func:`atomic_write_bytes` write a file under a hidden temporary name
  and rename it into place, so a reader sees either the old file or the new one, never a part.
"""

from __future__ import annotations

import errno
import os
import stat
import uuid
from collections.abc import Iterable
from pathlib import Path

__all__ = ["OutputError", "prepare_out_dir", "atomic_write_text", "atomic_write_bytes", "tmp_name"]


#: significant digits of the committed numbers: results move by ~1e-12 (relative) between machines
#: and library versions, so the files that regeneration compares carry no more than the arithmetic
#: supports (tidy: estimates to 9 digits; tables: statistics to 6 digits)
TIDY_DIGITS = 9
TABLE_DIGITS = 6


class OutputError(ValueError):
    """An output location cannot be used; the message names the option, the path and the reason."""


def _kind(st_mode: int) -> str:
    if stat.S_ISDIR(st_mode):
        return "a folder"
    if stat.S_ISFIFO(st_mode):
        return "a FIFO"
    if stat.S_ISSOCK(st_mode):
        return "a socket"
    if stat.S_ISCHR(st_mode) or stat.S_ISBLK(st_mode):
        return "a device"
    if stat.S_ISREG(st_mode):
        return "a file"
    return "a special file"


def _reason(e: OSError) -> str:
    return os.strerror(e.errno) if e.errno else str(e)


def prepare_out_dir(path, option: str = "--out", outputs: Iterable[str] = ()) -> Path:
    """Check that ``path`` can hold the command's ``outputs`` (file names), then create it.

    Raises :class:`OutputError` naming ``option`` and ``path`` when ``path`` is an existing
    non-folder, a parent of it is a file, an output name is taken by a folder or a special file,
    or the folder cannot be created or written. Nothing is created when it raises, except parent
    folders that the failing ``mkdir`` itself made before a later component failed.
    """
    p = Path(path)
    where = f"{option} {str(path)!r}"
    # the nearest existing ancestor must be a folder
    probe = p
    while True:
        try:
            st = probe.stat()
        except FileNotFoundError:
            if probe.parent == probe:
                break
            probe = probe.parent
            continue
        except NotADirectoryError:
            probe = probe.parent
            continue
        except OSError as e:
            raise OutputError(f"{where}: cannot inspect {str(probe)!r}: {_reason(e)}") from None
        if not stat.S_ISDIR(st.st_mode):
            if probe == p:
                raise OutputError(f"{where}: is {_kind(st.st_mode)}; expected a folder (new or existing)")
            raise OutputError(f"{where}: {str(probe)!r} is {_kind(st.st_mode)}, not a folder; expected a folder path")
        break
    if p.is_dir():
        for name in outputs:
            target = p / name
            try:
                st = target.lstat()
            except FileNotFoundError:
                continue
            except OSError as e:
                raise OutputError(f"{where}: cannot inspect {str(target)!r}: {_reason(e)}") from None
            if not stat.S_ISREG(st.st_mode) and not stat.S_ISLNK(st.st_mode):
                raise OutputError(
                    f"{where}: {str(target)!r} is {_kind(st.st_mode)}; expected a file name free for this "
                    "output (move it away or choose another folder)"
                )
    try:
        p.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise OutputError(f"{where}: cannot create the folder: {_reason(e)}") from None
    # writable? (root ignores permission bits, but not read-only mounts or pseudo file systems)
    probe_file = p / f".avbench-write-test-{os.getpid()}-{uuid.uuid4().hex[:8]}"
    try:
        fd = os.open(probe_file, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
        os.close(fd)
        os.unlink(probe_file)
    except OSError as e:
        if e.errno in (errno.EACCES, errno.EPERM, errno.EROFS, errno.ENOENT, errno.ENOTDIR, errno.EINVAL):
            raise OutputError(f"{where}: the folder is not writable: {_reason(e)}") from None
        raise OutputError(f"{where}: cannot write in the folder: {_reason(e)}") from None
    return p


def tmp_name(path: Path) -> Path:
    """A hidden temporary name beside ``path``, unique per process and call."""
    path = Path(path)
    return path.with_name(f".{path.name}.{os.getpid()}-{uuid.uuid4().hex[:8]}.tmp")


def atomic_write_bytes(path, data: bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file and an atomic rename."""
    path = Path(path)
    tmp = tmp_name(path)
    try:
        with open(tmp, "wb") as f:
            f.write(data)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def atomic_write_text(path, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` through a temporary file and an atomic rename."""
    atomic_write_bytes(path, text.encode("utf-8"))
