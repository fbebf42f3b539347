"""Monte Carlo study runner: replicates in parallel, saved block by block, resumable.

Work is cut into tasks of ``block_size`` replicates of one gyro. Replicate ``r`` of gyro ``g`` draws
from ``SeedSequence(seed, spawn_key=(g, r))`` -- the same stream ``SeedSequence(seed).spawn`` would
give its (g, r) grandchild -- so every number depends only on the config and the seed, never on the
worker count, the backend or the order tasks finish in. A worker (a loky process, or a Dask worker
anywhere on a cluster) receives only the config (gyros and estimator settings, a few kB) and the
block's replicate range, simulates its replicates itself and sends back their tidy rows; the process
running the study writes each finished block atomically (temporary name, then ``os.replace``) under
``<out>/_shards/<result key>/``, the key being a hash of everything that determines the results
(``config.json`` there shows which). Rerunning the same study computes only the missing blocks, and
a changed config gets a new key instead of mixing old and new results. A worker that dies is
replaced and its blocks retried a bounded number of times (:class:`StudyError` after that).

Failures are data: an estimator that raises, reports a failure, or returns non-finite values on a
replicate is recorded in the tidy table (column ``failure``) and the study goes on.
"""

from __future__ import annotations

import contextlib
import json
import os
import sys
import threading
import time
import uuid
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from avbench.estimators.allan.variance import memoize_allan
from avbench.estimators.results import FitResult
from avbench.studies.config import StudyConfig
from avbench.studies.seeding import replicate_rng

__all__ = [
    "run_study",
    "resolve_execution",
    "replicate_rng",
    "run_block",
    "Task",
    "tasks_of",
    "collect",
    "StudyError",
    "TIDY_COLUMNS",
    "EVIDENCE_COLUMNS",
]

TIDY_COLUMNS = [
    "gyro",
    "replicate",
    "estimator",
    "coefficient",
    "true",
    "estimate",
    "nonphysical",
    "failure",
    "seconds",
    "std_err",
    "lower",
    "upper",
]
#: each term's evidence, added to the tidy rows only when an estimator of the block reports it
#: (``Coefficient.evidence``: the likelihood ratio of the model without the term and its p-value,
#: e.g. ``whittle_debiased``); studies without such an estimator keep :data:`TIDY_COLUMNS` exactly
EVIDENCE_COLUMNS = ["evidence_lr", "evidence_p"]
COEFS = ["Q", "N", "B", "K", "R"]


@dataclass(frozen=True)
class Task:
    gyro_index: int
    start: int
    stop: int

    @property
    def shard_name(self) -> str:
        return f"g{self.gyro_index:02d}_r{self.start:06d}-{self.stop:06d}.parquet"


def code_key(cfg: StudyConfig) -> str:
    """Hash of the source that computes ``cfg``'s rows: its estimators' and terms' code, a plugin's
    files, and the runner (:func:`avbench.studies.provenance.code_hashes` states the rule). Shards live
    under ``_shards/<config key>-<code key>/``: a study rerun after its code changed starts afresh
    instead of mixing blocks of two versions (the config key alone cannot see an edit)."""
    from avbench.studies.provenance import code_key as key

    return key(cfg)


def shard_folder(out, cfg: StudyConfig) -> Path:
    """Where the blocks of ``cfg`` computed by this code are saved under the output folder ``out``."""
    return Path(out) / "_shards" / f"{cfg.result_key()}-{code_key(cfg)}"


def tasks_of(cfg: StudyConfig) -> list[Task]:
    B = cfg.block_size
    return [
        Task(g, s, min(s + B, cfg.replicates))
        for g in range(len(cfg.gyros))
        for s in range(0, cfg.replicates, B)
    ]


