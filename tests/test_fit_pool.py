"""The axes of one record fitted on several processes (recordings/fit_pool.py): the same bits as one."""

from __future__ import annotations

import dataclasses
import json
import threading

import numpy as np
import pytest

from avbench.noise_models import presets
from avbench.recordings.fit_pool import PARALLEL_MIN_SAMPLES, available_cores, fit_axes, worker_count
from avbench.estimators.results import jsonable


def _bits(fits, dt):
    """Everything a surface shows of one axis's fits, as text whose equality is bit equality (JSON
    writes a float's shortest round-trip digits), with the model's AV and the fit check's residuals."""
    out = {}
    tau = dt * 2.0 ** np.arange(12)
    for name, f in fits.items():
        entry = jsonable(dataclasses.asdict(f.result))  # every field a surface renders
        residuals = f.result.fit_check.residuals
        out[name] = (json.dumps(entry, sort_keys=True), f.result.model_avar(tau).tobytes(),
                     None if residuals is None else tuple(np.asarray(r).tobytes() for r in residuals))
    return out


def test_several_workers_give_the_bits_of_one():
    """Five axes (different presets and seeds), a curve fit and a GMWM, on 1 and 2 processes."""
    items = []
    for i, name in enumerate(["ADIS16405_X", "ADIS16405_Y", "SRS2000", "FOG1", "ADIS16405_Z"]):
        g = presets.get(name)
        x = g.simulate(30_000, np.random.default_rng([7, i]))
        items.append((x, g.dt, np.zeros(0, dtype=np.int64), ["wls", "gmwm"], {}))
    one = [_bits(f, it[1]) for f, it in zip(fit_axes(items, 1), items)]
    for workers in (2,):
        bar = _Threads()
        many = [_bits(f, it[1]) for f, it in zip(fit_axes(items, workers, bar), items)]
        assert many == one, workers
        assert bar.count == 2 * len(items)
        assert bar.others, "no axis was fitted by a worker process: the comparison tested nothing"


class _Threads:
    """A progress bar that notes which threads advanced it: a worker's fits are collected by another
    thread than this one."""

    def __init__(self):
        self.count, self.others = 0, 0

    def update(self, n):
        self.count += n
        self.others += threading.current_thread() is not threading.main_thread()


def test_worker_count_is_capped_by_the_cores_and_the_work():
    assert worker_count(4, 6, 10) == 4 and worker_count(12, 6, 10) == 6 and worker_count(1, 6, 10**9) == 1
    assert worker_count(None, 6, PARALLEL_MIN_SAMPLES - 1) == 1
    assert worker_count(None, 6, PARALLEL_MIN_SAMPLES) == min(6, available_cores())
    with pytest.raises(ValueError, match="--jobs"):
        worker_count(0, 6, 10)


def test_jobs_below_one_is_refused_before_the_file_is_read(tmp_path, capsys):
    from avbench.cli import main

    assert main(["estimate", str(tmp_path / "absent.csv"), "--jobs", "0", "--out", str(tmp_path)]) == 2
    assert "--jobs: expected a number of processes >= 1, got 0" in capsys.readouterr().err
