"""Output paths of every command: checked before any work, written whole.

One way for all commands (``avbench run``, ``estimate``, ``simulate``, ``bench``) to validate an
``--out`` and to write into it (inputs are checked by :func:`avbench.recordings.files.check_path_kind`):

* :func:`prepare_out_dir` refuses, with one line naming the option, the path and what was expected,
  an ``--out`` that is an existing file, lies under a file, cannot be created or written (a read-only
  file system, a missing permission), or where one of the command's output names is taken by a
  folder or a special file; only then does it create the folder;
* :func:`atomic_write_text` / :func:`atomic_write_bytes` write a file under a hidden temporary name
  and rename it into place, so a reader sees either the old file or the new one, never a part;
* :func:`write_set` writes several files as one set: each is rendered and written under a temporary
  name first, then all are renamed into place with SIGINT, SIGTERM and SIGHUP held back, and a rename
  that fails puts back every file already replaced. An error or a signal before the renames leaves
  the previous set and no temporary file; a signal during them waits until the new set is in place
  (and then ends the process as it would have). Only a power cut or SIGKILL in the microseconds of
  the renames can leave a mix;
* :func:`safe_name` makes a file-name component of any text (a column name, a file's stem): no
  separator, no ``..``, no ``$``, at most :data:`NAME_BYTES` bytes;
* no output is an input: :func:`prepare_out_dir` (``inputs``) and :func:`check_not_inputs` refuse an
  output path that is one of the command's input files (by path, link or hard link);
* one writer per output folder: :func:`folder_lock` holds ``.avbench.lock`` in it while a command
  writes there; a second command into the same folder is refused, naming the first (a lock whose
  process is gone is taken over);
* :func:`markdown_cell` escapes a text for a cell of a Markdown table.
"""

from __future__ import annotations

import contextlib
import errno
import hashlib
import os
import re
import signal
import stat
import threading
import uuid
from collections.abc import Callable, Iterable
from pathlib import Path

__all__ = ["OutputError", "prepare_out_dir", "probe_writable", "atomic_write_text", "atomic_write_bytes", "tmp_name", "write_set",
           "safe_name", "NAME_BYTES", "Interrupted", "check_not_inputs", "folder_lock", "LOCK_NAME", "markdown_cell",
           "locked_new_folder"]


#: significant digits of the committed numbers: results move by ~1e-12 (relative) between machines
#: and library versions, so the files that regeneration compares carry no more than the arithmetic
#: supports (tidy: estimates to 9 digits; tables: statistics to 6 digits)
TIDY_DIGITS = 9
TABLE_DIGITS = 6


#: the longest file name :func:`safe_name` makes (bytes of UTF-8): file systems allow 255, and a
#: temporary name (:func:`tmp_name`) and a suffix (``_coefficients.json``) must still fit
NAME_BYTES = 180
#: the longest file name a file system takes (NAME_MAX on Linux, macOS and Windows)
_NAME_MAX = 255


class OutputError(ValueError):
    """An output location cannot be used; the message names the option, the path and the reason."""


class Interrupted(KeyboardInterrupt):
    """A signal (SIGTERM, SIGHUP) arrived while :func:`write_set` wrote its temporary files: nothing was
    renamed into place, every temporary file is gone."""


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


