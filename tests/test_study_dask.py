"""The Dask backend: a real ``distributed.LocalCluster`` (2 worker processes, 1 thread each) gives
the same tidy table, row for row, as the local run with the same seed; by command-line flag and by
the [study] table; a scheduler that cannot be reached is a clear error."""

from __future__ import annotations

import socket

import pandas as pd
import pytest

distributed = pytest.importorskip("distributed")

import avbench.studies.runner as runner  # noqa: E402
from conftest import STUDY_COLS as COLS  # noqa: E402
from conftest import study_toml  # noqa: E402
from avbench.cli import main  # noqa: E402
from avbench.studies.config import load_config  # noqa: E402
from avbench.studies.report import read_tidy  # noqa: E402
from avbench.studies.runner import run_study, tasks_of  # noqa: E402

def toml(extra_study=""):
    return study_toml(name="tiny_dask", seed=5, extra_study=extra_study)


def test_dask_cluster_gives_the_local_table(tmp_path, dask_cluster, capsys):
    cluster = dask_cluster
    cfg_path = tmp_path / "s.toml"
    cfg_path.write_text(toml())
    local = run_study(load_config(cfg_path), tmp_path / "local", n_jobs=1, progress=False, make_report=False)

    # avbench run CONFIG --backend dask --scheduler tcp://...
    rc = main(
        ["run", str(cfg_path), "--backend", "dask", "--scheduler", cluster.scheduler_address,
         "--out", str(tmp_path / "dask"), "--no-progress"]
    )
    assert rc == 0, capsys.readouterr().err
    remote = read_tidy(tmp_path / "dask")  # estimates stored to 9 significant digits
    pd.testing.assert_frame_equal(local[COLS], remote[COLS], check_exact=False, rtol=1e-8, check_dtype=False)
    assert len(remote) == 2 * 6 * (3 + 4)
    # one dask task per block of replicates (not per replicate, not one per study)
    prefixes = {k: dict(v.state_counts) for k, v in cluster.scheduler.task_prefixes.items() if "_compute_block" in k}
    assert list(prefixes) == ["batch_of__compute_block_1_calls"]
    assert prefixes["batch_of__compute_block_1_calls"]["memory"] == len(tasks_of(load_config(cfg_path))) == 6

    # backend and scheduler given in the [study] table
    cfg_path.write_text(toml(f'backend = "dask"\nscheduler = "{cluster.scheduler_address}"'))
    cfg = load_config(cfg_path)
    assert (cfg.backend, cfg.scheduler) == ("dask", cluster.scheduler_address)
    by_config = run_study(cfg, tmp_path / "dask2", progress=False, make_report=False)
    pd.testing.assert_frame_equal(local[COLS], by_config[COLS])


def test_unreachable_scheduler_is_a_clear_error(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(runner, "DASK_CONNECT_TIMEOUT", 2)
    with socket.socket() as s:  # a free port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    cfg_path = tmp_path / "s.toml"
    cfg_path.write_text(toml())
    rc = main(["run", str(cfg_path), "--scheduler", f"tcp://127.0.0.1:{port}", "--out", str(tmp_path / "o"), "--no-progress"])
    err = capsys.readouterr().err
    assert rc == 2
    assert f"avbench: error: cannot connect to the dask scheduler at tcp://127.0.0.1:{port}" in err
    assert "Traceback" not in err


@pytest.mark.slow
def test_dask_without_scheduler_starts_a_local_cluster(tmp_path):
    cfg_path = tmp_path / "s.toml"
    cfg_path.write_text(toml())
    cfg = load_config(cfg_path)
    local = run_study(cfg, tmp_path / "local", n_jobs=1, progress=False, make_report=False)
    dask = run_study(cfg, tmp_path / "dask", n_jobs=2, backend="dask", progress=False, make_report=False)
    pd.testing.assert_frame_equal(local[COLS], dask[COLS])
