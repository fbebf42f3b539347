"""The run-to-run spread of N and B that a sensor which does *not* change between runs would show:
simulated ADIS16405 gyros, the default methods against the plain-model configuration (GMWM's
``WN+GM+RW`` from ``min_m="auto"``, no sensor filter, line or resonance).

``python -m avbench.studies.real_runs_spread --out results/real``             (simulate and fit; resumable)
``python -m avbench.studies.real_runs_spread --out results/real --models --data DIR``   (the models, from the runs)
``python -m avbench.studies.real_runs_spread --out results/real --tables-only``  (the tables from the fits)
``python -m avbench.studies.real_runs_spread --out results/real --variants --axes x,y``  (what moves B's spread)

Why. On the six ADIS16405 runs (``results/real/consistency.md``) the run-to-run CV of a coefficient is a
standard deviation of six values: its relative standard error is ~1/sqrt(2 x 5) ~ 32 %, and part of it is
the sampling error of each run's fit, not the sensor. Whether the default methods give N or B a larger
run-to-run spread than the plain model is a question about the *expected* spread, which six runs cannot
answer and a simulation can: the same gyro, many records, both configurations fitted to the SAME records
(paired).

The gyro (``--models``, needs the real runs): per ADIS gyro axis, ``gmwm_filtered`` (the first default
method) is fitted to each of the six 2.8 h runs through the recordings pipeline
(:func:`avbench.studies.real_runs._records`, :func:`avbench.recordings.fit.fit_axis`), and the axis's
model is the six-run median of each latent parameter, over the runs whose fit holds that latent; a
latent is kept when a majority of the runs hold it (gyro z: ``RS``, the 17-21 Hz resonance, on runs 2-6).
Written to ``spread_models.csv`` (SI values), which the simulation reads: the simulation itself needs no
real data, and its tables depend only on that file, :data:`SEED` and the code.

The simulation: replicate ``r`` of axis ``a`` (index in :data:`AXES`) is :data:`N_SAMPLES` samples at
:data:`DT` (2.78 h at 100 Hz, as the runs) drawn from the axis model with
:func:`avbench.studies.seeding.replicate_rng` ``(SEED, a, r)``; every fit in :data:`FITS` runs on it through
:func:`~avbench.recordings.fit.fit_axis` (as ``avbench estimate``). ``FITS``: the default methods of
``avbench estimate`` (:data:`avbench.estimators.base.DEFAULT_METHODS`: ``gmwm_filtered``,
``gmwm_despiked``), ``nnls_rel``, and the plain-model configuration (``gmwm`` with its defaults --
``WN+GM+RW``, ``min_m="auto"``, no line, no resonance --, and ``gmwm_despiked`` with those settings,
labelled ``gmwm_despiked_plain``). One shard per (axis, replicate) under
``OUT/_shards/spread/`` (git-ignored); a rerun resumes. Writes ``spread_fits.csv`` (one row per axis x
replicate x fit x coefficient: value, standard error, flag, poor fit, shortest cluster size, resonance
kept; the shards also hold each fit's CPU seconds, left out here: the tables depend only on the seed) and,
by :func:`summary` / :func:`paired`, ``spread.csv`` / ``spread.md``: per axis, fit and
coefficient the mean, the sampling SD and CV over the replicates with standard errors (bootstrap over
replicates, :data:`BOOT` resamples from :data:`SEED`), the CV a set of six runs would show on average
(c4(6) x CV) with its 95 % range (chi-square, 5 dof), the median standard error the fit claims; and
``spread_paired.csv`` (the first table of ``spread.md``): per axis, coefficient and default-method pair
the paired difference of the CVs (default - plain) with its bootstrap standard error and 95 % interval,
the 95 % range of that difference as six runs show it (random sets of six replicates), and the real
runs' CVs of the two fits from ``OUT/consistency.csv`` with the share of simulated six-run sets whose
difference reaches the real one.

``--variants`` (gyro x and y, the same records): the first default method from fixed cut-offs (:data:`VARIANTS`:
``min_m=16``, the shorter of ``gmwm``'s own choices, 16 or 32; ``min_m=2``, the real x runs'), and with the
filter's time constant given at the axis model's own (``filter_tf``), paired with ``gmwm_filtered`` and ``gmwm``
(:data:`VARIANT_PAIRS`): whether a difference of B's spread comes from the scales added, from fitting tf, or
from the model; writes ``spread_variants.csv`` / ``.md`` and ``spread_variants_fits.csv``.

``--tables-only`` (with or without ``--variants``) writes the tables from the fits alone (:func:`fit_rows`): the
shards where there are any, else the committed ``spread_fits.csv`` / ``spread_variants_fits.csv`` (the same
numbers; the shards are not kept), which are then left as they are. The fits ``--variants`` pairs with are
read the same way.

``--asymptotic --axes x,y`` (no simulation, seconds): what the large-sample theory says B's and N's spread is for the
designs the variants compare (:func:`asymptotic`): the efficient-GMM standard errors of the axis model's
parameters, :math:`(D^T\\Omega^{-1}D)^{-1}`, with the exact covariance :math:`\\Omega` of the AV under the
axis model (:func:`avbench.estimators.allan.covariance.av_covariance`) and the model's exact Jacobian ``D``;
writes ``spread_asymptotic.csv`` / ``.md``. It says whether the filter's parameter costs B information
(it does not: the same standard error to 4 digits) or whether a difference of the simulated spreads is a
finite-sample one.

Cost, measured (2 cores shared with other jobs, load 5-6, niced): one replicate of the three axes with
the five fits ~50-60 s wall (gyro z ~25-30 s: the resonance choice; x and y ~12-15 s).
"""