def _modelled(est, result=None) -> list[str]:
    """Coefficients an estimator estimates: its ``terms`` setting, else those its result gives a value
    (or a non-physical one)."""
    from avbench.estimators.validation import check_terms

    terms = getattr(est, "terms", None)
    if terms is not None:
        try:
            return list(check_terms(terms))
        except ValueError:
            pass
    if result is None:
        return []
    return [c for c, e in result.coefficients.items() if np.isfinite(e.fitted) or e.status == "non-physical"]


@dataclass(frozen=True)
class _Fit:
    """One estimator on one replicate: what it models, its result, and the seconds its fit took;
    ``intervals``: False where its intervals could not be computed (its bootstrap or ``conf_int`` raised)."""

    modelled: list
    result: FitResult
    seconds: float
    intervals: bool = True


def _fit_one(spec_est, gspec, rate, dt, boot_seed=None) -> _Fit:
    """Fit one estimator; its :class:`avbench.estimators.results.FitResult` (95 % intervals, after a
    parametric bootstrap where the spec asks for one)."""
    from avbench.estimators.results import failed

    est = spec_est.make(gspec)
    t0 = time.perf_counter()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            with np.errstate(all="ignore"):
                est.fit(rate, dt)
    except Exception as e:  # failures are data
        msg = f"{type(e).__name__}: {e}".splitlines()[0][:300]
        return _Fit(_modelled(est), failed(getattr(est, "name", "?"), msg), time.perf_counter() - t0, False)
    secs = time.perf_counter() - t0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with np.errstate(all="ignore"):
            ok = True
            if getattr(spec_est, "bootstrap", 0):
                try:
                    est.bootstrap(rate.size, dt, n_draws=spec_est.bootstrap, seed=boot_seed)
                except Exception:  # an interval that cannot be computed is missing, not a failed fit
                    ok = False
            result = est.result(0.95)
    return _Fit(_modelled(est, result), result, secs, ok and result.interval_error is None)


def run_block(cfg: StudyConfig, task: Task) -> pd.DataFrame:
    """Simulate and fit every replicate of one task; the tidy rows.

    One row per modelled coefficient. ``failure`` is empty on success, else the reason: the
    exception, the estimator's own failure report, or "non-finite estimate". When an estimator
    reports evidence per term (its result's ``Coefficient.evidence``: ``lr`` and ``p_value``), the
    block's rows get :data:`EVIDENCE_COLUMNS` as well (NaN for the other estimators' rows).
    """
    gspec = cfg.gyros[task.gyro_index]
    truth = gspec.gyro.coefficients
    rows, evid = [], []
    for r in range(task.start, task.stop):
        rate = gspec.gyro.simulate(gspec.n_samples, replicate_rng(cfg.seed, task.gyro_index, r))
        with memoize_allan():  # estimators asking for the same AV curve of this record share it
            fits = [(e, _fit_one(e, gspec, rate, gspec.gyro.dt, [cfg.seed, task.gyro_index, r, k]))
                    for k, e in enumerate(cfg.estimators)]
        for e, fit in fits:
            modelled = fit.modelled
            if not modelled:  # failed before saying what it models: one row per true coefficient
                modelled = [c for c in COEFS if np.isfinite(truth[c])]
            for c in modelled:
                coef = fit.result.coefficients[c]
                est = coef.fitted
                flag = coef.status == "non-physical"
                fail = fit.result.failure or ""
                if not fail and not flag and not np.isfinite(est):
                    fail = "non-finite estimate"
                ci = coef.estimate_interval or (np.nan, np.nan)
                unc = (coef.std_err, *ci) if fit.intervals else (np.nan,) * 3
                rows.append((gspec.label, r, e.label, c, float(truth[c]), est, flag, fail, fit.seconds, *unc))
                ev = coef.evidence
                evid.append((ev.lr, ev.p_value) if ev is not None else (np.nan, np.nan))
    df = pd.DataFrame(rows, columns=TIDY_COLUMNS)
    if any(np.isfinite(v[0]) for v in evid):
        df[EVIDENCE_COLUMNS] = pd.DataFrame(evid, columns=EVIDENCE_COLUMNS, index=df.index)
    return df


