"""Practitioners' baselines: how Allan-variance coefficients are read off in everyday use.

* ``slope_lines`` -- the graphical method of IEEE Std 952-1997 (Annex C), as automated in
  MathWorks' example "Inertial Sensor Noise Analysis Using Allan Variance": on the log-log Allan
  deviation, find the point whose local slope is closest to the slope of a term, draw the line of
  that slope through it, and read the coefficient where the line crosses a fixed tau.
* ``log_fit`` -- unweighted least squares of log10 of the model AV against log10 of the empirical AV
  over every tau of the grid (what the widely used ``imu_utils`` ROS package does); nonlinear in the
  coefficients.
* ``nnls_rel`` -- non-negative least squares (Lawson & Hanson 1974; ``scipy.optimize.nnls``) of the
  linear AV model with each row scaled by 1/AV, i.e. relative residuals.

All three use the five-term model of :mod:`avbench.estimators.allan.model` (Lv et al. 2015, eqs 3-6) and the
fully overlapping AV of :func:`avbench.estimators.allan.variance.allan_variance` on the octave grid by default.
As Guerrier, Molinari & Stebler (IEEE SPL 2016) show, slope reading is inconsistent for composite
models; these are baselines, not recommendations.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import least_squares, nnls

from avbench.estimators.allan.variance import allan_variance
from avbench.estimators.allan.model import (
    PLATEAU,
    TAU_POWER,
    coefficients_from_beta,
    design_matrix,
)
from avbench.estimators.base import Estimator, register
from avbench.estimators.threads import one_blas_thread
from avbench.estimators.allan.fit_check import assess_five_term
from avbench.estimators.validation import check_terms

__all__ = [
    "SlopeLines",
    "LogFit",
    "NNLSRel",
    "slope_line_coefficients",
    "log_fit_beta",
    "nnls_rel_beta",
    "READ_TAU",
]

#: The tau (s) at which each slope line is read (IEEE Std 952 Annex C; MathWorks example):
#: slope -1 at sqrt(3) (sigma = Q), -1/2 at 1 (sigma = N), 0 anywhere (sigma = 0.6643 B),
#: +1/2 at 3 (sigma = K), +1 at sqrt(2) (sigma = R).
READ_TAU = {"Q": math.sqrt(3.0), "N": 1.0, "B": 1.0, "K": 3.0, "R": math.sqrt(2.0)}
_SLOPE = {c: TAU_POWER[c] / 2.0 for c in TAU_POWER}  # log-log slope of the ADEV


def _av(rate, dt, taus, overlapping, min_clusters=2):
    res = allan_variance(rate, dt, taus=taus, overlapping=overlapping)
    ok = np.isfinite(res.avar) & (res.avar > 0) & (res.J >= min_clusters)
    if ok.sum() < 2:
        raise ValueError(
            f"rate: fewer than two positive Allan-variance values with >= {min_clusters} clusters; "
            "the record is too short"
        )
    return np.asarray(res.tau)[ok], np.asarray(res.avar)[ok]


def slope_line_coefficients(tau, adev, terms="NBK", ordered=False) -> tuple[dict, dict]:
    """Read coefficients off an ADEV curve with slope lines (IEEE Std 952 Annex C).

    For each term with ADEV slope :math:`s` (Q: -1, N: -1/2, B: 0, K: +1/2, R: +1), take the
    point :math:`i` whose forward log-log slope
    :math:`(\\log\\sigma_{i+1}-\\log\\sigma_i)/(\\log\\tau_{i+1}-\\log\\tau_i)` is closest to
    :math:`s`, intercept :math:`b = \\log\\sigma_i - s\\log\\tau_i`, and read

    .. math::

        \\log_{10} C = s\\log_{10}\\tau_C + b - \\log_{10} a_C

    with :math:`\\tau_C` from :data:`READ_TAU` and :math:`a_C = 1` except
    :math:`a_B = \\sqrt{2\\ln 2/\\pi} = 0.6643`. This is the MathWorks example's procedure for N
    (tau = 1 s), K (tau = 3 s) and B, extended to Q and R with IEEE Std 952's read-off points.

    With ``ordered=True`` the points are chosen jointly, minimising the summed slope mismatch
    :math:`\\sum_c |s_{i_c} - s_c|` subject to :math:`i_Q \\le i_N \\le i_B \\le i_K \\le i_R`: the
    terms dominate the curve in this order of tau (IEEE Std 952 Annex C, Fig. C.2), so a line for
    B is not read before the N region (dynamic programming over the points).

    Returns ``(coefficients, info)`` where ``info[c]`` is the index of the point used.

    Examples
    --------
    >>> tau = np.logspace(-1, 3, 13)
    >>> c, _ = slope_line_coefficients(tau, np.sqrt(4e-6 / tau), "N")
    >>> round(float(c["N"]), 9)
    0.002
    """
    terms = check_terms(terms)
    tau = np.asarray(tau, dtype=float)
    adev = np.asarray(adev, dtype=float)
    lt, la = np.log10(tau), np.log10(adev)
    slopes = np.diff(la) / np.diff(lt)
    cost = np.array([np.abs(slopes - _SLOPE[c]) for c in terms])
    if ordered:
        idx = _ordered_argmin(cost)
    else:
        idx = [int(np.argmin(row)) for row in cost]
    coefs, used = {}, {}
    for c, i in zip(terms, idx):
        s = _SLOPE[c]
        b = la[i] - s * lt[i]
        scale = math.sqrt(PLATEAU) if c == "B" else 1.0
        coefs[c] = float(10.0 ** (s * math.log10(READ_TAU[c]) + b) / scale)
        used[c] = i
    return coefs, used


def _ordered_argmin(cost: np.ndarray) -> list[int]:
    """Indices i_0 <= i_1 <= ... minimising sum_k cost[k, i_k] (dynamic programming)."""
    n_terms, n_pts = cost.shape
    total = cost[0].copy()
    back = []
    for k in range(1, n_terms):
        # best over j <= i of the previous total: a running minimum and its position
        pos = np.zeros(n_pts, dtype=int)
        run = total.copy()
        for i in range(1, n_pts):
            if run[i - 1] <= total[i]:
                run[i], pos[i] = run[i - 1], pos[i - 1]
            else:
                pos[i] = i
        back.append(pos)
        total = run + cost[k]
    idx = [int(np.argmin(total))]
    for pos in reversed(back):
        idx.append(int(pos[idx[-1]]))
    return idx[::-1]


class _AVBaseline(Estimator):
    """Shared settings and AV computation of the three baselines.

    ``min_clusters`` (default 2: every AV value): AV values from fewer clusters floor(n/m) are not
    used. (Raising it to 8 was tried on the ADIS16405 records: it does not remove the spurious
    rate ramps of ``log_fit``/``nnls_rel`` on Y and Z -- fewer long-tau points leave the rise to
    be explained by R -- so the default keeps every value.)
    """

    uses_allan_variance = True

    def _prepare(self, rate, dt):
        terms = check_terms(self.terms)
        if not isinstance(self.overlapping, bool):
            raise ValueError(f"overlapping: expected True or False, got {self.overlapping!r}")
        mc = self.min_clusters
        if isinstance(mc, bool) or not isinstance(mc, (int, np.integer)) or mc < 2:
            raise ValueError(f"min_clusters: expected an integer >= 2, got {mc!r}")
        tau, avar = _av(rate, dt, self.taus, self.overlapping, int(mc))
        return terms, tau, avar

    def _refit(self, tau, avar, coefs_fn):
        """The poor-fit check's handle on this fit (:func:`avbench.estimators.allan.fit_check.assess_five_term`):
        the fitted AV and the fit as a function of it, so that the check's reference distribution
        holds this estimator's own sampling error; None (plain chi^2) for a non-overlapping AV,
        whose covariance the check does not model."""
        return (tau, avar, coefs_fn) if self.overlapping else None


@register("slope_lines")
class SlopeLines(_AVBaseline):
    """IEEE Std 952 slope-line reading, automated as in the MathWorks example.

    See :func:`slope_line_coefficients`. Only the coefficients in ``terms`` are read (default N, B, K,
    as in the MathWorks example); each is read independently of the others, so the reading is biased
    wherever terms overlap on the curve (e.g. N read where white noise and bias instability mix).

    Parameters
    ----------
    terms : str
        Subset of "QNBKR" to read (default "NBK").
    taus : str or array
        tau grid for :func:`avbench.estimators.allan.variance.allan_variance` (default "octave", as MathWorks'
        ``allanvar`` default).
    overlapping : bool
        Fully overlapping AV (default True).
    min_clusters : int
        AV values from fewer clusters are not used (default 2: all; see ``_AVBaseline``).
    ordered : bool
        Read the lines in the order the terms appear along tau (default True; see
        :func:`slope_line_coefficients`). ``False`` is the MathWorks example literally: each slope
        is matched anywhere on the curve. On real MEMS records whose shortest taus are flattened by
        the sensor's own low-pass filter, the literal reading takes that flat first segment for the
        bias-instability plateau (B = 2086 deg/h on ADIS16405 run 1, Z; 46 deg/h ordered).

    Examples
    --------
    >>> import numpy as np
    >>> from noise_models import Gyro, AngleRandomWalk
    >>> x = Gyro(dt=0.01, terms=[AngleRandomWalk(N=1e-3)]).simulate(100_000, np.random.default_rng(1))
    >>> est = SlopeLines(terms="N").fit(x, 0.01)
    >>> bool(abs(est.coefficients_["N"] / 1e-3 - 1) < 0.05)
    True
    """

    def __init__(self, *, terms="NBK", taus="octave", overlapping=True, ordered=True, min_clusters=2):
        self.terms = terms
        self.taus = taus
        self.overlapping = overlapping
        self.ordered = ordered
        self.min_clusters = min_clusters

    @one_blas_thread()
    def _fit(self, rate, dt):
        terms, tau, avar = self._prepare(rate, dt)
        if not isinstance(self.ordered, bool):
            raise ValueError(f"ordered: expected True or False, got {self.ordered!r}")
        coefs, used = slope_line_coefficients(tau, np.sqrt(avar), terms, ordered=self.ordered)
        diag = {"tau": tau, "avar": avar, "tau_used": {c: float(tau[i]) for c, i in used.items()}}
        refit = self._refit(tau, avar,
                            lambda a: slope_line_coefficients(tau, np.sqrt(a), terms, ordered=self.ordered)[0])
        diag.update(assess_five_term(rate, dt, coefs, len(terms), (tau[0], tau[-1]), refit=refit))
        return coefs, {}, diag


@register("log_fit")
class LogFit(_AVBaseline):
    """Unweighted least squares in log10 of the AV (as the ``imu_utils`` ROS package fits).

    .. math::

        \\min_{\\beta > 0} \\sum_j \\left[\\log_{10}\\big(X(\\tau_j)\\beta\\big)
        - \\log_{10}\\hat\\sigma^2(\\tau_j)\\right]^2

    with :math:`X, \\beta` of Lv et al. (2015, eqs 3-6), solved in :math:`u = \\log\\beta` by
    ``scipy.optimize.least_squares`` (trust-region reflective, analytic Jacobian) from the ``nnls_rel``
    solution.
    Elements of beta are bounded below by ``1e-12 * min_j avar_j / tau_j^p``: a term the data do not
    need ends at that floor and is reported as 0 (its contribution is then below 1e-12 of the AV
    everywhere on the grid), and above by ``max_j avar_j / tau_j^p`` (the term alone explaining the
    largest AV value).

    Parameters
    ----------
    terms : str
        Modelled coefficients (default "QNBKR").
    taus, overlapping, min_clusters
        As :class:`SlopeLines`.
    """

    round_off_amplified = True  # an iterative least-squares optimiser's end point (a term at its floor: 4e-11 vs 0) (Estimator.round_off_amplified)

    def __init__(self, *, terms="QNBKR", taus="octave", overlapping=True, min_clusters=2):
        self.terms = terms
        self.taus = taus
        self.overlapping = overlapping
        self.min_clusters = min_clusters

    @one_blas_thread()
    def _fit(self, rate, dt):
        terms, tau, avar = self._prepare(rate, dt)
        beta, sol = log_fit_beta(tau, avar, terms)
        coefs, nonphys = coefficients_from_beta(beta, terms)
        diag = {"tau": tau, "avar": avar, "beta": beta, "fitted_avar": design_matrix(tau, terms) @ beta,
                "cost": float(sol.cost), "success": bool(sol.success)}
        if not sol.success:
            diag["failure"] = f"least_squares: {sol.message}"
        refit = self._refit(tau, avar, lambda a: coefficients_from_beta(log_fit_beta(tau, a, terms)[0], terms)[0])
        diag.update(assess_five_term(rate, dt, coefs, len(terms), (tau[0], tau[-1]), refit=refit))
        return coefs, nonphys, diag


def log_fit_beta(tau, avar, terms):
    """beta >= 0 minimising sum_j [log10(X beta) - log10 avar_j]^2 (see :class:`LogFit`).

    Returns ``(beta, scipy OptimizeResult)``; elements that end at the floor are set to 0.
    """
    tau, avar = np.asarray(tau, dtype=float), np.asarray(avar, dtype=float)
    X = design_matrix(tau, terms)
    y = np.log10(avar)
    ceiling = np.max(avar[:, None] / X, axis=0)
    floor = 1e-12 * np.min(avar[:, None] / X, axis=0)
    beta0 = nnls_rel_beta(tau, avar, terms)
    u0 = np.log(np.clip(beta0, floor * 10, ceiling))

    def resid(u):
        return np.log10(X @ np.exp(u)) - y

    def jac(u):  # d log10(sum_k X_ik e^u_k) / d u_j = X_ij e^u_j / (X e^u)_i / ln 10
        c = X * np.exp(u)
        return c / (c.sum(axis=1, keepdims=True) * math.log(10))

    # the analytic Jacobian matters: with finite differences, a term whose optimum is at its floor
    # was approached so slowly that 2 % of 2 h MEMS records hit the evaluation limit unconverged
    sol = least_squares(resid, u0, jac=jac, bounds=(np.log(floor), np.log(ceiling)), method="trf",
                        x_scale=1.0, xtol=1e-10, ftol=1e-10, max_nfev=5000)
    beta = np.exp(sol.x)
    beta[sol.x <= np.log(floor) + 1e-6] = 0.0
    return beta, sol


def nnls_rel_beta(tau, avar, terms) -> np.ndarray:
    """beta >= 0 minimising sum_j (X_j beta / avar_j - 1)^2 (see :class:`NNLSRel`)."""
    tau, avar = np.asarray(tau, dtype=float), np.asarray(avar, dtype=float)
    A = design_matrix(tau, terms) / avar[:, None]
    # column scaling keeps nnls well conditioned when the columns span many decades
    s = np.linalg.norm(A, axis=0)
    beta, _ = nnls(A / s, np.ones(len(avar)))
    return beta / s


@register("nnls_rel")
class NNLSRel(_AVBaseline):
    """Non-negative least squares with relative residuals.

    .. math::

        \\min_{\\beta \\ge 0} \\sum_j \\left(\\frac{X(\\tau_j)\\beta}{\\hat\\sigma^2(\\tau_j)} - 1\\right)^2

    (Lawson & Hanson 1974 active-set NNLS, ``scipy.optimize.nnls``; model of Lv et al. 2015,
    eqs 3-6). A zero element of beta is a coefficient the fit set to 0 (a physical value: the term
    is not needed), unlike OLS's negative elements.

    Parameters
    ----------
    terms : str
        Modelled coefficients (default "QNBKR").
    taus, overlapping, min_clusters
        As :class:`SlopeLines`.
    """

    def __init__(self, *, terms="QNBKR", taus="octave", overlapping=True, min_clusters=2):
        self.terms = terms
        self.taus = taus
        self.overlapping = overlapping
        self.min_clusters = min_clusters

    @one_blas_thread()
    def _fit(self, rate, dt):
        terms, tau, avar = self._prepare(rate, dt)
        beta = nnls_rel_beta(tau, avar, terms)
        coefs, nonphys = coefficients_from_beta(beta, terms)
        fitted = design_matrix(tau, terms) @ beta
        diag = {"tau": tau, "avar": avar, "beta": beta, "fitted_avar": fitted}
        refit = self._refit(tau, avar, lambda a: coefficients_from_beta(nnls_rel_beta(tau, a, terms), terms)[0])
        diag.update(assess_five_term(rate, dt, coefs, len(terms), (tau[0], tau[-1]), refit=refit))
        return coefs, nonphys, diag
