"""Compiled integrand of Imhof's (1961) integral for :func:`avbench.estimators.allan.fit_check.weighted_chi2_sf`.

QUADPACK calls the integrand a few thousand times per p-value; as a Python function (two NumPy
reductions per call) it costs 10-30 ms, most of a curve fit with its check (``nnls_rel`` would take
26x the octave AV it fits). As a C callback (:class:`scipy.LowLevelCallable` of a numba ``cfunc``) the
same integrals cost ~0.5 ms (``results/bench/README.md``). The terms are summed in index order with
the C library's ``atan`` and ``log1p`` instead of NumPy's pairwise sums and SIMD loops: the p-values
agree to ~3e-16 absolute (``tests/test_fit_check.py``), far below the integral's own error (~1e-14).

The callback's arguments (``xx``, ``n`` of them) are ``u, mode, x, w_1 ... w_k``: the integration
variable, which part of the integral (0: the direct part sin(theta(u)) / (u rho(u)) on [0, a]; 1 and 2: the
Fourier parts sin(phi) / (u rho) and -cos(phi) / (u rho) that QUADPACK's QAWF multiplies by cos(xu/2)
and sin(xu/2)), the point x and the weights.
"""

import math

from numba import cfunc, types


@cfunc(types.float64(types.intc, types.CPointer(types.float64)), cache=True)
def imhof_integrand(n, xx):
    u = xx[0]
    mode = xx[1]
    x = xx[2]
    phi = 0.0
    log_rho4 = 0.0
    for i in range(3, n):
        wu = xx[i] * u
        phi += math.atan(wu)
        log_rho4 += math.log1p(wu * wu)
    phi *= 0.5
    rho = math.exp(0.25 * log_rho4)
    if mode == 0.0:
        return math.sin(phi - 0.5 * x * u) / (u * rho)
    if mode == 1.0:
        return math.sin(phi) / (u * rho)
    return -math.cos(phi) / (u * rho)
