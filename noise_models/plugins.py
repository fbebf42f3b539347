"""Plugins: classes named by import path ``"pkg.module:Class"`` or registered by installed packages.

A study config (and ``avbench.estimators.get``) can name a class that avbench does not ship:

* by **import path**, ``"my_pkg.my_module:MyEstimator"`` (the module is imported, the class read);
* by **entry point**: an installed distribution declares, in its ``pyproject.toml``,

  .. code-block:: toml

      [project.entry-points."avbench.estimators"]
      my_estimator = "my_pkg.my_module:MyEstimator"

      [project.entry-points."avbench.noise_terms"]
      MyDrift = "my_pkg.terms:MyDrift"

  and the name on the left (``my_estimator``) works like a built-in name.

Every process that runs a study -- the ``avbench`` process, loky workers, Dask workers -- imports
plugins the same way (a worker unpickles the configured classes by reference, which imports their
modules), so a plugin must be installed (or importable) on every worker machine. :func:`version_of`
gives the version that the study's result hash records.
"""

from __future__ import annotations

import functools
import hashlib
import importlib
import importlib.metadata
import sys
from pathlib import Path

from avbench.renamed import OLD_NAMES, moved

__all__ = [
    "ESTIMATOR_GROUP",
    "NOISE_TERM_GROUP",
    "PluginError",
    "import_module",
    "load_object",
    "entry_point_names",
    "entry_point_target",
    "version_of",
]

#: entry-point group of estimator classes (name -> "module:Class")
ESTIMATOR_GROUP = "avbench.estimators"
#: entry-point group of noise-term classes (name -> "module:Class")
NOISE_TERM_GROUP = "avbench.noise_terms"


class PluginError(ValueError):
    """A plugin cannot be loaded; the message names the module or entry point and why."""


def is_import_path(name: str) -> bool:
    """``"pkg.module:Class"``: a module path, one colon, an attribute path."""
    mod, sep, attr = name.partition(":")
    return bool(sep) and bool(mod) and bool(attr) and ":" not in attr and " " not in name


def import_module(module: str, search: Path | None = None):
    """Import ``module``; a :class:`PluginError` naming it (and what is missing) if that fails.

    If the module cannot be found and ``search`` (a folder, e.g. the study config's) holds it as
    ``<top>.py`` or ``<top>/``, that folder is put first on ``sys.path`` and the import retried:
    a study can name an estimator in a file beside it. Worker processes started from this one
    (loky, a local Dask cluster) inherit ``sys.path``; remote Dask workers need the module
    installed.
    """
    try:
        return importlib.import_module(module)
    except ModuleNotFoundError as e:
        top, missing = module.split(".")[0], e.name or ""
        if missing.split(".")[0] in OLD_NAMES:  # a plugin written against avbench's pre-0.2 names
            raise PluginError(f"plugin module {module!r}: {moved(missing)}") from None
        if search is not None and missing == top:
            folder = Path(search).resolve()
            if (folder / f"{top}.py").is_file() or (folder / top).is_dir():
                if str(folder) not in sys.path:
                    sys.path.insert(0, str(folder))
                importlib.invalidate_caches()
                return import_module(module)
        raise PluginError(
            f"cannot import plugin module {module!r} ({e}); expected it installed in this Python "
            "environment (pip install ...) or on PYTHONPATH"
        ) from None
    except ImportError as e:  # e.g. a pre-0.2 avbench folder on sys.path refusing its old name
        raise PluginError(f"plugin module {module!r}: {e}") from None
    except Exception as e:
        raise PluginError(f"importing plugin module {module!r} failed: {type(e).__name__}: {e}") from None


def load_object(path: str, search: Path | None = None):
    """The object named by ``"pkg.module:Attr"`` (dotted attribute paths allowed)."""
    if not is_import_path(path):
        raise PluginError(f"expected an import path 'package.module:Name', got {path!r}")
    module, _, attr = path.partition(":")
    obj = import_module(module, search)
    for part in attr.split("."):
        try:
            obj = getattr(obj, part)
        except AttributeError:
            raise PluginError(f"plugin module {module!r} has no attribute {attr!r}") from None
    return obj


@functools.lru_cache(maxsize=None)
def _entry_points(group: str) -> dict[str, str]:
    return {ep.name: ep.value for ep in importlib.metadata.entry_points(group=group)}


def entry_point_names(group: str) -> list[str]:
    """Names registered in entry-point ``group`` by the installed distributions (not loaded)."""
    return sorted(_entry_points(group))


def entry_point_target(group: str, name: str) -> str | None:
    """The ``"module:Class"`` that entry point ``name`` of ``group`` points to, or None."""
    target = _entry_points(group).get(name)
    if target is None:  # installed since the first look (e.g. in a running interpreter)
        _entry_points.cache_clear()
        target = _entry_points(group).get(name)
    return target


def version_of(obj) -> str:
    """The version of the code that defines ``obj`` (a class or a module).

    The installed distribution's ``name==version`` when the module belongs to one; else the
    module's ``__version__``; else a hash of its source file (so an edited local file counts as a
    new version).
    """
    modname = obj.__name__ if isinstance(obj, type(sys)) else obj.__module__
    top = modname.split(".")[0]
    dists = importlib.metadata.packages_distributions().get(top, [])
    if dists:
        d = dists[0]
        return f"{d}=={importlib.metadata.version(d)}"
    mod = sys.modules.get(modname)
    v = getattr(mod, "__version__", None) or getattr(sys.modules.get(top), "__version__", None)
    if v:
        return str(v)
    f = getattr(mod, "__file__", None)
    if f and Path(f).is_file():
        return "source sha256:" + hashlib.sha256(Path(f).read_bytes()).hexdigest()[:16]
    return "unknown"
