"""Monte Carlo study runner: replicates in parallel, saved block by block, resumable.

Work is cut into tasks of ``block_size`` replicates of one gyro. Replicate ``r`` of gyro ``g`` draws
from ``SeedSequence(seed, spawn_key=(g, r))`` -- the same stream ``SeedSequence(seed).spawn`` would
give its (g, r) grandchild -- so every number depends only on the config and the seed, never on the
worker count, the backend or the order tasks finish in. Each finished block is written atomically
(temporary name, then rename) under ``<out>/_shards/<result key>/``, the key being a hash of
everything that determines the results; rerunning the same study computes only the missing blocks,
and a changed config gets a new key instead of mixing old and new results.

Failures are data: an estimator that raises, reports a failure, or returns non-finite values on a
replicate is recorded in the tidy table (column ``failure``) and the study goes on.
"""

from __future__ import annotations

import os
import sys
import time
import traceback
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from studies.config import StudyConfig

__all__ = ["run_study", "replicate_rng", "run_block", "Task", "tasks_of", "collect", "TIDY_COLUMNS"]

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
]
COEFS = ["Q", "N", "B", "K", "R"]


@dataclass(frozen=True)
class Task:
    gyro_index: int
    start: int
    stop: int

    @property
    def shard_name(self) -> str:
        return f"g{self.gyro_index:02d}_r{self.start:06d}-{self.stop:06d}.parquet"


def replicate_rng(seed: int, gyro_index: int, replicate: int) -> np.random.Generator:
    """The generator of replicate ``replicate`` of gyro ``gyro_index`` (independent of scheduling)."""
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(gyro_index, replicate)))


def tasks_of(cfg: StudyConfig) -> list[Task]:
    B = cfg.block_size
    return [
        Task(g, s, min(s + B, cfg.replicates))
        for g in range(len(cfg.gyros))
        for s in range(0, cfg.replicates, B)
    ]


def _modelled(est, coefs, nonphys) -> list[str]:
    """Coefficients an estimator estimates: its ``terms`` setting, else what it returned."""
    from estimators.av_model import check_terms

    terms = getattr(est, "terms", None)
    if terms is not None:
        try:
            return list(check_terms(terms))
        except ValueError:
            pass
    if coefs is None:
        return []
    return [c for c in COEFS if np.isfinite(coefs[c]) or bool(nonphys[c])]


def _fit_one(spec_est, gspec, rate, dt):
    """Fit one estimator; return (modelled, coefficients or None, nonphysical, failure, seconds)."""
    est = spec_est.make(gspec)
    t0 = time.perf_counter()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            with np.errstate(all="ignore"):
                est.fit(rate, dt)
    except Exception as e:  # failures are data
        msg = f"{type(e).__name__}: {e}".splitlines()[0][:300]
        return _modelled(est, None, None), None, None, msg, time.perf_counter() - t0
    secs = time.perf_counter() - t0
    failure = str(est.diagnostics_.get("failure") or "")
    coefs, nonphys = est.coefficients_, est.nonphysical_
    return _modelled(est, coefs, nonphys), coefs, nonphys, failure, secs


def run_block(cfg: StudyConfig, task: Task) -> pd.DataFrame:
    """Simulate and fit every replicate of one task; the tidy rows.

    One row per modelled coefficient. ``failure`` is empty on success, else the reason: the
    exception, the estimator's own failure report, or "non-finite estimate".
    """
    gspec = cfg.gyros[task.gyro_index]
    truth = gspec.gyro.coefficients
    rows = []
    for r in range(task.start, task.stop):
        rate = gspec.gyro.simulate(gspec.n_samples, replicate_rng(cfg.seed, task.gyro_index, r))
        for e in cfg.estimators:
            modelled, coefs, nonphys, failure, secs = _fit_one(e, gspec, rate, gspec.gyro.dt)
            if not modelled:  # failed before saying what it models: one row per true coefficient
                modelled = [c for c in COEFS if np.isfinite(truth[c])]
            for c in modelled:
                est = np.nan if coefs is None else float(coefs[c])
                flag = False if nonphys is None else bool(nonphys[c])
                fail = failure
                if not fail and not flag and not np.isfinite(est):
                    fail = "non-finite estimate"
                rows.append((gspec.label, r, e.label, c, float(truth[c]), est, flag, fail, secs))
    return pd.DataFrame(rows, columns=TIDY_COLUMNS)


