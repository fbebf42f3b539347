"""Monte Carlo studies: TOML configs (this folder), the runner, tables, figures and the CLI.

The names below are loaded on first access (PEP 562), so that ``avbench --help`` (``studies.cli``)
does not import the simulators, the estimators or pandas.
"""

import importlib as _importlib

__all__ = ["ConfigError", "StudyConfig", "load_config", "parse_config", "run_study"]

_LAZY = {
    "ConfigError": "studies.config",
    "StudyConfig": "studies.config",
    "load_config": "studies.config",
    "parse_config": "studies.config",
    "run_study": "studies.runner",
}


def __getattr__(name: str):
    if name not in _LAZY:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(_importlib.import_module(_LAZY[name]), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(_LAZY))
