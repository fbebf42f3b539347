"""Bounded trust-region reflective least squares, scipy's algorithm step for step, its linear algebra compiled.

:func:`trf_bounds` is ``scipy.optimize.least_squares(fun, x0, jac=jac, bounds=(lb, ub), method="trf",
x_scale=1.0, ...)`` for what GMWM asks of it (finite bounds, the exact trust-region solver, linear loss,
a callable Jacobian): the same iteration -- Coleman & Li's scaling, the SVD of the augmented Jacobian,
Moré's iteration for the Levenberg-Marquardt parameter, the reflective step selection, the same trust-region
radius updates and stopping rules, in the same order (Branch, Coleman & Li, 1999, SIAM J. Sci. Comput.
21(1), Sect. 2; Moré, 1978; scipy's ``optimize/_lsq/trf.py`` and ``common.py`` are the reference this
follows) -- and the same result fields (``x``, ``cost``, ``fun``, ``jac``, ``grad``, ``optimality``,
``active_mask``, ``nfev``, ``njev``, ``status``, ``message``, ``success``).

Why: a GMWM fit solves ~70 small problems (17 scales, 3-8 parameters) to tolerances of 1e-15, ~27
evaluations each, and scipy's per-iteration bookkeeping (some forty NumPy and LAPACK calls on arrays of
a few elements, the differentiable-function wrappers) was ~70 % of the fit (issue 25: 0.46 s on a
4 h, 10 Hz record against a target of 0.3 s). Here each outer iteration's scaling and SVD is one
compiled call (:func:`_prepare`) and each trial step one more (:func:`_step`); the residuals, the
Jacobian, the cost and the gradient stay NumPy calls in Python, as in scipy.

Same arithmetic: the elementwise operations are IEEE-exact either way; dot products and matrix-vector
products call BLAS in both (numba's ``np.dot`` and NumPy's), the SVD LAPACK's ``gesdd`` in both; a sum of
n < 8 terms is sequential in both. End points agree with scipy's to round-off (``tests/test_trf.py``:
identical on most problems; where the last bits of a BLAS call differ, within the tolerance the solve
stops at), which the optimiser may carry further along a flat direction, as BLAS builds do
(``Estimator.round_off_amplified``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from scipy.optimize import OptimizeResult

__all__ = ["trf_bounds", "TERMINATION_MESSAGES"]

EPS = float(np.finfo(float).eps)

#: ``result.message`` by ``result.status``, as scipy's least_squares words them
TERMINATION_MESSAGES = {
    0: "The maximum number of function evaluations is exceeded.",
    1: "`gtol` termination condition is satisfied.",
    2: "`ftol` termination condition is satisfied.",
    3: "`xtol` termination condition is satisfied.",
    4: "Both `ftol` and `xtol` termination conditions are satisfied.",
}


@njit(cache=True, error_model="numpy")
def _norm(a):
    return math.sqrt(np.dot(a, a))


@njit(cache=True, error_model="numpy")
def _sum(a):
    """NumPy's sum of a contiguous float64 vector: sequential below 8 terms, then 8 partial sums
    combined pairwise (NumPy's pairwise summation for n <= 128)."""
    n = a.size
    if n < 8:
        res = 0.0
        for i in range(n):
            res += a[i]
        return res
    if n > 128:
        raise ValueError("_sum: more than 128 terms")
    r = a[:8].copy()
    i = 8
    while i < n - (n % 8):
        for j in range(8):
            r[j] += a[i + j]
        i += 8
    res = ((r[0] + r[1]) + (r[2] + r[3])) + ((r[4] + r[5]) + (r[6] + r[7]))
    while i < n:
        res += a[i]
        i += 1
    return res


@njit(cache=True, error_model="numpy")
def _cl_scaling(x, g, lb, ub):
    """Coleman-Li scaling vector v and its derivative dv (scipy's ``CL_scaling_vector``)."""
    n = x.size
    v = np.ones(n)
    dv = np.zeros(n)
    for i in range(n):
        if g[i] < 0 and np.isfinite(ub[i]):
            v[i] = ub[i] - x[i]
            dv[i] = -1.0
        if g[i] > 0 and np.isfinite(lb[i]):
            v[i] = x[i] - lb[i]
            dv[i] = 1.0
    return v, dv


@njit(cache=True, error_model="numpy")
def _initial_radius(x, g, lb, ub):
    v, _ = _cl_scaling(x, g, lb, ub)
    delta = _norm(x / np.sqrt(v))
    return 1.0 if delta == 0 else delta


@njit(cache=True, error_model="numpy")
def _gradient_norm(x, g, lb, ub):
    """The Coleman-Li scaled gradient's largest component (the ``gtol`` rule's ``g_norm``)."""
    v, _ = _cl_scaling(x, g, lb, ub)
    return np.max(np.abs(g * v))


@njit(cache=True, error_model="numpy")
def _prepare(x, g, J, f, lb, ub):
    """One outer iteration's scaled problem: the scaling ``d``, ``diag_h``, ``g_h``, ``J_h = J d`` and the
    SVD ``(uf, s, V)`` of the augmented Jacobian ``[J_h; diag(diag_h)^(1/2)]`` (scipy's ``trf_bounds``,
    ``tr_solver="exact"``, ``x_scale`` 1)."""
    m, n = J.shape
    v, dv = _cl_scaling(x, g, lb, ub)
    d = np.sqrt(v)
    diag_h = g * dv
    g_h = d * g
    J_aug = np.zeros((m + n, n))
    for i in range(m):
        for j in range(n):
            J_aug[i, j] = J[i, j] * d[j]
    sq = np.sqrt(diag_h)
    for j in range(n):
        J_aug[m + j, j] = sq[j]
    J_h = J_aug[:m].copy()
    U, s, Vt = np.linalg.svd(J_aug, full_matrices=False)
    f_aug = np.zeros(m + n)
    f_aug[:m] = f
    uf = np.dot(U.T, f_aug)
    V = Vt.T
    return d, diag_h, g_h, J_h, uf, s, V


@njit(cache=True, error_model="numpy")
def _phi(alpha, suf, s, delta):
    denom = s**2 + alpha
    p_norm = _norm(suf / denom)
    phi = p_norm - delta
    phi_prime = -_sum(suf**2 / denom**3.0) / p_norm  # NumPy's power(denom, 3): libm's pow
    return phi, phi_prime


@njit(cache=True, error_model="numpy")
def _solve_trust_region(n, m, uf, s, V, delta, alpha0, half):
    """scipy's ``solve_lsq_trust_region`` with ``initial_alpha`` given, rtol 0.01, 10 iterations.
    ``half`` is 0.5, passed at run time so that ``** half`` is libm's pow, as Python's float ``** 0.5``
    (a constant exponent 0.5 is compiled to a square root, which differs in the last bit now and then)."""
    suf = s * uf
    full_rank = False
    if m >= n:
        full_rank = s[-1] > EPS * m * s[0]
    if full_rank:
        p = -np.dot(V, uf / s)
        if _norm(p) <= delta:
            return p, 0.0
    alpha_upper = _norm(suf) / delta
    if full_rank:
        phi, phi_prime = _phi(0.0, suf, s, delta)
        alpha_lower = -phi / phi_prime
    else:
        alpha_lower = 0.0
    if not full_rank and alpha0 == 0:
        alpha = max(0.001 * alpha_upper, (alpha_lower * alpha_upper) ** half)
    else:
        alpha = alpha0
    for _ in range(10):
        if alpha < alpha_lower or alpha > alpha_upper:
            alpha = max(0.001 * alpha_upper, (alpha_lower * alpha_upper) ** half)
        phi, phi_prime = _phi(alpha, suf, s, delta)
        if phi < 0:
            alpha_upper = alpha
        ratio = phi / phi_prime
        alpha_lower = max(alpha_lower, alpha - ratio)
        alpha -= (phi + delta) * ratio / delta
        if abs(phi) < 0.01 * delta:
            break
    p = -np.dot(V, suf / (s**2 + alpha))
    p *= delta / _norm(p)
    return p, alpha


@njit(cache=True, error_model="numpy")
def _step_to_bound(x, s, lb, ub):
    """scipy's ``step_size_to_bound``: the smallest step along ``s`` to a bound, and which are hit."""
    n = x.size
    steps = np.full(n, np.inf)
    for i in range(n):
        if s[i] != 0:
            steps[i] = max((lb[i] - x[i]) / s[i], (ub[i] - x[i]) / s[i])
    min_step = np.min(steps)
    hits = np.zeros(n)
    for i in range(n):
        if steps[i] == min_step:
            hits[i] = np.sign(s[i])
    return min_step, hits


@njit(cache=True, error_model="numpy")
def _intersect_trust_region(x, s, delta):
    a = np.dot(s, s)
    if a == 0:
        raise ValueError("`s` is zero.")
    b = np.dot(x, s)
    c = np.dot(x, x) - delta**2
    if c > 0:
        raise ValueError("`x` is not within the trust region.")
    d = math.sqrt(b * b - a * c)
    q = -(b + math.copysign(d, b))
    t1 = q / a
    t2 = c / q
    if t1 < t2:
        return t1, t2
    return t2, t1


@njit(cache=True, error_model="numpy")
def _quadratic_1d(J, g, s, diag):
    v = np.dot(J, s)
    a = np.dot(v, v)
    a += np.dot(s * diag, s)
    a *= 0.5
    b = np.dot(g, s)
    return a, b


@njit(cache=True, error_model="numpy")
def _quadratic_1d_from(J, g, s, diag, s0):
    v = np.dot(J, s)
    a = np.dot(v, v)
    a += np.dot(s * diag, s)
    a *= 0.5
    b = np.dot(g, s)
    u = np.dot(J, s0)
    b += np.dot(u, v)
    c = 0.5 * np.dot(u, u) + np.dot(g, s0)
    b += np.dot(s0 * diag, s)
    c += 0.5 * np.dot(s0 * diag, s0)
    return a, b, c


@njit(cache=True, error_model="numpy")
def _minimize_quadratic_1d(a, b, lo, hi, c):
    t0, t1, t2 = lo, hi, 0.0
    k = 2
    if a != 0:
        extremum = -0.5 * b / a
        if lo < extremum < hi:
            t2 = extremum
            k = 3
    best_t = t0
    best_y = t0 * (a * t0 + b) + c
    y1 = t1 * (a * t1 + b) + c
    if y1 < best_y:
        best_t, best_y = t1, y1
    if k == 3:
        y2 = t2 * (a * t2 + b) + c
        if y2 < best_y:
            best_t, best_y = t2, y2
    return best_t, best_y


@njit(cache=True, error_model="numpy")
def _evaluate_quadratic(J, g, s, diag):
    Js = np.dot(J, s)
    q = np.dot(Js, Js)
    q += np.dot(s * diag, s)
    return 0.5 * q + np.dot(s, g)


@njit(cache=True, error_model="numpy")
def _in_bounds(x, lb, ub):
    for i in range(x.size):
        if not (x[i] >= lb[i] and x[i] <= ub[i]):
            return False
    return True


@njit(cache=True, error_model="numpy")
def _select_step(x, J_h, diag_h, g_h, p, p_h, d, delta, lb, ub, theta):
    """scipy's ``select_step``: the trust-region step, its reflection or the scaled gradient step."""
    if _in_bounds(x + p, lb, ub):
        return p, p_h, -_evaluate_quadratic(J_h, g_h, p_h, diag_h)
    p_stride, hits = _step_to_bound(x, p, lb, ub)
    r_h = p_h.copy()
    for i in range(r_h.size):
        if hits[i] != 0:
            r_h[i] *= -1
    r = d * r_h
    p *= p_stride
    p_h *= p_stride
    x_on_bound = x + p
    _, to_tr = _intersect_trust_region(p_h, r_h, delta)
    to_bound, _ = _step_to_bound(x_on_bound, r, lb, ub)
    r_stride = min(to_bound, to_tr)
    if r_stride > 0:
        r_stride_l = (1 - theta) * p_stride / r_stride
        if r_stride == to_bound:
            r_stride_u = theta * to_bound
        else:
            r_stride_u = to_tr
    else:
        r_stride_l = 0.0
        r_stride_u = -1.0
    if r_stride_l <= r_stride_u:
        a, b, c = _quadratic_1d_from(J_h, g_h, r_h, diag_h, p_h)
        r_stride, r_value = _minimize_quadratic_1d(a, b, r_stride_l, r_stride_u, c)
        r_h *= r_stride
        r_h += p_h
        r = r_h * d
    else:
        r_value = np.inf
    p *= theta
    p_h *= theta
    p_value = _evaluate_quadratic(J_h, g_h, p_h, diag_h)
    ag_h = -g_h
    ag = d * ag_h
    to_tr = delta / _norm(ag_h)
    to_bound, _ = _step_to_bound(x, ag, lb, ub)
    if to_bound < to_tr:
        ag_stride = theta * to_bound
    else:
        ag_stride = to_tr
    a, b = _quadratic_1d(J_h, g_h, ag_h, diag_h)
    ag_stride, ag_value = _minimize_quadratic_1d(a, b, 0.0, ag_stride, 0.0)
    ag_h *= ag_stride
    ag *= ag_stride
    if p_value < r_value and p_value < ag_value:
        return p, p_h, -p_value
    if r_value < p_value and r_value < ag_value:
        return r, r_h, -r_value
    return ag, ag_h, -ag_value


@njit(cache=True, error_model="numpy")
def _strictly_feasible(x, lb, ub):
    """scipy's ``make_strictly_feasible`` with ``rstep=0``."""
    x_new = x.copy()
    for i in range(x.size):
        active = 0
        if x[i] <= lb[i]:
            active = -1
        if x[i] >= ub[i]:
            active = 1
        if active == -1:
            x_new[i] = np.nextafter(lb[i], ub[i])
        elif active == 1:
            x_new[i] = np.nextafter(ub[i], lb[i])
        if x_new[i] < lb[i] or x_new[i] > ub[i]:
            x_new[i] = 0.5 * (lb[i] + ub[i])
    return x_new


@njit(cache=True, error_model="numpy")
def _step(m, uf, s, V, delta, alpha, x, J_h, diag_h, g_h, d, lb, ub, theta, half):
    """One trial step of an outer iteration: the trust-region solution at radius ``delta``, the step
    selected from it, the strictly feasible trial point, and the norms the radius update and the
    stopping rules need."""
    n = x.size
    p_h, alpha = _solve_trust_region(n, m, uf, s, V, delta, alpha, half)
    p = d * p_h
    step, step_h, predicted = _select_step(x, J_h, diag_h, g_h, p, p_h, d, delta, lb, ub, theta)
    x_new = _strictly_feasible(x + step, lb, ub)
    return x_new, predicted, alpha, _norm(step_h), _norm(step), _norm(x)


def _update_radius(delta, actual, predicted, step_norm, bound_hit):
    if predicted > 0:
        ratio = actual / predicted
    elif predicted == actual == 0:
        ratio = 1
    else:
        ratio = 0
    if ratio < 0.25:
        delta = 0.25 * step_norm
    elif ratio > 0.75 and bound_hit:
        delta *= 2.0
    return delta, ratio


def _termination(dF, F, dx_norm, x_norm, ratio, ftol, xtol):
    ftol_ok = dF < ftol * F and ratio > 0.25
    xtol_ok = dx_norm < xtol * (xtol + x_norm)
    if ftol_ok and xtol_ok:
        return 4
    if ftol_ok:
        return 2
    if xtol_ok:
        return 3
    return None


def _active(x, lb, ub, rtol):
    """scipy's ``find_active_constraints``: -1 on a lower bound, 1 on an upper one, 0 inside."""
    active = np.zeros_like(x, dtype=int)
    lower_dist, upper_dist = x - lb, ub - x
    lower = np.isfinite(lb) & (lower_dist <= np.minimum(upper_dist, rtol * np.maximum(1, np.abs(lb))))
    upper = np.isfinite(ub) & (upper_dist <= np.minimum(lower_dist, rtol * np.maximum(1, np.abs(ub))))
    active[lower] = -1
    active[upper] = 1
    return active


def _feasible_start(x, lb, ub, rstep=1e-10):
    """scipy's ``make_strictly_feasible`` with its default ``rstep``, as least_squares moves ``x0``: a start
    within ``rstep`` (relative) of a bound is put that far inside it."""
    x_new = x.copy()
    active = _active(x, lb, ub, rstep)
    lower, upper = active == -1, active == 1
    x_new[lower] = lb[lower] + rstep * np.maximum(1, np.abs(lb[lower]))
    x_new[upper] = ub[upper] - rstep * np.maximum(1, np.abs(ub[upper]))
    tight = (x_new < lb) | (x_new > ub)
    x_new[tight] = 0.5 * (lb[tight] + ub[tight])
    return x_new


def trf_bounds(fun, jac, x0, lb, ub, *, ftol=1e-8, xtol=1e-8, gtol=1e-8, max_nfev=None) -> OptimizeResult:
    """Minimise ``0.5 * ||fun(x)||^2`` over ``lb <= x <= ub`` (finite bounds) by scipy's trust-region
    reflective method, ``jac(x)`` the Jacobian of ``fun``; the result as ``least_squares`` returns it.

    ``x0`` must lie within the bounds (a start within 1e-10, relative, of a bound is moved that far inside,
    as scipy does); ``max_nfev`` defaults to 100 per parameter, as scipy's does.
    """
    x = np.array(x0, dtype=float)
    lb, ub = np.asarray(lb, dtype=float), np.asarray(ub, dtype=float)
    if x.ndim != 1 or lb.shape != x.shape or ub.shape != x.shape:
        raise ValueError(f"x0, lb, ub: expected three vectors of one length, got shapes {x.shape}, {lb.shape}, {ub.shape}")
    if not (np.all(np.isfinite(lb)) and np.all(np.isfinite(ub)) and np.all(lb < ub)):
        raise ValueError("lb, ub: expected finite bounds with lb < ub in every component")
    if not np.all((x >= lb) & (x <= ub)):
        raise ValueError("x0 is infeasible: expected lb <= x0 <= ub")
    x = _feasible_start(x, lb, ub)
    f = np.atleast_1d(np.asarray(fun(x), dtype=float))
    if not np.all(np.isfinite(f)):
        raise ValueError("Residuals are not finite in the initial point.")
    J = np.atleast_2d(np.asarray(jac(x), dtype=float))
    m, n = J.shape
    if max_nfev is None:
        max_nfev = 100 * n
    f_true = f.copy()
    nfev = njev = 1
    cost = 0.5 * np.dot(f, f)
    g = J.T.dot(f)
    delta = _initial_radius(x, g, lb, ub)
    alpha = 0.0
    status = None
    while True:
        g_norm = _gradient_norm(x, g, lb, ub)
        if g_norm < gtol:
            status = 1
        if status is not None or nfev == max_nfev:
            break
        d, diag_h, g_h, J_h, uf, s, V = _prepare(x, g, np.ascontiguousarray(J), f, lb, ub)
        theta = max(0.995, 1 - g_norm)
        actual = -1
        while actual <= 0 and nfev < max_nfev:
            x_new, predicted, alpha, step_h_norm, step_norm, x_norm = _step(
                m, uf, s, V, delta, alpha, x, J_h, diag_h, g_h, d, lb, ub, theta, 0.5)
            f_new = np.atleast_1d(np.asarray(fun(x_new), dtype=float))
            nfev += 1
            if not np.all(np.isfinite(f_new)):
                delta = 0.25 * step_h_norm
                continue
            cost_new = 0.5 * np.dot(f_new, f_new)
            actual = cost - cost_new
            delta_new, ratio = _update_radius(delta, actual, predicted, step_h_norm, step_h_norm > 0.95 * delta)
            status = _termination(actual, cost, step_norm, x_norm, ratio, ftol, xtol)
            if status is not None:
                break
            alpha *= delta / delta_new
            delta = delta_new
        if actual > 0:
            x, f, cost = x_new, f_new, cost_new
            f_true = f.copy()
            J = np.atleast_2d(np.asarray(jac(x), dtype=float))
            njev += 1
            g = J.T.dot(f)
    if status is None:
        status = 0
    return OptimizeResult(x=x, cost=cost, fun=f_true, jac=J, grad=g, optimality=g_norm,
                          active_mask=_active(x, lb, ub, xtol), nfev=nfev, njev=njev, status=status,
                          message=TERMINATION_MESSAGES[status], success=status > 0)
