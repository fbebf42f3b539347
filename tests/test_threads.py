"""The fits' linear algebra runs on one BLAS thread (estimators.threads)."""

import numpy as np
from threadpoolctl import ThreadpoolController, threadpool_limits

from avbench.estimators.threads import one_blas_thread


def _blas_threads():
    return {lib["filepath"]: lib["num_threads"] for lib in ThreadpoolController().info() if lib["user_api"] == "blas"}


def test_one_blas_thread_inside_and_restored_after():
    with threadpool_limits(limits=2, user_api="blas"):
        before = _blas_threads()
        with one_blas_thread():
            inside = _blas_threads()
        after = _blas_threads()
    assert inside and set(inside.values()) == {1}
    assert after == before


def test_a_fit_runs_on_one_blas_thread(monkeypatch):
    # the estimators' small solves see one thread, whatever the caller set
    from avbench import estimators

    import scipy.linalg

    seen = []

    def spy(f):
        def inner(*args, **kwargs):
            seen.append(set(_blas_threads().values()))
            return f(*args, **kwargs)
        return inner

    # the solvers a least-squares fit may call: the normal equations' eigenvalues and Cholesky factor
    # the SVD fallback
    for module, name in ((np.linalg, "lstsq"), (np.linalg, "eigvalsh"), (scipy.linalg, "cho_factor")):
        monkeypatch.setattr(module, name, spy(getattr(module, name)))
    x = np.random.default_rng(0).standard_normal(20_000) * 1e-3
    with threadpool_limits(limits=2, user_api="blas"):
        estimators.get("wls", taus="octave").fit(x, 0.01)
    assert seen and all(s == {1} for s in seen)


def test_scipy_blas_limited_when_the_first_block_runs_before_scipy_is_loaded():
    """A process whose first one-thread block runs before scipy.linalg is imported (an ``avbench estimate``
    worker, a script fitting an axis): SciPy's own BLAS, whose LAPACK the fits call, is held to one thread too."""
    import subprocess
    import sys

    code = (
        "import sys\n"
        "from threadpoolctl import threadpool_limits, ThreadpoolController\n"
        "from avbench.estimators.threads import one_blas_thread\n"
        "assert 'scipy.linalg' not in sys.modules\n"
        "with one_blas_thread():\n"
        "    pass\n"
        "import scipy.linalg\n"
        "with threadpool_limits(limits=2, user_api='blas'):\n"
        "    with one_blas_thread():\n"
        "        info = ThreadpoolController().info()\n"
        "libs = {i['filepath']: i['num_threads'] for i in info if i['user_api'] == 'blas'}\n"
        "print(sorted(set(libs.values())))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[1]"
