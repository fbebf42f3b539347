"""Step 4: fit every method to every axis, gap-aware, failures kept as data; pool recordings.

* **Gaps.** Methods that work on the Allan variance (least squares, the practitioners' fits, GMWM)
  see a gap-aware AV (:func:`avbench.estimators.allan.variance.skip_gaps`: clusters that straddle a gap are left out).
  Methods that work on the samples themselves (likelihood, ARMA-EM, filters) cannot skip a gap: on a
  record with gaps they are fitted to its longest gap-free run, and the result says so.
* **Scale.** A record whose largest magnitude is far from 1 (say 1e-200 or 1e300 in SI) is multiplied
  by a power of two before fitting and the coefficients divided by it after: every coefficient scales
  linearly with the data, and a power of two changes no digit, so the estimates scale exactly.
* **Failures.** A method that raises on this record is reported (its message, flag "failed") and
  the other methods go on; its warnings are kept.
* **Several recordings** (``--combine``) of one sensor are pooled as one record whose file
  boundaries are gaps, and :func:`agreement` tests whether their Allan variances agree.
"""

from __future__ import annotations

import math
import time
import warnings
from dataclasses import dataclass

import numpy as np

from avbench.estimators.results import FitResult
from avbench.estimators.results import failed as failed_result

__all__ = ["LEVEL", "MethodFit", "fit_axis", "fitted_avar", "agreement", "uses_allan_variance", "scaled_allan",
           "random_effects", "between_runs", "auto_inflation"]

_SCALE_LIMIT = 2.0**40  # records within 2^-40..2^40 of unit RMS are fitted as they are (no copy)


def uses_allan_variance(name: str) -> bool:
    """True if estimator ``name`` sees the record only through its Allan variance (so gaps can be
    skipped): the estimator class says so (:attr:`avbench.estimators.base.Estimator.uses_allan_variance`)."""
    from avbench import estimators

    return bool(estimators.estimator_class(name).uses_allan_variance)


@dataclass
class MethodFit:
    """One method on one axis: its typed result (:class:`avbench.estimators.results.FitResult`, SI of the
    record as given, the fitting scale undone) and how it was run."""

    name: str
    result: FitResult
    scale: float  # the record was multiplied by this before fitting
    seconds: float
    error: str | None = None  # the exception's message when the method raised (``result`` then "failed")
    run: tuple[int, int] | None = None  # (start, length) of the gap-free run used, None = whole record

    @property
    def warnings(self) -> list[str]:
        return list(self.result.warnings)

    def coefficients(self) -> dict[str, float]:
        """Q, N, B, K, R in SI as fitted (NaN where absent or non-physical), whatever their status."""
        return {c: e.fitted for c, e in self.result.coefficients.items()}

    def std_errors(self) -> dict[str, float]:
        """Standard errors (SI) where the method gives them."""
        return {c: e.std_err for c, e in self.result.coefficients.items() if math.isfinite(e.std_err)}


def scaled_allan(x, dt, starts):
    """(gap-aware octave overlapping AV of ``x * scale``, scale): the curve at unit magnitude, so that
    records of 1e300 or 1e-200 neither overflow nor underflow; divide AV by scale^2 (ADEV by scale)."""
    from avbench.estimators.allan.variance import allan_variance_gaps

    x = np.asarray(x)
    scale = _scale_of(x)
    return allan_variance_gaps(x * scale if scale != 1.0 else x, dt, starts, "octave"), scale


def _scale_of(x) -> float:
    """A power of two that brings the largest magnitude of ``x`` near 1, or 1.0 when it is already
    within 2^+-40 (two passes, no copy; squares would over/underflow at the extremes)."""
    if x.size == 0:
        return 1.0
    big = max(float(x.max()), -float(x.min()))
    if big == 0 or not math.isfinite(big) or 1 / _SCALE_LIMIT <= big <= _SCALE_LIMIT:
        return 1.0
    return 2.0 ** (-math.frexp(big)[1])


