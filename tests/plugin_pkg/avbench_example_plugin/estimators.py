"""Estimators of the example plugin.

``TwoSlope`` is declared in the entry-point group ``avbench.estimators`` (name ``two_slope``);
``WhiteOnly`` registers itself on import (``@register``), for configs that list this module in
``[study] plugins``.
"""

import numpy as np

from avbench.estimators import Estimator, allan_variance, register


class TwoSlope(Estimator):
    """N and K from a cluster-count-weighted least-squares fit of N^2/tau + K^2 tau/3 to the AV."""

    def __init__(self, *, taus="octave", overlapping=True):
        self.taus = taus
        self.overlapping = overlapping

    def _fit(self, rate, dt):
        av = allan_variance(rate, dt, taus=self.taus, overlapping=self.overlapping)
        w = np.sqrt(av.J - 1.0) / av.avar  # relative errors of the AV values ~ 1 / sqrt(J - 1)
        X = np.column_stack([1.0 / av.tau, av.tau / 3.0]) * w[:, None]
        beta = np.linalg.lstsq(X, av.avar * w, rcond=None)[0]
        coefs = {c: float(np.sqrt(b)) if b > 0 else np.nan for c, b in zip("NK", beta)}
        nonphysical = {c: bool(b <= 0) for c, b in zip("NK", beta)}
        return coefs, nonphysical, {"beta": beta, "tau": av.tau}


@register("example_white")
class WhiteOnly(Estimator):
    """N alone, from the Allan variance at tau = dt (white rate noise: AV = N^2 / tau)."""

    def __init__(self, *, overlapping=True):
        self.overlapping = overlapping

    def _fit(self, rate, dt):
        av = allan_variance(rate, dt, taus=np.array([dt]), overlapping=self.overlapping)
        return {"N": float(np.sqrt(av.avar[0] * dt))}, {}, {}
