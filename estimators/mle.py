"""Exact Gaussian maximum likelihood of the composite gyro model through the Kalman filter.

The rate is modelled as white noise (N) + first-order Gauss-Markov (sigma, Tc) + rate random walk (K)
(+ deterministic drift R), the model of Nikolic et al. (IEEE Sensors J. 2016) and of the
GMWM literature; the likelihood is evaluated exactly by the Kalman filter of a linear Gaussian
state-space model (statsmodels ``MLEModel``; Durbin & Koopman 2012, Ch. 7 for the prediction error
decomposition and Ch. 5 for the exact diffuse initialisation of the level and drift).

Block averaging (setting ``block``)
-----------------------------------
The Kalman filter costs O(n) per likelihood evaluation, too slow for 1e6 samples and a few hundred
evaluations. The record is therefore replaced by its means over non-overlapping blocks of m samples,
and the likelihood of *the block means* is computed **exactly**: the block mean of the model is
again a linear state-space model with known matrices (no approximation, only the information at
time scales below m dt is given up). Per sample,
:math:`x_k = \\phi x_{k-1} + e_k` (:math:`\\phi = e^{-\\Delta t/T_c}`, :math:`\\mathrm{var}\\,e =
\\sigma^2(1-\\phi^2)`; Miao et al. 2015, eq. 6), :math:`L_k = L_{k-1} + r\\Delta t + w_k`
(:math:`\\mathrm{var}\\,w = K^2\\Delta t`), :math:`y_k = x_k + L_k + \\varepsilon_k`
(:math:`\\mathrm{var}\\,\\varepsilon = N^2/\\Delta t`). With :math:`s_j` the GM value and
:math:`L_j` the level at the end of block j, and :math:`c_i = (1-\\phi^i)/(1-\\phi)`,

.. math::

    s_{j+1} &= \\phi^m s_j + \\textstyle\\sum_{i=1}^m \\phi^{i-1} e_{(i)}, &
    \\bar x_{j+1} &= a\\,s_j + \\tfrac1m\\textstyle\\sum_{i=1}^m c_i\\, e_{(i)},\\quad
    a = \\tfrac1m\\textstyle\\sum_{i=1}^m\\phi^i, \\\\
    L_{j+1} &= L_j + r\\,m\\Delta t + \\textstyle\\sum_{i=1}^m w_{(i)}, &
    \\bar L_{j+1} &= L_j + r\\Delta t\\,\\tfrac{m+1}2 + \\tfrac1m\\textstyle\\sum_{i=1}^m i\\,w_{(i)},

(index (i) counts innovations from the *end* of the block), and the block mean is
:math:`\\bar y_{j+1} = \\bar x_{j+1} + \\bar L_{j+1} + \\bar\\varepsilon_{j+1}` with
:math:`\\mathrm{var}\\,\\bar\\varepsilon = N^2/(m\\Delta t)`. The state is
:math:`(s, \\bar x, L, \\bar L[, r])`; the disturbance covariances follow from the sums above. For
m = 1 this is the sample-level model itself. Quantization noise: averaging divides its variance by
m^2 (its block mean telescopes to a difference of two angle errors), so for m > 1 it
is often negligible beside the white noise; it can be modelled exactly with the latent "QN": with
white angle noise :math:`\\theta` of std Q the block mean of the quantization rate telescopes to
:math:`(\\theta_j - \\theta_{j-1})/(m\\Delta t)`, :math:`\\theta_j` the angle error at the end of
block j, i.e. two more states :math:`(\\theta_j, \\theta_{j-1})` with
:math:`T = \\begin{pmatrix}0&0\\\\1&0\\end{pmatrix}`, disturbance variance :math:`Q^2` on the first.

The default ``block="auto"`` takes the smallest m giving at most ``max_blocks`` (50,000) block means,
but never more than a fifth of the Gauss-Markov correlation time found by the GMWM starting fit (so
that the GM stays resolved). For 1e6 samples at 100 Hz this is m = 20 (0.2 s blocks) and a fit
of WN+GM+RW takes 10-25 s on a shared 2-core machine (GMWM start included; measured on the ADIS16405
records and on simulated records). The price is paid by N: the white-noise information sits
at the shortest time scales, so its relative standard error becomes :math:`1/\\sqrt{2n/m}` instead
of the CRLB :math:`1/\\sqrt{2n}`; B, K and R, whose information lies at long time scales, lose
almost nothing. Use ``block=1`` for the full sample-level likelihood.

Starting values come from :class:`estimators.gmwm.GMWM` with the same latent model, fitted on the
octaves the block means resolve (cluster sizes >= m). Standard errors
are from the observed information (numerical Hessian of the log-likelihood in the log-parameters,
statsmodels ``cov_type="approx"``) by the delta method; the drift, a diffuse state, gets the filtered
GLS estimate and its filtered standard deviation.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pandas as pd
from statsmodels.tsa.statespace.initialization import Initialization
from statsmodels.tools.sm_exceptions import PrecisionWarning
from statsmodels.tsa.statespace.mlemodel import MLEModel

from estimators.base import Estimator, register
from estimators.gmwm import GMWM, parse_model

__all__ = ["MLE", "BlockMeanModel", "block_means"]

_ALLOWED = ("QN", "WN", "GM", "RW", "DR")


def block_means(rate, m: int) -> np.ndarray:
    """Means of the non-overlapping blocks of ``m`` samples (a trailing partial block is dropped)."""
    J = rate.size // m
    return rate[: J * m].reshape(J, m).mean(axis=1)


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


@register("mle")
class MLE(Estimator):
    """Maximum-likelihood estimator of (Q,) N, B (via GM), K (and R) through the Kalman filter.

    Parameters
    ----------
    model : str or list of str
        Latent model from "QN", "WN", "GM", "RW", "DR" (default "WN+GM+RW"); see
        :func:`estimators.gmwm.parse_model`.
    block : "auto" or int
        Block size m for the exact block-mean likelihood (module docstring); 1 = the samples themselves.
    max_blocks : int
        For ``block="auto"``: target number of block means (default 50,000).
    maxiter : int
        Iterations of the L-BFGS optimiser (default 200).

    Attributes
    ----------
    diagnostics_ : dict
        ``std_err`` (pandas.Series like ``coefficients_``), ``params`` (sigma, Tc, ...), ``block``,
        ``loglike``, ``converged``, ``start`` (the GMWM starting coefficients).

    Examples
    --------
    >>> import numpy as np
    >>> from noise_models import Gyro, AngleRandomWalk, RateRandomWalk
    >>> g = Gyro(dt=0.1, terms=[AngleRandomWalk(N=1e-3), RateRandomWalk(K=1e-5)])
    >>> x = g.simulate(100_000, np.random.default_rng(3))
    >>> est = MLE(model="WN+RW", block=1).fit(x, 0.1)
    >>> bool(abs(est.coefficients_["N"] / 1e-3 - 1) < 5 * est.diagnostics_["std_err"]["N"] / 1e-3)
    True
    """

    def __init__(self, *, model="WN+GM+RW", block="auto", max_blocks=50_000, maxiter=200):
        self.model = model
        self.block = block
        self.max_blocks = max_blocks
        self.maxiter = maxiter

    def _check(self):
        latents = parse_model(self.model)
        bad = [lat for lat in latents if lat not in _ALLOWED]
        if bad:
            raise ValueError(f"model: the MLE supports latents {', '.join(_ALLOWED)}; got {', '.join(bad)}")
        if not any(lat in latents for lat in ("QN", "WN", "GM", "RW")):
            raise ValueError("model: expected at least one stochastic latent (QN, WN, GM or RW)")
        if not (self.block == "auto" or (isinstance(self.block, (int, np.integer))
                                         and not isinstance(self.block, bool) and self.block >= 1)):
            raise ValueError(f"block: expected 'auto' or a positive integer, got {self.block!r}")
        for name in ("max_blocks", "maxiter"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
                raise ValueError(f"{name}: expected a positive integer, got {v!r}")
        return latents

    def _fit(self, rate, dt):
        latents = self._check()
        n = rate.size
        m = max(1, math.ceil(n / self.max_blocks)) if self.block == "auto" else int(self.block)
        if n // m < 16:
            raise ValueError(f"block: {m} samples per block leave {n // m} block means; expected at least 16")
        # the start is fitted on the scales the block means resolve (tau >= m dt)
        start = GMWM(model="+".join(latents), min_m=_pow2_at_least(m)).fit(rate, dt)
        sp = start.diagnostics_["params"]
        if self.block == "auto" and "GM" in latents:
            m = max(1, min(m, int(sp["GM.tc"] / (5 * dt))))
        y = block_means(rate, m)
        if y.size < 16:
            raise ValueError(f"block: {m} samples per block leave {y.size} block means; expected at least 16")
        mod = BlockMeanModel(y, latents, m, dt)
        x0 = _start_values(latents, sp, start.diagnostics_, dt)
        with np.errstate(all="ignore"), warnings.catch_warnings():
            # statsmodels warns that finite-difference Hessians are approximate (we know; see docs)
            warnings.simplefilter("ignore", PrecisionWarning)
            # the matrices are built with real arithmetic: finite differences, not complex steps
            res = mod.fit(start_params=x0, method="lbfgs", maxiter=self.maxiter, disp=False,
                          optim_complex_step=False, cov_type="approx",
                          cov_kwds={"approx_complex_step": False, "approx_centered": True})
            cov = np.asarray(res.cov_params())
        vals = mod.values(res.params)
        # a non-positive variance (flat or non-concave likelihood, e.g. a term at zero) has no
        # standard error: NaN, not 0
        var = np.diag(cov) if np.all(np.isfinite(cov)) else np.full(len(vals), np.nan)
        se_log = dict(zip(mod.param_names, np.sqrt(np.where(var > 0, var, np.nan))))
        from noise_models.terms import B_EQUIV_OVER_SIGMA

        coefs, std = {}, {}
        for name, coef, scale in (("log_Q", "Q", 1.0), ("log_N", "N", 1.0), ("log_sigma", "B", B_EQUIV_OVER_SIGMA), ("log_K", "K", 1.0)):
            if name in vals:
                coefs[coef] = scale * vals[name]
                std[coef] = coefs[coef] * se_log[name]
        if "DR" in latents:
            # the filter runs on scaled data: the slope state is in scaled units
            r = float(res.filtered_state[-1, -1]) / mod.scale
            coefs["R"] = abs(r)
            std["R"] = float(math.sqrt(max(res.filtered_state_cov[-1, -1, -1], 0.0))) / mod.scale
        converged = bool(res.mle_retvals.get("converged", False)) if res.mle_retvals else False
        diag = {
            "std_err": pd.Series(std, dtype=float).reindex(["Q", "N", "B", "K", "R"]),
            "params": {k[4:]: v for k, v in vals.items()},
            "block": m,
            "loglike": float(res.llf) + y.size * math.log(mod.scale),
            "converged": converged,
            "start": start.coefficients_,
        }
        if not np.isfinite(res.llf):
            diag["failure"] = "non-finite log-likelihood at the optimum"
        return coefs, {}, diag


def _pow2_at_least(m: int) -> int:
    return 1 << max(0, math.ceil(math.log2(m)))


def _start_values(latents, sp, gdiag, dt):
    """log-parameters from the GMWM fit; a term GMWM set to 0 starts at 1 % of its largest value."""
    avar, tau = gdiag["avar"], gdiag["tau"]
    out = []
    if "QN" in latents:
        out.append(sp["QN.Q"] if sp["QN.Q"] > 0 else 0.01 * math.sqrt(avar[0] * tau[0] ** 2 / 3))
    if "WN" in latents:
        out.append(sp["WN.N"] if sp["WN.N"] > 0 else 0.01 * math.sqrt(avar[0] * tau[0]))
    if "GM" in latents:
        out += [sp["GM.sigma"], sp["GM.tc"]]
    if "RW" in latents:
        top = math.sqrt(np.max(3 * avar / tau))
        out.append(max(sp["RW.K"], 0.01 * top))
    return np.log(np.maximum(np.array(out, dtype=float), 1e-300))
