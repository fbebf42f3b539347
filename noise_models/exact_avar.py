"""Exact Allan variance of discrete-time stationary processes, from their autocovariance.

For a stationary rate sequence with autocovariance r(i) (lag i samples), let
V(l) = Var(sum of l consecutive samples) = l r(0) + 2 sum_{i=1}^{l-1} (l - i) r(i).
The non-overlapping Allan variance at cluster size m is

.. math::

    \\sigma^2(m) = \\frac{1}{2}E[(\\bar\\omega_{k+1} - \\bar\\omega_k)^2] = \\frac{4V(m) - V(2m)}{2m^2},

which equals the general formula quoted in SPEC ("Discrete generators"):
(1/m^2)[m(1 - rho(m)) + sum_{i=1}^{m-1} i(2 rho(m-i) - rho(i) - rho(2m-i))] sigma^2.
The sums are accumulated in extended precision (numpy.longdouble) because 4V(m) - V(2m) cancels
when the process is strongly correlated over 2m samples.
"""

from __future__ import annotations

import numpy as np

__all__ = ["avar_from_autocovariance", "check_m"]


def check_m(m) -> np.ndarray:
    """Cluster sizes as a 1-D int array of positive integers (an int64 array that is one already is
    returned as it is: fits call the exact AV at the same cluster sizes thousands of times)."""
    if type(m) is np.ndarray and m.dtype == np.int64 and m.ndim == 1 and m.size and m.min() >= 1:
        return m
    arr = np.atleast_1d(np.asarray(m))
    if arr.ndim != 1 or arr.size == 0:
        raise ValueError(f"cluster sizes: expected a non-empty 1-D array, got shape {arr.shape}")
    mi = np.rint(arr).astype(np.int64)
    if np.any(np.abs(arr - mi) > 1e-9 * np.maximum(1, np.abs(arr))) or np.any(mi < 1):
        raise ValueError(f"cluster sizes: expected positive integers, got {arr!r}")
    return mi


def avar_from_autocovariance(r, m) -> np.ndarray:
    """Exact non-overlapping-cluster AV at cluster sizes ``m`` from autocovariance ``r``.

    Parameters
    ----------
    r : array_like
        Autocovariance at lags 0, 1, ..., len(r)-1 (rate units squared); lags beyond are taken as 0.
    m : array_like of int
        Cluster sizes (samples).
    """
    m = check_m(m)
    r = np.asarray(r, dtype=np.longdouble)
    lmax = int(2 * m.max())
    rr = np.zeros(lmax + 1, dtype=np.longdouble)
    k = min(len(r), lmax + 1)
    rr[:k] = r[:k]
    i = np.arange(lmax + 1, dtype=np.longdouble)
    # C1(l) = sum_{i=1}^{l-1} r(i), C2(l) = sum_{i=1}^{l-1} i r(i)
    c1 = np.concatenate(([0.0, 0.0], np.cumsum(rr[1:lmax])))
    c2 = np.concatenate(([0.0, 0.0], np.cumsum((i * rr)[1:lmax])))

    def var_sum(l):
        return l * rr[0] + 2 * (l * c1[l] - c2[l])

    ml = m.astype(np.longdouble)
    av = (4 * var_sum(m) - var_sum(2 * m)) / (2 * ml * ml)
    return np.asarray(av, dtype=np.float64)
