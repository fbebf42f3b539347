"""Resuming studies: only missing blocks are computed, a changed config never mixes with old
results, and a study killed by a real signal (SIGINT, then SIGKILL) ends, when rerun, with the
same table as an uninterrupted run."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pandas as pd
import pytest

from avbench.studies.runner import shard_folder

import avbench.studies.runner as runner
from conftest import STUDY_COLS as COLS
from avbench.studies.config import load_config
from avbench.studies.report import read_tidy
from avbench.studies.runner import collect, run_study, tasks_of

ROOT = Path(__file__).resolve().parents[1]


def toml(seed=3, replicates=6, block_size=2, n_samples=4000, wls_terms="QNB", description="x"):
    return textwrap.dedent(
        f"""
        [study]
        name = "resume"
        description = "{description}"
        seed = {seed}
        replicates = {replicates}
        n_samples = {n_samples}
        block_size = {block_size}

        [[gyros]]
        name = "g"
        dt = 0.1
        terms = [{{type = "AngleRandomWalk", N = [0.5, "deg/sqrt(h)"]}}, {{type = "Quantization", Q = 1e-5}},
                 {{type = "BiasInstability", B = [10.0, "deg/h"], tau_max = 600.0}}]

        [[estimators]]
        name = "ols"
        settings = {{ terms = "QNB", taus = "octave" }}

        [[estimators]]
        name = "wls"
        settings = {{ terms = "{wls_terms}", taus = "octave" }}
        """
    )


def cfg_of(tmp_path, text, name="s.toml", **overrides):
    p = tmp_path / name
    p.write_text(text)
    return load_config(p, overrides or None)


@pytest.fixture
def count_blocks(monkeypatch):
    """Counts the blocks computed (the serial path calls runner.run_block in this process)."""
    calls = []
    real = runner.run_block

    def counting(cfg, task):
        calls.append(task)
        return real(cfg, task)

    monkeypatch.setattr(runner, "run_block", counting)
    return calls


def test_rerun_computes_only_missing_blocks(tmp_path, count_blocks):
    cfg = cfg_of(tmp_path, toml())
    full = run_study(cfg, tmp_path / "out", progress=False, make_report=False)
    assert len(count_blocks) == 3
    shard_dir = shard_folder(tmp_path / "out", cfg)
    kept = {p.name: p.stat().st_mtime_ns for p in shard_dir.glob("*.parquet")}
    (shard_dir / tasks_of(cfg)[1].shard_name).unlink()
    del kept[tasks_of(cfg)[1].shard_name]
    count_blocks.clear()
    again = run_study(cfg, tmp_path / "out", progress=False, make_report=False)
    assert count_blocks == [tasks_of(cfg)[1]]
    assert {p: (shard_dir / p).stat().st_mtime_ns for p in kept} == kept  # untouched
    pd.testing.assert_frame_equal(full[COLS], again[COLS])
    count_blocks.clear()
    run_study(cfg, tmp_path / "out", progress=False, make_report=False)
    assert count_blocks == []  # nothing left to do


def test_more_replicates_reuse_finished_blocks(tmp_path, count_blocks):
    cfg6 = cfg_of(tmp_path, toml(replicates=6))
    run_study(cfg6, tmp_path / "out", progress=False, make_report=False)
    count_blocks.clear()
    cfg10 = cfg_of(tmp_path, toml(replicates=6), replicates=10)  # like --replicates 10
    assert cfg10.result_key() == cfg6.result_key()
    t10 = run_study(cfg10, tmp_path / "out", progress=False, make_report=False)
    assert [(t.start, t.stop) for t in count_blocks] == [(6, 8), (8, 10)]
    fresh = run_study(cfg10, tmp_path / "fresh", progress=False, make_report=False)
    pd.testing.assert_frame_equal(t10[COLS], fresh[COLS])


def test_changed_code_gets_its_own_shards(tmp_path, count_blocks, monkeypatch):
    """Blocks computed by other code are not resumed (the config key cannot see a change of an
    estimator): the shard folder carries the hash of the code that computes the rows."""
    cfg = cfg_of(tmp_path, toml())
    run_study(cfg, tmp_path / "out", progress=False, make_report=False)
    assert len(count_blocks) == 3
    run_study(cfg, tmp_path / "out", progress=False, make_report=False)
    assert len(count_blocks) == 3  # same code: resumed, nothing computed
    monkeypatch.setattr(runner, "code_key", lambda cfg: "other-code")
    run_study(cfg, tmp_path / "out", progress=False, make_report=False)
    assert len(count_blocks) == 6  # other code: computed afresh, in its own folder
    assert len(list((tmp_path / "out" / "_shards").iterdir())) == 2


def test_code_key_reads_the_estimators_source(tmp_path):
    cfg = cfg_of(tmp_path, toml())
    key = runner.code_key(cfg)
    assert len(key) == 12 and key == runner.code_key(cfg)


def test_changed_config_gets_its_own_shards(tmp_path, count_blocks):
    """Seed, settings, gyros, record length: a new hash and folder, never a mix; the replicate
    count, block size, backend and description do not change what a block holds."""
    base = cfg_of(tmp_path, toml())
    t0 = run_study(base, tmp_path / "out", progress=False, make_report=False)
    shards = tmp_path / "out" / "_shards"
    before = {p.name: p.stat().st_mtime_ns for p in (shard_folder(tmp_path / "out", base)).iterdir()}
    keys = {base.result_key()}
    for change in (dict(seed=4), dict(wls_terms="QN"), dict(n_samples=4096)):
        count_blocks.clear()
        cfg = cfg_of(tmp_path, toml(**change))
        assert cfg.result_key() not in keys
        keys.add(cfg.result_key())
        t = run_study(cfg, tmp_path / "out", progress=False, make_report=False)
        assert len(count_blocks) == 3  # all recomputed
        assert not t[COLS].equals(t0[COLS])
    assert {p.name.rsplit("-", 1)[0] for p in shards.iterdir()} == keys
    assert {p.name: p.stat().st_mtime_ns for p in (shard_folder(tmp_path / "out", base)).iterdir()} == before
    for same in (dict(description="other words"),):
        assert cfg_of(tmp_path, toml(**same)).result_key() == base.result_key()
    assert cfg_of(tmp_path, toml(), backend="dask").result_key() == base.result_key()
    # a config.json beside the shards says which config they belong to
    assert '"seed": 3' in (shard_folder(tmp_path / "out", base) / "config.json").read_text()


def test_stale_temporary_files_are_cleaned(tmp_path):
    cfg = cfg_of(tmp_path, toml())
    shard_dir = shard_folder(tmp_path / "out", cfg)
    shard_dir.mkdir(parents=True)
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    stale = shard_dir / f".g00_r000000-000002.parquet.{int(dead.stdout)}-1-abcdef12.tmp"
    stale.write_bytes(b"partial")
    run_study(cfg, tmp_path / "out", progress=False, make_report=False)
    assert not stale.exists()


def _interruptible():
    """In the child: Ctrl-C as a terminal delivers it. A shell that starts a command in the background
    (``cmd &`` without job control) makes it ignore SIGINT, and a child inherits that; Python then
    installs no KeyboardInterrupt handler, so these tests would test nothing."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _cli(out: Path, config: Path) -> subprocess.Popen:
    env = {**os.environ, "MPLBACKEND": "Agg", "PYTHONPATH": str(ROOT)}
    return subprocess.Popen(
        [sys.executable, "-m", "avbench.cli", "run", str(config), "--out", str(out), "--no-progress"],
        cwd=ROOT,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=_interruptible,
    )


