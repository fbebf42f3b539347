"""Which scales a fit of the AV curve uses: the shortest cluster size (GMWM's ``min_m``).

Real sensors low-pass filter their output (anti-aliasing, averaging), which bends the first octaves of
the AV away from every latent model without a filter term: fitted on all octaves, a Gauss-Markov term
then takes the filter's shape (Tc ~ dt) instead of the bias instability. The rules here choose the
shortest cluster size ``m0`` a fit keeps (every longer usable one with it), from fits on the cut-offs
tried in turn from the shortest up; each fit's Hansen J is chi^2 with (scales - parameters) degrees
of freedom where the model holds.

``"auto"``
    Drop the shortest scale while the difference of the two J statistics, chi^2 with (number
    dropped) degrees of freedom when the dropped values obey the model (the difference-in-Hansen / C
    test of Eichenbaum, Hansen & Singleton 1988), rejects at level :data:`SCALE_TEST_LEVEL`; keep the
    first scale that is not rejected. A model that misses the curve in the middle is not rescued this
    way (dropping one shortest scale hardly changes its J): it stays on all scales.
``"adequate"``
    The shortest cut-off whose own fit Hansen's J test does not reject at :data:`SCALE_TEST_LEVEL`,
    keeping at least the longer half of the usable scales (the model must explain the longer half of
    the curve: without that bound a model that misses a Gauss-Markov bump "passes" on the last few
    scales); if none is, the ``"auto"`` choice. It differs from ``"auto"`` only where the all-scale fit
    is rejected, i.e. where the model misses the first octaves over more than one scale (dropping one
    scale at a time changes J too little for the difference test).
an integer
    That cluster size, fixed.

A caller may keep the record's white noise in the fit (:func:`white_reach`; GMWM does for ``"adequate"``): a cut-off
is tried only up to the last octave of the first stretch of octaves where the record's AV falls nearly as 1/tau
(local slope within 1/4 of -1: white noise makes at least three quarters of the AV). Beyond it the fit does not see
the white level: N is then read off the bias-instability region (a 1/f rise, a sinusoid's skirt), where a filter
term with a time constant of a second or a Gauss-Markov term trades with it, and it moves with the record's length
(an accelerometer's N by 40 % between 30 minutes and 2.8 h). Where the model misses the curve elsewhere, no cut-off
within the reach is adequate, the one Hansen's J rejects least is taken (:func:`choose_scales`), and the poor-fit
check says the fit misses the curve.

:func:`shorter_adequate` is the ``"adequate"`` rule below a given cut-off, with a further test of
each fit (a resonance added to a model, :mod:`avbench.estimators.selection.resonance`).

A fit is a dict with at least ``"J_stat"``; the rules add ``"k"``, the number of scales it used.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import numpy as np

__all__ = ["SCALE_TEST_LEVEL", "WHITE_SLOPE_TOLERANCE", "ScaleChoice", "white_reach", "reach_binds", "cutoffs",
           "adequate", "choose_scales", "shorter_adequate"]

#: level of the difference-in-J test that drops a shortest scale (``"auto"``) and of Hansen's J test of one
#: cut-off's fit (``"adequate"``)
SCALE_TEST_LEVEL = 0.001


class ScaleChoice(NamedTuple):
    """What a scale rule chose: ``fit`` (the fit on the chosen scales, None where no cut-off was accepted),
    ``tried`` (``(min_m, J, n_scales)`` for every cut-off fitted, in order: ``extras_["scale_choice"]``)
    and ``reason`` (a sentence)."""

    fit: dict | None
    tried: list
    reason: str


#: an octave is in the white-noise region when its local AV slope lies within this of -1 (white rate noise):
#: against a flat term (bias instability) the slope is minus the white noise's share of the AV, so 1/4 keeps the
#: octaves where white noise makes at least three quarters of it
WHITE_SLOPE_TOLERANCE = 0.25


def white_reach(tau, avar, n, m, usable) -> int | None:
    """The longest cut-off that keeps the record's white noise in a fit: the cluster size of the last octave of
    the first stretch of at least two usable octaves (``usable``: a mask over the octave cluster sizes ``m``, taus
    ``tau``, AV ``avar`` of a record of ``n`` samples; a lone octave only where no stretch has two: the flank of
    a resonance's hump is no white region) whose local log-log slope of the AV lies within
    :data:`WHITE_SLOPE_TOLERANCE` of -1 (slopes as the engine reads them, ``numpy.gradient`` of the
    logarithms, where an octave has at least 16 clusters); None where no octave qualifies.

    >>> tau = 0.01 * 2.0 ** np.arange(10)
    >>> avar = np.r_[0.5, 0.8, 1.0 / tau[2:6] * 0.01, np.full(4, 0.3)]  # a filter, white, then a plateau
    >>> white_reach(tau, avar, 10**6, 2 ** np.arange(10), np.ones(10, bool))
    16
    """
    m = np.asarray(m)
    ok = np.flatnonzero(usable & (n // m >= 16) & (np.asarray(avar) > 0))
    if ok.size < 2:
        return None
    slope = np.gradient(np.log(np.asarray(avar, float)[ok]), np.log(np.asarray(tau, float)[ok]))
    white = np.abs(slope + 1.0) <= WHITE_SLOPE_TOLERANCE
    stretches, start = [], None  # (first, last) index of each run of white octaves
    for i, w in enumerate(np.r_[white, False]):
        if w and start is None:
            start = i
        elif not w and start is not None:
            stretches.append((start, i - 1))
            start = None
    if not stretches:
        return None
    _, last = next((st for st in stretches if st[1] > st[0]), stretches[0])
    return int(m[ok][last])


def reach_binds(reach, m, usable, n_free) -> bool:
    """Whether the white reach (:func:`white_reach`; None: none) stops the automatic rules short of a cut-off they
    would try otherwise: one that leaves at least ``n_free + 1`` usable scales and the longer half of them.

    >>> m = 2 ** np.arange(12)
    >>> every = np.ones(12, bool)
    >>> reach_binds(16, m, every, 3), reach_binds(64, m, every, 3), reach_binds(None, m, every, 3)
    (True, False, False)
    """
    if reach is None:
        return False
    k_all = np.count_nonzero(usable)
    return any(v > reach and 2 * np.count_nonzero(usable & (m >= v)) >= k_all
               for v in cutoffs("auto", m, usable, n_free))


def cutoffs(rule, m, usable, n_free, reach=None) -> list[int]:
    """The cut-offs a rule tries: for ``"auto"`` and ``"adequate"`` every cluster size of ``m`` that leaves at
    least ``n_free + 1`` usable scales (``usable``: a mask over ``m``) and is at most ``reach`` (None: any;
    :func:`white_reach`), shortest first; for an integer, itself."""
    if rule in ("auto", "adequate"):
        return [int(v) for v in m if np.count_nonzero(usable & (m >= v)) >= n_free + 1
                and (reach is None or v <= reach)]
    return [int(rule)]


def adequate(J, k, n_free) -> bool:
    """Hansen's J test of a fit on ``k`` scales with ``n_free`` parameters does not reject at
    :data:`SCALE_TEST_LEVEL` (chi^2 with max(k - n_free, 1) degrees of freedom)."""
    from scipy.special import chdtrc  # scipy.stats.chi2.sf(x, nu) is chdtrc(nu, x), without importing scipy.stats

    return chdtrc(max(k - n_free, 1), J) >= SCALE_TEST_LEVEL


def _fit_at(fit_on, m0, m, usable, tried) -> dict:
    """The fit on the usable scales from cut-off ``m0`` on, its number of scales as ``fit["k"]``, recorded in
    ``tried`` as ``(min_m, J, n_scales)``."""
    keep = usable & (m >= m0)
    fit = fit_on(keep)
    fit["k"] = int(np.count_nonzero(keep))
    tried.append((m0, fit["J_stat"], fit["k"]))
    return fit


def choose_scales(fit_on: Callable[[np.ndarray], dict], lows, m, usable, n_free, rule,
                  reached=False) -> ScaleChoice:
    """The scale rule ``rule`` (``"auto"``, ``"adequate"`` or an integer, module docstring) over the cut-offs
    ``lows`` (:func:`cutoffs`); ``fit_on(keep)`` fits the scales of the mask ``keep`` (``usable & (m >= m0)``).
    ``reached``: ``lows`` stop at the white reach (:func:`white_reach`) short of the cut-offs the rule would try
    otherwise; where then no cut-off is adequate, ``"adequate"`` takes the one whose fit Hansen's J rejects
    least (the largest p-value: the model misses the curve beyond the white region, and the sequential test
    is no guide there -- dropping a scale can raise J by moving the fit to another optimum); where one is, the
    longer cut-offs within the reach are fitted too, and those Hansen's J accepts are returned with the chosen
    fit as ``fit["alternatives"]`` (``[(min_m, fit), ...]``): on a short white region, which octaves of the
    sensor's front end a fit keeps moves N through the filter term, and the record accepts several.

    >>> J = {1: 400.0, 2: 9.0, 4: 8.5, 8: 8.2}  # the first octave bent: J falls 391 when it is dropped
    >>> m, usable = np.array([1, 2, 4, 8, 16, 32, 64, 128, 256, 512]), np.ones(10, bool)
    >>> fit_on = lambda keep: {"J_stat": J.get(int(m[keep][0]), 8.0)}
    >>> c = choose_scales(fit_on, cutoffs("auto", m, usable, 3), m, usable, 3, "auto")
    >>> [t[0] for t in c.tried], c.fit["k"]
    ([1, 2, 4], 9)
    """
    # scipy.stats.chi2.sf(x, nu) is chdtrc(nu, x) and chi2.ppf(q, nu) is 2 gammaincinv(nu / 2, q): the same bits,
    # without importing scipy.stats
    from scipy.special import chdtrc, gammaincinv

    best, tried, chosen, why, fits, found = None, [], False, None, [], False
    for m0 in lows:
        fit = _fit_at(fit_on, m0, m, usable, tried)
        k = fit["k"]
        if best is None:
            k_all = k
        if 2 * k >= k_all:
            fits.append((m0, fit))
        if rule == "adequate" and 2 * k >= k_all and adequate(fit["J_stat"], k, n_free):
            best, found = fit, True  # the shortest cut-off whose own J is not rejected
            why = "the shortest cut-off whose own fit Hansen's J does not reject"
            if reached:
                best["alternatives"] = _adequate_beyond(fit_on, lows, m0, m, usable, n_free, k_all, tried)
            break
        if chosen:
            if 2 * k < k_all:
                break  # "adequate" keeps at least the longer half of the scales
            continue  # "adequate": the sequential choice is made; look on for an adequate cut-off
        if best is not None and not best["J_stat"] - fit["J_stat"] > 2 * gammaincinv((best["k"] - k) / 2, 1 - SCALE_TEST_LEVEL):
            why = "the difference-in-J test does not reject the shortest scale kept"
            if rule != "adequate":
                break  # the shorter scale agrees with the rest: keep it
            chosen = True
            continue
        best = fit
    if rule == "adequate" and reached and fits and not found:
        m0, best = max(fits, key=lambda mf: chdtrc(max(mf[1]["k"] - n_free, 1), mf[1]["J_stat"]))
        return ScaleChoice(best, tried, "no cut-off within the white reach is adequate by Hansen's J: the one it "
                                        f"rejects least (min_m={m0})")
    if rule not in ("auto", "adequate"):
        reason = f"fixed by the setting (min_m={rule!r})"
    elif why is None:
        reason = "the difference-in-J test rejected the shortest scale at every cut-off tried: the last one"
    elif rule == "adequate" and not found:
        reason = f"no cut-off is adequate by Hansen's J on the longer half of the scales; as 'auto': {why}"
    else:
        reason = why
    return ScaleChoice(best, tried, reason)


def _adequate_beyond(fit_on, lows, m0, m, usable, n_free, k_all, tried) -> list:
    """``[(min_m, fit), ...]`` for the cut-offs of ``lows`` longer than ``m0`` that keep the longer half of the
    ``k_all`` scales and whose fits Hansen's J accepts (each fitted; ``tried`` extended)."""
    out = []
    for m1 in [v for v in lows if v > m0]:
        if 2 * np.count_nonzero(usable & (m >= m1)) < k_all:
            break
        fit = _fit_at(fit_on, m1, m, usable, tried)
        if adequate(fit["J_stat"], fit["k"], n_free):
            out.append((int(m1), fit))
    return out


def shorter_adequate(fit_on: Callable[[np.ndarray], dict], lows, m, usable, n_free, below, max_tau, dt,
                     accept: Callable[[dict], bool] | None = None) -> ScaleChoice:
    """The ``"adequate"`` rule among the cut-offs of ``lows`` shorter than ``below`` whose tau is at most
    ``max_tau`` (s, sampling ``dt``): the shortest whose fit keeps at least the longer half of the usable
    scales (counted from ``lows[0]``), is not rejected by Hansen's J at :data:`SCALE_TEST_LEVEL` and is
    accepted by ``accept(fit)``; ``fit`` None where none is."""
    k_all = int(np.count_nonzero(usable & (m >= lows[0]))) if lows else 0
    lows = [v for v in lows if v < below and v * dt <= max_tau]
    tried = []
    for m0 in lows:
        fit = _fit_at(fit_on, m0, m, usable, tried)
        if 2 * fit["k"] >= k_all and adequate(fit["J_stat"], fit["k"], n_free) and (accept is None or accept(fit)):
            return ScaleChoice(fit, tried, f"the shortest adequate and accepted cut-off below {below} (min_m={m0})")
    return ScaleChoice(None, tried, f"no cut-off below {below} is adequate and accepted")
