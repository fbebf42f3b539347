"""Frequency-domain (Whittle) maximum likelihood of the composite gyro model: the estimators
``whittle`` (:class:`Whittle`) and ``whittle_debiased`` (:class:`WhittleDebiased`).

They are built from:

* :mod:`~avbench.estimators.likelihood.whittle_spectra` -- the terms' spectra, expected periodograms
  and autocovariances;
* :mod:`~avbench.estimators.likelihood.whittle_likelihood` -- the likelihood of a record, with the
  trend slope profiled out, its maximisation (:func:`whittle_fit`) and the spectral fit check;
* :mod:`~avbench.estimators.likelihood.whittle_intervals` -- profile-likelihood intervals and
  evidence, and the bounds of the terms estimated as 0;
* :mod:`avbench.estimators.selection` -- the model-choice components: backward elimination and the
  choice between non-nested models (``elimination``), the chi-bar-squared evidence (``evidence``),
  the boundary-aware interval search and the domain switch (``profile``).

The likelihood
--------------
:math:`\\ell(\\theta) = -\\sum_k w_k[\\log S(\\omega_k;\\theta) + I_k/S(\\omega_k;\\theta)]` over the
Fourier frequencies (Whittle 1953; Percival & Walden 1993, Sec. 6.6), with :math:`S = \\sum_j a_j
S_j` the sum of the exact discrete-time spectra of the generators in :mod:`avbench.noise_models`,
and :math:`I_k` the periodogram after a linear trend is regressed out by frequency-domain GLS
(Hannan 1963): one regression removes the ramp :math:`\\hat R = |\\hat\\beta|/\\Delta t` and makes
the random-walk periodogram exact. The variance of :math:`\\hat\\beta` is exact under the fitted model
(the random walk's drift included). Standard errors are the Cramér-Rao bound of
:func:`avbench.estimators.likelihood.crlb.crlb` at the estimate for the terms kept (the inverse Whittle
information, computed by the same code); R's from the slope's exact variance.

Term selection (settings ``select``, ``criterion``)
---------------------------------------------------
With ``select=True`` the terms in ``terms`` are candidates: backward elimination on a penalised
likelihood :math:`-2\\ell + c\\,p` (:func:`~avbench.estimators.selection.elimination.backward_elimination`).
``criterion="bic"``: :math:`c = \\log n` (Schwarz 1978). ``criterion="lr"``: the 5 % likelihood-ratio
test of each variance being 0, whose null is the chi-bar-squared mixture
:math:`\\tfrac12\\chi^2_0 + \\tfrac12\\chi^2_1` (Self & Liang 1987): :math:`c = 2.706`. A
Gauss-Markov term counts two parameters (its Tc is not identified under the null; the penalty is
an approximation there). The ramp is kept when :math:`\\hat\\beta^2 / \\mathrm{Var}_0 > c` with
:math:`\\mathrm{Var}_0` the variance of :math:`\\hat\\beta` without a ramp (exact, with the random
walk of the full model, even when K itself is dropped): BIC's penalty, or for the LR test the
two-sided :math:`\\chi^2_1` 95 % point 3.841 (the slope's null, 0, is not on a boundary). Dropped
terms are reported as 0; ``conf_int`` gives them the boundary upper bound
(:func:`~avbench.estimators.likelihood.whittle_intervals.zero_bounds`). A term whose variance has Wald
statistic :math:`z \\approx 1/(2\\,\\mathrm{rel.std}(c))` is kept with probability about
:math:`\\Phi(z - \\sqrt{c})`. ``bias="select"``: flicker or Gauss-Markov bias instability, the full
model of lower criterion (non-nested models: the comparison is the criterion's, not a test;
:func:`~avbench.estimators.selection.elimination.choose_by_criterion`), before term selection.

De-biased likelihood (setting ``spectrum="debiased"``)
------------------------------------------------------
Sykulski, Olhede, Guillaumin, Lilly & Early (2019), "The de-biased Whittle likelihood", Biometrika
106(2) (arXiv 1605.06718): :math:`S(\\omega_k)` is replaced by the expected periodogram of a record
of n samples, :math:`\\bar I_k = \\sum_{|\\tau|<n}(1-|\\tau|/n)c(\\tau)e^{-i\\omega_k\\tau}`, one FFT
from each term's autocovariance; the model stays linear in the variances. Reading of the paper,
where it does not say: flicker's autocovariance is that of the likelihood's ideal 1/f spectrum
(minus its variogram; the generator's finite ``tau_max`` is not modelled, as in the plain
likelihood); white noise and the random walk (exact through the trend regression) keep their
spectra; the trend slope is still profiled out of the periodogram (the expected periodogram is that
of the noise, not of the detrended residual). The standard errors (``std_err_``) stay the
Cramér-Rao bound of the exact spectrum.

Profile-likelihood intervals and evidence (setting ``intervals="profile"``)
--------------------------------------------------------------------------
Each candidate term of the full fit gets its profile-likelihood interval on :math:`[0, \\infty)`,
boundary-aware (a term the data cannot resolve gets :math:`[0, \\text{upper}]`; at a true 0 the
statistic follows the chi-bar-squared law, so 0 is covered with probability 97.5 %), and its
evidence: the likelihood ratio of the model without it and that law's p-value
(:func:`~avbench.estimators.likelihood.whittle_intervals.profile_evidence`). ``conf_int()`` returns
these intervals at the 95 % level (other levels: Wald, nested with them). The ramp R keeps a normal
interval :math:`|\\hat R| \\pm z\\,\\mathrm{se}` with se under the full model whose random walk is at
the upper end of its profile interval.

Domain of the variances (setting ``domain``)
--------------------------------------------
``"nonnegative"`` (``whittle``'s default): every variance :math:`\\ge 0`; a term the noise would
take below 0 sits on its floor, and its neighbour absorbs the difference one way only.
``"spectrum"`` (``whittle_debiased``'s default): the maximum over the larger domain where the
variances of Q, N, B, K may be negative as long as the model's expected periodogram (or spectrum)
is positive at every Fourier frequency -- estimates below 0 allowed and truncated only when
reported, as in variance-component estimation (Searle, Casella & McCulloch 1992): a true 0 is an
interior point, so the estimate keeps its asymptotically normal law there instead of the boundary
law. Scored from the non-negative maximum; a Gauss-Markov variance keeps its floor (its Tc is
undefined at 0). Reported: each coefficient :math:`\\sqrt{\\max(a_j, 0)}`, and its profile interval
on :math:`[0, \\infty)` with the other terms profiled over the same domain, :math:`\\hat\\ell` the
maximum of :math:`\\ell_p` over :math:`a \\ge 0` (a term estimated below 0 gets :math:`[0,
\\text{upper}]` and no evidence, LR 0 and p = 1).

Interval domain (setting ``interval_domain``)
---------------------------------------------
``"fit"`` (``whittle``'s default): each term's interval over the fit's domain. ``"switch_steeper"``
(``whittle_debiased``'s default; with ``intervals="profile"`` and ``domain="spectrum"``): a term
whose steeper-spectrum neighbour (Q's N, N's B, B's K) the signed fit puts below 0 by more than
1.96 of its Wald standard errors takes its interval and evidence from the non-negative domain,
every other term keeps the signed domain's
(:func:`~avbench.estimators.selection.profile.steeper_negative_neighbours`): B beside a random walk
estimated far below 0, where the signed domain's profile statistic of B is inflated. The estimates
are the same. The measurements behind it: ``results/README.md``, coverage_defaults.

Model averaging (setting ``averaging``)
---------------------------------------
``"akaike"`` (with ``select=False``): each variance is the average of its estimates over the full
model and every submodel without some of the terms whose absence the data do not rule out (Wald
:math:`z^2` below :func:`~avbench.estimators.selection.averaging.negligible_z2`), each weighted by
its Akaike weight :math:`\\propto e^{-\\mathrm{AIC}/2}`, a dropped term counting 0 (Buckland, Burnham
& Augustin 1997; :mod:`~avbench.estimators.selection.averaging`). ``"bic"``: the same with the
weights :math:`\\propto e^{-\\mathrm{BIC}/2}` (penalty :math:`\\log n` per parameter; Raftery 1995).
``"akaike_kept"``, ``"bic_kept"``: each coefficient averaged over the models that hold its own term,
their weights renormalised (:data:`~avbench.estimators.selection.averaging.RULES`): a term the data
cannot tell from absent is left out of its neighbours' estimates without pulling its own toward 0.
The submodels are fitted over the same domain; a positive combination of valid spectra is valid. A
Gauss-Markov Tc and the trend slope stay the full model's. The intervals stay the full model's
profile-likelihood intervals (valid whatever the true terms); the model choice ``term_weights`` gives
each model's weight. Measured in ``results/random_gyros``.

Where it is not exact
---------------------
* The Whittle likelihood replaces the Toeplitz covariance by a circulant one: ordinates at distinct
  Fourier frequencies are treated as independent with mean :math:`S(\\omega_k)`. No taper is
  applied: for the spectra of this model (white noise with 1/f and 1/f^2 rises at low frequency)
  the untapered periodogram is consistent (Velasco & Robinson 2000 for fractional exponents
  d < 3/4; flicker is d = 1/2, the random walk d = 1 is exact here through the trend regression).
* Flicker: the generator is a finite impulse response (``tau_max``); below f ~ 1/tau_max its
  spectrum flattens, while the likelihood uses the ideal 1/f. With ``tau_max`` >= the record length
  only the first few Fourier frequencies are affected; a finite record of 1/f noise has no
  stationary start either. The expected periodogram of 1/f noise exceeds its spectrum at the lowest
  ordinates (the leakage of a spectrum singular at 0), which the plain likelihood ignores and
  ``spectrum="debiased"`` models.
* Quantization: its spectrum vanishes like :math:`\\omega^2` at low frequency; harmless beside any
  white noise, but Q alone (no N) would make the low-frequency ordinates leakage-dominated.
* The ramp: a deterministic trend regressor, not a spectral parameter; with a short record the
  fitted spectrum's own error makes its standard error somewhat small (the trend and the flicker
  level share the lowest frequencies).
* Gauss-Markov (``bias="gauss_markov"``): B is SPEC's :math:`B_{equiv} = 0.9294\\sigma`. Over the
  band a record resolves, a Gauss-Markov process with Tc beyond the record looks like a random walk
  and one with Tc of a few samples like white noise; flicker is told from Gauss-Markov by the
  curvature of the spectrum across the decades between.
* Short records: the profiled trend slope takes low-frequency power (``reml=True`` gives it back),
  a term near its boundary at 0 trades power with its neighbour (``domain="spectrum"`` removes it),
  and a coefficient is the square root of a variance estimate (Jensen: about -rel.std/2 of a CRLB
  std). Terms forced where they are absent sit on that boundary too. Measured in
  ``results/coverage_true_terms``.
* Selection: intervals after selection ignore the selection step (post-selection inference), which
  is why dropped terms keep the full model's upper bound; near the detection limit the kept terms'
  Wald intervals are too narrow. ``whittle_debiased`` keeps every candidate and gives
  profile-likelihood intervals instead (``results/coverage_defaults``, ``results/random_gyros``).
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from avbench.estimators.allan.fit_check import as_fit_check
from avbench.estimators.base import Estimator, register
from avbench.estimators.likelihood.whittle_intervals import evidence_table, profile_evidence, zero_bounds
from avbench.estimators.likelihood.whittle_likelihood import WhittleFit, spectral_fit_check, whittle_fit
from avbench.estimators.likelihood.whittle_spectra import (component, component_of, components, is_shaped, trend,
                                                           walk)
from avbench.estimators.results import Evidence, FitParts
from avbench.estimators.selection import averaging, choices
from avbench.estimators.selection.elimination import (PENALTY, SLOPE_PENALTY, backward_elimination,
                                                      choose_by_criterion, penalised, wald_drop_candidates)
from avbench.estimators.selection.profile import steeper_negative_neighbours
from avbench.estimators.settings import Boolean, Check, Interval, Options
from avbench.estimators.validation import check_terms
from avbench.noise_models.units import COEFFICIENTS

__all__ = ["Whittle", "WhittleDebiased"]


#: the default candidates: every coefficient ("QNBKR")
_ALL_TERMS = "".join(COEFFICIENTS)
#: the coefficient whose spectrum the setting ``bias`` chooses: flicker, or its shaped (Gauss-Markov) component
_BIAS = "B"


def _admissible(sub) -> bool:
    """A model needs at least one spectral component (any term but the ramp)."""
    return any(x in components() for x in sub)


def _n_par(comps) -> int:
    """The parameters of the components ``comps``: each term's fit parameters (a Gauss-Markov term two)."""
    return sum(len(component(c).fit_parameters) for c in comps)


