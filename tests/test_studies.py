"""The study runner: identical tables for any job count, failures recorded as data, worker deaths
retried then reported, small tasks, atomic shards, execution choices checked before writing.

A test-only estimator ``test_flaky`` (registered below) fits OLS but misbehaves on the records whose
first sample is positive (about half the replicates; replicates are separate fits, so the condition
must depend on the data): it raises, reports a divergence, returns non-finite values, or ends its
worker process, depending on its ``mode`` setting.
"""

from __future__ import annotations

import math
import os
import pickle
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from avbench.studies.runner import shard_folder

from conftest import STUDY_COLS as COLS
from conftest import study_toml
from avbench.estimators.base import Estimator, register
from avbench.estimators.curve_fits.least_squares import OLS
from avbench.estimators.results import FitParts
from avbench.studies.config import load_config, parse_config
from avbench.studies.report import summarize
from avbench.studies.runner import (
    StudyError,
    Task,
    _atomic_write_parquet,
    collect,
    replicate_rng,
    resolve_execution,
    run_study,
    tasks_of,
)


@register("test_flaky")
class Flaky(Estimator):
    """Test only: OLS that misbehaves (``mode``) on records whose first sample is positive."""

    def __init__(self, *, mode="raise", terms="QN", parent_pid=0, marker=""):
        self.mode = mode
        self.terms = terms
        self.parent_pid = parent_pid
        self.marker = marker

    def _fit(self, rate, dt):
        if rate[0] > 0:
            if self.mode == "raise":
                raise RuntimeError("deliberate failure (rate[0] > 0)")
            if self.mode == "report":
                failure = "diverged at sample 7 (deliberate)"
                return {c: math.nan for c in self.terms}, {}, {}, FitParts(failure=failure)
            if self.mode == "nonfinite":
                return {c: math.inf for c in self.terms}, {}, {}
            if self.mode == "exit" and os.getpid() != self.parent_pid:  # never in the test process
                if not self.marker or not os.path.exists(self.marker):
                    if self.marker:
                        Path(self.marker).touch()
                    os._exit(3)
        return OLS(terms=self.terms, taus="octave")._fit(rate, dt)



def flaky_toml(mode, label=None, **settings):
    s = ", ".join(f"{k} = {v!r}" if isinstance(v, str) else f"{k} = {v}" for k, v in {"mode": mode, **settings}.items())
    s = s.replace("'", '"')
    return f'\n[[estimators]]\nname = "test_flaky"\nlabel = "{label or "flaky_" + mode}"\nsettings = {{ {s} }}\n'


def write(tmp_path, text, name="study.toml") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def first_sample_positive(cfg, g, r) -> bool:
    gs = cfg.gyros[g]
    return bool(gs.gyro.simulate(gs.n_samples, replicate_rng(cfg.seed, g, r))[0] > 0)


def test_tidy_identical_for_jobs_1_and_2(tmp_path):
    """--jobs 1 (in process) and --jobs 2 (loky workers) give the same table row for row; the
    test-only estimator class reaches the workers with the config."""
    extra = flaky_toml("raise") + flaky_toml("report")
    cfg = load_config(write(tmp_path, study_toml(extra_estimators=extra)))
    a = run_study(cfg, tmp_path / "j1", n_jobs=1, progress=False, make_report=False)
    b = run_study(cfg, tmp_path / "j2", n_jobs=2, progress=False, make_report=False)
    pd.testing.assert_frame_equal(a[COLS], b[COLS])
    assert len(a) == 2 * 6 * (3 + 4 + 2 + 2)  # gyros x replicates x modelled coefficients
    assert (a["failure"] != "").any() and (a["failure"] == "").any()
    assert not a[a["estimator"].isin(["ols", "wls"])]["failure"].astype(bool).any()


