"""Benchmarks of the estimators' fits, each against a same-run baseline where one exists.

* :class:`EstimatorScaling` -- every estimator's ``fit`` against n (linear cost), an ADIS16405-like
  100 Hz record (N, B, K), octave grids; larger n are skipped once a fit takes > ``budget_s``.
* :class:`FitCost` -- each curve fit with its poor-fit check, and GMWM, on lv2015's 4 h, 10 Hz record
  against the octave AV of that record (what the fit check costs beside the AV it checks).
* :class:`OnlineKernels` -- SHAKF / NEKF / ARMA-EM kernels against their plain-NumPy per-sample
  references (:mod:`avbench.bench.online_filters`, :mod:`avbench.bench.arma_em`).
* :class:`OnlineDefaults` -- shakf / nekf with default settings against the full per-sample trajectory.
* :class:`MleFit` -- ``mle`` (compiled likelihood) against a statsmodels ``MLEModel`` fit of the same
  likelihood (:func:`mle_statsmodels_path`), 4 h at 100 Hz.
* :class:`MleFitDrift` -- ``mle`` with the full latent model QN+WN+GM+RW+DR (as in the studies) on 2 h
  of the ADIS16405_X preset: the augmented Kalman filter against the exact initial (diffuse) filter.
* :class:`WhittleFit` -- ``whittle`` (with and without term selection) on 4 h at 100 Hz against one FFT.
"""

from __future__ import annotations

import math
import warnings

import numpy as np

from avbench.bench.engine import SIZES

__all__ = ["EstimatorScaling", "FitCost", "OnlineKernels", "QuickOnlineKernels", "OnlineDefaults", "MleFit",
           "MleFitDrift", "WhittleFit", "ESTIMATOR_SETTINGS", "mle_statsmodels_path"]

_LS = {"taus": "octave", "overlapping": True}
ESTIMATOR_SETTINGS = {
    "ols": _LS,
    "ols_trimmed": _LS,
    "wls": _LS,
    "wls_edf": _LS,
    "slope_lines": {},
    "log_fit": {},
    "nnls_rel": {},
    "gmwm": {},
    "mle": {},
    "shakf": {"x0": "truth", "trajectory_every": 0},
    "nekf": {"x0": "truth", "trajectory_every": 0},
    "shakf_multitau": {"x0": "truth", "trajectory_every": 0},
    "nekf_multitau": {"x0": "truth", "trajectory_every": 0},
    "arma_em": {},
    "whittle": {},
}


def _quiet_fit(est, rate, dt):
    """``est.fit(rate, dt)`` without warnings (the benchmarks time fits, not their messages)."""
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore")
        return est.fit(rate, dt)


class EstimatorScaling:
    """Every registered estimator's ``fit`` (terms NBK) on an ADIS16405-like 100 Hz record."""

    params = [sorted(ESTIMATOR_SETTINGS), SIZES[:-1] + [3 * 10**7]]
    quick_params = [["wls", "shakf"], [10**4]]
    param_names = ["estimator", "n"]
    repeats = 3
    quick_repeats = 1
    budget_s = 15.0
    _records: dict = {}

    def setup(self, estimator, n):
        from avbench import estimators
        from avbench.noise_models import presets

        if estimator not in estimators.names():
            raise NotImplementedError
        g = presets.get("ADIS16405_Y")
        key = n
        if key not in EstimatorScaling._records:
            EstimatorScaling._records.clear()
            EstimatorScaling._records[key] = g.simulate(n, np.random.default_rng(6))
        self.rate, self.dt = EstimatorScaling._records[key], g.dt
        settings = {"terms": "NBK"}
        for k, v in ESTIMATOR_SETTINGS.get(estimator, {}).items():
            settings[k] = {c: float(g.coefficients[c]) for c in "NBK"} if v == "truth" else v
        try:
            self.est = estimators.get(estimator, **settings)
        except (TypeError, ValueError):
            settings.pop("terms")
            self.est = estimators.get(estimator, **settings)
        _quiet_fit(self.est, self.rate[: min(n, 5000)], self.dt)  # compile / load kernels

    def time_fit(self, estimator, n):
        _quiet_fit(self.est, self.rate, self.dt)

    def teardown(self, estimator, n):
        self.rate = None


class OnlineKernels:
    """Compiled online-filter kernels vs the plain-NumPy per-sample references (authors' modules)."""

    params = [["shakf_nekf", "arma_em"]]
    param_names = ["module"]

    def setup(self, module):
        self.quick = False

    def track_kernel_vs_reference(self, module):
        return _online_rows(module, self.quick)


