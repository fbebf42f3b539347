"""Model averaging over the terms a fit cannot tell from absent: Akaike or Schwarz (BIC) weights.

Keeping every candidate term protects the intervals (they are valid whichever terms are present)
but costs the point estimates: a term absent from the record still takes its share of the
information, and its neighbours' estimates carry its noise (white noise N beside an absent
quantization Q: 1.6-2.4 times the Cramér-Rao bound of the true model). Dropping the terms a
criterion rejects recovers that efficiency where they are absent and biases the neighbours where
they are present but weak (the pre-test estimator). Averaging over the submodels, each weighted by
its Akaike weight, sits between the two:

.. math:: \\bar\\theta = \\sum_m w_m\\,\\hat\\theta_m,\\qquad
          w_m = \\frac{e^{-\\Delta_m/2}}{\\sum_k e^{-\\Delta_k/2}},\\qquad
          \\Delta_m = \\mathrm{AIC}_m - \\min_k \\mathrm{AIC}_k,\\quad \\mathrm{AIC} = -2\\ell + 2p,

with a dropped term's parameter 0 in the models without it (Buckland, Burnham & Augustin 1997,
Biometrics 53, 603-618; Burnham & Anderson 2002, Sec. 4.2). For one variance whose signed estimate
is z standard errors from 0, the weight of the model with it is :math:`1/(1 + e^{1 - z^2/2})`: 0.27
at z = 0, 0.5 at :math:`z = \\sqrt 2`, 0.95 at z = 2.8.

With the penalty :math:`\\log n` per parameter instead of 2 (BIC), the weights approximate the models'
posterior probabilities under unit-information priors (Raftery 1995, Sociological Methodology 25,
111-163; Hoeting, Madigan, Raftery & Volinsky 1999, Statistical Science 14, 382-417): the model with
the variance weighs :math:`1/(1 + e^{(\\log n - z^2)/2})`, 0.004 at z = 0 and 0.5 at :math:`z^2 = \\log n`
(n = 72,000: 11.2), so an absent term is dropped almost always and a term near its detection limit
is shared between the models.

**Own term kept** (``"akaike_kept"``, ``"bic_kept"``): each coefficient is averaged over the models
that hold its own term, their weights renormalised, so a coefficient is never pulled toward 0 by the
models that drop it, while its neighbours still leave out the terms the data cannot tell from absent.
A model without a term states that the term is undetectable, not that it is 0; where the term is
present but weak the zeros of those models are a selection's bias on its own estimate. On
``results/random_gyros`` (200 gyros, 6 records each) this keeps Q, B and K at the Cramér-Rao bound
where the averages with zeros lose them (measured there).

Only terms whose absence the data do not rule out enter the average: a term whose Wald statistic
:math:`z^2` exceeds :func:`negligible_z2` of the penalty gives every model without it a weight below
:data:`NEGLIGIBLE_WEIGHT` of the full model's, and is kept in all of them (:func:`droppable`).

The averaged estimate's interval is not the averaged models' (Buckland et al.'s variance ignores the
selection's own randomness near the threshold): callers keep the full model's profile-likelihood
intervals, valid whatever the true set of terms.

>>> from avbench.estimators.selection.averaging import akaike_weights
>>> w = akaike_weights({("N",): (-100.0, 1), ("Q", "N"): (-100.0, 2)})
>>> round(w[("N",)], 4), round(w[("Q", "N")], 4)
(0.7311, 0.2689)
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Hashable, Sequence
from dataclasses import dataclass

import numpy as np

__all__ = ["PENALTY", "Rule", "RULES", "NEGLIGIBLE_WEIGHT", "NEGLIGIBLE_Z2", "negligible_z2", "criterion_weights",
           "akaike_weights", "penalised_weights", "droppable", "submodels", "average", "average_own_term"]

#: the penalty per parameter of the Akaike information criterion
PENALTY = 2.0
#: a model's weight relative to the full model's below which it is left out of the average
NEGLIGIBLE_WEIGHT = 1e-6


@dataclass(frozen=True)
class Rule:
    """An averaging: its penalty per parameter given the number of observations n, and whether each
    coefficient is averaged over the models holding its own term only (:func:`average_own_term`) or
    over every model, 0 where dropped (:func:`average`)."""

    penalty: Callable[[int], float]
    own_term: bool

    def mean(self, params: dict[Hashable, dict], weights: dict[Hashable, float], names: Sequence[str]) -> dict:
        """Each parameter of ``names`` averaged by this rule."""
        return (average_own_term if self.own_term else average)(params, weights, names)


def _akaike(n: int) -> float:
    return PENALTY


#: the averagings by name: Akaike or Schwarz (BIC) weights, with zeros or with each own term kept
RULES = {"akaike": Rule(_akaike, own_term=False), "bic": Rule(math.log, own_term=False),
         "akaike_kept": Rule(_akaike, own_term=True), "bic_kept": Rule(math.log, own_term=True)}


def negligible_z2(penalty: float) -> float:
    """The Wald statistic z^2 of a term above which every model without it has a negligible weight
    under ``penalty`` per parameter: dropping it lowers the log-likelihood by about z^2/2."""
    return penalty - 2 * math.log(NEGLIGIBLE_WEIGHT)


#: :func:`negligible_z2` of the Akaike penalty
NEGLIGIBLE_Z2 = negligible_z2(PENALTY)


def criterion_weights(criteria: dict) -> dict:
    """Each model's weight :math:`e^{-\\Delta_m/2}/\\sum_k e^{-\\Delta_k/2}` from its information
    criterion (key -> criterion, lower is better; :math:`\\Delta_m` its excess over the lowest)."""
    best = min(criteria.values())
    raw = {k: math.exp(-(c - best) / 2) for k, c in criteria.items()}
    total = sum(raw.values())
    return {k: v / total for k, v in raw.items()}


def penalised_weights(models: dict, penalty: float) -> dict:
    """Each model's weight from ``models`` (key -> (maximised log-likelihood, number of parameters))
    and its criterion :math:`-2\\ell + \\mathrm{penalty}\\,p`."""
    return criterion_weights({k: -2 * ll + penalty * p for k, (ll, p) in models.items()})


def akaike_weights(models: dict) -> dict:
    """Each model's Akaike weight from ``models``: key -> (maximised log-likelihood, number of
    parameters)."""
    return penalised_weights(models, PENALTY)


def droppable(names: Sequence[str], z2: Sequence[float], penalty: float = PENALTY) -> list[str]:
    """The terms of ``names`` worth averaging over: those whose Wald statistic ``z2`` (NaN: unknown)
    is not above :func:`negligible_z2` of ``penalty``."""
    limit = negligible_z2(penalty)
    return [c for c, z in zip(names, z2) if not (np.isfinite(z) and z > limit)]


def submodels(names: Sequence[str], candidates: Sequence[str],
              admissible: Callable[[list], bool] = lambda sub: True) -> list[list[str]]:
    """Every admissible model of ``names`` without some of ``candidates`` (the full model first,
    then by the number of terms dropped)."""
    out = []
    for k in range(len(candidates) + 1):
        for drop in itertools.combinations(candidates, k):
            sub = [c for c in names if c not in drop]
            if sub and admissible(sub):
                out.append(sub)
    return out


def average(params: dict[Hashable, dict], weights: dict[Hashable, float], names: Sequence[str]) -> dict:
    """The weighted average of each parameter of ``names`` over the models (``params``: model ->
    {name: value}); a model without a parameter contributes 0."""
    return {c: float(sum(w * params[m].get(c, 0.0) for m, w in weights.items())) for c in names}


def average_own_term(params: dict[Hashable, dict], weights: dict[Hashable, float], names: Sequence[str]) -> dict:
    """The average of each parameter of ``names`` over the models holding it, their weights renormalised
    (a parameter no model holds: 0).

    >>> average_own_term({"QN": {"Q": 1.0, "N": 2.0}, "N": {"N": 4.0}}, {"QN": 0.25, "N": 0.75}, ["Q", "N"])
    {'Q': 1.0, 'N': 3.5}
    """
    out = {}
    for c in names:
        held = {m: w for m, w in weights.items() if c in params[m]}
        total = sum(held.values())
        out[c] = float(sum(w * params[m][c] for m, w in held.items()) / total) if total > 0 else 0.0
    return out
