"""The benchmarks (asv-style classes run by :mod:`avbench.bench.harness`; ``python -m bench`` runs them all).

Every speed claim is a ratio against a baseline timed in the same loop:

* ``Generation`` -- the composite five-term gyro (Q + N + B + K + R) against NumPy's own
  standard-normal generator drawing the same number of normals (4 per sample: Q, N, B, K; R is
  deterministic) into a preallocated, already-touched buffer: the physical limit of any Gaussian
  generator (the gyro, which must allocate its output, also pays the page faults). B is a Gauss-Markov term or the
  flicker (Kasdin-Walter) filter with ``tau_max`` = 1 h at 100 Hz (360 000 taps).
* ``AllanOverlapping`` -- :func:`avbench.estimators.allan_variance` (overlapping, octave taus) against
  allantools ``oadev`` on the same data, values checked equal to 1e-10 relative.
* ``Deviations`` -- Hadamard, modified, total and Theo1 variances
  (:mod:`avbench.estimators.allan.deviations`) against allantools at octave taus, same values.
* ``AllanEngine`` -- non-overlapping octave AV and :class:`StreamingAllan` (scaling only).
* ``EstimatorScaling`` -- every estimator's ``fit`` against n (linear cost), an ADIS16405-like
  100 Hz record (N, B, K), octave grids; larger n are skipped once a fit takes > ``budget_s``.
* ``FitCost`` -- each curve fit with its poor-fit check, and GMWM, on lv2015's 4 h, 10 Hz record
  against the octave AV of that record (the fit check's cost, issue 25).
* ``OnlineKernels`` -- SHAKF / NEKF / ARMA-EM kernels against their plain-NumPy per-sample
  references (:mod:`avbench.bench.online_filters`, :mod:`avbench.bench.arma_em`).
* ``StreamingMemory`` -- peak memory of Gyro.stream + StreamingAllan + SHAKF partial_fit, in a child
  process, for growing n (flat in n), up to 24 h at 1 kHz (8.64e7 samples).
* ``AllanKernel`` -- the overlapping AV against its own path before issue 14 (same kernel; check,
  mean and buffer handling before) and against the bound of one cumulative sum + one read per tau.
* ``OnlineDefaults`` -- shakf / nekf with default settings against the full per-sample trajectory.
* ``MleFit`` -- ``mle`` (compiled likelihood) against the statsmodels path it replaced, 4 h at 100 Hz.
* ``MleFitDrift`` -- ``mle`` with the full latent model QN+WN+GM+RW+DR (as in the studies) on 2 h of
  the ADIS16405_X preset: the augmented Kalman filter against the exact initial filter of before.
* ``WhittleFit`` -- ``whittle`` (with and without term selection) on 4 h at 100 Hz against one FFT.
* ``FlickerPreset`` -- the ADIS16405 preset (flicker B, tau_max = 2x the record) at 1e6 samples.
* ``ReadRecording`` -- reading a 7-column CSV (time + 6 IMU axes) through ``avbench estimate``'s
  reader (:mod:`avbench.recordings.readers`) against a bare ``pandas.read_csv`` of the same file,
  and the reader's peak memory over the numeric data (:mod:`avbench.bench.recordings`).
* ``EstimateEndToEnd`` -- ``avbench estimate`` with its defaults on an EuRoC-style CSV, whole process
  (reading included): 1 h at 100 Hz and 2 h at 400 Hz, 6 axes, beside the cost of reading the file,
  of the six Allan variances and of each default method's fits (:mod:`avbench.bench.estimate_e2e`).
* ``EstimateMemory`` -- peak RSS of ``avbench estimate`` (nnls_rel, gmwm) on an n-sample .npy in a
  child process, against the record's size, up to 5e7 samples (400 MB).
* ``LvStudy`` -- wall time of ``avbench run studies/lv2015.toml`` with ``--jobs 1`` and ``--jobs 2``
  from fresh processes, alternated (full mode only), and where a replicate's time goes.
* ``StartUp`` / ``FirstCall`` -- ``avbench --help`` and every subcommand's help against the bare
  interpreter, CPU time of ``from avbench import estimators, noise_models``, and each filter's first-ever compile
  and second-process first-call cost (:mod:`avbench.bench.startup`).
"""

from __future__ import annotations

import math
import shutil
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

