"""Committed study results are a pure function of their config and seed.

A study goes config -> replicates -> ``tidy.csv`` -> tables, and each step is checked at the precision
its arithmetic supports:

* **tidy.csv -> tables** is exact. The report is re-rendered from the committed ``tidy.csv`` (which
  is what the tables are computed from: ``write_report`` reads the tidy rows back as stored) and
  every text output -- ``table.md``, ``table.csv``, ``leaderboard.md``, the scores, ``meta.json``
  -- must equal the committed one byte for byte (the PNGs' checksums aside: their bytes depend on
  the matplotlib/freetype build, not on the numbers).
* **config -> tidy.csv** is regenerated and compared row by row. Estimates of an estimator whose
  answer is a fixed sequence of floating-point operations must equal the stored 9 digits (1e-8
  relative). An estimator whose answer is an iterative optimiser's end point declares so
  (``Estimator.round_off_amplified``): BLAS/LAPACK and the CPU's vector width change the last bits
  of each step and the optimiser carries them to ~1e-7 relative (GMWM), ~1e-4 (the MLE's flat
  directions), or further on a coefficient the data cannot determine (measured across machines
  and across ``OPENBLAS_CORETYPE`` settings: results/README.md, "Across machines"). Its rows are
  compared to :data:`ROUND_OFF_SHARE` of the replicate spread of the same coefficient -- a
  difference no table, score or conclusion of the study can show -- and its flags exactly. The
  study runs in a fresh process on the kernels the committed results were computed with
  (:data:`REFERENCE_KERNELS`): on other kernels a chaotic filter's rows move by whole spreads.

lv2015 (the README's first command) runs in the default suite; the longer studies are marked slow.
A slow study is regenerated on the first block of replicates of every gyro (``--replicates
block_size``): each row is a function of (config, seed, gyro, replicate) alone -- the runner draws
replicate r of gyro g from ``SeedSequence(seed, spawn_key=(g, r))`` and fits it without reference to
any other replicate -- so the first block of each gyro runs every code path the committed rows came
from, and a stale row fails it. The full regeneration (CPU-hours for the 2 h and 24 h comparisons)
runs with ``AVBENCH_REGENERATE=all``.
"""

from __future__ import annotations

import json
import os
import platform
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from avbench.studies.config import load_config
from avbench import estimators
from avbench.studies.report import read_tidy, write_report

ROOT = Path(__file__).resolve().parents[1]
FAST = ["lv2015"]
SLOW = ["lv2015_grids", "online_sensitivity", "miao2014_adis16405", "miao2015_adis16405", "miao2015_fog",
        "miao2015_existing", "grand_comparison", "coverage", "coverage_true_terms", "model_selection_30min",
        "model_selection_2h", "model_selection_8h", "grand_comparison_2h", "grand_comparison_24h", "hadamard_twins", "coverage_defaults",
        "random_gyros"]
#: configured studies whose full runs (CPU-hours on 2 cores) are not committed yet: each is skipped,
#: saying so, until results/<study>/meta.json exists; then it joins SLOW
PENDING: list[str] = []


def _numpy_wider_than_avx2() -> str:
    """NumPy's runtime-dispatched SIMD targets beyond AVX2 on this CPU (names differ across NumPy versions)."""
    from numpy._core._multiarray_umath import __cpu_dispatch__

    return " ".join(f for f in __cpu_dispatch__ if f.startswith(("AVX512", "X86_V4")))


#: the kernels the committed studies were computed with: OpenBLAS's Haswell (AVX2) kernels, numba code
#: generated for a Haswell CPU, and NumPy's own loops dispatched no wider than AVX2. Any x86-64 CPU with
#: AVX2 runs them; left to choose, OpenBLAS, LLVM and NumPy pick wider (AVX-512) code on newer CPUs, whose
#: last bits differ -- harmless for a closed form, carried to O(1) by a chaotic filter (NEKF on FOG1: K
#: 1.5e-7 vs 3.7e-6 rad/s^1.5 on replicate 0, BLAS and numba) and to whole spreads on the terms a gyro
#: lacks by GMWM and the MLE (replicate 0 of grand_comparison: GMWM's Q on random2 5.3 spreads,
#: NumPy's loops alone)
REFERENCE_KERNELS = {"OPENBLAS_CORETYPE": "Haswell", "NUMBA_CPU_NAME": "haswell",
                     "NPY_DISABLE_CPU_FEATURES": _numpy_wider_than_avx2()}
