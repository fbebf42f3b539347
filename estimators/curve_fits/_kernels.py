"""Compiled passes of the least-squares AV-curve fits over their grid.

The five-term design has columns tau^p, p = -2 .. 2 (:mod:`avbench.estimators.allan.model`), so the
normal equations of a row-weighted fit need only the power sums

.. math:: s_q = \\sum_i w_i^2\\,\\tau_i^q\\ (q = -4 .. 4),\\qquad r_q = \\sum_i w_i^2\\,y_i\\,\\tau_i^q\\ (q = -2 .. 2),

:math:`(X^TW^2X)_{ab} = s_{p_a + p_b}`, :math:`(X^TW^2y)_a = r_{p_a}`: one pass over the grid, the
design (72 000 x 5 on ``taus="all"`` of 4 h at 10 Hz) never built. ``edf_weighted_sums`` is one
re-weighting step of ``wls_edf`` in the same pass: each row's level (the fitted AV, the empirical one
where it is not positive), the edf of the term dominating the fit there, its weight edf / (2 level^2)
and the power sums.

Sums are kept per block of :data:`BLOCK` rows and then added, so the rounding error of a sum grows
with ``BLOCK + n / BLOCK``, not with n. The powers are products of tau and 1/tau (within a few ulp
of ``tau ** p``). The plain NumPy versions below (``*_numpy``) are the references the tests compare
with.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["BLOCK", "power_sums", "edf_weighted_sums", "power_curve", "power_sums_numpy",
           "edf_weighted_sums_numpy", "power_curve_numpy"]

#: rows per block of the partial sums
BLOCK = 256


@njit(cache=True)
def _add_block(tau, y, w2, start, stop, w_offset, s, r):
    """Add rows start .. stop - 1 (weights ``w2[i - w_offset]``) to the power sums ``s``, ``r`` as one
    block: partial sums in registers, then added."""
    s0 = s1 = s2 = s3 = s4 = s5 = s6 = s7 = s8 = 0.0
    r0 = r1 = r2 = r3 = r4 = 0.0
    for i in range(start, stop):
        t = tau[i]
        inv = 1.0 / t
        a = w2[i - w_offset]
        t2 = t * t
        i2 = inv * inv
        c2 = a * i2
        c0 = c2 * i2
        s0 += c0
        s1 += c0 * t
        s2 += c2
        s3 += a * inv
        s4 += a
        s5 += a * t
        c6 = a * t2
        s6 += c6
        s7 += c6 * t
        s8 += c6 * t2
        b = a * y[i]
        r0 += b * i2
        r1 += b * inv
        r2 += b
        r3 += b * t
        r4 += b * t2
    s[0] += s0
    s[1] += s1
    s[2] += s2
    s[3] += s3
    s[4] += s4
    s[5] += s5
    s[6] += s6
    s[7] += s7
    s[8] += s8
    r[0] += r0
    r[1] += r1
    r[2] += r2
    r[3] += r3
    r[4] += r4


@njit(cache=True)
def power_sums(tau, y, w2):
    """``(s, r)``: s[q + 4] = sum_i w2_i tau_i^q (q = -4 .. 4), r[q + 2] = sum_i w2_i y_i tau_i^q
    (q = -2 .. 2)."""
    s = np.zeros(9)
    r = np.zeros(5)
    n = tau.size
    for start in range(0, n, BLOCK):
        _add_block(tau, y, w2, start, min(start + BLOCK, n), 0, s, r)
    return s, r


@njit(cache=True)
def edf_weighted_sums(tau, y, avar, powers, beta, edf_table, rule_of_column, level_out, edf_out):
    """One re-weighting pass of ``wls_edf``: per row, the contributions max(beta_j, 0) tau^p_j of
    the columns (``powers``: distinct, increasing, within -2 .. 2, as the five-term design's), the
    level (their sum where positive, else ``avar``), the dominant column (the first of the largest
    contributions), its edf ``edf_table[i, rule_of_column[j]]`` and the weight
    w^2 = (edf / 2) / level^2; writes level and edf and returns the power sums of
    :func:`power_sums` with these weights (block by block, while the block is in cache)."""
    # the five slots p = -2 .. 2: the column's max(beta, 0), or -1 for a power not in the design (its
    # contribution is then negative and never the largest, and 0 is added to the level instead)
    b = np.full(5, -1.0)
    rule = np.zeros(5, dtype=np.int64)
    for j in range(powers.size):
        b[powers[j] + 2] = beta[j] if beta[j] > 0.0 else 0.0
        rule[powers[j] + 2] = rule_of_column[j]
    b0, b1, b2, b3, b4 = b[0], b[1], b[2], b[3], b[4]
    m0, m1, m2, m3, m4 = max(b0, 0.0), max(b1, 0.0), max(b2, 0.0), max(b3, 0.0), max(b4, 0.0)
    s = np.zeros(9)
    r = np.zeros(5)
    w2 = np.empty(BLOCK)
    n = tau.size
    for start in range(0, n, BLOCK):
        stop = min(start + BLOCK, n)
        for i in range(start, stop):
            t = tau[i]
            inv = 1.0 / t
            t2 = t * t
            i2 = inv * inv
            # contributions in the order of the columns (increasing power): the first largest wins
            best = 0
            top = i2 * b0
            c = inv * b1
            if c > top:
                top = c
                best = 1
            if b2 > top:
                top = b2
                best = 2
            c = t * b3
            if c > top:
                top = c
                best = 3
            c = t2 * b4
            if c > top:
                best = 4
            model = (((i2 * m0 + inv * m1) + m2) + t * m3) + t2 * m4
            level = model if model > 0.0 else avar[i]
            e = edf_table[i, rule[best]]
            level_out[i] = level
            edf_out[i] = e
            w2[i - start] = (0.5 * e) / (level * level)
        _add_block(tau, y, w2, start, stop, start, s, r)
    return s, r


@njit(cache=True)
def power_curve(tau, powers, beta):
    """X beta: sum_j beta_j tau^p_j at every tau (the fitted curve, the design never built; the
    columns' ``powers`` distinct, within -2 .. 2), summed in increasing power."""
    b = np.zeros(5)
    for j in range(powers.size):
        b[powers[j] + 2] = beta[j]
    b0, b1, b2, b3, b4 = b[0], b[1], b[2], b[3], b[4]
    out = np.empty(tau.size)
    for i in range(tau.size):
        t = tau[i]
        inv = 1.0 / t
        out[i] = (((inv * inv * b0 + inv * b1) + b2) + t * b3) + t * t * b4
    return out


# -- plain NumPy references (the tests compare the kernels with them) ------------------------------

def power_sums_numpy(tau, y, w2):
    """:func:`power_sums` with NumPy (the design of all nine powers built)."""
    q = np.arange(-4, 5)
    V = np.asarray(tau, float)[:, None] ** q[None, :]
    return w2 @ V, (w2 * y) @ V[:, 2:7]


def power_curve_numpy(tau, powers, beta):
    return (np.asarray(tau, float)[:, None] ** np.asarray(powers)[None, :].astype(float)) @ beta


def edf_weighted_sums_numpy(tau, y, avar, powers, beta, edf_table, rule_of_column):
    """:func:`edf_weighted_sums` with NumPy: ``(s, r, level, edf)``."""
    X = np.asarray(tau, float)[:, None] ** np.asarray(powers)[None, :].astype(float)
    contrib = X * np.maximum(beta, 0)[None, :]
    model = contrib.sum(axis=1)
    level = np.where(model > 0, model, avar)
    col = contrib.argmax(axis=1)
    edf = edf_table[np.arange(len(tau)), np.asarray(rule_of_column)[col]]
    w2 = (0.5 * edf) / level**2
    s, r = power_sums_numpy(tau, y, w2)
    return s, r, level, edf