class StudyError(RuntimeError):
    """A study could not finish: workers kept dying, a block raised, or the cluster is unreachable.

    Finished blocks are saved; the message says what is missing and why.
    """


def _tmp_path(path: Path) -> Path:
    """A hidden temporary name beside ``path``, unique per process, thread and call."""
    return path.with_name(f".{path.name}.{os.getpid()}-{threading.get_ident()}-{uuid.uuid4().hex[:8]}.tmp")


def _atomic_write_parquet(df: pd.DataFrame, path: Path) -> None:
    """Write ``df`` under a temporary name, then rename: ``path`` is complete or absent."""
    tmp = _tmp_path(path)
    try:
        df.to_parquet(tmp, index=False)
        os.replace(tmp, path)
    finally:
        if tmp.exists():  # the write failed or was interrupted
            tmp.unlink()


def _atomic_write_text(text: str, path: Path) -> None:
    tmp = _tmp_path(path)
    try:
        tmp.write_text(text)
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()


def _remove_stale_tmp(folder: Path) -> None:
    """Temporary files left by a killed run (their process is gone); they never had a final name."""
    for f in folder.glob(".*.tmp"):
        try:
            pid = int(f.name.rsplit(".", 2)[-2].split("-")[0])
        except (ValueError, IndexError):
            continue
        if pid != os.getpid() and not _pid_alive(pid):
            f.unlink(missing_ok=True)


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OSError):
        return True
    return True


def _compute_block(cfg: StudyConfig, task: Task) -> tuple[Task, pd.DataFrame]:
    """What a worker runs: simulate and fit one block from the seed; returns only the small table.

    Workers never write files (on a cluster they may not share the client's disk): the process
    that runs the study saves each block as it arrives.
    """
    from avbench.studies.workers import one_numba_thread

    one_numba_thread()
    cfg.import_plugins()  # the same plugin modules as the process that loaded the config
    return task, run_block(cfg, task)


def _save_block(shard_dir: Path, task: Task, df: pd.DataFrame) -> None:
    _atomic_write_parquet(df, shard_dir / task.shard_name)


def collect(shard_dir: Path, tasks: list[Task], cfg: StudyConfig | None = None) -> pd.DataFrame:
    """The tidy table of the given blocks, sorted; each shard checked against its task."""
    frames = []
    for t in tasks:
        path = shard_dir / t.shard_name
        try:
            df = pd.read_parquet(path)
        except Exception as e:
            raise StudyError(f"{path}: unreadable shard ({type(e).__name__}: {e}); delete it and rerun") from e
        bad = None
        if list(df.columns) not in (TIDY_COLUMNS, TIDY_COLUMNS + EVIDENCE_COLUMNS):
            bad = f"columns {list(df.columns)}, expected {TIDY_COLUMNS} (+ {EVIDENCE_COLUMNS})"
        elif set(df["replicate"].unique()) != set(range(t.start, t.stop)):
            bad = f"replicates {sorted(set(df['replicate']))}, expected {t.start}..{t.stop - 1}"
        elif cfg is not None and set(df["gyro"].unique()) != {cfg.gyros[t.gyro_index].label}:
            bad = f"gyro {sorted(set(df['gyro']))}, expected {cfg.gyros[t.gyro_index].label!r}"
        if bad:
            raise StudyError(f"{path}: shard does not match its block ({bad}); delete it and rerun")
        frames.append(df)
    df = pd.concat(frames, ignore_index=True) if frames else pd.DataFrame(columns=TIDY_COLUMNS)
    return df.sort_values(["gyro", "replicate", "estimator", "coefficient"], kind="stable").reset_index(drop=True)


def _progress(total: int, initial: int, enabled: bool):
    if not enabled:
        return None
    try:
        from tqdm.auto import tqdm
    except ImportError:  # pragma: no cover
        return None
    return tqdm(total=total, initial=initial, unit="block", desc="replicate blocks", file=sys.stderr)


