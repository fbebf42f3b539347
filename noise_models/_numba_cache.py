"""Where numba keeps the compiled kernels (``cache=True``), so each is compiled once per machine.

numba writes its cache beside the source (``__pycache__``; an editable install, a source tree), else
in the user's cache folder (``~/.cache/numba``; a normal ``pip install`` into a read-only
site-packages), else it refuses to decorate a ``cache=True`` function at import
("no locator available"). :func:`ensure_cache_dir` runs before any kernel module is imported (from
the package ``__init__``s) and, only in that last case, points ``NUMBA_CACHE_DIR`` at a per-user
folder in the temporary directory, so the package imports and the kernels are still compiled once
and shared by later processes and every worker (which inherit the environment).
"""

from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path

__all__ = ["ensure_cache_dir"]

_checked = False


def _can_write(folder: Path) -> bool:
    try:
        folder.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=folder):
            pass
        return True
    except OSError:
        return False


def _user_cache() -> Path:
    # numba's user-wide locator: appdirs' user cache folder of "numba"
    if sys.platform == "darwin":
        return Path.home() / "Library" / "Caches" / "numba"
    if sys.platform == "win32":
        return Path(os.environ.get("LOCALAPPDATA", Path.home())) / "numba" / "Cache"
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "numba"


def ensure_cache_dir() -> str | None:
    """Make sure numba can cache this package's kernels; return the folder set, if one had to be.

    Cheap when the source tree's ``__pycache__`` is writable (one ``os.access``); never overrides a
    ``NUMBA_CACHE_DIR`` the user has set.
    """
    global _checked
    if _checked or os.environ.get("NUMBA_CACHE_DIR"):
        _checked = True
        return None
    _checked = True
    here = Path(__file__).resolve().parent
    pycache = here / "__pycache__"
    if os.access(pycache if pycache.is_dir() else here, os.W_OK):
        return None
    try:
        if _can_write(_user_cache()):
            return None
    except (OSError, RuntimeError):  # no home folder
        pass
    uid = os.getuid() if hasattr(os, "getuid") else os.environ.get("USERNAME", "user")
    folder = Path(tempfile.gettempdir()) / f"avbench-numba-cache-{uid}"
    if not _can_write(folder):
        return None  # nowhere to write: numba will say so when a kernel is compiled
    os.environ["NUMBA_CACHE_DIR"] = str(folder)
    if "numba" in sys.modules:  # numba read its config already
        from numba.core import config

        config.CACHE_DIR = str(folder)
    return str(folder)
