"""Checks of what an estimator is handed: its record (:func:`check_record`) and the grammars of the
settings several estimators share (:func:`check_terms`, :func:`check_taus`), which their declarations
use (:mod:`avbench.estimators.settings`).

A leaf of the estimators package: the contract (:mod:`avbench.estimators.base`), the Allan-variance
engine and every family import these checks from here, so that each is written once and none of
them needs another to validate its input.
"""

from __future__ import annotations

import numpy as np

from avbench.noise_models.terms import _check_dt as check_dt
from avbench.noise_models.units import COEFFICIENTS

__all__ = ["DT_RANGE", "TAU_GRIDS", "check_dt", "check_record", "check_not_constant", "check_taus", "check_terms",
           "check_variance_seen"]


#: sample intervals an estimator accepts (1 ns .. ~11.6 days): beyond them tau**2 and tau**-2 in the
#: Allan-variance model leave float64's comfortable range
DT_RANGE = (1e-9, 1e6)


def check_record(rate, dt) -> tuple[np.ndarray, float]:
    """Validate a gyro record: 1-D, finite, at least 16 samples; ``dt`` finite and in :data:`DT_RANGE`."""
    dt = check_dt(dt)
    if not DT_RANGE[0] <= dt <= DT_RANGE[1]:
        raise ValueError(
            f"dt: expected a sample interval between {DT_RANGE[0]:g} s and {DT_RANGE[1]:g} s "
            f"(a rate between {1 / DT_RANGE[1]:g} Hz and {1 / DT_RANGE[0]:g} Hz), got {dt!r} s"
        )
    arr = np.asarray(rate)
    if arr.dtype.kind not in "iuf":
        raise ValueError(f"rate: expected numeric samples, got dtype {arr.dtype}")
    if arr.ndim != 1:
        raise ValueError(f"rate: expected a 1-D array of rate samples, got shape {arr.shape}")
    if arr.size < 16:
        raise ValueError(f"rate: expected at least 16 samples, got {arr.size}")
    arr = arr.astype(np.float64, copy=False)
    bad = ~np.isfinite(arr)
    if bad.any():
        first = int(np.flatnonzero(bad)[0])
        raise ValueError(f"rate: {int(bad.sum())} non-finite sample(s) (NaN/inf), the first at index {first}")
    return arr, dt


def check_not_constant(rate: np.ndarray) -> None:
    """Refuse a record whose samples are all equal: a constant record has no noise, every Allan variance
    of it is 0, and no coefficient can be estimated (nor bounded: any noise below its resolution fits it).
    One rule for every estimator (:meth:`avbench.estimators.base.Estimator.fit` applies it), so that
    none answers with an error of its own arithmetic on it (a division by zero, an SVD that does not
    converge, a reduction of an empty array)."""
    if rate.size and float(np.min(rate)) == float(np.max(rate)):
        raise ValueError(f"rate: every one of the {rate.size} samples is {float(rate[0]):g}, a constant record: no "
                         "noise to estimate; expected a sensor's record (noise on every sample)")


def check_variance_seen(tau: np.ndarray, avar: np.ndarray, need: int) -> None:
    """Refuse a record long enough for ``need`` taus (``tau``, ``avar``: the ones its length allows) whose
    Allan variance is 0 at so many of them that fewer than ``need`` positive values remain: its cluster
    means do not vary there (a periodic record, e.g. +1, -1, +1, ... at every even cluster size), so a
    longer record would not help; the error names the taus. Nothing is said when the length is the
    cause (the caller's "too short" error then holds)."""
    tau, avar = np.asarray(tau, dtype=float), np.asarray(avar, dtype=float)
    zero = ~(avar > 0)
    if tau.size >= need and zero.any() and np.count_nonzero(~zero) < need:
        shown = ", ".join(f"{t:g}" for t in tau[zero][:6]) + (", ..." if zero.sum() > 6 else "")
        raise ValueError(
            f"rate: the Allan variance is 0 at {int(zero.sum())} of the {tau.size} taus the record is long enough "
            f"for (tau = {shown} s), leaving {int(np.count_nonzero(~zero))} of the {need} needed: its cluster means "
            "do not vary there (a periodic record such as +1, -1, +1, ...); expected a sensor's record (noise "
            "on every sample)")


TAU_GRIDS = ("octave", "decade", "all")


def check_taus(taus) -> None:
    """A ``taus`` setting must be one of :data:`TAU_GRIDS` or a non-empty 1-D array of positive seconds."""
    if isinstance(taus, str):
        if taus not in TAU_GRIDS:
            raise ValueError(f"taus: expected one of {', '.join(TAU_GRIDS)} or an array of seconds, got {taus!r}")
        return
    ok = isinstance(taus, list | tuple | np.ndarray) and not any(isinstance(t, bool) for t in np.ravel(taus))
    if ok:
        try:
            tau = np.asarray(taus, dtype=float)
        except (TypeError, ValueError):
            ok = False
        else:
            ok = tau.ndim == 1 and tau.size > 0 and bool(np.all(np.isfinite(tau))) and bool(np.all(tau > 0))
    if not ok:
        raise ValueError(
            f"taus: expected one of {', '.join(TAU_GRIDS)} or a non-empty list of positive seconds, got {taus!r}"
        )


def check_terms(terms) -> tuple[str, ...]:
    """Validate a collection of coefficient names; return them in canonical Q, N, B, K, R order."""
    if not isinstance(terms, str | list | tuple):
        raise ValueError(
            f"terms: expected a string such as 'QNB' (a non-empty subset of {''.join(COEFFICIENTS)}), got {terms!r}"
        )
    given, terms = terms, list(terms)
    bad = [t for t in terms if t not in COEFFICIENTS]
    if bad or not terms or len(set(terms)) != len(terms):
        raise ValueError(
            f"terms: expected a non-empty subset of {', '.join(COEFFICIENTS)} without repeats, got {given!r}"
        )
    return tuple(c for c in COEFFICIENTS if c in terms)
