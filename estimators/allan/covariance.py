"""The covariance of the overlapping Allan variance under a noise model (Gaussian, asymptotic): the
weight matrix of GMWM's second step (:mod:`avbench.estimators.likelihood.gmwm`) and the reference
distribution of the poor-fit check (:mod:`avbench.estimators.allan.fit_check`).

Isserlis' theorem turns the covariance of two AV estimates into an integral of the product of their
Haar filter gains against the squared spectrum (Percival 1995); the model's spectrum comes from its
noise terms (``gyro.psd``).

Cost. The squared spectrum of a sum of terms is a sum over pairs of terms, and each term's spectrum is
its amplitude times a fixed shape (:meth:`avbench.noise_models.terms.NoiseTerm.psd_factor`), so

.. math:: \\Omega = \\sum_{a \\le b} (2 - \\delta_{ab})\\, c_a c_b\\, P_{ab},\\qquad
    P_{ab} = \\frac1\\pi\\int_0^\\pi |H_j|^2|H_k|^2 S_a S_b\\,d\\omega

with the integrals :math:`P_{ab}` of unit-amplitude shapes computed once per (sample interval, cluster
sizes, grid, pair of shapes) and kept (:data:`CACHE_SIZE` entries, least recently used dropped): a fit
check of a five-term model or the second step of a fit whose term shapes do not depend on the fitted
values (white, quantization, flicker, random walk) costs a weighted sum of a few k x k matrices after
the first record of a study. A Gauss-Markov term's shape depends on its correlation time (a filter's on
its time constant, a resonance's on its frequency and damping), so its pairs would be integrated for
each new value: where two or more such pairs are not kept, the covariance is the direct midpoint sum of
the squared total spectrum (one product instead of one per pair; a GMWM fit check). The integrals are
the same midpoint sums either way: values agree with the direct sum to round-off (tests).

The Haar gains :math:`|H_m|^2` on the grid (sin^4 at k x n_grid points) are most of the cost of one
covariance, and GMWM asks for the covariance on the same grid some hundred times per record (each
candidate set of scales, each model its choices try): they are kept per grid (:data:`GAIN_CACHE_BYTES`:
a 2^21-point grid of 20 octaves, 320 MB; a 2-hour record at 400 Hz needs 19). A covariance asked again for the same
model, cluster sizes and record length is the kept result (:data:`RESULT_CACHE_SIZE`). Both return the
values computed afresh, bit for bit.
"""

from __future__ import annotations

from collections import OrderedDict

import numpy as np

from avbench.noise_models.term_base import FrequencyGrid

__all__ = ["av_covariance", "CACHE_SIZE"]

#: number of per-pair integral matrices kept between calls
CACHE_SIZE = 512
_PAIRS: OrderedDict = OrderedDict()
#: grid points per block of the integration (bounds the work arrays: k x CHUNK floats)
CHUNK = 1 << 17
#: bytes of Haar filter gains kept between calls (per cluster sizes and grid; :func:`_gains`): the gains
#: of the longest grid (2^21 points) for 20 octaves (records of up to 8.4e6 samples: 5.8 h at 400 Hz);
#: a longer record's gains come block by block on every call, as its memory matters more than their time
GAIN_CACHE_BYTES = 320 << 20
_GAINS: OrderedDict = OrderedDict()
#: number of covariances kept between calls (per model, cluster sizes, record length and grid)
RESULT_CACHE_SIZE = 64
_RESULTS: OrderedDict = OrderedDict()
#: number of grids (size, dt) whose frequencies are kept with the values the spectra compute from them
#: (:func:`_frequencies`; a 2^21-point grid holds ~130 MB of them)
GRIDS_KEPT = 2
_GRIDS: OrderedDict = OrderedDict()


def _haar_gain(m, w, s):
    """|H_m(w)|^2 of the overlapping-AV difference filter (d = mean of next m - mean of last m);
    ``s`` = sin(w/2)."""
    g = np.sin(0.5 * m * w)
    g *= g
    g *= g  # sin^4 by two in-place squarings (several times faster than ** 4)
    g *= 4.0 / (m * m)
    g /= s * s
    return g


