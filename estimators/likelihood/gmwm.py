"""Generalized Method of Wavelet Moments (GMWM; Guerrier, Skaloud, Stebler & Victoria-Feser, JASA 2013).

The Haar wavelet variance of the record at dyadic scales is matched to the wavelet variance implied
by a composite latent model. For the Haar filter at scale tau the (maximal-overlap) wavelet variance
is half the overlapping Allan variance at the same tau (SPEC; it agrees term by term with the Haar
wavelet variances nu^2 = sigma^2/tau_j (white), (tau_j^2 + 2) gamma^2 / (12 tau_j) (random walk),
tau_j^2 omega^2 / 16 (drift) of the SMAC group's ``wv`` package, with tau_j = 2m samples),

.. math:: \\nu^2(\\tau) = \\sigma^2_{AV}(\\tau)/2 ,

so the GMWM estimator (Guerrier et al. 2013, the GMWM criterion of their Sec. 3; the equation
numbers of that paper were not available to check here)

.. math::

    \\hat\\theta = \\arg\\min_\\theta\\; (\\hat\\nu - \\nu(\\theta))^T\\,\\Omega^{-1}\\,(\\hat\\nu - \\nu(\\theta))

is computed here on the overlapping AV at octave taus (``avbench.estimators.allan.variance.allan_variance``); the
factor 1/2 cancels. :math:`\\nu(\\theta)` is the *exact discrete-time* AV of the candidate model:
the sum of its noise terms' exact AVs (:mod:`avbench.estimators.likelihood._gmwm_model`).

Weighting matrix
----------------
Efficient GMM needs :math:`\\Omega`, the covariance of :math:`\\hat\\nu`. For a Gaussian process
the overlapping AV at cluster size m is :math:`\\frac12\\overline{d_t^2}` with :math:`d = h_m * \\omega`,
:math:`|H_m(\\omega)|^2 = 4\\sin^4(m\\omega/2)/(m^2\\sin^2(\\omega/2))`, and (Isserlis; Percival &
Walden 2000, Sec. 8.3 for one scale)

.. math::

    \\mathrm{Cov}(\\hat\\sigma^2_j, \\hat\\sigma^2_k) \\approx \\frac{1}{2\\sqrt{M_jM_k}}\\,
    \\frac1\\pi\\int_0^\\pi |H_j|^2|H_k|^2\\,S(\\omega)^2\\,d\\omega ,

with :math:`M_j = n - 2m_j + 1` terms and :math:`S` the model spectrum (``Gyro.psd``). This is the
asymptotic covariance of the wavelet variances (Guerrier et al. 2013, their asymptotic-normality
result; Percival 1995 for one scale) evaluated *parametrically* at a first-step
estimate (two-step GMM), rather than by their non-parametric spectral estimate at frequency zero of
the squared wavelet coefficients. Why: the parametric form is smooth and never singular, costs one
FFT-grid integral instead of a bootstrap, and uses the full inter-scale correlation, which for
random-walk-like terms is large (adjacent octaves correlate at 0.5-0.9) and is what the diagonal
chi^2/edf approximation ignores. The first step uses the diagonal weights
:math:`\\mathrm{edf}_j/(2\\hat\\sigma_j^4)` of the AV engine.

Latent models
-------------
The setting ``model`` names the terms (:mod:`avbench.noise_models.latents`): ``WN`` white rate (N),
``QN`` quantization (Q), ``GM`` first-order Gauss-Markov (sigma, Tc; reported as B through SPEC's
:math:`B_{equiv} = 0.9294\\sigma`), ``FL`` flicker bias instability (B itself; beyond Guerrier et al.
2013, whose latents are all state-space processes: its theoretical AV is the exact discrete curve of
the Kasdin-Walter generator, :class:`avbench.noise_models.BiasInstability`, with filter memory
``tau_max`` = twice the record as in the presets, so that the plateau holds to the longest usable
tau), ``RW`` rate random walk (K), ``DR`` deterministic drift / rate ramp (R). ``GM`` and ``FL`` are
alternatives for B (not both). Two latents of real sensors (beyond Guerrier et al. 2013): ``FW`` white
rate noise seen through the sensor's first-order low-pass filter (N, tf;
:class:`avbench.noise_models.FilteredWhiteNoise` with ``tc=tf``: the first octaves below the white
line are modelled instead of dropped), an alternative to ``WN`` (not both); ``SN`` sinusoidal noise
(amplitude A, frequency f0; :class:`avbench.noise_models.Sinusoidal`, IEEE Std 952-1997 Annex C),
which reports no coefficient. The AV covariance (weights, standard errors, the fit check) includes
the line's cross term with the rest of the spectrum
(:func:`avbench.estimators.allan.covariance.av_covariance`). ``RS`` a resonance, band-pass
Gauss-Markov noise (sigma, f0, tc; :class:`avbench.noise_models.Resonance`: a lightly damped mode's
noise, no power at f = 0, no coefficient). Each term states its parameters, their box and its
starting values (:class:`avbench.noise_models.term_base.NoiseTerm`); the fit loops over them.

Model choice
------------
The choices GMWM makes on the record are components of :mod:`avbench.estimators.selection`: the
shortest scale fitted (``min_m``, :mod:`~avbench.estimators.selection.scales`), a sinusoid where the
record has a spectral line (``lines="auto"``, :mod:`~avbench.estimators.selection.lines`), a resonance
where a band stands out of the spectrum (``resonance="auto"``,
:mod:`~avbench.estimators.selection.resonance`), the evidence between a Gauss-Markov and a flicker
bias instability (``bias_evidence``, :mod:`~avbench.estimators.selection.bias_model`), and the bounds
of coefficients the fit does not resolve (:mod:`~avbench.estimators.selection.bounds`). With ``min_m="adequate"`` the
shortest scale is never beyond the record's white region (:func:`~avbench.estimators.selection.scales.white_reach`); where that
region is short (an accelerometer's, between its filter and the set-up's 0.5 Hz line) the intervals hold each
cut-off within it the record accepts (``extras_["scale_alternatives"]``, :meth:`Estimator.conf_int`).

Solver
------
Parameters are optimised on their logarithms (positivity) by the trust-region reflective least
squares of scipy's ``least_squares`` (method "trf"), iterated step for step without scipy's per-call
machinery (:func:`avbench.estimators.likelihood._trf.trf_bounds`), from several automatic starts,
with the analytic Jacobian of the model's exact AV
(:class:`avbench.estimators.likelihood._gmwm_model.LatentAV`), and solved to the optimum
(:func:`avbench.estimators.likelihood.solve.solve`, tolerances 1e-15): a coefficient the data cannot resolve
lies along a flat direction of the criterion, where looser stopping rules end at a point set by the record's
last bits rather than by the criterion. A solve still running after a few hundred evaluations is usually
creeping toward a bound along a direction whose effect vanishes (a term the data drive to 0, a filter time
constant far below dt, a resonance's damping time beyond the record's scales): the parameter is settled on
that bound, or the solve restarted there at its evaluation limit, and the fit is reported converged when it
then is (``extras_["stop_reason"]``; ``failure`` only when not).
"""

