"""Standard errors and confidence intervals of the coefficients, common to every estimator.

After ``fit`` every estimator has ``std_err_`` (``pandas.Series`` indexed Q, N, B, K, R; SI; NaN
where the method gives none) and ``conf_int(level=0.95, conservative=False)``. Where the standard
errors come from:

=====================  ==========================================================================
``whittle``            inverse Whittle information at the estimate (:func:`avbench.estimators.likelihood.crlb.crlb`)
``gmwm``               GMM sandwich :math:`(D^T\\Omega^{-1}D)^{-1}` (Guerrier et al. 2013)
``mle``                observed information of the exact likelihood, delta method
LS curve fits          :func:`~avbench.estimators.curve_fits.least_squares.ls_std_err`: the sandwich of the least-squares solution with the
                       EDF (diagonal) covariance of the AV values under the fitted model, delta
                       method from :math:`\\beta` to the coefficients
every estimator        :meth:`Estimator.bootstrap` (:func:`parametric_bootstrap`): refit
                       ``n_draws`` records simulated from the fitted model with the exact
                       generators of :mod:`noise_models`; the only source for the practitioners'
                       baselines and the online filters (their cost is n_draws fits, so it is a
                       call, never automatic)
=====================  ==========================================================================

Intervals (:func:`interval`). The coefficients are positive scale parameters; their estimators are
closer to normal on the log scale (a variance estimate is roughly scaled chi^2), so the interval is
:math:`c\\,\\exp(\\pm z\\,\\mathrm{se}/c)` (the delta-method interval of log c, mapped back): always
positive, wider above than below, and identical to :math:`c \\pm z\\,\\mathrm{se}` to first order.
Where the relative standard error exceeds 0.5 (``MAX_LOG_REL_SE``; the data then say little and the
log-scale bound :math:`e^{z\\,\\mathrm{se}/c}` would explode) the interval is
:math:`[\\max(0, c - z\\,\\mathrm{se}),\\ c + z\\,\\mathrm{se}]`.
A coefficient estimated as 0 (a term dropped by model selection, or a scale run to its floor) has
lower bound 0 and the upper bound the estimator supplies (``parts_.zero_bounds``: a bound times
:math:`z^{p}`, with its power p; ``whittle`` gives the boundary bound of a
variance, :math:`c^2 \\le z\\,\\mathrm{se}(c^2)`), else NaN. Intervals ignore any bias of the estimator: coverage is
what the coverage study measures.

``conservative=True`` gives an *overbound* in the sense of Lethander & Taylor (NAVIGATION 2023):
one-sided upper bounds that hold for all modelled coefficients at once with probability at least
``level`` (Bonferroni over the p coefficients with a finite bound: each at one-sided level
1 - (1 - level)/p); the lower column is then 0.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
from scipy.special import ndtri

from avbench.noise_models.units import COEFFICIENTS

__all__ = ["interval", "parametric_bootstrap", "refits", "zero_quantile"]


#: above this relative standard error the log-scale interval is not used (exp(z se/c) explodes when
#: the data say little): the plain c +- z se, clipped at 0, instead
MAX_LOG_REL_SE = 0.5


def _check_level(level) -> float:
    if isinstance(level, bool) or not isinstance(level, (int, float, np.floating)) or not 0 < level < 1:
        raise ValueError(f"level: expected a probability strictly between 0 and 1, got {level!r}")
    return float(level)


def interval(coefs: pd.Series, se: pd.Series, level=0.95, conservative=False, upper_if_zero=None) -> pd.DataFrame:
    """Log-scale intervals for positive coefficients (module docstring); DataFrame lower, upper (SI)."""
    level = _check_level(level)
    c = coefs.reindex(list(COEFFICIENTS)).astype(float)
    s = se.reindex(list(COEFFICIENTS)).astype(float)
    ok = np.isfinite(c) & np.isfinite(s) & (c > 0)
    z = _z(level, conservative, int(ok.sum()))
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        r = np.where(ok, s / c, np.nan)
        log_scale = r <= MAX_LOG_REL_SE
        lower = np.where(ok, np.where(log_scale, c * np.exp(-z * r), np.maximum(c - z * s, 0.0)), np.nan)
        upper = np.where(ok, np.where(log_scale, c * np.exp(z * r), c + z * s), np.nan)
    zero = np.isfinite(c) & (c == 0)
    lower = np.where(zero, 0.0, lower)
    if upper_if_zero is not None:
        u0 = upper_if_zero.reindex(list(COEFFICIENTS)).astype(float).to_numpy()
        upper = np.where(zero, u0, upper)
    if conservative:
        lower = np.where(np.isfinite(upper), 0.0, lower)
    return pd.DataFrame({"lower": lower, "upper": upper}, index=list(COEFFICIENTS))


def _z(level, conservative, n_bounds):
    # the normal quantile by scipy.special.ndtri, which scipy.stats.norm.ppf calls: the same bits, without
    # importing scipy.stats (~0.7 s, paid by every study worker's first block; results/bench/README.md)
    if conservative:
        return ndtri(1 - (1 - level) / max(int(n_bounds), 1))
    return ndtri(0.5 + level / 2)


def zero_quantile(level, conservative, se, coefs) -> float:
    """The normal quantile :func:`interval` uses, for the bounds of terms estimated as 0."""
    level = _check_level(level)
    c = coefs.reindex(list(COEFFICIENTS)).astype(float)
    s = se.reindex(list(COEFFICIENTS)).astype(float)
    return float(_z(level, conservative, int((np.isfinite(c) & np.isfinite(s) & (c > 0)).sum())))


def refits(estimator, n_samples: int, dt: float, n_draws: int, seed=0):
    """Clones of a fitted ``estimator``, each fitted to one of ``n_draws`` records of ``n_samples``
    simulated from its coefficients with the exact generators (the five-term model,
    :meth:`avbench.noise_models.Gyro.from_coefficients`, flicker memory twice the record); a refit
    that raises is a missing draw (as in the studies). The parametric bootstraps of the standard
    errors (:func:`parametric_bootstrap`) and of the fit check
    (:func:`avbench.estimators.allan.fit_check.bootstrap_fit_check`) iterate over them."""
    from avbench.noise_models import Gyro

    g = Gyro.from_coefficients(estimator.coefficients_, dt, flicker_tau_max=2 * n_samples * dt)
    if g is None:
        raise ValueError("bootstrap: the fit gave no positive coefficient to simulate from")
    for ss in np.random.SeedSequence(seed).spawn(int(n_draws)):
        e = estimator.clone()
        try:
            e.fit(g.simulate(int(n_samples), np.random.default_rng(ss)), dt)
        except Exception:  # a failed refit is a missing draw
            continue
        yield e


def parametric_bootstrap(estimator, n_samples: int, dt: float, n_draws: int = 20, seed=0) -> pd.Series:
    """Standard errors (SI) by refitting ``n_draws`` records simulated from the fitted model.

    ``estimator`` is fitted; each draw uses an independent stream
    ``SeedSequence(seed).spawn(n_draws)`` and a clone of the estimator. The standard error is the
    standard deviation of the physical refits (NaN with fewer than 3).
    """
    if isinstance(n_draws, bool) or not isinstance(n_draws, (int, np.integer)) or n_draws < 3:
        raise ValueError(f"n_draws: expected an integer >= 3, got {n_draws!r}")
    draws = [e.coefficients_.to_numpy(dtype=float) for e in refits(estimator, n_samples, dt, n_draws, seed)]
    arr = np.array(draws) if draws else np.full((0, len(COEFFICIENTS)), np.nan)
    out = {}
    for j, c in enumerate(COEFFICIENTS):
        v = arr[:, j][np.isfinite(arr[:, j])] if arr.size else np.array([])
        out[c] = float(np.std(v, ddof=1)) if v.size >= 3 else math.nan
    return pd.Series(out, dtype=float)
