"""The test for a resonance in a record, and the choice a latent model makes on it (GMWM's
``resonance="auto"``).

A resonance (:class:`avbench.noise_models.Resonance`, ``RS``: a lightly damped mode's band-pass noise)
shapes the AV's first octaves, which a model without it can only drop (:mod:`.scales`). The test
(:func:`find_band`, a choice, not from a paper) looks for the band of the record's Welch spectrum
that stands highest above its running median; the choice (:func:`choose_resonance`) adds ``RS`` where
the model without it drops scales, such a band stands out (prominence at least
:data:`RESONANCE_MIN_PROMINENCE`, significant at :data:`RESONANCE_TEST_LEVEL`), and the model with it
keeps a shorter cut-off that (a) Hansen's J does not reject at
:data:`~avbench.estimators.selection.scales.SCALE_TEST_LEVEL` keeping the longer half of the scales
(``min_m="adequate"``'s rule), (b) sees the band (shortest tau at most :data:`RESONANCE_SEEN` / f0),
(c) is a resonance (quality factor at least :data:`RESONANCE_MIN_Q`), (d) leaves the white noise resolved (N at
least :data:`RESONANCE_WHITE_Z` standard errors above zero) and (e) passes the poor-fit check. The
centre frequency stays within :data:`RESONANCE_FREQUENCY_FACTOR` of the band found (:func:`resonance_hint`), and
the damping time within the narrowest band the spectrum resolves (:func:`resonance_box`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from avbench.noise_models.latents import parse_model
from avbench.noise_models.sensor_terms import RESONANCE_MAX_FREQUENCY
from avbench.noise_models.term_base import FitHint

__all__ = ["RESONANCE_MAX_FREQUENCY", "RESONANCE_SEEN", "RESONANCE_FREQUENCY_FACTOR", "RESONANCE_MIN_PROMINENCE",
           "RESONANCE_MIN_Q", "RESONANCE_WHITE_Z", "RESONANCE_TEST_LEVEL", "ResonanceBand", "ResonanceChoice", "find_band", "band_seen",
           "resonance_hint", "resonance_box", "white_resolved", "choose_resonance"]

#: a resonance is kept only where the shortest tau fitted is at most this over its centre frequency (twice its
#: AV's peak tau, 0.371 / f0): beyond, only its 1/tau^2 tail is fitted, a shape with no resonance in it
RESONANCE_SEEN = 0.75

#: a resonance's centre frequency stays within this factor of the band found in the spectrum (and the band
#: search keeps this factor away from a line the model holds): wide enough for the band's skew between its
#: peak bin and the fitted f0, narrow enough that the term cannot wander off to shape another part of the curve
RESONANCE_FREQUENCY_FACTOR = 1.5

#: a fitted resonance is kept only with at least this quality factor pi f0 tc (the lower end of the term's own
#: range, :meth:`avbench.noise_models.Resonance.fit_shape_bounds`, whose box is set by the band's upper frequency):
#: broader, it is a low-pass shape that trades with the white noise (an accelerometer's N interval reaching 0)
RESONANCE_MIN_Q = 1.0

#: a fitted resonance is kept only where the white noise stays resolved: N at least this many of its standard errors
#: above zero (its 95 % interval clear of zero). A resonance that trades with the white noise -- broad, or a low-pass
#: shape with the filter term -- leaves N's interval reaching zero, the coefficient the shorter scales are kept for
RESONANCE_WHITE_Z = 1.959963984540054

#: a band is a resonance candidate only if its spectrum stands this many times above its surroundings
#: (a lightly damped mode, not the slope of a filter)
RESONANCE_MIN_PROMINENCE = 2.0
#: and only if that prominence is significant at this level (:func:`find_band`)
RESONANCE_TEST_LEVEL = 0.001


class ResonanceBand(NamedTuple):
    """The band of a record's spectrum that stands highest above its surroundings (:func:`find_band`):
    ``f0`` (Hz), ``half_width`` (Hz, at half the excess power), ``prominence`` (Welch spectrum over its
    running median at f0), ``p_value`` (that ratio under a smooth spectrum), ``starts`` ((sigma, f0, tc)
    starting values of ``RS``), ``max_tc`` (s: the damping time of the narrowest band the spectrum resolves,
    :func:`resonance_box`)."""

    f0: float
    half_width: float
    prominence: float
    p_value: float
    starts: list
    max_tc: float = math.inf


def find_band(rate, dt, band, exclude=None) -> ResonanceBand | None:
    """The band of the record's spectrum that stands highest above its surroundings, and starting values
    of a resonance ``RS`` there (a choice, not from a paper). Welch periodogram (Hann, 50 % overlap,
    segments of up to 2048 samples), over its running median across a sixth of the frequencies (the
    surroundings; not within half of it of 0 or Nyquist, where the median is one-sided and a steep
    spectrum's slope would read as a band: at 100 Hz the search starts at 4.2 Hz); in ``band`` (Hz),
    outside ``exclude`` ((lo, hi) Hz or None), the frequency where the ratio is largest is f0. Evidence: a Welch
    ordinate of a smooth spectrum is S chi^2_nu / nu with nu ~ 1.9 x the number of segments for this window
    and overlap; nu is taken as the number of segments (conservative), so the ratio r exceeds its value
    with probability chi2.sf(r nu, nu), times the number of frequencies searched (Bonferroni). Starts:
    the excess power over the surroundings within the half-power points gives sigma^2 (times 2: a
    Lorentzian holds half its power within them), the half width at half power w (at least half a bin,
    df / 2) gives tc = 1 / (2 pi w); then the same f0 with a ten times longer and a ten times shorter tc. The
    fit decides, with tc at most 1 / (pi df), the band of half a bin (``max_tc``). None where no frequency of
    ``band`` can be searched."""
    from scipy.ndimage import median_filter
    from scipy.signal import welch
    from scipy.special import chdtrc  # scipy.stats.chi2.sf(x, nu) is chdtrc(nu, x), without importing scipy.stats

    x = np.asarray(rate, dtype=float)
    nper = int(min(2048, 2 ** math.floor(math.log2(max(x.size // 16, 16)))))
    f, p = welch(x - x.mean(), fs=1.0 / dt, nperseg=nper)
    size = max(3, (f.size // 6) | 1)
    base = median_filter(p, size=size, mode="nearest")
    ok = (f >= band[0]) & (f <= band[1]) & (base > 0)
    ok[: size // 2] = ok[f.size - size // 2:] = False  # the surroundings one-sided: a slope reads as a band
    if exclude is not None:
        ok &= (f < exclude[0]) | (f > exclude[1])
    if not ok.any():
        return None
    ratio = np.where(ok, p / np.where(base > 0, base, np.inf), 0.0)
    k = int(np.argmax(ratio))
    n_seg = max(1, (x.size - nper) // (nper // 2) + 1)
    p_value = min(1.0, int(ok.sum()) * float(chdtrc(n_seg, ratio[k] * n_seg)))
    excess = np.clip(p - base, 0.0, None)
    half = excess >= excess[k] / 2
    a = k
    while a > 0 and half[a - 1]:
        a -= 1
    b = k
    while b < f.size - 1 and half[b + 1]:
        b += 1
    df = f[1] - f[0]
    w = max((b - a + 1) * df / 2, df / 2)
    sigma = math.sqrt(max(2.0 * float(excess[a:b + 1].sum()) * df, 1e-300))
    tc = 1.0 / (2 * math.pi * w)
    starts = [(sigma, float(f[k]), tc), (sigma, float(f[k]), 10 * tc), (sigma, float(f[k]), tc / 10)]
    return ResonanceBand(float(f[k]), float(w), float(ratio[k]), p_value, starts, 1.0 / (math.pi * df))


def band_seen(rate, dt, tau, line=None) -> ResonanceBand | None:
    """The record's most prominent spectral band seen by the taus ``tau`` (:func:`find_band` in
    0.371 / tau_max to :data:`RESONANCE_MAX_FREQUENCY` / dt), away from a line the model already holds
    (``line``, :func:`avbench.estimators.selection.lines.choose_line`'s, included and significant: its
    frequency +- :data:`RESONANCE_FREQUENCY_FACTOR`)."""
    if not tau.size:
        return None
    exclude = None
    if line is not None and line.get("included") and line.get("significant"):
        exclude = (line["f0"] / RESONANCE_FREQUENCY_FACTOR, line["f0"] * RESONANCE_FREQUENCY_FACTOR)
    return find_band(rate, dt, (0.371 / tau[-1], RESONANCE_MAX_FREQUENCY / dt), exclude)


def resonance_hint(band: ResonanceBand | None) -> FitHint | None:
    """Where a fitted resonance starts and stays (:meth:`avbench.noise_models.Resonance.fit_starts`,
    ``fit_shape_bounds``): at the band's starts, its centre frequency within
    :data:`RESONANCE_FREQUENCY_FACTOR` of the band's; None without a band."""
    if band is None:
        return None
    return FitHint(window=(band.f0 / RESONANCE_FREQUENCY_FACTOR, band.f0 * RESONANCE_FREQUENCY_FACTOR),
                   starts=band.starts)