__all__ = [
    "Generation",
    "AllanOverlapping",
    "Deviations",
    "AllanEngine",
    "EstimatorScaling",
    "OnlineKernels",
    "StreamingMemory",
    "LvStudy",
    "AllanKernel",
    "OnlineDefaults",
    "MleFit",
    "MleFitDrift",
    "WhittleFit",
    "FlickerPreset",
    "StartUp",
    "FirstCall",
    "ReadRecording",
    "EstimateMemory",
    "EstimateEndToEnd",
    "FitCost",
    "ALL",
]

SIZES = [10**4, 10**5, 10**6, 10**7, 10**8]
QUICK_SIZES = [10**4, 10**5]
#: allantools is run up to this n (its memory and time grow fast beyond)
ALLANTOOLS_MAX_N = 10**7
ROOT = Path(__file__).resolve().parents[1]


def _repeats_for(n):
    return 5 if n < 10**8 else 3


def composite_gyro(kind: str, dt: float = 0.01):
    """The five-term gyro: Q + N + B + K + R; B Gauss-Markov ("gauss_markov") or flicker ("flicker")."""
    from avbench.noise_models import (
        AngleRandomWalk,
        BiasInstability,
        GaussMarkov,
        Gyro,
        Quantization,
        RateRamp,
        RateRandomWalk,
    )

    if kind == "gauss_markov":
        b = GaussMarkov.from_bias_instability((28.0, "deg/h"), tau_peak=100.0)
    elif kind == "flicker":
        b = BiasInstability(B=(28.0, "deg/h"), tau_max=3600.0)
    else:
        raise ValueError(f"kind: expected 'gauss_markov' or 'flicker', got {kind!r}")
    return Gyro(dt=dt, terms=[Quantization(Q=(20.0, "urad")), AngleRandomWalk(N=(2.2, "deg/sqrt(h)")), b,
                              RateRandomWalk(K=(68.0, "deg/h^1.5")), RateRamp(R=(1.0, "deg/h^2"))])


class Generation:
    """Composite gyro simulation vs raw standard normals (4 per sample)."""

    params = [["gauss_markov", "flicker"], SIZES]
    quick_params = [["gauss_markov", "flicker"], QUICK_SIZES]
    param_names = ["composite", "n"]
    repeats = 5
    budget_s = 60.0
    baselines = {"time_simulate": ("baseline_normals", "NumPy standard_normal, 4 per sample, into a reused buffer")}
    NORMALS_PER_SAMPLE = 4

    def repeats_for(self, *p):
        return _repeats_for(p[-1])

    def setup(self, composite, n):
        self.gyro = composite_gyro(composite)
        self.gyro.simulate(20_000, np.random.default_rng(0))  # compile kernels, cache the filter spectrum
        self.rng = np.random.default_rng(1)
        self.buf = np.zeros(n)  # touched once: the baseline pays no allocation or page faults

    def time_simulate(self, composite, n):
        self.gyro.simulate(n, np.random.default_rng(2))

    def baseline_normals(self, composite, n):
        for _ in range(self.NORMALS_PER_SAMPLE):
            self.rng.standard_normal(out=self.buf)

    def teardown(self, composite, n):
        self.gyro = self.buf = None


class AllanOverlapping:
    """Overlapping AV at octave taus: avbench vs allantools ``oadev`` (same values, 1e-10)."""

    params = [SIZES]
    quick_params = [QUICK_SIZES]
    param_names = ["n"]
    repeats = 5
    budget_s = 60.0
    baselines = {"time_allan_variance": ("baseline_allantools_oadev", "allantools.oadev (octave taus)")}

    def repeats_for(self, *p):
        return _repeats_for(p[-1])

    def setup(self, n):
        from avbench.estimators.allan.variance import allan_variance

        self.x = np.random.default_rng(3).standard_normal(n)
        self.x += np.cumsum(np.random.default_rng(4).standard_normal(n)) * 1e-3  # white + RRW
        allan_variance(self.x[:1000], 1.0)
        if n <= ALLANTOOLS_MAX_N:
            import allantools

            ours = allan_variance(self.x, 1.0, "octave", overlapping=True)
            t, dev, _, _ = allantools.oadev(self.x, rate=1.0, data_type="freq", taus="octave")
            k = min(len(t), len(ours.tau))
            if not (np.allclose(t[:k], ours.tau[:k]) and np.allclose(dev[:k] ** 2, ours.avar[:k], rtol=1e-10, atol=0)):
                raise AssertionError(f"allan_variance differs from allantools.oadev at n = {n}")

    def time_allan_variance(self, n):
        from avbench.estimators.allan.variance import allan_variance

        allan_variance(self.x, 1.0, "octave", overlapping=True)

    def baseline_allantools_oadev_available(self, n):
        return n <= ALLANTOOLS_MAX_N

    def baseline_allantools_oadev(self, n):
        import allantools

        allantools.oadev(self.x, rate=1.0, data_type="freq", taus="octave")

    def teardown(self, n):
        self.x = None


