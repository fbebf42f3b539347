"""Poor-fit check: does a fitted model reproduce the record's Allan-variance curve within its errors?

Every estimator that fits (or reads) the Allan-variance curve calls :func:`assess_fit` once at the
end of its fit; it returns the entries below, which go into the fit's typed check
(:func:`as_fit_check`; the arrays of ``fit_check`` stay among the estimator's ``extras_``):

``poor_fit``    bool: the model misses the AV curve beyond its statistical uncertainty;
``fit_stat``    the chi^2-type statistic below; ``fit_dof`` its degrees of freedom;
``fit_pvalue``  P(chi^2_dof >= fit_stat);
``fit_check``   dict of arrays ``tau, avar, model, z`` (z: residual / its standard deviation at each
                tau, for plots) and ``alpha``.

The statistic
-------------
The reference curve is the fully overlapping Allan variance at octave cluster sizes (the curve
users plot, :func:`avbench.estimators.allan.variance.allan_variance`), restricted to the tau range the estimator
used and to sizes with at least :data:`MIN_CLUSTERS` clusters (the Gaussian approximation of the
last octaves is poor). With residuals :math:`r = \\hat\\sigma^2 - \\sigma^2_{model}` at those k
taus,

.. math:: T = r^T\\,\\Omega^{-1} r \\;\\sim\\; \\chi^2_{k-p}\\quad\\text{under the fitted model},

where :math:`\\Omega` is the covariance of the overlapping AV values *under the fitted model*
(:func:`avbench.estimators.allan.covariance.av_covariance`: Isserlis / Percival 1995, from the model spectrum; it holds
the strong correlation of neighbouring octaves that a per-value EDF ignores) and p is the number of
fitted parameters. This is Hansen's J statistic of GMM evaluated for any fitted model: for
:class:`avbench.estimators.likelihood.gmwm.GMWM` it is the minimised objective itself, and chi^2_{k-p} is its
reference (efficient GMM). ``poor_fit`` is ``p < alpha`` (default :data:`ALPHA` = 0.01).

The reference distribution, per estimator
-----------------------------------------
An *inefficient* fit's residuals are not chi^2_{k-p}: its fitted curve carries its own sampling
error, larger than the efficient fit's, so T is stochastically larger and the plain reference
flags correct models (measured on white noise with the right term set: ``nnls_rel`` 85 % of
replicates at p < 0.01, ``log_fit`` 84.5 %, ``wls_edf`` 78.5 %; table below). Where the estimator is a function of the
overlapping AV (``slope_lines``, ``log_fit``, ``nnls_rel``: it hands its fitted AV and its fit as
a function of it to :func:`assess_five_term` as ``refit``), the fit is linearised at the data
(:func:`refit_weights`; constraints active at the solution, e.g. NNLS's zeros, stay active) and
the residual vector :math:`r \\approx (S_c - J S_f)\\,e` has covariance
:math:`\\Sigma_r = D\\Omega_u D^T`; then T is a weighted sum of independent chi^2_1 variables with
weights the eigenvalues of :math:`\\Omega_c^{-1/2}\\Sigma_r\\Omega_c^{-1/2}`, and its tail is computed
by Imhof's (1961) integral (:func:`weighted_chi2_sf`; the two-moment Satterthwaite tail below
1e-12). ``fit_reference`` says which reference gave the p-value ("chi2" or "weighted chi2"); the
weights are in ``fit_check["weights"]``; ``fit_dof`` stays k - p. The approximation: the AV
values are Gaussian with the model covariance (poor for the last few octaves the fits use, which
the check itself leaves out) and the fit is linear within their spread.

Not covered analytically: the least-squares family of :mod:`avbench.estimators.curve_fits.least_squares` on its
default grid (the non-overlapping AV at every cluster size: its joint covariance with the check's
octave AV is not modelled) keeps the chi^2_{k-p} reference; :func:`bootstrap_fit_check` gives any
five-term fit a parametric-bootstrap p-value instead (a call; it costs ``n_draws`` fits). The MLE
keeps chi^2_{k-p} (it is more efficient than the AV fit, so the reference is slightly liberal).

Measured (``studies/fit_check_calibration.py``; fixed seeds; false-alarm rate = fraction of
replicates flagged at p < 0.01 with the correct term set; power = fraction flagged on the wrong
model; the binomial 99 % interval of a 1 % rate over R = 200 replicates is 0-4 flags):

============================  ============  =========  =============  =============  ===============
case (samples, replicates)    method        reference  flagged        plain chi^2    note
============================  ============  =========  =============  =============  ===============
white noise, N (5e4, 200)     nnls_rel      weighted   2 (1.0 %)      85 %
white noise, N (5e4, 200)     log_fit       weighted   3 (1.5 %)      84.5 %
white noise, N (5e4, 200)     slope_lines   weighted   6 (3.0 %)      16.5 %         a
white noise, N (5e4, 200)     gmwm (WN)     chi2       5 (2.5 %)      2.5 %
white noise, N (5e4, 200)     ols           chi2       5 (2.5 %)      2.5 %
white noise, N (5e4, 200)     wls           chi2       7 (3.5 %)      3.5 %
white noise, N (5e4, 200)     wls_edf       chi2       157 (78.5 %)   78.5 %         b
white noise, N (2e4, 30)      wls_edf       bootstrap  p<0.1: 10 %    --             c
CRG20, QNB (3.6e4, 200)       log_fit       weighted   0 (0 %)        73 %           e
CRG20, QNB (3.6e4, 200)       nnls_rel      weighted   20 (10 %)      79.5 %         d
CRG20, QNB (3.6e4, 200)       slope_lines   weighted   187 (93.5 %)   100 %          a
CRG20, QNB (3.6e4, 200)       ols           chi2       63 (31.5 %)    31.5 %         b
CRG20, QNB (3.6e4, 200)       wls           chi2       103 (51.5 %)   51.5 %         b
CRG20, QNB (3.6e4, 200)       wls_edf       chi2       111 (55.5 %)   55.5 %         b
white + GM, N only (5e4, 50)  five-term     both       96-100 %       100 %          power
white + GM, N only (5e4, 50)  gmwm (WN)     chi2       22 (44 %)      44 %           f
============================  ============  =========  =============  =============  ===============

(a) Slope lines read each coefficient off one point of the curve; on a composite model that
reading is biased (Guerrier, Molinari & Stebler 2016), so the fitted curve really misses the
data: on CRG20 the flag is right, not a false alarm. On white noise the argmin's discrete choice
is outside the linearisation (3 % for a nominal 1 %).
(b) The least-squares family on its default grid keeps the plain reference: these rates are its
false alarms, and :func:`bootstrap_fit_check` is the remedy (c: p < 0.1 in 3 of 30 records,
nominal 10 %, against 78.5 % flagged at 0.01 with the plain reference).
(d) Every flagged record is one where NNLS set Q to 0 (Q = 0 in 43 of 60 records): the
linearisation holds an active constraint fixed, so the point mass of the constrained estimate at
0 is not in the reference; the zeroed Q does miss the precise first octaves.
(e) Conservative: p < 0.1 in 3 of 200 records (nominal 20): the log of an AV value from a few
clusters is far from the Gaussian the linearisation assumes, and the fit's response to the last
octaves is overstated; no false alarm, some power lost.
(f) GMWM's automatic scale choice (``min_m="auto"``) often drops every scale up to m = 1024-2048,
past the Gauss-Markov bump, before the check sees them: then the white-noise model fits what is
left. On the first 10 of these records: "auto" started at m = 1024-2048 in 6 and flagged 6 of the
10; ``min_m=1`` flagged 10 of 10.
Load average 8-10 on 2 cores while measuring (times not reported).

``gmwm_filtered`` on its own model (FW+GM+RW, the ADIS16405 gyro y model of
``results/real/spread_models.csv``, 2.78 h at 100 Hz, 17 octaves from m = 1): the spread study flagged 6 of
its 64 records (seed 242026). The check's null holds where it can be tested without the optimiser: on 400
other records (seed 777) T at the true model is chi^2_17 (mean 16.7, variance 34.3; p < 0.01 in 5) and the
efficient-GMM statistic linearised at the truth (the five fitted parameters' projection removed, true
weights) is chi^2_12 (mean 11.8, variance 22.8; p < 0.01 in 2). On the 64 study records that linearised
statistic already has p < 0.01 in 4 (binomial P = 0.004 at 1 %): the six flagged records are the six with
the largest T at the truth (p = 0.001-0.03 there). The fit's own J exceeds the linearised one by +0.3 to
+2.5 on five of them, which took two (linearised p = 0.011, 0.018) under 0.01; on 45 fresh records
(seed 777) the excess has median +0.24 (10-90 %: -0.56 to +0.76), which moves a nominal 1 % to about
1.1 %, and ``gmwm_filtered`` flagged none of them (p < 0.05 in 1, p < 0.1 in 4; KS p = 0.37). The
selection steps played no part (m = 1 kept on all 45 and on five of the six, no line, no resonance; the
sixth kept m >= 16 and its linearised p on those scales is 0.003); no fit is in a wrong local optimum
(on all six the true parameters give a larger statistic under the fit's own weights, and the fitted
log-parameters follow the linearised ones). Reading: the flags are the tail of those 64 records, a little
enlarged by the fit's curvature (the Gauss-Markov time constant, 30 % standard error, is where the
linearisation is poorest); no correction of the reference is warranted. ``tests/test_fit_check.py``
holds the linearised statistic (slow) and T under the filtered model (default run).

Reading. A flag means "the model with these coefficients misses this AV curve by more than its
random error", whatever the reason: a missing term (e.g. a rate random walk not modelled), a
term whose shape differs (a single Gauss-Markov term for a flat flicker plateau), scales the
sensor's own low-pass filter bends (the shortest taus of many MEMS IMUs), a non-physical
coefficient reported as NaN (its term is then missing from the model), or a fit that weights the
precise short-tau values too little. On hours of 100 Hz data the short-tau AV values are precise
to a fraction of a percent, so even small systematic misfits are flagged: read the per-tau ``z``
to see where.

The record's own covariance (``record_covariance=True``)
-------------------------------------------------------
:math:`\\Omega` above is the covariance of a *stationary* process with the fitted spectrum. A sensor whose
noise level moves during the record (an accelerometer that senses the lab's vibration; on the six
ADIS16405 runs the AV of 30-minute slices varies between the slices 15-110 times more than the
stationary model allows at 0.01-0.16 s and 3-9 times at 10-80 s, the gyros about 1 time) is then judged
against a variability it does not have, and every fit is flagged. With ``record_covariance=True`` the
variance of each AV value is taken from the record where the record shows it larger: the record is cut
into :data:`RECORD_BATCHES` equal batches of L samples, the overlapping AV of each batch is computed at
each check scale m whose batches hold at least :data:`MIN_CLUSTERS` clusters, and their sample variance
:math:`s_m^2` (B - 1 degrees of freedom) is set against the model's variance of a batch's AV,
:math:`\\Omega_{mm}\\,(n - 2m + 1)/(L - 2m + 1)` (the 1/M scaling of the covariance formula). The ratio
:math:`\\rho_m` replaces 1 as a variance factor where it exceeds the one-sided :data:`RECORD_LEVEL` point of
:math:`\\chi^2_{B-1}/(B-1)` (a stationary record that the model describes rarely does: per scale 1 %);
scales too long for the batches take the factor of the longest scale they resolve. The covariance
becomes :math:`S\\Omega S`, :math:`S = \\mathrm{diag}(\\sqrt{f_m})`: the model's correlation between scales,
the record's variances (batch means, the nonparametric long-run variance of the squared wavelet
coefficients that GMWM's asymptotic theory uses, Guerrier et al. 2013; Guerrier, Molinari & Stebler 2016
for its robust form). Where no factor exceeds 1 the check is the one above. Where one does and the
fit's Jacobian is given (``jacobian``: d model AV / d free log-parameter at the check's scales, the fit
weighted by :math:`\\Omega^{-1}`), the reference is the weighted chi^2 of the fit's residual
:math:`r = (I - G(G^T\\Omega^{-1}G)^{-1}G^T\\Omega^{-1})e`, :math:`e \\sim N(0, S\\Omega S)`
(:func:`record_reference_weights`; ``fit_reference`` "weighted chi2 (record)"). A statistic summed over
the scales can hide a few scales the model misses among many whose variance the record inflates, so the
misfit is then also judged scale by scale: each residual over its own standard deviation under that
reference (:func:`record_residual_sd`, the diagonal of :math:`PS\\Omega SP^T`; these are the ``z`` the
figures draw), each against the Bonferroni limit over the scales (:func:`residual_limit`: Student's t with
B - 1 degrees of freedom where the variance came from the batches, Gaussian where it is the model's;
:func:`scale_residuals`). A scale the fit pins (the filter's time constant at the shortest tau, a resonance there,
the random walk at the longest: leverage near 1) has a linearised residual variance near 0 that the nonlinear
fit's residual does not follow; its residual is judged against at least a tenth of its value's variance
(:data:`PINNED_LEVERAGE`, :func:`record_residual_sd`). Measured on records simulated from ``gmwm_filtered``'s fits of
ADIS16405 gyro run 3 y, run 5 y and the MTi-G's x (``results/real/fit_check_per_scale.py``, 30 records each,
1e6 samples, the per-scale test forced): without the floor every record was flagged at its first octave (median
largest |z| 170-12,800 times the limit), with it none of the 90 (95 % interval of the rate [0, 0.04], nominal
at most 0.005). Here
the batches' variance is set against the variance the record's own AV level implies, :math:`\\Omega_{mm}
(\\hat\\sigma^2_m/\\sigma^2_{model,m})^2` (an AV value's variance goes with its square): a term the model
lacks raises the level of every batch alike, which is a misfit, not a spread between batches; and scales
too long for the batches keep the model's variance (no batch says the record varies more there). The fit
is poor where either test fails, each at ``alpha / 2``, so the flag's level stays ``alpha``. What it does
not do: it does not make a wrong model pass; its residuals are judged against the record's own
variability (the tests: a missing term is still flagged on simulated records), and a scale whose batches
vary more than the model says counts less. The factors are in ``fit_check["record_factor"]``; the
reading (:func:`reading`, ``fit_reading``) says that the record is not stationary, by how much and where.

The reading
-----------
``fit_reading`` says the check in words (:func:`reading`): the statistic, what a record the fitted model
describes gives (the reference's mean: its degrees of freedom, or the sum of the weighted chi-square's
weights), which reference that is, and the p-value; in record mode the largest residual against its limit
and the non-stationarity the batches show.

Five-term fits (Lv et al. 2015 model, :mod:`avbench.estimators.allan.model`) are checked with their
continuous model curve; the covariance uses the spectra of the same terms (white angle noise for
Q, white rate for N, 1/f flicker for B, random walk for K; the ramp R is deterministic and adds
no variance).
"""

