"""The block-mean state-space model of :mod:`avbench.estimators.likelihood.mle` as a statsmodels ``MLEModel``.

The reference implementation: :mod:`avbench.estimators.likelihood.mle` fits with its own compiled likelihood
(:mod:`avbench.estimators.likelihood._mle_kernels`, same system matrices); the tests hold that one to this model's
Kalman filter and optimiser. Kept apart so that nothing outside the tests imports statsmodels'
state space (about 1 s and 40 MB per process).
"""

from __future__ import annotations

import numpy as np
from statsmodels.tsa.statespace.initialization import Initialization
from statsmodels.tsa.statespace.mlemodel import MLEModel

from avbench.estimators.likelihood._mle_kernels import BlockMeanSystem

__all__ = ["BlockMeanModel"]


class BlockMeanModel(MLEModel):
    """Exact state-space model of the block means of (quantization +) white + GM + RW (+ drift).

    See the module docstring for the block algebra.

    Parameters (``params``) are the natural logarithms of the stochastic terms' fit parameters, in the
    model's order (:class:`BlockMeanSystem`). The level (and the drift slope, if "DR") are diffuse states.

    The filter runs on ``endog * scale`` (default: 1 / std of the block means), with the noise
    parameters scaled to match: statsmodels declares the filter converged (steady state) once the
    covariance changes by less than an *absolute* 1e-19, which for rates in rad/s (variances
    ~1e-10) happens long before convergence and biases the likelihood. The reported log-likelihood
    is converted back to the original units (``llf + nobs * log(scale)``).
    """

    def __init__(self, endog, latents, m: int, dt: float, scale: float | None = None):
        endog = np.asarray(endog, dtype=float)
        self.scale = float(scale) if scale is not None else 1.0 / float(np.std(endog) or 1.0)
        endog = endog * self.scale
        self.system = BlockMeanSystem(latents, m, dt)
        self.latents = self.system.latents
        self.m, self.dt = self.system.m, self.system.dt
        k = self.system.k
        super().__init__(endog, k_states=k, k_posdef=k)
        self["design"] = self.system.Z[None, :]
        self["selection"] = np.eye(k)

    @property
    def param_names(self):
        return list(self.system.names)

    @property
    def start_params(self):
        return np.zeros(len(self.system.names))

    def values(self, params) -> dict:
        return self.system.values(params)

    def update(self, params, **kwargs):
        params = super().update(params, **kwargs)
        sysm = self.system
        T, Qc, H, P0, _ = sysm.matrices(params, self.scale)
        k = sysm.k
        init = Initialization(k)
        for a, b in sysm.stationary:
            init.set((a, b), "known", constant=np.zeros(b - a), stationary_cov=P0[a:b, a:b])
        init.set((sysm.lev, k), "diffuse")
        self["transition"] = T
        self["state_cov"] = Qc
        self["obs_cov"] = np.array([[H]])
        self.ssm.initialize(init)