def fit_axis(x, dt, starts, methods, settings=None, progress=None) -> dict[str, MethodFit]:
    """Fit each method in ``methods`` to the SI record ``x`` with gap-free runs starting at ``starts``.

    ``settings`` maps a method name to its settings; ``progress`` (a tqdm bar or None) is advanced
    once per method. The methods share their model choices where one would make them alike on the same
    values (:mod:`avbench.estimators.selection.shared`).
    """
    from avbench.estimators.selection.shared import shared_choices

    with shared_choices():
        return _fit_methods(x, dt, starts, methods, settings, progress)


def _fit_methods(x, dt, starts, methods, settings=None, progress=None) -> dict[str, MethodFit]:
    """:func:`fit_axis` within its scope of shared choices."""
    from avbench import estimators
    from avbench.estimators.allan.variance import skip_gaps

    settings = settings or {}
    starts = np.asarray(starts, dtype=np.int64)
    x = np.asarray(x)  # a plain ndarray (a memory map's view, no copy): estimators keep this very object
    scale = _scale_of(x)
    xs = x * scale if scale != 1.0 else x
    out = {}
    for name in methods:
        t0 = time.perf_counter()
        run = None
        data = xs
        if starts.size and not uses_allan_variance(name):
            s0 = np.concatenate(([0], starts))
            lengths = np.diff(np.append(s0, xs.size))
            i = int(np.argmax(lengths))
            run = (int(s0[i]), int(lengths[i]))
            data = xs[run[0]: run[0] + run[1]]
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                est = estimators.get(name, **settings.get(name, {}))
                if starts.size and run is None:
                    with skip_gaps(data, starts):
                        est.fit(data, dt)
                else:
                    est.fit(data, dt)
                err = None
            except MemoryError:
                raise
            except Exception as e:  # one method failing on this record is a result, not a crash
                est, err = None, f"{type(e).__name__}: {str(e).splitlines()[0] if str(e) else ''}"[:300]
        seconds = time.perf_counter() - t0
        messages = sorted({f"{w.category.__name__}: {_first_line(str(w.message))}" for w in caught})
        if est is None:
            result = failed_result(name, err)
        else:
            result = est.result(LEVEL).rescaled(scale)
        fit = MethodFit(name, result.with_warnings(messages), scale, seconds, err, run)
        out[name] = fit
        if progress is not None:
            progress.update(1)
    return out


def fitted_avar(fit: MethodFit, tau, scaled: bool = False) -> np.ndarray:
    """The AV curve (SI, rad^2/s^2 or (m/s^2)^2) a fitted method stands for, as its result gives it
    (:meth:`avbench.estimators.results.FitResult.model_avar`: the exact AV of its latent model where it
    has one, else the five-term curve). With ``scaled`` the curve is that of the record as fitted
    (times ``fit.scale`` squared)."""
    if fit.error is not None:
        return np.full(np.shape(tau), np.nan)
    return fit.result.fitted_model_avar(tau) if scaled else fit.result.model_avar(tau)


#: the interval level of every result of a recording (the screen's, the files' and the yaml's)
LEVEL = 0.95
#: a warning's message is kept up to this many characters, cut at a word
_WARNING_CHARS = 1000


def _first_line(message: str) -> str:
    """The first line of a warning's message, cut at a word boundary past :data:`_WARNING_CHARS` (never
    inside a number or a word), with an ellipsis where cut."""
    line = message.splitlines()[0] if message else ""
    if len(line) <= _WARNING_CHARS:
        return line
    cut = line.rfind(" ", 0, _WARNING_CHARS)
    return line[: cut if cut > 0 else _WARNING_CHARS].rstrip(" ,;:") + " ..."


