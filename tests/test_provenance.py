"""Provenance: the shard key and ``meta.json`` follow the code that computes a study's rows.

An edited estimator (a file beside the config, a helper module it imports, a package imported from
its source folder as an editable install is) gets new shards and so its new numbers, whatever version
string it declares; an edit to one built-in estimator's module moves the code hash of the estimators
that import it and of no other; a module shadowed by an installed one of the same name is said; and
``avbench run --jobs 2`` with the estimator in a file beside the config runs without losing a worker.
"""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from pathlib import Path

import pandas as pd
import pytest

from avbench.studies import provenance
from avbench.studies.config import load_config
from avbench.studies.report import read_tidy
from avbench.studies.runner import run_study
from conftest import STUDY_COLS

ROOT = Path(__file__).resolve().parents[1]

ESTIMATOR = '''
"""An OLS whose N is scaled by a factor from a helper module beside it."""
from avbench.estimators.curve_fits.least_squares import OLS
from scaled_helper import FACTOR

__version__ = "1.0"  # never changed by the edits below: the hash must not trust it


class Scaled(OLS):
    """OLS, N times FACTOR."""

    def _fit(self, rate, dt):
        coefs, flags, diag, *parts = super()._fit(rate, dt)
        coefs = dict(coefs)
        coefs["N"] = coefs["N"] * FACTOR
        return (coefs, flags, diag, *parts)
'''


def _study(folder: Path, estimator="scaled_est:Scaled", replicates=2) -> Path:
    p = folder / "s.toml"
    p.write_text(textwrap.dedent(f'''
        [study]
        name = "prov"
        seed = 5
        replicates = {replicates}
        block_size = 1
        n_samples = 3000

        [[gyros]]
        name = "g"
        dt = 0.1
        terms = [{{type = "AngleRandomWalk", N = 1e-3}}]

        [[estimators]]
        name = "{estimator}"
        settings = {{ terms = "N", taus = "octave" }}
        '''))
    return p


@pytest.fixture
def fresh_path(monkeypatch):
    """sys.path and the modules the test imports from its folder, restored afterwards."""
    monkeypatch.setattr("sys.path", list(sys.path))
    before = set(sys.modules)
    yield
    for m in set(sys.modules) - before:
        if m.startswith(("scaled_", "shadow_", "edpkg")):
            del sys.modules[m]


def _forget(*names):
    for m in list(sys.modules):
        if m.split(".")[0] in names:
            del sys.modules[m]


def _n(tidy):
    return tidy.loc[tidy["coefficient"] == "N", "estimate"].to_numpy()


def _run(config: Path, out: Path, *extra, env=None) -> pd.DataFrame:
    """``avbench run`` in a fresh process, as a researcher reruns a study; its tidy rows."""
    import os

    done = subprocess.run([sys.executable, "-m", "avbench", "run", str(config), "--no-progress", "--out", str(out),
                           *extra], capture_output=True, text=True, cwd=config.parent.parent,
                          env={**os.environ, **(env or {})})
    assert done.returncode == 0, done.stderr[-3000:]
    assert "died" not in done.stderr and "retrying" not in done.stderr, done.stderr[-3000:]
    return read_tidy(out)


def test_an_edited_file_estimator_gives_its_new_numbers(tmp_path):
    (tmp_path / "scaled_est.py").write_text(ESTIMATOR)
    (tmp_path / "scaled_helper.py").write_text("FACTOR = 1.0\n")
    config = _study(tmp_path)
    first = _run(config, tmp_path / "out")
    # the helper edited (the estimator's file and its __version__ unchanged), the study rerun in place
    (tmp_path / "scaled_helper.py").write_text("FACTOR = 2.0\n")
    again = _run(config, tmp_path / "out")
    assert _n(again) == pytest.approx(2 * _n(first), rel=1e-8)
    fresh = _run(config, tmp_path / "fresh")
    pd.testing.assert_frame_equal(again[STUDY_COLS], fresh[STUDY_COLS])
    assert len(list((tmp_path / "out" / "_shards").iterdir())) == 2  # the old blocks kept, not reused
    meta = json.loads((tmp_path / "out" / "meta.json").read_text())["provenance"]
    env = json.loads((tmp_path / "out" / "environment.json").read_text())
    assert env["python"] and env["libraries"]["numpy"] and "git_commit" in env
    assert meta["config"]["estimators"][0]["class"] == "scaled_est:Scaled"
    assert meta["code_key"] == (tmp_path / "out" / "_shards").glob(f"*-{meta['code_key']}").__next__().name[-12:]