def resonance_box(latents, lo, hi, band: ResonanceBand | None):
    """``(lo, hi)``, the log-parameter box of the model ``latents``, with a resonance ``RS``'s damping time at
    most ``band.max_tc``: the band of half a bin of the record's Welch spectrum (:func:`find_band`). A narrower
    band is not a band the spectrum shows but a line (a sinusoid ``SN``, :mod:`.lines`), and toward it the
    criterion is flat: a solve crawls along that ridge for thousands of evaluations and stops where the last
    bits of the record decide (the same record in two units ended at 10 s and at the record's length), and
    the second step's weights, and so its optimum, follow from where it stopped. Unchanged without ``RS`` or
    a band.

    >>> band = find_band(np.random.default_rng(0).standard_normal(2**16), 0.01, (1.0, 40.0))
    >>> lo, hi = resonance_box(("WN", "RS"), np.zeros(4), np.full(4, 9.0), band)
    >>> round(float(np.exp(hi[3])), 2)  # segments of 2048 samples of 0.01 s: 1 / (pi * 0.0488 Hz)
    6.52
    """
    from avbench.noise_models.latents import LATENT_TERMS, param_index

    if band is None or "RS" not in latents:
        return lo, hi
    i = param_index(latents, "RS") + LATENT_TERMS["RS"].fit_parameters.index("tc")
    hi = np.array(hi, dtype=float)
    hi[i] = max(min(hi[i], math.log(band.max_tc)), lo[i])
    return lo, hi


