"""The latent model's exact AV and its Jacobian in the log-parameters, in one compiled call
(:class:`avbench.estimators.likelihood._gmwm_model.LatentAV`).

:func:`latent_av_py` is the arithmetic of the reference (:class:`~avbench.estimators.likelihood._gmwm_model.
LatentAVReference`, the terms' own ``avar_shape_gradient``) written as one loop over the model's blocks:

.. math:: \\mathrm{AV}(u) = \\sum_l e^{2u_l}\\,U_l(\\tau; e^{v_l}),\\qquad
    \\partial_{u_l}\\mathrm{AV} = 2e^{2u_l}U_l,\\quad \\partial_{v_l}\\mathrm{AV} = e^{2u_l}\\,\\partial_{\\ln p} U_l

with the unit curves :math:`U_l` of each kind of block (:data:`FIXED` a curve without shape parameter, computed
once by the caller; :data:`GAUSS_MARKOV` the analytic d/d ln Tc; :data:`FILTER` the first-order filter's
central difference in ln tf, step 1e-4; :data:`SINUSOID` the analytic d/d ln f0; :data:`RESONANCE` central
differences in ln f0 and ln tc with the steps of :meth:`avbench.noise_models.Resonance.gradient_steps`),
calling the terms' own compiled kernels (:mod:`avbench.noise_models._term_kernels`). It returns 0, or 1 where a
block needs what only the reference does (a resonance's cluster sizes below its closed form's range, where the
reference sums the autocovariance in extended precision; a parameter outside the values a term accepts, where
the reference raises): the caller then asks the reference. The values agree with the reference to round-off
(the element-wise functions of NumPy's vectorised loops against the processor's libm; tests).
"""

from __future__ import annotations

import cmath
import math

import numpy as np

from avbench.noise_models._term_kernels import (_cexpm1, _gm_central_kernel, _gm_shape_kernel,
                                                _resonance_rows_kernel)
from avbench.noise_models.sensor_terms import GRADIENT_PHASE_STEP

__all__ = ["FIXED", "GAUSS_MARKOV", "FILTER", "SINUSOID", "RESONANCE", "latent_av", "latent_av_py"]

#: kinds of block: a unit curve without shape parameter (given), a Gauss-Markov term (tc), white noise through
#: the first-order filter (tf), a sinusoid (f0), a resonance (f0, tc)
FIXED, GAUSS_MARKOV, FILTER, SINUSOID, RESONANCE = 0, 1, 2, 3, 4

#: the relative step in ln tf of the filter's central difference
#: (:meth:`avbench.noise_models.FilteredWhiteNoise.avar_shape_derivative`)
_FILTER_STEP = 1e-4


def _filter_unit(mf, dt, tf, p1, p2, q, pow2, neg_m12, value, deriv):
    """:meth:`avbench.noise_models.FilteredWhiteNoise.avar_shape_derivative` at N = 1: the Gauss-Markov form
    at tf and tf e^{+-h} (compiled :func:`~avbench.noise_models._term_kernels._gm_central_py`); False where a
    step leaves the values a term accepts (the reference's one-sided fallback)."""
    h = _FILTER_STEP
    tfs = (tf, tf * math.exp(h), tf * math.exp(-h))
    a = np.empty(3)
    c2 = np.empty(3)
    s1 = np.empty(3)
    s2 = np.empty(3)
    t3 = np.empty(3)
    var = np.empty(3)
    e = np.empty((3, neg_m12.shape[0]))
    for r in range(3):
        t = tfs[r]
        b = math.exp(-dt / t)
        sigma = math.sqrt(1.0 / dt * (1 - b) / (1 + b))
        if not (sigma > 0 and math.isfinite(sigma) and math.isfinite(t) and t > 0):
            return False
        var[r] = sigma**2
        x = dt / t
        a[r] = x
        c2[r] = (-math.expm1(-x)) ** 2
        s1[r] = -math.expm1(-2 * x)
        s2[r] = math.exp(-x)
        t3[r] = x**3 / 6.0
        for j in range(neg_m12.shape[0]):
            e[r, j] = math.expm1(x * neg_m12[j])
    _gm_central_kernel(mf, a, c2, s1, s2, t3, e, p1, p2, q, pow2, var, h - (-h), value, deriv)
    return True