def _online_rows(module, quick):
    """The samples/s of a kernel and of its NumPy reference, and their ratio, as one flat row."""
    if module == "shakf_nekf":
        from avbench.bench import online_filters

        out = {}
        for row in online_filters.run(quick=quick):
            f = row["filter"]
            out[f"{f}_kernel_samples_per_s"] = row["kernel_samples_per_s"]
            out[f"{f}_reference_samples_per_s"] = row["reference_samples_per_s"]
            out[f"{f}_ratio"] = row["speedup"]
        return out
    from avbench.bench import arma_em

    r = arma_em.run(quick=quick)["arma_em"]
    return {
        "arma_em_kernel_samples_per_s": r["kernel_samples_per_s"],
        "arma_em_batch_samples_per_s": r["batch_samples_per_s"],
        "arma_em_reference_samples_per_s": r["reference_samples_per_s"],
        "arma_em_ratio": r["ratio"],
    }


class QuickOnlineKernels(OnlineKernels):
    """:class:`OnlineKernels` on the small sizes of the modules' own quick runs (``--quick``)."""

    def setup(self, module):
        self.quick = True


class FitCost:
    """Curve fits with their poor-fit check, and GMWM, on a 4 h, 10 Hz record (lv2015's SRS2000,
    144 000 samples) against the octave overlapping AV of that record (ratio = AV / fit; the target
    is fit <= 20x the AV, i.e. ratio >= 0.05, for the least-squares family, and gmwm <= 0.3 s).
    ``ls@octave`` rows use the overlapping octave grid (17 points); the others their defaults. The
    fit check's model covariance is computed once per grid and record length (kept between fits, as
    in a study's worker): the first fit of a setup is not timed."""

    params = [["ols", "wls", "wls_edf", "ols@octave", "wls@octave", "wls_edf@octave", "nnls_rel", "log_fit",
               "slope_lines", "gmwm"]]
    quick_params = [["wls@octave", "nnls_rel"]]
    param_names = ["estimator"]
    repeats = 5
    quick_repeats = 1
    baselines = {"time_fit": ("baseline_octave_av", "overlapping octave AV of the record")}

    def setup(self, estimator):
        from avbench import estimators
        from avbench.noise_models import presets

        g = presets.get("SRS2000")
        self.rate, self.dt = g.simulate(144_000, np.random.default_rng(25)), g.dt
        name, _, grid = estimator.partition("@")
        settings = {"taus": "octave", "overlapping": True} if grid == "octave" else {}
        self.est = estimators.get(name, **settings)
        _quiet_fit(self.est, self.rate, self.dt)  # kernels, the check's per-shape integrals
        self.baseline_octave_av(estimator)

    def time_fit(self, estimator):
        _quiet_fit(self.est, self.rate, self.dt)

    def baseline_octave_av(self, estimator):
        from avbench.estimators.allan.variance import allan_variance

        allan_variance(self.rate, self.dt, taus="octave", overlapping=True)

    def teardown(self, estimator):
        self.rate = None


def _adis_record(n, seed=6):
    from avbench.noise_models import presets

    g = presets.get("ADIS16405_Y")
    return g.simulate(n, np.random.default_rng(seed)), g.dt


def mle_statsmodels_path(rate, dt, model="WN+GM+RW", max_blocks=50_000, maxiter=200):
    """The block-mean likelihood fitted through statsmodels (the baseline of :class:`MleFit`).

    Model-weighted GMWM start, the block rule of ``mle``, statsmodels' ``MLEModel`` fit (L-BFGS with
    forward-difference scores) and its finite-difference Hessian. Returns (log-parameters, llf).
    """
    from statsmodels.tools.sm_exceptions import PrecisionWarning

    from avbench.estimators.likelihood._mle_model import BlockMeanModel
    from avbench.estimators.likelihood.gmwm import GMWM, parse_model
    from avbench.estimators.likelihood.mle import _pow2_at_least, block_means, gmwm_start_values

    latents = parse_model(model)
    m = max(1, math.ceil(rate.size / max_blocks))
    start = GMWM(model=model, min_m=_pow2_at_least(m)).fit(rate, dt)
    x0, tc = gmwm_start_values(start, latents, dt)
    if tc is not None:
        m = max(1, min(m, int(tc / (5 * dt))))
    y = block_means(rate, m)
    mod = BlockMeanModel(y, latents, m, dt)
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", PrecisionWarning)
        res = mod.fit(start_params=x0, method="lbfgs", maxiter=maxiter, disp=False, optim_complex_step=False,
                      cov_type="approx", cov_kwds={"approx_complex_step": False, "approx_centered": True})
        res.cov_params()
    return res.params, res.llf


