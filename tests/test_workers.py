"""The local worker pool of a study: its workers live through every block."""

from __future__ import annotations

import os
import time

import numpy as np
import pytest

from avbench.studies import workers

_HELD: list = []


def _hold(n_bytes: int) -> int:
    """Keep ``n_bytes`` of touched memory in this process, as a worker's caches do; its pid."""
    _HELD.append(np.ones(n_bytes // 8))
    time.sleep(1.2)  # past loky's 1 s between two memory checks: the next call is checked
    return os.getpid()


def test_a_worker_keeping_its_warm_state_is_not_restarted():
    """A worker holding 400 MB more after a block than after its start-up call (a FOG study's holds
    296 MB: the covariance's gains, FIR spectra, kernels) keeps running: loky would call it a leak,
    stop it with a UserWarning and start another, which pays the imports and kernel loads again."""
    pytest.importorskip("psutil")  # loky checks a worker's memory only through psutil
    pool = workers.local_workers(1, start=True)
    try:
        pids = [workers.submit(pool, _hold, 400 << 20).result(timeout=120) for _ in range(2)]
    finally:
        pool.shutdown(wait=True, kill_workers=True)
    assert len(set(pids)) == 1, f"the worker was restarted: pids {pids}"