def test_report_identical_for_jobs_1_and_2(tmp_path):
    """With local workers the figures are drawn by the workers while this process writes the
    tables: every output of the report (the hashes meta.json lists: tables, tidy, figures) is
    byte-identical to the one drawn in process, and this process never imports matplotlib."""
    import json
    import subprocess
    import sys

    small = {"replicates": 2, "block_size": 1}
    cfg = load_config(write(tmp_path, study_toml()), small)
    run_study(cfg, tmp_path / "j1", n_jobs=1, progress=False)
    code = ("import sys; from avbench.studies.config import load_config; from avbench.studies.runner import run_study; "
            f"run_study(load_config({str(tmp_path / 'study.toml')!r}, {small!r}), {str(tmp_path / 'j2')!r}, n_jobs=2, "
            "progress=False); print('matplotlib' in sys.modules)")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert res.stdout.strip().splitlines()[-1] == "False"
    one, two = (json.loads((tmp_path / j / "meta.json").read_text())["outputs"] for j in ("j1", "j2"))
    assert any(name.endswith(".png") for name in one)
    assert one == two


def test_same_numbers_for_any_block_size(tmp_path):
    """Replicate r of gyro g draws from its own stream: the blocking does not change any number."""
    a = run_study(load_config(write(tmp_path, study_toml(block_size=1))), tmp_path / "b1", progress=False, make_report=False)
    b = run_study(load_config(write(tmp_path, study_toml(block_size=4))), tmp_path / "b4", progress=False, make_report=False)
    pd.testing.assert_frame_equal(a[COLS], b[COLS])
    assert sorted((tmp_path / "b1" / "_shards").iterdir())[0].name == sorted((tmp_path / "b4" / "_shards").iterdir())[0].name


@pytest.mark.parametrize(
    "mode, reason",
    [
        ("raise", "RuntimeError: deliberate failure (rate[0] > 0)"),
        ("report", "diverged at sample 7 (deliberate)"),
        ("nonfinite", "non-finite estimate"),
    ],
)
def test_failures_are_data(tmp_path, mode, reason):
    """An estimator that raises, reports a divergence or returns non-finite values on some
    replicates: recorded with its reason, the study goes on, n_failed counts those replicates."""
    cfg = load_config(write(tmp_path, study_toml(replicates=8, extra_estimators=flaky_toml(mode, label="flaky"))))
    report = mode == "raise"  # the report (with figures) once
    tidy = run_study(cfg, tmp_path / "out", progress=False, make_report=report)
    f = tidy[tidy["estimator"] == "flaky"]
    expected_bad = {(cfg.gyros[g].label, r) for g in range(2) for r in range(8) if first_sample_positive(cfg, g, r)}
    assert 0 < len(expected_bad) < 16
    bad = f[f["failure"] != ""]
    assert set(zip(bad["gyro"], bad["replicate"])) == expected_bad
    assert set(bad["failure"]) == {reason}
    assert bad["estimate"].isna().all() if mode != "nonfinite" else True
    good = f[f["failure"] == ""]
    assert (np.isfinite(good["estimate"]) | good["nonphysical"]).all() and set(good["coefficient"]) == {"Q", "N"}
    # the other estimators are untouched
    assert (tidy[tidy["estimator"] != "flaky"]["failure"] == "").all()
    # the summary counts failed replicates per gyro x estimator x coefficient
    s = summarize(tidy)
    for g in ("g1", "g2"):
        n_bad = sum(1 for gl, _ in expected_bad if gl == g)
        row = s[(s["gyro"] == g) & (s["estimator"] == "flaky")]
        assert list(row["n_failed"]) == [n_bad, n_bad]
        assert list(row["n_ok"] + row["n_nonphysical"]) == [8 - n_bad, 8 - n_bad]
    if not report:
        return
    csv = pd.read_csv(tmp_path / "out" / "table.csv")
    assert csv[csv["estimator"] == "flaky"]["n_failed"].sum() == 2 * len(expected_bad)
    assert "flaky non-physical / failed" in (tmp_path / "out" / "table.md").read_text()