from __future__ import annotations

import argparse
import math
import os
import time
from pathlib import Path

import numpy as np
import pandas as pd

from avbench.estimators.results import VALUE_STATUSES
from avbench.studies.real_runs import _markdown
from avbench.studies.real_runs import _round as _round_to

__all__ = ["AXES", "FITS", "PAIRS", "SEED", "axis_models", "model_gyro", "replicate_rows", "fit_rows", "summary",
           "paired", "asymptotic", "main"]

AXES = ("x", "y", "z")
N_SAMPLES = 1_000_000  #: samples per simulated run (the ADIS16405 runs' length)
DT = 0.01  #: s (100 Hz, as the runs)
SEED = 24_2026  #: the study's seed (replicates and bootstrap)
BOOT = 2000  #: bootstrap resamples of the replicates for standard errors
COEFS = ("N", "B")  #: the coefficients whose run-to-run CV is compared (K is written too)
#: the plain model: ``gmwm``'s defaults (``WN+GM+RW`` from ``min_m="auto"``, no line, no resonance, no bias evidence)
_PLAIN = {"model": "WN+GM+RW", "min_m": "auto", "lines": "model", "resonance": "model", "bias_evidence": False}
#: label -> (estimator name, settings): the default methods, ``nnls_rel``, and the plain-model configuration
FITS = {
    "gmwm_filtered": ("gmwm_filtered", {}),
    "gmwm_despiked": ("gmwm_despiked", {}),
    "nnls_rel": ("nnls_rel", {}),
    "gmwm": ("gmwm", {}),
    "gmwm_despiked_plain": ("gmwm_despiked", dict(_PLAIN)),
}
#: (default method, its plain-model counterpart): ``gmwm_filtered`` against ``gmwm`` (WN+GM+RW), and
#: ``gmwm_despiked`` against the same despiking on the plain model
PAIRS = (("gmwm_filtered", "gmwm"), ("gmwm_despiked", "gmwm_despiked_plain"))


def _tf_held(models: pd.DataFrame, axis: str) -> tuple[str, dict]:
    """The first default method with the filter's time constant given (``filter_tf``) at the axis model's own:
    does fitting tf cost B's spread?"""
    tf = models[(models.axis == axis) & (models.latent == "FW") & (models.parameter == "tf")]["value"]
    return "gmwm_filtered", {"filter_tf": float(tf.iloc[0])}


