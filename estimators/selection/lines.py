r"""The strongest spectral line of a record and the evidence for it (a test for a hidden periodicity), and the
choice a latent model makes on it: a sinusoid ``SN`` added where the line is significant (GMWM's
``lines="auto"``, :func:`choose_line`), held near the line's frequency (:func:`sinusoid_hint`).

A sinusoid of random phase (:class:`avbench.noise_models.Sinusoidal`, IEEE Std 952-1997 Annex C)
adds a line to the spectrum; broadband noise does not. The test is Fisher's (1929) test for a
hidden periodicity, in the form that allows a coloured background: the periodogram ordinate of a
Gaussian process at a frequency without a line is :math:`S(f)\,E`, E standard exponential
(Brockwell & Davis 1991, Thm 10.3.2; also with a taper), so its ratio to the median of its
neighbours (:math:`\ln 2\, S(f)`, the exponential's median being ln 2) exceeds r with probability
:math:`2^{-r}`. The largest of K such ratios has

.. math:: p = 1 - (1 - 2^{-r})^K ,

taken here with K = every frequency searched (the Hann window correlates neighbouring ordinates, so
the effective number is smaller and p is conservative).

Choices (not from a paper): periodogram of the whole record with a Hann window after removing the
mean. A real line is not one bin wide (a sensor's line wanders in frequency over a long record), so
the background of bin k is taken beside it, not on it: the periodogram is cut into blocks
of b bins, and the background is the median of the bins of the blocks 2 to
:data:`FAR_BLOCKS` away on each side (N = 2 (FAR_BLOCKS - 1) b bins). A block spans a fixed band of
frequencies, :data:`BLOCK_HZ` (a line wanders in hertz, not in bins): b = floor(BLOCK_HZ T) bins of a
record of T seconds, at most :data:`BLOCK` and at least :data:`MIN_BLOCK` (b = 32 on a 10,000 s record
and longer ones, 5 on 30 minutes, 2 on 10 minutes). Its sampling error enters the
p-value: the median of N' independent exponentials (N' = N / 2 for the Hann window's correlated
neighbours): the ratio of an exponential E to the median M of N' others, scaled by ln 2 as above, exceeds
r with probability :math:`E[e^{-r' M}] = \prod_i j_i / (j_i + r')` over the order statistics that make
the median (M is a sum of independent exponentials over N', N' - 1, ..., r' = r M_0, M_0 = the median's
mean, ~ln 2); p is K times that (Bonferroni), capped at 1. The frequencies searched start where the background's span is at most a
fifth of the frequency (f >= 10 FAR_BLOCKS b df, df = 1/T: 0.256 Hz on records of 10,000 s, 0.22 Hz on
30 minutes, 0.27 Hz on 10 minutes, where a record of 10 minutes to hours sees the same lines) and stop
FAR_BLOCKS blocks below the Nyquist frequency. The line's variance is the
periodogram's excess over the background summed over the bins within max(0.02 Hz, 3 df) of the peak,
its amplitude :math:`A = \sqrt{2\,\mathrm{variance}}`.
"""

from __future__ import annotations

import functools
import math
from typing import NamedTuple

import numpy as np

from avbench.estimators.selection._kept import per_record
from avbench.noise_models.latents import parse_model
from avbench.noise_models.term_base import FitHint

__all__ = ["SpectralLine", "strongest_line", "line_evidence", "BLOCK", "BLOCK_HZ", "MIN_BLOCK", "block_bins",
           "FAR_BLOCKS", "LINE_TEST_LEVEL",
           "LINE_FREQUENCY_FACTOR", "LineChoice", "choose_line", "sinusoid_hint", "frequency_at_bound"]

#: the most bins in a block of the background (module docstring)
BLOCK = 32
#: the band a block of the background spans (Hz): 32 bins of a 10,000 s record; on a shorter record a
#: block holds fewer bins, and the search starts at the same frequency
BLOCK_HZ = 0.0032
#: the fewest bins in a block of the background (the p-value counts the background's bins)
MIN_BLOCK = 2
#: the background of a bin: the blocks 2 .. FAR_BLOCKS away on each side
FAR_BLOCKS = 8

#: level of the line test at which a model adds a sinusoid (GMWM's and nnls_rel's ``lines="auto"``)
LINE_TEST_LEVEL = 0.001