def resolve_execution(cfg: StudyConfig, n_jobs=1, backend=None, scheduler=None) -> tuple[int, str, str | None]:
    """Check and combine the command-line choices with the config's: (n_jobs, backend, scheduler).

    ``scheduler`` without ``backend`` implies "dask"; the config's scheduler is used only with the
    dask backend. Raises ValueError (before anything is written) for impossible combinations.
    """
    from avbench.studies.config_schema import STUDY

    if isinstance(n_jobs, bool) or not isinstance(n_jobs, int | np.integer) or n_jobs == 0:
        raise ValueError(f"jobs: expected a positive number of workers, or -1 for all cores, got {n_jobs!r}")
    n_jobs = int(n_jobs)
    cpus = os.cpu_count() or 1
    if n_jobs < -cpus:
        raise ValueError(f"jobs: expected at least -{cpus} (-1 = all {cpus} cores), got {n_jobs}")
    if backend is None:
        backend = "dask" if scheduler else cfg.backend
    problem = STUDY.keys["backend"].value_problem(backend)
    if problem:
        raise ValueError(f"backend: {problem}")
    if scheduler and backend != "dask":
        raise ValueError(f"scheduler: a dask scheduler address ({scheduler}) needs the dask backend, not {backend!r}")
    if backend == "dask" and not scheduler:
        scheduler = cfg.scheduler
    problem = STUDY.keys["scheduler"].value_problem(scheduler) if scheduler else None
    if problem:
        raise ValueError(f"scheduler: {problem}")
    return n_jobs, backend, scheduler or None


def run_study(
    cfg: StudyConfig,
    out: Path | str | None = None,
    n_jobs: int = 1,
    backend: str | None = None,
    scheduler: str | None = None,
    progress: bool = True,
    max_retries: int = 2,
    make_report: bool = True,
) -> pd.DataFrame:
    """Run (or resume) a study; write the tidy table, tables and figures; return the tidy table (with
    the report: ``attrs["table.md"]``, the text of this run's table.md).

    Blocks already saved by the same code under ``<out>/_shards/<result key>-<code key>/``
    (:func:`shard_folder`) are not recomputed. ``backend``
    "loky" runs ``n_jobs`` local processes (1: in this process); "dask" runs on the scheduler at
    ``scheduler`` (``tcp://host:port``), or on a local cluster of ``n_jobs`` worker processes.
    A worker that dies is replaced and its blocks retried up to ``max_retries`` times; then
    :class:`StudyError`. On KeyboardInterrupt the finished blocks stay saved: run again to resume.
    """
    n_jobs, backend, scheduler = resolve_execution(cfg, n_jobs, backend, scheduler)
    out = Path(out) if out is not None else Path("results") / cfg.name
    out.mkdir(parents=True, exist_ok=True)
    from avbench.outputs import folder_lock

    with folder_lock(out, "out", f"study {cfg.name}"):  # one run per output folder
        return _run_study(cfg, out, n_jobs, backend, scheduler, progress, max_retries, make_report)


