"""The contract's recovery check (:func:`avbench.estimators.contract.check_estimator`, check ``recovery``):
does a fitted estimator recover the coefficients of a simulated gyro within what its efficiency allows?

On a simple simulated gyro (:func:`recovery_gyro`: angle random walk plus rate random walk, 2^14
samples at 10 Hz, a fixed seed) every coefficient of the gyro the estimator reports lies within
:data:`Z_RECOVERY` standard deviations of an estimator :data:`EFFICIENCY_ALLOWANCE` times less
efficient than the Cramér-Rao bound of that record (``avbench.estimators.likelihood.crlb``):
:math:`|\\hat\\theta - \\theta| \\le z\\,E\\,\\sigma_{CRLB}`. With z = 4 an unbiased Gaussian
estimator that meets the allowance fails by chance with probability below 1e-4 per coefficient.
Every other coefficient the estimator reports on that record (Q, B, R of a five-term model) is
judged the same way on a second record, of :func:`full_recovery_gyro`; R is reported, not judged
(the bound does not cover a rate ramp). A coefficient the estimator flags non-physical is reported,
not judged (at least one must be recovered), and an estimator that warns, with an
``IdentifiabilityWarning``, that the record cannot determine its coefficients is excused.

>>> recovery_problem("N", 1.3e-3, 1e-3, 5.5e-6)
['N = 0.0013, true 0.001 (SI): off by 54.5 CRLB std, expected within 4 x 10 = 0.00022']
>>> recovery_problem("N", 1.1e-3, 1e-3, 5.5e-6)
[]
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from avbench.noise_models.units import COEFFICIENTS

__all__ = ["RECOVERY_SAMPLES", "Z_RECOVERY", "EFFICIENCY_ALLOWANCE", "recovery_gyro", "full_recovery_gyro",
           "check_recovery", "recovery_problem"]

#: record length of the recovery check (samples at dt = 0.1 s: about 27 minutes)
RECOVERY_SAMPLES = 1 << 14
#: standard deviations allowed in the recovery check
Z_RECOVERY = 4.0
#: how many times the CRLB standard deviation an estimator's own may be in the recovery check
EFFICIENCY_ALLOWANCE = 10.0
#: the seed of :func:`full_recovery_gyro`'s record
_SEED_ALL = 20260103
_INDEX = list(COEFFICIENTS)


def full_recovery_gyro():
    """The second record of the recovery check, for the coefficients the first gyro lacks:
    Q = 2e-4 rad, N = 1e-3 rad/√s, B = 3e-4 rad/s, K = 3e-5 rad/s^1.5 at dt = 0.1 s.

    Each term shows on :data:`RECOVERY_SAMPLES` / 4 samples (7 minutes): quantization at the first
    cluster sizes (3 Q^2 / tau^2 = 1.2 N^2 / tau at tau = 0.1 s), the bias-instability plateau
    (0.664 B^2 = 6e-8 rad^2/s^2) above white noise from tau = 17 s. No rate ramp: the Cramér-Rao
    bound does not cover one, so R is reported, not judged.
    """
    from avbench.noise_models import AngleRandomWalk, BiasInstability, Gyro, Quantization, RateRandomWalk

    return Gyro(dt=0.1, terms=[Quantization(Q=2e-4), AngleRandomWalk(N=1e-3), BiasInstability(B=3e-4, tau_max=3600.0),
                               RateRandomWalk(K=3e-5)], name="recovery_all")


def recovery_gyro():
    """The gyro of the recovery check: N = 1e-3 rad/√s, K = 3e-5 rad/s^1.5, dt = 0.1 s.

    On the record of 2^14 samples (27 minutes) the Cramér-Rao standard deviations are 0.55 % of N
    and 21 % of K: the AV is white-noise dominated, the rate random walk bends its last octaves
    (crossover 3 N^2 / K^2 = 3300 s). A curve fit of all five terms on all cluster sizes (OLS of
    Lv et al. 2015) still recovers N here, while a strong random walk would swamp it.
    """
    from avbench.noise_models import AngleRandomWalk, Gyro, RateRandomWalk

    return Gyro(dt=0.1, terms=[AngleRandomWalk(N=1e-3), RateRandomWalk(K=3e-5)], name="recovery")


def check_recovery(first, nonphysical, gyro, fit: Callable, unidentifiable: str | None = None) -> tuple[list[str], str]:
    """``(problems, note)`` of the recovery check of an estimator whose fit to :data:`RECOVERY_SAMPLES`
    samples of ``gyro`` (:func:`recovery_gyro`) gave the coefficients ``first`` with the flags
    ``nonphysical``: each coefficient of the gyro it reports judged against the gyro's Cramér-Rao bound
    (:func:`recovery_problem`), the others it reports on :func:`full_recovery_gyro`'s record, fitted by
    ``fit(rate, dt)`` (a new estimator of the same settings). ``unidentifiable``: the
    ``IdentifiabilityWarning`` the fit gave, which excuses the estimator (the note says so)."""
    from avbench.estimators.likelihood.crlb import crlb

    truth = gyro.coefficients
    bound = crlb(gyro, RECOVERY_SAMPLES)
    problems, checked, flagged = [], [], []
    for k in _INDEX:
        if not np.isfinite(truth[k]):
            continue
        v = first[k]
        if bool(nonphysical[k]):
            flagged.append(k)  # the estimator says it has no physical value: data, not an error
            continue
        if not np.isfinite(v):
            continue  # not modelled
        checked.append(k)
        problems += recovery_problem(k, v, truth[k], bound[k])
    others = [k for k in _INDEX if not np.isfinite(truth[k]) and (np.isfinite(first[k]) or bool(nonphysical[k]))]
    if others:  # coefficients the first gyro lacks: judged on a gyro that has them
        more, done, skipped = _recover_others(others, fit)
        problems += more
        checked += done
        flagged += skipped
    if not checked and not problems:
        problems.append(
            f"none of the gyro's coefficients ({', '.join(k for k in _INDEX if np.isfinite(truth[k]))}) "
            f"was estimated{' (flagged non-physical: ' + ', '.join(flagged) + ')' if flagged else ''}"
        )
    if problems and unidentifiable:
        # the estimator said, with an IdentifiabilityWarning, that this record cannot determine
        # its coefficients: it is excused, and the report says so
        return [], f"not judged: the estimator warned {unidentifiable!r} ({'; '.join(problems)})"
    notes = [f"{', '.join(checked)} recovered"] if checked else []
    if flagged:
        notes.append(f"{', '.join(flagged)} flagged non-physical or not judged")
    return problems, "; ".join(notes)


def _recover_others(coefs, fit):
    """(problems, recovered, not judged) for ``coefs`` on :func:`full_recovery_gyro`'s record."""
    from avbench.estimators.likelihood.crlb import crlb

    g = full_recovery_gyro()
    n = RECOVERY_SAMPLES // 4
    est = fit(g.simulate(n, np.random.default_rng(_SEED_ALL)), g.dt)
    truth, bound = g.coefficients, crlb(g, n)
    problems, done, skipped = [], [], []
    for k in coefs:
        v = est.coefficients_[k]
        if bool(est.nonphysical_[k]) or not np.isfinite(bound[k]) or not np.isfinite(truth[k]):
            skipped.append(k)
            continue
        if not np.isfinite(v):
            continue
        done.append(k)
        problems += recovery_problem(k, v, truth[k], bound[k], f" on the {g.name} record")
    return problems, done, skipped


def recovery_problem(k, v, true, bound, where: str = "") -> list[str]:
    """The recovery problem of coefficient ``k`` (estimate ``v``, truth ``true``, CRLB std ``bound``, SI) when it
    lies beyond ``Z_RECOVERY x EFFICIENCY_ALLOWANCE`` CRLB std of the truth, else none; ``where``: the record."""
    tol = Z_RECOVERY * EFFICIENCY_ALLOWANCE * float(bound)
    if abs(v - true) <= tol:
        return []
    return [f"{k} = {v:.4g}, true {true:.4g} (SI){where}: off by {abs(v - true) / bound:.1f} CRLB std, "
            f"expected within {Z_RECOVERY:g} x {EFFICIENCY_ALLOWANCE:g} = {tol:.3g}"]
