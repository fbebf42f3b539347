"""Exact Gaussian maximum likelihood of the composite gyro model through the Kalman filter.

The rate is modelled as white noise (N) + first-order Gauss-Markov (sigma, Tc) + rate random walk (K)
(+ deterministic drift R), the model of Nikolic et al. (IEEE Sensors J. 2016) and of the
GMWM literature; the likelihood is evaluated exactly by the Kalman filter of a linear Gaussian
state-space model (Durbin & Koopman 2012, Ch. 7 for the prediction error decomposition and Ch. 5 for
the exact diffuse initialisation of the level and drift; with a drift the equivalent augmented
filter of de Jong 1991, see "Kalman filters" below), compiled (:mod:`avbench.estimators.likelihood._mle_kernels`).
The same model as a statsmodels ``MLEModel`` (:mod:`avbench.estimators.likelihood._mle_model`) is the reference the
tests hold the compiled likelihood and the fit to.

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
that the GM stays resolved). For 1e6 samples at 100 Hz this is m = 20 (0.2 s blocks); the time of
a fit is in ``results/bench`` (``MleFit``, against the statsmodels reference path). The price is paid by N: the white-noise information sits
at the shortest time scales, so its relative standard error becomes :math:`1/\\sqrt{2n/m}` instead
of the CRLB :math:`1/\\sqrt{2n}`; B, K and R, whose information lies at long time scales, lose
almost nothing. Use ``block=1`` for the full sample-level likelihood.

Kalman filters
--------------
Two filters compute the same exact diffuse likelihood (to ~1e-14 relative; tested). Without a
drift, the exact initial filter of Durbin & Koopman (2012, Sec. 5.2): its covariance reaches a
steady state after a few thousand block means and every later step is a state update only. With
a drift ("DR") that filter's covariance never settles (the slope's variance keeps shrinking,
~1/t), and every step pays the full covariance recursion; there the **augmented** filter is used
(de Jong 1991, "The diffuse Kalman filter", Ann. Statist. 19; Durbin & Koopman 2012, Sec. 5.7):
the diffuse initial values (level, block-mean level, slope) become d extra columns of the state
mean, the covariance is that of a proper initial state and settles as without a drift, and the
likelihood is :math:`-\\tfrac12[n\\log2\\pi + \\sum\\log F_t + q - s'S^{-1}s + \\log|S|]` from the
accumulated cross-products of the innovation columns (:func:`avbench.estimators.likelihood._mle_kernels.augmented_loglike`).
On 2 h of the ADIS16405_X preset with "QN+WN+GM+RW+DR" this makes a likelihood evaluation ~8x
cheaper and the whole fit several times faster (``results/bench``, ``MleFitDrift``).

Starting values come from :class:`avbench.estimators.likelihood.gmwm.GMWM` with the same latent model, diagonal
weights and three trial correlation times, fitted on the octaves the block means resolve (cluster sizes >= m). The likelihood is
maximised by L-BFGS-B over the log-parameters, to a tighter tolerance than statsmodels' default
(each evaluation costs milliseconds), with the analytic score: each filter (exact initial, augmented)
carries the derivative recursions of its state (and diffuse columns), covariance, gain and forecast
variance in each parameter (Harvey 1989, Sec. 3.4.6), so one compiled pass gives the likelihood and
its gradient. L-BFGS-B's end point is then polished to the maximum by trust-region Newton steps
(:func:`_newton_polish`: on 30 minutes of a real ADIS16405 record L-BFGS-B stopped at a
saddle 2.9e3 below the maximum in log-likelihood, at a place the last bits of the samples decided);
a variance the likelihood drives to zero is set to exactly zero (``extras_["pinned_to_zero"]``;
the contract's floor rule then reports it not resolved, with its bound). Standard errors are from the
observed information (the Hessian in the log-parameters by central differences of the analytic
score) by the delta method; the drift, a diffuse state, gets the filtered GLS estimate and its
filtered standard deviation.

Where the maximum lies can surprise: on that record (and on axis x) the white noise goes to zero and
the Gauss-Markov term takes its place with a correlation time under one sample (0.6 dt): the short-time
noise is better described as slightly correlated than as white (the sensor's own filtering), and the
"B" of such a term (0.664 sigma) is not a bias instability. That is the model's maximum-likelihood
answer; where L-BFGS-B stopped on it is not a maximum.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from avbench.estimators.base import Estimator, register
from avbench.estimators.settings import Check, Interval, Options
from avbench.estimators.threads import one_blas_thread
from avbench.estimators.allan.fit_check import as_fit_check, assess_fit
from avbench.estimators.results import FitCheck, FitParts
from avbench.estimators.likelihood.gmwm import GMWM, build_gyro, parse_model
from avbench.noise_models.latents import LATENT_TERMS
from avbench.noise_models.units import COEFFICIENTS

__all__ = ["MLE", "block_means"]

def _allowed() -> list[str]:
    """The latents whose terms declare their part of the block-mean state space
    (:attr:`~avbench.noise_models.NoiseTerm.block_mean_states`), in the canonical order."""
    return [lat for lat, cls in LATENT_TERMS.items() if cls.block_mean_states is not None]


def _check_model(model) -> None:
    """A latent model the MLE can fit: :func:`~avbench.estimators.likelihood.gmwm.parse_model`'s grammar,
    latents from :func:`_allowed` only, at least one of them stochastic."""
    latents = parse_model(model)
    allowed = _allowed()
    bad = [lat for lat in latents if lat not in allowed]
    if bad:
        raise ValueError(f"model: the MLE supports latents {', '.join(allowed)}; got {', '.join(bad)}")
    if all(LATENT_TERMS[lat].deterministic for lat in latents):
        raise ValueError(f"model: expected at least one stochastic latent ({_stochastic()})")


def _stochastic() -> str:
    """'QN, WN, GM or RW': the latents of :func:`_allowed` with a random part."""
    stochastic = [lat for lat in _allowed() if not LATENT_TERMS[lat].deterministic]
    return f"{', '.join(stochastic[:-1])} or {stochastic[-1]}"


def _deterministic(latents) -> str | None:
    """The latent of ``latents`` without a random part (the drift "DR": a state of the filter, not a
    parameter), or None."""
    return next((lat for lat in latents if LATENT_TERMS[lat].deterministic), None)


def __getattr__(name):
    # the statsmodels reference model lives in avbench.estimators.likelihood._mle_model, imported on first use
    if name == "BlockMeanModel":
        from avbench.estimators.likelihood import _mle_model

        return getattr(_mle_model, name)
    if name == "BlockMeanSystem":
        from avbench.estimators.likelihood import _mle_kernels

        return getattr(_mle_kernels, name)
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
        :func:`avbench.estimators.likelihood.gmwm.parse_model`.
    block : "auto" or int
        Block size m for the exact block-mean likelihood (module docstring); 1 = the samples themselves.
    max_blocks : int
        For ``block="auto"``: target number of block means (default 50,000).
    maxiter : int
        Iterations of the L-BFGS optimiser (default 200).

    Attributes
    ----------
    extras_ : dict
        ``block``, ``start`` (the GMWM starting coefficients), ``polish_iterations``
        (trust-region Newton iterations after L-BFGS-B), ``finished_by_score`` (the trust region
        stopped where the log-likelihood's round-off hid the last gain and Newton steps on the score
        reached the maximum: :func:`_newton_polish`), ``pinned_to_zero`` (parameters the likelihood
        drove to zero: "N", "sigma", "K", ...). A fit that does not reach the maximum sets
        ``failure`` (its values are where the optimiser stopped).

    Examples
    --------
    >>> import numpy as np
    >>> from avbench.noise_models import Gyro, AngleRandomWalk, RateRandomWalk
    >>> g = Gyro(dt=0.1, terms=[AngleRandomWalk(N=1e-3), RateRandomWalk(K=1e-5)])
    >>> x = g.simulate(100_000, np.random.default_rng(3))
    >>> est = MLE(model="WN+RW", block=1).fit(x, 0.1)
    >>> bool(abs(est.coefficients_["N"] / 1e-3 - 1) < 5 * est.std_err_["N"] / 1e-3)
    True
    """
    round_off_amplified = True  # an optimiser's end point (Estimator.round_off_amplified)

    #: Kalman filter of the likelihood (:meth:`avbench.estimators.likelihood._mle_kernels.BlockMeanSystem.loglike`);
    #: not a setting: the benchmark sets "exact_initial" on an instance to time the path of before
    _loglike_method = "auto"

    parameter_constraints = {
        "model": [Check(_check_model, f"latents from {', '.join(_allowed())} joined by '+' (e.g. 'WN+GM+RW') or "
                                      f"a list of them, without repeats, at least one stochastic ({_stochastic()})",
                        explain=True)],
        "block": [Options("auto"), Interval(int, 1, None)],
        "max_blocks": [Interval(int, 1, None)],
        "maxiter": [Interval(int, 1, None)],
    }

    def __init__(self, *, model="WN+GM+RW", block="auto", max_blocks=50_000, maxiter=200):
        self.model = model
        self.block = block
        self.max_blocks = max_blocks
        self.maxiter = maxiter

    @one_blas_thread()
    def _fit(self, rate, dt):
        latents = parse_model(self.model)
        n = rate.size
        m = max(1, math.ceil(n / self.max_blocks)) if self.block == "auto" else int(self.block)
        if n // m < 16:
            raise ValueError(f"block: {m} samples per block leave {n // m} block means; expected at least 16")
        # the start is fitted on the scales the block means resolve (tau >= m dt)
        # (diagonal weights: a start, not an estimate; the model-weighted GMWM costs seconds more)
        start = GMWM(model="+".join(latents), min_m=_pow2_at_least(m), weighting="diagonal",
                     n_starts=_START_TRIES)
        start._assess = False  # the start's own poor-fit check is not used (the fit gets its own below)
        start.fit(rate, dt)
        x0, tc = gmwm_start_values(start, latents, dt)
        if self.block == "auto" and tc is not None:
            m = max(1, min(m, int(tc / (5 * dt))))
        y = block_means(rate, m)
        if y.size < 16:
            raise ValueError(f"block: {m} samples per block leave {y.size} block means; expected at least 16")
        from avbench.estimators.likelihood._mle_kernels import BlockMeanSystem

        system = BlockMeanSystem(latents, m, dt)
        scale = 1.0 / float(np.std(y) or 1.0)  # the filter runs on y * scale (see _mle_kernels)
        fit = maximize_loglike(system, y, scale, x0, self.maxiter, self._loglike_method)
        vals = system.values(fit["params"])
        cov = fit["cov"]
        # a non-positive variance (flat or non-concave likelihood, e.g. a term at zero) has no
        # standard error: NaN, not 0
        var = np.diag(cov)
        se_log = dict(zip(system.names, np.sqrt(np.where(var > 0, var, np.nan))))
        coefs, std = {}, {}
        for cls in sorted((LATENT_TERMS[lat] for lat in latents if not LATENT_TERMS[lat].deterministic),
                          key=lambda cls: COEFFICIENTS.index(cls.coefficient)):
            name = "log_" + cls.fit_parameters[0]  # the amplitude: its coefficient per unit amplitude
            coefs[cls.coefficient] = cls.coefficient_per_amplitude * vals[name]
            std[cls.coefficient] = coefs[cls.coefficient] * se_log[name]
        drift = _deterministic(latents)
        if drift is not None:
            # the filter runs on scaled data: the slope state is in scaled units
            a, P = fit["final_state"], fit["final_cov"]
            ramp = LATENT_TERMS[drift].coefficient
            coefs[ramp] = abs(float(a[-1]) / scale)
            std[ramp] = float(math.sqrt(max(P[-1, -1], 0.0))) / scale
        llf = fit["loglike"]
        params = {k[4:]: v for k, v in vals.items()}
        failure = None
        diag = {
            "block": m,
            "polish_iterations": fit["polish_iterations"],
            "finished_by_score": fit["finished_by_score"],
            "pinned_to_zero": [k[4:] for k in fit["pinned"]],
            "start": start.coefficients_,
        }
        if not np.isfinite(llf):
            failure = "non-finite log-likelihood at the optimum"
        elif not fit["converged"]:  # values at a point that is not the maximum: reported, not trusted
            failure = (f"the likelihood's maximum was not reached ({fit['polish_iterations']} Newton "
                               "iterations after L-BFGS-B; the values are where they stopped)")
        check, k = None, len(system.names) + (drift is not None)
        if np.isfinite(llf):
            p = params
            # the likelihood's parameters: each stochastic term's fit parameters (the drift is a state)
            names = {lat: LATENT_TERMS[lat].fit_parameters for lat in latents if lat != drift}
            # a term the polish set to zero is no term of the fitted model (its parameters still count)
            kept = [lat for lat in latents if lat not in names or p[names[lat][0]] > 0]
            values = [p[k] for lat in kept if lat in names for k in names[lat]]
            if drift is not None:
                values.append(coefs[LATENT_TERMS[drift].coefficient])
            n_par = sum(len(LATENT_TERMS[lat].fit_parameters) for lat in latents)
            gyro = build_gyro(kept, values, dt)
            check = assess_fit(rate, dt, gyro.avar, gyro, n_par, (m * dt, math.inf))
            diag["fit_check"] = check["fit_check"]
            diag["model"] = gyro  # the fitted latent model (Estimator.model_avar)
        ll = llf + y.size * math.log(scale)
        parts = FitParts(fit_check=FitCheck(None) if check is None else as_fit_check(check),
                         std_err=pd.Series(std, dtype=float).reindex(list(COEFFICIENTS)),
                         parameters=params, failure=failure, llf=ll,
                         aic=-2.0 * ll + 2.0 * k, bic=-2.0 * ll + k * math.log(y.size),
                         converged=bool(fit["converged"]), n_iter=int(fit["polish_iterations"]))
        return coefs, {}, diag, parts


