"""Bounded trust-region reflective least squares: scipy's algorithm step for step, without its per-call overhead.

:func:`trf_bounds` is ``scipy.optimize.least_squares(fun, x0, jac=jac, bounds=(lb, ub), method="trf",
x_scale=1.0, ...)`` for what GMWM asks of it (finite bounds, the exact trust-region solver, linear loss,
a callable Jacobian): the same iteration -- Coleman & Li's scaling, the SVD of the augmented Jacobian,
Moré's iteration for the Levenberg-Marquardt parameter, the reflective step selection, the same trust-region
radius updates and stopping rules, in the same order (Branch, Coleman & Li, 1999, SIAM J. Sci. Comput.
21(1), Sect. 2; Moré, 1978; scipy's ``optimize/_lsq/trf.py``, ``common.py`` and ``least_squares.py`` are the
reference this follows, operation for operation) -- and the same result fields (``x``, ``cost``, ``fun``,
``jac``, ``grad``, ``optimality``, ``active_mask``, ``nfev``, ``njev``, ``status``, ``message``, ``success``).

Why: a GMWM fit solves ~70 small problems (10-20 scales, 3-8 parameters) to tolerances of 1e-15, ~27
evaluations each, and the per-call machinery around scipy's arithmetic -- the differentiable-function
wrappers of every evaluation, ``scipy.linalg.svd``'s finiteness check and LAPACK workspace query on every
iteration, ``numpy.linalg.norm``'s dispatch, boolean-mask assignments on 3-8 elements -- is most of the fit
when scipy's function runs it (a GMWM fit of a 4 h, 10 Hz record then takes 0.46 s against a target of 0.3 s;
``results/bench/README.md``). Here the same NumPy operations run
without it: LAPACK's ``gesdd`` is called as ``scipy.linalg.svd`` calls it, with the workspace it computes,
queried once per shape (:func:`_svd`); a vector's norm is ``sqrt(x.dot(x))``, what ``numpy.linalg.norm``
computes.

Same arithmetic, so the same bits: every product, sum, dot product (BLAS) and SVD (LAPACK) is the one scipy
performs, on the same operands, in the same order (``tests/test_trf.py``: every result field equal to
scipy's on 200 random bounded problems, in a fresh process on the committed studies' kernels and on
whatever kernels the tests run on). It is not compiled (numba): numba's BLAS and LAPACK bindings cost ~16 s
of compilation on first use and ~0.3 s of cache loading in every new process, more than a compiled iteration
saves in a single ``avbench estimate``.
"""

from __future__ import annotations

import functools
import math

import numpy as np
from scipy.linalg import get_lapack_funcs
from scipy.optimize import OptimizeResult

__all__ = ["trf_bounds", "resume_trf", "lower_triangular_solver", "TERMINATION_MESSAGES"]

EPS = float(np.finfo(float).eps)

#: ``result.message`` by ``result.status``, as scipy's least_squares words them
TERMINATION_MESSAGES = {
    0: "The maximum number of function evaluations is exceeded.",
    1: "`gtol` termination condition is satisfied.",
    2: "`ftol` termination condition is satisfied.",
    3: "`xtol` termination condition is satisfied.",
    4: "Both `ftol` and `xtol` termination conditions are satisfied.",
}


def _norm(a):
    return math.sqrt(a.dot(a))  # numpy.linalg.norm of a vector: sqrt(x.dot(x))


def _cl_scaling(x, g, lb, ub):
    """Coleman-Li scaling vector v and its derivative dv (scipy's ``CL_scaling_vector``; bounds finite)."""
    below, above = g < 0, g > 0
    v = np.where(above, x - lb, np.where(below, ub - x, 1.0))
    dv = above.astype(float)
    dv -= below
    return v, dv


@functools.cache
def _gesdd(shape):
    """LAPACK's ``gesdd`` and the workspace ``scipy.linalg.svd(a, full_matrices=False)`` gives it, for a float64
    matrix of ``shape`` (queried once per shape)."""
    from scipy.linalg.lapack import _compute_lwork

    gesdd, gesdd_lwork = get_lapack_funcs(("gesdd", "gesdd_lwork"), (np.empty(shape),), ilp64="preferred")
    return gesdd, _compute_lwork(gesdd_lwork, shape[0], shape[1], compute_uv=True, full_matrices=False)


def _svd(a):
    """``scipy.linalg.svd(a, full_matrices=False)`` of a finite float64 ``a``: its LAPACK call, without its
    per-call checks and workspace query."""
    gesdd, lwork = _gesdd(a.shape)
    u, s, vt, info = gesdd(a, compute_uv=True, lwork=lwork, full_matrices=False, overwrite_a=False)
    if info != 0:
        raise np.linalg.LinAlgError(f"SVD did not converge (LAPACK gesdd info {info})")
    return u, s, vt


