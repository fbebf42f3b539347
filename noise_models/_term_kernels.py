"""The generators' sequential recursions, compiled with numba, and their plain-Python twins.

Each kernel works in place on a chunk of standard normal draws and returns the state the next chunk
starts from, so a record generated in chunks equals the record generated at once, bit for bit
(:class:`avbench.noise_models.term_base.TermStream`). The ``*_py`` functions are the same arithmetic in
plain Python: the kernels are compiled from them, and they are used where numba is not available.
The Gauss-Markov AV with its derivative (:func:`_gm_shape_py`) is the analytic Jacobian column of
:meth:`avbench.noise_models.GaussMarkov.avar_shape_derivative`.
"""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np

__all__: list[str] = []


def _diff_kernel_py(x, Q, prev, dt):
    """x_k <- (Q x_k - theta_{k-1}) / dt in place (theta_{-1} = prev); returns theta_last."""
    last = Q * x[x.shape[0] - 1]
    for k in range(x.shape[0] - 1, 0, -1):
        x[k] = (Q * x[k] - Q * x[k - 1]) / dt
    x[0] = (Q * x[0] - prev) / dt
    return last


def _walk_kernel_py(x, step, acc):
    """x_k <- acc_k = acc_{k-1} + step x_k in place; returns the last value."""
    for k in range(x.shape[0]):
        acc = acc + step * x[k]
        x[k] = acc
    return acc


def _ar1_kernel_py(e, phi, z):
    """e_k <- e_k + z, z <- phi e_k (in place); returns the carry phi x_last for the next chunk."""
    for k in range(e.shape[0]):
        x = e[k] + z
        e[k] = x
        z = phi * x
    return z


def _gm_shape_py(m, a, g, dg):
    """g(m, a) = f(m) / (1 - phi)^2 (:func:`avbench.noise_models.markov_terms._gm_f_over_c2`, phi = exp(-a))
    and its derivative dg/da,
    per cluster size ``m`` (float array), written into ``g`` and ``dg``.

    Element by element, the same two forms as :func:`_gm_f_over_c2`: where (2m+1) a < 1 the Taylor
    series f = sum_{k>=3} (-a)^k / k! c_k, c_k = -m 2^k - 3 + 4 (m+1)^k - (2m+1)^k, and its term-by-term
    derivative f' = sum_{k>=3} (-1)^k a^(k-1) / (k-1)! c_k (powers by recurrence); elsewhere
    f = m (1 - phi^2) - phi (-4 expm1(-m a) + expm1(-2 m a)) and
    f' = 2m phi^2 + 3 phi - 4(m+1) phi^(m+1) + (2m+1) phi^(2m+1)
    = phi (2m expm1(-a) - 4(m+1) expm1(-m a) + (2m+1) expm1(-2 m a)) (no cancellation). Then
    g' = f'/c^2 - 2 f phi / c^3 with c = 1 - phi. Each series stops where its next term is below
    1e-18 of its sum (per element; ``_gm_f_over_c2`` stops for the whole array at once: the values
    agree to round-off, tests)."""
    c = -math.expm1(-a)
    phi = math.exp(-a)
    for i in range(m.shape[0]):
        mi = m[i]
        if (2.0 * mi + 1.0) * a < 1.0:
            p2, pm, p2m = 8.0, (mi + 1.0) ** 3, (2.0 * mi + 1.0) ** 3
            term = a * a * a / 6.0  # a^k / k!
            dterm = a * a / 2.0  # a^(k-1) / (k-1)!
            f = 0.0
            df = 0.0
            sign = -1.0
            for k in range(3, 60):
                ck = -mi * p2 - 3.0 + 4.0 * pm - p2m
                f += sign * term * ck
                df += sign * dterm * ck
                dterm = term
                term *= a / (k + 1)
                p2 *= 2.0
                pm *= mi + 1.0
                p2m *= 2.0 * mi + 1.0
                sign = -sign
                if term * p2m < 1e-18 * abs(f) and dterm * p2m < 1e-18 * abs(df):
                    break
        else:
            e1 = math.expm1(-mi * a)
            e2 = math.expm1(-2.0 * mi * a)
            f = mi * (-math.expm1(-2.0 * a)) - phi * (-4.0 * e1 + e2)
            df = phi * (2.0 * mi * math.expm1(-a) - 4.0 * (mi + 1.0) * e1 + (2.0 * mi + 1.0) * e2)
        g[i] = f / (c * c)
        dg[i] = df / (c * c) - 2.0 * f * phi / (c * c * c)