def _atomic_write_parquet(df: pd.DataFrame, path: Path) -> None:
    tmp = path.with_name(path.name + f".{os.getpid()}.tmp")
    df.to_parquet(tmp, index=False)
    os.replace(tmp, path)


def _run_and_save(cfg: StudyConfig, task: Task, shard_dir: str) -> str:
    df = run_block(cfg, task)
    path = Path(shard_dir) / task.shard_name
    _atomic_write_parquet(df, path)
    return str(path)


def collect(shard_dir: Path, tasks: list[Task]) -> pd.DataFrame:
    frames = [pd.read_parquet(shard_dir / t.shard_name) for t in tasks]
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
    """Run (or resume) a study; write the tidy table, tables and figures; return the tidy table."""
    out = Path(out) if out is not None else Path("results") / cfg.name
    shard_dir = out / "_shards" / cfg.result_key()
    shard_dir.mkdir(parents=True, exist_ok=True)
    tasks = tasks_of(cfg)
    todo = [t for t in tasks if not (shard_dir / t.shard_name).exists()]
    backend = backend or cfg.backend
    scheduler = scheduler or cfg.scheduler
    bar = _progress(len(tasks), len(tasks) - len(todo), progress and bool(todo))
    try:
        _execute(cfg, todo, shard_dir, n_jobs, backend, scheduler, bar, max_retries)
    finally:
        if bar is not None:
            bar.close()
    tidy = collect(shard_dir, tasks)
    _atomic_write_parquet(tidy, out / "tidy.parquet")
    if make_report:
        from studies.report import write_report

        write_report(cfg, tidy, out)
    return tidy


def _execute(cfg, todo, shard_dir, n_jobs, backend, scheduler, bar, max_retries):
    if not todo:
        return
    if n_jobs == 1 and backend == "loky":
        for t in todo:
            _run_and_save(cfg, t, str(shard_dir))
            if bar is not None:
                bar.update(1)
        return
    from joblib import Parallel, delayed, parallel_config

    attempt = 0
    remaining = list(todo)
    while remaining:
        try:
            if backend == "dask":
                ctx = _dask_context(scheduler, n_jobs)
            else:
                ctx = parallel_config(backend="loky", n_jobs=n_jobs)
            with ctx:
                gen = Parallel(return_as="generator_unordered")(
                    delayed(_run_and_save)(cfg, t, str(shard_dir)) for t in remaining
                )
                for _ in gen:
                    if bar is not None:
                        bar.update(1)
            remaining = []
        except Exception as e:  # a worker died: retry what is missing, a bounded number of times
            remaining = [t for t in remaining if not (shard_dir / t.shard_name).exists()]
            attempt += 1
            if attempt > max_retries or not _is_worker_death(e):
                raise RuntimeError(
                    f"study {cfg.name}: {len(remaining)} block(s) not computed after {attempt} attempt(s): "
                    f"{type(e).__name__}: {e}"
                ) from e
            print(
                f"worker failure ({type(e).__name__}); retrying {len(remaining)} block(s), attempt {attempt + 1}",
                file=sys.stderr,
            )


def _is_worker_death(e: Exception) -> bool:
    name = type(e).__name__
    text = "".join(traceback.format_exception_only(type(e), e))
    return name in ("TerminatedWorkerError", "KilledWorker", "BrokenProcessPool") or "worker" in text.lower()


class _dask_context:
    """joblib's dask backend on a given scheduler, or on a local cluster started for the run."""

    def __init__(self, scheduler, n_jobs):
        self.scheduler = scheduler
        self.n_jobs = n_jobs
        self.cluster = None
        self.client = None
        self.cfg = None

    def __enter__(self):
        try:
            from dask.distributed import Client, LocalCluster
        except ImportError:
            raise RuntimeError(
                "backend 'dask' needs dask.distributed: pip install 'avbench[dask]'"
            ) from None
        from joblib import parallel_config

        if self.scheduler:
            self.client = Client(self.scheduler)
        else:
            workers = max(1, self.n_jobs if self.n_jobs and self.n_jobs > 0 else os.cpu_count() or 1)
            self.cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None)
            self.client = Client(self.cluster)
        self.cfg = parallel_config(backend="dask")
        self.cfg.__enter__()
        return self

    def __exit__(self, *exc):
        try:
            self.cfg.__exit__(*exc)
        finally:
            self.client.close()
            if self.cluster is not None:
                self.cluster.close()
        return False