#: what makes B's spread differ between the first default method and the plain model (``--variants``, gyro
#: x and y): the default model from the cut-off ``gmwm`` chooses (m >= 16: the scales it adds, or the
#: model?), from m = 2 (the cut-off ``gmwm_filtered`` keeps on the real x runs), with tf held, and ``gmwm``
#: from m = 16 (its own choice is 16 or 32): ``FW`` against ``WN`` on the same scales
VARIANTS = {
    "gmwm_filtered_m16": ("gmwm_filtered", {"min_m": 16}),
    "gmwm_filtered_m2": ("gmwm_filtered", {"min_m": 2}),
    "gmwm_m16": ("gmwm", {"min_m": 16}),
    "gmwm_filtered_tf_held": _tf_held,
}
VARIANT_PAIRS = (("gmwm_filtered_m16", "gmwm"), ("gmwm_filtered", "gmwm_filtered_m16"),
                 ("gmwm_filtered_m2", "gmwm"), ("gmwm_filtered", "gmwm_filtered_m2"),
                 ("gmwm_filtered_m16", "gmwm_m16"), ("gmwm_m16", "gmwm"),
                 ("gmwm_filtered", "gmwm_filtered_tf_held"), ("gmwm_filtered_tf_held", "gmwm"))
SIG = 6  # significant digits written


def _round(v):
    return _round_to(v, SIG)


# -- the gyro ------------------------------------------------------------------------------------------------
def axis_models(data: Path, method: str = "gmwm_filtered") -> pd.DataFrame:
    """The six-run median latent model of each ADIS16405 gyro axis (module docstring): one row per axis x
    latent x parameter, ``value`` in SI (rad/s-based; time constants in s, frequencies in Hz), ``runs``
    holding the latent, and the per-run values."""
    from avbench.recordings.fit import fit_axis
    from avbench.studies.real_runs import _GROUP, _records

    per_axis: dict = {}
    for rec, sensor, axis, x, timing in _records(data):
        if _GROUP[rec] != "adis16405" or sensor != "gyro":
            continue
        fit = fit_axis(x, timing.dt, timing.starts, [method])[method]
        if fit.error is not None or fit.result.parameters is None:
            raise RuntimeError(f"{method} failed on {rec} gyro {axis}: {fit.result.failure or 'no latent model'}")
        si = fit.result.parameters  # SI: the scales divided by the fitting scale, time constants and frequencies as they are
        per_axis.setdefault(axis, []).append((rec, si))
        print(f"{rec} gyro {axis}: " + " ".join(f"{k}={v:.4g}" for k, v in si.items()), flush=True)
    return median_model(per_axis)


def median_model(per_axis: dict) -> pd.DataFrame:
    """``{axis: [(run, {"LAT.param": SI value})]}`` -> the :func:`axis_models` table: a latent is kept when a
    majority of the runs hold it, each of its parameters is the median over the runs that hold it."""
    from avbench.estimators.likelihood.gmwm import LATENTS, parse_model

    rows = []
    for axis, runs in per_axis.items():
        count: dict = {}
        for _, si in runs:
            for lat in {k.split(".")[0] for k in si}:
                count[lat] = count.get(lat, 0) + 1
        for lat in parse_model([lat for lat, c in count.items() if 2 * c > len(runs)]):
            for p in LATENTS[lat][0]:
                key = f"{lat}.{p}"
                vals = [si[key] for _, si in runs if key in si]
                rows.append({"axis": axis, "latent": lat, "parameter": p, "value": _round(float(np.median(vals))),
                             "runs": len(vals), "per_run": " ".join(f"{v:.5g}" for v in vals)})
    return pd.DataFrame(rows)


def model_gyro(models: pd.DataFrame, axis: str, dt: float = DT):
    """The :class:`avbench.noise_models.Gyro` of ``axis`` in a :func:`axis_models` table."""
    from avbench.estimators.likelihood.gmwm import LATENTS, build_gyro, parse_model

    sub = models[models.axis == axis]
    if sub.empty:
        raise ValueError(f"axis {axis!r}: not in the model table (axes there: {sorted(set(models.axis))})")
    latents = parse_model(list(dict.fromkeys(sub.latent)))
    value = {f"{r.latent}.{r.parameter}": float(r.value) for r in sub.itertuples()}
    return build_gyro(latents, [value[f"{lat}.{p}"] for lat in latents for p in LATENTS[lat][0]], dt)


