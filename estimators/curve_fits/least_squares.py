"""Least-squares fits of the Allan-variance curve (Lv et al. 2015) and an EDF-weighted extension.

All four fit the linear model sigma^2(tau) = X(tau) beta of :mod:`avbench.estimators.allan.model`
(Lv et al. 2015, eqs 4-7) to the AV values of the record, and differ only in which rows they keep
and how they weight them:

``ols``          all AV values, unweighted (eq. 7);
``ols_trimmed``  only the values whose 1-sigma ADEV error 100/sqrt(2(J-1)) % is at most
                 ``max_error_pct`` (40 % in Lv et al. 2015, section 3.1);
``wls``          every row multiplied by its cluster count J (eqs 11-14, as written);
``wls_edf``      (beyond the paper) rows scaled by 1/sd(AV_i), sd from the equivalent degrees of
                 freedom of each AV value for the noise type that dominates it, iterated from the
                 ``wls`` fit.

Notes on Lv et al. 2015. Eq. 9 calls e(tau) "the variance of w_i" and then divides the equation
by it; since Var(AV) is proportional to AV^2/J, the statistically natural row scale is sqrt(J)/AV,
whereas eqs 11-13 multiply each row by J (i.e. least-squares weights J^2, and no AV^2 factor).
``wls`` implements eqs 11-14 exactly as printed; ``wls_edf`` is the variance-correct version.
Negative elements of beta are reported as non-physical (NaN, flagged), as the paper prints "-".
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from avbench.estimators.allan.variance import allan_variance, edf_overlapping
from avbench.estimators.allan.model import BETA_SCALE, TAU_POWER, coefficients_from_beta, design_matrix
from avbench.estimators.curve_fits._kernels import edf_weighted_sums, power_curve, power_sums
from avbench.estimators.settings import Boolean, Interval, Taus, Terms
from avbench.estimators.validation import check_terms
from avbench.noise_models.units import COEFFICIENTS
from avbench.estimators.base import Estimator, register
from avbench.estimators.threads import one_blas_thread
from avbench.estimators.allan.fit_check import as_fit_check, assess_five_term
from avbench.estimators.results import FitParts

__all__ = ["OLS", "TrimmedOLS", "WLS", "EDFWeightedLS", "solve_scaled", "solve_normal", "solve_power_design",
           "edf_table", "edf_of_rows", "ls_std_err", "MAX_GRAM_COND"]


#: largest condition number of the column-equilibrated normal equations solved by Cholesky (see
#: :func:`solve_scaled`); beyond it the weighted design's SVD (``lstsq``) solves instead
MAX_GRAM_COND = 1e4


def solve_scaled(X: np.ndarray, y: np.ndarray, row_scale: np.ndarray | None = None) -> np.ndarray:
    """Least-squares beta minimising ||diag(row_scale) (X beta - y)||, with column equilibration.

    The columns tau^-2 .. tau^2 span many decades; scaling them to unit norm gives the same
    solution with far better conditioning. The equilibrated normal equations are solved by
    Cholesky (:func:`solve_normal`); where their condition number exceeds :data:`MAX_GRAM_COND`,
    the equilibrated weighted design is solved by ``lstsq`` (LAPACK gelsd: QR, then SVD).
    """
    if row_scale is not None:
        X = X * row_scale[:, None]
        y = y * row_scale
    beta = solve_normal(X.T @ X, X.T @ y)
    return _lstsq_equilibrated(X, y) if beta is None else beta


def _lstsq_equilibrated(X, y):
    norms = np.linalg.norm(X, axis=0)
    norms[norms == 0] = 1.0
    b, *_ = np.linalg.lstsq(X / norms, y, rcond=None)
    return b / norms


def solve_normal(G: np.ndarray, g: np.ndarray) -> np.ndarray | None:
    """beta solving the normal equations G beta = g (G = X^T W^2 X, g = X^T W^2 y) by Cholesky after
    column equilibration, D^-1 G D^-1 (D beta) = D^-1 g with D = sqrt(diag G) (the column norms of
    the weighted design); None where the equilibrated matrix is singular, not finite or has a
    condition number above :data:`MAX_GRAM_COND` (then the caller solves the weighted design by SVD).

    Error bound: a Cholesky solve of a symmetric positive definite system is backward stable, so
    the solution's relative error (in the equilibrated norm) is at most about kappa times the relative
    error of the equilibrated G and g, kappa = cond(D^-1 G D^-1) = cond(WXD^-1)^2. Those carry one
    rounding per entry plus the error of their sums (:mod:`avbench.estimators.curve_fits._kernels`:
    blocks of 256 rows, within ~(256 + n / 256) eps in the worst case, ~1e-15 typically), so the
    difference from an SVD of the weighted design (whose own error is ~cond(WXD^-1) eps) is
    below kappa x 3e-14 <= 3e-10 at :data:`MAX_GRAM_COND`. The designs the studies fit are far
    better conditioned (cond(WXD^-1) <= 31 on taus="all" for every record length and weighting of
    the committed studies: kappa <= 1e3).
    """
    G = np.asarray(G, dtype=float)
    d = np.sqrt(np.diag(G))
    if not (np.all(np.isfinite(G)) and np.all(np.isfinite(g)) and np.all(d > 0)):
        return None
    Gs = G / np.outer(d, d)
    lam = np.linalg.eigvalsh(Gs)
    if not lam[0] * MAX_GRAM_COND > lam[-1]:
        return None
    from scipy.linalg import cho_factor, cho_solve

    try:
        c = cho_factor(Gs, lower=True, check_finite=False)
    except np.linalg.LinAlgError:
        return None
    return cho_solve(c, np.asarray(g, dtype=float) / d, check_finite=False) / d


def _powers(terms) -> np.ndarray:
    return np.array([TAU_POWER[c] for c in terms], dtype=np.int64)


def _gram(sums, powers):
    """(G, g) of the power design from the power sums of :func:`avbench.estimators.curve_fits._kernels.power_sums`."""
    s, r = sums
    return s[powers[:, None] + powers[None, :] + 4], r[powers + 2]


def solve_power_design(tau, y, terms, row_scale=None, *, sums=None) -> np.ndarray:
    """:func:`solve_scaled` for the five-term design of ``terms`` at ``tau``, without building it:
    the normal equations from one pass of power sums (``sums``, if given: those of the weights
    ``row_scale**2``; ``row_scale`` may then be a callable returning it, asked only when the SVD
    fallback needs the design)."""
    tau = np.ascontiguousarray(tau, dtype=float)
    y = np.ascontiguousarray(y, dtype=float)
    powers = _powers(terms)
    if sums is None:
        w2 = np.ones(tau.size) if row_scale is None else np.square(row_scale, dtype=float)
        sums = power_sums(tau, y, w2)
    beta = solve_normal(*_gram(sums, powers))
    if beta is None:
        rs = row_scale() if callable(row_scale) else row_scale
        beta = solve_scaled(design_matrix(tau, terms), y, None if rs is None else np.asarray(rs, dtype=float))
    return beta


class _AVCurveFit(Estimator):
    """Shared machinery: compute the AV, pick rows and weights, solve, pack the result."""

    uses_allan_variance = True

    parameter_constraints = {"terms": [Terms()], "taus": [Taus()], "overlapping": [Boolean()]}

    def __init__(self, *, terms="QNBKR", taus="all", overlapping=False):
        self.terms = terms
        self.taus = taus
        self.overlapping = overlapping

    def _weights(self, av, terms):
        """(row mask, row scale or None, extra diagnostics, power sums of those weights or None)."""
        return np.ones(len(av), dtype=bool), None, {}, None

    @one_blas_thread()
    def _fit(self, rate, dt):
        terms = check_terms(self.terms)
        av = allan_variance(rate, dt, taus=self.taus, overlapping=bool(self.overlapping))
        mask, scale, extra, sums = self._weights(av, terms)
        if mask.sum() < len(terms):
            coefs = {c: np.nan for c in terms}
            failure = f"only {int(mask.sum())} AV values usable for {len(terms)} coefficients"
            return coefs, {}, {"allan": av}, FitParts(failure=failure)
        rs = None if scale is None else scale[mask]
        if mask.all():
            beta = solve_power_design(av.tau, av.avar, terms, rs, sums=sums)
        else:
            beta = solve_power_design(av.tau[mask], av.avar[mask], terms, rs)
        coefs, nonphys = coefficients_from_beta(beta, terms)
        fitted = power_curve(np.ascontiguousarray(av.tau, dtype=float), _powers(terms), beta)

        extras = {
            "allan": av,
            "used": mask,
            "beta": dict(zip(terms, beta)),
            "fitted_avar": fitted,
            "residuals": av.avar - fitted,
            **extra,
        }
        check = assess_five_term(rate, dt, coefs, len(terms), (av.tau[mask].min(), av.tau[mask].max()))
        extras["fit_check"] = check["fit_check"]
        return coefs, nonphys, extras, FitParts(fit_check=as_fit_check(check),
                                                std_err=ls_std_err(beta, terms, None, rs, av, mask))


@register("ols")
class OLS(_AVCurveFit):
    """Ordinary least squares on all AV values (Lv et al. 2015, eq. 7).

    Parameters
    ----------
    terms : str or list
        Coefficients modelled (subset of "QNBKR"; Lv et al. 2015 fit "QNB").
    taus : "all", "octave", "decade" or array
        AV grid (Lv et al. 2015 use "all Allan variance values" without saying which grid).
    overlapping : bool
        Overlapping AV (default: non-overlapping, as eq. 2).
    """


@register("ols_trimmed")
class TrimmedOLS(_AVCurveFit):
    """OLS on the AV values whose error 100/sqrt(2(J-1)) % is at most ``max_error_pct``.

    Lv et al. 2015, section 3.1 and eq. 8 (threshold 40 %, "empirically 30 % to 40 %").
    """

    parameter_constraints = {**_AVCurveFit.parameter_constraints,
                             "max_error_pct": [Interval(float, 0, None, closed="neither")]}

    def __init__(self, *, terms="QNBKR", taus="all", overlapping=False, max_error_pct=40.0):
        super().__init__(terms=terms, taus=taus, overlapping=overlapping)
        self.max_error_pct = max_error_pct

    def _weights(self, av, terms):
        with np.errstate(divide="ignore"):
            err = 100.0 / np.sqrt(2.0 * (av.J - 1))
        return err <= float(self.max_error_pct), None, {"error_pct": err}, None


@register("wls")
class WLS(_AVCurveFit):
    """Weighted least squares of Lv et al. 2015, eqs 11-14: every row multiplied by J.

    .. math:: \\beta = (X'^T X')^{-1} X'^T y',\\quad X' = \\mathrm{diag}(J) X,\\ y' = \\mathrm{diag}(J) y
    """

    def _weights(self, av, terms):
        J = av.J.astype(float)
        return np.ones(len(av), dtype=bool), J, {"row_scale": J}, None


_NOISE_OF_TERM = {"Q": "white_pm", "N": "white_fm", "B": "flicker_fm", "K": "rw_fm", "R": "rw_fm"}


def _edf_nonoverlapping(J: np.ndarray, white_pm: np.ndarray) -> np.ndarray:
    """EDF of the non-overlapping AV from J clusters, by noise type (``white_pm``: True where the
    noise is white PM, else white FM's value).

    Exact for white FM, 2(J-1)^2/(3J-4) (adjacent differences correlate with rho = -1/2), and for
    white PM, 2(J-1)^2 / [(J-1) + (8/9)(J-2) + (1/18)(J-3)] (rho_1 = -2/3, rho_2 = 1/6); the
    white-FM value is used for flicker and random-walk FM (an approximation).
    """
    return np.where(white_pm, _edf_nonoverlapping_rule(J, True), _edf_nonoverlapping_rule(J, False))


def _edf_nonoverlapping_rule(J: np.ndarray, white_pm: bool) -> np.ndarray:
    """:func:`_edf_nonoverlapping` for one noise type at every J."""
    J = J.astype(float)
    J1 = J - 1
    num = 2 * J1 * J1
    den = J1 + 8 / 9 * (J - 2) + (J - 3) / 18 if white_pm else 3 * J - 4
    return np.maximum(num / np.maximum(den, 1), 1.0)


@register("wls_edf")
class EDFWeightedLS(_AVCurveFit):
    """Least squares weighted by the actual variance of each AV value (beyond Lv et al. 2015).

    Var(AV_i) ~ 2 AV_i^2 / edf_i, with AV_i the fitted model value and edf_i the equivalent degrees
    of freedom for the noise type whose term dominates the fitted AV at tau_i (overlapping: NIST SP
    1065 Table 5; non-overlapping: see ``_edf_nonoverlapping``). Starts from the ``wls`` fit and
    re-weights ``n_iter`` times (rows whose fitted AV is not positive keep the empirical AV).
    """

    #: the rows' weights sqrt(edf / 2) / AV carry the inverse of the AV's unit
    diagnostic_units = {"row_scale": -2}

    parameter_constraints = {**_AVCurveFit.parameter_constraints, "n_iter": [Interval(int, 1, None)]}

    def __init__(self, *, terms="QNBKR", taus="all", overlapping=False, n_iter=5):
        super().__init__(terms=terms, taus=taus, overlapping=overlapping)
        self.n_iter = n_iter

    def _weights(self, av, terms):
        tau, y = np.ascontiguousarray(av.tau, dtype=float), np.ascontiguousarray(av.avar, dtype=float)
        beta = solve_power_design(tau, y, terms, av.J.astype(float))
        table, rule = edf_table(av, terms)
        powers = _powers(terms)
        level, edf = np.empty(tau.size), np.empty(tau.size)
        sums = None
        for _ in range(self.n_iter):
            sums = edf_weighted_sums(tau, y, y, powers, beta, table, rule, level, edf)
            beta = solve_power_design(tau, y, terms, lambda: np.sqrt(edf / 2.0) / level, sums=sums)
        # the weights of the last solve (its power sums: the fit's own solve repeats it)
        scale = np.sqrt(edf / 2.0) / level
        return np.ones(len(av), dtype=bool), scale, {"row_scale": scale, "edf": edf}, sums


def edf_table(av, terms):
    """``(table, rule)``: the edf of every AV value under each edf rule the ``terms`` need (columns of
    ``table``, rows of ``av``) and the rule of each term's column. Overlapping: NIST SP 1065 Table 5
    for the noise type of each term; non-overlapping: ``_edf_nonoverlapping`` (white PM for Q, the
    white-FM value for the others)."""
    noise = [_NOISE_OF_TERM[t] for t in terms]
    if av.overlapping:
        kinds = list(dict.fromkeys(noise))
        cols = [edf_overlapping(av.m, av.n_samples, k) for k in kinds]
        rule = [kinds.index(k) for k in noise]
    else:
        pm = [k == "white_pm" for k in noise]
        kinds = list(dict.fromkeys(pm))
        cols = [_edf_nonoverlapping_rule(av.J, k) for k in kinds]
        rule = [kinds.index(k) for k in pm]
    return np.ascontiguousarray(np.column_stack(cols), dtype=float), np.array(rule, dtype=np.int64)


def edf_of_rows(av, beta, terms):
    """(model AV level, edf) of every AV value under the fit ``beta``: the level is the fitted AV
    (the empirical one where the fit is not positive), the edf that of the noise type whose term
    dominates the fitted AV there (the first of equal contributions; overlapping: NIST SP 1065
    Table 5; else ``_edf_nonoverlapping``). One compiled pass
    (:func:`avbench.estimators.curve_fits._kernels.edf_weighted_sums`)."""
    tau, y = np.ascontiguousarray(av.tau, dtype=float), np.ascontiguousarray(av.avar, dtype=float)
    table, rule = edf_table(av, terms)
    level, edf = np.empty(tau.size), np.empty(tau.size)
    edf_weighted_sums(tau, y, y, _powers(terms), np.asarray(beta, dtype=float), table, rule, level, edf)
    return level, edf


def ls_std_err(beta: np.ndarray, terms, X: np.ndarray, row_scale, av, mask, *, level_edf=None,
               beta_scale=None) -> pd.Series:
    """Standard errors of a least-squares AV-curve fit (sandwich with the EDF covariance of the AV).

    .. math::

        \\mathrm{Cov}(\\hat\\beta) = A\\,\\Omega\\,A^T,\\quad A = (X^TW^2X)^{-1}X^TW^2,\\quad
        \\Omega = \\mathrm{diag}(2\\,\\sigma^4_i/\\mathrm{edf}_i),

    :math:`W` the row scale (``row_scale``; rows of ``X`` -- ``None``: the five-term design at
    ``av.tau`` -- and ``av`` selected by ``mask``),
    :math:`\\sigma^2_i` the fitted AV and :math:`\\mathrm{edf}_i` the equivalent degrees of freedom of
    the noise type dominating it (:func:`edf_of_rows`, as ``wls_edf``
    weights). The AV values at different taus are correlated (adjacent octaves by 0.5-0.9 for
    random-walk-like terms; :func:`avbench.estimators.allan.covariance.av_covariance` computes it, at a cost of seconds
    per fit on long records): the diagonal ignores this, so these standard errors are optimistic
    where the fit leans on the long taus (K, R) - the coverage study measures by how much.
    Delta method: :math:`\\mathrm{se}(c) = \\mathrm{se}(\\beta_c)/(2\\,k_c\\,c)`, :math:`\\beta_c = k_c c^2`.
    NaN for a coefficient without a physical estimate, and for all on grids denser than about
    two taus per octave (median ratio of consecutive cluster sizes below 1.5, e.g. ``taus="all"``):
    neighbouring AV values there are almost perfectly correlated and a diagonal covariance would
    be wrong by orders of magnitude (use ``Estimator.bootstrap``).
    ``level_edf`` (level, edf) and ``beta_scale`` (beta_c = k_c c^2) replace the AV's for a fit of
    another variance (the Hadamard fit).
    """
    out = pd.Series(math.nan, index=list(COEFFICIENTS), dtype=float)
    m = np.asarray(av.m, dtype=float)[mask]
    if m.size < 2 or np.median(m[1:] / m[:-1]) < 1.5:
        return out
    level, edf = edf_of_rows(av, beta, terms) if level_edf is None else level_edf
    var = (2 * level**2 / edf)[mask]
    w = np.ones(var.size) if row_scale is None else np.asarray(row_scale, dtype=float)
    Xm = (design_matrix(av.tau, terms) if X is None else X)[mask]
    norms = np.linalg.norm(Xm * w[:, None], axis=0)
    norms[norms == 0] = 1.0
    A = np.linalg.pinv(Xm * w[:, None] / norms) * w[None, :] / norms[:, None]
    cov = (A * var[None, :]) @ A.T
    scales = BETA_SCALE if beta_scale is None else beta_scale
    for j, c in enumerate(terms):
        v = math.sqrt(beta[j] / scales[c]) if np.isfinite(beta[j]) and beta[j] >= 0 else math.nan
        if np.isfinite(v) and v > 0 and cov[j, j] >= 0:
            out[c] = math.sqrt(cov[j, j]) / (2 * scales[c] * v)
    return out