#: share of a coefficient's replicate spread within which an optimiser's regenerated row must lie
ROUND_OFF_SHARE = 1e-2
#: tidy columns compared as numbers; the rest (names, flags, failure messages) as text
NUMBERS = ("true", "estimate", "std_err", "lower", "upper")
#: a term's evidence: its likelihood ratio (a difference of two maximised log-likelihoods) and p-value
EVIDENCE = ("evidence_lr", "evidence_p")
#: absolute round-off of a likelihood ratio: the log-likelihoods it differences are sums over the
#: record's ordinates of magnitude up to ~1e7 (n/2 <= 7.2e5 terms of the standardised record), so
#: their last bits, up to ~2e-9 absolute (1e7 x 2.2e-16; this bound allows 5x that), move a small LR in
#: its 9th significant digit (measured across two machines on coverage_defaults' first block: at most
#: 2e-11, e.g. ADIS16405_X 0.00769636832 against 0.0076963683). A p-value moves with it:
#: |d log p / d LR| <= 1/2 + 1/(2 sqrt(LR)) for the chi-bar-squared tail of one variance (Mills ratio)
LR_ATOL = 1e-8
KEY = ["gyro", "replicate", "estimator", "coefficient"]


def _reference_kernels_run_here() -> bool:
    from numpy._core._multiarray_umath import __cpu_features__

    return platform.machine().lower() in ("x86_64", "amd64") and bool(__cpu_features__.get("AVX2"))


def _amplified(cfg) -> dict[str, bool]:
    """Each estimator label of the study -> whether its class declares round-off amplification."""
    return {e.label: bool(getattr(e.cls or estimators.estimator_class(e.name), "round_off_amplified", False))
            for e in cfg.estimators}


def _tidy_equal(new: pd.DataFrame, old: pd.DataFrame, cfg, study: str, spread: np.ndarray | None = None) -> None:
    """``new`` equals ``old`` row by row at the precision of each estimator's arithmetic; ``spread``
    (default: computed from ``old``) is each row's replicate spread of its coefficient."""
    assert list(new.columns) == list(old.columns), f"{study}/tidy.csv: columns differ"
    assert new[KEY].astype(str).values.tolist() == old[KEY].astype(str).values.tolist(), f"{study}/tidy.csv: rows differ"
    for c in new.columns:
        if c not in NUMBERS + EVIDENCE:
            assert new[c].astype(str).tolist() == old[c].astype(str).tolist(), f"{study}/tidy.csv: column {c}"
    if set(EVIDENCE) <= set(old.columns):
        _evidence_equal(new, old, study)
    amplified = old["estimator"].map(_amplified(cfg)).fillna(False).to_numpy(bool)
    if spread is None:
        spread = _spread(old)
    for c in NUMBERS:
        a, b = new[c].to_numpy(float), old[c].to_numpy(float)
        tol = 1e-8 * np.abs(b)
        tol = np.where(amplified, np.maximum(tol, ROUND_OFF_SHARE * np.nan_to_num(spread)), tol)
        bad = ~((np.abs(a - b) <= tol) | (np.isnan(a) & np.isnan(b)))
        if bad.any():
            rows = old.loc[bad, KEY].assign(committed=b[bad], regenerated=a[bad], allowed=tol[bad])
            raise AssertionError(f"{study}/tidy.csv: column {c} differs in {bad.sum()} rows "
                                 f"(amplified: {sorted(set(old.loc[bad & amplified, 'estimator']))}):\n"
                                 f"{rows.head(10).to_string()}")