#: GM correlation times the GMWM start tries (GMWM's default is 6; the likelihood refines the start)
_START_TRIES = 3


def _pow2_at_least(m: int) -> int:
    return 1 << max(0, math.ceil(math.log2(m)))


def gmwm_start_values(start, latents, dt) -> tuple[np.ndarray, float | None]:
    """The likelihood's starting log-parameters from a fitted GMWM ``start``: each stochastic term's
    :meth:`~avbench.noise_models.NoiseTerm.likelihood_start` from its GMWM values and the AV that fit saw
    (at least 1e-300); and the shortest time the block means must resolve
    (:meth:`~avbench.noise_models.NoiseTerm.block_mean_memory`, None if no term has one)."""
    sp, avar, tau = start.parts_.parameters, start.extras_["avar"], start.extras_["tau"]
    out, memory = [], []
    for lat in latents:
        cls = LATENT_TERMS[lat]
        if not cls.deterministic:
            values = [sp[f"{lat}.{p}"] for p in cls.fit_parameters]
            out += cls.likelihood_start(values, tau, avar)
            memory.append(cls.block_mean_memory(values))
    memory = [t for t in memory if t is not None]
    return np.log(np.maximum(np.array(out, dtype=float), 1e-300)), (min(memory) if memory else None)


#: relative step of the central-difference score of the Hessian (statsmodels' ``_get_epsilon(x, 3)``)
_EPS_GRAD = np.finfo(float).eps ** (1 / 3)
#: relative step of the Hessian's outer differences (statsmodels ``approx_centered``: eps^(1/4)/2)
_EPS_HESS = np.finfo(float).eps ** (1 / 4) / 2