class Deviations:
    """The deviation family at octave taus: avbench ``deviation`` vs allantools on the same data.

    ``hvar``/``ohvar``/``mvar``/``totvar`` against ``hdev``/``ohdev``/``mdev``/``totdev`` up to 1e6; Theo1 (whose cost
    is (N - m) m / 2 per tau by definition, O(N^2) over an octave grid reaching m ~ N) and the
    modified and Hadamard total variances (15 m per window of 3m points, O(N^2) over an octave grid
    reaching m ~ N/3) against allantools' pure-Python ``theo1``/``mtotdev``/``htotdev`` on small
    records only. Values checked equal to 1e-9. Each timed call of ours includes the noise
    identification and the edf (its caches cleared every call); ``time_values`` times the values
    alone (``edf=False``). The sizes give the scaling in n.
    """

    KINDS = ["hvar", "ohvar", "mvar", "totvar", "theo1", "mtotvar", "htotvar"]
    params = [KINDS, [1000, 3000, *SIZES[:3]]]
    #: the smoke run leaves out MTOT/HTOT, whose allantools baselines take ~10 s at 1000 samples
    quick_params = [["ohvar", "mvar", "totvar", "theo1"], [10**3, 10**4]]
    param_names = ["kind", "n"]
    repeats = 3
    budget_s = 60.0
    baselines = {"time_deviation": ("baseline_allantools", "allantools hdev / ohdev / mdev / totdev / theo1 / mtotdev / "
                                                           "htotdev (octave taus)"),
                 "time_values": ("baseline_allantools", "allantools hdev / ohdev / mdev / totdev / theo1 / mtotdev / "
                                                        "htotdev (octave taus)")}
    ALLANTOOLS = {"hvar": "hdev", "ohvar": "ohdev", "mvar": "mdev", "totvar": "totdev", "theo1": "theo1", "mtotvar": "mtotdev",
                  "htotvar": "htotdev"}
    #: the O(N^2)-over-octaves statistics: largest n timed (ours) and largest n given to allantools' pure-Python loops
    QUADRATIC_MAX_N = {"theo1": 10**4, "mtotvar": 10**4, "htotvar": 10**4}
    QUADRATIC_ALLANTOOLS_MAX_N = {"theo1": 3000, "mtotvar": 1000, "htotvar": 1000}

    def repeats_for(self, kind, n):
        # the linear-cost statistics take milliseconds (allantools <= 1 s): a median of 9 alternated runs, so
        # that one preemption on a loaded machine does not decide a ratio; the O(N^2) ones 3
        return 9 if kind not in self.QUADRATIC_MAX_N and n <= 10**6 else 3

    def setup(self, kind, n):
        from avbench.estimators.allan.deviations import deviation

        if n > self.QUADRATIC_MAX_N.get(kind, n):
            raise NotImplementedError(f"{kind} costs O(n^2) over octave taus: not timed at n = {n}")
        rng = np.random.default_rng(3)
        self.x = rng.standard_normal(n) + np.cumsum(rng.standard_normal(n)) * 1e-3
        deviation(self.x[:1000], 1.0, kind)  # compile
        if self.baseline_allantools_available(kind, n) and n <= 10**5:
            import allantools

            ours = deviation(self.x, 1.0, kind, "octave")
            t_at, dev, _, _ = getattr(allantools, self.ALLANTOOLS[kind])(self.x, rate=1.0, data_type="freq",
                                                                          taus=ours.m.astype(float))
            keep = np.isin(ours.m, t_at)  # allantools drops a value of a single term (hdev's largest m)
            if not np.allclose(dev**2, ours.avar[keep], rtol=1e-9, atol=0):
                raise AssertionError(f"{kind} differs from allantools at n = {n}")

    def time_deviation(self, kind, n):
        from avbench.estimators.allan.deviations import clear_caches, deviation

        clear_caches()
        deviation(self.x, 1.0, kind, "octave")

    def time_values(self, kind, n):
        """The values alone (``edf=False``), which is all allantools computes."""
        from avbench.estimators.allan.deviations import deviation

        deviation(self.x, 1.0, kind, "octave", edf=False)

    def baseline_allantools_available(self, kind, n):
        return n <= self.QUADRATIC_ALLANTOOLS_MAX_N.get(kind, ALLANTOOLS_MAX_N)

    def baseline_allantools(self, kind, n):
        import allantools
        from avbench.estimators.allan.deviations import _cluster_sizes

        m = _cluster_sizes(kind, "octave", n, 1.0, 10, None)
        getattr(allantools, self.ALLANTOOLS[kind])(self.x, rate=1.0, data_type="freq", taus=m.astype(float))

    def teardown(self, kind, n):
        self.x = None