# -- the simulation ------------------------------------------------------------------------------------------
def replicate_rows(models: pd.DataFrame, axis: str, replicate: int, fits=None, n_samples: int = N_SAMPLES,
                   seed: int = SEED) -> list[dict]:
    """Every fit of ``fits`` (default :data:`FITS`: label -> (estimator name, settings), or a function of the
    model table and the axis returning that) on replicate ``replicate`` of ``axis``: one row per fit x
    coefficient (N, B, K in the display units deg/sqrt(h), deg/h, deg/h^1.5)."""
    from avbench.noise_models.units import DISPLAY_UNITS, from_si
    from avbench.recordings.fit import fit_axis
    from avbench.recordings.report import coefficient_flags
    from avbench.studies.seeding import replicate_rng

    fits = FITS if fits is None else fits
    x = model_gyro(models, axis).simulate(n_samples, replicate_rng(seed, AXES.index(axis), replicate))
    rows = []
    for label, spec in fits.items():
        name, settings = spec(models, axis) if callable(spec) else spec
        t0 = time.process_time()
        fit = fit_axis(x, DT, np.zeros(0, dtype=np.int64), [name], {name: settings})[name]
        cpu = time.process_time() - t0
        check, choice = fit.result.fit_check, fit.result.model_choice
        coefs, se, flags = fit.coefficients(), fit.std_errors(), coefficient_flags(fit)
        rs = (choice.get("resonance_test") or {}).get("included", False)
        for c in ("N", "B", "K"):
            unit = DISPLAY_UNITS["gyro"][c]
            s = se.get(c, math.nan)
            rows.append({"axis": axis, "replicate": replicate, "fit": label, "coefficient": c, "unit": unit,
                         "value": _round(from_si(c, coefs[c], unit)),
                         "std_err": _round(from_si(c, s, unit)) if np.isfinite(s) else math.nan,
                         "flag": flags[c], "poor_fit": bool(check.poor_fit),
                         "fit_pvalue": _round(check.pvalue), "min_m": choice.get("min_m", math.nan),
                         "resonance": bool(rs), "failed": fit.error is not None, "cpu_s": round(cpu, 2)})
    return rows


def simulate(models: pd.DataFrame, out: Path, replicates: int, axes=AXES, fits=None, kind: str = "spread") -> pd.DataFrame:
    """Replicates 0 .. ``replicates``-1 of every axis (replicate-major, so that a stopped run has the
    same number on each axis), one shard per (axis, replicate) under ``OUT/_shards/<kind>``; shards
    already there are kept."""
    shards = out / "_shards" / kind
    shards.mkdir(parents=True, exist_ok=True)
    for r in range(replicates):
        for axis in axes:
            p = shards / f"{axis}_{r:04d}.csv"
            done = pd.read_csv(p) if p.exists() else None
            todo = {k: v for k, v in (FITS if fits is None else fits).items() if done is None or k not in set(done.fit)}
            if not todo:
                continue
            t0 = time.time()
            rows = pd.concat([done, pd.DataFrame(replicate_rows(models, axis, r, todo))], ignore_index=True)
            tmp = p.with_suffix(".tmp")
            rows.to_csv(tmp, index=False)
            os.replace(tmp, p)
            b = rows[rows.coefficient == "B"].set_index("fit")
            print(f"{axis} r{r}: {time.time() - t0:.0f} s wall; B " + " ".join(
                f"{k}={v:.4g}" for k, v in b["value"].items()), flush=True)
    return collect(out, kind)


def collect(out: Path, kind: str = "spread") -> pd.DataFrame:
    """The shards as one table (axis, replicate, fit, coefficient order)."""
    parts = sorted((out / "_shards" / kind).glob("*.csv"))
    if not parts:
        raise SystemExit(f"real_runs_spread: no shards under {out / '_shards' / kind}")
    df = pd.concat([pd.read_csv(p) for p in parts], ignore_index=True)
    rank = df["fit"].map({f: i for i, f in enumerate({**FITS, **VARIANTS})})
    return (df.assign(_rank=rank).sort_values(["axis", "replicate", "_rank", "coefficient"], kind="stable")
            .drop(columns="_rank").reset_index(drop=True))