def _score(f, p, rel=_EPS_GRAD):
    """Central-difference gradient of ``f`` at ``p`` (relative step ``rel``, at least ``rel * 0.1``)."""
    h = rel * np.maximum(np.abs(p), 0.1)
    g = np.empty(p.size)
    for i in range(p.size):
        e = np.zeros(p.size)
        e[i] = h[i]
        g[i] = (f(p + e) - f(p - e)) / (2 * h[i])
    return g


def score_hessian(score, p, rel=_EPS_GRAD) -> np.ndarray:
    """Hessian of the function whose gradient is ``score`` at ``p``: central differences of the
    score (relative step ``rel``; eps^(1/3), the optimum for an exact gradient, errs by ~eps^(2/3)
    relative), symmetrised."""
    h = rel * np.maximum(np.abs(p), 0.1)
    hess = np.empty((p.size, p.size))
    for i in range(p.size):
        e = np.zeros(p.size)
        e[i] = h[i]
        hess[i] = (score(p + e) - score(p - e)) / (2 * h[i])
    return (hess + hess.T) / 2


def observed_cov(loglike, p, score=None, hess=None) -> np.ndarray:
    """Inverse observed information of ``loglike`` at ``p``: the Hessian by central differences of
    the score, symmetrised; NaN where it is not finite.

    ``score``: the analytic score (a function of the log-parameters); its central differences
    (:func:`score_hessian`) err by ~eps^(2/3) relative. Without it, the score is itself central
    differences of ``loglike`` (statsmodels ``cov_type="approx"``, ``approx_centered=True``), whose
    nested round-off (~eps^(1/2) relative to the log-likelihood's scale, divided by the steps)
    dominates along the likelihood's flat directions. ``hess``: the Hessian at ``p`` if the caller
    has it already.
    """
    if hess is None and score is None:
        hess = score_hessian(lambda q: _score(loglike, q), p, _EPS_HESS)
    elif hess is None:
        hess = score_hessian(score, p)
    try:
        return -np.linalg.pinv(hess) if np.all(np.isfinite(hess)) else np.full(hess.shape, np.nan)
    except np.linalg.LinAlgError:
        return np.full(hess.shape, np.nan)


