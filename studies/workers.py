"""The local worker processes of a study: started early, warm for every block, gone with their parent.

A study run with ``--jobs N`` (backend "loky") uses one pool of ``N`` processes per Python process
(a loky reusable executor). Each worker, when it starts (:func:`_init_worker`), imports the study
runner once and runs numba kernels and BLAS on one thread (the workers already fill the cores); the
compiled kernels come from numba's disk cache, so a worker pays imports and cache loads once, never
per block. ``avbench run`` calls :func:`local_workers` before it reads the config, so the workers
start while the parent is still importing.

No orphans: if the process running the study dies without shutting the pool down (SIGKILL, a
crash), its workers are re-parented; each notices within :data:`PARENT_POLL_S` seconds and exits,
and loky's resource trackers, which wait for the workers, exit with them.

This module imports only the standard library (``avbench run`` imports it before anything heavy).
"""

from __future__ import annotations

import contextlib
import importlib
import os
import pickle
import sys
import threading
import time

__all__ = ["local_workers", "started_early", "worker_count", "workers_note", "submit", "one_numba_thread", "allow_warm_state", "warm_report_imports",
           "warm_parent_report_imports",
           "PARENT_POLL_S", "IDLE_WORKER_TIMEOUT_S"]

#: seconds between two checks, in a local worker, that the process running the study is alive
PARENT_POLL_S = 0.5
#: seconds an idle local worker waits for more blocks before it exits (it is reused meanwhile)
IDLE_WORKER_TIMEOUT_S = 300


#: memory a local worker keeps by design once it has fitted: the caches bounded in their own modules
#: (the covariance's Haar gains, up to 320 MiB, ``estimators.allan.covariance.GAIN_CACHE_BYTES``; the
#: simulators' FIR spectra; numba's loaded kernels) and the allocator's arenas. A FOG study's worker
#: holds 296 MB more after its first block than before it, and the same after its 2nd to 4th.
WARM_STATE_BYTES = 1 << 30

#: modules each local worker imports as it starts, by name: the runner, which hands the workers their
#: blocks (and imports this module), so the first block does not pay for its imports
WARM_IMPORTS = ("avbench.studies.runner",)
#: what a local worker imports when it has no block left: the report's figures (matplotlib), which the
#: workers draw while the study's process writes the tables
REPORT_IMPORTS = ("avbench.studies.figures",)


def worker_count(n_jobs: int, work: int | None = None) -> int:
    """Processes for ``n_jobs``: itself if positive, else ``cpus + 1 + n_jobs`` (-1 = all cores), at most
    the cores and, given ``work`` (blocks to compute), at most that many: a process more than the cores
    only competes for them (each worker also pays its imports and kernel loads), and one more than the
    blocks idles after paying them (``--jobs 64`` on 2 cores: 85.6 s against 6.0 s for ``--jobs 2``)."""
    cpus = os.cpu_count() or 1
    n = min(n_jobs if n_jobs > 0 else max(1, cpus + 1 + n_jobs), cpus)
    return n if work is None else max(1, min(n, work))


def workers_note(n_jobs: int, work: int) -> str | None:
    """What :func:`worker_count` capped, as a line for the user (None when it ran ``n_jobs`` as asked)."""
    n, cpus = worker_count(n_jobs, work), os.cpu_count() or 1
    if n_jobs <= 0 or n == n_jobs:
        return None
    return f"--jobs {n_jobs}: {n} worker process(es), at most one per core ({cpus}) and per block of work ({work})"