#: kind of shards -> the table of their fits written under OUT (the shards are not kept)
FIT_TABLES = {"spread": "spread_fits.csv", "variants": "spread_variants_fits.csv"}


def fit_rows(out: Path, kind: str = "spread") -> tuple[pd.DataFrame, bool]:
    """The fits of ``kind`` and whether they come from the shards: the shards under ``OUT/_shards/<kind>``
    where there are any (:func:`collect`), else the table written from them (:data:`FIT_TABLES`), so that
    the summary tables regenerate on a clone that holds only the committed fits."""
    if any((out / "_shards" / kind).glob("*.csv")):
        return collect(out, kind), True
    table = out / FIT_TABLES[kind]
    if not table.exists():
        raise SystemExit(f"real_runs_spread: no shards under {out / '_shards' / kind} and no {table}")
    return pd.read_csv(table), False


# -- the summary ---------------------------------------------------------------------------------------------
def _c4(n: int) -> float:
    """E[s] / sigma for a normal sample of size n."""
    return math.sqrt(2.0 / (n - 1)) * math.exp(math.lgamma(n / 2) - math.lgamma((n - 1) / 2))


def _cv(v: np.ndarray) -> np.ndarray:
    """CV (%) along the last axis (SD with ddof 1 over the mean)."""
    return 100 * np.std(v, axis=-1, ddof=1) / np.mean(v, axis=-1)


def _boot_index(n: int, seed: int = SEED) -> np.ndarray:
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(99, n))).integers(0, n, (BOOT, n))


def _wide(df: pd.DataFrame, coef: str, axis: str, ok_only: bool = False) -> pd.DataFrame:
    """Replicates x fits of one coefficient on one axis; with ``ok_only`` a value flagged (e.g. "not
    resolved": the user gets an interval, not a value) is left out (NaN)."""
    sub = df[(df.axis == axis) & (df.coefficient == coef)]
    if ok_only:
        sub = sub.assign(value=sub["value"].where(sub["flag"].isin(VALUE_STATUSES)))
    return sub.pivot(index="replicate", columns="fit", values="value")


def summary(df: pd.DataFrame, runs: int = 6, truth_table: dict | None = None) -> pd.DataFrame:
    """Per axis, fit and coefficient: replicates, mean, sampling SD and CV with bootstrap standard errors,
    the expected CV of ``runs`` runs (c4(runs) x CV, normal values) and its 95 % range (chi-square with
    runs - 1 dof), the median claimed standard error and SD / SE, poor fits, values flagged, failures."""
    from scipy.stats import chi2

    out = []
    lo, hi = (math.sqrt(chi2.ppf(q, runs - 1) / (runs - 1)) for q in (0.025, 0.975))
    for (axis, fit, coef), g in df.groupby(["axis", "fit", "coefficient"], sort=False):
        v = g["value"].to_numpy(dtype=float)
        v = v[np.isfinite(v)]
        if v.size < 3:
            continue
        ok = g["value"].to_numpy(dtype=float)[g["flag"].isin(VALUE_STATUSES).to_numpy() & np.isfinite(g["value"].to_numpy(dtype=float))]
        b = v[_boot_index(v.size)]
        sd, mean, cv = float(np.std(v, ddof=1)), float(np.mean(v)), float(_cv(v))
        se = np.nanmedian(g["std_err"].to_numpy(dtype=float)) if np.isfinite(g["std_err"]).any() else math.nan
        t = (truth_table or {}).get((axis, coef), math.nan)
        out.append({"axis": axis, "fit": fit, "coefficient": coef, "unit": g["unit"].iloc[0], "replicates": int(v.size),
                    "truth": _round(t), "mean": _round(mean), "mean_se": _round(sd / math.sqrt(v.size)),
                    "sd": _round(sd), "sd_se": _round(float(np.std(np.std(b, axis=1, ddof=1), ddof=1))),
                    "cv_pct": _round(cv), "cv_se": _round(float(np.std(_cv(b), ddof=1))),
                    f"cv{runs}_expected_pct": _round(_c4(runs) * cv),
                    f"cv{runs}_low_pct": _round(lo * cv), f"cv{runs}_high_pct": _round(hi * cv),
                    "median_se": _round(se), "sd_over_se": _round(sd / se) if np.isfinite(se) and se > 0 else math.nan,
                    "poor_fits": int(g["poor_fit"].sum()), "flagged": int((~g["flag"].isin(VALUE_STATUSES)).sum()),
                    "cv_ok_pct": _round(float(_cv(ok))) if ok.size >= 3 else math.nan,
                    "failed": int(g["failed"].sum())})
    return pd.DataFrame(out)