def probe_writable(folder) -> None:
    """Create and remove an empty file in ``folder``: the OSError of a folder that cannot be written (root
    ignores permission bits, but not read-only mounts or pseudo file systems)."""
    probe = Path(folder) / f".avbench-write-test-{os.getpid()}-{uuid.uuid4().hex[:8]}"
    fd = os.open(probe, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    os.close(fd)
    os.unlink(probe)


def _key(path) -> str:
    return os.path.normcase(os.path.realpath(path))


def _same_file(a, b) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False


def check_not_inputs(outputs: Iterable[tuple[str, Path]], inputs: Iterable[tuple[str, Path]]) -> None:
    """Refuse an output that is an input: ``outputs`` as ``(option, path)``, ``inputs`` as ``(what, path)``
    (``"the input recording"``, ``"the study's paper_table"``); the same path, a link to it or a hard link.
    Raises :class:`OutputError` naming both."""
    inputs = [(what, Path(p)) for what, p in inputs]
    for option, out in outputs:
        out = Path(out)
        for what, src in inputs:
            if _key(out) == _key(src) or _same_file(out, src):
                raise OutputError(f"{option} {str(out)!r}: is {what} {str(src)!r}; expected another output place "
                                  "(an input is never written over)")


def prepare_out_dir(path, option: str = "--out", outputs: Iterable[str] = (), inputs=()) -> Path:
    """Check that ``path`` can hold the command's ``outputs`` (file names), none of them one of
    ``inputs`` (``(what, path)``, :func:`check_not_inputs`), then create it.

    Raises :class:`OutputError` naming ``option`` and ``path`` when ``path`` is an existing
    non-folder, a parent of it is a file, an output name is taken by a folder or a special file
    or is an input, or the folder cannot be created or written. Nothing is created when it raises,
    except parent folders that the failing ``mkdir`` itself made before a later component failed.
    """
    p = Path(path)
    outputs = list(outputs)
    check_not_inputs([(option, p / name) for name in outputs], inputs)
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
    # writable? (probe_writable)
    try:
        probe_writable(p)
    except OSError as e:
        if e.errno in (errno.EACCES, errno.EPERM, errno.EROFS, errno.ENOENT, errno.ENOTDIR, errno.EINVAL):
            raise OutputError(f"{where}: the folder is not writable: {_reason(e)}") from None
        raise OutputError(f"{where}: cannot write in the folder: {_reason(e)}") from None
    return p


def tmp_name(path: Path) -> Path:
    """A hidden temporary name beside ``path``, unique per process and call, never longer than a file
    system allows (a long name is shortened to a digest of it)."""
    path = Path(path)
    tag = f"{os.getpid()}-{uuid.uuid4().hex[:8]}.tmp"
    name = f".{path.name}.{tag}"
    if len(name.encode("utf-8")) > _NAME_MAX:
        name = f".avbench-{hashlib.sha256(path.name.encode('utf-8', 'surrogateescape')).hexdigest()[:16]}.{tag}"
    return path.with_name(name)


def safe_name(text: str, limit: int = NAME_BYTES) -> str:
    """A file-name component made of ``text``: every run of characters other than letters, digits, ``.``,
    ``-``, ``+`` and ``_`` (a ``/``, a blank, a bracket, a ``$``, a control character) becomes one ``_``;
    leading dots and underscores and trailing underscores go (no hidden file, no ``..``); an empty result
    is ``_``; a result longer than ``limit`` bytes of UTF-8 is cut and ends with ``~`` and 8 hex digits of
    the SHA-256 of ``text``, so that distinct long texts keep distinct names.

    >>> safe_name("gx [deg/s]"), safe_name("../x"), safe_name("$a$ b"), len(safe_name("é" * 300).encode()) <= 180
    ('gx_deg_s', 'x', 'a_b', True)
    """
    name = re.sub(r"[^\w.+-]+", "_", str(text), flags=re.UNICODE).lstrip("._").rstrip("_") or "_"
    raw = name.encode("utf-8", "surrogateescape")
    if len(raw) <= limit:
        return name
    digest = hashlib.sha256(str(text).encode("utf-8", "surrogateescape")).hexdigest()[:8]
    cut = raw[: limit - 9].decode("utf-8", "ignore")
    return f"{cut}~{digest}"


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


#: the signals whose default would end the process between the renames of :func:`write_set`
_HELD = tuple(getattr(signal, n) for n in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, n))


def _raise_interrupted(signum, frame):
    raise Interrupted(f"interrupted by {signal.Signals(signum).name}")


def write_set(items: Iterable[tuple[Path, Callable[[], bytes]]]) -> list[Path]:
    """Write ``items`` (``(path, render)``: ``render()`` gives the file's bytes) as one set (see the module
    docstring); returns the paths. Each file's temporary name lies beside it (so that a rename stays
    within one file system); an existing file is kept under a hard link until the set is complete.
    A SIGTERM or SIGHUP before the renames raises :class:`Interrupted` (a ``KeyboardInterrupt``); one
    during the renames is held back (Python runs signal handlers in the main thread, whichever thread
    the signal reached) and raised again once the set is in place."""
    items = [(Path(p), render) for p, render in items]
    main = threading.current_thread() is threading.main_thread()
    old = {sig: signal.getsignal(sig) for sig in _HELD} if main else {}
    held: list[int] = []
    temps: list[tuple[Path, Path]] = []
    try:
        for sig in old:  # SIGTERM / SIGHUP while the temporary files are written: remove them, rename nothing
            if sig != signal.SIGINT:
                signal.signal(sig, _raise_interrupted)
        for path, render in items:
            data = render()
            tmp = tmp_name(path)
            temps.append((tmp, path))
            with open(tmp, "wb") as f:
                f.write(data)
        for sig in old:  # from here on a signal waits for the set to be whole
            signal.signal(sig, lambda signum, frame: held.append(signum))
        _commit(temps)
        temps = []
    finally:
        for tmp, _ in temps:
            tmp.unlink(missing_ok=True)
        for sig, handler in old.items():
            signal.signal(sig, handler)
    for sig in dict.fromkeys(held):  # the set is in place: each held signal now does what it would have done
        signal.raise_signal(sig)
    return [p for p, _ in items]


