import os

import numpy as np
import pytest
from scipy import stats


def mc_tolerance(samples: np.ndarray, alpha: float = 1e-4) -> np.ndarray:
    """Two-sided Student-t half-width for the mean of ``samples`` along axis 0 at level ``alpha``.

    The tolerance of every statistical test comes from the replicates themselves: the standard
    error of their mean times the t quantile for len(samples) - 1 degrees of freedom.
    """
    R = samples.shape[0]
    se = samples.std(axis=0, ddof=1) / np.sqrt(R)
    return stats.t.ppf(1 - alpha / 2, R - 1) * se


@pytest.fixture
def tol():
    return mc_tolerance


def check_monte_carlo_recovery(name: str, seed: int, R: int, n: int = 1_000_000, coefs=("N", "B")) -> None:
    """White + Gauss-Markov + random walk, 2.8 h at 100 Hz, R replicates fitted by estimator ``name``.

    The mean is within 3 standard errors of the truth, and the estimator's own standard errors
    (``diagnostics_["std_err"]``) agree with the replicate spread (variance ratio inside the
    chi^2_{R-1} 99.8 % interval).
    """
    from avbench import estimators
    from avbench.noise_models import AngleRandomWalk, GaussMarkov, Gyro, RateRandomWalk

    g = Gyro(dt=0.01, terms=[AngleRandomWalk(N=8.7e-4), GaussMarkov(sigma=1e-4, tc=50.0), RateRandomWalk(K=2e-6)])
    coefs = list(coefs)
    est, se = [], []
    for s in np.random.SeedSequence(seed).spawn(R):
        e = estimators.get(name).fit(g.simulate(n, np.random.default_rng(s)), 0.01)
        est.append(e.coefficients_[coefs].values)
        se.append(e.diagnostics_["std_err"][coefs].values)
    est, se = np.array(est), np.array(se)
    assert_mc_recovery(g.coefficients[coefs].values, est, se)


def assert_mc_recovery(truth, est, se) -> None:
    """Replicates ``est`` (R x p) are unbiased for ``truth`` within 3 Monte Carlo standard errors, and
    the estimator's standard errors ``se`` (R x p) match their spread (variance ratio inside the
    chi^2_{R-1} 99.8 % interval)."""
    R = est.shape[0]
    sd = est.std(axis=0, ddof=1)
    assert np.all(np.abs(est.mean(axis=0) - truth) < 3 * sd / np.sqrt(R)), (est.mean(axis=0), truth, sd)
    lo, hi = stats.chi2.ppf([0.001, 0.999], R - 1) / (R - 1)
    ratio = sd**2 / np.mean(se**2, axis=0)
    assert np.all((ratio > lo) & (ratio < hi)), ratio


#: tidy-table columns that must be identical between runs (all but the fit time)
STUDY_COLS = ["gyro", "replicate", "estimator", "coefficient", "true", "estimate", "nonphysical", "failure"]

_TINY_BODY = """
[[gyros]]
name = "g1"
dt = 0.1
terms = [{type = "AngleRandomWalk", N = [0.5, "deg/sqrt(h)"]}, {type = "Quantization", Q = 1e-5},
         {type = "BiasInstability", B = [10.0, "deg/h"], tau_max = 600.0}]

[[gyros]]
name = "g2"
dt = 0.05
terms = [{type = "AngleRandomWalk", N = [0.2, "deg/sqrt(h)"]}, {type = "RateRandomWalk", K = [50.0, "deg/h^1.5"]}]

[[estimators]]
name = "ols"
settings = { terms = "QNB", taus = "octave" }

[[estimators]]
name = "wls"
settings = { terms = "QNBK", taus = "all" }
"""


def study_toml(name="tiny", seed=7, replicates=6, block_size=2, n_samples=3000, extra_study="", extra_estimators=""):
    """A tiny two-gyro study (short records, cheap estimators) for the runner tests."""
    import textwrap

    head = (
        f'[study]\nname = "{name}"\nseed = {seed}\nreplicates = {replicates}\n'
        f"n_samples = {n_samples}\nblock_size = {block_size}\n{extra_study}\n"
    )
    return head + _TINY_BODY + textwrap.dedent(extra_estimators)


PLUGIN_PKG = __import__("pathlib").Path(__file__).parent / "plugin_pkg"


@pytest.fixture(scope="session")
def example_plugin():
    """The example plugin package ``tests/plugin_pkg`` installed into this test environment.

    A real install (``pip install``, offline, no dependencies, its own standard-library build
    backend), so that its entry points are seen by this process and by every worker process;
    uninstalled at the end of the session. Nothing is written into the source tree but Python's
    byte-code cache (git-ignored).
    """
    import importlib
    import subprocess
    import sys

    from avbench.noise_models import plugins

    pip = [sys.executable, "-m", "pip", "--disable-pip-version-check", "-q"]
    subprocess.run(
        pip + ["install", "--no-deps", "--no-build-isolation", "--no-index", "--force-reinstall", str(PLUGIN_PKG)],
        check=True,
    )
    importlib.invalidate_caches()
    plugins._entry_points.cache_clear()
    yield "avbench_example_plugin"
    subprocess.run(pip + ["uninstall", "-y", "avbench-example-plugin"], check=False)
    importlib.invalidate_caches()
    plugins._entry_points.cache_clear()


@pytest.fixture(scope="module")
def dask_cluster():
    """A real ``distributed.LocalCluster`` (2 worker processes, 1 thread each) for a test module."""
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0") as c:
        yield c


#: the optional, licensed static recordings (folder with adis16405-calgary/ and mtig-cont-imu1/),
#: read in place where the environment variable AVBENCH_REAL_DATA says; tests that need them skip
REAL_DATA = os.environ.get("AVBENCH_REAL_DATA")


def real_recording(rel: str):
    """(path, skip marker) of one recording under :data:`REAL_DATA`; the marker skips, saying why,
    when the variable is unset or the file is absent."""
    from pathlib import Path

    path = Path(REAL_DATA or "/nonexistent") / rel
    why = ("real recordings not configured: set AVBENCH_REAL_DATA to their folder (optional, licensed data)"
           if not REAL_DATA else f"{rel} not found under AVBENCH_REAL_DATA={REAL_DATA} (optional, licensed data)")
    return path, pytest.mark.skipif(not path.exists(), reason=why)