def paired(df: pd.DataFrame, pairs=PAIRS, coefs=COEFS, real: pd.DataFrame | None = None, runs: int = 6,
           ok_only: bool = False) -> pd.DataFrame:
    """Per axis, coefficient and (default, plain) pair -- the first of a pair the design nearer the default
    methods, the second the one nearer the plain model (:data:`PAIRS`, :data:`VARIANT_PAIRS`) --, on the
    replicates both fitted: the two CVs, their difference default - plain with its bootstrap standard error and
    95 % percentile interval (replicates resampled together: the pairing is kept), the ratio of the sampling SDs
    and the correlation of the two fits' values; then what ``runs`` runs show: the 95 % range of the difference
    of the two CVs computed on ``runs`` replicates (:data:`BOOT` random sets of ``runs`` distinct replicates,
    the same records fitted both ways), and, given ``real`` (``consistency.csv`` of the real runs), the CVs the
    real runs gave for the two fits where both are methods there (``real_cv_default``, ``real_cv_plain``) and
    the share of simulated sets of ``runs`` whose difference is at least the real one (``p_real``). ``ok_only``:
    only the replicates on which neither fit's value is flagged (``values`` "both ok"; else "all", as
    ``consistency.csv`` counts every finite value)."""
    cons = None
    if real is not None:
        cons = real[real.sensor == "gyro"].set_index(["axis", "method", "coefficient"])["cv_pct"]
    out = []
    for axis in sorted(set(df.axis), key=AXES.index):
        for coef in coefs:
            w = _wide(df, coef, axis, ok_only)
            for default, plain in pairs:
                if default not in w or plain not in w:
                    continue
                ab = w[[default, plain]].dropna().to_numpy(dtype=float).T  # 2 x replicates
                if ab.shape[1] < 3:
                    continue
                idx = _boot_index(ab.shape[1])
                cv = _cv(ab)
                d = _cv(ab[0][idx]) - _cv(ab[1][idx])
                out.append({"axis": axis, "coefficient": coef, "default": default, "plain": plain,
                            "values": "both ok" if ok_only else "all", "replicates": ab.shape[1],
                            "cv_default_pct": _round(float(cv[0])), "cv_plain_pct": _round(float(cv[1])),
                            "diff_pct": _round(float(cv[0] - cv[1])), "diff_se": _round(float(np.std(d, ddof=1))),
                            "diff_low": _round(float(np.quantile(d, 0.025))),
                            "diff_high": _round(float(np.quantile(d, 0.975))),
                            "sd_ratio": _round(float(np.std(ab[0], ddof=1) / np.std(ab[1], ddof=1))),
                            "correlation": _round(float(np.corrcoef(ab)[0, 1]))})
                if ab.shape[1] >= 2 * runs:  # sets of `runs` out of at least twice as many
                    sets = _six_sets(ab.shape[1], runs)
                    d6 = _cv(ab[0][sets]) - _cv(ab[1][sets])
                else:
                    d6 = np.full(1, math.nan)
                real_default = cons.get((axis, default, coef), math.nan) if cons is not None else math.nan
                real_plain = cons.get((axis, plain, coef), math.nan) if cons is not None else math.nan
                real_d = real_default - real_plain
                out[-1].update({f"diff{runs}_low": _round(float(np.quantile(d6, 0.025))),
                                f"diff{runs}_high": _round(float(np.quantile(d6, 0.975))),
                                "real_cv_default": real_default, "real_cv_plain": real_plain,
                                "p_real": _round(float(np.mean(d6 >= real_d)))
                                if np.isfinite(real_d) and np.isfinite(d6).all() else math.nan})
    return pd.DataFrame(out)