def _factor(term):
    """``(c, unit, shared)``: the term's amplitude and unit shape (``psd_factor``), and whether the
    shape's integrals may be kept (equal unit shapes, by ``==`` on their parameters, have equal
    spectra). Only when the class that says how the spectrum scales is the class that defines the
    spectrum: a subclass that changes ``psd`` without ``psd_factor``, or a term with the default factor,
    is integrated on every call, as it is."""
    def owner(name):
        return next(k for k in type(term).__mro__ if name in k.__dict__)

    if owner("psd_factor") is not owner("psd"):
        return 1.0, term, False
    c, unit = term.psd_factor()
    return float(c), unit, True


def _gains(m, n_grid):
    """``[(w, G)]`` per block of the midpoint grid: the frequencies and the Haar gains |H_m(w)|^2 of
    every cluster size (k x block). The same values as computing them on each call (they are: the
    same elementwise arithmetic per row), kept per grid for the last cluster sizes asked
    (:data:`GAIN_CACHE_BYTES` in all, the least recently used dropped first): a request for a run of
    consecutive cluster sizes of the kept ones gets views of them. GMWM's second step on each candidate
    set of scales (the same grid, the shortest scale dropped each time) and the fit check integrate on
    the same grid, and the gains (sin^4 at k x n_grid points) are most of the cost of a direct sum.
    Gains larger than the whole budget are not kept and come one block at a time, so that the work
    arrays stay k x :data:`CHUNK`."""
    omega_all = (np.arange(n_grid) + 0.5) * (np.pi / n_grid)
    starts = range(0, n_grid, CHUNK)
    for key, (m_kept, blocks) in list(_GAINS.items()):
        if key[0] != n_grid or not m.size:
            continue
        i = int(np.searchsorted(m_kept, m[0])) if np.all(np.diff(m_kept) > 0) else -1
        if 0 <= i and i + m.size <= m_kept.size and np.array_equal(m_kept[i : i + m.size], m):
            try:
                _GAINS.move_to_end(key)
            except KeyError:  # dropped meanwhile by another thread: ``blocks`` holds them
                pass
            return [(omega_all[a : a + CHUNK], G[i : i + m.size]) for a, G in zip(starts, blocks)]

    def block(a):
        w = omega_all[a : a + CHUNK]
        return _haar_gain(m[:, None], w[None, :], np.sin(w / 2)[None, :])

    size = m.size * n_grid * 8
    if size > GAIN_CACHE_BYTES:  # too large to keep: one block at a time, none kept
        return ((omega_all[a : a + CHUNK], block(a)) for a in starts)
    # room first (the least recently used dropped), so that the budget bounds what is held at any time
    while _GAINS and sum(v[0].size * k[0] * 8 for k, v in list(_GAINS.items())) + size > GAIN_CACHE_BYTES:
        try:
            _GAINS.popitem(last=False)
        except KeyError:
            break
    blocks = [block(a) for a in starts]
    key = (n_grid, m.tobytes())
    _GAINS[key] = (m.copy(), blocks)
    _GAINS.move_to_end(key)
    return [(omega_all[a : a + CHUNK], G) for a, G in zip(starts, blocks)]


def _grid_size(m, grid_per_cycle, max_grid) -> int:
    return int(min(max(grid_per_cycle * m.max(), 4096), max_grid))


def _pair_integrals(shapes, pairs, m, dt, n_grid) -> dict:
    """``{(a, b): P_ab}`` for index pairs into ``shapes`` (unit-amplitude terms), one pass over the grid."""
    out = {p: np.zeros((m.size, m.size)) for p in pairs}
    used = sorted({i for p in pairs for i in p})
    keep = m.size * n_grid * 8 <= GAIN_CACHE_BYTES
    for w, G in _gains(m, n_grid):
        f = _frequencies(w, dt, n_grid, keep)
        S = {i: shapes[i].psd(f, dt) / (2 * dt) for i in used}
        for i, j in pairs:
            out[(i, j)] += (G * (S[i] * S[j])) @ G.T
    for v in out.values():
        v *= 1.0 / n_grid  # (1/pi) * integral = mean over the grid
    return out