from __future__ import annotations

import dataclasses
import functools
import math
import warnings

import numpy as np

from avbench.noise_models.gyro import Gyro

__all__ = ["ALPHA", "MIN_CLUSTERS", "RECORD_BATCHES", "RECORD_LEVEL", "PINNED_LEVERAGE", "record_variance_factor",
           "record_reference_weights", "record_residual_sd", "scale_residuals", "residual_limit", "reading",
           "assess_fit", "assess_five_term", "fit_statistic",
           "union_covariance", "refit_weights", "weighted_chi2_sf", "chernoff_bound", "bootstrap_fit_check"]

#: significance level of the poor-fit flag
ALPHA = 0.01
#: octave cluster sizes with fewer clusters floor(n/m) are not used by the check
MIN_CLUSTERS = 8
#: batches of the record whose AVs' variance gives the check's own variances (``record_covariance``)
RECORD_BATCHES = 8
#: one-sided level at which the batches' variance of an AV value counts as larger than the model's
RECORD_LEVEL = 0.01
#: leverage beyond which a scale counts as pinned by the fit: its residual is judged against at least
#: ``1 - PINNED_LEVERAGE`` of its value's variance (:func:`record_residual_sd`)
PINNED_LEVERAGE = 0.9
#: below this the Imhof integral is at the level of its error: the two-moment tail is used
IMHOF_FLOOR = 1e-12
#: finite-difference step of :func:`refit_weights`, in standard deviations of each AV value
REL_STEP = 0.01


