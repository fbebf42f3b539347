"""The exact state-space model of block means behind :mod:`estimators.mle` (statsmodels).

Kept apart so that ``import estimators`` does not import statsmodels (about 1 s and 40 MB per
process); :mod:`estimators.mle` imports this module when it fits.
"""

from __future__ import annotations

import math

import numpy as np
from statsmodels.tsa.statespace.initialization import Initialization
from statsmodels.tsa.statespace.mlemodel import MLEModel

__all__ = ["BlockMeanModel"]


def _gm_block(phi_log, sigma, m):
    """Transition and disturbance covariance of (s, xbar) for a GM with log(phi) = phi_log."""
    j = np.arange(1, m + 1, dtype=float)
    phi = math.exp(phi_log)
    c = np.expm1(j * phi_log) / math.expm1(phi_log)  # (1 - phi^j) / (1 - phi), stable as phi -> 1
    pw = np.exp((j - 1) * phi_log)  # phi^(j-1)
    q = sigma**2 * -math.expm1(2 * phi_log)  # sigma^2 (1 - phi^2)
    a = float(np.exp(j * phi_log).sum()) / m
    cov = q * np.array([[pw @ pw, pw @ c / m], [pw @ c / m, c @ c / m**2]])
    T = np.array([[phi**m, 0.0], [a, 0.0]])
    return T, cov


def _level_block(K2dt, m, dt, drift):
    j = np.arange(1, m + 1, dtype=float)
    cov = K2dt * np.array([[m, j.sum() / m], [j.sum() / m, (j @ j) / m**2]])
    T = np.array([[1.0, 0.0], [1.0, 0.0]])
    if drift:
        T = np.hstack([T, [[m * dt], [dt * (m + 1) / 2]]])
        T = np.vstack([T, [0.0, 0.0, 1.0]])
        cov = np.pad(cov, ((0, 1), (0, 1)))
    return T, cov


class BlockMeanModel(MLEModel):
    """Exact state-space model of the block means of (quantization +) white + GM + RW (+ drift).

    See the module docstring for the block algebra.

    Parameters (``params``) are the natural logarithms of, in order, Q (if "QN"), N (if "WN"),
    sigma and Tc (if "GM"), K (if "RW"). The level (and the drift slope, if "DR") are diffuse states.

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
        self.latents = tuple(latents)
        self.m, self.dt = int(m), float(dt)
        self.has_gm = "GM" in latents
        self.has_q = "QN" in latents
        self.drift = "DR" in latents
        self._q = 2 if self.has_gm else 0  # first state of the quantization block
        self._lev = self._q + (2 if self.has_q else 0)
        k = self._lev + 2 + (1 if self.drift else 0)
        super().__init__(endog, k_states=k, k_posdef=k)
        Z = np.zeros((1, k))
        Z[0, self._lev + 1] = 1.0
        if self.has_gm:
            Z[0, 1] = 1.0
        if self.has_q:  # block mean of theta-differences telescopes: (theta_j - theta_{j-1}) / (m dt)
            Z[0, self._q], Z[0, self._q + 1] = 1.0 / (m * dt), -1.0 / (m * dt)
        self["design"] = Z
        self["selection"] = np.eye(k)
        self._names = []
        for lat in self.latents:
            self._names += {"QN": ["log_Q"], "WN": ["log_N"], "GM": ["log_sigma", "log_tc"],
                            "RW": ["log_K"]}.get(lat, [])

    @property
    def param_names(self):
        return list(self._names)

    @property
    def start_params(self):
        return np.zeros(len(self._names))

    def values(self, params) -> dict:
        return dict(zip(self._names, np.exp(np.asarray(params, dtype=float))))

    def update(self, params, **kwargs):
        params = super().update(params, **kwargs)
        v = {key: (val if key == "log_tc" else val * self.scale) for key, val in self.values(params).items()}
        m, dt, k = self.m, self.dt, self.k_states
        T, Qc = np.zeros((k, k)), np.zeros((k, k))
        init = Initialization(k)
        if self.has_gm:
            sigma, tc = v["log_sigma"], v["log_tc"]
            Tg, Qg = _gm_block(-dt / tc, sigma, m)
            T[:2, :2], Qc[:2, :2] = Tg, Qg
            P0 = sigma**2 * np.outer(Tg[:, 0], Tg[:, 0]) + Qg  # (s_1, xbar_1) from a stationary s_0
            init.set((0, 2), "known", constant=np.zeros(2), stationary_cov=P0)
        if self.has_q:
            q, Q2 = self._q, v["log_Q"] ** 2
            T[q + 1, q] = 1.0
            Qc[q, q] = Q2
            init.set((q, q + 2), "known", constant=np.zeros(2), stationary_cov=Q2 * np.eye(2))
        K2dt = v.get("log_K", 0.0) ** 2 * dt
        Tl, Ql = _level_block(K2dt, m, dt, self.drift)
        T[self._lev :, self._lev :], Qc[self._lev :, self._lev :] = Tl, Ql
        init.set((self._lev, k), "diffuse")
        self["transition"] = T
        self["state_cov"] = Qc
        self["obs_cov"] = np.array([[v.get("log_N", 0.0) ** 2 / (m * dt)]])
        self.ssm.initialize(init)