def _wait_for_shards(shard_dir: Path, more_than: int, proc: subprocess.Popen, timeout=120.0) -> int:
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        n = len(list(shard_dir.glob("*.parquet"))) if shard_dir.is_dir() else 0
        if n > more_than:
            return n
        assert proc.poll() is None, proc.communicate()
        time.sleep(0.005)
    raise AssertionError("no new shard appeared")


def test_killed_study_resumes_to_the_uninterrupted_result(tmp_path):
    """SIGINT after the first block, SIGKILL after the next: no partial file ever has a final
    name, the interrupt says how to resume, and the third run ends with the same table as an
    uninterrupted run, computing only what was missing."""
    text = toml(seed=11, replicates=40, block_size=1, n_samples=200_000)
    config = tmp_path / "study.toml"
    config.write_text(text)
    cfg = load_config(config)
    out = tmp_path / "out"
    shard_dir = shard_folder(out, cfg)
    tasks = tasks_of(cfg)

    proc = _cli(out, config)
    _wait_for_shards(shard_dir, 0, proc)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    assert "rerun the same command to resume" in err
    assert "blocks of replicates are saved in" in err
    n1 = len(list(shard_dir.glob("*.parquet")))
    assert 1 <= n1 < len(tasks)

    proc = _cli(out, config)
    _wait_for_shards(shard_dir, n1, proc)
    proc.send_signal(signal.SIGKILL)
    proc.communicate(timeout=60)
    assert proc.returncode == -signal.SIGKILL
    done = [t for t in tasks if (shard_dir / t.shard_name).exists()]
    assert n1 < len(done) < len(tasks)
    collect(shard_dir, done, cfg)  # every file with a final name is a complete, matching block
    assert not (out / "tidy.csv").exists()
    stamps = {t.shard_name: (shard_dir / t.shard_name).stat().st_mtime_ns for t in done}

    proc = _cli(out, config)
    stdout, err = proc.communicate(timeout=300)
    assert proc.returncode == 0, err
    assert "## g" in stdout  # the table is printed
    assert {n: (shard_dir / n).stat().st_mtime_ns for n in stamps} == stamps  # not recomputed
    assert not list(shard_dir.glob(".*.tmp"))
    resumed = read_tidy(out)  # estimates stored to 9 significant digits
    straight = run_study(cfg, tmp_path / "straight", progress=False, make_report=False)
    pd.testing.assert_frame_equal(resumed[COLS], straight[COLS], check_exact=False, rtol=1e-8, check_dtype=False)


