"""Latent models: a gyro named by the codes of its terms (``"WN+GM+RW"``), and the parameter vector a fit of it
estimates.

A latent model is a sum of independent noise terms, each named by its :attr:`NoiseTerm.latent` code:

====  ==========================================================  ===================  ============
code  term                                                        parameters           reports
====  ==========================================================  ===================  ============
QN    :class:`~avbench.noise_models.Quantization`                 Q                    Q
WN    :class:`~avbench.noise_models.AngleRandomWalk`              N                    N
FW    :class:`~avbench.noise_models.FilteredWhiteNoise` (tf=...)  N, tf                N
GM    :class:`~avbench.noise_models.GaussMarkov`                  sigma, tc            B (B_equiv)
FL    :class:`~avbench.noise_models.BiasInstability`              B                    B
RW    :class:`~avbench.noise_models.RateRandomWalk`               K                    K
DR    :class:`~avbench.noise_models.RateRamp`                     R                    R
SN    :class:`~avbench.noise_models.Sinusoidal`                   A, f0                --
RS    :class:`~avbench.noise_models.Resonance`                    sigma, f0, tc        --
====  ==========================================================  ===================  ============

The table is read from the terms themselves (:attr:`NoiseTerm.fit_parameters`,
:attr:`NoiseTerm.coefficient`); its row order is the canonical order of a model's terms and of the
parameter vector (:data:`LATENT_TERMS`). A model has at most one term per reported coefficient (GM and
FL are two models of B, WN and FW two of N).

>>> parse_model("RW+WN+GM")
('WN', 'GM', 'RW')
>>> build_gyro(("WN", "RW"), [1e-3, 2e-6], dt=0.1)
Gyro(dt=0.1, terms=[AngleRandomWalk(N=0.001), RateRandomWalk(K=2e-06)])
"""

from __future__ import annotations

from avbench.noise_models.gyro import Gyro
from avbench.noise_models.markov_terms import GaussMarkov
from avbench.noise_models.power_law_terms import (AngleRandomWalk, BiasInstability, Quantization, RateRamp,
                                                  RateRandomWalk)
from avbench.noise_models.sensor_terms import FilteredWhiteNoise, Resonance, Sinusoidal
from avbench.noise_models.term_base import NoiseTerm

__all__ = ["LATENT_TERMS", "LATENTS", "parse_model", "build_gyro", "n_parameters", "param_index", "white_latent"]

#: latent code -> term class, in the canonical order of a model's terms and of its parameter vector
LATENT_TERMS: dict[str, type[NoiseTerm]] = {
    cls.latent: cls
    for cls in (Quantization, AngleRandomWalk, FilteredWhiteNoise, GaussMarkov, BiasInstability, RateRandomWalk,
                RateRamp, Sinusoidal, Resonance)
}

#: latent code -> (the parameters a fit estimates, the coefficient reported or None), read from the terms
LATENTS: dict[str, tuple[tuple[str, ...], str | None]] = {
    code: (cls.fit_parameters, cls.coefficient) for code, cls in LATENT_TERMS.items()
}


def _alternatives() -> str:
    """'not both GM and FL (two models of B) and ...': the latents that report one coefficient."""
    by_coef: dict[str, list[str]] = {}
    for code, cls in LATENT_TERMS.items():
        if cls.coefficient is not None:
            by_coef.setdefault(cls.coefficient, []).append(code)
    return " and ".join(f"not both {' and '.join(codes)} (two models of {c})"
                        for c, codes in by_coef.items() if len(codes) > 1)


def parse_model(model) -> tuple[str, ...]:
    """Latent codes from ``"WN+GM+RW"`` or a list of them, in the canonical order of :data:`LATENT_TERMS`;
    a ValueError naming the grammar for anything else (an unknown code, a repeat, two terms reporting
    one coefficient)."""
    if isinstance(model, str):
        parts = [p.strip().upper() for p in model.split("+")]
    elif isinstance(model, (list, tuple)):
        parts = [str(p).strip().upper() for p in model]
    else:
        parts = None
    coefs = [LATENT_TERMS[p].coefficient for p in parts or () if p in LATENT_TERMS]
    reported = [c for c in coefs if c is not None]
    if (not parts or any(p not in LATENT_TERMS for p in parts) or len(set(parts)) != len(parts)
            or len(set(reported)) != len(reported)):
        raise ValueError(
            f"model: expected latent names from {', '.join(LATENT_TERMS)} joined by '+' (e.g. 'WN+GM+RW') "
            f"or a list of them, without repeats, {_alternatives()}; got {model!r}"
        )
    return tuple(p for p in LATENT_TERMS if p in parts)


def build_gyro(latents, values, dt, flicker_tau_max=None) -> Gyro:
    """The :class:`~avbench.noise_models.Gyro` of the latents ``latents`` at parameter values ``values`` (SI;
    each term's :attr:`~NoiseTerm.fit_parameters` in turn). ``flicker_tau_max``: the filter memory of a
    flicker latent "FL" (required with it)."""
    it = iter(values)
    terms = []
    for lat in latents:
        cls = LATENT_TERMS[lat]
        terms.append(cls.from_fit([next(it) for _ in cls.fit_parameters], tau_max=flicker_tau_max))
    return Gyro(dt=dt, terms=terms)


def n_parameters(latents) -> int:
    """The length of the parameter vector of ``latents``."""
    return sum(len(LATENT_TERMS[lat].fit_parameters) for lat in latents)


def param_index(latents, name) -> int:
    """Index of the first parameter of latent ``name`` in the parameter vector of ``latents``."""
    i = 0
    for lat in latents:
        if lat == name:
            return i
        i += len(LATENT_TERMS[lat].fit_parameters)
    raise ValueError(name)


def white_latent(latents) -> str | None:
    """The latent holding the white rate noise N (``WN``, or ``FW``: the same white noise seen through the
    sensor's filter, whose AV beyond the filter is N^2 / tau as WN's), or None."""
    return next((lat for lat in latents if LATENT_TERMS[lat].coefficient == "N"), None)
