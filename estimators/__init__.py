"""Estimators of the Allan-variance coefficients Q, N, B, K, R, and the Allan-variance engine.

Every estimator follows one interface (:class:`avbench.estimators.base.Estimator`): configure with settings,
``fit(rate, dt)``, read ``coefficients_`` (SI, ``pandas.Series`` indexed Q, N, B, K, R).
``estimators.get(name, **settings)`` builds one from its registry name; ``estimators.names()``
lists them.

Importing this package is cheap: the built-in estimators are listed by name in
:data:`avbench.estimators.base.BUILTIN` and their modules (with scipy.optimize, statsmodels and the compiled
filters they need) are imported the first time one of them is asked for; the Allan-variance names
(``allan_variance``, ``StreamingAllan``, ...) and every submodule (``avbench.estimators.likelihood.gmwm``, ...) are
loaded on first access (PEP 562 module ``__getattr__``).
"""

if __name__ != "avbench.estimators":  # the folder imported by its pre-0.2 name (from a source checkout)
    from avbench.renamed import moved as _moved

    raise ImportError(_moved(__name__))


import importlib as _importlib

from avbench.noise_models._numba_cache import ensure_cache_dir as _ensure_cache_dir

_ensure_cache_dir()  # before any module with compiled kernels is imported

from avbench.estimators.base import (  # noqa: E402
    AvbenchWarning,
    DivergenceWarning,
    Estimator,
    IdentifiabilityWarning,
    estimator_class,
    get,
    names,
    register,
)

__all__ = [
    "AllanResult",
    "AvbenchWarning",
    "DivergenceWarning",
    "Estimator",
    "IdentifiabilityWarning",
    "RecursiveAllan",
    "StreamingAllan",
    "allan_variance",
    "crlb",
    "estimator_class",
    "get",
    "names",
    "register",
]

#: public names loaded on first access, and the module that holds them
_LAZY = {
    **{name: "avbench.estimators.allan.variance" for name in ("AllanResult", "RecursiveAllan", "StreamingAllan", "allan_variance")},
    "crlb": "avbench.estimators.likelihood.crlb",
}


def __getattr__(name: str):
    if name in _LAZY:
        value = getattr(_importlib.import_module(_LAZY[name]), name)
    elif not name.startswith("__"):
        try:  # a submodule, as if every module had been imported with the package
            value = _importlib.import_module(f"{__name__}.{name}")
        except ModuleNotFoundError as e:
            if e.name != f"{__name__}.{name}":
                raise
            raise AttributeError(f"module {__name__!r} has no attribute {name!r}") from None
    else:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    globals()[name] = value
    return value


def __dir__():
    import pkgutil

    return sorted(set(globals()) | set(_LAZY) | {m.name for m in pkgutil.iter_modules(__path__)})
