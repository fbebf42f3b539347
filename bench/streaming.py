"""Peak memory of the streaming path: Gyro.stream -> StreamingAllan + SHAKF partial_fit, in chunks.

``measure(n_samples, ...)`` runs :func:`stream_record` in a *child process* (so that the peak RSS is
this workload's, not the benchmark runner's) and returns its report. The child imports avbench,
warms the compiled kernels up on a short record, notes its RSS, then streams ``n_samples`` samples
and reports

* ``peak_rss_mb`` -- the process's peak resident set (VmHWM of /proc/self/status, else
  ``resource.getrusage``) up to the end of the stream, imports included;
* ``peak_rss_with_readout_mb`` -- the same after reading ``coefficients_`` (a pandas Series: the
  stream itself does not import pandas, ``pandas_imported_by_stream`` says so);
* ``rss_after_imports_mb`` -- the peak before the stream started (libraries + warm-up);
* ``traced_peak_mb`` -- the peak of memory allocated during the stream (``tracemalloc``, which
  sees NumPy's buffers): this is the part that would grow with n if anything kept the record;
* ``rss_anon_end_mb`` / ``rss_file_end_mb`` -- private (heap) and file-backed (library code,
  shared between processes) resident memory at the end.

``python -m avbench.bench.streaming N`` runs one measurement in this process and prints it as JSON.
"""

from __future__ import annotations

import json
import subprocess
import sys
import time

__all__ = ["stream_record", "measure", "streaming_gyro"]


def streaming_gyro(dt: float = 1e-3, tau_max: float = 100.0):
    """ADIS16405-like N + flicker B + K gyro at 1 kHz (flicker filter memory ``tau_max`` s)."""
    from avbench.noise_models import AngleRandomWalk, BiasInstability, Gyro, RateRandomWalk

    return Gyro(dt=dt, terms=[AngleRandomWalk(N=(2.2, "deg/sqrt(h)")),
                              BiasInstability(B=(28.0, "deg/h"), tau_max=tau_max),
                              RateRandomWalk(K=(68.0, "deg/h^1.5"))], name="stream_1kHz")


def stream_record(n_samples: int, chunk_size: int = 1 << 18, dt: float = 1e-3, tau_max: float = 100.0,
                  seed: int = 0) -> dict:
    """Stream ``n_samples`` through StreamingAllan and SHAKF; memory and time figures (this process)."""
    import resource
    import tracemalloc
    import warnings

    import numpy as np

    from avbench import estimators
    from avbench.estimators.allan.variance import StreamingAllan

    def rss_mb():
        # VmHWM is this process's own peak; ru_maxrss can carry a parent's peak across fork/exec
        try:
            with open("/proc/self/status") as f:
                for line in f:
                    if line.startswith("VmHWM:"):
                        return int(line.split()[1]) / 1024.0
        except OSError:  # pragma: no cover - not Linux
            pass
        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0

    g = streaming_gyro(dt, tau_max)
    x0 = {c: v for t in g.terms for c, v in t.coefficients().items()}  # (Gyro.coefficients is a pandas Series)

    def run(n):
        acc = StreamingAllan(dt)
        kf = estimators.get("shakf", terms="NBK", x0=x0, trajectory_every=0)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            for chunk in g.stream(n, np.random.default_rng(seed), chunk_size=chunk_size):
                acc.update(chunk)
                kf.partial_fit(chunk, dt)
        return acc, kf

    run(min(n_samples, 1 << 16))  # compile / load kernels, fill caches
    base = rss_mb()
    tracemalloc.start()
    t0 = time.perf_counter()
    acc, kf = run(n_samples)
    secs = time.perf_counter() - t0
    _, traced_peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    av = acc.result()
    status = _proc_status()
    stream_peak = rss_mb()
    pandas_in_stream = "pandas" in sys.modules
    shakf_n = float(kf.coefficients_["N"])  # the contract's pandas Series: pandas is imported here
    return {
        "n_samples": int(n_samples),
        "chunk_size": int(chunk_size),
        "dt": dt,
        "tau_max_s": tau_max,
        "seconds": secs,
        "samples_per_s": n_samples / secs,
        "peak_rss_mb": stream_peak,
        "peak_rss_with_readout_mb": rss_mb(),
        "pandas_imported_by_stream": pandas_in_stream,
        "rss_after_imports_mb": base,
        "traced_peak_mb": traced_peak / 2**20,
        "rss_anon_end_mb": status.get("RssAnon", float("nan")),
        "rss_file_end_mb": status.get("RssFile", float("nan")),
        "n_taus": int(len(av)),
        "shakf_N": shakf_n,
        "true_N": x0["N"],
    }


def _proc_status() -> dict:
    """MB figures of /proc/self/status (RssAnon: private heap; RssFile: mapped library files)."""
    out = {}
    try:
        with open("/proc/self/status") as f:
            for line in f:
                key, _, rest = line.partition(":")
                if rest.strip().endswith("kB"):
                    out[key] = int(rest.split()[0]) / 1024.0
    except OSError:  # pragma: no cover - not Linux
        pass
    return out


def measure(n_samples: int, timeout: float = 3600.0, **kwargs) -> dict:
    """:func:`stream_record` in a fresh Python process; its report."""
    args = [sys.executable, "-m", "avbench.bench.streaming", str(int(n_samples)), json.dumps(kwargs)]
    out = subprocess.run(args, capture_output=True, text=True, timeout=timeout, check=False)
    if out.returncode != 0:
        raise RuntimeError(f"avbench.bench.streaming child failed ({out.returncode}): {out.stderr[-2000:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


if __name__ == "__main__":
    n = int(float(sys.argv[1])) if len(sys.argv) > 1 else 1_000_000
    kw = json.loads(sys.argv[2]) if len(sys.argv) > 2 else {}
    print(json.dumps(stream_record(n, **kw)))