class AllanEngine:
    """Non-overlapping octave AV (batch) and the streaming accumulator (chunks of 2^18)."""

    params = [SIZES]
    quick_params = [QUICK_SIZES]
    param_names = ["n"]
    repeats = 5
    budget_s = 60.0

    def repeats_for(self, *p):
        return _repeats_for(p[-1])

    def setup(self, n):
        from avbench.estimators.allan.variance import StreamingAllan, allan_variance

        self.x = np.random.default_rng(5).standard_normal(n)
        allan_variance(self.x[:1000], 1.0, overlapping=False)
        StreamingAllan(1.0).update(self.x[:1000])

    def time_nonoverlapping_octave(self, n):
        from avbench.estimators.allan.variance import allan_variance

        allan_variance(self.x, 1.0, "octave", overlapping=False)

    def time_streaming_octave(self, n):
        from avbench.estimators.allan.variance import StreamingAllan

        acc = StreamingAllan(1.0)
        for i in range(0, n, 1 << 18):
            acc.update(self.x[i : i + (1 << 18)])

    def teardown(self, n):
        self.x = None


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
        rows = _online_rows(module, self.quick)
        return rows


def _online_rows(module, quick):
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
    def setup(self, module):
        self.quick = True


class StreamingMemory:
    """Peak memory (child process) of streaming generation + StreamingAllan + SHAKF, against n."""

    params = [[10**6, 10**7, 86_400_000]]
    quick_params = [[10**5, 10**6]]
    param_names = ["n"]

    def setup(self, n):
        pass

    def peakmem_stream(self, n):
        from avbench.bench.streaming import measure

        return measure(n)


class LvStudy:
    """``avbench run studies/lv2015.toml --jobs 2`` from a fresh process, and a replicate's profile."""

    params = [["lv2015"]]
    quick_params = [[]]
    param_names = ["study"]

    def setup(self, study):
        pass

    def track_wall(self, study):
        from avbench.bench.startup import study_walls

        out = Path(tempfile.mkdtemp(prefix="avbench_bench_"))
        try:  # untimed first run: warms numba's disk cache and the OS file cache, gives a tidy table
            subprocess.run([sys.executable, "-m", "avbench.cli", "run", str(ROOT / "studies" / f"{study}.toml"),
                            "--jobs", "2", "--out", str(out), "--no-progress"],
                           check=True, capture_output=True, cwd=ROOT, timeout=1800)
            t_report = _time_report(out, study)
        finally:
            shutil.rmtree(out, ignore_errors=True)
        walls = study_walls(study, rounds=2, warm=False)
        return {"wall_s": walls["wall_jobs2_s"], "report_s": t_report, **walls, **replicate_profile(study)}


def _time_report(out: Path, study: str) -> float:
    """Seconds to rewrite the finished study's tables and figures (avbench.studies.report.write_report)."""
    from avbench.studies.config import load_config
    from avbench.studies.report import read_tidy, write_report

    cfg = load_config(ROOT / "studies" / f"{study}.toml")
    tidy = read_tidy(out)
    (out / "_bench_report").mkdir()
    t0 = time.perf_counter()
    write_report(cfg, tidy, out / "_bench_report")
    return time.perf_counter() - t0