def _gm_rows_py(mf, a, c2, s1, s2, t3, e, p1, p2, q, pow2, out):
    """g(m, a) = f(m) / (1 - phi)^2 (phi = exp(-a)) for each row's ``a[r]``, written into ``out[r]``: the
    arithmetic of :func:`avbench.noise_models.markov_terms._gm_f_over_c2_numpy` in its order, one row at a
    time, so each row is bit for bit that function's result at ``a[r]``.

    The values that function takes from NumPy's vectorised math or from scalar ``pow`` / ``expm1`` /
    ``exp`` come in precomputed by the caller (:func:`avbench.noise_models.markov_terms._gm_f_over_c2_rows`):
    per row ``c2 = (1 - phi)^2``, ``s1 = -expm1(-2a)``, ``s2 = exp(-a)``, ``t3 = a^3 / 6``; ``e[r]`` the
    vectorised ``expm1(-m a)`` then ``expm1(-2 m a)``; per series index ``i`` (k = i + 3) and cluster
    size ``j``: ``p1[i, j] = (m_j + 1)^k`` and ``p2[i, j] = (2 m_j + 1)^k`` (vectorised), ``q[i, j] =
    (2 m_j + 1)^(k+1)`` (scalar pow), ``pow2[i] = 2^k``.

    Where (2m+1) a < 1 the Taylor series f = sum_{k>=3} (-a)^k / k! c_k with
    c_k = -m 2^k - 3 + 4 (m+1)^k - (2m+1)^k, stopped for all those m at once where the next term bound
    a^(k+1)/(k+1)! (2 max m + 1)^(k+1) is below 1e-18 of the smallest |sum|; elsewhere
    f = m (1 - phi^2) - phi (-4 expm1(-m a) + expm1(-2 m a))."""
    nm = mf.shape[0]
    small = np.empty(nm, dtype=np.bool_)
    total = np.empty(nm)
    for r in range(a.shape[0]):
        ar = a[r]
        ns = 0
        jmax = -1
        for j in range(nm):
            small[j] = (2.0 * mf[j] + 1.0) * ar < 1.0
            if small[j]:
                ns += 1
                if jmax < 0 or mf[j] > mf[jmax]:
                    jmax = j
                total[j] = 0.0
        if ns > 0:
            term = t3[r]
            sign = -1.0
            for i in range(p1.shape[0]):
                k = i + 3
                st = sign * term
                for j in range(nm):
                    if small[j]:
                        ck = -mf[j] * pow2[i] - 3.0 + 4.0 * p1[i, j] - p2[i, j]
                        total[j] = total[j] + st * ck
                term = term * (ar / (k + 1))
                sign = -sign
                smallest = np.inf
                for j in range(nm):
                    if small[j]:
                        v = abs(total[j])
                        if v != v:
                            smallest = v
                            break
                        if v < smallest:
                            smallest = v
                if term * q[i, jmax] < 1e-18 * smallest:
                    break
        for j in range(nm):
            if small[j]:
                out[r, j] = total[j] / c2[r]
            else:
                f = mf[j] * s1[r] - s2[r] * (-4.0 * e[r, j] + e[r, nm + j])
                out[r, j] = f / c2[r]



def _gm_central_py(mf, a, c2, s1, s2, t3, e, p1, p2, q, pow2, var, step, value, deriv):
    """A Gauss-Markov AV and its central difference: with ``g`` the three rows of :func:`_gm_rows_py` (at
    ``a[0]`` and the two steps ``a[1]``, ``a[2]``) and ``var`` the three variances,
    ``value = var[0] g[0] / m^2`` and ``deriv = (var[1] g[1] / m^2 - var[2] g[2] / m^2) / step``, each
    operation as NumPy's element-wise one (the first-order filter's shape derivative,
    :meth:`avbench.noise_models.FilteredWhiteNoise.avar_shape_derivative`)."""
    g = np.empty((3, mf.shape[0]))
    _gm_rows_kernel(mf, a, c2, s1, s2, t3, e, p1, p2, q, pow2, g)
    for j in range(mf.shape[0]):
        mf2 = mf[j] * mf[j]
        value[j] = var[0] * g[0, j] / mf2
        deriv[j] = (var[1] * g[1, j] / mf2 - var[2] * g[2, j] / mf2) / step


