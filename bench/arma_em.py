"""Throughput of ``arma_em``: compiled E-K recursive-EM kernel vs the plain-NumPy per-sample reference.

:func:`bench_arma_em` times the numba kernel (:func:`estimators._arma_em_kernels.ek_run`) on
``n_samples`` of an ADIS16405_Y record (N + B + K, the 2-state model of Miao et al. 2015, eq. 63)
and the NumPy reference (:mod:`estimators._arma_em_reference`) on a shorter slice of the same
record, both with the recursive M-step after every sample (the paper's setting), takes the median
of ``repeats`` runs and returns samples/s and their ratio; it also times a batch pass (parameters
fixed, no M-step). One thread; the kernel is compiled before timing.
``python -m bench.arma_em`` prints the numbers.
"""

from __future__ import annotations

import time

import numpy as np

__all__ = ["bench_arma_em", "run"]


def _filter(g, y, recursive):
    from estimators.arma_em import EKFilter, initial_model

    coefs = {c: g.coefficients[c] for c in "NBK"}
    A, C, Q, R = initial_model(coefs, 100.0, g.dt, "NBK", "eq63")
    s = float(np.sqrt(R[0]))
    f = EKFilter(A.copy(), C / s, Q.copy(), R / s**2)
    f.start(float(y[0] / s), np.eye(2) / float(f.C @ f.C))
    return f, y[1:] / s


def _median_rate(g, y, repeats, recursive, engine):
    times = []
    for _ in range(repeats):
        f, ys = _filter(g, y, recursive)
        t0 = time.perf_counter()
        f.run(ys, recursive=recursive, warmup=100, update_every=1, trace_every=0, engine=engine)
        times.append(time.perf_counter() - t0)
    return len(ys) / float(np.median(times))


def bench_arma_em(n_samples=1_000_000, n_reference=2_000, repeats=5, seed=0) -> dict:
    """Samples/s of the compiled kernel and of the NumPy reference, and their ratio.

    Returns
    -------
    dict
        ``kernel_samples_per_s`` (recursive EM, M-step every sample), ``batch_samples_per_s``
        (fixed parameters), ``reference_samples_per_s``, ``ratio`` (kernel / reference, both
        recursive), ``n_samples``, ``n_reference``, ``repeats``.
    """
    from noise_models import presets

    g = presets.get("ADIS16405_Y")
    y = g.simulate(n_samples, np.random.default_rng(seed))
    _median_rate(g, y[:1000], 1, True, "numba")  # compile / load the kernel
    _median_rate(g, y[:1000], 1, False, "numba")
    kernel = _median_rate(g, y, repeats, True, "numba")
    batch = _median_rate(g, y, repeats, False, "numba")
    reference = _median_rate(g, y[:n_reference], max(1, repeats // 2), True, "reference")
    return {
        "kernel_samples_per_s": kernel,
        "batch_samples_per_s": batch,
        "reference_samples_per_s": reference,
        "ratio": kernel / reference,
        "n_samples": n_samples,
        "n_reference": n_reference,
        "repeats": repeats,
    }


def run(quick: bool = False) -> dict:
    """The benchmark at full size, or a small one (``quick``) for CI (no timing assertions)."""
    if quick:
        return {"arma_em": bench_arma_em(n_samples=20_000, n_reference=300, repeats=1)}
    return {"arma_em": bench_arma_em()}


if __name__ == "__main__":  # pragma: no cover
    import sys

    for name, res in run(quick="--quick" in sys.argv).items():
        print(
            f"{name}: kernel {res['kernel_samples_per_s'] / 1e6:.2f} M samples/s (recursive EM), "
            f"{res['batch_samples_per_s'] / 1e6:.2f} M samples/s (batch pass); "
            f"NumPy reference {res['reference_samples_per_s']:.0f} samples/s; ratio {res['ratio']:.0f}x"
        )