def fit_statistic(avar, model, cov, n_params):
    """(T, dof, p-value, z) of the residual ``avar - model`` with covariance ``cov`` (see module)."""
    from scipy.linalg import cho_factor, cho_solve
    from scipy.special import chdtrc  # chi^2 tail: scipy.stats.chi2.sf's own function, without importing scipy.stats

    r = np.asarray(avar, float) - np.asarray(model, float)
    dof = max(int(r.size - n_params), 1)
    sd = np.sqrt(np.clip(np.diag(cov), 0, None))
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.where(sd > 0, r / sd, np.where(r == 0, 0.0, np.inf * np.sign(r)))
    try:
        T = float(r @ cho_solve(cho_factor(cov, lower=True), r))
    except (np.linalg.LinAlgError, ValueError):
        T = math.inf
    if not np.isfinite(T) or T < 0:
        T = math.inf
    p = float(chdtrc(dof, T)) if np.isfinite(T) else 0.0
    return T, dof, p, z


def weighted_chi2_sf(x, weights) -> float:
    """P(sum_i w_i Z_i^2 > x) for independent standard normal Z_i and weights w_i >= 0.

    Imhof (1961, eq. 3.2) with h_i = 1 and no non-centrality:

    .. math:: P(Q > x) = \\frac12 + \\frac1\\pi\\int_0^\\infty
        \\frac{\\sin\\theta(u)}{u\\,\\rho(u)}\\,du,\\quad
        \\theta(u) = \\tfrac12\\sum_i \\arctan(w_i u) - \\tfrac12 x u,\\quad
        \\rho(u) = \\prod_i (1 + w_i^2 u^2)^{1/4},

    integrated numerically: directly up to two periods of the x u / 2 oscillation, as Fourier
    integrals beyond (absolute error ~1e-14, checked against chi^2 and simulation in the tests).
    Below :data:`IMHOF_FLOOR` the integral is at the level of its own error, and the tail is taken
    from the two-moment (Satterthwaite 1946) approximation :math:`a\\chi^2_\\nu`,
    :math:`a = \\sum w^2/\\sum w`,
    :math:`\\nu = (\\sum w)^2/\\sum w^2` (capped at the floor, so the flag never depends on it).
    """
    from scipy import integrate
    from scipy.special import chdtrc  # scipy.stats.chi2.sf(x, nu) is chdtrc(nu, x)

    w = np.asarray(weights, dtype=float)
    w = w[w > 1e-12 * max(float(w.max(initial=0.0)), 1e-300)]
    if w.size == 0:
        return 0.0 if x > 0 else 1.0
    if not np.isfinite(x):
        return 0.0
    if x <= 0:
        return 1.0
    if chernoff_bound(x, w) < 0.1 * IMHOF_FLOOR:
        # the tail is surely below the floor, where the integral's value is not used: a poor fit does not
        # pay for it (same result as integrating, then taking the two-moment tail)
        a, nu = float(np.sum(w**2) / np.sum(w)), float(np.sum(w) ** 2 / np.sum(w**2))
        return float(min(IMHOF_FLOOR, float(chdtrc(nu, x / a))))

    # [0, a] directly; beyond, sin(phi - xu/2) = sin(phi) cos(xu/2) - cos(phi) sin(xu/2) as Fourier
    # integrals (QUADPACK's QAWF), which follow the slow u^(-1-k/2) decay of few weights; the integrand
    # is compiled (_fit_check_kernels: the three parts, chosen by the second argument)
    f = _imhof_callable()
    a = 4 * math.pi / x
    extra = tuple(float(v) for v in w)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", integrate.IntegrationWarning)
        v0, _ = integrate.quad(f, 0.0, a, args=(0.0, x) + extra, limit=200, epsabs=1e-13)
        v1, _ = integrate.quad(f, a, np.inf, args=(1.0, x) + extra, weight="cos", wvar=0.5 * x, limlst=200,
                               epsabs=1e-13)
        v2, _ = integrate.quad(f, a, np.inf, args=(2.0, x) + extra, weight="sin", wvar=0.5 * x, limlst=200,
                               epsabs=1e-13)
    val = v0 + v1 + v2
    p = 0.5 + val / math.pi
    if p < IMHOF_FLOOR:
        a, nu = float(np.sum(w**2) / np.sum(w)), float(np.sum(w) ** 2 / np.sum(w**2))
        p = min(IMHOF_FLOOR, float(chdtrc(nu, x / a)))
    return float(min(max(p, 0.0), 1.0))


