"""Synthetic gyros whose Allan-variance coefficients, and exact discrete Allan variance, are known.

>>> from avbench.noise_models import presets
>>> g = presets.get("SRS2000")
>>> g.dt
0.1
"""

if __name__ != "avbench.noise_models":  # the folder imported by its pre-0.2 name (from a source checkout)
    from avbench.renamed import moved as _moved

    raise ImportError(_moved(__name__))


from avbench.noise_models._numba_cache import ensure_cache_dir as _ensure_cache_dir

_ensure_cache_dir()  # before any module with compiled kernels is imported

from avbench.noise_models import presets, units  # noqa: E402
from avbench.noise_models.gyro import Gyro  # noqa: E402
from avbench.noise_models.terms import (  # noqa: E402
    AngleRandomWalk,
    BiasInstability,
    FilteredWhiteNoise,
    GaussMarkov,
    NoiseTerm,
    Quantization,
    RateRamp,
    RateRandomWalk,
    Resonance,
    SecondOrderGaussMarkov,
    Sinusoidal,
)

__all__ = [
    "AngleRandomWalk",
    "BiasInstability",
    "FilteredWhiteNoise",
    "GaussMarkov",
    "Gyro",
    "NoiseTerm",
    "Quantization",
    "RateRamp",
    "RateRandomWalk",
    "Resonance",
    "SecondOrderGaussMarkov",
    "Sinusoidal",
    "presets",
    "units",
    "TERM_TYPES",
    "term_class",
]

#: term classes by name (used by study configs)
TERM_TYPES = {
    cls.__name__: cls
    for cls in (
        AngleRandomWalk,
        BiasInstability,
        FilteredWhiteNoise,
        GaussMarkov,
        Quantization,
        RateRamp,
        RateRandomWalk,
        Resonance,
        SecondOrderGaussMarkov,
        Sinusoidal,
    )
}


def term_class(name: str, search=None) -> type[NoiseTerm]:
    """The noise-term class called ``name`` in a study config.

    A built-in term (a key of :data:`TERM_TYPES`), the name of an entry point of the group
    ``avbench.noise_terms`` declared by an installed package, or an import path
    ``"package.module:Class"`` (see :mod:`avbench.noise_models.plugins`; ``search`` as there). The class
    must subclass :class:`NoiseTerm`. Errors are ``ValueError`` naming what was expected.
    """
    from avbench.noise_models import plugins

    if not isinstance(name, str):
        raise ValueError(f"expected a term type name, got {name!r}")
    if name in TERM_TYPES:
        return TERM_TYPES[name]
    if plugins.is_import_path(name):
        target = name
    else:
        target = plugins.entry_point_target(plugins.NOISE_TERM_GROUP, name)
        if target is None:
            known = sorted(set(TERM_TYPES) | set(plugins.entry_point_names(plugins.NOISE_TERM_GROUP)))
            raise ValueError(
                f"unknown term type {name!r}; expected one of {', '.join(known)}, "
                "or an import path 'package.module:Class'"
            )
    cls = plugins.load_object(target, search)
    if not (isinstance(cls, type) and issubclass(cls, NoiseTerm)):
        raise plugins.PluginError(f"term type {name!r}: {target} is {cls!r}, expected a subclass of avbench.noise_models.NoiseTerm")
    return cls