def av_covariance(gyro, m, n_samples, grid_per_cycle: int = 8, max_grid: int = 1 << 21, *,
                  reuse: bool = True) -> np.ndarray:
    """Asymptotic covariance of the overlapping AV at cluster sizes ``m`` under ``gyro`` (Gaussian).

    .. math::

        \\Omega_{jk} = \\frac{1}{2\\sqrt{M_jM_k}}\\frac1\\pi\\int_0^\\pi
            |H_j|^2|H_k|^2 S^2\\,d\\omega,\\quad S = \\mathrm{psd}(f)/(2\\Delta t),\\ \\omega = 2\\pi f\\Delta t,
            \\ M_j = n - 2m_j + 1

    by the midpoint rule on ``min(max(grid_per_cycle * max(m), 4096), max_grid)`` points (the filters
    oscillate with period 2 pi / m), as a weighted sum of per-pair integrals of the terms' spectral
    shapes kept between calls (module docstring). Deterministic terms (ramp) have zero PSD and add
    nothing. For white noise the diagonal agrees with the NIST SP 1065 edf, Var = 2 AV^2 / edf
    (checked in the tests).

    ``reuse=False``: one midpoint sum of the squared total spectrum, nothing kept but the Haar gains
    (the same values to round-off). GMWM's second step asks for it: its model has a Gauss-Markov term
    whose shape changes with every fit, so the pairs with it would be integrated anew each time (one
    product per pair instead of one for the sum). ``reuse=True`` takes that sum too where two or more
    pairs with a fitted shape are not kept (module docstring).
    """
    m = np.asarray(m, dtype=float)
    n_grid = _grid_size(m, grid_per_cycle, max_grid)
    key = _result_key(gyro, m, n_samples, n_grid, reuse)
    kept = _RESULTS.get(key) if key is not None else None
    if kept is not None:
        try:
            _RESULTS.move_to_end(key)
        except KeyError:  # dropped meanwhile by another thread: ``kept`` holds it
            pass
        return kept.copy()
    out = _covariance(gyro, m, n_samples, n_grid, reuse)
    if key is not None:
        _RESULTS[key] = out.copy()
        while len(_RESULTS) > RESULT_CACHE_SIZE:
            try:
                _RESULTS.popitem(last=False)
            except KeyError:
                break
    return out


def _result_key(gyro, m, n_samples, n_grid, reuse):
    """The key of a covariance among those kept: the model's terms (each its class and the values of its
    parameters, as the terms compare), dt, the cluster sizes, the record length, the grid and the path;
    None for a term with a parameter that cannot be hashed (an array): such a covariance is computed on
    every call."""
    try:
        terms = tuple((type(t), tuple(t._params().items())) for t in gyro.terms)
        hash(terms)
    except TypeError:
        return None
    return (terms, float(gyro.dt), m.tobytes(), int(n_samples), n_grid, bool(reuse))


def _covariance(gyro, m, n_samples, n_grid, reuse) -> np.ndarray:
    """:func:`av_covariance` computed (nothing kept but the gains and, with ``reuse``, the pairs)."""
    M = n_samples - 2 * m + 1
    if not reuse:
        return (_direct(gyro, m, n_grid) + _line_cross(gyro, m)) / (2.0 * np.sqrt(np.outer(M, M)))
    dt = float(gyro.dt)
    parts = [f for f in map(_factor, gyro.terms) if f[0] != 0.0]
    out = np.zeros((m.size, m.size))
    if parts:
        shapes = [u for _, u, _ in parts]
        grid_key = (dt, m.tobytes(), n_grid)
        keys, found, missing = {}, {}, []
        for i in range(len(shapes)):
            for j in range(i, len(shapes)):
                key = (grid_key, shapes[i], shapes[j])
                keys[(i, j)] = key
                P = _PAIRS.get(key)
                if P is None:
                    missing.append((i, j))
                else:
                    found[(i, j)] = P
                    try:
                        _PAIRS.move_to_end(key)
                    except KeyError:  # dropped meanwhile by another thread: found[] holds it
                        pass
        fitted = [bool(u.shape_parameters()) for u in shapes]
        if sum(fitted[i] or fitted[j] for i, j in missing) >= 2:
            # two or more pairs with a shape the fit chose (a correlation time, a filter's, a frequency): such
            # pairs are seldom asked again, and one product per pair costs more than the direct sum's one
            return (_direct(gyro, m, n_grid) + _line_cross(gyro, m)) / (2.0 * np.sqrt(np.outer(M, M)))
        found.update(_pair_integrals(shapes, missing, m, dt, n_grid) if missing else {})
        new = {p: found[p] for p in missing}
        for (i, j) in keys:
            out += ((1.0 if i == j else 2.0) * parts[i][0] * parts[j][0]) * found[(i, j)]
        for p, P in new.items():
            if parts[p[0]][2] and parts[p[1]][2]:
                _PAIRS[keys[p]] = P
        while len(_PAIRS) > CACHE_SIZE:
            try:
                _PAIRS.popitem(last=False)
            except KeyError:
                break
    out += _line_cross(gyro, m)
    return out / (2.0 * np.sqrt(np.outer(M, M)))


