"""How long to record: the record length at which each coefficient is known to within ±X % at 95 %.

For a gyro -- a preset, datasheet coefficients, or the model fitted to a short pilot record -- the
Cramér-Rao bound of each coefficient at ``n`` samples (:func:`avbench.estimators.likelihood.crlb.crlb`,
the Whittle information of the exact discrete model) scaled by the recommended estimator's measured
efficiency :math:`e_c` (RMSE over the CRLB) is the spread its estimate will have, so the half-width
of the 95 % interval relative to the coefficient is

.. math::

    h_c(n) = z_{0.975}\\, e_c\\, \\mathrm{CRLB}_c(n) / c ,

and the planned length is the shortest ``n`` with :math:`h_c(n) \\le X/100` for every coefficient asked
for (:func:`plan`). At that length 95 % of records give an estimate within ±X % of the truth, if the
estimator's spread is what it was measured to be; :func:`check_plan` simulates records of that length,
fits them with the recommended estimator, and counts the share that did (with its Clopper-Pearson
interval).

:data:`EFFICIENCY` holds, per coefficient, the upper end of the 95 % bootstrap interval of the median
RMSE/CRLB of ``whittle_debiased`` over the 200 gyros of ``results/random_gyros`` (drawn outside the
presets, 6 records of 2 h each: ``efficiency.csv``, column ``median_hi``): the planner plans for a gyro
at the upper end of what the median gyro costs, not for the best case. A test holds the constants to
the committed file.

The bound is computed exactly up to :data:`N_EXACT` samples; a longer plan is extrapolated along the
bound's own log-log slope between the last two exact lengths (said in the result: ``extrapolated``).

>>> from avbench.noise_models import presets
>>> p = plan(presets.get("ADIS16405_X"), target=0.10)
>>> sorted(p.coefficients)
['B', 'K', 'N']
>>> bool(p.samples["K"] > p.samples["N"])       # the random walk needs the longest record
True
>>> bool(p.precision("B", p.samples["B"]) <= 0.10)
True
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from scipy import stats

from avbench.estimators.likelihood.crlb import crlb
from avbench.noise_models.units import COEFFICIENTS

__all__ = ["EFFICIENCY", "RECOMMENDED", "N_EXACT", "Plan", "plan", "precision_at", "check_plan", "CheckResult",
           "format_duration", "parse_duration"]

#: the estimator the plan is for (the recommended one: ``avbench estimate``'s advice for a study's Monte Carlo)
RECOMMENDED = "whittle_debiased"

#: upper end of the bootstrap 95 % interval of RECOMMENDED's median RMSE/CRLB per coefficient over the
#: random gyros (results/random_gyros/efficiency.csv, "Whittle debiased (profile)", ``median_hi``)
EFFICIENCY = {"Q": 1.06444, "N": 1.211, "B": 1.08363, "K": 1.08278}

#: the longest record whose bound is computed exactly (the Whittle information costs ~1 s and ~1 GB here)
N_EXACT = 1 << 24

#: the shortest record planned for: below it the AV has no scales to speak of
N_MIN = 1 << 10

_Z = float(stats.norm.ppf(0.975))


def precision_at(gyro, n_samples: int, coefficients=None) -> dict[str, float]:
    """:math:`h_c(n)`: the half-width of the 95 % interval of each coefficient relative to its value, at
    ``n_samples`` samples, for the coefficients of ``gyro`` the planner covers (those of :data:`EFFICIENCY`)."""
    truth = gyro.coefficients
    bound = crlb(gyro, int(n_samples))
    coefs = coefficients if coefficients is not None else _planned(gyro)
    return {c: _Z * EFFICIENCY[c] * float(bound[c]) / float(truth[c]) for c in coefs}


def _planned(gyro) -> list[str]:
    truth = gyro.coefficients
    return [c for c in COEFFICIENTS if c in EFFICIENCY and np.isfinite(truth.get(c, math.nan)) and truth[c] > 0]


@dataclass(frozen=True)
class Plan:
    """The planned record length per coefficient: ``samples[c]`` (and ``seconds(c)``) is the shortest record at
    which coefficient ``c``'s 95 % interval is within ±``target`` of its value; ``extrapolated[c]`` is true where
    that length lies beyond :data:`N_EXACT` and was extrapolated; ``curve`` the relative precision at the lengths
    evaluated (rows: samples, columns: coefficients)."""

    gyro: object
    target: float
    samples: dict[str, float]
    extrapolated: dict[str, bool]
    curve: pd.DataFrame = field(repr=False)

    @property
    def coefficients(self) -> list[str]:
        return list(self.samples)

    @property
    def dt(self) -> float:
        return float(self.gyro.dt)

    def seconds(self, c: str) -> float:
        return float(self.samples[c]) * self.dt

    @property
    def longest(self) -> str:
        """The coefficient that needs the longest record (the one the record length is planned for)."""
        return max(self.samples, key=self.samples.get)

    @property
    def record_samples(self) -> int:
        """The record length that meets the target for every coefficient."""
        return int(math.ceil(max(self.samples.values())))

    def precision(self, c: str, n_samples) -> float:
        return precision_at(self.gyro, int(n_samples), [c])[c]


def plan(gyro, target: float, coefficients=None) -> Plan:
    """The shortest record at which each coefficient of ``gyro`` is known to within ±``target`` (a fraction,
    0.10 for ±10 %) at 95 % by the recommended estimator (module docstring)."""
    target = float(target)
    if not (0.0 < target < 1.0):
        raise ValueError(f"target: expected a relative precision between 0 and 1 (0.1 for ±10 %), got {target!r}")
    coefs = list(coefficients) if coefficients is not None else _planned(gyro)
    missing = [c for c in coefs if c not in _planned(gyro)]
    if missing or not coefs:
        raise ValueError(f"the gyro has no {', '.join(missing) or 'coefficient'} to plan for: the planner covers "
                         f"{', '.join(EFFICIENCY)} where present and positive (got {gyro!r})")
    rows, lengths = [], []
    n = N_MIN
    while True:  # doubling until every coefficient meets the target, or the exact range ends
        h = precision_at(gyro, n, coefs)
        rows.append(h)
        lengths.append(n)
        if all(v <= target for v in h.values()) or n >= N_EXACT:
            break
        n *= 2
    curve = pd.DataFrame(rows, index=pd.Index(lengths, name="samples"))
    samples, extrapolated = {}, {}
    for c in coefs:
        samples[c], extrapolated[c] = _crossing(gyro, c, curve[c], target)
    return Plan(gyro=gyro, target=target, samples=samples, extrapolated=extrapolated, curve=curve)


def _crossing(gyro, c, h: pd.Series, target: float) -> tuple[float, bool]:
    """The length where ``h`` falls to ``target``: bisection in log n between the two doubling lengths around it
    (to 1 %), or the extrapolation along the last doubling's log-log slope beyond :data:`N_EXACT`."""
    n, v = h.index.to_numpy(float), h.to_numpy(float)
    if v[0] <= target:
        return float(n[0]), False
    above = np.nonzero(v > target)[0][-1]
    if above == len(v) - 1:  # not met in the exact range
        slope = math.log(v[-1] / v[-2]) / math.log(n[-1] / n[-2]) if len(v) > 1 else -0.5
        slope = min(slope, -1e-3)
        return float(n[-1] * (target / v[-1]) ** (1.0 / slope)), True
    lo, hi = n[above], n[above + 1]
    while hi / lo > 1.01:
        mid = math.sqrt(lo * hi)
        if precision_at(gyro, int(mid), [c])[c] > target:
            lo = mid
        else:
            hi = mid
    return float(math.ceil(hi)), False


