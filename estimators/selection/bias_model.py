"""Which model of bias instability a record supports: a Gauss-Markov term (``GM``) or flicker noise (``FL``)
(GMWM's ``bias_evidence=True``).

The same latent model with ``GM`` and ``FL`` exchanged (:func:`exchanged`) is fitted on the same scales,
and the two are compared by a GMM information criterion. Hansen's J of an efficient two-step fit is,
to first order, twice the log-likelihood ratio of the model against the unrestricted moments, so

.. math:: \\mathrm{AIC} = J + 2p

(p the model's parameters; the GMM analogue of Akaike's criterion, the constant of the moments
cancelling between the two; Andrews 1999, Econometrica 67, for J-based criteria; each J here with its
own model's second-step weights, equal to first order where either model is right), and the Akaike
weights :math:`e^{-\\mathrm{AIC}/2}`, normalised, say how much the record favours each. The evidence is
decisive where the preferred model's weight is at least :data:`BIAS_EVIDENCE_WEIGHT`. The coefficients
reported are the fitted model's; unless the record decisively favours that model, an interval holds the
coefficient under the other one too (:func:`held_alternative`): where the evidence is not decisive, and where it
decisively favours the other model.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import NamedTuple

from avbench.estimators.selection.averaging import criterion_weights
from avbench.noise_models.latents import parse_model

__all__ = ["BIAS_EVIDENCE_WEIGHT", "BiasEvidence", "exchanged", "weigh_bias_models", "held_alternative"]

#: the Akaike weight at which the record's evidence between a Gauss-Markov and a flicker bias instability is
#: called decisive: a difference in AIC of 5.9
BIAS_EVIDENCE_WEIGHT = 0.95


class BiasEvidence(NamedTuple):
    """What :func:`weigh_bias_models` found: ``preferred`` ("GM" or "FL"), its Akaike ``weight``, whether the
    evidence is ``decisive``, and the ``report`` (the model choice ``bias_evidence``: ``{"GM": {...}, "FL":
    {...}, "preferred", "weight", "fitted", "decisive", "min_m"}``, each model with ``J_stat``, ``n_par``,
    ``aic``, ``B`` (SI: B_equiv for GM, B for FL), ``coefficients``, ``std_err`` (dicts, SI) and ``weight``;
    ``fitted``: the model whose coefficients are reported)."""

    preferred: str
    weight: float
    decisive: bool
    report: dict


def exchanged(latents) -> tuple[str, ...]:
    """The latent model ``latents`` with its bias-instability term exchanged (GM for FL and FL for GM)."""
    return parse_model(tuple({"GM": "FL", "FL": "GM"}.get(lat, lat) for lat in latents))


def weigh_bias_models(latents, fit, other, other_fit, n_free: Callable[[tuple], int], min_m: int) -> BiasEvidence:
    """The evidence between the fit ``fit`` of ``latents`` and the fit ``other_fit`` of ``other`` (its
    :func:`exchanged` model) on the same scales (shortest cluster size ``min_m``); ``n_free(latents)``: the
    number of parameters a fit estimates. A fit is a dict with ``J_stat``, ``coefs`` (coefficient -> SI) and
    ``diag["std_err"]`` (a pandas Series).

    >>> import pandas as pd
    >>> gm = {"J_stat": 4.0, "coefs": {"N": 1.0, "B": 2.0}, "diag": {"std_err": pd.Series({"N": 0.1, "B": 0.2})}}
    >>> fl = {"J_stat": 30.0, "coefs": {"N": 1.0, "B": 2.5}, "diag": {"std_err": pd.Series({"N": 0.1, "B": 0.3})}}
    >>> ev = weigh_bias_models(("WN", "GM"), gm, ("WN", "FL"), fl, lambda lats: 1 + len(lats), 1)
    >>> ev.preferred, ev.decisive, round(ev.report["FL"]["aic"] - ev.report["GM"]["aic"], 1)
    ('GM', True, 26.0)
    """
    out = {}
    for lats, f in ((latents, fit), (other, other_fit)):
        name = "GM" if "GM" in lats else "FL"
        p = n_free(lats)
        se = f["diag"]["std_err"]
        out[name] = {"J_stat": float(f["J_stat"]), "n_par": p, "aic": float(f["J_stat"]) + 2.0 * p,
                     "B": float(f["coefs"].get("B", math.nan)),
                     "coefficients": {c: float(v) for c, v in f["coefs"].items()},
                     "std_err": {c: float(se[c]) for c in f["coefs"] if c in se.index}}
    for name, w in criterion_weights({k: v["aic"] for k, v in out.items()}).items():
        out[name]["weight"] = w
    preferred = max(out, key=lambda k: out[k]["weight"])
    decisive = bool(out[preferred]["weight"] >= BIAS_EVIDENCE_WEIGHT)
    out.update({"preferred": preferred, "weight": out[preferred]["weight"],
                "fitted": "GM" if "GM" in latents else "FL", "decisive": decisive, "min_m": int(min_m)})
    return BiasEvidence(preferred, out[preferred]["weight"], decisive, out)


def held_alternative(report: dict | None) -> dict | None:
    """The other bias-instability model's entry of a :class:`BiasEvidence` report (its ``coefficients`` and
    ``std_err``), which the intervals hold too, unless the record decisively favours the fitted model: where it
    does not decide between the two, and where it decisively favours the other (the values reported are then
    the less supported model's, and an interval of theirs alone would miss the coefficient the record
    supports). None where the record decisively favours the fitted model or there is no report."""
    if not report or (report["decisive"] and report["preferred"] == report["fitted"]):
        return None
    return report["FL" if report["fitted"] == "GM" else "GM"]