def _evidence_equal(new: pd.DataFrame, old: pd.DataFrame, study: str) -> None:
    """The evidence columns equal at the precision a likelihood ratio's arithmetic supports
    (:data:`LR_ATOL`), the p-value at what that LR's round-off moves it."""
    lr_new, lr_old = new["evidence_lr"].to_numpy(float), old["evidence_lr"].to_numpy(float)
    tol_lr = 1e-8 * np.abs(lr_old) + LR_ATOL
    p_new, p_old = new["evidence_p"].to_numpy(float), old["evidence_p"].to_numpy(float)
    with np.errstate(divide="ignore", invalid="ignore"):
        dlogp = np.abs(np.log(p_new) - np.log(p_old))
        tol_logp = 1e-8 + tol_lr * (0.5 + 0.5 / np.sqrt(np.maximum(lr_old, 1e-300)))
    for c, bad in (("evidence_lr", ~((np.abs(lr_new - lr_old) <= tol_lr) | (np.isnan(lr_new) & np.isnan(lr_old)))),
                   ("evidence_p", ~((p_new == p_old) | (dlogp <= tol_logp) | (np.isnan(p_new) & np.isnan(p_old))))):
        if bad.any():
            rows = old.loc[bad, KEY].assign(committed=old[c].to_numpy(float)[bad], regenerated=new[c].to_numpy(float)[bad])
            raise AssertionError(f"{study}/tidy.csv: column {c} differs in {bad.sum()} rows:\n{rows.head(10).to_string()}")


def _spread(tidy: pd.DataFrame) -> np.ndarray:
    return tidy.groupby(["gyro", "estimator", "coefficient"])["estimate"].transform("std").to_numpy(float)


def _check_report(study: str, tmp_path: Path) -> None:
    """The committed tables re-rendered from the committed tidy.csv, byte for byte (PNG bytes aside)."""
    committed = ROOT / "results" / study
    assert (committed / "meta.json").is_file(), f"results/{study} is not a complete committed report"
    cfg = load_config(ROOT / "studies" / f"{study}.toml")
    out = tmp_path / f"{study}_report"
    out.mkdir()
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore")
        write_report(cfg, read_tidy(committed), out)
    new, old = (json.loads((d / "meta.json").read_text()) for d in (out, committed))
    outputs, old_outputs = new.pop("outputs"), old.pop("outputs")
    # the code and the environment are recorded as they are where the report is written; the resolved
    # config is a function of the config alone
    prov, old_prov = new.pop("provenance"), old.pop("provenance", {})
    assert set(prov) == set(old_prov) and prov["config"] == old_prov["config"], f"{study}/meta.json: provenance"
    # the bounds' last digits are the machine's linear algebra (12 kept): the tables show 4
    bounds, old_bounds = new.pop("crlb", {}), old.pop("crlb", {})
    assert bounds.keys() == old_bounds.keys() and all(
        bounds[g].keys() == old_bounds[g].keys()
        and np.allclose([bounds[g][c] for c in bounds[g]], [old_bounds[g][c] for c in bounds[g]], rtol=1e-9, atol=0)
        for g in bounds), f"{study}/meta.json: crlb"
    assert new == old, f"{study}/meta.json differs"
    assert set(outputs) == set(old_outputs), f"{study}: the report's files differ"
    for name in sorted(k for k in outputs if not k.endswith(".png")):
        assert (out / name).read_text() == (committed / name).read_text(), f"{study}/{name} differs"


def _replicates_checked(cfg) -> int:
    """The first block of every gyro, or every replicate with ``AVBENCH_REGENERATE=all``."""
    if os.environ.get("AVBENCH_REGENERATE", "").lower() == "all":
        return cfg.replicates
    return min(cfg.replicates, cfg.block_size)


def _check(study: str, tmp_path: Path, replicates: int | None = None) -> None:
    committed = ROOT / "results" / study
    assert (committed / "meta.json").is_file(), f"results/{study} is not a complete committed report"
    cfg = load_config(ROOT / "studies" / f"{study}.toml")
    replicates = cfg.replicates if replicates is None else replicates
    out = tmp_path / study
    if not _reference_kernels_run_here():
        pytest.skip("the committed studies were computed with x86-64 AVX2 kernels, which this CPU cannot run")
    # a fresh process, so that BLAS and numba start on the reference kernels (see REFERENCE_KERNELS)
    done = subprocess.run([sys.executable, "-m", "avbench", "run", str(ROOT / "studies" / f"{study}.toml"),
                           "--out", str(out), "--jobs", "2", "--no-progress", "--replicates", str(replicates)],
                          env={**os.environ, **REFERENCE_KERNELS}, capture_output=True, text=True)
    assert done.returncode == 0, f"avbench run {study} failed:\n{done.stderr[-3000:]}"
    old = read_tidy(committed)
    spread = _spread(old)
    first = (old["replicate"] < replicates).to_numpy()
    _tidy_equal(read_tidy(out), old[first].reset_index(drop=True), cfg, study, spread[first])
    if replicates == cfg.replicates:  # a whole rerun: the committed meta.json names the code that ran it
        made = json.loads((out / "meta.json").read_text())["provenance"]
        kept = json.loads((committed / "meta.json").read_text())["provenance"]
        assert made == kept, (f"results/{study}/meta.json names other code than this checkout's (code key "
                              f"{kept['code_key']} vs {made['code_key']}): regenerate it with "
                              f"avbench run studies/{study}.toml --jobs 2")


