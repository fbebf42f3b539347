"""Intervals and evidence of a Whittle fit: the profile-likelihood interval and evidence of every
spectral term (:func:`profile_evidence`), the table the estimator reports (:func:`evidence_table`,
the ramp included), and the upper bounds of the terms estimated as 0 (:func:`zero_bounds`).

The model-choice components -- the boundary-aware interval search, the chi-bar-squared evidence and
the domain switch -- are :mod:`avbench.estimators.selection.profile` and
:mod:`avbench.estimators.selection.evidence`; this module gives them the Whittle likelihood's profile
fits.

Profile fits. Each bound of term j is found on :math:`\\ell_p(a_j)`, every other parameter refitted
with :math:`a_j` held (:meth:`~.whittle_likelihood.WhittleFit.fit` with ``fixed``, scoring in the
variances themselves, projected on their floors). Each profile fit starts on the profile path
predicted from the two nearest points already fitted (:func:`~avbench.estimators.selection.profile.profile_start`).
:math:`\\ell_p(0)` is the fit without the term, warm-started from the full fit. In the signed
domain (``domain="spectrum"``) a profile start that leaves the domain of a positive spectrum is
replaced by the nearest point fitted, then by that point without its negative variances.

The ramp R is not a spectral parameter: its interval is :math:`|\\hat R| \\pm z\\,\\mathrm{se}`
(clipped at 0) and its evidence the two-sided :math:`\\chi^2_1` p-value of its z, with se the exact
standard error of the slope under the full model whose random walk K is at the upper end of its
profile interval: a random walk's drift is a ramp to every estimator, and a K the record barely
resolves must not leave its drift to be read as one.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from avbench.estimators.likelihood.whittle_likelihood import FLOOR, WhittleFit, whittle_fit
from avbench.estimators.likelihood.whittle_spectra import component, component_of, components, is_shaped, trend, walk
from avbench.estimators.selection.evidence import present, two_sided_pvalue
from avbench.estimators.selection.profile import RunningMax, profile_interval, profile_start

__all__ = ["profile_evidence", "evidence_table", "zero_bounds"]


def profile_evidence(wf: WhittleFit, full: dict, level: float = 0.95, tol: float = 0.01):
    """Evidence and profile-likelihood interval of every spectral term of the fit ``full``.

    For each term j (variance :math:`a_j`; a Gauss-Markov term's :math:`\\sigma^2`, its Tc profiled):

    * ``lr``: :math:`2(\\hat\\ell - \\hat\\ell_{-j})`, the likelihood ratio of the model without j
      (the term's variance at its boundary 0), and ``p_value`` from the chi-bar-squared law
      (:func:`~avbench.estimators.selection.evidence.chibar2_pvalue`; for Gauss-Markov, whose Tc is
      not identified under the null, the same law is an approximation);
    * ``lower``, ``upper``: the profile-likelihood interval of :math:`a_j` on :math:`[0, \\infty)`,
      :math:`\\{a \\ge 0: 2(\\hat\\ell - \\ell_p(a)) \\le \\chi^2_{1,\\text{level}}\\}`, with
      :math:`\\ell_p(0) = \\hat\\ell_{-j}` (:func:`~avbench.estimators.selection.profile.profile_interval`).
      The interval is valid without knowing which terms are present: every candidate stays in the model.

    In the signed domain (``full["signed"]``) the other terms are profiled over the same domain, and
    a term estimated at or below 0 gets :math:`[0, \\text{upper}]` with :math:`\\hat\\ell` the
    maximum of :math:`\\ell_p` over :math:`a \\ge 0`, and no evidence (LR 0, p = 1).
    Returns ``{term: dict(lr, p_value, estimate, lower, upper)}`` in normalised variance units, and
    the best log-likelihood seen (a profile fit that beats the full fit replaces it)."""
    from scipy import stats

    q_level = float(stats.chi2.ppf(level, 1))
    comps = list(full["comps"])
    p = len(comps)
    has_gm = any(is_shaped(c) for c in comps)
    signed = bool(full.get("signed"))
    _, top = wf.start(comps, full["tc"])
    lo = np.log(FLOOR * top)
    if has_gm:
        lo = np.append(lo, math.log(wf.dt))
    best = RunningMax(float(full["loglik"]))
    out = {}
    try:
        cov = np.linalg.inv(full["detail"]["info"])  # in log-variances, or (signed) the variances
    except np.linalg.LinAlgError:
        cov = None

    def to_x(a, tc):
        """The fit's coordinates: log-variances, or (signed) the variances; then log Tc."""
        a = np.asarray(a, dtype=float)
        x = a.copy() if signed else np.log(a)
        return np.append(x, math.log(tc)) if tc is not None else x

    a_full = np.asarray(full["a"], dtype=float)
    x_full = to_x(a_full, full["tc"])
    for i, c in enumerate(comps):
        a_hat = float(a_full[i])
        absent = c in full["absent"]
        # the signed domain's estimate at or below 0: the profile's maximum over a >= 0 is at 0
        at_zero = signed and absent
        # the fit without c: the boundary point of the profile
        sub = [x for x in comps if x != c]
        sub_fit = None
        if any(x in components() for x in sub):
            warm = {x: full["a"][comps.index(x)] for x in sub}
            warm["tc"] = full["tc"]
            sub_fit = whittle_fit(wf, sub, 1, warm=warm, hold_floor=True, signed=signed)
            ll0 = sub_fit["loglik"]
        else:
            ll0 = -np.inf
        best.update(ll0)
        a_floor = FLOOR * float(top[i])
        u_hat = math.log(max(a_hat, a_floor))
        # Wald std of log a_i and the regression of the other coordinates on it (signed: the
        # information is in the variances, d log a_i = da_i / a_i)
        su = 1.0
        slope = None
        to_log = 1.0 if not signed else (a_hat if a_hat > 0 else math.nan)
        if cov is not None and cov[i, i] > 0 and np.isfinite(to_log):
            su = math.sqrt(cov[i, i]) / to_log
            if np.all(np.isfinite(cov[:, i])):
                slope = cov[:, i] / cov[i, i] * to_log
        su = min(max(su, 0.05), 5.0)
        # the profile path of the other parameters: the full fit's regression on u_i to start with,
        # then the line through the two nearest profile points already fitted
        if at_zero and sub_fit is not None and np.isfinite(ll0):
            a0 = np.insert(np.asarray(sub_fit["a"], dtype=float), i, a_floor)
            visited = [(u_hat, to_x(a0, sub_fit["tc"] if has_gm else None))]
        else:
            visited = [(u_hat, x_full)]

        def prof(u, i=i, slope=slope, visited=visited):
            x0 = profile_start(visited, u, slope, lo, log_units=not signed)
            x0[i] = math.exp(u) if signed else u
            a0 = x0[:p] if signed else np.exp(x0[:p])
            tc0 = math.exp(x0[-1]) if has_gm else None
            if signed and not np.isfinite(wf.loglik(comps, a0, tc0)):
                # the predicted start leaves the domain of a positive spectrum: the nearest point
                # fitted, then that point without its negative variances (always inside)
                near = min(visited, key=lambda v: abs(v[0] - u))[1].copy()
                near[i] = math.exp(u)
                a0 = near[:p]
                if not np.isfinite(wf.loglik(comps, a0, tc0)):
                    a0 = np.maximum(a0, 0.0)
            lo_i = lo.copy()
            lo_i[i] = -np.inf
            r = wf.fit(comps, a0, tc0, lo_i, fixed=i, tol=1e-4, signed=signed)
            if np.isfinite(r[2]):
                visited.append((u, to_x(r[0], r[1])))
                best.update(float(r[2]))
            return float(r[2])

        iv = profile_interval(prof, u_hat, su, ll0, best, q_level, absent=absent, at_zero=at_zero, tol=tol)
        out[c] = dict(lr=iv.lr, p_value=iv.p_value, estimate=0.0 if absent else a_hat, lower=iv.lower,
                      upper=iv.upper)
    return out, best.value


def evidence_table(wf: WhittleFit, full: dict, ev: dict, coefs: dict, se, ramp_z2: float, has_r: bool,
                   level: float) -> pd.DataFrame:
    """The ``evidence`` DataFrame (per coefficient: ``lr``, ``p_value``, ``lower``, ``upper`` in SI,
    ``present`` at 5 %) from the spectral terms' profile evidence ``ev`` (:func:`profile_evidence`,
    normalised variance units; a Gauss-Markov term reported as B) and the ramp's z-statistic
    (module docstring: the interval :math:`|\\hat R| \\pm z\\,\\mathrm{se}` at ``level``, se at least the
    slope's exact standard error with the random walk at the upper end of its profile interval)."""
    from scipy import stats

    rows = {}
    for c, e in ev.items():
        f = component(c).coefficient_per_amplitude  # a Gauss-Markov term's B per sigma
        rows[component(c).coefficient] = dict(
            lr=e["lr"], p_value=e["p_value"], lower=f * math.sqrt(e["lower"]) * wf.scale,
            upper=f * math.sqrt(e["upper"]) * wf.scale)
    if has_r and np.isfinite(ramp_z2):
        z = float(stats.norm.ppf(0.5 + level / 2))
        ramp = trend()
        r, s = float(coefs.get(ramp, 0.0)), float(se[ramp])
        r = r if r > 0 else math.sqrt(ramp_z2) * s
        walker = walk(ev)
        if walker is not None:
            # the ramp cannot be told from the random walk's drift: its interval and evidence
            # allow for every drift the data allow, K up to its profile upper bound
            a_walk = max(float(full["a"][full["comps"].index(walker)]), float(ev[walker]["upper"]))
            var = wf.trend_variance(full["comps"], full["a"], full["tc"], a_walk=a_walk)
            s = max(s, math.sqrt(var) * wf.scale / wf.dt)
        z2 = (r / s) ** 2
        rows[ramp] = dict(lr=z2, p_value=two_sided_pvalue(z2), lower=max(r - z * s, 0.0), upper=r + z * s)
    df = pd.DataFrame.from_dict(rows, orient="index", columns=["lr", "p_value", "lower", "upper"])
    df["present"] = present(df["p_value"])
    return df


def zero_bounds(wf: WhittleFit, fit: dict, kept, terms, coefs: dict, se) -> dict:
    """Upper bounds of the terms estimated as 0 (dropped or at their floor), for ``conf_int``.

    A variance at the boundary 0 has the one-sided bound :math:`c^2 \\le z\\,\\mathrm{se}(c^2)`,
    se from the Whittle information in the variances (which stays finite at 0) of the kept terms plus
    the absent one; the ramp: :math:`|R| \\le z\\,\\mathrm{se}(R)`. Stored as the bound at z = 1
    and the power of z (``zero_upper``, ``zero_upper_power``). None for a Gauss-Markov term (its Tc is
    undefined at 0)."""
    up, power = {}, {}
    a = {c: fit["a"][fit["comps"].index(c)] for c in kept}
    tc = fit["tc"]
    ramp = trend()
    for c in terms:
        if coefs.get(c, 1.0) != 0.0:
            continue
        if c == ramp:
            up[c], power[c] = float(se[ramp]), 1.0
            continue
        if any(is_shaped(x) and component(x).coefficient == c for x in fit["comps"]):
            continue  # a Gauss-Markov term reported as c
        comps = list(kept) + [component_of(c)]
        Bm = wf.basis_matrix(comps, tc)
        S = np.array([a[x] for x in kept]) @ Bm[:-1]
        W = wf.w / S**2
        F = (Bm * W) @ Bm.T
        try:
            var = np.linalg.inv(F)[-1, -1]
        except np.linalg.LinAlgError:
            continue
        if var > 0:
            up[c], power[c] = math.sqrt(math.sqrt(var)) * wf.scale, 0.5
    return {"zero_upper": pd.Series(up, dtype=float), "zero_upper_power": pd.Series(power, dtype=float)}