#: the Newton polish stops at a maximum (negative definite Hessian) where the Newton step's
#: predicted gain is below this relative to the log-likelihood: its own round-off (~1e-12 relative),
#: under which no step can be told from a worse one. The step may then still be ~1e-3 of a standard
#: error (the gain is quadratic in it); the finishing steps below take it to round-off
POLISH_GAIN = 1e-12
#: at a maximum, plain Newton steps on the analytic score go on until the step is below this in every
#: log-parameter (relative change of the parameter), at most FINISH_MAXITER of them
FINISH_STEP, FINISH_MAXITER = 1e-10, 6
#: at most this many Newton (trust-region) iterations after the quasi-Newton stage
POLISH_MAXITER = 60
#: the log-likelihood of ``nobs`` block means is a sum of ``nobs`` terms, whose value carries round-off
#: up to about ``nobs * eps`` relative (measured: 1.2 times that on the record where the trust region
#: stalled); a trust-region step is accepted by comparing values, so a gain under this many times that
#: round-off cannot be confirmed by them and the score decides from there (:func:`_newton_polish`)
UNRESOLVED_GAIN = 100.0
#: a variance whose removal lowers the log-likelihood by at most this much is set to zero by the
#: polish (a likelihood-ratio statistic of 2e-4, four decades under any test's threshold)
PIN_LOGLIKE = 1e-4