def _fma(a, b, c):
    """a b + c rounded once (exact rational arithmetic here; the compiled kernels use the processor's fused
    multiply-add, the same value)."""
    if not (math.isfinite(a) and math.isfinite(b) and math.isfinite(c)):
        return a * b + c
    return float(Fraction(a) * Fraction(b) + Fraction(c))


def _cmul(xr, xi, yr, yi, fused):
    """x y for complex x = xr + i xi, y = yr + i yi as NumPy multiplies complex128 arrays: with ``fused`` (its
    vectorised loops on a processor with fused multiply-add, e.g. AVX-512) each part one fma,
    (fma(xr, yr, -(xi yi)), fma(xr, yi, xi yr)); else the plain products (xr yr - xi yi, xr yi + xi yr).
    Which one NumPy does here: :func:`numpy_complex_product`."""
    if fused:
        return _fma(xr, yr, -(xi * yi)), _fma(xr, yi, xi * yr)
    return xr * yr - xi * yi, xr * yi + xi * yr


def numpy_complex_product():
    """``True`` when NumPy's complex128 products (array by array, array by scalar, scalar by array) are the
    fused form of :func:`_cmul`, ``False`` when they are the plain one, None when neither (then no kernel
    reproduces them): probed on pairs whose two forms differ."""
    rng = np.random.default_rng(12345)
    x = rng.standard_normal(64) + 1j * rng.standard_normal(64)
    y = rng.standard_normal(64) + 1j * rng.standard_normal(64)
    got = [x * y, x * y[0], x[0] * y]
    pairs = [(x, y), (x, np.full(64, y[0])), (np.full(64, x[0]), y)]
    for fused in (True, False):
        if all(complex(*_cmul_py(a.real, a.imag, b.real, b.imag, fused)) == g
               for prod, (xs, ys) in zip(got, pairs) for a, b, g in zip(xs, ys, prod)):
            return fused
    return None


_cmul_py = _cmul


def _cdiv(xr, xi, yr, yi):
    """x / y as NumPy divides complex128 arrays (Smith's algorithm, unfused)."""
    if abs(yr) >= abs(yi):
        if yr == 0.0 and yi == 0.0:
            return xr / abs(yr), xi / abs(yr)
        rat = yi / yr
        scl = 1.0 / (yr + yi * rat)
        return (xr + xi * rat) * scl, (xi - xr * rat) * scl
    rat = yr / yi
    scl = 1.0 / (yi + yr * rat)
    return (xr * rat + xi) * scl, (xi * rat - xr) * scl


def _cexpm1(zr, zi):
    """expm1(z) as NumPy computes it for complex128: (expm1(x) cos y - 2 sin^2(y/2), e^x sin y)."""
    a = math.sin(zi / 2)
    return math.expm1(zr) * math.cos(zi) - 2 * a * a, math.exp(zr) * math.sin(zi)