class MleFit:
    """``mle`` (defaults) on 4 h at 100 Hz: compiled likelihood vs :func:`mle_statsmodels_path`."""

    params = [[1_440_000]]
    quick_params = [[20_000]]  # plumbing only, on a short record (keeps the default suite short)
    param_names = ["n"]
    repeats = 3
    quick_repeats = 1
    budget_s = 300.0
    baselines = {"time_fit": ("baseline_statsmodels",
                              "model-weighted GMWM start + statsmodels MLEModel fit + Hessian")}

    def setup(self, n):
        from avbench import estimators
        self.rate, self.dt = _adis_record(n)
        self.est = estimators.get("mle")
        _quiet_fit(self.est, self.rate[:20_000], self.dt)  # compile / load the kernel

    def time_fit(self, n):
        _quiet_fit(self.est, self.rate, self.dt)

    def baseline_statsmodels(self, n):
        from avbench.estimators.threads import one_blas_thread

        with one_blas_thread():  # as the fit it is compared with (both single-threaded BLAS)
            mle_statsmodels_path(self.rate, self.dt)

    def teardown(self, n):
        self.rate = None


class MleFitDrift:
    """``mle`` with model QN+WN+GM+RW+DR on 2 h of ADIS16405_X at 100 Hz: the augmented Kalman filter
    (the default with a drift) against the exact initial filter (``_loglike_method = "exact_initial"``,
    whose covariance never reaches its steady state with a drift); same optimiser, start and Hessian."""

    params = [[720_000]]
    quick_params = [[20_000]]  # plumbing only, on a short record (keeps the default suite short)
    param_names = ["n"]
    repeats = 3
    quick_repeats = 1
    budget_s = 300.0
    baselines = {"time_fit": ("baseline_exact_initial",
                              "same fit through the exact initial (diffuse) Kalman filter")}
    model = "QN+WN+GM+RW+DR"

    def setup(self, n):
        from avbench import estimators
        from avbench.noise_models import presets

        g = presets.get("ADIS16405_X")
        self.rate, self.dt = g.simulate(n, np.random.default_rng(1)), g.dt
        self.est = estimators.get("mle", model=self.model)
        self.exact = estimators.get("mle", model=self.model)
        self.exact._loglike_method = "exact_initial"
        for est in (self.est, self.exact):
            _quiet_fit(est, self.rate[:20_000], self.dt)  # compile / load the kernels

    def time_fit(self, n):
        _quiet_fit(self.est, self.rate, self.dt)

    def baseline_exact_initial(self, n):
        _quiet_fit(self.exact, self.rate, self.dt)

    def teardown(self, n):
        self.rate = None


class WhittleFit:
    """``whittle`` (defaults: QNBKR with BIC term selection; and all five terms without selection) on 4 h
    at 100 Hz, against one real FFT of the same record (the O(n log n) floor of any Whittle fit)."""

    params = [[1_440_000]]
    quick_params = [[40_000]]
    param_names = ["n"]
    repeats = 5
    quick_repeats = 1
    budget_s = 120.0
    baselines = {"time_fit": ("baseline_rfft", "numpy.fft.rfft of the record (one FFT)"),
                 "time_fit_full": ("baseline_rfft", "numpy.fft.rfft of the record (one FFT)")}

    def setup(self, n):
        from avbench import estimators
        self.rate, self.dt = _adis_record(n)
        self.est = estimators.get("whittle")
        self.full = estimators.get("whittle", select=False)
        for est in (self.est, self.full):
            _quiet_fit(est, self.rate[:20_000], self.dt)  # compile / load the kernels

    def time_fit(self, n):
        _quiet_fit(self.est, self.rate, self.dt)

    def time_fit_full(self, n):
        _quiet_fit(self.full, self.rate, self.dt)

    def baseline_rfft(self, n):
        np.fft.rfft(self.rate)

    def teardown(self, n):
        self.rate = None


class OnlineDefaults:
    """shakf / nekf ``fit`` with DEFAULT settings (x0 from an AV fit, decimated trajectory) vs the
    same filter keeping its full per-sample trajectory (``trajectory_every=1``), on an ADIS16405_Y-like record."""

    params = [["shakf", "nekf"], [1_000_000]]
    quick_params = [["shakf", "nekf"], [20_000]]
    param_names = ["estimator", "n"]
    repeats = 3
    quick_repeats = 1
    budget_s = 120.0
    baselines = {"time_fit_default": ("baseline_full_trajectory", "same filter with trajectory_every=1")}

    def setup(self, estimator, n):
        from avbench import estimators
        self.rate, self.dt = _adis_record(n, seed=7)
        self.est = estimators.get(estimator, terms="NBK")
        self.full = estimators.get(estimator, terms="NBK", trajectory_every=1)
        for est in (self.est, self.full):
            _quiet_fit(est, self.rate[:70_000], self.dt)  # compile / load kernels

    def time_fit_default(self, estimator, n):
        _quiet_fit(self.est, self.rate, self.dt)

    def baseline_full_trajectory(self, estimator, n):
        _quiet_fit(self.full, self.rate, self.dt)

    def teardown(self, estimator, n):
        self.rate = None
