"""Start-up stays light: what ``from avbench import estimators, noise_models`` and ``avbench --help`` load, the lazy
estimator registry, and where numba caches the compiled kernels.

No timings here (they are in bench/): the checks are on which modules a fresh interpreter imports.
"""

from __future__ import annotations

import importlib
import json
import os
import pkgutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
HEAVY = ("pandas", "scipy.optimize", "statsmodels", "matplotlib", "joblib", "dask", "pyarrow")


def _fresh_modules(code: str) -> set[str]:
    """The modules loaded by ``code`` in a fresh interpreter."""
    run = subprocess.run(
        [sys.executable, "-c", code + "\nimport sys, json; print(json.dumps(sorted(sys.modules)))"],
        capture_output=True, text=True, cwd=ROOT, env={**os.environ, "PYTHONPATH": str(ROOT)}, check=True,
    )
    return set(json.loads(run.stdout.strip().splitlines()[-1]))


def _heavy(mods: set[str]) -> list[str]:
    return [h for h in HEAVY if h in mods]


def test_import_loads_no_heavy_library_and_no_estimator_module():
    mods = _fresh_modules("from avbench import estimators, noise_models")
    assert not _heavy(mods)
    loaded = {m for m in mods if m.startswith("avbench.estimators.")}
    assert loaded <= {"avbench.estimators.base", "avbench.estimators.validation", "avbench.estimators.uncertainty",
                      "avbench.estimators.results"}, loaded


@pytest.mark.parametrize("argv", [["--help"], ["run", "--help"], ["simulate", "--help"], ["studies", "--help"],
                                  ["check-estimator", "--help"], ["bench", "--help"]])
def test_help_imports_neither_simulators_nor_estimators(argv):
    mods = _fresh_modules(
        "import contextlib, io\nfrom avbench.cli import main\n"
        f"with contextlib.redirect_stdout(io.StringIO()):\n    try:\n        main({argv!r})\n    except SystemExit:\n        pass"
    )
    assert not _heavy(mods)
    assert not {m for m in mods if m.startswith(("avbench.estimators", "avbench.noise_models"))}


def test_listed_estimate_help_is_the_real_one():
    """``avbench --help`` lists ``estimate`` without importing it: with the parser's own help line."""
    import argparse

    from avbench.cli import build_parser

    def listed(parser):
        action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
        return {c.dest: c.help for c in action._choices_actions}

    assert listed(build_parser(["--help"]))["estimate"] == listed(build_parser())["estimate"]
    assert listed(build_parser(["--help"])) == listed(build_parser())


def test_registry_table_matches_what_the_modules_register():
    """BUILTIN (name -> module:Class) is exactly what importing every estimator module registers."""
    from avbench import estimators
    from avbench.estimators.base import _REGISTRY, BUILTIN

    for m in pkgutil.walk_packages(estimators.__path__, "avbench.estimators."):
        if not m.name.rpartition(".")[2].startswith("_"):
            importlib.import_module(m.name)
    shipped = {n: f"{c.__module__}:{c.__qualname__}" for n, c in _REGISTRY.items()
               if c.__module__.startswith("avbench.estimators.")}
    assert shipped == BUILTIN
    assert set(BUILTIN) <= set(estimators.names())


def test_lazy_names_and_user_registration():
    code = (
        "import sys\nimport avbench.estimators.curve_fits.least_squares\nfrom avbench import estimators\n"
        "assert 'avbench.estimators.likelihood.gmwm' not in sys.modules\n"
        "assert estimators.estimator_class('gmwm').__name__ == 'GMWM' and 'avbench.estimators.likelihood.gmwm' in sys.modules\n"
        "from avbench.estimators import allan_variance, StreamingAllan\n"
        "assert avbench.estimators.curve_fits.least_squares.WLS is estimators.estimator_class('wls')\n"
        "@estimators.register('my_est')\n"
        "class Mine(estimators.Estimator):\n"
        "    '''A user's estimator.'''\n"
        "assert 'my_est' in estimators.names() and estimators.get('my_est').__class__ is Mine\n"
        "try:\n"
        "    estimators.register('mle')(Mine)\n"
        "except ValueError as e:\n"
        "    assert 'already registered' in str(e)\n"
        "else:\n"
        "    raise AssertionError('a built-in name was taken over')\n"
        "try:\n"
        "    estimators.no_such_thing\n"
        "except AttributeError:\n"
        "    pass\n"
        "print('ok')\n"
    )
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT,
                         env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert run.returncode == 0 and run.stdout.strip() == "ok", run.stderr