def _commit(temps: list[tuple[Path, Path]]) -> None:
    """Rename every temporary file into place; on a failure, put back every file already replaced (from
    its hard link) and remove the new ones that had no predecessor."""
    done: list[tuple[Path, Path | None]] = []  # (final path, hard link to the file it replaced)
    try:
        for tmp, path in temps:
            keep = None
            if os.path.lexists(path):
                keep = tmp_name(path)
                try:
                    os.link(path, keep, follow_symlinks=False)
                except OSError:
                    keep = None  # a file system without hard links: this file cannot be put back
            try:
                os.replace(tmp, path)
            except BaseException:
                if keep is not None:
                    keep.unlink(missing_ok=True)
                raise
            done.append((path, keep))
    except BaseException:
        for path, keep in reversed(done):
            if keep is not None:
                os.replace(keep, path)
            else:
                path.unlink(missing_ok=True)
        raise
    finally:
        for _, keep in done:
            if keep is not None:
                keep.unlink(missing_ok=True)


#: the lock file :func:`folder_lock` holds in an output folder
LOCK_NAME = ".avbench.lock"


class folder_lock:
    """Hold :data:`LOCK_NAME` in ``folder`` (created exclusively, holding this process's id and the
    command) for as long as the ``with`` block runs. A folder locked by a live process raises
    :class:`OutputError` naming ``option``, the folder and that process; a lock left by a process
    that is gone (killed) is taken over. Two runs into one ``--out`` would otherwise mix their blocks
    and each print the other's tables as its own. Re-entrant: within a process that holds the lock,
    a nested ``with`` neither takes nor releases it."""

    def __init__(self, folder, option: str = "--out", command: str = "avbench"):
        self.path = Path(folder) / LOCK_NAME
        self.option, self.command, self.held = option, command, False

    def __enter__(self):
        text = f"{os.getpid()}\n{self.command}\n"
        for _ in range(3):
            try:
                fd = os.open(self.path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
            except FileExistsError:
                pid, what = self._holder()
                if pid == os.getpid():  # this process holds it already (a command around run_study)
                    return self
                if pid is not None and _alive(pid):
                    raise OutputError(
                        f"{self.option} {str(self.path.parent)!r}: another avbench run (process {pid}: {what}) is "
                        "writing into this folder; expected one run per output folder (wait for it to finish, or "
                        "choose another folder)") from None
                self.path.unlink(missing_ok=True)  # left by a process that is gone
                continue
            with os.fdopen(fd, "w") as f:
                f.write(text)
            self.held = True
            self._signals = {}
            if threading.current_thread() is threading.main_thread():  # a SIGTERM or SIGHUP that would end
                for sig in (s for s in _HELD if s != signal.SIGINT):  # the process (their default) removes the lock first
                    if signal.getsignal(sig) in (signal.SIG_DFL, None):
                        self._signals[sig] = signal.signal(sig, self._end)
            return self
        raise OutputError(f"{self.option} {str(self.path.parent)!r}: cannot take {LOCK_NAME}; expected a folder "
                          "no other run writes into")

    def _holder(self) -> tuple[int | None, str]:
        try:
            lines = self.path.read_text().splitlines()
            return int(lines[0]), (lines[1] if len(lines) > 1 else "?")
        except (OSError, ValueError, IndexError):
            return None, "?"

    def _end(self, signum, frame):
        """A signal whose default ends the process: release the lock, then end as the default would."""
        self.__exit__()
        signal.signal(signum, signal.SIG_DFL)
        signal.raise_signal(signum)

    def __exit__(self, *exc):
        if self.held and self._holder()[0] == os.getpid():
            self.path.unlink(missing_ok=True)
        self.held = False
        for sig, handler in getattr(self, "_signals", {}).items():
            if signal.getsignal(sig) == self._end:
                signal.signal(sig, handler)
        self._signals = {}
        return False


@contextlib.contextmanager
def locked_new_folder(folder, option: str = "--out", command: str = "avbench"):
    """:class:`folder_lock` on ``folder`` for the ``with`` block, creating ``folder`` (and missing parents)
    first when it does not exist yet, so that two runs into one new folder are locked against each
    other too. Folders this call created are removed again if the block leaves them empty (the command
    refused its input or was refused the lock): nothing half-made is left. A path that cannot be a
    folder (a file, or under one) is not locked: the command's own check names the problem."""
    p = Path(folder)
    made, probe = [], p
    while not probe.exists() and probe.parent != probe:
        made.append(probe)
        probe = probe.parent
    if not probe.is_dir():
        yield None
        return
    try:
        p.mkdir(parents=True, exist_ok=True)
    except OSError:  # cannot be created: the command's own check names why
        yield None
        return
    try:
        with folder_lock(p, option, command) as lock:
            yield lock
    finally:
        for d in made:  # deepest first; stops at the first one something was written into
            try:
                d.rmdir()
            except OSError:
                break


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:
        return True
    return True


def markdown_cell(text) -> str:
    r"""``text`` for one cell of a Markdown table: ``|`` and ``\`` escaped, line breaks as blanks, so that a
    label such as ``wls|NK`` stays one cell.

    >>> print(markdown_cell("wls|NK"), markdown_cell("a\\b"))
    wls\|NK a\\b
    """
    return str(text).replace("\\", "\\\\").replace("|", "\\|").replace("\r", " ").replace("\n", " ")