#: a sinusoid started at a significant spectral line keeps its frequency within this factor of the line's
#: (GMWM's bounds, :func:`sinusoid_hint`; nnls_rel's profile of the frequency): the periodogram places the
#: line to a few 1/T, the AV curve hardly at all, and a free frequency wanders off the line to shape
#: another part of the curve
LINE_FREQUENCY_FACTOR = 1.05


class SpectralLine(NamedTuple):
    """``f0`` (Hz), ``amplitude`` (the record's unit), ``prominence`` (peak over the background),
    ``p_value`` (the test above), ``n_searched`` (K), ``band`` (Hz searched)."""

    f0: float
    amplitude: float
    prominence: float
    p_value: float
    n_searched: int
    band: tuple[float, float]


def block_bins(n, dt) -> int:
    """The bins of a block of the background on a record of ``n`` samples every ``dt`` s (module docstring):
    floor(:data:`BLOCK_HZ` n dt) within [:data:`MIN_BLOCK`, :data:`BLOCK`].

    >>> block_bins(1_000_000, 0.01), block_bins(180_000, 0.01), block_bins(60_000, 0.01)
    (32, 5, 2)
    """
    return int(min(BLOCK, max(MIN_BLOCK, math.floor(BLOCK_HZ * n * dt + 1e-9))))


@functools.lru_cache(maxsize=2)
def _hann(n):
    """``np.hanning(n)``, kept for the axes of one record (read-only)."""
    w = np.hanning(n)
    w.flags.writeable = False
    return w