def agreement(records, dt, min_edf: float = 4.0) -> dict:
    """Do several recordings of one sensor axis have the same Allan variance?

    ``records`` is a list of ``(x, starts)``. At every octave tau that all of them reach with at least
    ``min_edf`` degrees of freedom, the log-AVs are compared by the homogeneity statistic
    ``sum_i (edf_i/2) (ln AV_i - mean)^2`` (weighted mean; ``Var ln AV ~ 2/edf``), ~ chi^2 with
    ``R - 1`` degrees of freedom when they agree. The p-value returned is the smallest over tau times
    the number of taus (Bonferroni; the taus are positively correlated, so this is conservative).
    """
    from scipy import stats

    from avbench.estimators.allan.variance import allan_variance_gaps

    avs = [allan_variance_gaps(x, dt, s, "octave") for x, s in records]
    common = set(avs[0].m.tolist())
    for a in avs[1:]:
        common &= set(a.m.tolist())
    rows = []
    for m in sorted(common):
        la, w = [], []
        for a in avs:
            i = int(np.flatnonzero(a.m == m)[0])
            if not (a.edf[i] >= min_edf and a.avar[i] > 0):
                break
            la.append(math.log(a.avar[i]))
            w.append(a.edf[i] / 2.0)
        else:
            la, w = np.array(la), np.array(w)
            mean = float(np.sum(w * la) / np.sum(w))
            T = float(np.sum(w * (la - mean) ** 2))
            rows.append((m * dt, T, float(stats.chi2.sf(T, len(avs) - 1))))
    if not rows:
        return {"p_value": None, "agree": None, "n_taus": 0, "worst_tau_s": None,
                "note": "no tau with enough clusters in every recording"}
    worst = min(rows, key=lambda r: r[2])
    p = min(1.0, worst[2] * len(rows))
    return {"p_value": p, "agree": bool(p >= 0.01), "n_taus": len(rows), "worst_tau_s": worst[0],
            "note": "chi^2 homogeneity of log AV per octave tau, Bonferroni over taus; agree = p >= 0.01"}


