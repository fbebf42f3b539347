"""Poor-fit check: does a fitted model reproduce the record's Allan-variance curve within its errors?

Every estimator that fits (or reads) the Allan-variance curve calls :func:`assess_fit` once at the
end of its fit; the result goes into ``diagnostics_`` as

``poor_fit``    bool: the model misses the AV curve beyond its statistical uncertainty;
``fit_stat``    the chi^2-type statistic below; ``fit_dof`` its degrees of freedom;
``fit_pvalue``  P(chi^2_dof >= fit_stat);
``fit_check``   dict of arrays ``tau, avar, model, z`` (z: residual / its standard deviation at each
                tau, for plots) and ``alpha``.

The statistic
-------------
The reference curve is the fully overlapping Allan variance at octave cluster sizes (the curve
users plot, :func:`estimators.allan.allan_variance`), restricted to the tau range the estimator
used and to sizes with at least :data:`MIN_CLUSTERS` clusters (the Gaussian approximation of the
last octaves is poor). With residuals :math:`r = \\hat\\sigma^2 - \\sigma^2_{model}` at those k
taus,

.. math:: T = r^T\\,\\Omega^{-1} r \\;\\sim\\; \\chi^2_{k-p}\\quad\\text{under the fitted model},

where :math:`\\Omega` is the covariance of the overlapping AV values *under the fitted model*
(:func:`estimators.gmwm.av_covariance`: Isserlis / Percival 1995, from the model spectrum; it holds
the strong correlation of neighbouring octaves that a per-value EDF ignores) and p is the number of
fitted parameters. This is Hansen's J statistic of GMM evaluated for any fitted model: for
:class:`estimators.gmwm.GMWM` it is the minimised objective itself; for the other fitters, whose
criterion is different, T is at least the J value of the efficient fit on the same scales, so
the chi^2_{k-p} reference is approximate (a check, not an exact test). ``poor_fit`` is
``p < alpha`` (default :data:`ALPHA` = 0.01).

Reading. A flag means "the model with these coefficients misses this AV curve by more than its
random error", whatever the reason: a missing term (e.g. a rate random walk not modelled), a
term whose shape differs (a single Gauss-Markov term for a flat flicker plateau), scales the
sensor's own low-pass filter bends (the shortest taus of many MEMS IMUs), a non-physical
coefficient reported as NaN (its term is then missing from the model), or a fit that weights the
precise short-tau values too little. On hours of 100 Hz data the short-tau AV values are precise
to a fraction of a percent, so even small systematic misfits are flagged: read the per-tau ``z``
to see where.

Five-term fits (Lv et al. 2015 model, :mod:`estimators.av_model`) are checked with their
continuous model curve; the covariance uses the spectra of the same terms (white angle noise for
Q, white rate for N, 1/f flicker for B, random walk for K; the ramp R is deterministic and adds
no variance).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["ALPHA", "MIN_CLUSTERS", "assess_fit", "assess_five_term", "five_term_gyro", "fit_statistic"]

#: significance level of the poor-fit flag
ALPHA = 0.01
#: octave cluster sizes with fewer clusters floor(n/m) are not used by the check
MIN_CLUSTERS = 8


def five_term_gyro(coefs, dt):
    """A ``noise_models.Gyro`` holding the five-term model's terms that are finite and positive
    (for the covariance of the AV under that model); ``None`` if there is none."""
    from noise_models import AngleRandomWalk, BiasInstability, Gyro, Quantization, RateRamp, RateRandomWalk

    make = {"Q": lambda v: Quantization(Q=v), "N": lambda v: AngleRandomWalk(N=v),
            "B": lambda v: BiasInstability(B=v), "K": lambda v: RateRandomWalk(K=v),
            "R": lambda v: RateRamp(R=v)}
    terms = []
    for c, f in make.items():
        v = coefs.get(c, math.nan) if hasattr(coefs, "get") else math.nan
        if v is not None and np.isfinite(v) and v > 0:
            terms.append(f(float(v)))
    return Gyro(dt=dt, terms=terms) if terms else None


def fit_statistic(avar, model, cov, n_params):
    """(T, dof, p-value, z) of the residual ``avar - model`` with covariance ``cov`` (see module)."""
    from scipy import stats
    from scipy.linalg import cho_factor, cho_solve

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
    p = float(stats.chi2.sf(T, dof)) if np.isfinite(T) else 0.0
    return T, dof, p, z


def assess_fit(rate, dt, model_avar, cov_gyro, n_params, tau_range=None, *, alpha=ALPHA, reference=None,
               cov_scale=1.0) -> dict:
    """The poor-fit diagnostics of one fitted model on one record (module docstring).

    Parameters
    ----------
    rate, dt : record (rad/s) and sample interval (s).
    model_avar : callable
        ``model_avar(tau) -> ndarray``: the fitted model's AV at ``tau`` (s).
    cov_gyro : noise_models.Gyro or None
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
        (e.g. the robust AV of :mod:`estimators.robust`).
    cov_scale : float
        Factor applied to the model covariance of the reference values (the robust AV's variance
        bound, 1/efficiency; 1 for the classical AV).

    Returns
    -------
    dict with ``poor_fit``, ``fit_stat``, ``fit_dof``, ``fit_pvalue``, ``fit_check``.
    """
    from estimators.allan import allan_variance
    from estimators.gmwm import av_covariance

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
        out.update(poor_fit=False, fit_stat=math.nan, fit_dof=0, fit_pvalue=math.nan)
        return out
    if cov_gyro is None or not np.all(np.isfinite(model)):
        cov = np.zeros((tau.size, tau.size))
    else:
        cov = av_covariance(cov_gyro, m, n) * cov_scale
    T, dof, p, z = fit_statistic(avar, model, cov, n_params)
    out["fit_check"]["z"] = z
    out.update(poor_fit=bool(p < alpha), fit_stat=T, fit_dof=dof, fit_pvalue=p)
    return out


def assess_five_term(rate, dt, coefs, n_params, tau_range=None, *, alpha=ALPHA) -> dict:
    """:func:`assess_fit` for coefficients of the five-term model (NaN / missing terms omitted)."""
    from estimators.av_model import model_avar

    finite = {c: v for c, v in coefs.items() if v is not None and np.isfinite(v)}
    return assess_fit(rate, dt, lambda tau: model_avar(finite, tau), five_term_gyro(finite, dt), n_params,
                      tau_range, alpha=alpha)
