"""What computed a study's rows: the code of its estimators and terms, avbench, the libraries, the config.

**The code rule.** A study's rows are a function of its config, its seed and the source code that
simulates and fits them; :func:`code_hashes` hashes exactly that code, so a rerun after an edit
recomputes the studies whose code the edit touched and reuses the others' blocks:

* a class of avbench (a built-in estimator or term): the module defining it and the modules defining
  its base classes, with every avbench module they import, transitively (read from the source with
  :mod:`ast`: every ``import``, at the top of a module or inside a function). An edit to GMWM's module
  reruns the studies that fit GMWM, not the least-squares studies;
* a class from outside avbench (an estimator or term in a file beside the config, an import path, an
  installed or editable plugin): every source file of its top-level package (a single module: its
  file), and those of the modules beside it that it imports (same folder on ``sys.path``: a helper
  module next to the estimator's file), whatever version string the package declares;
* the runner itself: this study machinery (the runner, the config, the seeding) and the gyro that sums
  the terms, with their avbench imports.

The shards of a study live under ``_shards/<config key>-<code key>/`` (``studies.runner.shard_folder``);
within a study every block is recomputed when its code key moves (a block fits every estimator on one
simulated record). :func:`provenance` adds what is recorded but not part of the key -- avbench's
version and git commit, the Python and library versions, the full resolved config -- for
``meta.json``.

**A shadowed module is said.** A config naming ``read_off:ReadOff`` imports an installed ``read_off``
when there is one, even if a ``read_off.py`` sits beside the config; :func:`shadowed` names each such
module (the runner warns, ``meta.json`` lists them).
"""

from __future__ import annotations

import ast
import functools
import hashlib
import importlib.metadata
import platform
import subprocess
import sys
from pathlib import Path

__all__ = ["code_hashes", "code_key", "provenance", "shadowed", "LIBRARIES"]

#: the libraries whose versions ``meta.json`` records (what the rows' arithmetic runs on)
LIBRARIES = ("numpy", "scipy", "pandas", "statsmodels", "numba", "joblib", "matplotlib", "pyarrow")
#: the modules of the study machinery whose code computes every row, whatever the estimators
RUNNER_MODULES = ("avbench.studies.runner", "avbench.studies.config", "avbench.studies.seeding",
                  "avbench.noise_models.gyro")
_ROOT = Path(__file__).resolve().parents[1]  # the repository (or the installed tree) holding avbench


def _source(mod: str) -> Path | None:
    """The source file of an already importable module, without importing it again."""
    m = sys.modules.get(mod)
    if m is None:
        try:
            import importlib

            m = importlib.import_module(mod)
        except Exception:
            return None
    f = getattr(m, "__file__", None)
    return Path(f) if f and Path(f).is_file() and f.endswith(".py") else None


def _imports(path: Path, module: str) -> set[str]:
    """Names the module at ``path`` imports (absolute; ``from P import x`` gives both P and P.x)."""
    package = module if path.stem == "__init__" else module.rpartition(".")[0]
    out = set()
    for node in ast.walk(ast.parse(path.read_bytes(), str(path))):
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                up = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(up + ([base] if base else []))
            out.add(base)
            out.update(f"{base}.{a.name}" for a in node.names)
    return out


@functools.lru_cache(maxsize=None)
def _avbench_closure(module: str) -> frozenset[str]:
    """``module`` and every avbench module it imports, transitively (package ``__init__``s excluded:
    an avbench module never imports its own package's)."""
    seen, todo = set(), [module]
    while todo:
        m = todo.pop()
        if m in seen:
            continue
        path = _source(m)
        if path is None:
            continue
        seen.add(m)
        for name in _imports(path, m):
            if name.startswith("avbench.") and name not in seen and not _reports_only(name):
                p = _source(name) if name in sys.modules or _is_module(name) else None
                if p is not None and p.name != "__init__.py":
                    todo.append(name)
    return frozenset(seen)


def _reports_only(name: str) -> bool:
    """A study module that reads rows rather than computing them (tables, scores, figures, workers)."""
    return name.startswith("avbench.studies.") and name not in RUNNER_MODULES


def _is_module(name: str) -> bool:
    import importlib.util

    try:
        return importlib.util.find_spec(name) is not None
    except (ImportError, ValueError):
        return False