def _six_sets(n: int, runs: int, seed: int = SEED) -> np.ndarray:
    """:data:`BOOT` random sets of ``runs`` distinct replicates out of ``n`` (rows of an index array)."""
    rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(98, n, runs)))
    return np.argsort(rng.random((BOOT, n)), axis=1)[:, :runs]


def truth_table(models: pd.DataFrame) -> dict:
    """(axis, coefficient) -> the axis model's own N, B, K in display units (B: B_equiv of its Gauss-Markov
    term, as GMWM reports it; :attr:`avbench.noise_models.Gyro.coefficients`)."""
    from avbench.noise_models.units import DISPLAY_UNITS, from_si

    out = {}
    for axis in sorted(set(models.axis)):
        c = model_gyro(models, axis).coefficients
        for k in ("N", "B", "K"):
            out[(axis, k)] = from_si(k, float(c[k]), DISPLAY_UNITS["gyro"][k])
    return out


#: the designs of :func:`asymptotic`: label -> (the model: "axis" = the axis model's own latents, or a
#: latent string whose white term replaces the axis model's; shortest cluster size)
ASYMPTOTIC_DESIGNS = {
    "default model, every octave": ("axis", 1),
    "default model, m >= 2": ("axis", 2),
    "default model, m >= 16": ("axis", 16),
    "WN+GM+RW, m >= 16 (plain)": ("WN+GM+RW", 16),
}


