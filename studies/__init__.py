"""Monte Carlo studies: TOML configs (this folder), the runner, tables, figures and the CLI.

The names below are loaded on first access (PEP 562), so that ``avbench --help`` (``avbench.cli``)
does not import the simulators, the estimators or pandas.
"""

if __name__ != "avbench.studies":  # the folder imported by its pre-0.2 name (from a source checkout)
    from avbench.renamed import moved as _moved

    raise ImportError(_moved(__name__))


import importlib as _importlib

__all__ = ["ConfigError", "StudyConfig", "load_config", "parse_config", "run_study"]

_LAZY = {
    "ConfigError": "avbench.studies.config",
    "StudyConfig": "avbench.studies.config",
    "load_config": "avbench.studies.config",
    "parse_config": "avbench.studies.config",
    "run_study": "avbench.studies.runner",
}


def __getattr__(name: str):
    if name not in _LAZY:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(_importlib.import_module(_LAZY[name]), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(_LAZY))