def test_estimators_command_describes_every_estimator(capsys):
    from avbench import estimators
    from avbench.cli import main

    assert main(["estimators"]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert [ln.split()[0] for ln in lines] == estimators.names()
    assert all(len(ln.split(None, 1)) == 2 for ln in lines)  # a description on every line


def test_numba_cache_falls_back_to_a_temp_folder(tmp_path, monkeypatch):
    """Neither the source tree nor the user's cache folder writable: NUMBA_CACHE_DIR is set to a
    writable per-user folder (numba would otherwise refuse to import a cache=True kernel)."""
    from avbench.noise_models import _numba_cache as nc

    blocker = tmp_path / "a_file"
    blocker.write_text("")
    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    monkeypatch.setattr(nc, "_checked", False)
    monkeypatch.setattr(nc.os, "access", lambda *a, **k: False)
    monkeypatch.setattr(nc, "_user_cache", lambda: blocker / "numba")  # cannot be created
    monkeypatch.setattr(nc.tempfile, "gettempdir", lambda: str(tmp_path))
    from numba.core import config

    monkeypatch.setattr(config, "CACHE_DIR", config.CACHE_DIR)
    folder = nc.ensure_cache_dir()
    assert folder is not None and Path(folder).parent == tmp_path and Path(folder).is_dir()
    assert os.environ["NUMBA_CACHE_DIR"] == folder == config.CACHE_DIR
    # a user's own choice is never overridden
    monkeypatch.setattr(nc, "_checked", False)
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "mine"))
    assert nc.ensure_cache_dir() is None and os.environ["NUMBA_CACHE_DIR"] == str(tmp_path / "mine")


def test_numba_cache_untouched_when_the_source_tree_is_writable(monkeypatch):
    from avbench.noise_models import _numba_cache as nc

    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    monkeypatch.setattr(nc, "_checked", False)
    monkeypatch.setattr(nc.os, "access", lambda *a, **k: True)
    assert nc.ensure_cache_dir() is None and "NUMBA_CACHE_DIR" not in os.environ


@pytest.mark.parametrize("moving", [False, True])
def test_estimate_does_not_import_scipy_stats(tmp_path, moving):
    """``avbench estimate`` on a static record (both default methods fitted) and on a record in motion (answered
    before any fit) loads no ``scipy.stats``: importing it costs ~0.7 s of a process whose target is 3 s; every
    distribution function the command needs is scipy.special's (the functions scipy.stats calls)."""
    import numpy as np

    rng = np.random.default_rng(3)
    n, fs = 30_000, 100.0
    gyro = 1e-3 * rng.standard_normal((n, 3))
    accel = 1e-2 * rng.standard_normal((n, 3))
    if moving:
        gyro[n // 3: n // 3 + 200, 0] += 0.8  # a turn at 0.8 rad/s for 2 s
    np.savez(tmp_path / "rec.npz", gyro=gyro, accel=accel, fs=np.float64(fs))
    argv = ["estimate", str(tmp_path / "rec.npz"), "--fs", "100", "--units", "rad/s", "--accel-units", "m/s^2",
            "--out", str(tmp_path / "out"), "--no-progress"]
    mods = _fresh_modules(
        "import contextlib, io\nfrom avbench.cli import main\n"
        f"with contextlib.redirect_stdout(io.StringIO()):\n    try:\n        main({argv!r})\n    except SystemExit:\n        pass"
    )
    assert "avbench.recordings.quality" in mods
    assert ("avbench.estimators.likelihood.gmwm" in mods) is not moving  # fitted only when static
    assert "scipy.stats" not in mods