def replicate_profile(study: str = "lv2015") -> dict:
    """Where the time goes: imports (fresh process), config, one replicate's simulation and fits."""
    code = "import time; t=time.perf_counter(); import avbench.studies.runner, avbench.studies.report; print(time.perf_counter()-t)"
    imp = float(subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT,
                               check=True).stdout.strip())
    from avbench.estimators.allan.variance import memoize_allan
    from avbench.studies.config import load_config
    from avbench.studies.runner import _fit_one, replicate_rng

    t0 = time.perf_counter()
    cfg = load_config(ROOT / "studies" / f"{study}.toml")
    t_cfg = time.perf_counter() - t0
    sims, fits = [], []
    for r in range(4):
        g = cfg.gyros[r % len(cfg.gyros)]
        t0 = time.perf_counter()
        rate = g.gyro.simulate(g.n_samples, replicate_rng(cfg.seed, r % len(cfg.gyros), 100 + r))
        t1 = time.perf_counter()
        with memoize_allan():
            for e in cfg.estimators:
                _fit_one(e, g, rate, g.gyro.dt)
        sims.append(t1 - t0)
        fits.append(time.perf_counter() - t1)
    return {"imports_s": imp, "config_s": t_cfg, "replicate_simulate_s": float(np.median(sims[1:])),
            "replicate_fits_s": float(np.median(fits[1:])), "replicates": cfg.replicates * len(cfg.gyros)}


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
    """The ``mle`` fit as it was before issue 14 (the baseline of :class:`MleFit`).

    Model-weighted GMWM start, the same block rule, statsmodels' ``MLEModel`` fit (L-BFGS with
    forward-difference scores) and its finite-difference Hessian. Returns (log-parameters, llf).
    """
    from statsmodels.tools.sm_exceptions import PrecisionWarning

    from avbench.estimators.likelihood._mle_model import BlockMeanModel
    from avbench.estimators.likelihood.gmwm import GMWM, parse_model
    from avbench.estimators.likelihood.mle import _pow2_at_least, _start_values, block_means

    latents = parse_model(model)
    m = max(1, math.ceil(rate.size / max_blocks))
    start = GMWM(model=model, min_m=_pow2_at_least(m)).fit(rate, dt)
    sp = start.diagnostics_["params"]
    if "GM" in latents:
        m = max(1, min(m, int(sp["GM.tc"] / (5 * dt))))
    y = block_means(rate, m)
    mod = BlockMeanModel(y, latents, m, dt)
    x0 = _start_values(latents, sp, start.diagnostics_, dt)
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", PrecisionWarning)
        res = mod.fit(start_params=x0, method="lbfgs", maxiter=maxiter, disp=False, optim_complex_step=False,
                      cov_type="approx", cov_kwds={"approx_complex_step": False, "approx_centered": True})
        res.cov_params()
    return res.params, res.llf


class MleFit:
    """``mle`` (defaults) on 4 h at 100 Hz: compiled likelihood vs the statsmodels path of before."""

    params = [[1_440_000]]
    quick_params = [[20_000]]  # plumbing only, on a short record (keeps the default suite short)
    param_names = ["n"]
    repeats = 3
    quick_repeats = 1
    budget_s = 300.0
    baselines = {"time_fit": ("baseline_statsmodels",
                              "model-weighted GMWM start + statsmodels MLEModel fit + Hessian (mle before issue 14)")}

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
    (default with a drift) against the exact initial filter (the path before, whose covariance never
    reaches its steady state with a drift); same optimiser, start and Hessian."""

    params = [[720_000]]
    quick_params = [[20_000]]  # plumbing only, on a short record (keeps the default suite short)
    param_names = ["n"]
    repeats = 3
    quick_repeats = 1
    budget_s = 300.0
    baselines = {"time_fit": ("baseline_exact_initial",
                              "same fit through the exact initial (diffuse) Kalman filter (mle before)")}
    model = "QN+WN+GM+RW+DR"

    def setup(self, n):
        from avbench import estimators
        from avbench.noise_models import presets

        g = presets.get("ADIS16405_X")
        self.rate, self.dt = g.simulate(n, np.random.default_rng(1)), g.dt
        self.est = estimators.get("mle", model=self.model)
        self.old = estimators.get("mle", model=self.model)
        self.old._loglike_method = "exact_initial"
        for est in (self.est, self.old):
            _quiet_fit(est, self.rate[:20_000], self.dt)  # compile / load the kernels

    def time_fit(self, n):
        _quiet_fit(self.est, self.rate, self.dt)

    def baseline_exact_initial(self, n):
        _quiet_fit(self.old, self.rate, self.dt)

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
    full per-sample trajectory (the default before issue 14), on an ADIS16405_Y-like record."""

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


