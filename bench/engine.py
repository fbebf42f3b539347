"""Benchmarks of the engine: the simulators and the Allan-variance family, each against a same-run baseline.

* :class:`Generation` -- the composite five-term gyro (Q + N + B + K + R) against NumPy's own
  standard-normal generator drawing the same number of normals (4 per sample: Q, N, B, K; R is
  deterministic) into a preallocated, already-touched buffer: the physical limit of any Gaussian
  generator (the gyro, which must allocate its output, also pays the page faults). B is a
  Gauss-Markov term or the flicker (Kasdin-Walter) filter with ``tau_max`` = 1 h at 100 Hz (360 000 taps).
* :class:`FlickerPreset` -- the ADIS16405 preset (flicker B, ``tau_max`` = 2x the record) at 1e6 samples.
* :class:`AllanOverlapping` -- :func:`avbench.estimators.allan_variance` (overlapping, octave taus)
  against allantools ``oadev`` on the same data, values checked equal to 1e-10 relative.
* :class:`Deviations` -- Hadamard, modified, total and Theo1 variances
  (:mod:`avbench.estimators.allan.deviations`) against allantools at octave taus, same values.
* :class:`AllanEngine` -- non-overlapping octave AV and :class:`StreamingAllan` (scaling only).
* :class:`AllanKernel` -- the overlapping AV against the same kernel behind an unfused preparation
  (:func:`allan_variance_unfused`) and against the bound of one cumulative sum + one read per tau.
* :class:`StreamingMemory` -- peak memory of Gyro.stream + StreamingAllan + SHAKF partial_fit, in a
  child process, for growing n (flat in n), up to 24 h at 1 kHz (8.64e7 samples).
"""

from __future__ import annotations

import math
import time

import numpy as np

__all__ = ["Generation", "FlickerPreset", "AllanOverlapping", "Deviations", "AllanEngine", "AllanKernel",
           "StreamingMemory", "composite_gyro", "allan_variance_unfused", "SIZES", "QUICK_SIZES", "ALLANTOOLS_MAX_N"]

SIZES = [10**4, 10**5, 10**6, 10**7, 10**8]
QUICK_SIZES = [10**4, 10**5]
#: allantools is run up to this n (its memory and time grow fast beyond)
ALLANTOOLS_MAX_N = 10**7


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


def allan_variance_unfused(rate, dt, taus="octave"):
    """The overlapping AV with an unfused preparation (the baseline of :class:`AllanKernel`):
    ``check_record`` (a boolean ``isfinite`` temporary), a NumPy mean pass and a fresh cumulative-sum
    array, then the same per-tau kernel as :func:`~avbench.estimators.allan.variance.allan_variance`."""
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
    """Overlapping octave AV: the fused path vs :func:`allan_variance_unfused`, and the memory bound
    (one cumulative sum + one read of S per tau), all timed in this run."""

    params = [[10**6, 10**7]]
    quick_params = [[10**5]]
    param_names = ["n"]
    repeats = 7
    quick_repeats = 2
    budget_s = 60.0
    baselines = {"time_allan_variance": ("baseline_unfused", "check_record + mean + fresh cumsum + same kernel (unfused)")}

    def setup(self, n):
        from avbench.estimators.allan.variance import allan_variance

        self.x = np.random.default_rng(3).standard_normal(n)
        self.x += np.cumsum(np.random.default_rng(4).standard_normal(n)) * 1e-3
        a, b = allan_variance(self.x, 1.0), allan_variance_unfused(self.x, 1.0)
        if not np.allclose(a.avar, b.avar, rtol=1e-12, atol=0):
            raise AssertionError(f"fused AV differs from the unfused path at n = {n}")

    def time_allan_variance(self, n):
        from avbench.estimators.allan.variance import allan_variance

        allan_variance(self.x, 1.0, "octave", overlapping=True)

    def baseline_unfused(self, n):
        allan_variance_unfused(self.x, 1.0)

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
