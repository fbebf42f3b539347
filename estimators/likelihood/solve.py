"""GMWM's criterion minimised to its optimum: scipy's trust-region reflective least squares
(:func:`avbench.estimators.likelihood._trf.trf_bounds`, step for step) at tolerances 1e-15, with the parameters
whose effect vanishes toward a bound settled there (:func:`solve`)."""

from __future__ import annotations

import math

import numpy as np

from avbench.estimators.likelihood._trf import resume_trf, trf_bounds

__all__ = ["MAX_NFEV", "SETTLE_NFEV", "CREEP_SHARE", "CONVERGED_DECREMENT", "solve", "settle", "pushed",
           "newton_decrement"]

#: evaluations of one trust-region solve (:func:`solve`)
MAX_NFEV = 2000
#: evaluations after which a solve still running is settled where the criterion is flat (:func:`settle`)
SETTLE_NFEV = 300
#: a parameter whose gradient component is more than this share of the sum of the magnitudes it is made of,
#: sum_i |J_ij f_i|, where a solve stops short is still pushed by the data (at round-off the share is
#: ~1e-12): :func:`solve` tries it on the bound it is pushed to
CREEP_SHARE = 1e-3
#: a solve stopped by its evaluation limit is converged when the Gauss-Newton step left, over the parameters
#: not held by a bound, is at most this many standard errors long (its Newton decrement, :func:`newton_decrement`)
CONVERGED_DECREMENT = 1e-8


def solve(fun, u0, lo, hi, jac):
    """Minimise ``0.5 ||fun(u)||^2`` over ``lo <= u <= hi`` to the optimum, not to a tolerance (xtol, ftol,
    gtol 1e-15): looser stopping rules end where the last bits of the record decide, so that the end point
    of a coefficient along a flat direction of the criterion, and the criterion J, move between units of
    the same record by more than round-off of the input moves them; at 1e-15 they agree as under round-off.

    A solve still running after :data:`SETTLE_NFEV` evaluations is usually creeping along a direction
    whose effect on the curve vanishes exponentially in the log-parameter: a term the data drive to zero
    (K of a record without rate random walk), a filter time constant far below dt (FW's ``tf`` on a 10 Hz
    record), a resonance's damping time beyond the record's scales. Such a parameter's limit is its bound,
    which the trust region approaches by ever smaller steps (thousands of evaluations), so that where it
    stops depends on the last bits of the record. :func:`settle` holds the parameters still pushed there on
    their bounds and solves the rest (tens of evaluations); its end point is returned where it is a
    Karush-Kuhn-Tucker point no higher than the running solve's. Otherwise the solve runs on from where it
    stopped (:func:`~avbench.estimators.likelihood._trf.resume_trf`: the run from its start, bit for bit) to
    :data:`MAX_NFEV` evaluations; at that limit every parameter still pushed (:func:`pushed`) is
    put on its bound and the solve restarted, the lower criterion of the two end points kept.

    The result carries ``converged`` and ``stop_reason`` (a sentence: the tolerance met, the parameters
    settled, or the evaluation limit with the restart and the end point's Newton decrement). ``converged``
    is least_squares' own (a tolerance met), a settled Karush-Kuhn-Tucker point, or, at the evaluation
    limit, a Newton decrement at most :data:`CONVERGED_DECREMENT` (the optimum lies within 1e-8 standard
    errors of the end point: nothing a further step could change in a reported coefficient). A solve that
    ends before :data:`SETTLE_NFEV` evaluations is returned as the solver gives it (scipy's
    ``least_squares`` step for step, :func:`avbench.estimators.likelihood._trf.trf_bounds`).
    """
    clip = lambda u: np.clip(u, lo + 1e-9, hi - 1e-9)  # noqa: E731
    run = lambda u, limit=MAX_NFEV: trf_bounds(fun, jac, clip(u), lo, hi,  # noqa: E731
                                               xtol=1e-15, ftol=1e-15, gtol=1e-15, max_nfev=limit)
    first = run(u0, SETTLE_NFEV)
    if first.status != 0:  # the first SETTLE_NFEV evaluations of run(u0), step for step
        first.converged, first.stop_reason = bool(first.success), f"least_squares: {first.message}"
        return first
    settled, spent = settle(fun, jac, first, lo, hi)
    if settled is not None:
        return settled
    sol = resume_trf(first, MAX_NFEV)  # run(u0) with MAX_NFEV, bit for bit, without its first SETTLE_NFEV again
    sol.nfev += spent - first.nfev  # the held solves' evaluations counted too
    if sol.status != 0:
        sol.converged, sol.stop_reason = bool(sol.success), f"least_squares: {sol.message}"
        return sol
    tries, g = pushed(sol)
    reason = f"least_squares stopped after {sol.nfev} evaluations"
    for idx in tries:  # the first restart that lowers the criterion is kept
        u = sol.x.copy()
        u[idx] = np.where(g[idx] > 0, lo[idx], hi[idx])
        again = run(u)
        if again.cost <= sol.cost:
            again.nfev += sol.nfev
            sol = again
            reason += (f"; parameter(s) {', '.join(str(int(i)) for i in idx)}, still pushed there, restarted on "
                       f"their bounds: least_squares: {sol.message}")
            break
    else:
        if tries:
            reason += "; no parameter still pushed there gave a lower criterion restarted on its bound"
    decrement = newton_decrement(sol, lo, hi)
    sol.converged = bool(sol.status > 0 or decrement <= CONVERGED_DECREMENT)
    sol.stop_reason = f"{reason} (Newton decrement {decrement:.2g} standard errors)"
    return sol