def _resonance_rows_py(mi, absalpha, alpha, k1, p, cg, s, sigma2, fused, small, out):
    """The resonance's exact AV (:meth:`avbench.noise_models.Resonance.avar`) at cluster sizes ``mi`` (int)
    for each row's poles, in the closed form sigma^2 Re{(1 + i c) F_m(phi)} with
    F_m = [m (-expm1(-2 alpha)) - e^-alpha (-4 expm1(-m alpha) + expm1(-2 m alpha))] / [m^2 (-expm1(-alpha))^2]:
    NumPy's operations of ``_gm_form`` in their order (complex products fused as NumPy's vectorised
    loops fuse them where ``fused``, :func:`_cmul`), so each value is bit for bit NumPy's. Per row (complex arrays but
    ``absalpha`` and ``sigma2``): ``absalpha`` |alpha|, ``alpha``, ``k1`` -expm1(-2 alpha), ``p`` e^-alpha,
    ``cg`` -expm1(-alpha), ``s`` 1 + i c, ``sigma2``. Where (2m + 1)|alpha| < 1 the closed form loses digits: ``small[r, j]`` is set and
    ``out[r, j]`` left for the caller (the autocovariance route)."""
    for r in range(alpha.shape[0]):
        ar, ai = alpha[r].real, alpha[r].imag
        pr, pim = p[r].real, p[r].imag
        cgr, cgi = cg[r].real, cg[r].imag
        for j in range(mi.shape[0]):
            small[r, j] = (2 * mi[j] + 1) * absalpha[r] < 1.0
            if small[r, j]:
                continue
            x = float(mi[j])
            z1r, z1i = _cmul(-x, 0.0, ar, ai, fused)
            e1r, e1i = _cexpm1(z1r, z1i)
            z2r, z2i = _cmul(-2.0 * x, 0.0, ar, ai, fused)
            e2r, e2i = _cexpm1(z2r, z2i)
            qr, qi = _cmul(-4.0, 0.0, e1r, e1i, fused)
            vr, vi = _cmul(pr, pim, qr + e2r, qi + e2i, fused)
            tr, ti = _cmul(x, 0.0, k1[r].real, k1[r].imag, fused)
            d0r, d0i = _cmul(x * x, 0.0, cgr, cgi, fused)
            dr, di = _cmul(d0r, d0i, cgr, cgi, fused)
            fr, fi = _cdiv(tr - vr, ti - vi, dr, di)
            gr, _ = _cmul(s[r].real, s[r].imag, fr, fi, fused)
            out[r, j] = sigma2[r] * gr


def _sogm_kernel_py(A, C, e, x, out):
    """x_k = A x_{k-1} + C e_k (C lower-triangular), out_k = first state; x updated in place."""
    a00, a01, a10, a11 = A[0, 0], A[0, 1], A[1, 0], A[1, 1]
    c00, c10, c11 = C[0, 0], C[1, 0], C[1, 1]
    x0, x1 = x[0], x[1]
    for k in range(e.shape[0]):
        w0 = c00 * e[k, 0]
        w1 = c10 * e[k, 0] + c11 * e[k, 1]
        x0, x1 = a00 * x0 + a01 * x1 + w0, a10 * x0 + a11 * x1 + w1
        out[k] = x0
    x[0], x[1] = x0, x1


try:  # compiled when numba is available (it is a dependency); same arithmetic either way
    from llvmlite import ir as _ir
    from numba import njit, types as _types
    from numba.core import cgutils
    from numba.extending import intrinsic, overload

    @intrinsic
    def _fma_llvm(typingctx, a, b, c):
        """LLVM's fused multiply-add (one rounding; the processor's instruction where it has one)."""
        def codegen(context, builder, signature, args):
            d = _ir.DoubleType()
            fn = cgutils.get_or_insert_function(builder.module, _ir.FunctionType(d, [d, d, d]), "llvm.fma.f64")
            return builder.call(fn, args)

        return _types.float64(_types.float64, _types.float64, _types.float64), codegen

    @overload(_fma)
    def _fma_compiled(a, b, c):
        return lambda a, b, c: _fma_llvm(a, b, c)

    _cmul = njit(cache=True)(_cmul)
    _cdiv = njit(cache=True)(_cdiv)
    _cexpm1 = njit(cache=True)(_cexpm1)

    _sogm_kernel = njit(cache=True)(_sogm_kernel_py)
    _ar1_kernel = njit(cache=True)(_ar1_kernel_py)
    _diff_kernel = njit(cache=True)(_diff_kernel_py)
    _walk_kernel = njit(cache=True)(_walk_kernel_py)
    _gm_shape_kernel = njit(cache=True)(_gm_shape_py)
    _gm_rows_kernel = njit(cache=True)(_gm_rows_py)
    _gm_central_kernel = njit(cache=True)(_gm_central_py)
    _resonance_rows_kernel = njit(cache=True)(_resonance_rows_py)
except ImportError:  # pragma: no cover
    _gm_shape_kernel = _gm_shape_py
    _gm_rows_kernel = _gm_rows_py
    _gm_central_kernel = _gm_central_py
    _resonance_rows_kernel = _resonance_rows_py
    _diff_kernel = _diff_kernel_py
    _walk_kernel = _walk_kernel_py
    _sogm_kernel = _sogm_kernel_py
    _ar1_kernel = _ar1_kernel_py