def test_impossible_setting_is_a_config_error(tmp_path):
    """A value the estimator's declaration refuses (here: OLS trimmed with a negative threshold) is
    rejected before any work, naming the setting, what it accepts and what it got."""
    extra = '\n[[estimators]]\nname = "ols_trimmed"\nsettings = { max_error_pct = -1.0 }\n'
    with pytest.raises(ValueError, match=r"estimators\[2\]\.settings: \(gyro g1\) estimator 'ols_trimmed': "
                                         r"max_error_pct=-1\.0: expected a finite number > 0"):
        load_config(write(tmp_path, study_toml(extra_estimators=extra)))


@pytest.mark.parametrize("name, bad, match", [
    ("gmwm", 'model = "WN+XX"', "model"),
    ("mle", "maxiter = 0", "maxiter"),
    ("whittle", 'criterion = "aic"', "criterion"),
    ("ols_trimmed", 'max_error_pct = "40"', "max_error_pct"),
    ("shakf", "b = 1.5", "b=1.5"),
    ("nekf_multitau", "m = [1, 1]", "distinct"),
    ("arma_em", 'terms = "QNBK"', "quantization"),
    ("wls_edf_hadamard", 'terms = "NBKR"', "rate ramp"),
    # relations between settings (the class's setting_relations)
    ("shakf", 'terms = "NB", x0 = { N = 1e-4 }', "x0: expected exactly the modelled terms NB, missing"),
    ("shakf_multitau", 'terms = "N", m = 3, R0 = [1.0, 2.0]', "R0: expected a positive number or 3"),
    ("nnls_rel", 'terms = "QB", filter = "fit"', "expected N in terms"),
    ("arma_em", 'x0 = { N = 1e-3 }', "x0: expected exactly the modelled terms NBK, missing"),
])
def test_settings_are_checked_without_trial_fits(tmp_path, monkeypatch, name, bad, match):
    """A config's estimator settings are checked by the class's declaration (constraints and relations)
    and against the record, never by fitting (trial fits of GMWM made loading a 16-gyro config take
    minutes): nothing is fitted for valid settings, and bad settings are a config error naming the
    setting."""
    from avbench.estimators import estimator_class

    fitted = []
    monkeypatch.setattr(estimator_class(name), "_fit", lambda self, rate, dt: fitted.append(rate.size))
    ok = f'\n[[estimators]]\nname = "{name}"\n'
    load_config(write(tmp_path, study_toml(extra_estimators=ok)))
    assert fitted == [], "loading the config fitted an estimator"
    extra = f'\n[[estimators]]\nname = "{name}"\nsettings = {{ {bad} }}\n'
    with pytest.raises(ValueError, match=rf"estimators\[2\]\.settings: \(gyro g1\) .*{match}"):
        load_config(write(tmp_path, study_toml(extra_estimators=extra)))
    assert fitted == []


def test_plugin_settings_are_checked_only_by_what_it_declares(tmp_path, monkeypatch):
    """An estimator that declares nothing (``test_flaky``, a plugin of this module) is not fitted when
    the config is read: any value of its settings passes (no setting is checked by its name alone), and
    a setting its ``__init__`` does not take is refused naming those it does."""
    fitted = []
    monkeypatch.setattr(Flaky, "_fit", lambda self, rate, dt: fitted.append(rate.size))
    load_config(write(tmp_path, study_toml(extra_estimators=flaky_toml("no such mode", marker=3, terms="QX"))))
    assert fitted == []
    with pytest.raises(ValueError, match=r"estimators\[2\]\.settings: \(gyro g1\) .*unknown setting\(s\) "
                                         r"colour; accepted: mode, terms, parent_pid, marker"):
        load_config(write(tmp_path, study_toml(extra_estimators=flaky_toml("raise", colour="red"))))


