"""Throughput of the online filters: compiled kernel vs the plain-NumPy per-sample reference.

Each function times the kernel on ``n_samples`` of an ADIS16405_Y-like record and the NumPy
reference (:mod:`avbench.estimators.online._reference`) on a shorter slice of the same record (it is
~10^4 times slower), takes the median of ``repeats`` runs, and returns samples/s and their ratio.
One thread, kernels compiled before timing. ``python -m avbench.bench.online_filters`` prints the numbers.
"""

from __future__ import annotations

import time
import warnings

import numpy as np

__all__ = ["bench_shakf", "bench_nekf", "run"]


def _record(n_samples, seed):
    from avbench.noise_models import presets

    g = presets.get("ADIS16405_Y")
    return g, g.simulate(n_samples, np.random.default_rng(seed))


def _median_rate(fn, n, repeats):
    from avbench.estimators.base import IdentifiabilityWarning

    times = []
    for _ in range(repeats):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", IdentifiabilityWarning)
            t0 = time.perf_counter()
            fn()
            times.append(time.perf_counter() - t0)
    return n / float(np.median(times))


def _estimator(name, g, **settings):
    from avbench import estimators
    from avbench.estimators.base import IdentifiabilityWarning

    est = estimators.get(name, terms="NBK", x0={c: g.coefficients[c] for c in "NBK"}, trajectory_every=0, **settings)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IdentifiabilityWarning)
        est.fit(g.simulate(64, np.random.default_rng(0)), g.dt)  # compile / load the kernel
    return est


def bench_shakf(n_samples=2_000_000, n_reference=2_000, repeats=5, seed=0) -> dict:
    """SHAKF (3 states, tau0 measurement): samples/s of the kernel and of the NumPy reference."""
    from avbench.estimators.online._reference import shakf_reference

    g, rate = _record(n_samples, seed)
    est = _estimator("shakf", g)
    kernel = _median_rate(lambda: est.fit(rate, g.dt), n_samples, repeats)
    cfg = est._cfg
    short = rate[:n_reference]
    ref = _median_rate(
        lambda: shakf_reference(short, est._zinv, est._A, cfg["m"], np.ones(3), cfg["P0"], cfg["Q0"],
                                np.ones(1), cfg["b"], cfg["adapt_flags"]),
        n_reference, max(1, repeats // 2),
    )
    return {"filter": "shakf", "states": 3, "kernel_samples_per_s": kernel,
            "reference_samples_per_s": ref, "speedup": kernel / ref}


def bench_nekf(n_samples=500_000, n_reference=1_000, repeats=3, p=5, seed=0) -> dict:
    """NEKF (3 states + 2*3*p weights): samples/s of the kernel and of the NumPy reference."""
    from avbench.estimators.online._reference import nekf_reference

    g, rate = _record(n_samples, seed)
    est = _estimator("nekf", g, p=p)
    kernel = _median_rate(lambda: est.fit(rate, g.dt), n_samples, repeats)
    st, cfg = est._state, est._cfg
    nq = 3
    rng = np.random.default_rng(cfg["seed"])
    xa0 = np.concatenate([np.ones(nq), cfg["eta_scale"] * rng.standard_normal(p * nq), np.zeros(nq * p)])
    P0 = np.diag(np.r_[np.full(nq, 0.25), np.full(2 * nq * p, cfg["wP0"])])
    short = rate[:n_reference]
    ref = _median_rate(
        lambda: nekf_reference(short, est._zinv, est._A, cfg["m"], xa0, P0, st["Qbar"], st["Rbar"], nq, p),
        n_reference, 1,
    )
    return {"filter": "nekf", "states": nq + 2 * nq * p, "kernel_samples_per_s": kernel,
            "reference_samples_per_s": ref, "speedup": kernel / ref}


def run(quick: bool = False) -> list[dict]:
    """Both benchmarks (``quick``: small sizes, for smoke tests; no timing claims)."""
    if quick:
        return [bench_shakf(50_000, 300, 2), bench_nekf(20_000, 200, 1)]
    return [bench_shakf(), bench_nekf()]


if __name__ == "__main__":
    import sys

    for row in run(quick="--quick" in sys.argv):
        print(
            f"{row['filter']:6s} states={row['states']:3d}  kernel {row['kernel_samples_per_s'] / 1e6:8.3f} M samples/s"
            f"  reference {row['reference_samples_per_s'] / 1e3:8.2f} k samples/s  speedup x{row['speedup']:,.0f}"
        )
