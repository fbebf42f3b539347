"""Edges of the commands and the library: no traceback at the edges.

Every bad input ends in one line ``avbench: error: ...`` naming the file or option and what was
expected, exit code 2, and nothing written; valid inputs at the numeric extremes give right answers.
The CLI cases run ``avbench`` as a real subprocess.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from avbench import estimators
from avbench.estimators.allan.model import model_avar
from avbench.estimators.base import BUILTIN
from avbench.noise_models import presets

ROOT = Path(__file__).resolve().parents[1]

TINY = textwrap.dedent(
    """
    [study]
    name = "tiny"
    seed = 3
    replicates = 2
    n_samples = 4096

    [[gyros]]
    preset = "SRS2000"

    [[estimators]]
    name = "wls"
    settings = { terms = "QNB", taus = "octave" }
    """
)


def avbench(*args, cwd=None, timeout=120):
    env = {**os.environ, "MPLBACKEND": "Agg"}
    return subprocess.run(
        [sys.executable, "-m", "avbench.cli", *map(str, args)],
        capture_output=True, text=True, cwd=cwd or ROOT, env=env, timeout=timeout,
    )


def refused(proc, *needles):
    """Exit 2, one line on stderr starting 'avbench: error:', containing every needle, no traceback."""
    err = proc.stderr.strip()
    assert proc.returncode == 2, (proc.returncode, err)
    assert "Traceback" not in err, err
    assert err.startswith("avbench: error:") and len(err.splitlines()) == 1, err
    for n in needles:
        assert n in err, (n, err)
    return err


def files_under(path: Path) -> set[str]:
    return {str(p.relative_to(path)) for p in path.rglob("*")} if path.exists() else set()


@pytest.fixture
def tiny(tmp_path):
    p = tmp_path / "tiny.toml"
    p.write_text(TINY)
    return p


# -- avbench run / table -------------------------------------------------------------------------


def test_run_out_is_a_file(tiny, tmp_path):
    afile = tmp_path / "afile"
    afile.write_text("keep me")
    refused(avbench("run", tiny, "--out", afile), "--out", "is a file", "expected a folder")
    refused(avbench("run", tiny, "--out", afile / "sub"), "--out", "is a file, not a folder")
    assert afile.read_text() == "keep me"
    assert files_under(tmp_path) == {"tiny.toml", "afile"}


def test_run_out_not_writable(tiny):
    # root ignores permission bits, so use a place no one can create folders in: /proc
    refused(avbench("run", tiny, "--out", "/proc/avbench-out"), "--out", "/proc")


def test_run_output_name_taken_by_a_folder(tiny, tmp_path):
    out = tmp_path / "out"
    (out / "table.md").mkdir(parents=True)
    refused(avbench("run", tiny, "--out", out), "table.md", "is a folder")
    assert files_under(out) == {"table.md"}


def test_deeply_nested_toml(tmp_path):
    p = tmp_path / "deep.toml"
    p.write_text(TINY + "\n[extra]\nx = " + "[" * 5000 + "]" * 5000 + "\n")
    refused(avbench("run", p, "--out", tmp_path / "out"), "deep.toml", "nested")
    assert not (tmp_path / "out").exists()


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs on this system")
def test_fifo_is_named_as_a_fifo(tmp_path):
    fifo = tmp_path / "study.toml"
    os.mkfifo(fifo)
    refused(avbench("run", fifo, "--out", tmp_path / "out"), "is a FIFO", "expected a study file")


def test_table_on_foreign_corrupt_and_incomplete_folders(tiny, tmp_path):
    foreign = tmp_path / "foreign"
    foreign.mkdir()
    (foreign / "table.csv").write_text("a,b\n1,2\n")
    refused(avbench("table", foreign), "incomplete")
    (foreign / "meta.json").write_text("{not json")
    refused(avbench("table", foreign), "meta.json", "not JSON")
    (foreign / "meta.json").write_text('{"outputs": {"table.csv": "0"}}')
    refused(avbench("table", foreign), "table.csv does not belong to this report")

    out = tmp_path / "out"
    assert avbench("run", tiny, "--out", out, "--no-progress").returncode == 0
    ok = avbench("table", out)
    assert ok.returncode == 0 and "## SRS2000" in ok.stdout
    latex = avbench("table", out, "--latex")
    assert latex.returncode == 0 and "\\begin{tabular}" in latex.stdout and "True value" in latex.stdout
    table = out / "table.csv"
    table.write_text(table.read_text().replace("wls", "xyz", 1))  # edited after the run
    refused(avbench("table", out), "table.csv does not belong to this report")


def test_interrupted_report_is_never_read_as_complete(tiny, tmp_path, monkeypatch):
    """A report killed while it is written (here: figures raise) leaves no meta.json: 'table' refuses."""
    from avbench.studies import figures
    from avbench.studies.config import load_config
    from avbench.studies.report import check_report
    from avbench.studies.runner import run_study

    cfg = load_config(tiny)
    out = tmp_path / "out"
    run_study(cfg, out, progress=False)
    check_report(out)

    def killed(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(figures, "study_figures", killed)
    with pytest.raises(KeyboardInterrupt):
        run_study(load_config(tiny, {"replicates": 4}), out, progress=False)
    assert not (out / "meta.json").exists()
    with pytest.raises(ValueError, match="incomplete"):
        check_report(out)
    monkeypatch.undo()
    run_study(load_config(tiny, {"replicates": 4}), out, progress=False)  # the rerun completes it
    assert check_report(out)["replicates"] == 4


# -- avbench simulate ----------------------------------------------------------------------------


def test_simulate_refuses_records_that_cannot_fit_in_memory(tmp_path):
    err = refused(avbench("simulate", "SRS2000", "--samples", "3000000000", cwd=tmp_path), "record length", "GiB")
    assert "available" in err
    assert files_under(tmp_path) == set()


def test_simulate_negative_seed_names_the_option(tmp_path):
    refused(avbench("simulate", "SRS2000", "--samples", "100", "--seed", "-1", cwd=tmp_path), "--seed")


# -- library: settings and magnitudes ------------------------------------------------------------


@pytest.mark.parametrize(
    "settings, key",
    [({"terms": 5}, "terms"), ({"terms": None}, "terms"), ({"terms": "123"}, "terms"),
     ({"overlapping": "maybe"}, "overlapping"), ({"taus": 5}, "taus"), ({"taus": "weekly"}, "taus")],
)
def test_shared_settings_are_checked_at_construction_and_fit(settings, key):
    with pytest.raises(ValueError, match=rf"estimator 'wls': {key}=.*: expected"):
        estimators.get("wls", **settings)
    est = estimators.estimator_class("wls")(**settings)  # built directly: refused at fit
    with pytest.raises(ValueError, match=rf"{key}=.*: expected"):
        est.fit(np.random.default_rng(0).standard_normal(1024), 0.1)


@pytest.fixture(scope="module")
def record():
    g = presets.get("CRG20")
    return g.simulate(1 << 14, np.random.default_rng(7)), g.dt


#: relative agreement between fits of x and of x * 1e300 (or 1e-200): the rounding of x * scale
#: (1e-16) carried through a closed-form fit, or amplified to the tolerance of an iterative optimizer
#: (objective to ~1e-10, so parameters to ~sqrt(1e-10) relative on flat directions)
ITERATIVE = {"mle", "log_fit", "whittle"}  # and every gmwm variant (numerical optimisers)


@pytest.mark.parametrize("name", sorted(BUILTIN))  # the shipped estimators (not test-only ones)
def test_estimates_scale_with_the_data(name, record):
    x, dt = record
    fits = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", estimators.AvbenchWarning)
        for scale in (1.0, 1e300, 1e-200, 2.0**700, 2.0**-700):
            est = estimators.get(name).fit(x * scale, dt)
            fits[scale] = (est.coefficients_ / scale, est.nonphysical_, est.diagnostics_.get("data_scale", 1.0))
    a, flags, _ = fits[1.0]
    assert np.isfinite(a).any(), "no coefficient at all"
    # outside the safe range the fit runs in power-of-two units: data differing by a power of two
    # are the same numbers there, so their estimates scale exactly
    up, down = fits[2.0**700], fits[2.0**-700]
    assert up[2] != 1.0 and down[2] != 1.0
    pd.testing.assert_series_equal(up[0], down[0], check_exact=True)
    for scale in (1e300, 1e-200):
        b, bflags, data_scale = fits[scale]
        assert data_scale != 1.0
        assert (bflags == flags).all() and (b.isna() == a.isna()).all(), (scale, a, b)
        if name in ITERATIVE or name.startswith("gmwm"):  # a coefficient at its bound (1e-10 vs 0.0) is noise: compare fitted curves
            tau = dt * 2.0 ** np.arange(12)
            np.testing.assert_allclose(model_avar(b, tau), model_avar(a, tau), rtol=1e-4)
        else:
            np.testing.assert_allclose(b.dropna(), a.dropna(), rtol=1e-8)


def test_extreme_sample_interval_is_refused():
    x = np.random.default_rng(0).standard_normal(1024)
    with pytest.raises(ValueError, match="dt: expected a sample interval between"):
        estimators.get("wls").fit(x, 1e-300)


def test_allan_variance_of_overflowing_data_does_not_crash():
    av = estimators.allan_variance(np.random.default_rng(1).standard_normal(4096) * 1e300, 0.1)
    assert np.isinf(av.avar).all()


# -- failures stay data --------------------------------------------------------------------------

FAILING = textwrap.dedent(
    """
    [study]
    name = "failing"
    seed = 1
    replicates = 2
    n_samples = 16

    [[gyros]]
    name = "zero"
    dt = 0.01
    terms = [{type = "AngleRandomWalk", N = 0.0}]

    [[gyros]]
    name = "huge"
    dt = 0.01
    terms = [{type = "AngleRandomWalk", N = 1e200}]

    [[estimators]]
    name = "wls"

    [[estimators]]
    name = "gmwm"
    """
)


def test_method_failing_on_every_record_is_data_not_a_config_error(tmp_path):
    """gmwm cannot fit 16 samples, nobody can fit N = 0 (a constant record): the study runs and records it, and a
    gyro of absurd magnitude (N = 1e200) does not abort the report."""
    from avbench.studies.config import load_config
    from avbench.studies.report import check_report, read_tidy
    from avbench.studies.runner import run_study

    p = tmp_path / "failing.toml"
    p.write_text(FAILING)
    cfg = load_config(p)  # not refused: no setting was given, nothing in the config is wrong
    out = tmp_path / "out"
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore")
        run_study(cfg, out, progress=False)
    meta = check_report(out)
    assert {"av_huge.png", "spread_huge.png", "av_zero.png"} <= set(meta["outputs"])
    tidy = read_tidy(out)
    g = tidy[tidy["estimator"] == "gmwm"]
    assert (g["failure"] != "").all()
    assert g.loc[g["gyro"] == "huge", "failure"].str.contains("use a longer record").all()
    assert tidy.loc[tidy["gyro"] == "zero", "failure"].str.contains("constant record").all()  # N = 0: no noise
