"""The differences of the masked Allan variance at one cluster size, in one compiled pass
(:func:`avbench.estimators.robust.gmwm.masked_allan_variance`).

:func:`masked_differences_py` is the reference: the same element-wise arithmetic as the NumPy expressions
``(S[2m:] - S[m:-m]) / c2 - (S[m:-m] - S[:-2m]) / c1`` and ``1 / c1 + 1 / c2`` over the starts whose two
clusters both hold a kept sample (``c1, c2 > 0``), so the compiled pass returns the same bits (tests); the
means over them are NumPy's (pairwise sums), taken by the caller.
"""

from __future__ import annotations

__all__ = ["masked_differences", "masked_differences_py"]


def masked_differences_py(S, C, m, d, g):
    """Into ``d[:k]`` the differences of the means of the kept samples of two adjacent clusters of ``m``
    samples, and into ``g[:k]`` ``1 / c1 + 1 / c2`` (``c1, c2`` the kept samples in each), for the ``k`` starts
    (in order) whose two clusters both hold one; ``S`` the cumulative sum of the kept samples (0 for the
    others) and ``C`` the cumulative count of kept samples, each with a leading 0. Returns ``k``."""
    k = 0
    for i in range(C.size - 2 * m):
        c1 = C[i + m] - C[i]
        c2 = C[i + 2 * m] - C[i + m]
        if c1 > 0 and c2 > 0:
            d[k] = (S[i + 2 * m] - S[i + m]) / c2 - (S[i + m] - S[i]) / c1
            g[k] = 1.0 / c1 + 1.0 / c2
            k += 1
    return k


try:
    from numba import njit

    masked_differences = njit(cache=True)(masked_differences_py)
except ImportError:  # pragma: no cover
    masked_differences = masked_differences_py
