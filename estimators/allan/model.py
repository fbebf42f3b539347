"""The five-term Allan-variance model shared by every curve-fitting estimator.

.. math::

    \\sigma^2(\\tau) = \\frac{3Q^2}{\\tau^2} + \\frac{N^2}{\\tau} + \\frac{2\\ln 2}{\\pi}B^2
                     + \\frac{K^2\\tau}{3} + \\frac{R^2\\tau^2}{2}
                   = X(\\tau)\\,\\beta

with :math:`X = [\\tau^{-2}, \\tau^{-1}, 1, \\tau, \\tau^2]` and
:math:`\\beta = [3Q^2, N^2, (2\\ln2/\\pi)B^2, K^2/3, R^2/2]` (Lv et al. 2015, eqs 3-6; their eq. 6
prints the last element as K^2/2, a misprint for R^2/2). Columns are chosen by ``terms``.
"""

from __future__ import annotations

import math

import numpy as np

from avbench.estimators.validation import check_terms
from avbench.noise_models.units import COEFFICIENTS

__all__ = [
    "PLATEAU",
    "BETA_SCALE",
    "TAU_POWER",
    "design_matrix",
    "beta_from_coefficients",
    "coefficients_from_beta",
    "model_avar",
]

#: (2 ln 2 / pi): the bias-instability plateau factor, = 0.6643^2.
PLATEAU = 2.0 * math.log(2.0) / math.pi

#: beta_j = BETA_SCALE[c] * c**2
BETA_SCALE = {"Q": 3.0, "N": 1.0, "B": PLATEAU, "K": 1.0 / 3.0, "R": 0.5}

#: sigma^2 contribution of coefficient c is beta_c * tau**TAU_POWER[c]
TAU_POWER = {"Q": -2, "N": -1, "B": 0, "K": 1, "R": 2}


def design_matrix(tau, terms) -> np.ndarray:
    """Columns tau**p for the modelled ``terms`` (shape ``(len(tau), len(terms))``)."""
    tau = np.asarray(tau, dtype=float)
    return np.column_stack([tau ** TAU_POWER[c] for c in check_terms(terms)])


def beta_from_coefficients(coefs: dict, terms) -> np.ndarray:
    """beta for the given coefficients (SI), in the order of ``terms``."""
    return np.array([BETA_SCALE[c] * coefs[c] ** 2 for c in check_terms(terms)])


def coefficients_from_beta(beta, terms) -> tuple[dict, dict]:
    """Coefficients (SI) from a fitted beta; negative elements are non-physical (NaN, flagged).

    Returns ``(coefficients, nonphysical)``, two dicts keyed by coefficient name.
    """
    terms = check_terms(terms)
    coefs, nonphys = {}, {}
    for c, b in zip(terms, np.asarray(beta, dtype=float)):
        if not np.isfinite(b) or b < 0:
            coefs[c], nonphys[c] = math.nan, True
        else:
            coefs[c], nonphys[c] = math.sqrt(b / BETA_SCALE[c]), False
    return coefs, nonphys


def model_avar(coefs: dict, tau) -> np.ndarray:
    """The continuous-time model AV at ``tau`` for coefficients in SI (missing or NaN terms omitted)."""
    tau = np.asarray(tau, dtype=float)
    out = np.zeros_like(tau)
    for c in COEFFICIENTS:
        v = coefs.get(c, math.nan) if hasattr(coefs, "get") else coefs[c]
        if v is not None and np.isfinite(v):  # float64 arithmetic: an absurd value gives inf, not OverflowError
            out = out + BETA_SCALE[c] * np.float64(v) ** 2 * tau ** TAU_POWER[c]
    return out