def _run_study(cfg, out, n_jobs, backend, scheduler, progress, max_retries, make_report) -> pd.DataFrame:
    shard_dir = shard_folder(out, cfg)
    shard_dir.mkdir(parents=True, exist_ok=True)
    _remove_stale_tmp(shard_dir)
    about = shard_dir / "config.json"
    if not about.exists():  # which config these shards belong to (for people, not read back)
        _atomic_write_text(json.dumps(cfg.result_payload(), indent=2, sort_keys=True, default=str), about)
    from avbench.studies.provenance import shadowed

    for msg in shadowed(cfg):  # said before any work: the study runs the module that was imported
        warnings.warn(f"study {cfg.name}: {msg}", stacklevel=2)
    tasks = tasks_of(cfg)
    todo = [t for t in tasks if not (shard_dir / t.shard_name).exists()]
    if backend == "loky" and n_jobs != 1:  # no more processes than cores and blocks, said
        from avbench.studies.workers import worker_count, workers_note

        note = workers_note(n_jobs, len(todo)) if todo else None
        if note:
            print(f"study {cfg.name}: {note}", file=sys.stderr)
        n_jobs = worker_count(n_jobs, len(todo) or None)
    bar = _progress(len(tasks), len(tasks) - len(todo), progress and bool(todo))
    try:
        _execute(cfg, todo, shard_dir, n_jobs, backend, scheduler, bar, max_retries)
    except KeyboardInterrupt:
        saved = sum((shard_dir / t.shard_name).exists() for t in tasks)
        print(
            f"\nstudy {cfg.name}: interrupted; {saved} of {len(tasks)} blocks of replicates are saved in "
            f"{shard_dir}; run the same study again (same config, same --out) to compute only the rest",
            file=sys.stderr,
        )
        raise
    finally:
        if bar is not None:
            bar.close()
    tidy = collect(shard_dir, tasks, cfg)
    from avbench.studies.report import write_report, write_tidy

    if make_report:  # tidy.csv, tables, figures (drawn by the local workers, if any); meta.json last
        pool = None
        if backend == "loky" and n_jobs != 1:
            from avbench.studies.workers import local_workers

            pool = local_workers(n_jobs)
        tidy.attrs["table.md"] = write_report(cfg, tidy, out, executor=pool).attrs["table.md"]
    else:
        write_tidy(tidy, out)
    return tidy


def _execute(cfg, todo, shard_dir, n_jobs, backend, scheduler, bar, max_retries):
    if not todo:
        return

    def done(task, df):
        _save_block(shard_dir, task, df)
        if bar is not None:
            bar.update(1)

    if n_jobs == 1 and backend == "loky":  # in this process, on one core as a worker: one BLAS thread
        from avbench.estimators.threads import one_blas_thread

        for t in todo:
            with one_blas_thread():
                df = run_block(cfg, t)
            done(t, df)
        return
    with contextlib.ExitStack() as stack:
        if backend == "dask":
            client = stack.enter_context(_dask_context(scheduler, n_jobs))
            run = _dask_runner(client.client)
        else:
            run = _local_runner(n_jobs)
        remaining, attempt = list(todo), 0
        while remaining:
            attempt += 1
            try:
                # one task per block (the blocks are the chunks); results come back as they
                # finish and are saved here at once, so a later failure loses nothing
                for task, df in run(cfg, remaining):
                    done(task, df)
                remaining = []
            except Exception as e:
                remaining = [t for t in remaining if not (shard_dir / t.shard_name).exists()]
                which = ", ".join(_block_label(cfg, t) for t in remaining[:6]) + (" ..." if len(remaining) > 6 else "")
                if not _is_worker_death(e):
                    raise StudyError(
                        f"study {cfg.name}: a block failed with {type(e).__name__}: {e}\n"
                        f"{len(remaining)} block(s) not computed ({which}); the finished ones are saved. "
                        "Estimator exceptions are recorded as data, so this is an error in the simulation "
                        "or the runner (run with --jobs 1 to get its traceback)."
                    ) from e
                if attempt > max_retries:
                    raise StudyError(
                        f"study {cfg.name}: a worker process died {attempt} time(s) "
                        f"(last: {type(e).__name__}: {_first_line(e)}); gave up after {max_retries} "
                        f"retries with {len(remaining)} block(s) not computed: {which}. The finished blocks "
                        "are saved. A worker dies when an estimator ends its process (os._exit, a crash in "
                        "compiled code) or runs out of memory; rerun to retry only the missing blocks."
                    ) from e
                print(
                    f"study {cfg.name}: a worker process died ({type(e).__name__}); retrying "
                    f"{len(remaining)} block(s), attempt {attempt + 1} of {max_retries + 1}",
                    file=sys.stderr,
                )