def _root_of(module: str) -> tuple[Path, list[Path]] | None:
    """(the folder on ``sys.path`` holding ``module``'s top-level package, its source files)."""
    top = module.split(".")[0]
    m = sys.modules.get(top)
    if m is None:
        return None
    paths = list(getattr(m, "__path__", []) or [])
    if paths:
        files = sorted({q for p in paths for q in Path(p).rglob("*.py") if "__pycache__" not in q.parts})
        return Path(paths[0]).resolve().parent, files
    f = getattr(m, "__file__", None)
    return (Path(f).resolve().parent, [Path(f)]) if f and f.endswith(".py") and Path(f).is_file() else None


@functools.lru_cache(maxsize=None)
def _installed_roots() -> frozenset[Path]:
    """The folders packages are installed into (site-packages): a module found there beside a plugin is an
    installed dependency, not a part of the plugin."""
    import site
    import sysconfig

    folders = [*site.getsitepackages(), site.getusersitepackages(), *sysconfig.get_paths().values()]
    return frozenset(Path(f).resolve() for f in folders if f)


def _plugin_files(module: str) -> dict[str, Path]:
    """Source files of the package defining ``module`` and of the modules beside it that it imports."""
    files, seen, todo = {}, set(), [module.split(".")[0]]
    while todo:
        top = todo.pop()
        if top in seen:
            continue
        seen.add(top)
        found = _root_of(top)
        if found is None:
            continue
        root, paths = found
        for p in paths:
            files[f"{top}/{p.resolve().relative_to(root).as_posix()}"] = p
            for name in _imports(p, top):
                other = name.split(".")[0]
                if other != "avbench" and other not in seen:
                    o = _root_of(other)
                    if o is not None and o[0] == root and root not in _installed_roots():  # beside it
                        todo.append(other)
    return files


def _class_files(cls) -> dict[str, Path]:
    """The source files that define ``cls``'s behaviour (the module docstring's rule)."""
    files = {}
    for k in cls.__mro__:
        mod = k.__module__
        if mod in ("builtins", "abc"):
            continue
        if mod.split(".")[0] == "avbench":
            for m in _avbench_closure(mod):
                files[m] = _source(m)
        else:
            files.update(_plugin_files(mod))
    return files


def _hash(files: dict[str, Path]) -> str:
    h = hashlib.sha256()
    for label in sorted(files):
        h.update(label.encode() + b"\0")
        h.update(Path(files[label]).read_bytes())
    return h.hexdigest()[:16]


def code_hashes(cfg) -> dict:
    """``{"runner": hash, "estimators": {label: hash}, "terms": {class: hash}, "plugins": {module: hash}}``.

    Each hash is of the source files of the module docstring's rule (16 hex digits of SHA-256).
    """
    runner = {}
    for m in RUNNER_MODULES:
        runner.update({x: _source(x) for x in _avbench_closure(m)})
    ests = {e.label: _hash(_class_files(_estimator_class(e, cfg))) for e in cfg.estimators}
    terms = {}
    for g in cfg.gyros:
        for t in g.gyro.terms:
            k = type(t)
            terms.setdefault(f"{k.__module__}:{k.__qualname__}", _hash(_class_files(k)))
    plugins = {m: _hash(_plugin_files(m)) for m in getattr(cfg, "plugins", ())}
    return {"runner": _hash(runner), "estimators": ests, "terms": dict(sorted(terms.items())), "plugins": plugins}


def _estimator_class(spec, cfg):
    if spec.cls is not None:
        return spec.cls
    from avbench import estimators

    return estimators.estimator_class(spec.name, cfg.path.parent if cfg.path else None)


def code_key(cfg) -> str:
    """One hash of :func:`code_hashes` (12 hex digits): the code half of a shard folder's name."""
    import json

    return hashlib.sha256(json.dumps(code_hashes(cfg), sort_keys=True).encode()).hexdigest()[:12]


def shadowed(cfg) -> list[str]:
    """Messages for the modules a config names that were imported from elsewhere than the module of
    the same name beside the config (an installed package shadowing a local file)."""
    if cfg.path is None:
        return []
    folder = Path(cfg.path).resolve().parent
    classes = [_estimator_class(e, cfg) for e in cfg.estimators] + [type(t) for g in cfg.gyros for t in g.gyro.terms]
    tops = {k.__module__.split(".")[0] for k in classes} | {m.split(".")[0] for m in getattr(cfg, "plugins", ())}
    out = []
    for top in sorted(tops - {"avbench"}):
        local = folder / f"{top}.py" if (folder / f"{top}.py").is_file() else folder / top
        if not local.exists():
            continue
        found = _root_of(top)
        if found is not None and found[0] != folder:
            where = sys.modules[top].__file__ or found[0]
            out.append(f"module {top!r} is imported from {where}, not from {local} beside the config "
                       f"(an installed {top!r} comes first on the import path); rename the local file, "
                       "or uninstall the other, to run the one you mean")
    return out


