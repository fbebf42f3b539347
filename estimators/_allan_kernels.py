"""Compiled inner loops of the Allan-variance engine (one pass over the cumulative sum per tau).

``S`` is the cumulative sum of the (mean-removed) rate with S[0] = 0. The plain NumPy versions in
:mod:`estimators.allan` (``_oavar_sums_numpy``, ``_avar_sums_numpy``) are the reference the tests
compare against.
"""

import numpy as np
from numba import njit, prange


@njit(cache=True, parallel=True)
def oavar_sums(S, m):
    """sum_k (S[k+2m] - 2 S[k+m] + S[k])^2 for each m (fully overlapping)."""
    out = np.empty(m.size)
    n1 = S.size
    for i in prange(m.size):
        mi = m[i]
        count = n1 - 2 * mi
        a0 = 0.0
        a1 = 0.0
        a2 = 0.0
        a3 = 0.0
        k = 0
        while k + 3 < count:
            d0 = S[k + 2 * mi] - 2.0 * S[k + mi] + S[k]
            d1 = S[k + 1 + 2 * mi] - 2.0 * S[k + 1 + mi] + S[k + 1]
            d2 = S[k + 2 + 2 * mi] - 2.0 * S[k + 2 + mi] + S[k + 2]
            d3 = S[k + 3 + 2 * mi] - 2.0 * S[k + 3 + mi] + S[k + 3]
            a0 += d0 * d0
            a1 += d1 * d1
            a2 += d2 * d2
            a3 += d3 * d3
            k += 4
        while k < count:
            d0 = S[k + 2 * mi] - 2.0 * S[k + mi] + S[k]
            a0 += d0 * d0
            k += 1
        out[i] = (a0 + a1) + (a2 + a3)
    return out


@njit(cache=True, parallel=True)
def avar_sums(S, m):
    """sum_j (C_{j+1} - C_j)^2 over adjacent non-overlapping cluster sums C_j, for each m."""
    out = np.empty(m.size)
    n = S.size - 1
    for i in prange(m.size):
        mi = m[i]
        J = n // mi
        acc = 0.0
        for j in range(J - 1):
            d = S[(j + 2) * mi] - 2.0 * S[(j + 1) * mi] + S[j * mi]
            acc += d * d
        out[i] = acc
    return out