def test_worker_death_retried_once_then_study_completes(tmp_path):
    """A worker that dies once (os._exit) is replaced and its blocks retried: same table as serial."""
    marker = tmp_path / "died_once"
    extra = flaky_toml("exit", label="flaky", parent_pid=os.getpid(), marker=str(marker))
    cfg = load_config(write(tmp_path, study_toml(replicates=4, block_size=1, extra_estimators=extra)))
    assert any(first_sample_positive(cfg, g, r) for g in range(2) for r in range(4))
    b = run_study(cfg, tmp_path / "j2", n_jobs=2, progress=False, make_report=False, max_retries=2)
    assert marker.exists()  # a worker did die
    a = run_study(cfg, tmp_path / "j1", n_jobs=1, progress=False, make_report=False)
    pd.testing.assert_frame_equal(a[COLS], b[COLS])


def test_worker_death_every_time_is_reported_clearly(tmp_path, capsys):
    """A worker that dies on every attempt: bounded retries, then a StudyError naming the blocks;
    the blocks that finished are saved and no tidy table is written."""
    extra = flaky_toml("exit", label="flaky", parent_pid=os.getpid())
    cfg = load_config(write(tmp_path, study_toml(replicates=4, block_size=1, extra_estimators=extra)))
    dying = {(cfg.gyros[g].label, r) for g in range(2) for r in range(4) if first_sample_positive(cfg, g, r)}
    assert dying
    with pytest.raises(StudyError) as info:
        run_study(cfg, tmp_path / "out", n_jobs=2, progress=False, make_report=False, max_retries=1)
    msg = str(info.value)
    assert "worker process died 2 time(s)" in msg and "gave up after 1 retries" in msg
    for g, r in sorted(dying)[:3]:
        assert f"{g} replicates {r}-{r}" in msg
    assert "attempt 2 of 2" in capsys.readouterr().err
    shard_dir = shard_folder(tmp_path / "out", cfg)
    saved = {p.name for p in shard_dir.glob("*.parquet")}
    for g in range(2):
        for r in range(4):
            if (cfg.gyros[g].label, r) in dying:
                assert Task(g, r, r + 1).shard_name not in saved
    assert not (tmp_path / "out" / "tidy.csv").exists()
    assert not list(shard_dir.glob(".*.tmp"))


def test_what_is_shipped_per_task_is_small(tmp_path):
    """Workers get the config (gyros and settings) and a replicate range, never records."""
    cfg = load_config(write(tmp_path, study_toml(n_samples=1_000_000, extra_estimators=flaky_toml("raise"))))
    for t in tasks_of(cfg):
        assert len(pickle.dumps((cfg, t))) < 20_000
    import cloudpickle

    from avbench.studies.runner import _compute_block

    assert len(cloudpickle.dumps((_compute_block, cfg, tasks_of(cfg)[0]))) < 20_000
    # a block's result is a few rows, not samples
    lv = load_config("studies/lv2015.toml")
    assert len(pickle.dumps(lv)) < 20_000


def test_execution_choices_rejected_before_anything_is_written(tmp_path):
    cfg = load_config(write(tmp_path, study_toml()))
    for kwargs, match in [
        (dict(n_jobs=0), "jobs: expected a positive number"),
        (dict(n_jobs=-1000), "jobs: expected at least"),
        (dict(backend="loky", scheduler="tcp://127.0.0.1:8786"), "needs the dask backend"),
        (dict(backend="spark"), "backend: expected 'loky' or 'dask'"),
        (dict(scheduler="my laptop"), "scheduler: expected a dask scheduler address"),
    ]:
        with pytest.raises(ValueError, match=match):
            run_study(cfg, tmp_path / "out", progress=False, **kwargs)
        assert not (tmp_path / "out").exists()
    # --scheduler alone means the dask backend; the config's scheduler is only used with dask
    assert resolve_execution(cfg, 2, None, "tcp://h:1") == (2, "dask", "tcp://h:1")
    raw = parse_config({**_raw(tmp_path), "study": {**_raw(tmp_path)["study"], "backend": "dask", "scheduler": "tcp://h:2"}})
    assert resolve_execution(raw, 1, None, None) == (1, "dask", "tcp://h:2")
    assert resolve_execution(raw, 1, "loky", None) == (1, "loky", None)