def allan_variance_before(rate, dt, taus="octave"):
    """The overlapping AV as computed before issue 14: ``check_record`` (boolean ``isfinite``
    temporary), a NumPy mean pass, a fresh cumulative-sum array, the same per-tau kernel."""
    from avbench.estimators.allan import _kernels as K
    from avbench.estimators.allan.variance import _result, cluster_sizes
    from avbench.estimators.validation import check_record

    rate, dt = check_record(rate, dt)
    n = rate.size
    m = cluster_sizes(taus, n, dt, 10)
    S = K.centred_cumsum(rate, float(rate.mean()), np.empty(n + 1))
    mf = m.astype(float)
    return _result(m, K.oavar_sums(S, m) / (2.0 * mf * mf * (n - 2 * mf + 1)), n, dt, True, "auto", 0.683)


class AllanKernel:
    """Overlapping octave AV: the fused path vs the path before issue 14, and the memory bound
    (one cumulative sum + one read of S per tau), all timed in this run."""

    params = [[10**6, 10**7]]
    quick_params = [[10**5]]
    param_names = ["n"]
    repeats = 7
    quick_repeats = 2
    budget_s = 60.0
    baselines = {"time_allan_variance": ("baseline_before", "check_record + mean + fresh cumsum + same kernel (before)")}

    def setup(self, n):
        from avbench.estimators.allan.variance import allan_variance

        self.x = np.random.default_rng(3).standard_normal(n)
        self.x += np.cumsum(np.random.default_rng(4).standard_normal(n)) * 1e-3
        a, b = allan_variance(self.x, 1.0), allan_variance_before(self.x, 1.0)
        if not np.allclose(a.avar, b.avar, rtol=1e-12, atol=0):
            raise AssertionError(f"fused AV differs from the path before at n = {n}")

    def time_allan_variance(self, n):
        from avbench.estimators.allan.variance import allan_variance

        allan_variance(self.x, 1.0, "octave", overlapping=True)

    def baseline_before(self, n):
        allan_variance_before(self.x, 1.0)

    def track_bound(self, n):
        """Seconds of the bound (best of 5): one compiled cumulative sum + n_taus reads of S."""
        from avbench.estimators.allan import _kernels as K
        from avbench.estimators.allan.variance import allan_variance, cluster_sizes

        m = cluster_sizes("octave", n, 1.0, 10)
        S = np.empty(n + 1)
        best = {"cumsum": math.inf, "read": math.inf, "ours": math.inf}
        for _ in range(5):
            for key, fn in (("cumsum", lambda: K.centred_cumsum(self.x, 0.0, S)), ("read", lambda: K.finite_sum(S)),
                            ("ours", lambda: allan_variance(self.x, 1.0, "octave", overlapping=True))):
                t0 = time.perf_counter()
                fn()
                best[key] = min(best[key], time.perf_counter() - t0)
        bound = best["cumsum"] + m.size * best["read"]
        return {"bound_s": bound, "cumsum_s": best["cumsum"], "read_s": best["read"], "n_taus": int(m.size),
                "ours_min_s": best["ours"], "ours_over_bound": best["ours"] / bound}

    def teardown(self, n):
        self.x = None


class FlickerPreset:
    """The ADIS16405 preset (flicker B with tau_max = 2x its record) simulating 1e6 samples, vs
    NumPy drawing the same number of normals as the gyro's white terms."""

    params = [["ADIS16405_Y"], [10**6]]
    quick_params = [["ADIS16405_Y"], [10**5]]
    param_names = ["preset", "n"]
    repeats = 5
    quick_repeats = 1
    budget_s = 60.0
    baselines = {"time_simulate": ("baseline_normals", "NumPy standard_normal, 3 per sample, into a reused buffer")}

    def setup(self, preset, n):
        from avbench.noise_models import presets

        self.g = presets.get(preset)
        self.g.simulate(1000, np.random.default_rng(0))
        self.buf = np.zeros(n)
        self.rng = np.random.default_rng(1)

    def time_simulate(self, preset, n):
        self.g.simulate(n, np.random.default_rng(2))

    def baseline_normals(self, preset, n):
        for _ in range(3):
            self.rng.standard_normal(out=self.buf)

    def teardown(self, preset, n):
        self.g = self.buf = None