def _dask_runner(client):
    """Blocks on a dask cluster (through joblib's dask backend), yielded as they finish."""

    def run(cfg, tasks):
        from joblib import Parallel, delayed, parallel_config

        with parallel_config(backend="dask", client=client, wait_for_workers_timeout=120):
            yield from Parallel(return_as="generator_unordered", batch_size=1)(
                delayed(_compute_block)(cfg, t) for t in tasks
            )

    return run


def _local_runner(n_jobs: int):
    """Blocks on the local worker pool, yielded as they finish; on any error the pool is stopped.

    At most two blocks per worker are queued at a time (the rest are submitted as blocks finish),
    so that stopping the pool has little to discard.
    """

    def run(cfg, tasks):
        from concurrent.futures import FIRST_COMPLETED, wait

        from avbench.studies.workers import (local_workers, submit, warm_parent_report_imports, warm_report_imports,
                                             worker_count)

        executor = local_workers(n_jobs)
        workers = worker_count(n_jobs)
        window = 2 * workers
        todo, running, warmed, parent_warm = iter(tasks), set(), 0, None
        try:
            while True:
                exhausted = True
                for t in todo:
                    running.add(submit(executor, _compute_block, cfg, t))
                    if len(running) >= window:
                        exhausted = False
                        break
                # no block left to queue: each worker that falls idle imports what the report's
                # figures need now rather than after the last block (a task apart, never yielded)
                while exhausted and warmed < workers - len(running):
                    executor.submit(warm_report_imports)
                    warmed += 1
                if exhausted and parent_warm is None:  # and this process, for its tables
                    parent_warm = warm_parent_report_imports()
                if not running:
                    return
                finished, running = wait(running, return_when=FIRST_COMPLETED)
                for f in finished:
                    yield f.result()
        except BaseException:
            executor.shutdown(wait=True, kill_workers=True)  # stop the queued and the running blocks
            raise

    return run


def _block_label(cfg, t: Task) -> str:
    return f"{cfg.gyros[t.gyro_index].label} replicates {t.start}-{t.stop - 1}"


def _first_line(e: BaseException) -> str:
    return (str(e).strip().splitlines() or [""])[0][:200]


_WORKER_DEATH = ("TerminatedWorkerError", "KilledWorker", "BrokenProcessPool", "WorkerLostError")


def _is_worker_death(e: BaseException) -> bool:
    """A worker process ended (killed, crashed, out of memory), as opposed to a block raising."""
    seen = set()
    while e is not None and id(e) not in seen:
        seen.add(id(e))
        if type(e).__name__ in _WORKER_DEATH:
            return True
        e = e.__cause__ or e.__context__
    return False


#: seconds to wait for a remote dask scheduler to answer
DASK_CONNECT_TIMEOUT = 30


class _dask_context:
    """A dask client for the run: on a given scheduler, or on a local cluster started for it."""

    def __init__(self, scheduler, n_jobs):
        self.scheduler = scheduler
        self.n_jobs = n_jobs
        self.cluster = None
        self.client = None

    def __enter__(self):
        try:
            from dask.distributed import Client, LocalCluster
        except ImportError:
            raise StudyError(
                "backend 'dask' needs dask.distributed: pip install -e \".[dask]\" (or pip install 'dask[distributed]')"
            ) from None
        if self.scheduler:
            try:
                self.client = Client(self.scheduler, timeout=DASK_CONNECT_TIMEOUT)
            except Exception as e:
                raise StudyError(
                    f"cannot connect to the dask scheduler at {self.scheduler}: {type(e).__name__}: {_first_line(e)} "
                    "(start one with 'dask scheduler' and workers with 'dask worker ADDRESS')"
                ) from None
        else:
            from avbench.studies.workers import worker_count

            self.cluster = LocalCluster(
                n_workers=worker_count(self.n_jobs), threads_per_worker=1, processes=True, dashboard_address=":0"
            )
            self.client = Client(self.cluster)
        return self

    def __exit__(self, *exc):
        try:
            if self.client is not None:
                self.client.close()
        finally:
            if self.cluster is not None:
                self.cluster.close()
        return False
