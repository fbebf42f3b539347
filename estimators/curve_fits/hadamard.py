"""EDF-weighted least squares on the overlapping Hadamard variance: B and K read past a rate ramp.

The Hadamard variance (NIST SP 1065 eq. 20; :mod:`avbench.estimators.allan.deviations`) is a third
difference of the phase, so a linear rate ramp (R) adds nothing to it, where it adds R^2 tau^2 / 2
to the Allan variance. Its four-term model (continuous time; the ramp's column is identically 0) is

.. math::

    \\sigma_H^2(\\tau) = \\frac{10 Q^2}{3\\tau^2} + \\frac{N^2}{\\tau}
        + h_B\\,\\frac{2\\ln 2}{\\pi} B^2 + \\frac{K^2\\tau}{6},
    \\qquad h_B = \\frac{24\\ln 2 - 9\\ln 3}{12\\ln 2} = 0.81128,

derived from the phase generalized covariances of :mod:`avbench.noise_models.exact_variances`:
the filter (-1, 3, -3, 1) at (0, m, 2m, 3m) has autocorrelation (20, -15, 6, -1) at lags 0, m, 2m,
3m, which gives 20 Q^2 / (6 tau^2) for white angle noise, N^2/tau for white rate (the AV's value),
2 m^2 (24 ln 2 - 9 ln 3) g / (6 tau^2) for flicker rate (G = g d^2 ln|d|, against 4 ln 2 g / dt^2 for
the AV plateau) and m^3 K^2 dt^3 / (6 m^2 dt^2) = K^2 tau / 6 for the rate random walk.

``wls_edf_hadamard`` is ``wls_edf`` (its AV twin: overlapping octave AV, rows scaled by
sqrt(edf/2)/level, iterated from the J-weighted fit) with the Hadamard variance, its model, and the
edf of each Hadamard value for the noise type dominating the fitted curve there
(:func:`~avbench.estimators.allan.deviations.edf_quadratic`). Standard errors: the same sandwich
as ``wls_edf`` (:func:`~avbench.estimators.curve_fits.least_squares.ls_std_err`, diagonal in tau).
R is not estimable from the Hadamard variance; asking for it is an error.
"""

from __future__ import annotations

import math

import numpy as np

from avbench.estimators.allan.deviations import deviation, edf_quadratic
from avbench.estimators.allan.fit_check import as_fit_check, assess_five_term
from avbench.estimators.results import FitParts
from avbench.estimators.allan.model import PLATEAU, TAU_POWER
from avbench.estimators.base import Estimator, register
from avbench.estimators.threads import one_blas_thread
from avbench.estimators.curve_fits.least_squares import ls_std_err, solve_scaled
from avbench.estimators.settings import Interval, Taus, Terms
from avbench.estimators.validation import check_terms

__all__ = ["HadamardEDFWeightedLS", "H_BETA_SCALE", "hadamard_design_matrix", "hadamard_model"]

H_FLICKER = (24 * math.log(2) - 9 * math.log(3)) / (12 * math.log(2))
#: sigma_H^2 contribution of coefficient c is H_BETA_SCALE[c] * c**2 * tau**TAU_POWER[c]
H_BETA_SCALE = {"Q": 10.0 / 3.0, "N": 1.0, "B": H_FLICKER * PLATEAU, "K": 1.0 / 6.0}
_NOISE_OF_TERM = {"Q": "white_pm", "N": "white_fm", "B": "flicker_fm", "K": "rw_fm"}


def hadamard_design_matrix(tau, terms) -> np.ndarray:
    tau = np.asarray(tau, dtype=float)
    return np.column_stack([tau ** TAU_POWER[c] for c in terms])


def hadamard_model(coefs: dict, tau) -> np.ndarray:
    """The continuous-time Hadamard variance of coefficients (SI) at ``tau`` (R contributes 0)."""
    tau = np.asarray(tau, dtype=float)
    out = np.zeros_like(tau)
    for c, k in H_BETA_SCALE.items():
        v = coefs.get(c, math.nan)
        if v is not None and np.isfinite(v):
            out = out + k * float(v) ** 2 * tau ** TAU_POWER[c]
    return out


@register("wls_edf_hadamard")
class HadamardEDFWeightedLS(Estimator):
    """EDF-weighted least squares on the overlapping Hadamard variance (module docstring).

    Parameters
    ----------
    terms : str
        Subset of "QNBK" (default all four; R is invisible to the Hadamard variance).
    taus : "octave", "decade" or array
        Hadamard grid (m <= N/3).
    n_iter : int
        Re-weighting iterations (as ``wls_edf``).
    """

    #: the rows' weights sqrt(edf / 2) / AV carry the inverse of the AV's unit
    diagnostic_units = {"row_scale": -2}

    uses_allan_variance = False  # it reads the record through the Hadamard variance, not allan_variance

    parameter_constraints = {
        "terms": [Terms("QNBK", why="the Hadamard variance is blind to a rate ramp: R cannot be fitted")],
        "taus": [Taus()],
        "n_iter": [Interval(int, 1, None)],
    }

    def __init__(self, *, terms="QNBK", taus="octave", n_iter=5):
        self.terms = terms
        self.taus = taus
        self.n_iter = n_iter

    @one_blas_thread()
    def _fit(self, rate, dt):
        terms = check_terms(self.terms)
        hv = deviation(rate, dt, "ohvar", self.taus, edf=False)
        X = hadamard_design_matrix(hv.tau, terms)
        if len(hv.tau) < len(terms):
            failure = f"only {len(hv.tau)} Hadamard values for {len(terms)} coefficients"
            return {c: np.nan for c in terms}, {}, {}, FitParts(failure=failure)
        noise_of_column = np.array([_NOISE_OF_TERM[t] for t in terms], dtype=object)
        K = hv.J
        beta = solve_scaled(X, hv.avar, K.astype(float))
        for _ in range(self.n_iter):
            contrib = X * np.maximum(beta, 0)[None, :]
            level = np.where(contrib.sum(axis=1) > 0, contrib.sum(axis=1), hv.avar)
            dominant = noise_of_column[contrib.argmax(axis=1)]
            edf = np.array([edf_quadratic("ohvar", int(m), int(k), str(d)) for m, k, d in zip(hv.m, K, dominant)])
            scale = np.sqrt(edf / 2.0) / level
            beta = solve_scaled(X, hv.avar, scale)
        scales = {c: H_BETA_SCALE[c] for c in terms}
        ok = np.isfinite(beta) & (beta >= 0)
        coefs = {c: math.sqrt(b / scales[c]) if g else math.nan for c, b, g in zip(terms, beta, ok)}
        nonphys = {c: not g for c, g in zip(terms, ok)}
        mask = np.ones(len(hv.tau), dtype=bool)
        se = ls_std_err(beta, terms, X, scale, hv, mask, level_edf=(level, edf), beta_scale=scales)
        extras = {
            "hadamard": hv,
            "beta": dict(zip(terms, beta)),
            "fitted_hvar": X @ beta,
            "row_scale": scale,
            "edf": edf,
        }
        check = assess_five_term(rate, dt, coefs, len(terms), (hv.tau.min(), hv.tau.max()))
        extras["fit_check"] = check["fit_check"]
        return coefs, nonphys, extras, FitParts(fit_check=as_fit_check(check), std_err=se)
