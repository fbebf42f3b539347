"""Evidence for a term of a model: the p-value of the likelihood ratio of dropping it.

A variance component's null value, 0, is on the boundary of its parameter space. The likelihood
ratio :math:`T = 2(\\hat\\ell - \\hat\\ell_{-j})` of dropping one such term then follows, under the
null and with the other parameters interior, the chi-bar-squared mixture
:math:`\\tfrac12\\chi^2_0 + \\tfrac12\\chi^2_1` (Self & Liang 1987, JASA 82, 605-610, Case 5):
half the time the unconstrained maximum would be below 0 and the constrained one sits on 0
(:math:`T = 0`), half the time it is interior (:math:`T \\sim \\chi^2_1`). Hence

.. math:: P(T \\ge t) = \\tfrac12 P(\\chi^2_1 \\ge t)\\ (t > 0),\\qquad P(T \\ge 0) = 1,

and the 5 % test rejects at :math:`t > \\chi^2_{1,0.90} = 2.706` (:data:`CHIBAR2_CRITICAL_5`). A
parameter whose null is interior (a trend slope, which may take either sign) keeps the two-sided
:math:`\\chi^2_1` law: :func:`two_sided_pvalue`, 5 % point :data:`CHI2_CRITICAL_5`.

A term is reported ``present`` when its p-value is below :data:`PRESENCE_ALPHA` (:func:`present`).

>>> from avbench.estimators.selection.evidence import chibar2_pvalue, CHIBAR2_CRITICAL_5
>>> chibar2_pvalue(0.0), round(chibar2_pvalue(CHIBAR2_CRITICAL_5), 6)
(1.0, 0.05)
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["CHIBAR2_CRITICAL_5", "CHI2_CRITICAL_5", "PRESENCE_ALPHA", "chibar2_pvalue", "two_sided_pvalue",
           "present"]

#: the 5 % critical value of the chi-bar-squared mixture 1/2 chi2_0 + 1/2 chi2_1: the chi2_1 90 % point
CHIBAR2_CRITICAL_5 = 2.705543454095404
#: the 5 % critical value of a two-sided chi2_1 test (an interior null): the chi2_1 95 % point
CHI2_CRITICAL_5 = 3.841458820694124
#: level below which a term's p-value makes it ``present``
PRESENCE_ALPHA = 0.05


def chibar2_pvalue(lr: float) -> float:
    """p-value of a likelihood-ratio statistic for one variance on the boundary 0: the null law is
    :math:`\\tfrac12\\chi^2_0 + \\tfrac12\\chi^2_1` (Self & Liang 1987, JASA 82, Case 5), so
    :math:`P(T \\ge t) = \\tfrac12 P(\\chi^2_1 \\ge t)` for t > 0 and 1 at t <= 0; NaN for a
    statistic that is not finite."""
    from scipy import stats

    if not np.isfinite(lr):
        return math.nan
    return 1.0 if lr <= 0 else 0.5 * float(stats.chi2.sf(lr, 1))


def two_sided_pvalue(z2: float) -> float:
    """p-value of a squared z-statistic whose null is interior: :math:`P(\\chi^2_1 \\ge z^2)`."""
    from scipy import stats

    return float(stats.chi2.sf(z2, 1))


def present(p_value, alpha: float = PRESENCE_ALPHA):
    """Whether a term is present at level ``alpha``: ``p_value < alpha`` (elementwise for arrays and
    Series)."""
    return p_value < alpha