def maximize_loglike(system, y, scale, x0, maxiter, method="auto") -> dict:
    """Maximise the exact block-mean log-likelihood over the log-parameters (L-BFGS-B).

    The objective is ``-loglike / nobs`` (as statsmodels' ``MLEModel.fit``) with a tight
    tolerance and the analytic score (:meth:`BlockMeanSystem.score`: the filter's derivative
    recursions, one compiled pass for the likelihood and the whole gradient; the finite-difference
    gradients of before -- statsmodels' forward differences, then central ones -- left ~sqrt(eps)
    of gradient noise that the likelihood's flat directions turned into ~1e-4 relative parameter
    noise). The covariance of the log-parameters is the inverse of the observed information, the
    Hessian by central differences of the analytic score (:func:`observed_cov`). L-BFGS-B's end
    point is polished to the maximum by trust-region Newton steps (:func:`_newton_polish`). Returns
    ``params``, ``cov``, ``loglike`` (scaled units), ``converged``, ``final_state`` and ``final_cov``
    (last filtered state and covariance), ``polish_iterations`` and ``lbfgs_loglike`` (the
    log-likelihood where L-BFGS-B stopped).
    ``method`` selects the Kalman filter (:meth:`BlockMeanSystem.loglike`; the filters give the same
    likelihood to ~1e-14 relative, "exact_initial" is the slower path of before, kept for the tests
    and the benchmark).
    """
    from scipy.optimize import minimize

    nobs = y.size
    y = np.ascontiguousarray(y, dtype=float)

    def objective_and_score(p):
        with np.errstate(all="ignore"):
            v, g = system.score(y, p, scale, method=method)
        v, g = -v / nobs, -g / nobs
        return (v, np.where(np.isfinite(g), g, 0.0)) if np.isfinite(v) else (1e300, np.zeros(p.size))

    res = minimize(objective_and_score, np.asarray(x0, dtype=float), jac=True, method="L-BFGS-B",
                   options={"maxiter": int(maxiter), "gtol": 1e-8, "ftol": 1e-14})
    p, polish = _newton_polish(objective_and_score, res.x, list(system.names), system.groups, nobs)
    converged = polish["converged"]
    free = polish["free"]
    cov = np.full((p.size, p.size), np.nan)  # a pinned term has no standard error
    if free.any():
        cov[np.ix_(free, free)] = observed_cov(None, p[free], hess=-nobs * polish["hess"])
    a, P = np.empty(system.k), np.empty((system.k, system.k))
    llf = system.loglike(y, p, scale, (a, P), method=method)
    return {"params": p, "cov": cov, "loglike": float(llf), "converged": converged,
            "final_state": a, "final_cov": P, "polish_iterations": polish["iterations"],
            "pinned": polish["pinned"], "lbfgs_loglike": float(-res.fun * nobs),
            "finished_by_score": polish["by_score"]}


