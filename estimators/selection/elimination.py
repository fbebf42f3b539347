"""Choosing the terms of a model by a penalised likelihood: backward elimination, and the choice
between non-nested models.

Criterion: :math:`-2\\ell + c\\,p` for a model of p parameters and maximised log-likelihood
:math:`\\ell` (:func:`penalised`), the per-parameter penalty ``c`` of :data:`PENALTY`:

* ``"bic"``: :math:`c = \\log n`, the Bayesian information criterion (Schwarz 1978), consistent for
  the true set as n grows;
* ``"lr"``: :math:`c = 2.706`, the 5 % likelihood-ratio test of one variance at its boundary 0
  (the chi-bar-squared null of Self & Liang 1987, :mod:`avbench.estimators.selection.evidence`).

:data:`SLOPE_PENALTY` is the same for a parameter whose null is interior (a trend slope): BIC's
:math:`\\log n`, or the two-sided :math:`\\chi^2_1` 95 % point 3.841.

:func:`backward_elimination`: from the full model, drop the term whose removal lowers the criterion
most, until none does (or one term is left). :func:`wald_drop_candidates` limits each round's refits
to the terms whose Wald statistic is not far above the penalty. :func:`choose_by_criterion`: the
model of lowest criterion among non-nested ones (the comparison is the criterion's, not a test),
with their weights :math:`\\propto e^{-\\Delta_m/2}` (Akaike weights; Burnham & Anderson 2002).

Each returns what it chose and why (:class:`Elimination`, :class:`ModelChoice`); the fits
themselves are the caller's objects, reached through the callables it passes.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Hashable, Sequence
from typing import Any, NamedTuple

import numpy as np

from avbench.estimators.selection.averaging import criterion_weights
from avbench.estimators.selection.evidence import CHI2_CRITICAL_5, CHIBAR2_CRITICAL_5

__all__ = ["PENALTY", "SLOPE_PENALTY", "penalised", "wald_drop_candidates", "Elimination", "backward_elimination",
           "ModelChoice", "choose_by_criterion"]

#: penalty per parameter of each selection criterion, as a function of the record length n
PENALTY = {"bic": math.log, "lr": lambda n: CHIBAR2_CRITICAL_5}
#: the penalty of a parameter whose null is interior (a trend slope, either sign): the 5 % test is the
#: two-sided chi2_1 95 % point, not the boundary mixture's
SLOPE_PENALTY = {"bic": math.log, "lr": lambda n: CHI2_CRITICAL_5}


def penalised(loglik: float, n_params: int, penalty: float) -> float:
    """The criterion :math:`-2\\ell + c\\,p` (lower is better)."""
    return -2 * loglik + n_params * penalty


def wald_drop_candidates(names: Sequence[str], info: np.ndarray, absent, penalty: float) -> list[str]:
    """Terms worth trying to drop: those at their boundary (``absent``) and those whose log-variance
    Wald statistic :math:`1/\\mathrm{se}(\\log a)^2` (from the inverse of ``info``, the information in
    the log-variances) is below 4 x the penalty: a term far above the threshold would never be
    dropped, so its refit is skipped. A singular information makes every term a candidate."""
    p = len(names)
    try:
        cov = np.linalg.inv(info)
        var = np.diag(cov)[:p]
    except np.linalg.LinAlgError:
        var = np.full(p, np.inf)
    out = []
    for i, c in enumerate(names):
        v = var[i] if np.isfinite(var[i]) and var[i] > 0 else np.inf
        if c in absent or 1.0 / v < 4 * max(penalty, 1.0):
            out.append(c)
    return out


class Elimination(NamedTuple):
    """What :func:`backward_elimination` chose and why: ``chosen`` the final fit; ``visited`` every
    fit made, keyed by its tuple of terms (the full model first, in the order fitted); ``dropped``
    the terms removed, in order; ``stop`` why it stopped (``"no improvement"``, ``"no candidate"``
    or ``"one term left"``)."""

    chosen: Any
    visited: dict
    dropped: list
    stop: str


def backward_elimination(full, terms: Callable[[Any], Sequence[Hashable]], criterion: Callable[[Any], float],
                         candidates: Callable[[Any], Sequence[Hashable]],
                         refit: Callable[[Any, list], Any],
                         admissible: Callable[[list], bool] = lambda sub: True) -> Elimination:
    """Backward elimination on ``criterion`` (lower is better) from the fit ``full``.

    ``terms(fit)``: the fit's terms; ``candidates(fit)``: the terms worth trying to drop from it;
    ``refit(fit, sub)``: the fit of the terms ``sub`` (warm-started from ``fit``), made once per
    set of terms; ``admissible(sub)``: whether ``sub`` is a model at all. Each round fits every
    admissible candidate's reduced model and moves to the best one if it lowers the criterion (ties:
    the first candidate)."""
    visited = {tuple(terms(full)): full}
    cur, dropped, stop = full, [], "one term left"
    while len(terms(cur)) > 1:
        cands = []
        for c in candidates(cur):
            sub = [x for x in terms(cur) if x != c]
            if not admissible(sub):
                continue
            key = tuple(sub)
            if key not in visited:
                visited[key] = refit(cur, sub)
            cands.append((c, visited[key]))
        if not cands:
            stop = "no candidate"
            break
        c, best = min(cands, key=lambda t: criterion(t[1]))
        if criterion(best) < criterion(cur):
            cur = best
            dropped.append(c)
        else:
            stop = "no improvement"
            break
    return Elimination(chosen=cur, visited=visited, dropped=dropped, stop=stop)


class ModelChoice(NamedTuple):
    """What :func:`choose_by_criterion` chose and why: ``chosen`` the key of the model of lowest
    criterion; ``criteria`` each model's criterion; ``weights`` each model's weight
    :math:`e^{-\\Delta/2}/\\sum e^{-\\Delta/2}` (None with a single model)."""

    chosen: Hashable
    criteria: dict
    weights: dict | None


def choose_by_criterion(models: dict, criterion: Callable[[Any], float]) -> ModelChoice:
    """The model of ``models`` (key -> fit) with the lowest ``criterion`` (ties: the first)."""
    chosen = min(models, key=lambda k: criterion(models[k]))
    weights = None
    if len(models) > 1:
        weights = criterion_weights({k: criterion(m) for k, m in models.items()})
    return ModelChoice(chosen=chosen, criteria={k: float(criterion(m)) for k, m in models.items()}, weights=weights)