def _children(pid: int) -> set[int]:
    """Live (non-zombie) processes whose parent is ``pid`` (Linux /proc)."""
    out = set()
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                fields = (d / "stat").read_text().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(fields[1]) == pid and fields[0] != "Z":
                out.add(int(d.name))
    return out


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


def _read_to_eof(stream, timeout: float = 10.0) -> bytes:
    """Everything left in a pipe until EOF; fails if some process still holds its write end."""
    os.set_blocking(stream.fileno(), False)
    data, t0 = b"", time.monotonic()
    while time.monotonic() - t0 < timeout:
        chunk = stream.read()
        if chunk == b"":
            return data
        data += chunk or b""
        time.sleep(0.1)
    raise AssertionError("the stopped study's output pipe is still held open by another process")


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs Linux /proc to list the workers")
@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGINT])
def test_stopped_parent_leaves_no_workers(tmp_path, sig):
    """SIGKILL (or Ctrl-C) of ``avbench run --jobs 2`` while its workers compute: every process it
    started (loky workers, resource trackers) exits within seconds, none keeps the caller's stdout or
    stderr open, and Ctrl-C ends with the resume message and no traceback."""
    config = tmp_path / "study.toml"
    config.write_text(toml(seed=5, replicates=40, block_size=1, n_samples=200_000))
    out = tmp_path / "out"
    shard_dir = shard_folder(out, load_config(config))
    env = {**os.environ, "MPLBACKEND": "Agg", "PYTHONPATH": str(ROOT)}
    proc = subprocess.Popen(
        [sys.executable, "-m", "avbench.cli", "run", str(config), "--out", str(out), "--no-progress", "--jobs", "2"],
        cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, preexec_fn=_interruptible,
    )
    _wait_for_shards(shard_dir, 1, proc)  # the workers are running blocks
    children = _children(proc.pid)
    assert len(children) >= 2, children  # at least the two workers
    proc.send_signal(sig)
    proc.wait(timeout=30)
    t0 = time.monotonic()
    while any(_alive(p) for p in children) and time.monotonic() - t0 < 10:
        time.sleep(0.1)
    survivors = [p for p in children if _alive(p)]
    for p in survivors:  # clean up before failing
        os.kill(p, signal.SIGKILL)
    assert not survivors, f"{len(survivors)} process(es) of the stopped study still alive after 10 s"
    _read_to_eof(proc.stdout)
    err = _read_to_eof(proc.stderr).decode()
    if sig == signal.SIGINT:
        assert proc.returncode == 130, err
        assert "rerun the same command to resume" in err and "Traceback" not in err, err