@dataclass(frozen=True)
class CheckResult:
    """:func:`check_plan`'s count: per coefficient, ``met[c]`` of ``records`` fits gave an estimate within
    ±target of the truth; ``interval[c]`` is the Clopper-Pearson 95 % interval of that share; ``failed`` counts
    fits whose coefficient was not an estimate (not resolved, failed)."""

    samples: int
    records: int
    met: dict[str, int]
    failed: dict[str, int]
    interval: dict[str, tuple[float, float]]

    def share(self, c: str) -> float:
        return self.met[c] / self.records


def _clopper_pearson(k: int, n: int, level: float = 0.95) -> tuple[float, float]:
    a = 1.0 - level
    lo = 0.0 if k == 0 else float(stats.beta.ppf(a / 2, k, n - k + 1))
    hi = 1.0 if k == n else float(stats.beta.ppf(1 - a / 2, k + 1, n - k))
    return lo, hi


def _check_one(gyro, n, coefs, seed, estimator) -> dict[str, float]:
    from avbench import estimators
    from avbench.estimators.threads import one_blas_thread

    rate = gyro.simulate(n, np.random.default_rng(seed))
    with one_blas_thread():
        r = estimators.get(estimator).fit(rate, gyro.dt).result()
    return {c: (r.coefficients[c].value if r.coefficients[c].status == "ok" else math.nan) for c in coefs}