class StartUp:
    """``avbench --help`` (and every subcommand's) vs the bare interpreter; CPU of the package imports."""

    params = [["fresh process"]]
    param_names = ["process"]
    help_repeats = 5

    def setup(self, process):
        pass

    def track_help(self, process):
        from avbench.bench.startup import help_times

        return help_times(self.help_repeats)

    def track_import(self, process):
        from avbench.bench.startup import import_cpu

        return import_cpu(self.help_repeats)


class QuickStartUp(StartUp):
    help_repeats = 1


class FirstCall:
    """Each estimator's first fit: first-ever (empty numba cache) and in a second process."""

    params = [["shakf", "shakf_multitau", "nekf", "nekf_multitau", "arma_em", "mle", "gmwm", "wls"]]
    quick_params = [["wls"]]
    param_names = ["estimator"]

    def setup(self, estimator):
        from avbench import estimators
        if estimator not in estimators.names():
            raise NotImplementedError
        self.settings = dict(ESTIMATOR_SETTINGS.get(estimator, {}))
        if "terms" in estimators.estimator_class(estimator)._param_names():
            self.settings["terms"] = "NBK"

    def track_first_call(self, estimator):
        from avbench.bench.startup import first_call

        return first_call(estimator, self.settings)


class ReadRecording:
    """A 7-column CSV read by ``avbench estimate``'s reader against ``pandas.read_csv`` (same file)."""

    params = [[10**5, 10**6]]
    quick_params = [[10**4]]
    param_names = ["n"]
    baselines = {"time_read": ("baseline_read", "pandas.read_csv of the same file (C engine, defaults)")}

    def setup(self, n):
        from avbench.bench.recordings import write_csv

        self.dir = Path(tempfile.mkdtemp(prefix="avbench_csv_"))
        self.path = write_csv(self.dir / "r.csv", n)
        self.n = n

    def teardown(self, n):
        shutil.rmtree(self.dir, ignore_errors=True)

    def time_read(self, n):
        from avbench.recordings.readers import read_recording

        read_recording(self.path, gyro="gyro_x,gyro_y,gyro_z", accel="acc_x,acc_y,acc_z")

    def baseline_read(self, n):
        import pandas as pd

        pd.read_csv(self.path)

    def peakmem_read(self, n):
        from avbench.bench.recordings import read_peak

        return read_peak(self.path, n)


class EstimateEndToEnd:
    """``avbench estimate FILE`` (defaults) from a fresh process, and where its time goes."""

    params = [["1h_100Hz", "2h_400Hz"]]
    quick_params = [["quick_2min_100Hz"]]
    param_names = ["case"]

    def setup(self, case):
        pass

    def track_end_to_end(self, case):
        from avbench.bench.estimate_e2e import measure

        return measure(case)


class EstimateMemory:
    """Peak RSS of ``avbench estimate`` on an n-sample .npy (child process), against the record's size."""

    params = [[10**6, 10**7, 5 * 10**7]]
    quick_params = [[10**5]]
    param_names = ["n"]

    def setup(self, n):
        pass

    def peakmem_estimate(self, n):
        from avbench.bench.recordings import estimate_peak

        return estimate_peak(n)


ALL = [Generation, AllanOverlapping, Deviations, AllanEngine, AllanKernel, EstimatorScaling, FitCost, OnlineKernels,
       OnlineDefaults, MleFit, MleFitDrift, WhittleFit, FlickerPreset, StreamingMemory, ReadRecording, EstimateMemory,
       EstimateEndToEnd, LvStudy, StartUp, FirstCall]


def classes(quick: bool) -> list:
    """The benchmark classes of a run (``quick``: the CI subset on tiny sizes)."""
    if quick:
        return [Generation, AllanOverlapping, Deviations, AllanEngine, AllanKernel, EstimatorScaling, FitCost,
                QuickOnlineKernels,
                OnlineDefaults, MleFit, MleFitDrift, WhittleFit, FlickerPreset, StreamingMemory, ReadRecording,
                EstimateMemory, QuickStartUp, FirstCall]
    return ALL


def loglog_slope(n, t) -> float:
    """Least-squares slope of log t against log n (1 = linear cost)."""
    n, t = np.asarray(n, float), np.asarray(t, float)
    ok = (n > 0) & (t > 0)
    if ok.sum() < 2:
        return math.nan
    return float(np.polyfit(np.log(n[ok]), np.log(t[ok]), 1)[0])
