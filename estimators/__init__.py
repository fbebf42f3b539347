"""Estimators of the Allan-variance coefficients Q, N, B, K, R, and the Allan-variance engine.

Every estimator follows one interface (:class:`estimators.base.Estimator`): configure with settings,
``fit(rate, dt)``, read ``coefficients_`` (SI, ``pandas.Series`` indexed Q, N, B, K, R).
``estimators.get(name, **settings)`` builds one from its registry name; ``estimators.names()``
lists them. Every module of this package that defines estimators registers them on import.
"""

import importlib as _importlib
import pkgutil as _pkgutil

from estimators.base import (
    AvbenchWarning,
    DivergenceWarning,
    Estimator,
    IdentifiabilityWarning,
    estimator_class,
    get,
    names,
    register,
)
from estimators.allan import AllanResult, RecursiveAllan, StreamingAllan, allan_variance
from estimators.crlb import crlb

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

# Import every estimator module so that its classes register themselves.
for _m in _pkgutil.iter_modules(__path__):
    if not _m.name.startswith("_") and _m.name not in {"base", "allan", "av_model", "contract"}:
        _importlib.import_module(f"{__name__}.{_m.name}")