def _newton_polish(objective_and_score, p, names, groups, nobs):
    """Take the quasi-Newton end point ``p`` to the maximum: trust-region Newton steps
    (``scipy.optimize.minimize(method="trust-exact")``, More & Sorensen 1983) on ``objective_and_score``
    (minus the log-likelihood per observation and its analytic score) with the Hessian by central
    differences of the score (:func:`score_hessian`), until it is at a maximum where the Newton
    step's predicted gain is below the log-likelihood's round-off (:data:`POLISH_GAIN`, a tolerance
    relative to the information: 1/2 g' H^-1 g); a term the likelihood drives to zero is set to
    zero (the boundary rule below). Where L-BFGS-B already stopped at the maximum, this costs one
    Hessian, the one the standard errors need anyway.

    Why: L-BFGS-B stops when a step no longer lowers the objective by 1e-14 relative, which on the
    likelihood's stiff and flat directions together (information eigenvalues from ~1e5 down to ~20
    and below, per log-parameter) can happen far from the maximum -- at a saddle, on the first 30
    minutes of ADIS16405 run 1 axis z, 2.9e3 below the maximum in log-likelihood with a gradient of
    ~10; there the last bits of the samples (or their unit) decided where it stopped.
    A trust region handles the saddle (an indefinite Hessian) and converges quadratically once
    near the maximum, so that the end point no longer depends on the path.

    Boundary rule: the maximum may lie at a variance of zero (log-parameter -inf: on that record the
    white noise, whose share the Gauss-Markov term with a correlation time under one sample takes
    over), which Newton steps approach by 0.5 in the log-parameter per iteration, forever. After each
    iteration, a noise scale (a term's amplitude, the first of its ``groups`` of parameter indices:
    ``log_Q``, ``log_N``, ``log_sigma``, ``log_K``) whose gradient still pushes it down and whose
    removal lowers the log-likelihood by at most :data:`PIN_LOGLIKE` is set to zero (log-parameter
    -inf; the term's other parameters are frozen with it, ``log_tc`` with ``log_sigma``; a term whose
    score is within the round-off of zero counts as pushed down: random3 of the grand comparison, replicate 0,
    ended with Q = 3e-33, a score of -9e-60 and no curvature, where the trust region could not move and
    the fit ended unconverged) and the rest are
    maximised again. The answer is the maximum over the remaining terms, which does not depend on
    the iteration where the term was pinned.

    Round-off rule: the trust region accepts a step by comparing log-likelihood values, whose
    round-off grows with the number of block means (:data:`UNRESOLVED_GAIN`); near a maximum on a
    flat direction the remaining gain can sink into it before the Newton step's predicted gain
    reaches :data:`POLISH_GAIN` (40 000 samples of ADIS16405_Y, block 1: a predicted gain of 1.8e-11
    relative under a round-off of 1.5e-11, 21 rejected or round-off-sized steps in 9 s and no
    maximum). Once a step is rejected where the predicted gain is below that round-off (Hessian
    positive definite), or the iterations run out there, the plain Newton steps of the score
    (``finish``) take over, and the fit has converged if they reach the maximum by the score's test;
    where they do not (the bound on the round-off is a worst case: on a long flat ridge the values
    can still see such gains), the trust region goes on from there without that stop.
    Returns ``(p, info)``: ``p`` with -inf for pinned
    terms, info holding ``hess`` (of the objective over the free parameters, ``free`` their mask),
    ``iterations``, ``pinned`` (names) and ``converged``.
    """
    from scipy.optimize import minimize

    start = np.array(p, dtype=float)
    p = start.copy()
    free = np.ones(p.size, dtype=bool)
    scales = [group[0] for group in groups]
    shapes = {group[0]: group[1:] for group in groups}
    pinned, iterations, converged, by_score = [], 0, False, False
    f0 = objective_and_score(p)[0]
    cache = {}

    def sub(q):
        v, g = objective_and_score(_fill(p, free, q))
        return v, g[free]

    def hess(q):
        key = (q.tobytes(), free.tobytes())
        if key not in cache:
            cache.clear()
            cache[key] = score_hessian(lambda r: sub(r)[1], q)
        return cache[key]

    def at_maximum(q, tolerance=POLISH_GAIN):
        """The Newton step's predicted gain is below ``tolerance`` relative, at a maximum."""
        v, g = sub(q)
        w, V = np.linalg.eigh(hess(q))
        if not (np.all(np.isfinite(w)) and w[0] > 0):
            return False
        return 0.5 * float(np.sum((V.T @ g) ** 2 / w)) <= tolerance * abs(v)

    round_off = nobs * np.finfo(float).eps  # of the objective's value, relative (UNRESOLVED_GAIN)
    #: a gain the values cannot confirm (UNRESOLVED_GAIN times their round-off, never below POLISH_GAIN)
    unresolved = max(POLISH_GAIN, UNRESOLVED_GAIN * round_off)

    def finish(q):
        """Plain Newton steps from a maximum whose remaining gain round-off hides: the analytic score
        is far more precise than the log-likelihood's value, and the step it gives is taken as it is
        (no comparison of values), until it is below FINISH_STEP in every log-parameter. The Hessian
        of the first step serves them all (one score per step: the steps are round-off sized, over
        which the Hessian does not change; the covariance takes the one at the end point)."""
        H = hess(q)
        for _ in range(FINISH_MAXITER):
            step = np.linalg.solve(H, sub(q)[1])
            if not np.all(np.isfinite(step)):
                break
            q = q - step
            if np.max(np.abs(step)) <= FINISH_STEP:
                break
        return q

    def to_pin(q):
        """Noise scales the gradient pushes down (or leaves alone, to the values' round-off: a term so
        small that the sum cannot see it has a score without a sign) whose removal costs at most
        PIN_LOGLIKE."""
        r = _fill(p, free, q)
        v, g = objective_and_score(r)
        no_sign = round_off * abs(v)
        out = []
        for i in scales:
            if free[i] and g[i] >= -no_sign:
                t = r.copy()
                t[i] = -np.inf
                if (objective_and_score(t)[0] - v) * nobs <= PIN_LOGLIKE:
                    out.append(i)
        return out

    stall_stop = True  # until the score's steps once failed to finish from a stall (then as before)
    for _ in range(len(scales) + 2):
        state = {"x": p[free].copy(), "pin": [], "done": False, "stalled": False}

        def after_step(intermediate_result):
            rejected = np.array_equal(intermediate_result.x, state["x"])
            q = state["x"] = intermediate_result.x.copy()
            state["pin"] = to_pin(q)
            if state["pin"]:
                raise StopIteration
            if at_maximum(q):
                state["done"] = True
                raise StopIteration
            if stall_stop and rejected and at_maximum(q, unresolved):  # the values may no longer see the gain
                state["stalled"] = True
                raise StopIteration

        state["pin"] = to_pin(p[free])
        if not state["pin"]:
            if at_maximum(p[free]):
                converged = True
                break
            res = minimize(sub, p[free], jac=True, hess=hess, method="trust-exact", callback=after_step,
                           options={"gtol": 0.0, "maxiter": POLISH_MAXITER})
            iterations += int(res.nit)
            p[free] = state["x"]
        if not state["pin"]:
            # stopped short of the maximum (its values could not confirm the last gain, or
            # POLISH_MAXITER iterations): Newton steps on the score, and the score's verdict
            converged = state["done"]
            if not converged and (state["stalled"] or at_maximum(p[free], unresolved)):
                q = finish(p[free])
                if at_maximum(q):
                    p[free], converged, by_score = q, True, True
                elif state["stalled"]:  # far from quadratic yet: on with the trust region, without that stop
                    stall_stop = False
                    continue
            break
        for i in state["pin"]:
            p[i] = -np.inf
            free[i] = False
            pinned.append(names[i])
            free[shapes[i]] = False
        if not free.any():
            converged = True
            break
    if converged and free.any() and not by_score:
        p[free] = finish(p[free])
    f = objective_and_score(p)[0]
    # never worse than the start (to the objective's round-off, which the last Newton steps do not see)
    if not (np.isfinite(f) and f <= f0 + unresolved * abs(f0) + PIN_LOGLIKE * len(pinned) / nobs):
        p, free, pinned, converged, by_score = start, np.ones(p.size, dtype=bool), [], False, False
    h = hess(p[free]) if free.any() else np.zeros((0, 0))
    return p, {"hess": h, "free": free, "iterations": iterations, "pinned": pinned, "converged": converged,
               "by_score": by_score}


def _fill(p, free, q):
    r = p.copy()
    r[free] = q
    return r