@per_record  # each method fitted to an axis asks for the same record's line
def strongest_line(x, dt, band=None, *, floor=True) -> SpectralLine | None:
    """The strongest line of record ``x`` (sample interval ``dt``) in ``band`` (Hz; default: every
    frequency the test can search, module docstring), or None when no frequency can be searched
    (a record too short for the band). ``floor=False`` searches the whole ``band`` even below the
    frequency where the background's span is a fifth of the frequency (a table of a fixed band on
    short records; the p-value is then less safe on a steep spectrum)."""
    x = np.asarray(x, dtype=float)
    if x.ndim != 1:
        return None
    block = block_bins(x.size, dt)
    span = FAR_BLOCKS * block
    if x.size < 8 * span:
        return None
    x = x - x.mean()
    w = _hann(x.size)
    P = np.abs(np.fft.rfft(x * w)) ** 2
    f = np.fft.rfftfreq(x.size, dt)
    df = 1.0 / (x.size * dt)
    lo, hi = (10 * span * df if floor else df), f[-1 - span]
    if band is not None:
        lo, hi = max(lo, float(band[0])), min(hi, float(band[1]))
    idx = np.flatnonzero((f >= lo) & (f <= hi))
    if idx.size == 0:
        return None
    n_blocks = P.size // block
    blocks = P[: n_blocks * block].reshape(n_blocks, block)
    bl = np.minimum(idx // block, n_blocks - 1)
    offsets = np.r_[-FAR_BLOCKS:-1, 2:FAR_BLOCKS + 1]
    # the median over the neighbouring blocks' bins, for the block of each searched bin (one per block; the
    # searched bins ascend, so their blocks do)
    first = np.r_[True, bl[1:] != bl[:-1]]
    ub, inv = bl[first], np.cumsum(first) - 1
    nb = np.clip(ub[:, None] + offsets[None, :], 0, n_blocks - 1)
    bg_block = np.median(blocks[nb].reshape(ub.size, -1), axis=1)
    bg = bg_block[inv]
    ratio = P[idx] / np.where(bg > 0, bg, np.inf)
    j = int(np.argmax(ratio))
    k, r = int(idx[j]), float(ratio[j])
    line = np.abs(f - f[k]) < max(0.02, 3 * df)
    var = max(0.0, float((P[line] - bg[j]).sum())) * 2.0 / (x.size * float(np.sum(w * w)))
    n_eff = offsets.size * block // 2
    j_up = np.arange(n_eff - (n_eff + 1) // 2 + 1, n_eff + 1, dtype=float)
    log_single = float(np.sum(np.log(j_up / (j_up + r * math.log(2.0) * n_eff / (n_eff + 0.5)))))
    p = min(1.0, idx.size * math.exp(log_single))
    return SpectralLine(float(f[k]), math.sqrt(2.0 * var), r, float(p), int(idx.size), (float(lo), float(hi)))


def line_evidence(x, dt, tau, level=LINE_TEST_LEVEL) -> dict | None:
    """The evidence for a sinusoid in a model of record ``x`` fitted at the taus ``tau`` (s): the strongest
    line (:func:`strongest_line`) in the band those taus see (an AV peak 0.371 / f0 within them, up to the
    Nyquist frequency), as a dict with ``f0``, ``amplitude``, ``prominence``, ``p_value``, ``n_searched``,
    ``band``, ``significant`` (p below ``level``) and ``level``; None when no frequency can be searched.
    The one rule by which GMWM's and nnls_rel's ``lines="auto"`` add a sinusoid."""
    tau = np.asarray(tau, dtype=float)
    found = strongest_line(x, dt, (0.371 / tau[-1], 0.5 / dt)) if tau.size else None
    if found is None:
        return None
    return {"f0": found.f0, "amplitude": found.amplitude, "prominence": found.prominence,
            "p_value": found.p_value, "n_searched": found.n_searched, "band": found.band,
            "significant": bool(found.p_value < level), "level": level}


class LineChoice(NamedTuple):
    """What :func:`choose_line` chose: ``latents`` (the model, with ``SN`` where it was added), ``line`` (the
    line test's dict, :func:`line_evidence`, with ``included``: SN in the model; None where no frequency can
    be searched; it is the model choice ``line_test``) and ``reason`` (a sentence)."""

    latents: tuple[str, ...]
    line: dict | None
    reason: str


def choose_line(latents, x, dt, tau, auto: bool) -> LineChoice:
    """The record's strongest spectral line in the band the taus ``tau`` see (:func:`line_evidence` at level
    :data:`LINE_TEST_LEVEL`), and the model: with ``auto`` (GMWM's ``lines="auto"``) a significant line adds
    a sinusoid ``SN`` to ``latents``; else the latents stay as given.

    >>> import numpy as np
    >>> t = np.arange(2**16) * 0.01
    >>> x = np.random.default_rng(1).standard_normal(t.size) + 0.3 * np.sin(2 * np.pi * 7.7 * t)
    >>> c = choose_line(("WN",), x, 0.01, 0.01 * 2.0 ** np.arange(10), auto=True)
    >>> c.latents, round(c.line["f0"], 2), c.line["significant"]
    (('WN', 'SN'), 7.7, True)
    """
    line = line_evidence(x, dt, tau, LINE_TEST_LEVEL)
    if line is None:
        return LineChoice(latents, None, "no frequency can be searched (record too short for the band)")
    if line["significant"] and auto and "SN" not in latents:
        latents = parse_model(latents + ("SN",))
        reason = "a significant line: SN added"
    elif line["significant"]:
        reason = "a significant line" + ("; SN in the model" if "SN" in latents else "; lines='model': SN not added")
    else:
        reason = "no significant line"
    line["included"] = "SN" in latents
    return LineChoice(latents, line, reason)


def sinusoid_hint(line) -> FitHint | None:
    """Where a fitted sinusoid starts and stays (:meth:`avbench.noise_models.Sinusoidal.fit_starts`,
    ``fit_shape_bounds``): at the line's amplitude and frequency, its frequency within
    :data:`LINE_FREQUENCY_FACTOR` of the line's, for a significant ``line`` (:func:`line_evidence`); None
    otherwise (the sinusoid is then started at the bumps of the AV curve)."""
    if line is None or not line["significant"]:
        return None
    return FitHint(window=(line["f0"] / LINE_FREQUENCY_FACTOR, line["f0"] * LINE_FREQUENCY_FACTOR),
                   starts=((line["amplitude"], line["f0"]),))


def frequency_at_bound(f0, line) -> bool:
    """Whether a fitted sinusoid's frequency ``f0`` lies on the edge of its window around the significant
    ``line`` (:data:`LINE_FREQUENCY_FACTOR`): the bump's shape is then not one pure tone at the line."""
    return bool(abs(math.log(f0 / line["f0"])) >= math.log(LINE_FREQUENCY_FACTOR) * (1 - 1e-6))