def _resonance_unit(mi, dt, f0, tc, fused, value, d_f0, d_tc):
    """:meth:`avbench.noise_models.Resonance.avar_shape_gradient` at sigma = 1: five rows of the compiled
    closed form (:func:`~avbench.noise_models._term_kernels._resonance_rows_py`); False where a row is at or
    above the Nyquist frequency or a cluster size needs the autocovariance route."""
    m_max = 0.0
    for j in range(mi.shape[0]):
        m_max = max(m_max, float(mi[j]))
    w0, decay = 2 * math.pi * f0 * dt, m_max * dt / tc
    hf = min(1e-4, GRADIENT_PHASE_STEP / (w0 * m_max))
    ht = min(1e-4, GRADIENT_PHASE_STEP / decay)
    fs = (f0, f0 * math.exp(hf), f0 * math.exp(-hf), f0, f0)
    tcs = (tc, tc, tc, tc * math.exp(ht), tc * math.exp(-ht))
    absalpha = np.empty(5)
    alpha = np.empty(5, dtype=np.complex128)
    k1 = np.empty(5, dtype=np.complex128)
    p = np.empty(5, dtype=np.complex128)
    cg = np.empty(5, dtype=np.complex128)
    s = np.empty(5, dtype=np.complex128)
    sigma2 = np.ones(5)
    for r in range(5):
        f, t = fs[r], tcs[r]
        if not (f > 0 and math.isfinite(f) and t > 0 and math.isfinite(t)) or f >= 0.5 / dt * (1 - 1e-12):
            return False
        rho, w = math.exp(-dt / t), 2 * math.pi * f * dt
        c = -math.expm1(-2 * dt / t) / (2 * rho * math.sin(w))
        ar, ai = dt / t, -w
        alpha[r] = complex(ar, ai)
        absalpha[r] = math.hypot(ar, ai)
        er, ei = _cexpm1(-2.0 * ar, -2.0 * ai)
        k1[r] = complex(-er, -ei)
        p[r] = cmath.exp(complex(-ar, -ai))
        er, ei = _cexpm1(-ar, -ai)
        cg[r] = complex(-er, -ei)
        s[r] = complex(1.0, c)
    out = np.empty((5, mi.shape[0]))
    small = np.empty((5, mi.shape[0]), dtype=np.bool_)
    _resonance_rows_kernel(mi, absalpha, alpha, k1, p, cg, s, sigma2, fused, small, out)
    for r in range(5):
        for j in range(mi.shape[0]):
            if small[r, j]:
                return False
    for j in range(mi.shape[0]):
        value[j] = out[0, j]
        d_f0[j] = (out[1, j] - out[2, j]) / (2 * hf)
        d_tc[j] = (out[3, j] - out[4, j]) / (2 * ht)
    return True


def latent_av_py(kind, first, u, mi, dt, fixed, p1, p2, q, pow2, neg_m12, extra_j, extra_e, fused, value, jac):
    """The model's AV into ``value`` and its Jacobian in ``u`` into ``jac`` (both overwritten); 0, or 1 where the
    reference must answer (module docstring). Block ``b`` is of kind ``kind[b]`` with its amplitude at
    ``u[first[b]]`` and its shape parameters after it; ``fixed[b]`` its unit curve (kind :data:`FIXED`); ``p1``,
    ``p2``, ``q``, ``pow2``, ``neg_m12``: the Gauss-Markov series' powers of the cluster sizes ``mi``
    (:func:`avbench.noise_models.markov_terms._series_powers`); ``extra_j`` (-1: none) and ``extra_e``: a term
    e^{2 u_j} e(tau) added; ``fused``: NumPy's complex products fused (the resonance's closed form)."""
    nm = mi.shape[0]
    mf = np.empty(nm)
    for j in range(nm):
        mf[j] = float(mi[j])
    for j in range(nm):
        value[j] = 0.0
        for k in range(jac.shape[1]):
            jac[j, k] = 0.0
    unit = np.empty(nm)
    d1 = np.empty(nm)
    d2 = np.empty(nm)
    for b in range(kind.shape[0]):
        i = first[b]
        scale = math.exp(2.0 * u[i])
        kb = kind[b]
        if kb == FIXED:
            for j in range(nm):
                unit[j] = fixed[b, j]
        elif kb == GAUSS_MARKOV:
            a = dt / math.exp(u[i + 1])
            _gm_shape_kernel(mf, a, unit, d1)
            for j in range(nm):
                sc = 1.0 / (mf[j] * mf[j])
                d1[j] = sc * (-a) * d1[j]
                unit[j] = sc * unit[j]
        elif kb == FILTER:
            if not _filter_unit(mf, dt, math.exp(u[i + 1]), p1, p2, q, pow2, neg_m12, unit, d1):
                return 1
        elif kb == SINUSOID:
            f0 = math.exp(u[i + 1])
            if f0 > 0.5 / dt * (1 + 1e-12):
                return 1
            w = 2 * math.pi * f0 * dt
            sw = math.sin(w / 2)
            cw = math.cos(w / 2) / sw
            for j in range(nm):
                half = mf[j] * w / 2
                s = math.sin(half)
                den = mf[j] ** 2 * sw**2
                unit[j] = 1.0 * s**4 / den
                d1[j] = 1.0 * w * s**3 * (2 * mf[j] * math.cos(half) - s * cw) / den
        else:
            if not _resonance_unit(mi, dt, math.exp(u[i + 1]), math.exp(u[i + 2]), fused, unit, d1, d2):
                return 1
        for j in range(nm):
            value[j] += scale * unit[j]
        if kb != FIXED:
            for j in range(nm):
                jac[j, i + 1] = scale * d1[j]
        if kb == RESONANCE:
            for j in range(nm):
                jac[j, i + 2] = scale * d2[j]
        for j in range(nm):
            jac[j, i] = 2.0 * scale * unit[j]
    if extra_j >= 0:
        ex = math.exp(2.0 * u[extra_j])
        for j in range(nm):
            value[j] += ex * extra_e[j]
            jac[j, extra_j] += 2.0 * ex * extra_e[j]
    return 0


try:
    from numba import njit

    _filter_unit = njit(cache=True)(_filter_unit)
    _resonance_unit = njit(cache=True)(_resonance_unit)
    latent_av = njit(cache=True)(latent_av_py)
except ImportError:  # pragma: no cover
    latent_av = latent_av_py