def test_an_edited_package_imported_from_its_source_gives_its_new_numbers(tmp_path):
    """A package imported from its source folder (what an editable install puts on the path): its
    files are hashed, not its version."""
    src = tmp_path / "src"
    (src / "edpkg").mkdir(parents=True)
    (src / "edpkg" / "__init__.py").write_text('__version__ = "0.1"\n')
    (src / "edpkg" / "est.py").write_text(ESTIMATOR.replace("from scaled_helper import FACTOR",
                                                            "from edpkg.factor import FACTOR"))
    (src / "edpkg" / "factor.py").write_text("FACTOR = 1.0\n")
    config = _study(tmp_path, "edpkg.est:Scaled")
    first = _run(config, tmp_path / "out", env={"PYTHONPATH": str(src)})
    (src / "edpkg" / "factor.py").write_text("FACTOR = 3.0\n")
    again = _run(config, tmp_path / "out", env={"PYTHONPATH": str(src)})
    assert _n(again) == pytest.approx(3 * _n(first), rel=1e-8)


def test_a_builtin_edit_moves_only_the_estimators_that_import_it(tmp_path, monkeypatch):
    p = tmp_path / "b.toml"
    p.write_text(textwrap.dedent('''
        [study]
        name = "b"
        seed = 1
        replicates = 1
        n_samples = 3000
        [[gyros]]
        name = "g"
        dt = 0.1
        terms = [{type = "AngleRandomWalk", N = 1e-3}, {type = "RateRandomWalk", K = 1e-5}]
        [[estimators]]
        name = "ols"
        settings = { terms = "NK", taus = "octave" }
        [[estimators]]
        name = "gmwm"
        settings = { model = "WN+RW" }
        '''))
    cfg = load_config(p)
    before = provenance.code_hashes(cfg)
    gmwm = type(cfg.estimators[1].make(cfg.gyros[0])).__module__
    assert gmwm not in provenance._avbench_closure(type(cfg.estimators[0].make(cfg.gyros[0])).__module__)
    edited = tmp_path / "edited.py"
    real = provenance._source
    edited.write_bytes(real(gmwm).read_bytes() + b"\n# an edit\n")
    monkeypatch.setattr(provenance, "_source", lambda m: edited if m == gmwm else real(m))
    after = provenance.code_hashes(cfg)
    assert after["estimators"]["gmwm"] != before["estimators"]["gmwm"]
    assert after["estimators"]["ols"] == before["estimators"]["ols"]
    assert after["terms"] == before["terms"] and after["runner"] == before["runner"]


def test_a_shadowed_local_module_is_said(tmp_path, fresh_path):
    installed = tmp_path / "site"
    installed.mkdir()
    (installed / "shadow_est.py").write_text(ESTIMATOR.replace("from scaled_helper import FACTOR", "FACTOR = 1.0"))
    here = tmp_path / "study"
    here.mkdir()
    (here / "shadow_est.py").write_text(ESTIMATOR.replace("from scaled_helper import FACTOR", "FACTOR = 5.0"))
    sys.path.insert(0, str(installed))
    cfg = load_config(_study(here, "shadow_est:Scaled", replicates=1))
    with pytest.warns(UserWarning, match=r"module 'shadow_est' is imported from .*site.*not from .*study"):
        run_study(cfg, tmp_path / "out", progress=False, make_report=False)
    assert provenance.shadowed(cfg) and not provenance.shadowed(load_config(ROOT / "studies" / "lv2015.toml"))


def test_two_workers_run_an_estimator_beside_the_config(tmp_path):
    """``avbench run`` starts its workers before it reads the config: the file's folder reaches them
    with each block (and each figure), so no worker dies and nothing is computed twice."""
    (tmp_path / "scaled_est.py").write_text(ESTIMATOR)
    (tmp_path / "scaled_helper.py").write_text("FACTOR = 1.0\n")
    config = _study(tmp_path, replicates=4)
    two = _run(config, tmp_path / "two", "--jobs", "2")
    one = _run(config, tmp_path / "one")
    pd.testing.assert_frame_equal(one[STUDY_COLS], two[STUDY_COLS])
