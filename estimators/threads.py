"""One BLAS thread for the small dense linear algebra of a fit.

The estimators' optimisers (L-BFGS-B, trust-region least squares, NNLS, the SVD of a least-squares
fit) call BLAS and LAPACK on matrices of a few to a few tens of columns. OpenBLAS hands even those
to its thread pool, and waking the pool costs more than the arithmetic: on a machine whose cores
are busy (other processes, a study's own workers) a thread waits for its time slice, and scipy's
L-BFGS-B on 4 parameters takes ~10 ms per iteration instead of ~0.1 ms (``results/bench/README.md``).
:func:`one_blas_thread` limits every loaded BLAS to one thread for the duration of a block (the
values do not depend on it: OpenBLAS does not split matrices this small between threads). A
study's worker processes already run with one BLAS thread (``studies.workers``); this makes a fit
in the parent process (``avbench estimate``, ``--jobs 1``, a notebook) do the same.
"""

from __future__ import annotations

import contextlib

__all__ = ["one_blas_thread"]

_controller = None


def _get_controller():
    """The controller of every BLAS the fits call: NumPy's and SciPy's (scipy.linalg loaded first: a library
    loaded after the controller lists them is not limited -- SciPy's LAPACK, e.g. the whitening solves of
    GMWM's second step, then runs on the full thread pool)."""
    global _controller
    if _controller is None:
        import scipy.linalg  # noqa: F401  (SciPy's own OpenBLAS, listed below)
        from threadpoolctl import ThreadpoolController

        _controller = ThreadpoolController()  # lists the loaded BLAS libraries once (~10 ms)
    return _controller


@contextlib.contextmanager
def one_blas_thread():
    """Context manager: every BLAS library loaded when the first block ran (NumPy's and SciPy's at least) uses
    one thread inside it (~15 us to enter and leave)."""
    with _get_controller().limit(limits=1, user_api="blas"):
        yield