def lower_triangular_solver(L):
    """``b -> solve_triangular(L, b, lower=True)`` for a finite lower-triangular ``L``: the LAPACK call
    ``scipy.linalg.solve_triangular`` makes (``trtrs``, on the transposed system for a C-ordered ``L``), the
    same bits, without its per-call input checks (~300 calls per GMWM fit: its second step's whitening)."""
    trtrs, = get_lapack_funcs(("trtrs",), (L,))
    a, lower, trans = (L, 1, 0) if L.flags.f_contiguous else (L.T, 0, 1)

    def solve(b):
        x, info = trtrs(a, b, lower=lower, trans=trans)
        if info != 0:
            raise np.linalg.LinAlgError(f"triangular solve failed (LAPACK trtrs info {info})")
        return x

    return solve


def _solve_trust_region(n, m, uf, s, V, delta, alpha):
    """scipy's ``solve_lsq_trust_region`` with ``initial_alpha`` given, rtol 0.01, 10 iterations."""
    suf = s * uf
    full_rank = False
    if m >= n:
        full_rank = s[-1] > EPS * m * s[0]
    if full_rank:
        p = -V.dot(uf / s)
        if _norm(p) <= delta:
            return p, 0.0

    def phi_and_derivative(alpha):
        denom = s**2 + alpha
        p_norm = _norm(suf / denom)
        return p_norm - delta, -(suf**2 / denom**3).sum() / p_norm  # np.sum's reduction

    alpha_upper = _norm(suf) / delta
    if full_rank:
        phi, phi_prime = phi_and_derivative(0.0)
        alpha_lower = -phi / phi_prime
    else:
        alpha_lower = 0.0
    if not full_rank and alpha == 0:
        alpha = max(0.001 * alpha_upper, (alpha_lower * alpha_upper)**0.5)
    for _ in range(10):
        if alpha < alpha_lower or alpha > alpha_upper:
            alpha = max(0.001 * alpha_upper, (alpha_lower * alpha_upper)**0.5)
        phi, phi_prime = phi_and_derivative(alpha)
        if phi < 0:
            alpha_upper = alpha
        ratio = phi / phi_prime
        alpha_lower = max(alpha_lower, alpha - ratio)
        alpha -= (phi + delta) * ratio / delta
        if np.abs(phi) < 0.01 * delta:
            break
    p = -V.dot(suf / (s**2 + alpha))
    p *= delta / _norm(p)
    return p, alpha


def _step_to_bound(x, s, lb, ub):
    """scipy's ``step_size_to_bound``: the smallest step along ``s`` to a bound, and which are hit."""
    non_zero = np.nonzero(s)
    s_non_zero = s[non_zero]
    steps = np.empty_like(x)
    steps.fill(np.inf)
    with np.errstate(over="ignore"):
        steps[non_zero] = np.maximum((lb - x)[non_zero] / s_non_zero, (ub - x)[non_zero] / s_non_zero)
    min_step = np.min(steps)
    return min_step, np.equal(steps, min_step) * np.sign(s).astype(int)


def _intersect_trust_region(x, s, delta):
    a = np.dot(s, s)
    if a == 0:
        raise ValueError("`s` is zero.")
    b = np.dot(x, s)
    c = np.dot(x, x) - delta**2
    if c > 0:
        raise ValueError("`x` is not within the trust region.")
    d = np.sqrt(b * b - a * c)
    q = -(b + math.copysign(d, b))
    t1 = q / a
    t2 = c / q
    return (t1, t2) if t1 < t2 else (t2, t1)


def _quadratic_1d(J, g, s, diag, s0=None):
    v = J.dot(s)
    a = np.dot(v, v)
    a += np.dot(s * diag, s)
    a *= 0.5
    b = np.dot(g, s)
    if s0 is None:
        return a, b
    u = J.dot(s0)
    b += np.dot(u, v)
    c = 0.5 * np.dot(u, u) + np.dot(g, s0)
    b += np.dot(s0 * diag, s)
    c += 0.5 * np.dot(s0 * diag, s0)
    return a, b, c


def _minimize_quadratic_1d(a, b, lo, hi, c=0):
    t = [lo, hi]
    if a != 0:
        extremum = -0.5 * b / a
        if lo < extremum < hi:
            t.append(extremum)
    t = np.asarray(t)
    y = t * (a * t + b) + c
    k = np.argmin(y)
    return t[k], y[k]


def _evaluate_quadratic(J, g, s, diag):
    Js = J.dot(s)
    q = np.dot(Js, Js)
    q += np.dot(s * diag, s)
    return 0.5 * q + np.dot(s, g)