def _raw(tmp_path):
    import tomllib

    return tomllib.loads(study_toml())


def test_shards_are_written_atomically(tmp_path, monkeypatch):
    """A write that fails half-way leaves neither a final name nor a temporary file."""
    df = pd.DataFrame({"a": [1, 2]})
    target = tmp_path / "x.parquet"

    def broken(self, path, **kw):
        Path(path).write_bytes(b"PAR1 half a file")
        raise OSError("disk full")

    monkeypatch.setattr(pd.DataFrame, "to_parquet", broken)
    with pytest.raises(OSError, match="disk full"):
        _atomic_write_parquet(df, target)
    assert list(tmp_path.iterdir()) == []


def test_collect_rejects_a_shard_that_does_not_match_its_block(tmp_path):
    cfg = load_config(write(tmp_path, study_toml()))
    run_study(cfg, tmp_path / "out", progress=False, make_report=False)
    shard_dir = shard_folder(tmp_path / "out", cfg)
    tasks = tasks_of(cfg)
    wrong = pd.read_parquet(shard_dir / tasks[1].shard_name)
    wrong.to_parquet(shard_dir / tasks[0].shard_name, index=False)
    with pytest.raises(StudyError, match=r"does not match its block \(replicates \[2, 3\], expected 0\.\.1\); delete it"):
        collect(shard_dir, tasks, cfg)
    (shard_dir / tasks[0].shard_name).write_bytes(b"garbage")
    with pytest.raises(StudyError, match="unreadable shard"):
        collect(shard_dir, tasks, cfg)


def test_evidence_columns_only_when_an_estimator_reports_evidence(tmp_path):
    """Tidy rows carry each term's evidence (likelihood ratio, chi-bar^2 p-value) from an estimator
    that reports it (whittle_debiased), NaN on the other estimators' rows; a study without such an
    estimator keeps exactly the columns it had (committed tidy.csv files stay byte for byte)."""
    from avbench.studies.report import read_tidy, write_tidy
    from avbench.studies.runner import EVIDENCE_COLUMNS, TIDY_COLUMNS

    plain = run_study(load_config(write(tmp_path, study_toml(replicates=2))), tmp_path / "p", progress=False,
                      make_report=False)
    assert list(plain.columns) == TIDY_COLUMNS
    extra = '\n[[estimators]]\nname = "whittle_debiased"\nlabel = "wd"\nsettings = { terms = "NBK" }\n'
    cfg = load_config(write(tmp_path, study_toml(replicates=2, n_samples=4000, extra_estimators=extra), "e.toml"))
    tidy = run_study(cfg, tmp_path / "e", progress=False, make_report=False)
    assert list(tidy.columns) == TIDY_COLUMNS + EVIDENCE_COLUMNS
    wd = tidy[tidy["estimator"] == "wd"]
    assert sorted(set(wd["coefficient"])) == ["B", "K", "N"]
    assert (wd["evidence_lr"] >= 0).all() and wd["evidence_p"].between(0, 1).all()
    # the p-value is the chi-bar^2 tail of the LR: 1/2 P(chi2_1 >= lr), 1 at lr = 0
    from scipy import stats

    expect = np.where(wd["evidence_lr"] > 0, 0.5 * stats.chi2.sf(wd["evidence_lr"], 1), 1.0)
    np.testing.assert_allclose(wd["evidence_p"], expect, rtol=1e-12)
    assert tidy.loc[tidy["estimator"] != "wd", EVIDENCE_COLUMNS].isna().all().all()
    write_tidy(tidy, tmp_path / "e")
    back = read_tidy(tmp_path / "e")
    np.testing.assert_allclose(back["evidence_lr"], tidy["evidence_lr"], rtol=1e-8, equal_nan=True)
