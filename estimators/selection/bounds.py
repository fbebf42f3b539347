"""Bounds for coefficients a latent-model fit does not resolve: the record's AV caps each term.

A term's AV alone, :math:`c^2 u(\\tau)` with u its exact AV at unit coefficient, cannot exceed the
record's AV anywhere, so

.. math:: c \\le \\min_\\tau \\sqrt{\\mathrm{AV}_{97.5\\%}(\\tau) / u(\\tau)},

with :math:`\\mathrm{AV}_{97.5\\%} = \\hat\\sigma^2\\,\\nu/\\chi^2_{\\nu}(0.025)` the upper 97.5 % chi^2
limit of the record's AV (the engine's edf :math:`\\nu`; :func:`av_upper_limits`). Two rules use it:

* a one-parameter term the fit put at zero (its scale on the lower bound) is reported as the interval
  [0, upper] (:func:`terms_at_zero`);
* a Gauss-Markov term that peaks within the first three octaves fitted (peak tau < :data:`GM_RESOLVED_PEAK_FACTOR`
  x the shortest tau) shapes the sensor's filter there and says nothing about bias instability: B gets
  [0, upper] with the bound any bias term obeys (the AV at every tau is at least the plateau
  (2 ln 2 / pi) B^2), and so do the terms that rise with tau (K, R), which then stand in for the
  missing bias instability (:func:`gm_unresolved`).

The coefficient keeps its value (the fitted model); a report flags it ``not resolved`` and shows the
interval (``parts_.unresolved``: coefficient -> upper).
"""

from __future__ import annotations

import math
import warnings

import numpy as np

from avbench.noise_models.latents import LATENT_TERMS, build_gyro, param_index
from avbench.noise_models.markov_terms import GM_PEAK_TAU_OVER_TC
from avbench.noise_models.term_base import PLATEAU

__all__ = ["GM_RESOLVED_PEAK_FACTOR", "av_upper_limits", "data_upper", "gm_unresolved", "terms_at_zero"]

#: a Gauss-Markov term whose AV peak (1.8926 Tc) lies less than this factor above the shortest tau
#: fitted (three octaves) shapes the first octaves -- the sensor's filter -- and does not resolve B
GM_RESOLVED_PEAK_FACTOR = 8.0

#: the one-parameter latents whose AV rises with tau: where the model has no bias instability they take its
#: share of the curve (:func:`gm_unresolved`)
RISING_LATENTS = ("RW", "DR")


def av_upper_limits(tau_all, avar_all, edf_all, usable) -> tuple[np.ndarray, np.ndarray]:
    """``(tau, upper)``: the usable octave taus (mask ``usable``) with an edf, and the upper 97.5 % chi^2 limits
    of the record's AV there (engine edf).

    >>> from scipy.stats import chi2
    >>> tau, up = av_upper_limits(np.array([1.0, 2.0]), np.array([4.0, 2.0]), np.array([10.0, 5.0]), np.ones(2, bool))
    >>> bool(up[0] == 4.0 * 10.0 / chi2.ppf(0.025, 10.0))
    True
    """
    # scipy.stats.chi2.ppf(q, nu) is 2 gammaincinv(nu / 2, q): the same bits, without importing scipy.stats
    from scipy.special import gammaincinv

    ok = usable & (edf_all > 0)
    return tau_all[ok], avar_all[ok] * edf_all[ok] / (2 * gammaincinv(edf_all[ok] / 2, 0.025))


def data_upper(lat, tau, upper_av, dt, tau_fl) -> float | None:
    """The largest coefficient of the one-parameter latent ``lat`` whose AV alone, c^2 u(tau) with u the term's
    exact AV at unit coefficient, stays below ``upper_av`` (:func:`av_upper_limits`) at every ``tau``:
    sqrt(min_tau upper_av / u); None where u is 0 at every tau. ``tau_fl``: a flicker term's memory."""
    unit = build_gyro((lat,), [1.0], dt, tau_fl).avar(tau)
    good = unit > 0
    return float(math.sqrt(np.min(upper_av[good] / unit[good]))) if good.any() else None


def gm_unresolved(latents, values, tau_first, tau, upper_av, dt, tau_fl) -> dict | None:
    """``{"B": (0, upper), ...}`` where the Gauss-Markov term of the fit (``values``: the fitted parameter
    vector of ``latents``) peaks within the first three octaves of the shortest tau fitted ``tau_first``
    (module docstring), with the terms that rise with tau (K, R) bounded too; None where it resolves B.
    An :class:`~avbench.estimators.base.IdentifiabilityWarning` says so (its bounds are in the record's
    unit, in the returned dict, not in the message: the fit may run on a standardised record). ``tau``,
    ``upper_av``: :func:`av_upper_limits`."""
    from avbench.estimators.base import IdentifiabilityWarning

    tc = values[param_index(latents, "GM") + LATENT_TERMS["GM"].fit_parameters.index("tc")]
    peak = GM_PEAK_TAU_OVER_TC * tc
    if peak >= GM_RESOLVED_PEAK_FACTOR * tau_first:
        return None
    upper = float(math.sqrt(np.min(upper_av) / PLATEAU))
    unresolved = {"B": (0.0, upper)}
    for lat in RISING_LATENTS:
        bound = data_upper(lat, tau, upper_av, dt, tau_fl) if lat in latents else None
        if bound is not None:
            unresolved[LATENT_TERMS[lat].coefficient] = (0.0, bound)
    others = [c for c in unresolved if c != "B"]
    warnings.warn(
        f"B not resolved: the Gauss-Markov term peaks at tau = {peak:.3g} s, within three octaves of the shortest "
        f"tau fitted ({tau_first:.3g} s), where the sensor's filter shapes the curve; bias instability is "
        f"bounded by the 97.5 % upper limit of the smallest AV read as a plateau"
        + (f"; {', '.join(others)} not resolved either (the model has no bias instability to share the curve "
           f"with): bounded by the record's AV" if others else "")
        + " (each bound: the upper end of the coefficient's interval)",
        IdentifiabilityWarning, stacklevel=3,
    )
    return unresolved


def terms_at_zero(latents, coefs, tau, upper_av, dt, tau_fl, known=()) -> dict:
    """``{coefficient: (0, upper)}`` for each one-parameter term of ``latents`` the fit put at zero (``coefs``:
    coefficient -> value, 0 where the term's scale ran to its lower bound) and not in ``known`` (already
    bounded), with its :func:`data_upper` bound. ``tau``, ``upper_av``: :func:`av_upper_limits`."""
    out = {}
    if not upper_av.size:
        return out
    for lat in latents:
        cls = LATENT_TERMS[lat]
        coef = cls.coefficient
        if coef is None or len(cls.fit_parameters) != 1 or coefs.get(coef, 1.0) != 0.0:
            continue
        if coef in known or coef in out:
            continue
        bound = data_upper(lat, tau, upper_av, dt, tau_fl)
        if bound is not None:
            out[coef] = (0.0, bound)
    return out
