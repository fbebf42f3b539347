"""Synthetic gyros whose Allan-variance coefficients, and exact discrete Allan variance, are known.

>>> from noise_models import presets
>>> g = presets.get("SRS2000")
>>> g.dt
0.1
"""

from noise_models._numba_cache import ensure_cache_dir as _ensure_cache_dir

_ensure_cache_dir()  # before any module with compiled kernels is imported

from noise_models import presets, units  # noqa: E402
from noise_models.gyro import Gyro  # noqa: E402
from noise_models.terms import (  # noqa: E402
    AngleRandomWalk,
    BiasInstability,
    GaussMarkov,
    NoiseTerm,
    Quantization,
    RateRamp,
    RateRandomWalk,
    SecondOrderGaussMarkov,
)

__all__ = [
    "AngleRandomWalk",
    "BiasInstability",
    "GaussMarkov",
    "Gyro",
    "NoiseTerm",
    "Quantization",
    "RateRamp",
    "RateRandomWalk",
    "SecondOrderGaussMarkov",
    "presets",
    "units",
    "TERM_TYPES",
]

#: term classes by name (used by study configs)
TERM_TYPES = {
    cls.__name__: cls
    for cls in (
        AngleRandomWalk,
        BiasInstability,
        GaussMarkov,
        Quantization,
        RateRamp,
        RateRandomWalk,
        SecondOrderGaussMarkov,
    )
}