def _select_step(x, J_h, diag_h, g_h, p, p_h, d, delta, lb, ub, theta):
    """scipy's ``select_step``: the trust-region step, its reflection or the scaled gradient step."""
    xp = x + p
    if ((xp >= lb) & (xp <= ub)).all():
        return p, p_h, -_evaluate_quadratic(J_h, g_h, p_h, diag_h)
    p_stride, hits = _step_to_bound(x, p, lb, ub)
    r_h = np.copy(p_h)
    r_h[hits.astype(bool)] *= -1
    r = d * r_h
    p *= p_stride
    p_h *= p_stride
    x_on_bound = x + p
    _, to_tr = _intersect_trust_region(p_h, r_h, delta)
    to_bound, _ = _step_to_bound(x_on_bound, r, lb, ub)
    r_stride = min(to_bound, to_tr)
    if r_stride > 0:
        r_stride_l = (1 - theta) * p_stride / r_stride
        r_stride_u = theta * to_bound if r_stride == to_bound else to_tr
    else:
        r_stride_l = 0
        r_stride_u = -1
    if r_stride_l <= r_stride_u:
        a, b, c = _quadratic_1d(J_h, g_h, r_h, diag_h, s0=p_h)
        r_stride, r_value = _minimize_quadratic_1d(a, b, r_stride_l, r_stride_u, c=c)
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
    ag_stride = theta * to_bound if to_bound < to_tr else to_tr
    a, b = _quadratic_1d(J_h, g_h, ag_h, diag_h)
    ag_stride, ag_value = _minimize_quadratic_1d(a, b, 0, ag_stride)
    ag_h *= ag_stride
    ag *= ag_stride
    if p_value < r_value and p_value < ag_value:
        return p, p_h, -p_value
    if r_value < p_value and r_value < ag_value:
        return r, r_h, -r_value
    return ag, ag_h, -ag_value


def _strictly_feasible(x, lb, ub, rstep=0.0):
    """scipy's ``make_strictly_feasible``: a point on a bound (``rstep`` 0: each trial point) is moved to the next
    float inside it, one within ``rstep`` (relative) of a bound (the start, as least_squares moves ``x0``) that far
    inside it."""
    if rstep == 0:
        lower, upper = x <= lb, x >= ub
    else:
        active = _active(x, lb, ub, rstep)
        lower, upper = active == -1, active == 1
    x_new = x.copy()
    if not (lower.any() or upper.any()):  # strictly inside: nothing to move
        return x_new
    lower &= ~upper
    if rstep == 0:
        x_new[lower] = np.nextafter(lb[lower], ub[lower])
        x_new[upper] = np.nextafter(ub[upper], lb[upper])
    else:
        x_new[lower] = lb[lower] + rstep * np.maximum(1, np.abs(lb[lower]))
        x_new[upper] = ub[upper] - rstep * np.maximum(1, np.abs(ub[upper]))
    tight = (x_new < lb) | (x_new > ub)
    x_new[tight] = 0.5 * (lb[tight] + ub[tight])
    return x_new


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


def trf_bounds(fun, jac, x0, lb, ub, *, ftol=1e-8, xtol=1e-8, gtol=1e-8, max_nfev=None) -> OptimizeResult:
    """Minimise ``0.5 * ||fun(x)||^2`` over ``lb <= x <= ub`` (finite bounds) by scipy's trust-region
    reflective method, ``jac(x)`` the Jacobian of ``fun``; the result as ``least_squares`` returns it.

    ``x0`` must lie within the bounds (a start within 1e-10, relative, of a bound is moved that far inside,
    as scipy does); ``max_nfev`` defaults to 100 per parameter, as scipy's does. A run stopped by ``max_nfev``
    goes on by :func:`resume_trf`.
    """
    x = np.array(x0, dtype=float)
    lb, ub = np.asarray(lb, dtype=float), np.asarray(ub, dtype=float)
    if x.ndim != 1 or lb.shape != x.shape or ub.shape != x.shape:
        raise ValueError(f"x0, lb, ub: expected three vectors of one length, got shapes {x.shape}, {lb.shape}, {ub.shape}")
    if not (np.all(np.isfinite(lb)) and np.all(np.isfinite(ub)) and np.all(lb < ub)):
        raise ValueError("lb, ub: expected finite bounds with lb < ub in every component")
    if not np.all((x >= lb) & (x <= ub)):
        raise ValueError("x0 is infeasible: expected lb <= x0 <= ub")
    x = _strictly_feasible(x, lb, ub, rstep=1e-10)
    f = np.atleast_1d(np.asarray(fun(x), dtype=float))
    if not np.all(np.isfinite(f)):
        raise ValueError("Residuals are not finite in the initial point.")
    J = np.atleast_2d(np.asarray(jac(x), dtype=float))
    m, n = J.shape
    if max_nfev is None:
        max_nfev = 100 * n
    cost = 0.5 * np.dot(f, f)
    g = J.T.dot(f)
    v, _ = _cl_scaling(x, g, lb, ub)
    delta = _norm(x / v**0.5)
    if delta == 0:
        delta = 1.0
    state = {"fun": fun, "jac": jac, "lb": lb, "ub": ub, "ftol": ftol, "xtol": xtol, "gtol": gtol,
             "x": x, "f": f, "f_true": f.copy(), "J": J, "g": g, "cost": cost, "delta": delta, "alpha": 0.0,
             "nfev": 1, "njev": 1, "f_aug": np.zeros(m + n), "J_aug": np.zeros((m + n, n))}
    return _iterate(state, max_nfev)


