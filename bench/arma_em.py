"""Throughput of ``arma_em``: compiled E-K recursive-EM kernel vs the plain-NumPy per-sample reference.

:func:`bench_arma_em` simulates ``n_samples`` of an ADIS16405_Y record (N + B + K, the 2-state
model of Miao et al. 2015, eq. 63) and, in the same run (median of ``repeats``):

* the numba kernel (:func:`avbench.estimators.online._arma_em_kernels.ek_run`) with the recursive M-step after
  every sample (the paper's setting), and a batch pass (parameters fixed, no M-step);
* the NumPy reference (:mod:`avbench.estimators.online._arma_em_reference`) on a shorter slice, recursive;
* what a user runs: ``ArmaEM()`` with default settings, fed on line with ``partial_fit`` in
  chunks of ``chunk`` samples (recursive EM every sample, trajectory every 1000 samples,
  start from the Allan-variance fit of the first chunk), and ``fit`` in batch mode
  (``recursive=False``, one pass);
* a raw baseline: a compiled scalar Kalman filter (random walk in white noise) over the same
  samples, the cheapest per-sample filter, so that the ratios cancel the machine's load.

It returns samples/s, the ratios and the 1-minute load average. One thread; kernels are compiled
before timing. ``python -m avbench.bench.arma_em`` prints the numbers.
"""

from __future__ import annotations

import os
import time
import warnings

import numpy as np

__all__ = ["bench_arma_em", "run"]


def _filter(g, y, recursive):
    from avbench.estimators.online.arma_em import EKFilter, initial_model, prior_covariance

    coefs = {c: g.coefficients[c] for c in "NBK"}
    A, C, Q, R = initial_model(coefs, 100.0, g.dt, "NBK", "eq63")
    s = float(np.sqrt(R[0]))
    f = EKFilter(A.copy(), C / s, Q.copy(), R / s**2)
    f.start(float(y[0] / s), prior_covariance(f.A, f.Q, len(y)))
    return f, y[1:] / s


def _median_rate(g, y, repeats, recursive, engine):
    times = []
    for _ in range(repeats):
        f, ys = _filter(g, y, recursive)
        t0 = time.perf_counter()
        f.run(ys, recursive=recursive, warmup=100, update_every=1, trace_every=0, engine=engine)
        times.append(time.perf_counter() - t0)
    return len(ys) / float(np.median(times))


def _estimator_rate(y, dt, repeats, chunk, **settings):
    """Samples/s of ArmaEM(**settings): partial_fit in chunks (``chunk``) or one fit (None)."""
    from avbench.estimators.online.arma_em import ArmaEM

    times = []
    for _ in range(repeats):
        est = ArmaEM(**settings)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            t0 = time.perf_counter()
            if chunk is None:
                est.fit(y, dt)
            else:
                for lo in range(0, len(y), chunk):
                    est.partial_fit(y[lo : lo + chunk], dt)
            times.append(time.perf_counter() - t0)
    return len(y) / float(np.median(times))


def _raw_kalman():
    from numba import njit

    @njit(cache=True)
    def kalman_rw(y, q, r):  # scalar random walk in white noise: the cheapest per-sample filter
        x, p, ll = 0.0, 1.0, 0.0
        for t in range(y.shape[0]):
            p += q
            s = p + r
            e = y[t] - x
            k = p / s
            x += k * e
            p = (1.0 - k) * p
            ll += e * e / s
        return ll

    return kalman_rw


def _raw_rate(y, repeats):
    f = _raw_kalman()
    f(y[:100], 1e-6, 1.0)
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        f(y, 1e-6, 1.0)
        times.append(time.perf_counter() - t0)
    return len(y) / float(np.median(times))


def bench_arma_em(n_samples=1_000_000, n_reference=2_000, repeats=5, chunk=100_000, seed=0) -> dict:
    """Samples/s of the compiled kernel, of the estimator with default settings, of the NumPy
    reference and of a raw scalar Kalman filter, with their ratios and the load average.

    Returns
    -------
    dict
        ``kernel_samples_per_s`` (recursive EM, M-step every sample), ``batch_samples_per_s``
        (kernel, fixed parameters), ``reference_samples_per_s``, ``ratio`` (kernel / reference,
        both recursive), ``online_default_samples_per_s`` (``ArmaEM().partial_fit`` in chunks),
        ``batch_default_samples_per_s`` (``ArmaEM(recursive=False).fit``), ``raw_samples_per_s``
        and ``online_over_raw`` (the scalar Kalman baseline), ``load_avg_1min``, ``n_samples``,
        ``n_reference``, ``repeats``, ``chunk``.
    """
    from avbench.noise_models import presets

    g = presets.get("ADIS16405_Y")
    y = g.simulate(n_samples, np.random.default_rng(seed))
    _median_rate(g, y[:1000], 1, True, "numba")  # compile / load the kernels
    _median_rate(g, y[:1000], 1, False, "numba")
    _estimator_rate(y[:5000], g.dt, 1, 2500)
    load = os.getloadavg()[0]
    raw = _raw_rate(y, repeats)
    kernel = _median_rate(g, y, repeats, True, "numba")
    batch = _median_rate(g, y, repeats, False, "numba")
    online = _estimator_rate(y, g.dt, repeats, chunk)
    batch_default = _estimator_rate(y, g.dt, repeats, None, recursive=False)
    reference = _median_rate(g, y[:n_reference], max(1, repeats // 2), True, "reference")
    return {
        "kernel_samples_per_s": kernel,
        "batch_samples_per_s": batch,
        "reference_samples_per_s": reference,
        "ratio": kernel / reference,
        "online_default_samples_per_s": online,
        "batch_default_samples_per_s": batch_default,
        "raw_samples_per_s": raw,
        "online_over_raw": online / raw,
        "load_avg_1min": 0.5 * (load + os.getloadavg()[0]),
        "n_samples": n_samples,
        "n_reference": n_reference,
        "repeats": repeats,
        "chunk": chunk,
    }


def run(quick: bool = False) -> dict:
    """The benchmark at full size, or a small one (``quick``) for CI (no timing assertions)."""
    if quick:
        return {"arma_em": bench_arma_em(n_samples=20_000, n_reference=300, repeats=1, chunk=5_000)}
    return {"arma_em": bench_arma_em()}


if __name__ == "__main__":  # pragma: no cover
    import sys

    for name, res in run(quick="--quick" in sys.argv).items():
        print(
            f"{name} (load {res['load_avg_1min']:.1f}): kernel {res['kernel_samples_per_s'] / 1e6:.2f} M samples/s "
            f"(recursive EM), {res['batch_samples_per_s'] / 1e6:.2f} M samples/s (batch pass); "
            f"ArmaEM() default online (partial_fit, chunks of {res['chunk']}) "
            f"{res['online_default_samples_per_s'] / 1e6:.2f} M/s, batch fit {res['batch_default_samples_per_s'] / 1e6:.2f} M/s; "
            f"raw scalar Kalman {res['raw_samples_per_s'] / 1e6:.1f} M/s (online/raw {res['online_over_raw']:.3f}); "
            f"NumPy reference {res['reference_samples_per_s']:.0f} samples/s; ratio {res['ratio']:.0f}x"
        )