def white_resolved(fit) -> bool:
    """Whether a fit (``coefs``, ``diag["std_err"]``) resolves its white noise N: at least
    :data:`RESONANCE_WHITE_Z` standard errors above zero (True for a model without N).

    >>> import pandas as pd
    >>> white_resolved({"coefs": {"N": 3e-3}, "diag": {"std_err": pd.Series({"N": 1e-4})}})
    True
    >>> white_resolved({"coefs": {"N": 3e-3}, "diag": {"std_err": pd.Series({"N": 11.3})}})
    False
    """
    n = fit["coefs"].get("N")
    if n is None:
        return True
    se = fit["diag"]["std_err"].get("N")
    return bool(se is not None and math.isfinite(se) and n > RESONANCE_WHITE_Z * se)


class ResonanceChoice(NamedTuple):
    """What :func:`choose_resonance` chose: ``fit`` (the model's fit, with or without ``RS``), ``tried`` (the
    cut-offs fitted: the model's, then those with RS), ``latents`` (with ``RS`` where it was added) and
    ``report`` (the model choice ``resonance_test``: the band, each cut-off tried with its fit-check p-value,
    whether RS was included and why, its ``sigma, f0, tc``, the two fits' J on the same scales)."""

    fit: dict
    tried: list
    latents: tuple[str, ...]
    report: dict