def check_plan(p: Plan, records: int = 40, seed: int = 0, jobs: int = 1, samples: int | None = None,
               estimator: str = RECOMMENDED, progress: bool = False) -> CheckResult:
    """Simulate ``records`` records of the planned length (or ``samples``) from the plan's gyro, fit each with the
    recommended estimator, and count per coefficient the records whose estimate is within ±target of the truth.
    Record ``i`` is drawn from ``SeedSequence(seed, spawn_key=(i,))``: the count does not depend on ``jobs``."""
    from joblib import Parallel, delayed

    n = int(samples if samples is not None else p.record_samples)
    if records < 1:
        raise ValueError(f"records: expected a positive count, got {records!r}")
    coefs = p.coefficients
    seeds = [np.random.SeedSequence(seed, spawn_key=(i,)) for i in range(records)]
    work = (delayed(_check_one)(p.gyro, n, coefs, s, estimator) for s in seeds)
    if progress:
        from tqdm import tqdm

        work = tqdm(work, total=records, desc=f"check: {records} records of {format_duration(n * p.dt)}",
                    unit="record")
    fits = Parallel(n_jobs=max(1, min(int(jobs), records)))(work)
    truth = p.gyro.coefficients
    met, failed, interval = {}, {}, {}
    for c in coefs:
        est = np.array([f[c] for f in fits], float)
        failed[c] = int(np.sum(~np.isfinite(est)))
        met[c] = int(np.sum(np.abs(est - truth[c]) <= p.target * truth[c]))
        interval[c] = _clopper_pearson(met[c], records)
    return CheckResult(samples=n, records=records, met=met, failed=failed, interval=interval)


_UNITS = (("d", 86400.0), ("h", 3600.0), ("min", 60.0), ("s", 1.0))


def format_duration(seconds: float) -> str:
    """A duration as a person reads it: ``2.5 h``, ``40 min``, ``3.1 d``.

    >>> format_duration(9000), format_duration(2400), format_duration(12)
    ('2.5 h', '40 min', '12 s')
    """
    for name, size in _UNITS:
        if seconds >= size or name == "s":
            v = seconds / size
            return f"{v:.2g} {name}" if v < 10 else f"{v:.0f} {name}"
    raise AssertionError("unreachable")


def parse_duration(text: str) -> float:
    """Seconds from ``2h``, ``90 min``, ``45s``, ``1.5d`` (a bare number is seconds).

    >>> parse_duration("2h"), parse_duration("90 min"), parse_duration("45")
    (7200.0, 5400.0, 45.0)
    """
    s = str(text).strip().lower().replace(" ", "")
    for name, size in (*_UNITS, ("m", 60.0), ("sec", 1.0), ("hours", 3600.0), ("hour", 3600.0)):
        if s.endswith(name) and s[: -len(name)]:
            try:
                v = float(s[: -len(name)])
            except ValueError:
                continue
            break
    else:
        try:
            v, size = float(s), 1.0
        except ValueError:
            raise ValueError(f"duration: expected a number with a unit (2h, 90min, 45s, 1.5d), got {text!r}") from None
    if not (math.isfinite(v) and v > 0):
        raise ValueError(f"duration: expected a positive length, got {text!r}")
    return v * size


@dataclass(frozen=True)
class PilotAxis:
    """One axis of a pilot record: the gyro model fitted to it (``None`` where no coefficient was resolved), the
    coefficients the pilot could not resolve (each with its upper bound in SI, or None), the sensor and axis."""

    sensor: str
    axis: str
    gyro: object
    unresolved: dict[str, float | None]


def gyros_from_pilot(path, estimator: str = RECOMMENDED, **reader_options) -> list[PilotAxis]:
    """Fit ``estimator`` to every axis of a pilot record (read as ``avbench estimate`` reads it: the reader
    options are :func:`avbench.recordings.load_recording`'s) and return the model each axis's resolved
    coefficients stand for (:meth:`avbench.noise_models.Gyro.from_coefficients`), on its longest gap-free run."""
    from avbench import estimators
    from avbench.noise_models.gyro import Gyro
    from avbench.recordings import load_recording

    loaded = load_recording(path, **reader_options)
    first, length = loaded.timing.longest_run()
    out = []
    for rec in loaded.sensors:
        for axis, x in rec.axes.items():
            r = estimators.get(estimator).fit(np.asarray(x[first:first + length], float), loaded.timing.dt).result()
            ok = {c: r.coefficients[c].value for c in EFFICIENCY if r.coefficients[c].status == "ok"}
            unresolved = {c: (r.coefficients[c].interval[1] if r.coefficients[c].interval else None)
                          for c in EFFICIENCY if r.coefficients[c].status == "not resolved"}
            gyro = Gyro.from_coefficients(ok, loaded.timing.dt)
            if gyro is not None:
                gyro.name = f"{rec.sensor} {axis}"
            out.append(PilotAxis(rec.sensor, axis, gyro, unresolved))
    if not out:
        raise ValueError(f"{path}: no gyro or accelerometer axis to plan for")
    return out