def resume_trf(result: OptimizeResult, max_nfev: int) -> OptimizeResult:
    """The run that ended in ``result`` (status 0: its evaluation limit) gone on until ``max_nfev`` evaluations in
    all: bit for bit the run :func:`trf_bounds` makes with ``max_nfev`` from the same start (the iteration's state --
    point, residuals, Jacobian, trust radius, Levenberg-Marquardt parameter -- is where the shorter run left it;
    a new outer iteration recomputes the scaling and SVD of the same point, the values the longer run holds
    there). ``result`` is left as it is."""
    if result.status != 0 or "_state" not in result:
        raise ValueError("resume_trf: expected a run stopped by its evaluation limit (status 0)")
    state = dict(result["_state"])
    state["f_aug"], state["J_aug"] = state["f_aug"].copy(), state["J_aug"].copy()
    return _iterate(state, max_nfev)


def _iterate(state: dict, max_nfev: int) -> OptimizeResult:
    """The trust-region reflective iteration from ``state`` (:func:`trf_bounds`) until a stopping rule or
    ``max_nfev`` evaluations in all."""
    fun, jac, lb, ub = state["fun"], state["jac"], state["lb"], state["ub"]
    ftol, xtol, gtol = state["ftol"], state["xtol"], state["gtol"]
    x, f, f_true, J, g, cost = state["x"], state["f"], state["f_true"], state["J"], state["g"], state["cost"]
    delta, alpha, nfev, njev = state["delta"], state["alpha"], state["nfev"], state["njev"]
    f_aug, J_aug = state["f_aug"], state["J_aug"]
    m, n = J.shape
    status = None
    while True:
        v, dv = _cl_scaling(x, g, lb, ub)
        g_norm = np.abs(g * v).max()  # numpy.linalg.norm(g * v, ord=inf)
        if g_norm < gtol:
            status = 1
        if status is not None or nfev == max_nfev:
            break
        d = v**0.5
        diag_h = g * dv
        g_h = d * g
        f_aug[:m] = f
        J_aug[:m] = J * d
        J_h = J_aug[:m]
        J_aug[m:].flat[::n + 1] = diag_h**0.5  # np.diag(diag_h**0.5): the rest of J_aug[m:] stays 0
        U, s, V = _svd(J_aug)
        V = V.T
        uf = U.T.dot(f_aug)
        theta = max(0.995, 1 - g_norm)
        actual = -1
        while actual <= 0 and nfev < max_nfev:
            p_h, alpha = _solve_trust_region(n, m, uf, s, V, delta, alpha)
            step, step_h, predicted = _select_step(x, J_h, diag_h, g_h, d * p_h, p_h, d, delta, lb, ub, theta)
            x_new = _strictly_feasible(x + step, lb, ub)
            f_new = np.atleast_1d(np.asarray(fun(x_new), dtype=float))
            nfev += 1
            step_h_norm = _norm(step_h)
            if not np.isfinite(f_new).all():
                delta = 0.25 * step_h_norm
                continue
            cost_new = 0.5 * np.dot(f_new, f_new)
            actual = cost - cost_new
            delta_new, ratio = _update_radius(delta, actual, predicted, step_h_norm, step_h_norm > 0.95 * delta)
            status = _termination(actual, cost, _norm(step), _norm(x), ratio, ftol, xtol)
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
    out = OptimizeResult(x=x, cost=cost, fun=f_true, jac=J, grad=g, optimality=g_norm,
                         active_mask=_active(x, lb, ub, xtol), nfev=nfev, njev=njev, status=status,
                         message=TERMINATION_MESSAGES[status], success=status > 0)
    if status == 0:
        out["_state"] = {**state, "x": x, "f": f, "f_true": f_true, "J": J, "g": g, "cost": cost, "delta": delta,
                         "alpha": alpha, "nfev": nfev, "njev": njev}
    return out
