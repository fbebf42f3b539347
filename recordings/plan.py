"""The outputs of a command that reads a recording, planned before the work and written as one set.

An :class:`OutputPlan` is a list of :class:`PlannedOutput` -- each a file name, its path, the option
that places it (``--out`` for the files named after the input, ``--kalibr`` for a path the user gives)
and its writer, a function of the results that gives the file's bytes. The plan is made and checked
before the first fit (:meth:`OutputPlan.check`):

* **names** are made from the input's stem and ``--column`` by
  :func:`avbench.outputs.safe_name` (:func:`output_stem`): no separator, no ``..``, no ``$``, short
  enough for any file system with room for a temporary name;
* **places**: ``--out`` can hold every output (:func:`avbench.outputs.prepare_out_dir`), and every other
  path lies in a folder that exists or can be made, in which a file can be created, and is not a folder
  or a special file;
* **no clash**: no output is an input recording (the same file, by path or hard link), and no two
  outputs are one file.

:meth:`OutputPlan.write` then renders every output from the results and writes them as one set
(:func:`avbench.outputs.write_set`): an error or a SIGTERM before the renames leaves the previous set,
and after them the new one, never a mix. A command adds an output by appending a
:class:`PlannedOutput`; nothing else changes.
"""

from __future__ import annotations

import os
import stat
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from avbench.outputs import NAME_BYTES, OutputError, check_not_inputs, prepare_out_dir, probe_writable, safe_name, write_set

__all__ = ["PlannedOutput", "OutputPlan", "output_stem", "check_file_target", "STEM_BYTES"]

#: the longest stem (bytes): the longest suffix a command adds (``_coefficients.json``, 18) still fits
#: within :data:`avbench.outputs.NAME_BYTES`
STEM_BYTES = NAME_BYTES - 30


def output_stem(path, column=None, combined: bool = False) -> str:
    """The prefix of every output named after a recording: its stem (a bag folder: its name), then
    ``--column``'s value and ``combined`` (several recordings pooled), each made safe
    (:func:`avbench.outputs.safe_name`) and the whole at most :data:`STEM_BYTES` bytes.

    >>> output_stem("logs/run 1.csv", "gx [deg/s]"), output_stem("../x.npy"), output_stem("a.npz", None, True)
    ('run_1_gx_deg_s', 'x', 'a_combined')
    """
    p = Path(path)
    parts = [safe_name(p.stem or p.name)]
    if column is not None:
        parts.append(safe_name(str(column)))
    if combined:
        parts.append("combined")
    return safe_name("_".join(parts), STEM_BYTES)


@dataclass
class PlannedOutput:
    """One output: its file ``name`` (as messages show it), its ``path``, the ``option`` that places it,
    and ``write(results) -> bytes``."""

    name: str
    path: Path
    write: Callable[[Any], bytes]
    option: str = "--out"


@dataclass
class OutputPlan:
    """The outputs of one run, in ``out`` (``--out``) and elsewhere (``--kalibr``)."""

    out: Path
    outputs: list[PlannedOutput] = field(default_factory=list)

    def add(self, name: str, write: Callable[[Any], bytes]) -> None:
        """An output named ``name`` in ``--out``."""
        self.outputs.append(PlannedOutput(name, self.out / name, write))

    def add_path(self, path, option: str, write: Callable[[Any], bytes]) -> None:
        """An output at a path the user gave with ``option``."""
        self.outputs.append(PlannedOutput(str(path), Path(path), write, option))

    @property
    def names(self) -> list[str]:
        return [o.name for o in self.outputs]

    def check(self, inputs) -> Path:
        """Refuse, before any work, a plan that cannot be written or would write over an input or over
        itself (the module docstring); creates ``--out`` (only that). Returns ``--out``."""
        for o in self.outputs:
            if o.option != "--out":
                check_file_target(o.path, o.option)
        keys = {}
        for o in self.outputs:
            k = _key(o.path)
            if k in keys:
                other = keys[k]
                raise OutputError(f"{o.option} {o.name!r}: is also the output {other.name!r} ({other.option}); "
                                  "expected another file name")
            keys[k] = o
        check_not_inputs([(o.option, o.path) for o in self.outputs], [("the input recording", src) for src in inputs])
        return prepare_out_dir(self.out, "--out", [o.name for o in self.outputs if o.option == "--out"])

    def write(self, results) -> list[Path]:
        """Render every output from ``results`` and write them as one set (:func:`avbench.outputs.write_set`)."""
        for o in self.outputs:
            o.path.parent.mkdir(parents=True, exist_ok=True)
        return write_set([(o.path, (lambda o=o: o.write(results))) for o in self.outputs])


def _key(path: Path) -> str:
    return os.path.normcase(os.path.realpath(path))


def check_file_target(path: Path, option: str) -> None:
    """A path the user gave for one output file: not a folder or a special file, a name a file system
    takes, in a folder that exists (or can be made) and in which a file can be created."""
    where = f"{option} {str(path)!r}"
    if len(path.name.encode("utf-8", "surrogateescape")) > 255:
        raise OutputError(f"{where}: the file name is longer than 255 bytes; expected a shorter name")
    try:
        st = path.lstat()
    except FileNotFoundError:
        st = None
    except NotADirectoryError:
        st = None
    except OSError as e:
        raise OutputError(f"{where}: cannot inspect it: {e.strerror or e}") from None
    if st is not None and stat.S_ISLNK(st.st_mode):
        try:
            st = path.stat()
        except OSError:
            st = None  # a broken link: replaced by the file
    if st is not None and not stat.S_ISREG(st.st_mode):
        from avbench.outputs import _kind

        raise OutputError(f"{where}: is {_kind(st.st_mode)}; expected a file name")
    parent = path.parent
    while True:
        try:
            pst = parent.stat()
        except (FileNotFoundError, NotADirectoryError):
            if parent == parent.parent:
                raise OutputError(f"{where}: no folder of it exists; expected a file path") from None
            parent = parent.parent
            continue
        except OSError as e:
            raise OutputError(f"{where}: cannot inspect {str(parent)!r}: {e.strerror or e}") from None
        if not stat.S_ISDIR(pst.st_mode):
            raise OutputError(f"{where}: {str(parent)!r} is not a folder; expected a file path")
        break
    try:
        probe_writable(parent)
    except OSError as e:
        raise OutputError(f"{where}: cannot write in {str(parent)!r}: {e.strerror or e}") from None