def asymptotic(models: pd.DataFrame, axes=("x", "y"), n_samples: int = N_SAMPLES, dt: float = DT,
               min_clusters: int = 8) -> pd.DataFrame:
    """Large-sample standard errors of B and N (per cent of the value) for each design of
    :data:`ASYMPTOTIC_DESIGNS` on each axis model: efficient GMM on the octave AVs with at least
    ``min_clusters`` clusters from the design's shortest cluster size on, :math:`V = (D^T\\Omega^{-1}D)^{-1}`,
    :math:`\\Omega` the exact AV covariance under the axis model (the truth), ``D`` the design model's
    Jacobian in log-parameters at the axis model's values (for ``WN+GM+RW`` on an ``FW`` axis: the same
    values without the filter's time constant, which the octaves from m = 16 on barely see: AV 2.6 % below the
    white line at the first). B is proportional to the Gauss-Markov sigma (B_equiv), so its relative standard
    error is sigma's log-scale one; N's is its white latent's."""
    from avbench.estimators.allan.covariance import av_covariance
    from avbench.estimators.likelihood.gmwm import LATENTS, _LatentAV, parse_model

    rows = []
    for axis in axes:
        sub = models[models.axis == axis]
        truth = model_gyro(models, axis, dt)
        own = parse_model(list(dict.fromkeys(sub.latent)))
        value = {f"{r.latent}.{r.parameter}": float(r.value) for r in sub.itertuples()}
        white = next(lat for lat in own if lat in ("WN", "FW"))
        m_all = 2.0 ** np.arange(int(math.log2(n_samples // min_clusters)) + 1)
        for label, (model, min_m) in ASYMPTOTIC_DESIGNS.items():
            latents = own if model == "axis" else parse_model(model)
            vals = []
            for lat in latents:
                src = white if lat in ("WN", "FW") else lat
                vals += [value[f"{src}.{p}"] for p in LATENTS[lat][0]]
            m = m_all[m_all >= min_m]
            omega = av_covariance(truth, m, n_samples, reuse=False)
            D = _LatentAV(latents, m * dt, dt, 2.0 * n_samples * dt).jacobian(np.log(vals))
            V = np.linalg.inv(D.T @ np.linalg.solve(omega, D))
            names = [f"{lat}.{p}" for lat in latents for p in LATENTS[lat][0]]
            own_white = next(lat for lat in latents if lat in ("WN", "FW"))
            se = {c: 100 * math.sqrt(V[i, i]) for c, i in (("B", names.index("GM.sigma")),
                                                           ("N", names.index(f"{own_white}.N")))}
            rows.append({"axis": axis, "design": label, "model": "+".join(latents), "min_m": int(min_m),
                         "n_scales": int(m.size), "se_B_pct": _round(se["B"]), "se_N_pct": _round(se["N"])})
    return pd.DataFrame(rows)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default="results/real", help="output folder")
    ap.add_argument("--models", action="store_true",
                    help="fit the six ADIS runs and write OUT/spread_models.csv (needs --data or $AVBENCH_REAL_DATA)")
    ap.add_argument("--data", default=os.environ.get("AVBENCH_REAL_DATA"), help="folder of the recordings (--models)")
    ap.add_argument("--replicates", type=int, default=64, help="simulated runs per axis (default 64, as committed)")
    ap.add_argument("--axes", default=",".join(AXES), help="comma-separated gyro axes")
    ap.add_argument("--variants", action="store_true",
                    help="instead: the VARIANTS fits on the same simulated records (with --axes x,y); "
                         "writes OUT/spread_variants*.csv/md")
    ap.add_argument("--tables-only", action="store_true",
                    help="only the tables, from the shards under OUT/_shards, else from OUT's committed fit tables")
    ap.add_argument("--asymptotic", action="store_true",
                    help="instead: the large-sample standard errors of B and N for the variants' designs (seconds); "
                         "writes OUT/spread_asymptotic.csv/md")
    args = ap.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    if args.models:
        if not args.data:
            raise SystemExit("real_runs_spread --models: give --data DIR or set AVBENCH_REAL_DATA")
        axis_models(Path(args.data)).to_csv(out / "spread_models.csv", index=False)
        return 0
    models = pd.read_csv(out / "spread_models.csv")
    axes = [a for a in args.axes.split(",") if a]
    bad = [a for a in axes if a not in AXES]
    if bad:
        raise SystemExit(f"real_runs_spread: --axes: expected some of {','.join(AXES)}, got {','.join(bad)}")
    if args.asymptotic:
        a = asymptotic(models, axes)
        a.to_csv(out / "spread_asymptotic.csv", index=False)
        (out / "spread_asymptotic.md").write_text(_markdown(a))
        return 0
    if args.variants:
        fits, _ = fit_rows(out)  # the FITS of the same records
        if args.tables_only:
            var, from_shards = fit_rows(out, "variants")
        else:
            var, from_shards = simulate(models, out, args.replicates, axes, VARIANTS, "variants"), True
        if from_shards:
            var = var.drop(columns="cpu_s")  # CPU seconds: in the shards only
            var.to_csv(out / FIT_TABLES["variants"], index=False)
        both = pd.concat([fits[fits.fit.isin(["gmwm_filtered", "gmwm"])], var], ignore_index=True)
        both = both[both.set_index(["axis", "replicate"]).index.isin(var.set_index(["axis", "replicate"]).index)]
        pv = pd.concat([paired(both, VARIANT_PAIRS), paired(both, VARIANT_PAIRS, ok_only=True)], ignore_index=True)
        pv.to_csv(out / "spread_variants.csv", index=False)
        (out / "spread_variants.md").write_text(_markdown(pv) + "\n" + _markdown(summary(var, truth_table=truth_table(models))))
        return 0
    df, from_shards = fit_rows(out) if args.tables_only else (simulate(models, out, args.replicates, axes), True)
    if from_shards:
        df = df.drop(columns="cpu_s")  # CPU seconds: in the shards only
        df.to_csv(out / FIT_TABLES["spread"], index=False)
    s = summary(df, truth_table=truth_table(models))
    real = pd.read_csv(out / "consistency.csv") if (out / "consistency.csv").exists() else None
    p = pd.concat([paired(df, real=real), paired(df, real=real, ok_only=True)], ignore_index=True)
    s.to_csv(out / "spread.csv", index=False)
    p.to_csv(out / "spread_paired.csv", index=False)
    (out / "spread.md").write_text(_markdown(p) + "\n" + _markdown(s))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