from __future__ import annotations

import functools
import math
from typing import NamedTuple

import numpy as np
from scipy.linalg import cho_factor

from avbench.estimators.allan.covariance import av_covariance
from avbench.estimators.allan.fit_check import as_fit_check, assess_fit
from avbench.estimators.results import Alternative, FitCheck, FitParts, extras_of
from avbench.estimators.selection import choices
from avbench.estimators.allan.variance import _noise_codes_from_slope, allan_variance
from avbench.estimators.base import Estimator, register
from avbench.estimators.likelihood._gmwm_model import LatentAV, log_bounds, log_starts, report
from avbench.estimators.likelihood._trf import lower_triangular_solver
from avbench.estimators.likelihood.solve import solve as _solve
from avbench.estimators.selection import bias_model, bounds, shared
from avbench.estimators.validation import check_variance_seen
from avbench.estimators.selection.lines import choose_line, frequency_at_bound, sinusoid_hint
from avbench.estimators.selection.resonance import band_seen, choose_resonance, resonance_box, resonance_hint
from avbench.estimators.selection.scales import (ScaleChoice, choose_scales, cutoffs, reach_binds, shorter_adequate,
                                                 white_reach)
from avbench.estimators.settings import Boolean, Check, Interval, NoneValue, Options, Relation
from avbench.estimators.threads import one_blas_thread
from avbench.noise_models.latents import (  # noqa: F401  (LATENTS, build_gyro: importable from here)
    LATENT_TERMS,
    LATENTS,
    build_gyro,
    n_parameters,
    param_index,
    parse_model,
    white_latent,
)

__all__ = ["GMWM", "GMWMFiltered", "LATENTS", "REAL_SENSOR_MODEL", "WaveletVariance", "parse_model", "build_gyro"]

#: :class:`~avbench.estimators.likelihood._gmwm_model.LatentAV` by the name studies and tests import
_LatentAV = LatentAV

#: half-width, in the log of the value, of the box that holds a parameter fixed by a setting (``filter_tf``):
#: wider than the solver's clip into the box (1e-9), far below anything a coefficient shows
HELD_WIDTH = 1e-8

#: GMWM's latent model of a real sensor's gyro or accelerometer (:class:`GMWMFiltered`, and the despiked
#: GMWM of :mod:`avbench.estimators.robust.gmwm`): white noise through the sensor's first-order filter,
#: a Gauss-Markov bias instability, a rate random walk; with ``lines="auto"`` and ``min_m="adequate"``
REAL_SENSOR_MODEL = "FW+GM+RW"

#: the engine's code for flicker FM (:func:`avbench.estimators.allan.variance._noise_codes_from_slope`)
_FLICKER_FM = 2


def first_step_edf(tau, avar, J, edf) -> np.ndarray:
    """The engine's edf as the first step's weights use it: a first scale whose AV is flat (the engine
    reads its slope as flicker FM: the sensor's low-pass filter holding the curve below the white-noise
    line) counts as one degree of freedom, i.e. it hardly weighs in the start.

    Why: the first step only chooses the basin the model-weighted second step starts in. On real
    records two basins compete, a Gauss-Markov term with the bias instability's correlation time and
    one that takes the filter's short-time correlation (tc ~ 0.05 s, reporting a B about twice the
    other's); weighted with its full edf (~0.9 n), the flat first octave pulls the start into the
    second."""
    edf = np.array(edf, dtype=float)
    if edf.size and _noise_codes_from_slope(np.asarray(tau, float), np.asarray(avar, float), np.asarray(J))[0] == _FLICKER_FM:
        edf[0] = 1.0
    return edf


class WaveletVariance(NamedTuple):
    """The AV values a :class:`GMWM` matches, and how to read them.

    ``tau, avar, m, edf``: octave taus (s), AV values, cluster sizes, engine edf as the first step
    weighs it (:func:`first_step_edf`). ``cov_scale``: factor by which their covariance exceeds the
    classical one (1 for the classical AV). ``white_gain``: None, or per tau the factor by which this AV estimator sees the
    white (ARW) part of the process, :math:`N^2/\\tau` (the model matched is then the exact AV plus
    ``(white_gain - 1) N^2 / tau``; for ``FW`` exact beyond the filter, approximate within it, where a
    left-out sample takes less information with it than the gain assumes). ``reference_is_classical``:
    the poor-fit check compares the fit with the classical AV (else with these values). ``diagnostics``:
    extra entries for the estimator's ``extras_``.
    """

    tau: np.ndarray
    avar: np.ndarray
    m: np.ndarray
    edf: np.ndarray
    cov_scale: float = 1.0
    white_gain: np.ndarray | None = None
    reference_is_classical: bool = True
    diagnostics: dict | None = None


def _alternative_units(min_m) -> dict:
    """How an entry of ``extras_["scale_alternatives"]`` scales with the record's unit."""
    return {"coefficients": 1, "std_err": 1}


#: ``model``'s grammar, as a declared setting reads it
_MODEL = (f"a latent model: names from {', '.join(LATENT_TERMS)} joined by '+' (e.g. 'WN+GM+RW') or a list of "
          "them, without repeats, at most one term per coefficient")