def local_workers(n_jobs: int, start: bool = False):
    """The pool of warm local worker processes for ``n_jobs`` (a loky reusable executor).

    The same pool is returned (and reused) for every call with the same ``n_jobs`` in this process;
    ``start=True`` starts its processes now instead of at the first block.
    """
    from joblib.externals.loky import get_reusable_executor

    workers = worker_count(n_jobs)
    threads = str(max(1, (os.cpu_count() or 1) // workers))
    executor = get_reusable_executor(
        max_workers=workers,
        timeout=IDLE_WORKER_TIMEOUT_S,
        initializer=_init_worker,
        initargs=(os.getpid(),),
        env={v: threads for v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")},
    )
    if start:
        executor.submit(os.getpid)  # loky starts every worker at the first submission
    return executor


@contextlib.contextmanager
def started_early(n_jobs: int | None):
    """Start the local pool for ``n_jobs`` now (``None``: do nothing); stop it at once on an error.

    An error (a bad config, Ctrl-C) must not wait for workers that are still importing.
    """
    if n_jobs is None:
        yield None
        return
    executor = local_workers(n_jobs, start=True)
    try:
        yield executor
    except BaseException:
        executor.shutdown(wait=False, kill_workers=True)
        raise


def _init_worker(parent_pid: int) -> None:
    """Run once in each local worker as it starts: exit with the parent, one thread, warm imports."""
    if os.getppid() != parent_pid:  # the parent died before this worker started
        os._exit(1)

    def watch():
        while True:
            time.sleep(PARENT_POLL_S)
            if os.getppid() != parent_pid:
                os._exit(1)

    threading.Thread(target=watch, name="avbench-exit-with-parent", daemon=True).start()
    one_numba_thread()
    allow_warm_state()
    for module in WARM_IMPORTS:  # imported once here, not with the first block
        importlib.import_module(module)


#: what the study's own process imports for its tables (pandas-heavy report modules) in a thread
#: once the last block is queued, while the workers compute (a study's config does not import it: the
#: least-squares fits check their settings without a trial fit; results/bench/README.md)
PARENT_REPORT_IMPORTS = ("avbench.studies.report", "avbench.studies.scoring")


def warm_report_imports(modules=REPORT_IMPORTS) -> None:
    """Import ``modules`` (:data:`REPORT_IMPORTS`: run by an idle local worker after the last block was
    queued; :data:`PARENT_REPORT_IMPORTS`: by a thread of the study's process at that moment)."""
    for module in modules:
        importlib.import_module(module)


def warm_parent_report_imports() -> threading.Thread:
    """Start a daemon thread importing :data:`PARENT_REPORT_IMPORTS` (an import another thread asks for
    meanwhile waits for it: Python's per-module import lock)."""
    t = threading.Thread(target=warm_report_imports, args=(PARENT_REPORT_IMPORTS,), name="avbench-warm-report",
                         daemon=True)
    t.start()
    return t


def allow_warm_state() -> None:
    """Raise loky's leak threshold in this worker to :data:`WARM_STATE_BYTES`.

    loky measures a worker's memory after its first call (here the start-up ``os.getpid``) and stops
    the worker, with a ``UserWarning`` about a memory leak, once it holds 300 MB more, which a study's
    worker does after its first block by its caches alone; another worker would then pay the imports and
    kernel loads again. A leak beyond the warm state still stops the worker.
    """
    from joblib.externals.loky import process_executor

    process_executor._MAX_MEMORY_LEAK_SIZE = max(process_executor._MAX_MEMORY_LEAK_SIZE, WARM_STATE_BYTES)


def one_numba_thread() -> None:
    """Workers already fill the cores: numba's parallel kernels in each would oversubscribe them."""
    try:
        import numba

        numba.set_num_threads(1)
    except (ImportError, ValueError):  # pragma: no cover
        pass


def submit(executor, fn, *args):
    """``executor.submit(fn, *args)`` for a local worker that may have started before this process put a
    folder on ``sys.path`` (``avbench run`` starts its workers before it reads the config, whose
    estimator may be a module beside it): the call travels pickled and is unpickled in the worker after
    :func:`_on_parent_path` adds the entries the worker lacks."""
    return executor.submit(_on_parent_path, list(sys.path), pickle.dumps((fn, args), protocol=pickle.HIGHEST_PROTOCOL))


def _on_parent_path(paths: list, call: bytes):
    """In a local worker: put first on ``sys.path`` the parent's entries it lacks, then run the call."""
    missing = [p for p in paths if p not in sys.path]
    if missing:
        sys.path[:0] = missing
        importlib.invalidate_caches()
    fn, args = pickle.loads(call)
    return fn(*args)