def _label(c) -> str:
    """The coefficient component ``c`` reports (a Gauss-Markov term reports B)."""
    return component(c).coefficient


def _typed_evidence(table: pd.DataFrame, level: float) -> dict:
    """Each row of the evidence table (:func:`~avbench.estimators.likelihood.whittle_intervals.evidence_table`)
    as an :class:`~avbench.estimators.results.Evidence`."""
    def num(v):
        return math.nan if v is None else float(v)

    return {c: Evidence(lr=num(r["lr"]), p_value=num(r["p_value"]), present=bool(r["present"]),
                        lower=num(r["lower"]), upper=num(r["upper"]), level=float(level))
            for c, r in table.iterrows()}


def _check_whittle_terms(terms) -> None:
    if not set(check_terms(terms)) - {trend()}:
        raise ValueError("terms: expected at least one stochastic term (Q, N, B or K) besides R")


@register("whittle")
class Whittle(Estimator):
    """Whittle maximum likelihood of Q, N, B, K, R (see the module docstring).

    Parameters
    ----------
    terms : str
        Terms modelled (subset of "QNBKR", at least one besides R); with ``select=True``, the candidates.
    bias : {"flicker", "gauss_markov", "select"}
        Spectrum of the bias-instability term: flicker (Kasdin & Walter, the presets' truth) or a
        first-order Gauss-Markov process (B reported as :math:`B_{equiv} = 0.9294\\sigma`); "select"
        fits the full model with each and keeps the one with the lower penalised likelihood (the
        ``criterion``'s, Gauss-Markov counting two parameters), before term selection.
    select : bool
        Choose the terms present among ``terms`` (module docstring). Default True.
    criterion : {"bic", "lr"}
        Selection rule: BIC (default) or the 5 % likelihood-ratio test with the chi-bar-squared null.
    n_starts : int
        Starting values of Tc tried for a Gauss-Markov term (>= 1).
    reml : bool
        Maximise the restricted (residual) likelihood: the profile likelihood minus
        :math:`\\tfrac12\\log\\sum_k w_k|G_k|^2/S_k`, the log of the trend slope's information
        (Patterson & Thompson 1971; Harville 1977). Profiling the slope out takes low-frequency power
        the flicker and random-walk terms should have had; REML gives it back. Default False (the
        plain profile likelihood).
    spectrum : {"plain", "debiased"}
        The model's ordinates: the spectrum (default) or the record's expected periodogram
        (Sykulski et al. 2019; module docstring).
    intervals : {"wald", "profile"}
        Wald intervals from the standard errors (default), or profile-likelihood intervals and
        evidence for every candidate term of the full model (the result's evidence).
    domain : {"nonnegative", "spectrum"}
        Where the variances are maximised: each >= 0 (default), or wherever the model spectrum is
        positive at every Fourier frequency (Q, N, B, K may go below 0; reported truncated at 0, their
        intervals on [0, inf)); see the module docstring, "Domain of the variances".
    interval_domain : {"fit", "switch_steeper"}
        With ``intervals="profile"`` and ``domain="spectrum"``: each term's interval over the fit's
        domain (``"fit"``, the default of :class:`Whittle`), or the non-negative domain's interval and
        evidence for a term whose steeper-spectrum neighbour the signed fit puts below 0 by more than
        1.96 of its standard errors (``"switch_steeper"``, the default of ``whittle_debiased``). The
        estimates are the same.
    averaging : {"none", "akaike", "bic", "akaike_kept", "bic_kept"}
        With ``select=False``: the estimates of the full model (``"none"``, the default of
        :class:`Whittle`), or their average over the submodels without the terms whose absence the data
        do not rule out, weighted by Akaike (``"akaike"``) or Schwarz (``"bic"``) weights, a dropped
        term counting 0, or (``"akaike_kept"``, ``"bic_kept"``) each coefficient averaged over the
        models that hold its own term (module docstring, "Model averaging"). The intervals and
        evidence of Q, N, B, K stay the full model's; the standard errors (the Cramér-Rao bound) and
        the ramp's test are taken at the averaged estimates.

    Attributes
    ----------
    std_err_ : pandas.Series
        Standard errors (SI) from the Whittle information at the estimate (``avbench.estimators.likelihood.crlb``).
    extras_ : dict
        ``terms`` (the terms kept), ``beta`` (trend slope, rad/s per sample), ``tc`` (Gauss-Markov),
        ``full_coefficients`` and ``full_std_err`` (the full model's), ``ramp_z2`` (the ramp's squared
        z-statistic, :math:`\\hat\\beta^2/\\mathrm{Var}_0`, NaN without R in ``terms``) and
        ``bias_models`` (the penalised likelihood of each full model tried). The result holds the
        rest: ``llf``, ``bic``, ``n_iter``, ``converged``, the model choices ``selection`` (the
        criterion of each model visited) and ``bias_model`` (the bias-instability spectrum used), and
        with ``intervals="profile"`` each term's evidence.

    Examples
    --------
    >>> import numpy as np
    >>> from avbench.noise_models import Gyro, AngleRandomWalk, RateRandomWalk
    >>> g = Gyro(dt=0.1, terms=[AngleRandomWalk(N=1e-3), RateRandomWalk(K=1e-5)])
    >>> est = Whittle(terms="NK", select=False).fit(g.simulate(100_000, np.random.default_rng(3)), 0.1)
    >>> bool(abs(est.coefficients_["N"] / 1e-3 - 1) < 4 * est.std_err_["N"] / 1e-3)
    True
    """

    #: ``beta`` is the fitted ramp's slope per sample (the rate's unit), not an AV coefficient
    diagnostic_units = {"beta": 1}

    parameter_constraints = {
        "terms": [Check(_check_whittle_terms, "a non-empty subset of Q, N, B, K, R without repeats with at least "
                                              "one of Q, N, B, K, e.g. 'NBK'")],
        "bias": [Options("flicker", "gauss_markov", "select")],
        "select": [Boolean()],
        "criterion": [Options(*PENALTY)],
        "n_starts": [Interval(int, 1, None)],
        "reml": [Boolean()],
        "spectrum": [Options("plain", "debiased")],
        "intervals": [Options("wald", "profile")],
        "domain": [Options("nonnegative", "spectrum")],
        "interval_domain": [Options("fit", "switch_steeper")],
        "averaging": [Options("none", *averaging.RULES)],
    }

    def __init__(self, *, terms=_ALL_TERMS, bias="flicker", select=True, criterion="bic", n_starts=4, reml=False,
                 spectrum="plain", intervals="wald", domain="nonnegative", interval_domain="fit", averaging="none"):
        self.terms = terms
        self.bias = bias
        self.select = select
        self.criterion = criterion
        self.n_starts = n_starts
        self.reml = reml
        self.spectrum = spectrum
        self.intervals = intervals
        self.domain = domain
        self.interval_domain = interval_domain
        self.averaging = averaging

    def _fit(self, rate, dt):
        # every setting is declared and none depends on another: a setting that applies only with another
        # (interval_domain with intervals="profile" and domain="spectrum") is without effect otherwise
        terms = check_terms(self.terms)
        wf = WhittleFit(rate, dt, reml=self.reml, debiased=self.spectrum == "debiased")
        signed = self.domain == "spectrum"
        n = rate.size
        pen = PENALTY[self.criterion](n)

        def n_par(f):
            return _n_par(f["comps"])

        def bic(f):
            return penalised(f["loglik"], n_par(f), pen)

        # the bias-instability spectrum: as set, or (bias="select") the better penalised full model
        bias = _BIAS
        shapes = [self.bias]
        if self.bias == "select":
            shapes = ["flicker", "gauss_markov"] if bias in terms else ["flicker"]
        fulls = {}
        for shape in shapes:
            # the coefficients' components; B's with a shape parameter (Gauss-Markov) for bias="gauss_markov"
            comps = [component_of(c, shaped=(shape == "gauss_markov" and c == bias)) for c in terms if c != trend()]
            fulls[shape] = whittle_fit(wf, comps, self.n_starts, signed=signed)
        bias_choice = choose_by_criterion(fulls, bic)
        shape = bias_choice.chosen
        full = fulls[shape]
        fits = {tuple(full["comps"]): full}
        chosen = full

        if self.select:
            def refit(cur, sub):
                warm = {x: cur["a"][cur["comps"].index(x)] for x in sub}
                warm["tc"] = cur["tc"]
                return whittle_fit(wf, sub, self.n_starts, warm=warm, signed=signed)

            elimination = backward_elimination(
                full, terms=lambda f: f["comps"], criterion=bic,
                candidates=lambda f: wald_drop_candidates(f["comps"], f["detail"]["info"], f["absent"], pen),
                refit=refit, admissible=_admissible)
            fits, chosen = elimination.visited, elimination.chosen
        weights = None
        if self.averaging != "none" and not self.select:
            rule = averaging.RULES[self.averaging]
            chosen, weights = self._averaged(wf, full, n_par, signed, rule, rule.penalty(n))
        # terms at their floor are absent
        kept = [c for c in chosen["comps"] if c not in chosen["absent"]]
        full_kept = [c for c in full["comps"] if c not in full["absent"]]
        walker = walk(full_kept)
        k_full = math.sqrt(full["a"][full["comps"].index(walker)]) * wf.scale if walker is not None else 0.0
        coefs, se, tr, ramp_z2 = self._report(wf, chosen, kept, terms, select=self.select, k_drift=k_full,
                                              pen=SLOPE_PENALTY[self.criterion](n))
        if chosen is full:
            full_coefs, full_se = coefs, se
        else:
            full_coefs, full_se, _, _ = self._report(wf, full, full_kept, terms, select=False, k_drift=k_full)
        zeros = zero_bounds(wf, chosen, kept, terms, coefs, se)
        extras = {
            "terms": "".join(_label(c) for c in kept) + (trend() if tr else ""),
            "beta": float(chosen["detail"]["beta"] * wf.scale),
            "tc": chosen["tc"],
            "full_std_err": full_se,
            "full_coefficients": pd.Series(full_coefs, dtype=float).reindex(list(COEFFICIENTS)),
            "ramp_z2": ramp_z2,
            "bias_models": bias_choice.criteria,
        }
        if bias_choice.weights is not None:  # bias="select": the full models' weights exp(-criterion/2), normalised
            extras["bias_weights"] = bias_choice.weights
        n_params = _n_par(kept) + 1
        check = spectral_fit_check(wf, chosen, n_params)
        if "fit_check" in check:
            extras["fit_check"] = check["fit_check"]
        evidence = {}
        if self.intervals == "profile":
            found = self._evidence(wf, full, coefs, se, ramp_z2, trend() in terms)
            evidence = _typed_evidence(found["evidence"], found["evidence_level"])
        failure = None
        if not chosen["converged"]:
            failure = f"Fisher scoring did not converge in {chosen['n_iter']} iterations"
        made = [choices.bias_model(shape, bias_choice.criteria if len(fulls) > 1 else None, bias_choice.weights),
                choices.criteria({"".join(k): float(bic(v)) for k, v in fits.items()})]
        if weights is not None:
            made.append(choices.term_weights({"penalty": rule.penalty(n), "models": weights}))
        llf, k = float(chosen["loglik"]), n_par(chosen)
        parts = FitParts(fit_check=as_fit_check(check), evidence=evidence, choices=tuple(made), failure=failure,
                         zero_bounds=(zeros["zero_upper"], zeros["zero_upper_power"]), std_err=se,
                         llf=llf, aic=penalised(llf, k, 2.0), bic=penalised(llf, k, math.log(n)),
                         converged=bool(chosen["converged"]), n_iter=int(chosen["n_iter"]))
        return coefs, {}, extras, parts

    def _averaged(self, wf, full, n_par, signed, rule, penalty):
        """The full fit with its variances replaced by their average by ``rule`` (weighted by the
        criterion with ``penalty`` per parameter) over the
        submodels without some of the terms whose absence the data do not rule out
        (:mod:`~avbench.estimators.selection.averaging`; the trend slope and a Gauss-Markov Tc stay
        the full model's), and the weights by model (its terms joined, e.g. ``"NBK"``)."""
        comps = full["comps"]
        k = len(comps)
        a = np.asarray(full["a"], dtype=float)
        try:
            var = np.diag(np.linalg.inv(full["detail"]["info"]))[:k]
        except np.linalg.LinAlgError:
            var = np.full(k, np.nan)
        with np.errstate(divide="ignore", invalid="ignore"):
            # the information is in the variances at a signed maximum, in their logarithms otherwise
            z2 = np.where(var > 0, a**2 / var if signed else 1.0 / var, np.nan)
        z2 = np.where([c in full["absent"] for c in comps], 0.0, z2)
        cands = averaging.droppable(comps, z2, penalty)
        models = {tuple(comps): full}
        for sub in averaging.submodels(comps, cands, admissible=_admissible):
            if tuple(sub) not in models:
                warm = {x: a[comps.index(x)] for x in sub}
                warm["tc"] = full["tc"]
                models[tuple(sub)] = whittle_fit(wf, sub, self.n_starts, warm=warm, signed=signed)
        w = averaging.penalised_weights({m: (f["loglik"], n_par(f)) for m, f in models.items()}, penalty)
        params = {m: dict(zip(f["comps"], np.asarray(f["a"], dtype=float).tolist())) for m, f in models.items()}
        mean = rule.mean(params, w, comps)
        a_bar = np.array([mean[c] for c in comps])
        absent = [c for c in comps if c in full["absent"] or mean[c] <= 0]
        named = {"".join(_label(c) for c in m): float(v) for m, v in w.items()}
        return dict(full, a=a_bar, absent=absent), named

    #: level of the profile-likelihood intervals computed by ``fit`` (``intervals="profile"``)
    PROFILE_LEVEL = 0.95

    def _evidence(self, wf, full, coefs, se, ramp_z2, has_r):
        """``evidence`` (:func:`~avbench.estimators.likelihood.whittle_intervals.evidence_table`) from
        the profile evidence of the full model over its domain, or (``interval_domain="switch_steeper"``)
        over the non-negative domain for the terms whose steeper neighbour the signed fit puts below
        0 beyond its noise."""
        ev, _ = profile_evidence(wf, full, self.PROFILE_LEVEL)
        if self.interval_domain == "switch_steeper" and full.get("nonneg") is not None:
            switched = steeper_negative_neighbours(full["comps"], full["a"], full["detail"]["info"])
            if switched:
                ev_nn = profile_evidence(wf, full["nonneg"], self.PROFILE_LEVEL)[0]
                ev = {c: (ev_nn[c] if c in switched and c in ev_nn else e) for c, e in ev.items()}
        df = evidence_table(wf, full, ev, coefs, se, ramp_z2, has_r, self.PROFILE_LEVEL)
        return {"evidence": df, "evidence_level": self.PROFILE_LEVEL}

    def conf_int(self, level=0.95, conservative=False) -> pd.DataFrame:
        """With ``intervals="profile"`` and the default two-sided 95 % level: the profile-likelihood
        intervals of the terms' evidence (``parts_.evidence``: every candidate term, valid without knowing the
        true set); otherwise the base class's Wald intervals, nested with the profile ones so that
        intervals widen with the level: at a higher level each holds the 95 % profile interval, at a
        lower one it lies within it (the profile interval can be the wider where Wald is not valid: a
        term at its boundary, the ramp with the random walk at its bound)."""
        out = super().conf_int(level, conservative)
        if not self.parts_.evidence or conservative:
            return out
        for c, ev in self.parts_.evidence.items():
            if np.isfinite(self.coefficients_[c]):
                lo, hi, at = ev.lower, ev.upper, ev.level
                if math.isclose(level, at):
                    out.loc[c, ["lower", "upper"]] = lo, hi
                elif level > at:
                    out.loc[c, "lower"] = np.fmin(out.loc[c, "lower"], lo)
                    out.loc[c, "upper"] = np.fmax(out.loc[c, "upper"], hi)
                else:
                    out.loc[c, "lower"] = np.fmax(out.loc[c, "lower"], lo)
                    out.loc[c, "upper"] = np.fmin(out.loc[c, "upper"], hi)
        return out

    def _report(self, wf, fit, kept, terms, select, k_drift=0.0, pen=None):
        """Coefficients (SI) and standard errors (crlb at the estimate; R: the exact variance of the
        slope, :meth:`~avbench.estimators.likelihood.whittle_likelihood.WhittleFit.trend_variance`).

        The ramp test uses the random-walk drift of the *full* model (``k_drift``): a random walk
        too weak to be kept still drifts, and that drift must not be read as a ramp."""
        from avbench.estimators.likelihood.crlb import crlb
        from avbench.noise_models import Gyro

        s, dt, n = wf.scale, wf.dt, wf.n
        val = {c: math.sqrt(fit["a"][fit["comps"].index(c)]) * s for c in kept}
        coefs = {c: 0.0 for c in terms}
        built = []
        for c, v in val.items():  # each term at its fitted amplitude (and Tc); a flicker term's memory 10 T
            cls = component(c)
            coefs[cls.coefficient] = cls.coefficient_per_amplitude * v
            built.append(cls.from_fit((v, fit["tc"]) if is_shaped(c) else (v,), tau_max=max(10 * n * dt, 1.0)))
        se = pd.Series(math.nan, index=list(COEFFICIENTS), dtype=float)
        ramp = trend()
        if built:
            bound = crlb(Gyro(dt=dt, terms=built), n)
            for c in bound.index:
                if c in coefs and c != ramp and np.isfinite(bound[c]):
                    se[c] = bound[c]
        keep_r, z2 = False, math.nan
        if ramp in terms:
            d = fit["detail"]
            walker = walk(val)
            a_walk = max(val[walker] if walker is not None else 0.0, k_drift) ** 2 / s**2
            var_r = wf.trend_variance(fit["comps"], fit["a"], fit["tc"], a_walk=a_walk) * s**2 / dt**2
            r_hat = abs(d["beta"]) * s / dt
            z2 = r_hat**2 / var_r
            keep_r = (not select) or z2 > (math.log(n) if pen is None else pen)
            coefs[ramp] = r_hat if keep_r else 0.0
            se[ramp] = math.sqrt(var_r)
        return coefs, se, keep_r, z2


