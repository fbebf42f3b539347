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

from estimators.base import Estimator, register
from estimators.fit_check import assess_fit
from estimators.gmwm import GMWM, build_gyro, parse_model

__all__ = ["MLE", "block_means"]

_ALLOWED = ("QN", "WN", "GM", "RW", "DR")


def __getattr__(name):
    # the statsmodels-based model lives in estimators._mle_model, imported on first use
    if name in ("BlockMeanModel", "_gm_block", "_level_block"):
        from estimators import _mle_model

        return getattr(_mle_model, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def block_means(rate, m: int) -> np.ndarray:
    """Means of the non-overlapping blocks of ``m`` samples (a trailing partial block is dropped)."""
    J = rate.size // m
    return rate[: J * m].reshape(J, m).mean(axis=1)


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
        from estimators._mle_model import BlockMeanModel

        mod = BlockMeanModel(y, latents, m, dt)
        x0 = _start_values(latents, sp, start.diagnostics_, dt)
        with np.errstate(all="ignore"), warnings.catch_warnings():
            # statsmodels warns that finite-difference Hessians are approximate (we know; see docs)
            from statsmodels.tools.sm_exceptions import PrecisionWarning

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
        else:
            p = diag["params"]
            names = {"QN": ("Q",), "WN": ("N",), "GM": ("sigma", "tc"), "RW": ("K",)}
            values = [p[k] for lat in latents if lat in names for k in names[lat]]
            if "DR" in latents:
                values.append(coefs["R"])
            gyro = build_gyro(latents, values, dt)
            diag.update(assess_fit(rate, dt, gyro.avar, gyro, len(values), (m * dt, math.inf)))
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