def _git_commit() -> str | None:
    """The commit of the avbench checkout this code runs from (``+dirty`` with uncommitted edits), or None."""
    if not (_ROOT / ".git").exists():
        return None
    try:
        head = subprocess.run(["git", "-C", str(_ROOT), "rev-parse", "HEAD"], capture_output=True, text=True,
                              timeout=10)
        if head.returncode:
            return None
        dirty = subprocess.run(["git", "-C", str(_ROOT), "status", "--porcelain", "--untracked-files=no"],
                               capture_output=True, text=True, timeout=30)
    except (OSError, subprocess.SubprocessError):
        return None
    return head.stdout.strip() + ("+dirty" if dirty.stdout.strip() else "")


def _version(dist: str) -> str | None:
    try:
        return importlib.metadata.version(dist)
    except importlib.metadata.PackageNotFoundError:
        return None


def resolved_config(cfg) -> dict:
    """The config as the study ran it: every gyro's terms and record, every estimator's class and its
    settings per gyro (defaults of the config applied), the seed and the replicates."""
    gyros = [{"label": g.label, "dt": g.gyro.dt, "n_samples": g.n_samples,
              "terms": [{"type": f"{type(t).__module__}:{type(t).__qualname__}", **_plain(t._params())}
                        for t in g.gyro.terms]} for g in cfg.gyros]
    ests = []
    for e in cfg.estimators:
        k = _estimator_class(e, cfg)
        ests.append({"label": e.label, "name": e.name, "class": f"{k.__module__}:{k.__qualname__}",
                     "bootstrap": e.bootstrap,
                     "settings": {g.label: _plain(e.settings_for(g)) for g in cfg.gyros}})
    return {"name": cfg.name, "seed": cfg.seed, "replicates": cfg.replicates, "block_size": cfg.block_size,
            "plugins": list(getattr(cfg, "plugins", ())), "gyros": gyros, "estimators": ests}


def _plain(v):
    """JSON-ready: tuples as lists, numpy scalars as numbers, anything else by its repr."""
    if isinstance(v, dict):
        return {str(k): _plain(x) for k, x in v.items()}
    if isinstance(v, list | tuple):
        return [_plain(x) for x in v]
    if isinstance(v, bool | int | str) or v is None:
        return v
    try:
        return float(v)
    except (TypeError, ValueError):
        return repr(v)


def environment() -> dict:
    """The machine's side of a study's provenance, written to ``environment.json`` beside ``meta.json``: the
    git commit of the avbench checkout (``+dirty`` with uncommitted edits), the Python and library versions.
    It is not committed with a study's results (``.gitignore``): a committed ``meta.json`` must be what any
    machine regenerates from the same code, and a commit cannot name itself."""
    return {"git_commit": _git_commit(), "python": platform.python_version(),
            "libraries": {d: _version(d) for d in LIBRARIES}}


def provenance(cfg) -> dict:
    """What ``meta.json`` records of the code that computed the rows (the hashes of its source, avbench's
    version, plugins' versions, the resolved config); the machine's side is :func:`environment`'s."""
    from avbench.noise_models.plugins import version_of

    plugin = {}
    for k in [_estimator_class(e, cfg) for e in cfg.estimators] + [type(t) for g in cfg.gyros for t in g.gyro.terms]:
        if k.__module__.split(".")[0] != "avbench":
            plugin[f"{k.__module__}:{k.__qualname__}"] = version_of(k)
    return {
        "code_key": code_key(cfg),
        "code": code_hashes(cfg),
        "avbench": _version("avbench"),
        "environment": "environment.json beside this file: git commit, Python and library versions of the "
                       "machine that wrote it (not committed)",
        "plugin_versions": plugin,
        "shadowed": shadowed(cfg),
        # where the rows come from: this code, from the config and the seed (a committed study whose
        # report was re-rendered from its tidy.csv says so instead)
        "rows": "computed by this code from the config and the seed",
        "config": resolved_config(cfg),
    }