@register("whittle_debiased")
class WhittleDebiased(Whittle):
    """The de-biased Whittle likelihood with every candidate term kept and profile-likelihood
    intervals: :class:`Whittle` with ``spectrum="debiased"`` (Sykulski et al. 2019, Biometrika
    106(2): the expected periodogram of the record replaces the spectrum), ``select=False`` and
    ``intervals="profile"`` (each term's interval on [0, inf) and its evidence, the likelihood ratio
    of dropping it with its chi-bar-squared p-value, in the result's evidence),
    ``domain="spectrum"`` (the maximum over variances that may go below 0 while the expected
    periodogram stays positive, each reported truncated at 0: no one-way trade between a term on
    its boundary and its neighbour; module docstring, "Domain of the variances") and
    ``interval_domain="switch_steeper"`` (a term whose steeper-spectrum neighbour the signed fit puts
    below 0 beyond its noise -- B beside a barely resolved or absent random walk -- takes its interval
    from the non-negative domain; module docstring, "Interval domain"). Every setting of
    :class:`Whittle` applies; only the defaults differ. ``averaging="bic_kept"`` (each coefficient
    averaged by BIC weight over the submodels holding its term) is within 1.25 x the Cramér-Rao bound
    on more of ``results/random_gyros``' gyros (Q 0.80, N 0.71, B 0.83, K 0.76 against 0.78, 0.62,
    0.76, 0.70) but biased where Q is near its detection limit (20 min of CRG20: N +1.33 CRLB std), so
    the full model's estimates stay the default; the intervals are the same either way."""

    def __init__(self, *, terms=_ALL_TERMS, bias="flicker", select=False, criterion="bic", n_starts=4, reml=False,
                 spectrum="debiased", intervals="profile", domain="spectrum", interval_domain="switch_steeper",
                 averaging="none"):
        super().__init__(terms=terms, bias=bias, select=select, criterion=criterion, n_starts=n_starts,
                         reml=reml, spectrum=spectrum, intervals=intervals, domain=domain,
                         interval_domain=interval_domain, averaging=averaging)
