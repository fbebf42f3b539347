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
    BETA_SCALE,
    PLATEAU,
    TAU_POWER,
    coefficients_from_beta,
    design_matrix,
)
from avbench.estimators.base import Estimator, register
from avbench.estimators.threads import one_blas_thread
from avbench.estimators.allan.fit_check import as_fit_check, assess_five_term
from avbench.estimators.results import FitParts, extras_of
from avbench.estimators.selection import choices
from avbench.estimators.settings import Boolean, Interval, Options, Relation, Taus, Terms
from avbench.estimators.validation import check_terms, check_variance_seen

__all__ = [
    "SlopeLines",
    "LogFit",
    "NNLSRel",
    "NNLSRelFiltered",
    "shaped_design",
    "profile_shapes",
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
        long_enough = np.isfinite(res.avar) & (res.J >= min_clusters)
        check_variance_seen(np.asarray(res.tau)[long_enough], np.asarray(res.avar)[long_enough], 2)
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
    used. (8 does not remove the spurious rate ramps of ``log_fit``/``nnls_rel`` on the ADIS16405
    records' Y and Z axes -- fewer long-tau points leave the rise to be explained by R -- so the
    default keeps every value.)
    """

    uses_allan_variance = True

    parameter_constraints = {
        "terms": [Terms()],
        "taus": [Taus()],
        "overlapping": [Boolean()],
        "min_clusters": [Interval(int, 2, None)],
    }

    def _prepare(self, rate, dt):
        terms = check_terms(self.terms)
        tau, avar = _av(rate, dt, self.taus, bool(self.overlapping), int(self.min_clusters))
        return terms, tau, avar

    def _refit(self, tau, avar, coefs_fn, model_jacobian=None):
        """The poor-fit check's handle on this fit (:func:`avbench.estimators.allan.fit_check.assess_five_term`):
        the fitted AV and the fit as a function of it, so that the check's reference distribution
        holds this estimator's own sampling error, and, where the fit has one, the analytic derivative
        of its model AV with respect to the fitted AV (``model_jacobian(tau)``, else the check refits
        by central differences); None (plain chi^2) for a non-overlapping AV, whose covariance the
        check does not model."""
        return (tau, avar, coefs_fn, model_jacobian) if self.overlapping else None


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
    >>> from avbench.noise_models import Gyro, AngleRandomWalk
    >>> x = Gyro(dt=0.01, terms=[AngleRandomWalk(N=1e-3)]).simulate(100_000, np.random.default_rng(1))
    >>> est = SlopeLines(terms="N").fit(x, 0.01)
    >>> bool(abs(est.coefficients_["N"] / 1e-3 - 1) < 0.05)
    True
    """

    parameter_constraints = {**_AVBaseline.parameter_constraints, "ordered": [Boolean()]}

    def __init__(self, *, terms="NBK", taus="octave", overlapping=True, ordered=True, min_clusters=2):
        self.terms = terms
        self.taus = taus
        self.overlapping = overlapping
        self.ordered = ordered
        self.min_clusters = min_clusters

    @one_blas_thread()
    def _fit(self, rate, dt):
        terms, tau, avar = self._prepare(rate, dt)
        coefs, used = slope_line_coefficients(tau, np.sqrt(avar), terms, ordered=bool(self.ordered))
        diag = {"tau": tau, "avar": avar, "tau_used": {c: float(tau[i]) for c, i in used.items()}}
        refit = self._refit(tau, avar,
                            lambda a: slope_line_coefficients(tau, np.sqrt(a), terms, ordered=bool(self.ordered))[0])
        check = assess_five_term(rate, dt, coefs, len(terms), (tau[0], tau[-1]), refit=refit)
        diag["fit_check"] = check["fit_check"]
        return coefs, {}, diag, FitParts(fit_check=as_fit_check(check))


def _filter_needs_n(filter, terms) -> None:
    """A filter (``filter`` "auto" or "fit") filters the white noise: N must be in ``terms``."""
    terms = check_terms(terms)
    if filter != "none" and "N" not in terms:
        raise ValueError(f"filter={filter!r} filters the white noise N: expected N in terms, got {terms!r}")


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
        failure = None if sol.success else f"least_squares: {sol.message}"
        sens = log_fit_sensitivity(tau, avar, terms, beta, sol) if sol.success else None
        refit = self._refit(tau, avar, lambda a: coefficients_from_beta(log_fit_beta(tau, a, terms)[0], terms)[0],
                            None if sens is None else (lambda t: design_matrix(t, terms) @ sens))
        check = assess_five_term(rate, dt, coefs, len(terms), (tau[0], tau[-1]), refit=refit)
        diag["fit_check"] = check["fit_check"]
        return coefs, nonphys, diag, FitParts(fit_check=as_fit_check(check), failure=failure,
                                              converged=bool(sol.success))


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
    # is approached so slowly that 2 % of 2 h MEMS records hit the evaluation limit unconverged
    sol = least_squares(resid, u0, jac=jac, bounds=(np.log(floor), np.log(ceiling)), method="trf",
                        x_scale=1.0, xtol=1e-10, ftol=1e-10, max_nfev=5000)
    beta = np.exp(sol.x)
    beta[sol.x <= np.log(floor) + 1e-6] = 0.0
    return beta, sol


def log_fit_sensitivity(tau, avar, terms, beta, sol) -> np.ndarray:
    """d beta / d avar of :func:`log_fit_beta` at its solution (shape ``(len(terms), len(tau))``), by the
    implicit function theorem: the free log-parameters u_F (beta > 0, no bound active) solve
    G(u, a) = J^T r = 0 with r_i = log10((X e^u)_i) - log10(a_i), so

    .. math:: \\frac{du_F}{da} = -H^{-1}\\frac{\\partial G}{\\partial a}
        = H^{-1} J^T \\mathrm{diag}\\Big(\\frac{1}{a\\ln 10}\\Big),\\qquad
        H = J^T J + \\sum_i r_i \\nabla^2 r_i,

    with :math:`c_{ij} = X_{ij} e^{u_j}`, :math:`s = X\\beta`, :math:`J = c / (s \\ln 10)` and
    :math:`\\nabla^2 r_i = (\\mathrm{diag}(c_i)/s_i - c_i c_i^T / s_i^2) / \\ln 10`; a term at a bound
    (its beta 0, or at its ceiling) stays there. The poor-fit check uses it in place of refits at AV
    values moved by +-0.01 standard deviations (34 refits, costing 90 % of a log_fit), without
    their O(h^2) and solver-tolerance error (agreement ~1e-5 relative, ``tests/test_fit_check.py``).
    """
    tau, avar = np.asarray(tau, dtype=float), np.asarray(avar, dtype=float)
    X = design_matrix(tau, terms)
    free = (beta > 0) & (np.asarray(sol.active_mask) == 0)
    out = np.zeros((X.shape[1], tau.size))
    if not free.any():
        return out
    ln10 = math.log(10.0)
    c = X[:, free] * beta[free]
    s = X @ beta
    q = c / s[:, None]
    r = np.log10(s) - np.log10(avar)
    J = q / ln10
    H = J.T @ J + (np.diag(r @ q) - q.T @ (r[:, None] * q)) / ln10
    du = np.linalg.solve(H, J.T / (avar * ln10)[None, :])
    out[free] = beta[free][:, None] * du
    return out


def nnls_rel_beta(tau, avar, terms) -> np.ndarray:
    """beta >= 0 minimising sum_j (X_j beta / avar_j - 1)^2 (see :class:`NNLSRel`)."""
    tau, avar = np.asarray(tau, dtype=float), np.asarray(avar, dtype=float)
    return _nnls_rel(design_matrix(tau, terms), avar)


def _nnls_rel(X, avar) -> np.ndarray:
    """beta >= 0 minimising sum_j (X_j beta / avar_j - 1)^2 for any design matrix X (columns: AV per unit)."""
    A = X / avar[:, None]
    # column scaling keeps nnls well conditioned when the columns span many decades
    s = np.linalg.norm(A, axis=0)
    s = np.where(s > 0, s, 1.0)  # a column that is zero on the grid (a line at whole periods) stays at 0
    beta, _ = nnls(A / s, np.ones(len(avar)))
    return beta / s


# --- nnls_rel's front-end filter and spectral line ------------------------------------------------------

#: points per octave of the grid on which nnls_rel profiles the filter's time constant tf
FILTER_GRID_PER_OCTAVE = 4
#: points of the grid on which it profiles a line's frequency (within LINE_FREQUENCY_FACTOR of the line's)
LINE_GRID_POINTS = 9


def shaped_design(tau, dt, terms, tf=None, f0=None) -> np.ndarray:
    """The design matrix of nnls_rel's model with the sensor's filter and a spectral line.

    The five-term columns of :func:`avbench.estimators.allan.model.design_matrix`, with, given a filter
    time constant ``tf``, N's column replaced by the exact discrete AV of unit white noise through the
    first-order low-pass (:class:`avbench.noise_models.FilteredWhiteNoise` with time constant ``tf``; its element of
    beta is still N^2: the long-tau AV is N^2 / tau), and, given a line frequency ``f0``, one more column:
    the exact discrete AV of a unit-amplitude sinusoid (:class:`avbench.noise_models.Sinusoidal`; its
    element of beta is A^2). Both AVs are linear in their variance given their shape parameter, so the
    fit stays a non-negative least squares at fixed (tf, f0). ``tau`` must be multiples of ``dt``."""
    from avbench.noise_models import FilteredWhiteNoise, Sinusoidal

    tau = np.asarray(tau, dtype=float)
    terms = check_terms(terms)
    X = design_matrix(tau, terms)
    m = np.rint(tau / dt).astype(np.int64)
    if tf is not None:
        X[:, terms.index("N")] = FilteredWhiteNoise(N=1.0, tf=float(tf)).avar(m, dt)
    if f0 is not None:
        X = np.column_stack([X, Sinusoidal(A=1.0, f0=float(f0)).avar(m, dt)])
    return X


def _shaped_fit(tau, avar, terms, dt, tf, f0):
    """(beta, sum of squared relative residuals) of nnls_rel at fixed (tf, f0)."""
    X = shaped_design(tau, dt, terms, tf, f0)
    beta = _nnls_rel(X, avar)
    r = X @ beta / avar - 1.0
    return beta, float(r @ r)


def filter_bounds(tau, dt) -> tuple[float, float]:
    """The range of the filter's time constant nnls_rel profiles: GMWM's ``FW`` range (from far below dt,
    where the filtered noise is white, to 16 times the shortest tau fitted)."""
    return dt / 100.0, 16.0 * max(dt, float(tau[0]))


def profile_shapes(tau, avar, terms, dt, tf_range=None, f0_range=None, start=None):
    """(tf, f0, beta, sse): the shape parameters of nnls_rel's filter and line that minimise its criterion,
    each profiled out (the non-negative least squares solved at every value tried).

    ``tf_range`` / ``f0_range``: (low, high) of the filter's time constant (s) and the line's frequency (Hz),
    or None for a term not in the model. Without ``start``, the joint grid (:data:`FILTER_GRID_PER_OCTAVE`
    points per octave of tf, :data:`LINE_GRID_POINTS` of f0, log-spaced) chooses the start; then each
    parameter is refined by Brent's bounded minimisation in its logarithm within one grid step of the start,
    in turn, twice. With ``start`` (the refits of the poor-fit check) only the refinement runs, from it."""
    from scipy.optimize import minimize_scalar

    def grid(rng, n):
        lo, hi = math.log(rng[0]), math.log(rng[1])
        return np.linspace(lo, hi, max(int(n), 2))

    axes = {}
    if tf_range is not None:
        axes["tf"] = grid(tf_range, math.log2(tf_range[1] / tf_range[0]) * FILTER_GRID_PER_OCTAVE + 1)
    if f0_range is not None:
        axes["f0"] = grid(f0_range, LINE_GRID_POINTS)

    def sse(u):
        return _shaped_fit(tau, avar, terms, dt, math.exp(u["tf"]) if "tf" in u else None,
                           math.exp(u["f0"]) if "f0" in u else None)[1]

    if start is None:
        best = None
        for idx in np.ndindex(*[v.size for v in axes.values()]):
            u = {k: float(v[i]) for (k, v), i in zip(axes.items(), idx)}
            val = sse(u)
            if best is None or val < best[0]:
                best = (val, u)
        u = best[1]
    else:
        u = {k: math.log(v) for k, v in start.items() if k in axes}
    step = {k: (v[1] - v[0]) if v.size > 1 else 0.0 for k, v in axes.items()}
    for _ in range(2):
        for k in axes:
            lo, hi = max(axes[k][0], u[k] - step[k]), min(axes[k][-1], u[k] + step[k])
            if not hi > lo:
                continue
            res = minimize_scalar(lambda x: sse({**u, k: x}), bounds=(lo, hi), method="bounded",
                                  options={"xatol": 1e-9})
            if res.fun <= sse(u):
                u[k] = float(res.x)
    tf = math.exp(u["tf"]) if "tf" in u else None
    f0 = math.exp(u["f0"]) if "f0" in u else None
    beta, val = _shaped_fit(tau, avar, terms, dt, tf, f0)
    return tf, f0, beta, val


@register("nnls_rel")
class NNLSRel(_AVBaseline):
    """Non-negative least squares with relative residuals.

    .. math::

        \\min_{\\beta \\ge 0} \\sum_j \\left(\\frac{X(\\tau_j)\\beta}{\\hat\\sigma^2(\\tau_j)} - 1\\right)^2

    (Lawson & Hanson 1974 active-set NNLS, ``scipy.optimize.nnls``; model of Lv et al. 2015,
    eqs 3-6). A zero element of beta is a coefficient the fit set to 0 (a physical value: the term
    is not needed), unlike OLS's negative elements.

    Real sensors (beyond Lv et al. 2015): the sensor's own low-pass filter bends the first
    octaves below the white-noise line, and a spectral line (IEEE Std 952-1997 Annex C's sinusoidal noise)
    makes a bump; the five-term model has neither and misses such curves (results/real). With
    ``filter="auto"`` and ``lines="auto"`` (:class:`NNLSRelFiltered`, ``nnls_rel_filtered``) the model
    carries them as columns of the same NNLS (:func:`shaped_design`: white noise through a first-order
    low-pass of time constant tf in place of N's column; a sinusoid of frequency f0), their shape
    parameters profiled (:func:`profile_shapes`), each entering only on evidence:

    * the line: when the record's strongest spectral line passes the line test
      (:func:`avbench.estimators.selection.lines.line_evidence`, level 0.001: GMWM's rule), its frequency
      then profiled within :data:`~avbench.estimators.selection.lines.LINE_FREQUENCY_FACTOR` of the line's;
    * the filter: when the model without it fails the poor-fit check (p < 0.01). The filtered model nests
      the five-term one (tf at its lower bound dt / 100 is white noise), so its criterion is never worse;
      the check is calibrated at 1 % for a model that holds, so a record without a filter gets one in
      about 1 % of cases (and then a tf the record does not resolve, near its floor).

    The filter's evidence is only as strong as the check's power, which for this inefficient fit is low on
    short records: on 65,536 samples of white noise through a filter of tf = dt / 2 (plus flicker, random
    walk and a line; seed 1 of ``studies/fit_check_calibration.py``'s ``filtered+line`` case) the five-term
    fit's z at 0.01 s is -51 and its p-value 0.91 (its own sampling error, in the reference, is that wide),
    so the filter stays out -- with N within 0.5 % of the truth. On 180,000 samples (the tests) and on the
    2.8 h ADIS16405 gyro axes (results/real) it enters.

    The result's model choices ``line_test`` and ``filter_test`` give the evidence (p-values, tf, f0,
    included), its ``parameters`` the fitted ``FW.tf``, ``SN.A``, ``SN.f0`` of the terms included; the poor-fit check
    counts each profiled shape parameter as a fitted parameter and re-profiles it in its linearisation;
    :meth:`model_avar` is the curve fitted (exact discrete AV of the filter and line terms, so ``tau`` must
    then be multiples of dt). The defaults (``"none"``) are the five-term fit above.

    Parameters
    ----------
    terms : str
        Modelled coefficients (default "QNBKR").
    taus, overlapping, min_clusters
        As :class:`SlopeLines`.
    filter : {"none", "auto", "fit"}
        The sensor's first-order filter on the white noise: never (default), on evidence (above), or
        always with tf fitted ("fit": a sensor known to filter, e.g. from its datasheet); needs N in ``terms``.
    lines : {"none", "auto"}
        A sinusoid at the strongest spectral line: never (default) or when the line test passes.
    """

    parameter_constraints = {
        **_AVBaseline.parameter_constraints,
        "filter": [Options("none", "auto", "fit")],
        "lines": [Options("none", "auto")],
    }
    setting_relations = (Relation(("filter", "terms"), lambda est: _filter_needs_n(est.filter, est.terms),
                                  "a filter filters the white noise: N in terms"),)

    def __init__(self, *, terms="QNBKR", taus="octave", overlapping=True, min_clusters=2, filter="none",
                 lines="none"):
        self.terms = terms
        self.taus = taus
        self.overlapping = overlapping
        self.min_clusters = min_clusters
        self.filter = filter
        self.lines = lines

    @one_blas_thread()
    def _fit(self, rate, dt):
        terms, tau, avar = self._prepare(rate, dt)
        if self.filter == "none" and self.lines == "none":
            beta = nnls_rel_beta(tau, avar, terms)
            coefs, nonphys = coefficients_from_beta(beta, terms)
            fitted = design_matrix(tau, terms) @ beta
            diag = {"tau": tau, "avar": avar, "beta": beta, "fitted_avar": fitted}
            refit = self._refit(tau, avar, lambda a: coefficients_from_beta(nnls_rel_beta(tau, a, terms), terms)[0])
            check = assess_five_term(rate, dt, coefs, len(terms), (tau[0], tau[-1]), refit=refit)
            diag["fit_check"] = check["fit_check"]
            return coefs, nonphys, diag, FitParts(fit_check=as_fit_check(check))
        return self._fit_shaped(rate, dt, terms, tau, avar)

    def _fit_shaped(self, rate, dt, terms, tau, avar):
        """The fit with the filter and line terms chosen on evidence (class docstring)."""
        from avbench.estimators.selection.lines import LINE_FREQUENCY_FACTOR, line_evidence

        f0_range, line = None, None
        if self.lines == "auto":
            line = line_evidence(rate, dt, tau)
            if line is not None:
                line["included"] = bool(line["significant"])
                if line["included"]:
                    f0_range = (max(line["f0"] / LINE_FREQUENCY_FACTOR, 0.371 / tau[-1]),
                                min(line["f0"] * LINE_FREQUENCY_FACTOR, 0.5 / dt))
        if self.filter == "fit":  # the filter as the user says: always in the model, tf fitted
            fit = self._shaped(rate, dt, terms, tau, avar, filter_bounds(tau, dt), f0_range)
            parts = self._parts(fit, line, None)
            return fit["coefs"], fit["nonphys"], extras_of(fit["diag"], parts), parts
        fit = self._shaped(rate, dt, terms, tau, avar, None, f0_range)
        filter_test = None
        if self.filter == "auto":
            filter_test = {"included": False, "p_without": fit["diag"]["fit_pvalue"], "p_with": math.nan,
                           "tf": math.nan}
            if fit["diag"]["poor_fit"]:  # the model without the filter fails: the filter enters (it nests it)
                fit = self._shaped(rate, dt, terms, tau, avar, filter_bounds(tau, dt), f0_range)
                filter_test.update(included=True, p_with=fit["diag"]["fit_pvalue"], tf=fit["tf"])
        parts = self._parts(fit, line, filter_test)
        return fit["coefs"], fit["nonphys"], extras_of(fit["diag"], parts), parts

    @staticmethod
    def _parts(fit, line, filter_test) -> FitParts:
        """The typed parts of the shaped fit ``fit``: its check, the line and filter tests made, its parameters."""
        made = ([] if line is None else [choices.line_test(line)]) + \
            ([] if filter_test is None else [choices.filter_test(filter_test)])
        return FitParts(fit_check=fit["check"], choices=tuple(made), parameters=dict(fit["params"]))

    def _shaped(self, rate, dt, terms, tau, avar, tf_range, f0_range) -> dict:
        """One shaped fit (:func:`profile_shapes`) with its poor-fit check."""
        from avbench.estimators.allan.fit_check import assess_fit
        from avbench.noise_models import FilteredWhiteNoise, Gyro, Sinusoidal

        tf, f0, beta, _ = profile_shapes(tau, avar, terms, dt, tf_range, f0_range)
        k = len(terms)
        coefs, nonphys = coefficients_from_beta(beta[:k], terms)
        params = {}
        if tf is not None:
            params["FW.tf"] = tf
        if f0 is not None:
            params.update({"SN.A": math.sqrt(max(float(beta[k]), 0.0)), "SN.f0": f0})
        diag = {"tau": tau, "avar": avar, "beta": beta[:k], "params": params, "dt": dt,
                "fitted_avar": shaped_design(tau, dt, terms, tf, f0) @ beta}
        # the model whose AV covariance the check uses: the five-term generators, N through the filter, the line
        base = Gyro.from_coefficients({c: v for c, v in coefs.items() if not (tf is not None and c == "N")}, dt)
        extra = []
        if tf is not None and coefs.get("N", 0.0) > 0:
            extra.append(FilteredWhiteNoise(N=coefs["N"], tf=tf))
        if f0 is not None and params["SN.A"] > 0:
            extra.append(Sinusoidal(A=params["SN.A"], f0=f0))
        gyro = Gyro(dt=dt, terms=(list(base.terms) if base is not None else []) + extra) if (base or extra) else None
        start = {"tf": tf, "f0": f0}

        def refit_fn(a, tau_c):
            tf_, f0_, b, _ = profile_shapes(tau, a, terms, dt, tf_range, f0_range, start=start)
            return shaped_design(tau_c, dt, terms, tf_, f0_) @ b

        refit = None
        if self.overlapping:
            refit = (np.rint(tau / dt).astype(np.int64), avar, refit_fn)
        n_params = k + (tf is not None) + 2 * (f0 is not None)
        check = assess_fit(rate, dt, lambda t: shaped_design(t, dt, terms, tf, f0) @ beta, gyro, n_params,
                           (tau[0], tau[-1]), refit=refit)
        diag.update(check)
        return {"coefs": coefs, "nonphys": nonphys, "diag": diag, "tf": tf if tf is not None else math.nan,
                "check": as_fit_check(check), "params": params}

    def model_avar(self, tau) -> np.ndarray:
        """The curve this fit made: the five-term AV of ``coefficients_``, with the filter's and the line's
        exact discrete AV where they entered (:func:`shaped_design`; ``tau`` multiples of dt then)."""
        self._check_fitted()
        params = self.parts_.parameters or {}
        if not params:
            return super().model_avar(tau)
        tau = np.asarray(tau, dtype=float)
        dt = float(self.extras_["dt"])
        tf, f0 = params.get("FW.tf"), params.get("SN.f0")
        terms = [c for c in "QNBKR" if np.isfinite(self.coefficients_[c])]
        beta = [BETA_SCALE[c] * float(self.coefficients_[c]) ** 2 for c in terms]
        if f0 is not None:
            beta.append(float(params["SN.A"]) ** 2)
        if tf is not None and "N" not in terms:
            tf = None
        return shaped_design(tau, dt, "".join(terms), tf, f0) @ np.array(beta)


@register("nnls_rel_filtered")
class NNLSRelFiltered(NNLSRel):
    """``nnls_rel`` for real sensors: the sensor's filter and a spectral line modelled on evidence
    (``filter="auto"``, ``lines="auto"``; :class:`NNLSRel`)."""

    def __init__(self, *, terms="QNBKR", taus="octave", overlapping=True, min_clusters=2, filter="auto",
                 lines="auto"):
        super().__init__(terms=terms, taus=taus, overlapping=overlapping, min_clusters=min_clusters, filter=filter,
                         lines=lines)
