"""avbench: how well can gyro noise coefficients be estimated?

One import name, five subpackages (each a top-level folder of the repository, mapped here at
install time; ``docs/ARCHITECTURE.md`` says what each holds and may import):

* :mod:`avbench.noise_models` -- noise terms that simulate themselves and know their exact
  discrete-time Allan variance, ``Gyro``, the papers' presets, units;
* :mod:`avbench.estimators` -- the estimator contract and registry, the Allan-variance engine and
  the fit check, and the estimator families (curve fits, online filters, likelihood, robust);
* :mod:`avbench.studies` -- Monte Carlo study configs, the runner, scores, tables and figures;
* :mod:`avbench.recordings` -- a user's recording to coefficients and a filter yaml
  (``avbench estimate``);
* :mod:`avbench.bench` -- the performance benchmarks (``python -m avbench.bench``).

Importing ``avbench`` imports none of them (they load on first access), so ``avbench --help``
stays fast.
"""

import importlib as _importlib

__version__ = "0.2.0"

_SUBPACKAGES = ("noise_models", "estimators", "studies", "recordings", "bench")

def __getattr__(name: str):
    if name in _SUBPACKAGES:
        module = _importlib.import_module(f"{__name__}.{name}")
        globals()[name] = module
        return module
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_SUBPACKAGES))