def pushed(sol):
    """The parameters a least-squares end point's gradient still pushes (a component above
    :data:`CREEP_SHARE` of the magnitudes it sums) as the sets to try on their bounds -- all of them, then
    each alone, the most pushed first (a parameter whose optimum moves with a creeping one's is pushed
    too) --, and the gradient."""
    g = sol.jac.T @ sol.fun
    size = np.abs(sol.jac).T @ np.abs(sol.fun)
    push = np.abs(g) > CREEP_SHARE * size
    alone = [np.array([i]) for i in np.argsort(-np.abs(g) / np.where(size > 0, size, 1.0)) if push[i]]
    return ([np.flatnonzero(push)] if len(alone) > 1 else []) + alone, g


def settle(fun, jac, sol, lo, hi):
    """A solve still running after :data:`SETTLE_NFEV` evaluations, settled where the criterion is flat:
    the parameters the gradient still pushes (:func:`pushed`) are held on the bounds they are pushed to (a
    box of width 2e-8) while the others are solved, each such solve
    given :data:`SETTLE_NFEV` evaluations; ``(end point, evaluations)``: the first held end point whose
    criterion is at most the running solve's, and where every held parameter is still pushed outward (a
    Karush-Kuhn-Tucker point: the parameter's optimum is its bound), None where there is none; the
    evaluations spent, the running solve's included.

    Why: along a direction whose effect on the curve vanishes as the parameter goes to its bound (a
    resonance's damping time beyond the record's scales, a term the data drive to zero) the criterion's
    profile falls monotonically to the bound, and the trust region approaches it by ever smaller steps
    (thousands of evaluations); with the parameter held, the others converge in tens."""
    tries, g = pushed(sol)
    nfev = sol.nfev
    for idx in tries:
        down = g[idx] > 0  # pushed to the lower bound
        lo2, hi2 = lo.copy(), hi.copy()
        hi2[idx] = np.where(down, lo[idx] + 2e-8, hi[idx])
        lo2[idx] = np.where(down, lo[idx], hi[idx] - 2e-8)
        u = sol.x.copy()
        u[idx] = np.where(down, lo[idx], hi[idx])
        held = trf_bounds(fun, jac, np.clip(u, lo2 + 1e-9, hi2 - 1e-9), lo2, hi2, xtol=1e-15, ftol=1e-15,
                          gtol=1e-15, max_nfev=SETTLE_NFEV)
        nfev += held.nfev
        if held.status == 0 or held.cost > sol.cost:
            continue
        g_held = held.jac.T @ held.fun
        if not np.all(np.where(down, g_held[idx] > 0, g_held[idx] < 0)):
            continue  # a held parameter's optimum lies inside: not settled by its bound
        held.nfev = nfev
        held.converged = True
        held.stop_reason = (f"least_squares still running after {sol.nfev} evaluations; parameter(s) "
                            f"{', '.join(str(int(i)) for i in idx)}, pushed there, settled on their bounds: "
                            f"least_squares: {held.message}")
        return held, nfev
    return None, nfev


def newton_decrement(sol, lo, hi):
    """The Gauss-Newton step left at a least-squares end point, in standard errors: sqrt(g' H^+ g) over
    the parameters not held by a bound (H = J'J the criterion's Gauss-Newton curvature, the inverse
    covariance of the estimate; g = J'f its gradient). A parameter within 1e-6 of a bound that its
    gradient pushes it against is held there."""
    g = sol.jac.T @ sol.fun
    held = ((sol.x <= lo + 1e-6) & (g > 0)) | ((sol.x >= hi - 1e-6) & (g < 0))
    free = ~held
    if not free.any():
        return 0.0
    jf, gf = sol.jac[:, free], g[free]
    return float(math.sqrt(max(float(gf @ np.linalg.pinv(jf.T @ jf, rcond=1e-13, hermitian=True) @ gf), 0.0)))