def choose_resonance(latents, best, tried, m, usable, band: Callable[[], ResonanceBand | None],
                     refit: Callable, check: Callable[[dict, tuple], dict] | None = None) -> ResonanceChoice:
    """A resonance ``RS`` added to the model ``latents`` on the record's evidence (module docstring).

    ``best``, ``tried``: the fit without RS and the cut-offs it tried (:func:`.scales.choose_scales`);
    ``m``, ``usable``: the octave cluster sizes and the mask of those usable; ``band()``: the record's band
    (:func:`band_seen`; called only when needed); ``refit(latents, band, below, accept, max_tau, seed)``:
    the fit of ``latents`` at the shortest cut-off below ``below`` that is adequate and accepted, started at
    ``seed`` (the other latents' fitted values) and the band's starts, as a :class:`.scales.ScaleChoice`;
    ``check(fit, latents)``: the poor-fit check's entries of a fit (None: no check). The two fits' J on the
    same scales are compared by the D (distance-metric) statistic, chi^2(3) where RS's sigma is not on its
    boundary: indicative only (f0 and tc are undefined without the term)."""
    from scipy.special import chdtrc  # scipy.stats.chi2.sf(x, nu) is chdtrc(nu, x), without importing scipy.stats

    from avbench.estimators.selection.scales import SCALE_TEST_LEVEL

    m0 = int(best["diag"]["m"][0])
    usable_m = m[usable]
    report = {"included": False, "min_m_without": m0, "J_without": float(best["J_stat"])}
    if not usable_m.size or m0 <= int(usable_m.min()):
        report["reason"] = "the model without a resonance keeps every scale"
        return ResonanceChoice(best, tried, latents, report)
    rs_latents = parse_model(latents + ("RS",))
    found = band()
    if found is None:
        report["reason"] = "no frequency to search"
        return ResonanceChoice(best, tried, latents, report)
    report.update({"band_f0": found.f0, "band_half_width": found.half_width,
                   "prominence": found.prominence, "band_p_value": found.p_value})
    if not (found.prominence >= RESONANCE_MIN_PROMINENCE and found.p_value < RESONANCE_TEST_LEVEL):
        report["reason"] = "no band of the spectrum stands out of its surroundings"
        return ResonanceChoice(best, tried, latents, report)
    checks = {}

    def passes(fit):
        # the band is seen (the shortest tau fitted within RESONANCE_SEEN / f0: beyond, the term is only its
        # 1/tau^2 tail, a shape with no resonance in it), it is a resonance (quality factor pi f0 tc at least
        # RESONANCE_MIN_Q: a broader band is a filter's or a Gauss-Markov shape, and trades with the white noise),
        # the white noise stays resolved (RESONANCE_WHITE_Z) and the poor-fit check passes (a resonance must not
        # make a flagged fit)
        params = fit["diag"]["params"]
        if fit["diag"]["tau"][0] * params["RS.f0"] > RESONANCE_SEEN:
            return False
        if math.pi * params["RS.f0"] * params["RS.tc"] < RESONANCE_MIN_Q:
            return False
        if not white_resolved(fit):
            return False
        if check is None:
            return True
        result = check(fit, rs_latents)
        checks[int(fit["diag"]["m"][0])] = result.get("fit_pvalue")
        return not result.get("poor_fit")

    fit, rs_tried, _ = refit(rs_latents, found, below=m0, accept=passes,
                             max_tau=RESONANCE_SEEN * RESONANCE_FREQUENCY_FACTOR / found.f0,
                             seed=best["diag"]["values"])
    report["fit_pvalues_with"] = checks
    report["tried"] = [{"min_m": a, "J_stat": b, "n_scales": c} for a, b, c in rs_tried]
    if fit is None:
        report["reason"] = ("no shorter cut-off is adequate with a resonance (Hansen's J at level "
                            f"{SCALE_TEST_LEVEL}) and passes the poor-fit check")
        return ResonanceChoice(best, tried, latents, report)
    m_rs = int(fit["diag"]["m"][0])
    j_without = next((j for a, j, _ in tried if a == m_rs), math.nan)
    params = fit["diag"]["params"]
    report.update({
        "included": True, "min_m_with": m_rs, "J_with": float(fit["J_stat"]),
        "J_without_same_scales": float(j_without),
        # the D (distance-metric) statistic of the two nested fits on the same scales; with sigma = 0 on
        # its boundary and f0, tc undefined without the term its chi^2(3) p-value is only indicative
        "p_value": float(chdtrc(3, j_without - fit["J_stat"])) if math.isfinite(j_without) else math.nan,
        "sigma": params["RS.sigma"], "f0": params["RS.f0"], "tc": params["RS.tc"],
        "reason": "the resonance lets the model fit shorter scales",
    })
    return ResonanceChoice(fit, tried + rs_tried, rs_latents, report)