def random_effects(y, se, level: float = 0.95) -> dict:
    """Between-run spread of one coefficient measured on k runs: DerSimonian & Laird (1986).

    Model: y_i = mu + u_i + e_i, u_i ~ N(0, tau^2) (the sensor differs from run to run),
    e_i ~ N(0, s_i^2) (the run's own sampling error, ``se``). DerSimonian & Laird's moment estimate
    (their eq. 8 with w_i = 1/s_i^2):

    .. math:: \\hat\\tau^2 = \\max\\Big(0, \\frac{Q - (k-1)}{\\sum w_i - \\sum w_i^2 / \\sum w_i}\\Big),
              \\quad Q = \\sum w_i (y_i - \\bar y_w)^2,

    the random-effects mean mu with weights 1/(s_i^2 + tau^2) and its standard error, the interval
    of tau^2 by the Q-profile method (Viechtbauer 2007: the tau^2 at which the generalised
    Q(tau^2) = sum (y_i - mu(tau^2))^2 / (s_i^2 + tau^2) equals the chi^2_{k-1} quantiles), and
    the prediction interval of a new run's value, mu +- t_{k-2} sqrt(tau^2 + SE(mu)^2) (Higgins,
    Thompson & Spiegelhalter 2009, eq. 12). Needs k >= 2 (k >= 3 for the prediction interval).
    Where a run has no standard error (or one of zero) the spread is the runs' plain SD with a
    chi^2 interval: it then includes each run's own sampling error.
    """
    from scipy import optimize, stats

    y = np.asarray(y, dtype=float)
    se = np.asarray(se, dtype=float)
    ok = np.isfinite(y)
    y, se = y[ok], se[ok]
    k = int(y.size)
    out = {"k": k, "mean": None, "mean_se": None, "tau": None, "tau_ci": None, "cv": None, "Q": None,
           "p_heterogeneity": None, "prediction": None, "method": None, "level": level}
    if k < 2:
        out["method"] = "fewer than 2 runs with a value"
        return out
    a = (1 - level) / 2
    if not np.all(np.isfinite(se) & (se > 0)):
        mu, sd = float(y.mean()), float(y.std(ddof=1))
        lo = sd * math.sqrt((k - 1) / stats.chi2.ppf(1 - a, k - 1))
        hi = sd * math.sqrt((k - 1) / stats.chi2.ppf(a, k - 1))
        out.update(mean=mu, mean_se=sd / math.sqrt(k), tau=sd, tau_ci=(lo, hi),
                   method="SD of the runs (no within-run standard errors): includes the sampling error")
        pred_sd = sd * math.sqrt(1 + 1 / k)
    else:
        v = se**2
        w = 1 / v
        yw = float(np.sum(w * y) / np.sum(w))
        Q = float(np.sum(w * (y - yw) ** 2))
        tau2 = max(0.0, (Q - (k - 1)) / (np.sum(w) - np.sum(w**2) / np.sum(w)))

        def mu_of(t2):
            ws = 1 / (v + t2)
            return float(np.sum(ws * y) / np.sum(ws)), float(1 / math.sqrt(np.sum(ws)))

        def qgen(t2):
            m, _ = mu_of(t2)
            return float(np.sum((y - m) ** 2 / (v + t2)))

        def root(target):  # Q_gen decreases in tau^2 from Q_gen(0) = Q
            if qgen(0.0) <= target:
                return 0.0
            hi = max(tau2, float(np.var(y)), float(v.max())) * 4 + 1e-300
            while qgen(hi) > target:
                hi *= 4
            return float(optimize.brentq(lambda t: qgen(t) - target, 0.0, hi, xtol=1e-14 * hi, rtol=1e-12))

        lo2, hi2 = root(stats.chi2.ppf(1 - a, k - 1)), root(stats.chi2.ppf(a, k - 1))
        mu, mu_se = mu_of(tau2)
        out.update(mean=mu, mean_se=mu_se, tau=math.sqrt(tau2), tau_ci=(math.sqrt(lo2), math.sqrt(hi2)), Q=Q,
                   p_heterogeneity=float(stats.chi2.sf(Q, k - 1)),
                   method="DerSimonian-Laird random effects; tau interval by Q-profile")
        pred_sd = math.sqrt(tau2 + mu_se**2)
    if out["mean"]:
        out["cv"] = out["tau"] / abs(out["mean"])
    if k >= 3:
        t = float(stats.t.ppf(1 - a, k - 2))
        out["prediction"] = (out["mean"] - t * pred_sd, out["mean"] + t * pred_sd)
    return out


def between_runs(per_run: list[dict[str, MethodFit]], method: str, level: float = 0.95) -> dict:
    """Per coefficient, :func:`random_effects` of ``method``'s estimates on each run separately.

    ``per_run``: one ``{method: MethodFit}`` per recording (the same axis). Runs where the method
    failed or gives no value for a coefficient are left out of that coefficient.
    """
    from avbench.noise_models.units import COEFFICIENTS

    out = {}
    for c in COEFFICIENTS:
        ys, ss = [], []
        for fits in per_run:
            f = fits[method]
            v = f.coefficients()[c]
            if not math.isfinite(v):
                continue
            se = (f.std_errors() or {}).get(c, math.nan)
            ys.append(v)
            ss.append(se)
        out[c] = random_effects(ys, ss, level)
    return out


def auto_inflation(spread: dict, coefficient: str, level: float = 0.95) -> float | None:
    """The factor by which a filter value should exceed the pooled estimate to cover the next run.

    The upper end of the one-sided ``level`` prediction interval of a new run's value divided by
    the random-effects mean (both from :func:`random_effects` at two-sided level 2 level - 1).
    None when there are fewer than 3 runs or no positive mean.
    """
    r = spread[coefficient]
    if r["prediction"] is None or not r["mean"] or r["mean"] <= 0:
        return None
    return max(1.0, r["prediction"][1] / r["mean"])