@functools.cache
def _imhof_callable():
    """The compiled Imhof integrand as a :class:`scipy.LowLevelCallable` (numba imported on first use)."""
    from scipy import LowLevelCallable

    from avbench.estimators.allan._fit_check_kernels import imhof_integrand

    return LowLevelCallable(imhof_integrand.ctypes)


def chernoff_bound(x, weights) -> float:
    r"""Chernoff's upper bound on P(sum_i w_i Z_i^2 > x) (independent standard normal Z_i, w_i > 0):

    .. math:: P \le \min_{0 < s < 1/(2 w_{max})} e^{-s x} \prod_i (1 - 2 s w_i)^{-1/2},

    the moment generating function of the weighted chi^2 at its minimising s, found by bisection on
    the increasing derivative :math:`-x + \\sum_i w_i/(1 - 2 s w_i)`. 1 when x <= sum w (the mean)."""
    w = np.asarray(weights, dtype=float)
    if not x > float(w.sum()):
        return 1.0
    lo, hi = 0.0, 0.5 / float(w.max())
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if float(np.sum(w / (1.0 - 2.0 * mid * w))) > x:
            hi = mid
        else:
            lo = mid
        if hi - lo <= 1e-15 * hi:
            break
    s = lo
    return float(math.exp(min(0.0, -s * x - 0.5 * float(np.sum(np.log1p(-2.0 * s * w))))))