def _line_cross(gyro, m) -> np.ndarray:
    r"""The spectral lines' share of the integral: :math:`2 P\,|H_j(\omega_0)|^2|H_k(\omega_0)|^2 S(\omega_0)`
    per line (power P at omega_0, ``term.spectral_lines``), S the continuous spectrum there.

    A line (a sinusoid of random phase, :class:`avbench.noise_models.Sinusoidal`) is the spectral
    density :math:`\pi P\,\delta(\omega - \omega_0)` in the convention of :func:`av_covariance`.
    Isserlis' integrand :math:`S^2 = S_c^2 + 2 S_c S_l + S_l^2` then has the cross term above, which
    is exactly the variance of the AV's line-times-noise products (the cluster-mean differences of the
    sinusoid and of the noise: :math:`\mathrm{Var}\,\frac1M\sum d_s d_n = \frac{1}{M} P |H|^4 S_c(\omega_0)`
    on the diagonal). :math:`S_l^2` (a Gaussian line's random amplitude) does not apply: a sinusoid of
    fixed amplitude adds only O(1/M^2) to the variance, and nothing is added for it. Without this term
    the covariance of a model with a sinusoid is too small wherever the sinusoid shapes the curve, and a
    correct fit is flagged (tests/test_gmwm_real_terms.py).
    """
    out = np.zeros((m.size, m.size))
    dt = float(gyro.dt)
    for term in gyro.terms:
        for f0, power in term.spectral_lines(dt):
            w0 = 2 * np.pi * f0 * dt
            s_c = float(gyro.psd(np.array([f0]))[0]) / (2 * dt)
            h = _haar_gain(m, w0, np.sin(w0 / 2))
            out += 2.0 * power * s_c * np.outer(h, h)
    return out


def _frequencies(w, dt, n_grid, keep):
    """The frequencies ``w / (2 pi dt)`` of a block of the grid; with ``keep``, as the block's
    :class:`~avbench.noise_models.term_base.FrequencyGrid` kept between calls (:data:`GRIDS_KEPT` grids), on
    which the terms' spectra keep what they compute from the frequencies alone (their sines, cosines and
    complex exponentials: a model's total spectrum on a kept grid costs its arithmetic only). The same
    values either way."""
    f = w / (2 * np.pi * dt)
    if not keep:
        return f
    key = (n_grid, float(dt))
    blocks = _GRIDS.get(key)
    if blocks is None:
        blocks = _GRIDS[key] = {}
        while len(_GRIDS) > GRIDS_KEPT:
            try:
                _GRIDS.popitem(last=False)
            except KeyError:
                break
    else:
        try:
            _GRIDS.move_to_end(key)
        except KeyError:  # dropped meanwhile by another thread: ``blocks`` holds it
            pass
    block = (float(w[0]), w.size)
    grid = blocks.get(block)
    if grid is None:
        grid = blocks[block] = FrequencyGrid(f)
    return grid


def _direct(gyro, m, n_grid) -> np.ndarray:
    """(1/pi) * integral of |H_j|^2 |H_k|^2 S^2 by one midpoint sum of the total spectrum, in blocks
    (as Y Y^T with Y = |H|^2 S: a symmetric rank-k product). The spectrum on the grid's kept frequencies
    (:func:`_frequencies`) where its Haar gains are kept (:data:`GAIN_CACHE_BYTES`)."""
    out = np.zeros((m.size, m.size))
    keep = m.size * n_grid * 8 <= GAIN_CACHE_BYTES
    for w, G in _gains(m, n_grid):
        S = gyro.psd(_frequencies(w, gyro.dt, n_grid, keep)) / (2 * gyro.dt)
        Y = G * S
        out += Y @ Y.T
    out *= 1.0 / n_grid  # (1/pi) * integral = mean over the grid
    return out