@pytest.mark.parametrize("study", FAST)
def test_committed_study_regenerates(study, tmp_path):
    _check(study, tmp_path)


#: a slow study's first block on 2 workers takes minutes on a quiet machine (the 24 h comparison's, with
#: its MLE fits, the longest) and several times that on a loaded one: the suite's 600 s default is for
#: unit tests
REGENERATION_TIMEOUT_S = 4 * 3600


@pytest.mark.slow
@pytest.mark.timeout(REGENERATION_TIMEOUT_S)
@pytest.mark.parametrize("study", SLOW + PENDING)
def test_committed_study_regenerates_slow(study, tmp_path):
    if study in PENDING and not (ROOT / "results" / study / "meta.json").is_file():
        pytest.skip(f"results/{study} not computed yet (CPU-hours): avbench run studies/{study}.toml --jobs 2")
    _check(study, tmp_path, _replicates_checked(load_config(ROOT / "studies" / f"{study}.toml")))


@pytest.mark.parametrize("study", FAST)
def test_committed_report_rerenders(study, tmp_path):
    _check_report(study, tmp_path)


@pytest.mark.slow
@pytest.mark.parametrize("study", SLOW + PENDING)
def test_committed_report_rerenders_slow(study, tmp_path):
    if study in PENDING and not (ROOT / "results" / study / "meta.json").is_file():
        pytest.skip(f"results/{study} not computed yet")
    _check_report(study, tmp_path)


def test_every_committed_study_is_covered():
    studies = {p.stem for p in (ROOT / "studies").glob("*.toml")}
    assert studies == set(FAST) | set(SLOW) | set(PENDING), "a study config without a regeneration test (or the reverse)"


def test_the_tidy_comparison_can_fail():
    """The row comparison passes a copy, and fails a deterministic row moved by 1e-6 relative and an
    optimiser's row moved by more than ROUND_OFF_SHARE of its replicate spread (but not by less)."""
    from types import SimpleNamespace

    tidy = read_tidy(ROOT / "results" / "lv2015")
    labels = sorted(tidy["estimator"].unique())
    optimiser, closed_form = labels[0], labels[1]
    cfg = SimpleNamespace(estimators=[
        SimpleNamespace(label=optimiser, cls=estimators.estimator_class("gmwm"), name="gmwm"),
        SimpleNamespace(label=closed_form, cls=None, name="ols")])
    _tidy_equal(tidy.copy(), tidy, cfg, "lv2015")

    def moved(label, by):
        new = tidy.copy()
        i = new.index[(new["estimator"] == label) & new["estimate"].notna() & (new["estimate"] != 0)][0]
        rows = (new["gyro"] == new.at[i, "gyro"]) & (new["estimator"] == label) & (new["coefficient"] == new.at[i, "coefficient"])
        new.at[i, "estimate"] += by(new.at[i, "estimate"], tidy.loc[rows, "estimate"].std())
        return new

    with pytest.raises(AssertionError, match="column estimate"):
        _tidy_equal(moved(closed_form, lambda x, s: 1e-6 * x), tidy, cfg, "lv2015")
    _tidy_equal(moved(optimiser, lambda x, s: 0.5 * ROUND_OFF_SHARE * s), tidy, cfg, "lv2015")
    with pytest.raises(AssertionError, match=optimiser):
        _tidy_equal(moved(optimiser, lambda x, s: 2 * ROUND_OFF_SHARE * s), tidy, cfg, "lv2015")
    flipped = tidy.copy()
    flipped.loc[flipped.index[0], "nonphysical"] = not flipped.loc[flipped.index[0], "nonphysical"]
    with pytest.raises(AssertionError, match="nonphysical"):
        _tidy_equal(flipped, tidy, cfg, "lv2015")
