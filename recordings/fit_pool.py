"""The axes of one record fitted in parallel: this process and worker processes share them.

One piece of work is one axis with all its methods (:func:`avbench.recordings.fit.fit_axis`: one
function fits one axis's methods, so that choices shared between the methods of an axis stay inside
it). With ``workers`` > 1, ``workers - 1`` worker processes (a loky executor, started when the fits
begin) take axes from the front of the list while this process fits axes from its back: the fits
start at once, and a worker still importing (~2-3 CPU-s: scipy, the estimators, the compiled kernels
from numba's disk cache) delays nothing -- on a record whose fits are short this process may fit
every axis itself.

**The same numbers with any number of workers.** Every axis is fitted by the same function on the
same array, with BLAS and numba's parallel kernels on one thread, here for the duration of the fits
and in every worker: the chunked sums of numba's parallel AV kernels depend on the thread count, so
the fits use one thread wherever they run. ``tests/test_fit_pool.py`` holds the fits of one worker
and of several to the same bits.

**How many workers.** :func:`worker_count`: the ``jobs`` asked for, else the cores this process may
run on, capped at the number of axes; with ``jobs`` not given, one (no worker process) for a record
shorter than :data:`PARALLEL_MIN_SAMPLES` per axis.
"""

from __future__ import annotations

import contextlib
import threading

__all__ = ["worker_count", "fit_axes", "available_cores", "one_thread", "PARALLEL_MIN_SAMPLES"]

#: with ``jobs`` not given, records shorter than this (per axis) are fitted in this process alone: their
#: fits (~0.3 s per method and axis on 2 minutes) cost less than a worker's start (~2-3 CPU-s)
PARALLEL_MIN_SAMPLES = 2**17


def available_cores() -> int:
    """The cores this process may use: joblib's count, which holds the CPU affinity and a container's CPU
    quota (a machine of 64 cores that gives this process 2 has 2)."""
    from joblib import cpu_count

    return max(1, int(cpu_count()))


def worker_count(jobs: int | None, n_axes: int, n_samples: int) -> int:
    """Processes fitting the axes (this one included): ``jobs`` if given (>= 1), else the available cores,
    or one for a record shorter than :data:`PARALLEL_MIN_SAMPLES`; never more than ``n_axes``.

    >>> worker_count(8, 6, 10), worker_count(None, 6, 100)
    (6, 1)
    """
    if jobs is not None:
        if int(jobs) < 1:
            raise ValueError(f"--jobs: expected a number of processes >= 1, got {jobs}")
        want = int(jobs)
    else:
        want = available_cores() if n_samples >= PARALLEL_MIN_SAMPLES else 1
    return max(1, min(want, n_axes))


@contextlib.contextmanager
def one_thread():
    """Numba's parallel kernels and every BLAS on one thread for the block (restored after)."""
    import numba

    from avbench.estimators.threads import one_blas_thread

    before = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        with one_blas_thread():
            yield
    finally:
        numba.set_num_threads(before)


def _fit(item):
    from avbench.recordings.fit import fit_axis

    x, dt, starts, methods, settings = item
    with one_thread():
        return fit_axis(x, dt, starts, methods, settings)


def _init_worker() -> None:
    import numba

    numba.set_num_threads(1)


def fit_axes(items, workers: int = 1, progress=None) -> list:
    """``[fit_axis(x, dt, starts, methods, settings) for each item]`` (items: those 5-tuples), in the
    items' order, on ``workers`` processes (this one included; module docstring). ``progress`` (a tqdm
    bar or None) is advanced once per method fitted."""
    items = list(items)
    results: list = [None] * len(items)

    def done(i, fits):
        results[i] = fits
        if progress is not None:
            progress.update(len(fits))

    if workers <= 1 or len(items) <= 1:
        for i, item in enumerate(items):
            done(i, _fit(item))
        return results
    from joblib.externals.loky import get_reusable_executor

    executor = get_reusable_executor(max_workers=workers - 1, initializer=_init_worker,
                                     env={v: "1" for v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")})
    lock = threading.Lock()
    ends = [0, len(items)]  # the next item from the front (the workers'), and the end of those left (this process's)
    finished = threading.Event()
    failures: list = []
    in_flight = [0]

    def take(front: bool):
        with lock:
            if ends[0] >= ends[1]:
                return None
            if front:
                ends[0] += 1
                in_flight[0] += 1
                return ends[0] - 1
            ends[1] -= 1
            return ends[1]

    def submit_next():
        i = take(front=True)
        if i is None:
            return
        future = executor.submit(_fit, items[i])
        future.add_done_callback(lambda f, i=i: collect(i, f))

    def collect(i, future):
        try:
            done(i, future.result())
        except BaseException as e:  # a worker that died: said after the fits of this process
            failures.append(e)
        with lock:
            in_flight[0] -= 1
        if not failures:
            submit_next()
        with lock:
            if in_flight[0] == 0 and (ends[0] >= ends[1] or failures):
                finished.set()

    try:
        for _ in range(workers - 1):
            submit_next()
        while (i := take(front=False)) is not None and not failures:
            done(i, _fit(items[i]))
        with lock:
            if in_flight[0] == 0:
                finished.set()
        finished.wait()
        if failures:
            raise failures[0]
    except BaseException:  # an error or Ctrl-C does not wait for the workers
        executor.shutdown(wait=False, kill_workers=True)
        raise
    executor.shutdown(wait=True, kill_workers=True)  # idle workers stopped and reaped now, not left behind
    return results
