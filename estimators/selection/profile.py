"""Boundary-aware profile-likelihood intervals of a variance component, and which of two domains'
intervals a term takes.

The interval
------------
For a term j with variance :math:`a_j \\ge 0`, the profile likelihood :math:`\\ell_p(a) =
\\max_{\\theta: a_j = a}\\ell(\\theta)` (every other parameter refitted) gives the interval

.. math:: \\{a \\ge 0:\\ 2(\\hat\\ell - \\ell_p(a)) \\le q\\},\\qquad q = \\chi^2_{1,\\text{level}},

with :math:`\\ell_p(0) = \\hat\\ell_{-j}`, the likelihood of the model without the term. At an
interior truth it covers with probability -> level (Wilks); at a truth on the boundary 0 the
statistic follows :math:`\\tfrac12\\chi^2_0 + \\tfrac12\\chi^2_1` (Self & Liang 1987) and 0 is covered
with probability :math:`\\tfrac12 + \\tfrac{\\text{level}}2`. Its lower end is 0 when the estimate is
on the boundary or when the likelihood ratio of dropping the term is within q; its evidence is that
ratio with its chi-bar-squared p-value (:mod:`avbench.estimators.selection.evidence`).

:func:`profile_interval` finds the bounds in :math:`u = \\log a` on the signed likelihood root
:math:`r(u) = \\sqrt{2(\\hat\\ell - \\ell_p(e^u))}`, close to linear in u: secant steps from the Wald
guess :math:`\\hat u \\pm \\sqrt q\\,\\mathrm{se}(\\hat u)` until r brackets :math:`\\sqrt q`, then
Illinois regula falsi until r is within 0.01 of :math:`\\sqrt q` or the bracket is narrower than
``tol`` Wald standard errors (:func:`likelihood_root`). The model enters only through the profile
function ``profile(u)``, which may find a likelihood above the maximum known so far
(:class:`RunningMax`: the highest value seen, across terms, is the :math:`\\hat\\ell` of every later
comparison). :func:`profile_start` predicts the other parameters along the profile path.

Where the maximum is over a domain larger than :math:`a \\ge 0` (variances allowed below 0 while the
model stays valid) and the estimate is at or below 0 (``at_zero``), :math:`\\hat\\ell` is the
highest profile value seen over :math:`a \\ge 0` (:math:`\\ell_p(0)` to start with): the interval is
:math:`[0, \\text{upper}]` and the evidence none (LR 0, p = 1).

The domain switch
-----------------
:func:`steeper_negative_neighbours`: with both a signed-domain fit and a non-negative one, a term
whose steeper-spectrum neighbour (the next term in the order Q, N, B or GM, K) the signed fit puts
below 0 by more than :data:`NEGATIVE_Z` Wald standard errors takes its interval from the
non-negative domain; every other term keeps the signed domain's.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from avbench.estimators.selection.evidence import chibar2_pvalue

__all__ = ["RunningMax", "ProfileInterval", "profile_interval", "likelihood_root", "profile_start", "NEGATIVE_Z",
           "steeper_negative_neighbours"]

#: a variance of the signed domain "below 0 beyond its noise": its Wald statistic below minus the
#: two-sided 95 % normal point (fixed a priori, not tuned)
NEGATIVE_Z = 1.959963984540054


class RunningMax:
    """The highest log-likelihood seen so far (the full fit's, raised by any profile or reduced fit
    that beats it): ``value``, and ``update(v)`` keeps ``max(value, v)``."""

    def __init__(self, value: float):
        self.value = value

    def update(self, v: float) -> None:
        self.value = max(self.value, v)


class ProfileInterval(NamedTuple):
    """One term's profile-likelihood interval and evidence (the variance's own units).

    ``lower_reason`` says why the lower end is 0: ``"estimate at 0"`` (the estimate is on the
    boundary), ``"not significant"`` (the likelihood ratio of dropping the term is within the
    critical value), or None (a bound found by the root search)."""

    lr: float
    p_value: float
    lower: float
    upper: float
    lower_reason: str | None


def profile_interval(profile: Callable[[float], float], u_hat: float, su: float, ll0: float, best: RunningMax,
                     q: float, *, absent: bool, at_zero: bool, tol: float = 0.01) -> ProfileInterval:
    """The profile-likelihood interval of one variance :math:`a = e^u` and its evidence.

    ``profile(u)``: the profile log-likelihood at :math:`u = \\log a` (it may raise ``best``);
    ``u_hat``: the estimate's u (the floor's where it is at its boundary); ``su``: the Wald standard
    error of u (the first guess of the bounds' distance); ``ll0``: the log-likelihood without the term
    (:math:`\\ell_p(0)`; -inf if there is no such model); ``best``: the maximum log-likelihood seen;
    ``q``: the critical value (:math:`\\chi^2_{1,\\text{level}}`); ``absent``: the estimate is at 0;
    ``at_zero``: the maximum is over a larger domain and the estimate is at or below 0 (module
    docstring). The evidence: ``lr`` :math:`= 2(\\hat\\ell - \\ell_p(0))` (0 with ``at_zero``), read
    after the upper bound is found, and its chi-bar-squared ``p_value``."""
    sq = math.sqrt(q)
    own = [ll0]  # at_zero: the highest profile value over a >= 0 seen (at or next to 0)

    def r_of(u):
        if at_zero:
            v = profile(u)
            own[0] = max(own[0], v)
            return math.sqrt(max(2 * (own[0] - v), 0.0)) - sq
        return math.sqrt(max(2 * (best.value - profile(u)), 0.0)) - sq

    upper = math.exp(likelihood_root(r_of, u_hat, +1, sq, su, tol))
    lr = 0.0 if at_zero else max(2 * (best.value - ll0), 0.0)
    if absent or lr <= q:
        lower = 0.0
        reason = "estimate at 0" if absent else "not significant"
    else:
        lower = math.exp(likelihood_root(r_of, u_hat, -1, sq, su, tol))
        reason = None
    return ProfileInterval(lr=lr, p_value=chibar2_pvalue(lr), lower=lower, upper=upper, lower_reason=reason)


def likelihood_root(r_of: Callable[[float], float], u_in: float, direction: int, sq: float, su: float,
                    tol: float) -> float:
    """u on the side ``direction`` (+1 or -1) of ``u_in`` (where the shifted likelihood root
    :math:`r - \\sqrt q` is :math:`-\\sqrt q`) at which ``r_of(u)`` :math:`= r(u) - \\sqrt q`
    reaches 0: secant steps from the Wald guess ``u_in + direction * sq * su`` (each between half
    and four times the last, at most 20) until it changes sign, then Illinois regula falsi until
    :math:`|r - \\sqrt q| < 0.01` or the bracket is narrower than ``tol * su``. +-inf if no sign
    change is found in 30 steps (an interval unbounded on that side)."""
    f_in = -sq
    u_out = u_in + direction * sq * su
    f_out = r_of(u_out)
    for _ in range(30):
        if f_out >= 0:
            break
        slope = (f_out - f_in) / (u_out - u_in) if u_out != u_in else 0.0
        jump = -f_out / slope if slope * direction > 0 else math.inf
        jump = min(max(abs(jump), 0.5 * abs(u_out - u_in)), 4 * abs(u_out - u_in), 20.0)
        u_in, f_in = u_out, f_out
        u_out = u_in + direction * jump
        f_out = r_of(u_out)
    else:
        return math.inf if direction > 0 else -math.inf
    if abs(f_out) < 0.01:
        return u_out
    side = 0
    for _ in range(30):
        if abs(u_out - u_in) < tol * su:  # relative to the interval's own scale
            break
        u_new = (u_in * f_out - u_out * f_in) / (f_out - f_in)
        f_new = r_of(u_new)
        if abs(f_new) < 0.01:
            return u_new
        if f_new > 0:
            u_out, f_out = u_new, f_new
            if side == -1:
                f_in *= 0.5
            side = -1
        else:
            u_in, f_in = u_new, f_new
            if side == 1:
                f_out *= 0.5
            side = 1
    return 0.5 * (u_in + u_out)


def profile_start(visited, u, slope, lo, log_units=True):
    """Start of the profile fit at :math:`u_i = u` (the profiled variance in log units): the other
    parameters on the line through the two visited profile points ``(u, x)`` nearest to u (the
    profile path is smooth in u), or, with one point (the full fit), along the full fit's regression
    ``slope`` (:math:`\\mathrm{cov}(x, u_i)/\\mathrm{var}(u_i)`). The parameters ``x`` are in log
    units, kept within 1 of the nearest point and above the floors ``lo`` (a parameter at its floor
    there stays), or (``log_units=False``, a fit in the signed domain) the variances themselves
    (and log Tc), without floors."""
    near = sorted(visited, key=lambda v: abs(v[0] - u))[:2]
    u1, x1 = near[0]
    if len(near) == 2 and abs(near[1][0] - u1) > 1e-12:
        u2, x2 = near[1]
        x = x1 + (x2 - x1) * ((u - u1) / (u2 - u1))
    elif slope is not None:
        x = x1 + slope * (u - u1)
    else:
        x = x1.copy()
    if not log_units:
        return x
    # a step of at most 1 log unit per parameter from the nearest point; a parameter at its floor
    # there stays (the predicted path of an absent term is not informative)
    x = np.clip(x, x1 - 1.0, x1 + 1.0)
    at_floor = x1 <= lo + 1e-6
    x[at_floor] = x1[at_floor]
    return np.maximum(x, lo + math.log(1.01))


def steeper_negative_neighbours(names, estimate, info, z: float = NEGATIVE_Z) -> dict:
    """The terms of a signed-domain fit that take their interval from the non-negative domain, each
    with the neighbour that sends it there: a term whose next term in ``names`` (the order Q, N, B or
    GM, K of the power laws' slopes, so the neighbour with the steeper spectrum, whose spectrum
    overlaps its own and trades power with it) has its variance below 0 by more than ``z`` of its
    Wald standard errors (``info``: the information in the variances at the signed maximum; its
    inverse's diagonal gives the variances). Empty if the information is singular."""
    names = list(names)
    a = np.asarray(estimate, dtype=float)
    try:
        var = np.diag(np.linalg.inv(info))[: len(names)]
    except np.linalg.LinAlgError:
        return {}
    neg = [bool(var[i] > 0 and a[i] < -z * math.sqrt(var[i])) for i in range(len(names))]
    return {c: names[j + 1] for j, c in enumerate(names) if j + 1 < len(names) and neg[j + 1]}