def _held_filter_in_model(filter_tf, model) -> None:
    """``filter_tf`` holds the time constant of ``FW``, which the model must have (a ValueError naming it)."""
    if filter_tf is not None and "FW" not in parse_model(model):
        raise ValueError(f"filter_tf: holds the filter latent FW's time constant, but model {model!r} "
                         f"has no FW (e.g. model='FW+GM+RW')")


@register("gmwm")
class GMWM(Estimator):
    """Generalized method of wavelet moments on the overlapping AV (Guerrier et al. 2013), two-step GMM.

    Parameters
    ----------
    model : str or list of str
        Latent model, e.g. ``"WN+GM+RW"`` (default) or ``["QN", "WN", "GM"]``
        (:func:`avbench.noise_models.latents.parse_model`).
    min_clusters : int
        Octave taus with fewer than this many clusters floor(n/m) are not used (default 8: the
        Gaussian large-M covariance is poor at the last octaves).
    min_m : "auto", "adequate" or int
        Octave cluster sizes below this are not used (:mod:`avbench.estimators.selection.scales`).
        ``"auto"`` (default): GMWM chooses its shortest scale itself. Real sensors low-pass filter their
        output, which bends the first octaves away from every latent model without a filter term: with
        all octaves a Gauss-Markov term fits the filter (Tc ~ dt) and reports a B several times too
        large. The rule: fit on all usable octaves, then on all but the shortest, and so on; the shortest
        scale is dropped while the difference of the two J statistics (the difference-in-Hansen / C test
        of Eichenbaum, Hansen & Singleton 1988) rejects at level
        :data:`~avbench.estimators.selection.scales.SCALE_TEST_LEVEL` (0.001); the first scale that is not
        rejected is kept, with every longer one. A model that misses the curve in the middle is not
        rescued this way: it stays on all scales and is flagged by the poor-fit check. An integer fixes
        the shortest cluster size (1: all octaves, the GMWM of Guerrier et al. 2013 as written;
        :class:`avbench.estimators.likelihood.mle.MLE` starts from a GMWM fit on the scales its block
        means resolve). ``"adequate"``: the shortest cut-off whose own fit is not rejected by Hansen's J
        test at that level, cut-offs tried from the shortest up, keeping at least half of the usable
        scales (the model must explain the longer half of the curve); if none is, the ``"auto"`` choice.
        It differs from ``"auto"`` only where the all-scale fit is rejected, i.e. where the model misses
        the first octaves over more than one scale; on a record the model describes the all-scale fit
        passes with probability 1 - 0.001 and the choice, and the poor-fit check's false-alarm rate, are
        those of all scales. The scales it drops are the sensor's front end as far as this model can tell
        and are reported (``min_m``, ``scale_choice``), not explained. ``"adequate"`` keeps the record's white
        noise in the fit: no cut-off beyond the first stretch of octaves where the AV falls nearly as 1/tau
        (:func:`~avbench.estimators.selection.scales.white_reach`; beyond it N would be read off the bias
        region, where the filter term trades with the other terms); where that stops it short and no cut-off
        within it is adequate, the one Hansen's J rejects least is taken. ``"auto"`` has no such limit: it is
        the choice of the simulated studies' GMWM, whose committed results it reproduces (with the limit, the
        GMWM rows of two flicker gyros of ``grand_comparison`` move: N closer to the truth, K further).
    weighting : {"model", "diagonal"}
        "model" (default): two-step efficient GMM with the parametric covariance
        :func:`av_covariance`; "diagonal": stop after the first step (edf weights).
    n_starts : int
        Number of starting values of Tc tried in the first step (log-spaced across the tau range).
    lines : {"model", "auto"}
        "model" (default here): the latents of ``model`` and no others. "auto": a sinusoid ``SN`` is
        added when the record's strongest spectral line passes the test for a hidden periodicity of
        :mod:`avbench.estimators.selection.lines` at level
        :data:`~avbench.estimators.selection.lines.LINE_TEST_LEVEL` (0.001) at a frequency the usable
        taus see; the model choice ``line_test`` says what was found and chosen. With ``SN`` in the model
        (given or added) and such a line found, the sinusoid is started at the line (frequency and
        amplitude) instead of at the eight strongest bumps of the AV curve, and its frequency stays
        within :data:`~avbench.estimators.selection.lines.LINE_FREQUENCY_FACTOR` of the line's
        (``line_test["f0_at_bound"]``: it ended on that bound).
    resonance : {"model", "auto"}
        "model" (default here): no resonance beyond ``model``'s. "auto": where the model drops scales
        (its chosen shortest cut-off is not the first usable one), a resonance ``RS`` is tried when a
        band of the record's spectrum stands out of its surroundings, and kept at the shortest cut-off
        below the model's own that Hansen's J does not reject keeping the longer half of the scales, that
        sees the band and whose fit passes the poor-fit check; else the model without it
        (:mod:`avbench.estimators.selection.resonance`). the model choice ``resonance_test``: the band
        (``band_f0``, ``prominence``, ``band_p_value``), each cut-off tried with its fit-check p-value,
        whether RS was included, the fitted ``sigma, f0, tc``, and the two fits' J on the same scales
        with the chi^2(3) p-value of their difference (indicative only: f0 and tc are undefined without
        the term). On a record the model without it fits at every scale nothing is tried.
    bias_evidence : bool
        False (default here). True: the record's evidence between a Gauss-Markov and a flicker bias
        instability, the model choice ``bias_evidence`` (:mod:`avbench.estimators.selection.bias_model`:
        the same model with GM and FL exchanged, on the same scales, GMM-AIC weights); the reported B is
        the model's own, and unless the evidence decisively favours it :meth:`conf_int` widens each interval
        to hold the other model's (:func:`~avbench.estimators.selection.bias_model.held_alternative`).
    fit_covariance : {"model", "record"}
        The covariance the final poor-fit check and the standard errors take for the AV values. "model" (default
        here): the stationary model's (:func:`av_covariance`). "record": each value's variance from the record's
        batches where they show it larger than the model allows
        (:func:`~avbench.estimators.allan.fit_check.record_variance_factor`: a sensor whose noise moves during the
        record), with the model's correlation between scales; the check's reference is then the weighted chi^2 of
        a fit weighted by the model covariance, and the standard errors are the GMM sandwich
        :math:`H^{-1}G^T\\Omega^{-1}\\Omega_r\\Omega^{-1}GH^{-1}`, :math:`H = G^T\\Omega^{-1}G` (Hansen 1982; with
        the record's long-run covariance as GMWM's asymptotic theory has it, Guerrier et al. 2013), each
        coefficient's standard error (and the alternatives' that :meth:`conf_int` unions) multiplied by the ratio
        of its sandwich to its model standard error where that exceeds 1 (``extras_["record_se_factor"]``).
        Two more readings follow the record's own variability: the bounds of terms the record does not resolve take
        each AV value's edf over its variance factor (:meth:`_bound_edf`), and where the fit misses the curve by
        more than the check's reference allows (its statistic above the reference's mean) every standard error is
        multiplied by the Birge ratio (:meth:`_dispersion`, ``extras_["dispersion"]``). Their measurement on
        the ADIS16405 accelerometers' 30-minute slices: ``results/real/accelerometers``. The fit itself (weights, Hansen's J of the scale
        choice, the resonance's acceptance) keeps the model covariance. Where the record shows no excess and the
        fit no misfit beyond its reference the two are the same.
    filter_tf : float or None
        None (default): the filter latent ``FW``'s time constant is fitted. A number (s): the sensor's
        front-end filter is known (a datasheet: a first-order low-pass of -3 dB bandwidth f has
        tf = 1 / (2 pi f)), and ``FW``'s tf is held at it: one parameter fewer (Hansen's J and the fit check
        count it so), no standard error. Needs ``FW`` in ``model``. the model choice ``filter_held`` (``tf``)
        says so, and ``avbench estimate`` prints it.

    Attributes
    ----------
    extras_ : dict
        ``tau``, ``avar``, ``fitted_avar``, ``J_stat`` (Hansen's J = the minimised objective, ~
        chi^2 with ``dof`` degrees of freedom under the model), ``dof``, ``scale_choice`` (for
        ``min_m="auto"``: each cut-off tried with its J) and the arrays of the poor-fit check of
        :mod:`avbench.estimators.allan.fit_check` (``fit_check``; with ``fit_covariance="record"`` also
        ``fit_check["record_factor"]``, each scale's variance factor, ``record_se_factor``, the
        coefficients' standard-error factors where above 1, and ``dispersion``, the Birge ratio where the
        misfit exceeds its reference's mean). The result holds the fitted latent
        parameters (SI), the GMM asymptotic standard errors (:math:`(D^T\\Omega^{-1}D)^{-1}`), the
        coefficients the fit does not resolve with their bounds (:mod:`avbench.estimators.selection.bounds`),
        the fit check and the model choices (``min_m``, the shortest cluster size used, among them).

    Examples
    --------
    >>> import numpy as np
    >>> from avbench.noise_models import Gyro, AngleRandomWalk, RateRandomWalk
    >>> g = Gyro(dt=0.1, terms=[AngleRandomWalk(N=1e-3), RateRandomWalk(K=1e-5)])
    >>> x = g.simulate(200_000, np.random.default_rng(3))
    >>> est = GMWM(model="WN+RW").fit(x, 0.1)
    >>> bool(abs(est.coefficients_["N"] / 1e-3 - 1) < 0.05)
    True
    """
    round_off_amplified = True  # an optimiser's end point (Estimator.round_off_amplified)

    uses_allan_variance = True

    #: what each setting accepts (:mod:`avbench.estimators.settings`), and the relation between them
    parameter_constraints = {
        "model": [Check(parse_model, _MODEL)],
        "min_clusters": [Interval(int, 2, None)],
        "min_m": [Options("auto", "adequate"), Interval(int, 1, None)],
        "weighting": [Options("model", "diagonal")],
        "n_starts": [Interval(int, 1, None)],
        "lines": [Options("model", "auto")],
        "resonance": [Options("model", "auto")],
        "bias_evidence": [Boolean()],
        "filter_tf": [NoneValue(), Interval(float, 0, None, closed="neither")],
        "fit_covariance": [Options("model", "record")],
    }
    setting_relations = (Relation(("filter_tf", "model"), lambda est: _held_filter_in_model(est.filter_tf, est.model),
                                  "filter_tf holds the time constant of the model's FW"),)

    #: the rate-like extras (Estimator.diagnostic_units)
    diagnostic_units = {"scale_alternatives": _alternative_units}

    #: run the poor-fit check (:func:`avbench.estimators.allan.fit_check.assess_fit`); not a setting: an estimator
    #: that uses the GMWM fit only as its start sets it False on its instance
    _assess = True

    def __init__(self, *, model="WN+GM+RW", min_clusters=8, min_m="auto", weighting="model", n_starts=6,
                 lines="model", resonance="model", bias_evidence=False, filter_tf=None, fit_covariance="model"):
        self.model = model
        self.min_clusters = min_clusters
        self.min_m = min_m
        self.weighting = weighting
        self.n_starts = n_starts
        self.lines = lines
        self.resonance = resonance
        self.bias_evidence = bias_evidence
        self.filter_tf = filter_tf
        self.fit_covariance = fit_covariance

    def _n_free(self, latents) -> int:
        """The number of parameters the fit of ``latents`` estimates (a tf held at ``filter_tf`` is not one)."""
        return n_parameters(latents) - (self.filter_tf is not None and "FW" in latents)

    def _hold(self, latents, lo, hi):
        """``(lo, hi)`` with the parameters held by the settings (``filter_tf``) in a box of relative width
        :data:`HELD_WIDTH` around their value: the solver keeps them there, and the covariance treats them
        as held (on their bound, :func:`avbench.estimators.likelihood._gmwm_model.report`)."""
        if self.filter_tf is None or "FW" not in latents:
            return lo, hi
        i = param_index(latents, "FW") + LATENT_TERMS["FW"].fit_parameters.index("tf")
        lo, hi = lo.copy(), hi.copy()
        lo[i], hi[i] = math.log(self.filter_tf) - HELD_WIDTH, math.log(self.filter_tf) + HELD_WIDTH
        return lo, hi

    # -- fitting ---------------------------------------------------------------------------------
    def _wavelet_variance(self, rate, dt):
        """The AV values matched (:class:`WaveletVariance`): here the classical overlapping AV at
        octave taus, with nothing added (robust variants: :mod:`avbench.estimators.robust.gmwm`)."""
        res = allan_variance(rate, dt, taus="octave", overlapping=True)
        return WaveletVariance(res.tau, res.avar, res.m, first_step_edf(res.tau, res.avar, res.J, res.edf))

    @one_blas_thread()
    def _fit(self, rate, dt):
        """The fit of the wavelet variance (:meth:`_wavelet_variance`) by :meth:`_fit_curve`; within a
        :func:`~avbench.estimators.selection.shared.shared_choices` scope (an axis of ``avbench estimate``) the
        outcome of another method that matched the same values of the same samples with the same choice settings
        is taken instead of fitting them again (the same numbers: :meth:`_choice_key`)."""
        wv = self._wavelet_variance(rate, dt)
        kept = shared.current()
        if kept is None:
            coefs, diag, parts = self._fit_curve(rate, dt, wv)
        else:
            coefs, diag, parts = kept.outcome(self._choice_key(rate, dt, wv), lambda: self._fit_curve(rate, dt, wv))
        extras = extras_of(diag, parts)
        extras.pop("values", None)  # the parameters' values in order: the result's ``parameters``
        return coefs, {}, {**extras, **(wv.diagnostics or {})}, parts

    #: the settings of :class:`GMWM` that shape its fit of the curve (the key of :meth:`_choice_key`)
    _CHOICE_SETTINGS = ("model", "min_clusters", "min_m", "weighting", "n_starts", "lines", "resonance",
                        "bias_evidence", "filter_tf", "fit_covariance")

    def _choice_key(self, rate, dt, wv):
        """What the fit of the curve reads (:func:`~avbench.estimators.selection.shared.choice_key`): the samples
        (the line and band tests, the poor-fit check), ``dt``, the wavelet variance's arrays and factors, the
        settings of :data:`_CHOICE_SETTINGS`, whether the fit is checked, and the methods that fit it."""
        settings = tuple((k, repr(getattr(self, k))) for k in self._CHOICE_SETTINGS)
        settings += (("cov_scale", float(wv.cov_scale)), ("reference_is_classical", bool(wv.reference_is_classical)),
                     ("assess", bool(self._assess)))
        cls = type(self)
        code = tuple(getattr(cls, f) for f in ("_fit_curve", "_scale_choice", "_fit_scales", "_fit_check",
                                               "_bias_evidence", "_record_std_err", "_bound_edf", "_widen",
                                               "_dispersion", "_alternatives", "_hold"))
        return shared.choice_key(rate, dt, [wv.tau, wv.avar, wv.m, wv.edf, wv.white_gain], settings, code)

    def _fit_curve(self, rate, dt, wv):
        """``(coefficients, diagnostics, typed parts)``: the model choices and the fit of the wavelet variance
        ``wv`` of ``rate``."""
        latents = parse_model(self.model)
        n = rate.size
        usable = (n // wv.m >= self.min_clusters) & (wv.avar > 0)
        line = None
        if "SN" in latents or self.lines == "auto":
            latents, line, _ = choose_line(latents, rate, dt, wv.tau[usable], self.lines == "auto")
        args = (wv, usable, n, dt, line)
        band = functools.cache(lambda: band_seen(rate, dt, wv.tau[usable], line))  # one Welch pass
        resonance = band() if "RS" in latents else None
        best, tried, _ = self._scale_choice(latents, *args, resonance)
        others = best.pop("alternatives", None)  # None: the white reach does not bind
        resonance_test = None
        if self.resonance == "auto" and "RS" not in latents:
            def refit(lats, found, below, accept, max_tau, seed):
                return self._scale_choice(lats, *args, found, below=below, accept=accept, max_tau=max_tau, seed=seed)

            check = (lambda fit, lats: self._fit_check(fit, lats, rate, dt, wv, usable, n)[0]) if self._assess else None
            plain, plain_latents = best, latents
            best, tried, latents, resonance_test = choose_resonance(latents, best, tried, wv.m, usable, band, refit,
                                                                    check)
            if others is not None and best is not plain:  # the model without the resonance: adequate, and competing
                others = [(int(plain["diag"]["m"][0]), plain)] + others
                alternatives = self._alternatives(plain_latents, others, dt)
            else:
                alternatives = self._alternatives(latents, others or [], dt)
        else:
            alternatives = self._alternatives(latents, others or [], dt)
        evidence = None
        if self.bias_evidence and {"GM", "FL"} & set(latents):
            evidence = self._bias_evidence(latents, best, wv, usable, n, dt, line, band() if "RS" in latents else None)
        diag = best["diag"]
        diag["min_m"] = int(diag["m"][0])
        if self.filter_tf is not None:
            diag["filter_held"] = {"tf": float(self.filter_tf)}
        if line is not None:
            diag["line_test"] = line
            if line["significant"] and "SN" in latents:
                line["f0_at_bound"] = frequency_at_bound(diag["params"]["SN.f0"], line)
        if self.min_m in ("auto", "adequate"):
            diag["scale_choice"] = [{"min_m": a, "J_stat": b, "n_scales": c} for a, b, c in tried]
        if evidence is not None:
            diag["bias_evidence"] = evidence
        if alternatives:
            diag["scale_alternatives"] = alternatives
        if self.resonance == "auto":
            diag["resonance_test"] = resonance_test or {"included": "RS" in latents, "reason": "in the model"}
        if not self._assess:  # a starting fit (avbench.estimators.likelihood.mle): no poor-fit check
            diag.pop("fit_jacobian", None), diag.pop("fit_free", None)
            return best["coefs"], diag, self._parts(diag, line, resonance_test, evidence)
        check, gyro = self._fit_check(best, latents, rate, dt, wv, usable, n, self.fit_covariance == "record")
        record_factor, dispersion = None, 1.0
        if self.fit_covariance == "record":
            record_factor, dispersion = check["fit_check"].get("record_factor"), self._dispersion(check)
        edf = self._bound_edf(wv, check, record_factor, dispersion)
        tau_ok, upper_av = bounds.av_upper_limits(wv.tau, wv.avar, edf, usable)
        unresolved = {}
        if "GM" in latents:
            unresolved = bounds.gm_unresolved(latents, diag["values"], diag["tau"][0], tau_ok, upper_av, dt,
                                              2.0 * n * dt) or {}
        unresolved.update(bounds.terms_at_zero(latents, best["coefs"], tau_ok, upper_av, dt, 2.0 * n * dt,
                                               known=unresolved))
        if unresolved:
            diag["unresolved"] = unresolved
        diag.update(check)
        if self.fit_covariance == "record":
            self._record_std_err(diag, latents, gyro, record_factor, n, wv.cov_scale)
            if dispersion > 1.0:
                diag["dispersion"] = dispersion
                self._widen(diag, {c: dispersion for c in diag["std_err"].index})
        diag.pop("fit_jacobian", None), diag.pop("fit_free", None)
        diag["model"] = gyro  # the fitted latent model (Estimator.model_avar)
        return best["coefs"], diag, self._parts(diag, line, resonance_test, evidence, check, unresolved)

    def _parts(self, diag, line, resonance_test, evidence, check=None, unresolved=None) -> FitParts:
        """The typed parts of the fit whose diagnostics are ``diag``: its check, the bounds of the terms it
        does not resolve, the choices made (in the order line, filter, resonance, bias model, first scale)."""
        made = [choices.line_test(line)] if line is not None else []
        if self.filter_tf is not None:
            made.append(choices.filter_held(self.filter_tf))
        if self.resonance == "auto":
            made.append(choices.resonance_test(diag["resonance_test"]))
        if evidence is not None:
            made.append(choices.bias_evidence(evidence))
        made.append(choices.first_scale(diag["min_m"]))
        failure = diag.get("failure")
        others = list((diag.get("scale_alternatives") or {}).values())
        held = bias_model.held_alternative(evidence)
        others += [held] if held is not None else []
        return FitParts(fit_check=FitCheck(None) if check is None else as_fit_check(check),
                        alternatives=tuple(Alternative(dict(a["coefficients"]), dict(a["std_err"])) for a in others),
                        unresolved={c: float(b[1]) if b[1] is not None else math.nan
                                    for c, b in (unresolved or {}).items()},
                        choices=tuple(made), parameters=dict(diag["params"]), failure=failure, std_err=diag["std_err"],
                        converged=failure is None)

    @staticmethod
    def _alternatives(latents, fits, dt) -> dict:
        """``extras_["scale_alternatives"]``: for each longer cut-off within the white reach that Hansen's J
        accepts (:func:`~avbench.estimators.selection.scales.choose_scales`'s ``fit["alternatives"]``), its
        ``coefficients`` and ``std_err`` (SI), keyed by its shortest cluster size. A fit whose Gauss-Markov term
        peaks within three octaves of its shortest tau resolves no B (:mod:`~avbench.estimators.selection.bounds`):
        it gives N only."""
        from avbench.noise_models.markov_terms import GM_PEAK_TAU_OVER_TC

        out = {}
        for m0, fit in fits:
            coefs = dict(fit["coefs"])
            if "GM" in latents:
                tc = fit["diag"]["values"][param_index(latents, "GM") + LATENT_TERMS["GM"].fit_parameters.index("tc")]
                if GM_PEAK_TAU_OVER_TC * tc < bounds.GM_RESOLVED_PEAK_FACTOR * fit["diag"]["tau"][0]:
                    coefs = {c: v for c, v in coefs.items() if c == "N"}
            se = fit["diag"]["std_err"]
            out[str(m0)] = {"coefficients": {c: float(v) for c, v in coefs.items()},
                            "std_err": {c: float(se[c]) for c in coefs if c in se.index}, "J_stat": float(fit["J_stat"]),
                            "n_scales": int(fit["k"])}
        return out

    def _fit_check(self, best, latents, rate, dt, wv, usable, n, record=False):
        """(the poor-fit check of :func:`assess_fit` for fit ``best`` of ``latents``, the fitted latent gyro);
        ``record``: with the record's own variances (``fit_covariance="record"``)."""
        diag = best["diag"]
        gyro = build_gyro(latents, diag["values"], dt, 2.0 * n * dt)  # FL: tau_max as in _fit_scales
        model_avar = gyro.avar
        white = white_latent(latents)
        if wv.white_gain is not None and white is not None:
            n_wn = diag["values"][param_index(latents, white)]

            def model_avar(tau):  # the fitted curve as the record's AV estimator sees it (see _fit_scales)
                gain = np.interp(np.log(tau), np.log(wv.tau), wv.white_gain)
                return gyro.avar(tau) + (gain - 1.0) * n_wn**2 / tau

        reference = None if wv.reference_is_classical else (wv.tau, wv.avar, wv.m, n)
        n_par = self._n_free(latents)
        jac = (diag["tau"], diag["fit_jacobian"]) if record and "fit_jacobian" in diag else None
        return assess_fit(rate, dt, model_avar, gyro, n_par, (diag["tau"][0], diag["tau"][-1]),
                          reference=reference, cov_scale=wv.cov_scale, record_covariance=record, jacobian=jac), gyro

    @staticmethod
    def _record_std_err(diag, latents, gyro, factor, n, cov_scale):
        """Standard errors under the record's own variances (``fit_covariance="record"``): the GMM sandwich over the
        model-weighted fit's, per coefficient, where it is larger; the same ratio widens the alternatives
        :meth:`conf_int` unions. Needs the check's scales to be the fit's (else nothing changes)."""
        if factor is None or not np.any(np.asarray(factor) > 1.0) or "fit_jacobian" not in diag:
            return
        G, tau = np.asarray(diag["fit_jacobian"], float), np.asarray(diag["tau"], float)
        factor = np.asarray(factor, float)
        if factor.size != tau.size or G.shape[1] == 0:
            return
        free = diag["fit_free"]
        omega = av_covariance(gyro, np.asarray(diag["m"], dtype=np.int64), n) * cov_scale
        try:
            WG = np.linalg.solve(omega, G)
            Hinv = np.linalg.inv(G.T @ WG)
            s = np.sqrt(factor)
            meat = WG.T @ (omega * np.outer(s, s)) @ WG
            V = Hinv @ meat @ Hinv
        except np.linalg.LinAlgError:
            return
        ratio = np.sqrt(np.clip(np.diag(V), 0, None) / np.diag(Hinv))
        se_factor = {}
        for lat in latents:
            coef = LATENT_TERMS[lat].coefficient
            i = param_index(latents, lat)
            if coef is None or not free[i]:
                continue
            r = float(ratio[int(np.count_nonzero(free[:i]))])
            if np.isfinite(r) and r > 1.0:
                se_factor[coef] = r
        if not se_factor:
            return
        diag["record_se_factor"] = se_factor
        GMWM._widen(diag, se_factor)

    @staticmethod
    def _bound_edf(wv, check, record_factor, dispersion=1.0):
        """The edf of each AV value of ``wv`` that the bounds of the terms the record does not resolve read
        (:func:`~avbench.estimators.selection.bounds.av_upper_limits`): the engine's, divided by the variance
        factors the record shows (``fit_covariance="record"``): each scale's from the batches (between the check's
        scales interpolated in log tau, beyond them its first or last) and the misfit's ``dispersion`` squared
        (:meth:`_dispersion`). An AV value that varies f times more than the stationary model allows has 1/f of
        the edf, and its chi^2 upper limit lies further up."""
        edf = np.asarray(wv.edf, float) / dispersion**2
        if record_factor is None or not np.any(np.asarray(record_factor) > 1.0):
            return edf
        return edf / np.interp(np.log(wv.tau), np.log(check["fit_check"]["tau"]), np.asarray(record_factor, float))

    @staticmethod
    def _widen(diag, factor: dict):
        """Multiply the standard errors of ``diag`` (``std_err``, and the alternatives' that :meth:`conf_int`
        unions: the scale alternatives, the bias models weighed) by ``factor[coefficient]``."""
        std = diag["std_err"].copy()
        for c, r in factor.items():
            if c in std.index:
                std[c] = std[c] * r
        diag["std_err"] = std
        entries = list((diag.get("scale_alternatives") or {}).values())
        entries += [v for k, v in (diag.get("bias_evidence") or {}).items() if k in ("GM", "FL")]
        for entry in entries:
            entry["std_err"] = {c: v * factor.get(c, 1.0) for c, v in entry["std_err"].items()}

    @staticmethod
    def _dispersion(check) -> float:
        """The Birge ratio of the fit's check (:func:`~avbench.estimators.allan.fit_check.assess_fit`'s entries):
        :math:`\\sqrt{T/\\mathrm{mean}}` where its statistic T exceeds the mean of its reference (the record
        reference's weights summed, else its degrees of freedom), else 1 (Birge 1932; the Particle Data Group's
        scale factor for inconsistent data). Where the fit misses the AV curve by more than its reference allows,
        the misfit is a variability of the record the covariance did not hold: every standard error is multiplied
        by it (``extras_["dispersion"]``), and the bounds read the AV with its edf divided by its square
        (:meth:`_bound_edf`)."""
        T = check.get("fit_stat")
        weights = (check.get("fit_check") or {}).get("weights")
        mean = float(np.sum(weights)) if weights is not None else float(check.get("fit_dof") or 0)
        if T is None or not np.isfinite(T) or not mean > 0 or T <= mean:
            return 1.0
        return math.sqrt(T / mean)

    def _scale_choice(self, latents, wv, usable, n, dt, line, resonance=None, below=None, accept=None, max_tau=np.inf,
                      seed=None) -> ScaleChoice:
        """The fit on the scales the setting ``min_m`` chooses
        (:func:`~avbench.estimators.selection.scales.choose_scales`). ``below``: the ``"adequate"`` rule among the cut-offs shorter than this one whose fit ``accept(fit)``
        accepts (:func:`~avbench.estimators.selection.scales.shorter_adequate`; a resonance added); ``seed``:
        the parameters of the other latents to start from (:meth:`_fit_scales`)."""
        m_all = wv.m
        n_par = self._n_free(latents)
        reach = white_reach(wv.tau, wv.avar, n, m_all, usable) if self.min_m == "adequate" else None
        lows = cutoffs(self.min_m, m_all, usable, n_par, reach)

        def fit_on(keep):
            return self._fit_scales(latents, wv.tau[keep], wv.avar[keep], m_all[keep], wv.edf[keep], n, dt,
                                    wv.cov_scale, None if wv.white_gain is None else wv.white_gain[keep], line,
                                    resonance, seed)

        if below is not None:
            return shorter_adequate(fit_on, lows, m_all, usable, n_par, below, max_tau, dt, accept)
        if not lows or np.count_nonzero(usable & (m_all >= lows[0])) < n_par + 1:
            k = np.count_nonzero(usable & (m_all >= (lows[0] if lows else 1)))
            long_enough = n // m_all >= self.min_clusters
            check_variance_seen(wv.tau[long_enough], wv.avar[long_enough], n_par + 1)
            raise ValueError(
                f"rate: {n} samples give {k} usable octave taus (>= {self.min_clusters} clusters, "
                f"m >= {self.min_m}), "
                f"fewer than the {n_par + 1} needed for model {'+'.join(latents)}; use a longer record"
            )
        binds = reach_binds(reach, m_all, usable, n_par)
        return choose_scales(fit_on, lows, m_all, usable, n_par, self.min_m, binds)

    def _bias_evidence(self, latents, best, wv, usable, n, dt, line, resonance) -> dict:
        """the model choice ``bias_evidence``: the same latents with GM and FL exchanged, fitted on the scales of
        ``best``, weighed against it (:func:`~avbench.estimators.selection.bias_model.weigh_bias_models`)."""
        other = bias_model.exchanged(latents)
        m0 = int(best["diag"]["m"][0])
        keep = usable & (wv.m >= m0)
        fit = self._fit_scales(other, wv.tau[keep], wv.avar[keep], wv.m[keep], wv.edf[keep], n, dt, wv.cov_scale,
                               None if wv.white_gain is None else wv.white_gain[keep], line, resonance)
        return bias_model.weigh_bias_models(latents, best, other, fit, self._n_free, m0).report

    def _fit_scales(self, latents, tau, avar, m, edf, n, dt, cov_scale, white_gain=None, line=None, resonance=None,
                    seed=None):
        """Two-step GMWM on the given scales; returns dict(coefs, J_stat, diag).

        ``white_gain`` (None or one value per tau): the record's AV estimator sees the white
        (ARW) part of the model multiplied by it (:class:`WaveletVariance`). ``line``, ``resonance``: a
        spectral line and band found in the record, where a sinusoid and a resonance start and stay
        (:func:`~avbench.estimators.selection.lines.sinusoid_hint`,
        :func:`~avbench.estimators.selection.resonance.resonance_hint`; a resonance's damping time within the
        band the spectrum resolves, :func:`~avbench.estimators.selection.resonance.resonance_box`). ``seed``: the
        fitted values of every latent but a resonance ``RS`` (last in the parameter vector), the model it is added
        to: the fit then starts there, with the resonance at each of ``resonance.starts`` (instead of every
        combination of the terms' starts)."""
        n_par = self._n_free(latents)
        T = n * dt
        hints = {"SN": sinusoid_hint(line), "RS": resonance_hint(resonance)}
        lo, hi = self._hold(latents, *log_bounds(latents, tau, avar, dt, T, hints))
        lo, hi = resonance_box(latents, lo, hi, resonance)

        tau_fl = 2.0 * T  # flicker latent: filter memory twice the record, as the presets
        extra = None
        white = white_latent(latents)
        if white_gain is not None and white is not None:
            extra = (param_index(latents, white), (white_gain - 1.0) / tau)
        model_av = LatentAV(latents, tau, dt, tau_fl, extra)

        # step 1: diagonal weights from the engine's edf, several starts
        L1 = np.sqrt(2.0 * avar**2 / edf * cov_scale)
        best = None
        if seed is not None:
            starts = [np.clip(np.log(np.r_[seed, rs]), lo + 1e-9, hi - 1e-9) for rs in resonance.starts]
        else:
            starts = log_starts(latents, tau, avar, self.n_starts, lo, hi, hints)
        for u0 in starts:
            sol = _solve(lambda u: (model_av(u) - avar) / L1, u0, lo, hi,
                         lambda u: model_av.jacobian(u) / L1[:, None])
            if best is None or sol.cost < best.cost:
                best = sol
        steps = [best]
        if self.weighting == "model":
            omega = av_covariance(build_gyro(latents, np.exp(best.x), dt, tau_fl), m, n, reuse=False) * cov_scale
            whiten = lower_triangular_solver(np.tril(cho_factor(omega, lower=True)[0]))

            def resid2(u):
                return whiten(model_av(u) - avar)

            best = _solve(resid2, best.x, lo, hi, lambda u: whiten(model_av.jacobian(u)))
            steps.append(best)
        u = best.x
        values = np.exp(u)
        at_floor = u <= lo + 1e-6
        coefs, std, params = report(latents, values, best.jac, at_floor)
        diag = {
            "params": params,
            "values": values,
            "std_err": std,
            "tau": tau,
            "m": m,
            "avar": avar,
            "fitted_avar": model_av(u),
            "J_stat": 2.0 * float(best.cost),
            "dof": int(tau.size - n_par),
            "weighting": self.weighting,
            "n_evaluations": int(sum(s.nfev for s in steps)),
        }
        free = (u > lo + 1e-6) & (u < hi - 1e-6)
        diag["fit_free"] = free  # the fitted curve's derivative in the free log-parameters (fit_covariance="record")
        diag["fit_jacobian"] = model_av.jacobian(u)[:, free]
        diag["stop_reason"] = best.stop_reason
        if not best.converged:
            diag["failure"] = f"least_squares: {best.message}"
        return {"coefs": coefs, "J_stat": diag["J_stat"], "diag": diag}


@register("gmwm_filtered")
class GMWMFiltered(GMWM):
    """GMWM whose white noise passes through the sensor's own low-pass filter (default model
    ``FW+GM+RW``; beyond Guerrier et al. 2013).

    Real IMUs filter before they sample: the first octaves of their AV lie below the white-noise
    line. :class:`GMWM` copes by dropping those scales (``min_m="auto"``), and on short records its
    Gauss-Markov term then takes what is left of the filter's shape (a B flagged "not resolved"). The
    ``FW`` latent (:class:`avbench.noise_models.FilteredWhiteNoise` with a first-order low-pass, time
    constant ``tf``) models the filter, so the scales are kept and the Gauss-Markov term is left to the
    bias instability. Settings as :class:`GMWM`, with defaults of its own: ``lines="auto"`` (a sinusoid
    ``SN`` when the record's strongest spectral line passes the line test), ``min_m="adequate"`` (the
    shortest cut-off the model fits by Hansen's J; it differs from ``"auto"`` only where the all-scale fit
    is rejected), ``resonance="auto"`` (a band-pass Gauss-Markov term ``RS`` where a band stands out of
    the spectrum and lets the model keep shorter scales), ``bias_evidence=True`` (the record's weights
    for a Gauss-Markov against a flicker B; unless they decisively favour the Gauss-Markov fit,
    :meth:`Estimator.conf_int` widens each interval to hold the flicker fit's too) and ``fit_covariance="record"`` (the poor-fit check and the standard
    errors take each AV value's variance from the record where it is larger than the stationary model's: a real
    sensor's noise level may move during the record).
    """

    #: the settings of :class:`GMWM`, with the same constraints
    parameter_constraints = {**GMWM.parameter_constraints}

    def __init__(self, *, model=REAL_SENSOR_MODEL, min_clusters=8, min_m="adequate", weighting="model", n_starts=6,
                 lines="auto", resonance="auto", bias_evidence=True, filter_tf=None, fit_covariance="record"):
        super().__init__(model=model, min_clusters=min_clusters, min_m=min_m, weighting=weighting, n_starts=n_starts,
                         lines=lines, resonance=resonance, bias_evidence=bias_evidence, filter_tf=filter_tf,
                         fit_covariance=fit_covariance)