def record_variance_factor(rate, m, model_var, n_samples, batches=RECORD_BATCHES, level=RECORD_LEVEL, carry=True):
    """Per cluster size ``m``, the factor (>= 1) by which the record's own variance of its AV value exceeds the
    model's ``model_var`` (the diagonal of the model covariance of the whole record's AV), from the AVs of
    ``batches`` equal batches (module docstring, "The record's own covariance"): the ratio
    :math:`\\rho_m = s^2_m / (\\Omega_{mm}(n - 2m + 1)/(L - 2m + 1))` where it exceeds the one-sided ``level``
    point of chi^2_{B-1}/(B-1), else 1; scales whose batches hold fewer than :data:`MIN_CLUSTERS` clusters take
    the factor of the longest scale that holds them (1 if none does; with ``carry=False`` they keep 1: the record
    says nothing of its variability there). The batches are contiguous stretches of the samples given (a record's
    gaps are not looked for here)."""
    from scipy.special import chdtri  # chi^2 upper quantile: chdtri(dof, p) is scipy.stats.chi2.isf(p, dof)

    from avbench.estimators.allan.variance import allan_variance

    m = np.asarray(m, dtype=np.int64)
    x = np.asarray(rate, float)
    L = int(n_samples) // int(batches)
    factor = np.ones(m.size)
    seen = (L // np.maximum(m, 1) >= MIN_CLUSTERS) & (np.asarray(model_var, float) > 0)
    if batches < 2 or not seen.any():
        return factor
    ms = m[seen]
    av = np.array([allan_variance(x[b * L:(b + 1) * L], 1.0, taus=ms.astype(float)).avar for b in range(batches)])
    s2 = np.var(av, axis=0, ddof=1)
    batch_var = np.asarray(model_var, float)[seen] * (n_samples - 2 * ms + 1) / (L - 2 * ms + 1)
    rho = s2 / batch_var
    crit = float(chdtri(batches - 1, level)) / (batches - 1)
    factor[seen] = np.where(rho > crit, rho, 1.0)
    if carry:
        last = np.flatnonzero(seen)[-1]
        factor[last + 1:] = factor[last]
    return factor


def record_reference_weights(omega, factor, jacobian) -> np.ndarray:
    """Weights of the null distribution of T when the AV values' covariance is ``S omega S``
    (S = diag(sqrt(factor))) but the fit weighted them by ``omega``: the eigenvalues of
    :math:`L^{-1}P S\\Omega S P^TL^{-T}`, :math:`LL^T = S\\Omega S`,
    :math:`P = I - G(G^T\\Omega^{-1}G)^{-1}G^T\\Omega^{-1}` (G = ``jacobian``, the fitted curve's derivative in
    the free parameters at the check's scales). With all factors 1 they are k - p ones and p zeros (chi^2_{k-p})."""
    from scipy.linalg import cho_factor, cho_solve, cholesky, solve_triangular

    G = np.asarray(jacobian, float)
    s = np.sqrt(np.asarray(factor, float))
    rec = omega * np.outer(s, s)
    cf = cho_factor(omega, lower=True)
    WG = cho_solve(cf, G)
    P = np.eye(omega.shape[0]) - G @ np.linalg.solve(G.T @ WG, WG.T)
    L = cholesky(rec, lower=True)
    A = solve_triangular(L, P @ rec @ P.T, lower=True)
    A = solve_triangular(L, A.T, lower=True)
    return np.clip(np.linalg.eigvalsh(0.5 * (A + A.T)), 0.0, None)


def record_residual_sd(omega, factor, jacobian, pinned=PINNED_LEVERAGE) -> np.ndarray:
    """Each scale's standard deviation of the fit's residual when the AV values' covariance is ``S omega S``
    and the fit weighted them by ``omega`` (the setting of :func:`record_reference_weights`): the square root
    of the diagonal of :math:`P S\\Omega S P^T`, and never less than :math:`\\sqrt{1 - h_{max}}` times the
    value's own standard deviation (``pinned`` = :math:`h_{max}`, :data:`PINNED_LEVERAGE`).

    Why the floor: where the fitted parameters follow one scale almost fully (its leverage
    :math:`h_i = 1 - \\mathrm{Var}(r_i)/\\mathrm{Var}(e_i)` near 1: the filter's time constant and a resonance
    at the shortest tau, the random walk at the longest) the linearised residual variance is the difference of
    two nearly equal numbers and falls towards 0 (3e-12 of the value's on the MTi-G's first octave), while the
    residual of the nonlinear fit keeps its curvature and round-off: a residual of 1e-6 of the value was then
    thousands of "standard deviations". Below a tenth of the value's variance the linearisation is not trusted;
    such a scale is judged against that tenth, and, with its full variance, in the summed statistic."""
    from scipy.linalg import cho_factor, cho_solve

    G = np.asarray(jacobian, float)
    s = np.sqrt(np.asarray(factor, float))
    rec = omega * np.outer(s, s)
    WG = cho_solve(cho_factor(omega, lower=True), G)
    P = np.eye(omega.shape[0]) - G @ np.linalg.solve(G.T @ WG, WG.T)
    var_r = np.clip(np.einsum("ij,jk,ik->i", P, rec, P), 0.0, None)
    return np.sqrt(np.maximum(var_r, (1.0 - pinned) * np.clip(np.diag(rec), 0.0, None)))


def scale_residuals(rate, m, avar, model, omega, jacobian, n_samples, alpha, pinned=PINNED_LEVERAGE):
    """``(z, limit)``: the fit's residual at each check scale over its own standard deviation, and the limit of
    :func:`residual_limit` at family-wise level ``alpha`` (the per-scale reading of the record check, module
    docstring). ``omega``: the model covariance of the AV values ``avar`` at cluster sizes ``m``; ``model``: the
    fitted AV there; ``jacobian``: the fitted curve's derivative in the free log-parameters at those scales.

    The batches' variance of each AV value is set against the variance the record's own AV level implies,
    :math:`\\Omega_{mm}(\\hat\\sigma^2_m/\\sigma^2_{model,m})^2` (a term the model lacks raises the level of
    every batch alike: a misfit, not a spread between batches), scales too long for the batches keep the model's
    (:func:`record_variance_factor` with ``carry=False``); the residual's standard deviation is
    :func:`record_residual_sd`'s (never below ``1 - pinned`` of the value's own variance); a residual
    whose variance came from the batches is read against Student's t with B - 1 degrees of freedom."""
    with np.errstate(divide="ignore", invalid="ignore"):
        level = np.where((model > 0) & np.isfinite(avar / model), (avar / model) ** 2, 1.0)
    spread = record_variance_factor(rate, m, np.diag(omega) * level, n_samples, carry=False)
    sd_r = record_residual_sd(omega, spread, jacobian, pinned)
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.where(sd_r > 0, (np.asarray(avar, float) - model) / sd_r, 0.0)
    return z, residual_limit(z.size, alpha, np.where(spread > 1.0, RECORD_BATCHES - 1.0, np.inf))


def residual_limit(k: int, alpha: float, dof=None):
    """The |z| beyond which one of ``k`` standardised residuals flags the fit at family-wise level ``alpha``
    (two-sided, Bonferroni): the Gaussian quantile, or Student's t with ``dof`` degrees of freedom where a
    residual's variance was estimated (``dof`` a number or an array per residual, inf for a known variance)."""
    from scipy.special import ndtri, stdtrit

    q = alpha / (2 * max(int(k), 1))
    if dof is None:
        return float(-ndtri(q))
    dof = np.asarray(dof, float)
    return np.where(np.isfinite(dof), -stdtrit(np.where(np.isfinite(dof), dof, 1.0), q), -ndtri(q))


def reading(stat, dof, pvalue, reference, mean=None, record_factor=None, tau=None, residual_z=None,
            limit=None) -> str:
    """The fit check in words: the statistic, the reference it is read against (what a record the fitted
    model describes gives: the mean ``mean``, else ``dof``), the p-value; where the record's own variances
    were used, how much more the record varies than a stationary model allows and where; where residuals
    are judged one by one, the largest against its limit."""
    if stat is None or not np.isfinite(stat):
        return "no check: too few scales to test the model against"
    ref = {"chi2": f"a chi-square with {dof} degrees of freedom",
           "weighted chi2": "the spread this fit's own sampling error gives (a weighted chi-square)",
           "weighted chi2 (record)": "the spread the record's own batches show, passed through the fit (a weighted "
                                     "chi-square)"}.get(reference, None)
    if ref is None:
        ref = f"{reference}: the statistics of records simulated from the fit" if str(reference).startswith(
            "parametric bootstrap") else str(reference)
    typical = mean if mean is not None and np.isfinite(mean) else dof
    p = "p < 1e-6" if pvalue is not None and pvalue < 1e-6 else f"p = {pvalue:.3g}"
    out = (f"misfit {stat:.3g}, where a record the fitted model describes gives about {typical:.3g} ({ref}); "
           f"a larger one by chance: {p}")
    if residual_z is not None and limit is not None and np.size(residual_z):
        z = np.asarray(residual_z, float)
        lim = np.broadcast_to(np.asarray(limit, float), z.shape)
        i = int(np.nanargmax(np.abs(z) / lim))
        at = f" at {tau[i]:.3g} s" if tau is not None else ""
        out += (f"; the largest residual {z[i]:+.3g} of its own standard deviation{at} (limit +-{lim[i]:.3g} there, "
                f"over the {z.size} scales)")
    if record_factor is not None and np.any(np.asarray(record_factor) > 1.0):
        f = np.asarray(record_factor, float)
        where = ""
        if tau is not None:
            moved = np.asarray(tau, float)[f > 1.0]
            where = f" at {moved.min():.3g}-{moved.max():.3g} s"
        out += (f"; NOT STATIONARY: the record's Allan variance varies between its {RECORD_BATCHES} batches up to "
                f"{f.max():.3g} x more than a stationary model allows{where} -- the check and the intervals use the "
                "record's own variances there")
    return out


def union_covariance(m_fit, m_check, cov_gyro, n_samples, cov_scale=1.0):
    """``(u, omega)``: the cluster sizes of the fit and of the check together (sorted) and the model
    covariance of the overlapping AV at them (:func:`avbench.estimators.allan.covariance.av_covariance`, times
    ``cov_scale``); the check's own covariance is its sub-matrix."""
    from avbench.estimators.allan.covariance import av_covariance

    u = np.union1d(np.asarray(m_fit, dtype=np.int64), np.asarray(m_check, dtype=np.int64))
    return u, av_covariance(cov_gyro, u, n_samples) * cov_scale


def refit_weights(refit, m_check, cov_gyro, n_samples, cov_scale=1.0, rel_step=REL_STEP, union=None):
    """Weights of the null distribution of T for an estimator that is a function of the AV curve.

    ``refit = (m_fit, avar_fit, fn[, model_jacobian])``: the cluster sizes and values of the (overlapping) AV
    the estimator fitted, and ``fn(avar, tau) -> model AV at tau`` re-running its fit on another AV
    vector. Linearised at ``avar_fit``, by the fit's own derivative ``model_jacobian(tau)`` (d model AV
    at ``tau`` / d ``avar_fit``, shape ``(len(tau), len(m_fit))``) where it has one, else by central
    differences of ``fn`` (steps ``rel_step`` times each value's standard deviation, or times the value
    itself where that is smaller, so the perturbed AV stays positive), the model at the check taus moves by :math:`J\\,\\delta e_f`, so the
    residual at the check taus is :math:`r = D\\,e` with :math:`D = S_c - J S_f` (selectors of the
    check and fit sizes in their union) and

    .. math:: \\Sigma_r = D\\,\\Omega_u D^T,\\qquad
        T = r^T\\Omega_c^{-1} r \\approx \\sum_i \\lambda_i\\,\\chi^2_{1,i},\\quad
        \\lambda = \\mathrm{eig}(L^{-1}\\Sigma_r L^{-T}),\\ \\Omega_c = LL^T,

    :math:`\\Omega_u` the model covariance of the AV at the union of sizes
    (:func:`union_covariance`; pass its result as ``union`` where it is already computed). Returns
    ``(weights, J)``. For an efficient fit the
    weights are k - p ones and p zeros (the chi^2_{k-p} of GMM); an inefficient one has some above
    1 and more than p below: that is where the plain chi^2 reference gave false alarms.
    """
    m_fit, avar_fit, fn = refit[:3]
    model_jacobian = refit[3] if len(refit) > 3 else None
    m_fit = np.asarray(m_fit, dtype=np.int64)
    avar_fit = np.asarray(avar_fit, dtype=float)
    m_check = np.asarray(m_check, dtype=np.int64)
    u, omega = union if union is not None else union_covariance(m_fit, m_check, cov_gyro, n_samples, cov_scale)
    i_f, i_c = np.searchsorted(u, m_fit), np.searchsorted(u, m_check)
    sd = np.sqrt(np.clip(np.diag(omega)[i_f], 0, None))
    tau_c = m_check * cov_gyro.dt
    if model_jacobian is not None:  # the fit's own derivative: no refits
        J = np.asarray(model_jacobian(tau_c), dtype=float).reshape(m_check.size, m_fit.size)
    else:  # central differences of the refits
        J = np.zeros((m_check.size, m_fit.size))
        for j in range(m_fit.size):
            h = rel_step * min(sd[j], abs(avar_fit[j])) if sd[j] > 0 else rel_step * abs(avar_fit[j])
            if not h > 0:
                continue
            up, dn = avar_fit.copy(), avar_fit.copy()
            up[j] += h
            dn[j] -= h
            J[:, j] = (np.asarray(fn(up, tau_c), float) - np.asarray(fn(dn, tau_c), float)) / (2 * h)
    D = -J @ np.eye(u.size)[i_f]
    D[np.arange(m_check.size), i_c] += 1.0
    sigma_r = D @ omega @ D.T
    oc = omega[np.ix_(i_c, i_c)]
    from scipy.linalg import cholesky, solve_triangular

    L = cholesky(oc, lower=True)
    A = solve_triangular(L, solve_triangular(L, sigma_r, lower=True).T, lower=True)
    lam = np.linalg.eigvalsh(0.5 * (A + A.T))
    return np.clip(lam, 0.0, None), J


def assess_fit(rate, dt, model_avar, cov_gyro, n_params, tau_range=None, *, alpha=ALPHA, reference=None,
               cov_scale=1.0, refit=None, record_covariance=False, jacobian=None) -> dict:
    """The poor-fit diagnostics of one fitted model on one record (module docstring).

    Parameters
    ----------
    rate, dt : record (rad/s) and sample interval (s).
    model_avar : callable
        ``model_avar(tau) -> ndarray``: the fitted model's AV at ``tau`` (s).
    cov_gyro : avbench.noise_models.Gyro or None
        Model whose spectrum gives the covariance of the AV values (``None``: the model has no
        random term; then the fit is poor unless the AV is zero).
    n_params : int
        Number of fitted parameters.
    tau_range : (float, float) or None
        The taus the estimator used; the check is restricted to them (default: all).
    alpha : float
        Significance level of the flag.
    reference : (tau, avar, m, n_samples) or None
        The octave AV curve to compare with, if not the classical overlapping AV of ``rate``
        (e.g. the robust AV of :mod:`avbench.estimators.robust.gmwm`).
    cov_scale : float
        Factor applied to the model covariance of the reference values (the robust AV's variance
        bound, 1/efficiency; 1 for the classical AV).
    refit : (m_fit, avar_fit, fn[, model_jacobian]) or None
        For an estimator that is a function of the overlapping AV at cluster sizes ``m_fit``
        (values ``avar_fit``): ``fn(avar, tau)`` re-runs its fit and returns its model AV at
        ``tau``; ``model_jacobian(tau)``, optional, its derivative at ``avar_fit``
        (:func:`refit_weights`). The p-value then comes from the weighted chi^2 of :func:`refit_weights` (the
        estimator's own inefficiency taken into account) instead of chi^2 with k - p dof.
    record_covariance : bool
        Take each AV value's variance from the record's batches where they show it larger than the model
        (module docstring, "The record's own covariance"; :func:`record_variance_factor`).
    jacobian : (taus, array) or None
        With ``record_covariance``: the fitted curve's derivative in the fit's free parameters at ``taus``
        (a fit weighted by the model covariance); the reference is then :func:`record_reference_weights`'s.

    Returns
    -------
    dict with ``poor_fit``, ``fit_stat``, ``fit_dof``, ``fit_pvalue``, ``fit_reference``, ``fit_reading``,
    ``fit_check``.
    """
    from avbench.estimators.allan.variance import allan_variance
    from avbench.estimators.allan.covariance import av_covariance

    if reference is None:
        av = allan_variance(rate, dt, taus="octave", overlapping=True)
        reference = (av.tau, av.avar, av.m, av.n_samples)
    tau, avar, m, n = (np.asarray(reference[0], float), np.asarray(reference[1], float),
                       np.asarray(reference[2]), int(reference[3]))
    keep = n // m >= MIN_CLUSTERS
    if tau_range is not None:
        lo, hi = tau_range
        keep &= (tau >= lo * (1 - 1e-9)) & (tau <= hi * (1 + 1e-9))
    tau, avar, m = tau[keep], avar[keep], m[keep]
    model = np.asarray(model_avar(tau), dtype=float) if tau.size else np.empty(0)
    out = {"fit_check": {"tau": tau, "avar": avar, "model": model, "z": np.full(tau.size, np.nan),
                         "alpha": float(alpha)}}
    if tau.size <= n_params:
        # nothing left to test the model against
        out.update(poor_fit=False, fit_stat=math.nan, fit_dof=0, fit_pvalue=math.nan, fit_reference="none",
                   fit_reading=reading(math.nan, 0, math.nan, "none"))
        return out
    union = None
    if cov_gyro is None or not np.all(np.isfinite(model)):
        cov = np.zeros((tau.size, tau.size))
    elif refit is not None:  # one covariance for the check and its reference (refit_weights)
        union = union_covariance(refit[0], m, cov_gyro, n, cov_scale)
        i_c = np.searchsorted(union[0], np.asarray(m, dtype=np.int64))
        cov = union[1][np.ix_(i_c, i_c)]
    else:
        cov = av_covariance(cov_gyro, m, n) * cov_scale
    factor = None
    if record_covariance and refit is None and np.any(cov):
        factor = record_variance_factor(rate, m, np.diag(cov), n)
        out["fit_check"]["record_factor"] = factor
        if np.any(factor > 1.0):
            cov = cov * np.sqrt(np.outer(factor, factor))
        else:
            factor = None
    T, dof, p, z = fit_statistic(avar, model, cov, n_params)
    out["fit_check"]["z"] = z
    reference_name = "chi2"
    residual_poor = None
    if factor is not None and jacobian is not None and np.isfinite(T):
        jt, jac = np.asarray(jacobian[0], float), np.asarray(jacobian[1], float)
        rows = np.searchsorted(jt, tau)
        if jac.ndim == 2 and jac.shape[1] and np.all(rows < jt.size) and np.allclose(jt[np.minimum(rows, jt.size - 1)], tau):
            try:
                lam = record_reference_weights(cov / np.sqrt(np.outer(factor, factor)), factor, jac[rows])
            except (np.linalg.LinAlgError, ValueError):
                lam = None
            if lam is not None and np.all(np.isfinite(lam)) and lam.sum() > 0:
                p = weighted_chi2_sf(T, lam)
                reference_name = "weighted chi2 (record)"
                out["fit_check"]["weights"] = lam
                # the misfit is judged also scale by scale (scale_residuals)
                zr, limit = scale_residuals(rate, m, avar, model, cov / np.sqrt(np.outer(factor, factor)), jac[rows],
                                            n, alpha / 2)
                out["fit_check"]["z"], out["fit_check"]["residual_limit"] = zr, limit
                residual_poor = bool(np.any(np.abs(zr) > limit))
    if union is not None and np.isfinite(T):
        try:
            lam, _ = refit_weights(refit, m, cov_gyro, n, cov_scale, union=union)
        except (np.linalg.LinAlgError, ValueError, FloatingPointError):
            lam = None  # keep the chi^2_{k-p} reference
        if lam is not None and np.all(np.isfinite(lam)) and lam.sum() > 0:
            p = weighted_chi2_sf(T, lam)
            reference_name = "weighted chi2"
            out["fit_check"]["weights"] = lam
    if residual_poor is None:
        poor = bool(p < alpha)
    else:  # the record's variances: the whole misfit and the largest residual, each at alpha / 2
        poor = bool(p < alpha / 2) or residual_poor
    check = out["fit_check"]
    weights = check.get("weights")
    out.update(poor_fit=poor, fit_stat=T, fit_dof=dof, fit_pvalue=p, fit_reference=reference_name,
               fit_reading=reading(T, dof, p, reference_name, None if weights is None else float(np.sum(weights)),
                                   check.get("record_factor"), tau,
                                   check["z"] if residual_poor is not None else None, check.get("residual_limit")))
    return out


def as_fit_check(entries: dict):
    """The :class:`~avbench.estimators.results.FitCheck` of the entries :func:`assess_fit` (or another
    check of the same form, the Whittle spectral check) returns: the flag, statistic, degrees of
    freedom, p-value, reference, the check in words (``fit_reading``) and, where the check is made per AV
    scale, the finite residuals ``(tau, z)``."""
    from avbench.estimators.results import FitCheck

    check = entries.get("fit_check")
    residuals = None
    if isinstance(check, dict) and "z" in check and "tau" in check:
        tau, z = np.asarray(check["tau"], float), np.asarray(check["z"], float)
        ok = np.isfinite(z)
        if ok.any():
            residuals = (tau[ok], z[ok])
    dof = entries.get("fit_dof")
    pf = entries.get("poor_fit")
    return FitCheck(poor_fit=None if pf is None else bool(pf), stat=_float(entries.get("fit_stat")),
                    dof=None if dof is None else int(dof), pvalue=_float(entries.get("fit_pvalue")),
                    reference=entries.get("fit_reference"), residuals=residuals,
                    reading=entries.get("fit_reading"))


def _float(v) -> float:
    return math.nan if v is None else float(v)


def assess_five_term(rate, dt, coefs, n_params, tau_range=None, *, alpha=ALPHA, refit=None) -> dict:
    """:func:`assess_fit` for coefficients of the five-term model (NaN / missing terms omitted).

    ``refit = (tau_fit, avar_fit, coefs_fn[, model_jacobian])``: the overlapping AV the estimator fitted,
    ``coefs_fn(avar) -> coefficients`` re-running its fit and, optionally, the derivative of its model AV
    (see :func:`assess_fit`; a None ``model_jacobian`` means refitting by central differences)."""
    from avbench.estimators.allan.model import model_avar

    finite = {c: v for c, v in coefs.items() if v is not None and np.isfinite(v)}
    ref = None
    if refit is not None:
        tau_f, avar_f, coefs_fn = refit[:3]

        def fn(a, tau):
            c = coefs_fn(a)
            return model_avar({k: v for k, v in c.items() if v is not None and np.isfinite(v)}, tau)

        ref = (np.rint(np.asarray(tau_f, float) / dt).astype(np.int64), avar_f, fn) + tuple(refit[3:])
    return assess_fit(rate, dt, lambda tau: model_avar(finite, tau), Gyro.from_coefficients(finite, dt), n_params,
                      tau_range, alpha=alpha, refit=ref)


def bootstrap_fit_check(estimator, n_samples: int, dt: float, n_draws: int = 199, seed=0):
    """Replace a fitted estimator's poor-fit p-value by a parametric bootstrap one (a call, never
    automatic: it costs ``n_draws`` fits).

    ``n_draws`` records of ``n_samples`` samples are simulated from the fitted coefficients with the
    exact generators (:meth:`avbench.noise_models.Gyro.from_coefficients`: the five-term model,
    flicker for B) and refitted by clones of ``estimator``; the p-value is
    :math:`(1 + \\#\\{T^*_b \\ge T\\})/(n_\\mathrm{draws} + 1)` with T the estimator's ``fit_stat``
    and :math:`T^*_b` the clones' (the smallest p-value is 1/(n_draws + 1): the flag at level
    alpha needs n_draws >= 1/alpha, 199 by default for alpha = 0.01). This is the reference for
    fits the analytic one cannot follow
    (the least-squares family on the non-overlapping AV at every cluster size, whose covariance
    with the check's octave AV is not modelled). The five-term model is what is simulated, so it
    suits the five-term fits, not GMWM or the MLE (whose chi^2 reference is their own). Updates
    the fit check of ``parts_`` (p-value, flag, reference, reading) and ``extras_["fit_boot_stats"]``,
    and returns the estimator.
    """

    if isinstance(n_draws, bool) or not isinstance(n_draws, (int, np.integer)) or n_draws < 19:
        raise ValueError(f"n_draws: expected an integer >= 19 (p-values down to 0.05), got {n_draws!r}")
    check = estimator.parts_.fit_check
    T = check.stat
    if not np.isfinite(T):
        return estimator
    from avbench.estimators.uncertainty import refits

    stats_ = []
    for e in refits(estimator, int(n_samples), dt, n_draws, seed):
        t = e.parts_.fit_check.stat
        if not np.isnan(t):
            stats_.append(float(t))
    if not stats_:
        return estimator
    b = np.array(stats_)
    p = float((1 + np.sum(b >= T)) / (b.size + 1))
    alpha = (estimator.extras_.get("fit_check") or {}).get("alpha", ALPHA)
    poor, reference = bool(p < alpha), f"parametric bootstrap, {b.size} draws"
    read = reading(T, check.dof, p, reference, float(np.mean(b)))
    estimator.extras_["fit_boot_stats"] = b
    estimator.parts_ = dataclasses.replace(estimator.parts_, fit_check=dataclasses.replace(
        check, poor_fit=poor, pvalue=p, reference=reference, reading=read))
    return estimator
