"""Study configuration: a small TOML file, validated completely before any work starts.

The schema -- every key, its type, default and allowed values -- is declared once in
:mod:`avbench.studies.config_schema`, which reads each table and words its errors; ``docs/CONFIG.md``
documents it with an example (a test holds the two together).
Estimators and noise terms may be plugins: a registry name, an entry point of the groups
``avbench.estimators`` / ``avbench.noise_terms``, or an import path ``"module:Class"`` (a module
beside the config file is found); ``[study] plugins`` lists modules to import first, in every
process (:mod:`avbench.noise_models.plugins`).

Errors name the file, the key and what was expected (:class:`ConfigError`), and are raised before any
work starts and before anything is written. Besides types and ranges, every gyro is simulated for a
few samples, and every estimator's settings are checked per gyro without fitting anything
(:func:`settings_problem`): against what the estimator class declares (its settings, their
constraints and relations: :func:`avbench.estimators.settings.validate_settings`, the check
``estimators.get`` and ``Estimator.fit`` make, with the same message), and against the study's record
(a ``taus`` within half the record: rejected here, not on every replicate).
"""

from __future__ import annotations

import hashlib
import json
import tomllib
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from avbench import estimators
from avbench.estimators.settings import validate_settings
from avbench.noise_models import TERM_TYPES, Gyro, presets, term_class
from avbench.noise_models.plugins import PluginError, import_module, version_of
from avbench.studies.config_schema import ESTIMATOR, GYRO, MAX_SAMPLES, ROOT, STUDY, TRUE_TERMS

__all__ = ["ConfigError", "StudyConfig", "GyroSpec", "EstimatorSpec", "load_config", "parse_config",
           "settings_problem"]


class ConfigError(ValueError):
    """A study configuration is invalid; the message names the file, key and expectation."""


@dataclass(frozen=True)
class GyroSpec:
    label: str
    gyro: Gyro
    n_samples: int
    source: dict  # the config entry as given (for hashing and reporting)
    paper_gyro: str | None = None


@dataclass(frozen=True)
class EstimatorSpec:
    label: str
    name: str
    settings: dict
    gyro_settings: dict
    x0_truth_scale: float | None = None
    paper_method: str | None = None
    #: parametric-bootstrap draws for the standard errors (0: the estimator's own, if any)
    bootstrap: int = 0
    #: the registered class; pickled with the spec, so a worker process that has not imported the
    #: module registering it (e.g. an estimator defined in a script or a test) can still build it
    cls: type | None = field(default=None, compare=False, repr=False)

    def settings_for(self, gyro: GyroSpec) -> dict:
        """The settings of this estimator on ``gyro``: ``settings`` updated by its ``gyro_settings``;
        ``terms = "true"`` (:data:`~avbench.studies.config_schema.TRUE_TERMS`) becomes the gyro's own
        term set (:attr:`Gyro.term_set <avbench.noise_models.Gyro.term_set>`); ``x0_truth_scale``
        sets ``x0`` from the truth."""
        s = dict(self.settings)
        s.update(self.gyro_settings.get(gyro.label, {}))
        if s.get("terms") == TRUE_TERMS:
            s["terms"] = gyro.gyro.term_set
        if self.x0_truth_scale is not None:
            truth = gyro.gyro.coefficients
            terms = s.get("terms", gyro.gyro.term_set)
            s["x0"] = {c: float(truth[c]) * self.x0_truth_scale for c in terms if np.isfinite(truth[c])}
        return s

    def make(self, gyro: GyroSpec) -> "avbench.estimators.Estimator":
        return estimators.get(self.cls if self.cls is not None else self.name, **self.settings_for(gyro))


@dataclass(frozen=True)
class StudyConfig:
    name: str
    seed: int
    replicates: int
    gyros: tuple[GyroSpec, ...]
    estimators: tuple[EstimatorSpec, ...]
    description: str = ""
    block_size: int = 5
    backend: str = "loky"
    scheduler: str | None = None
    paper_table: Path | None = None
    figure_gyros: tuple[str, ...] | None = None
    units: dict = field(default_factory=dict)
    path: Path | None = None
    raw: dict = field(default_factory=dict)
    #: modules named in ``[study] plugins``, imported by every process that runs the study
    plugins: tuple[str, ...] = ()
    #: code the study uses from outside avbench (plugin modules, estimator and term classes) -> version
    plugin_versions: dict = field(default_factory=dict)

    def import_plugins(self) -> None:
        """Import the ``[study] plugins`` modules (what a worker process does before its first block)."""
        for m in self.plugins:
            import_module(m, self.path.parent if self.path else None)

    def result_payload(self) -> dict:
        """Everything that determines the per-replicate results (not their count, not the backend).

        The seed, the record length, the gyros and the estimators with their settings and labels
        as written in the config; not ``replicates`` (more replicates reuse the finished blocks),
        ``block_size`` (it only names the shards), ``backend``, ``scheduler``, ``description`` or
        the paper references.
        """
        study = {k: v for k, v in self.raw.get("study", {}).items() if k in ("seed", "duration_s", "n_samples")}
        payload = {
            "study": study,
            "gyros": [{k: v for k, v in g.items() if k != "paper_gyro"} for g in self.raw.get("gyros", [])],
            "estimators": [
                {k: v for k, v in e.items() if k not in ("paper_method",)} for e in self.raw.get("estimators", [])
            ],
        }
        if self.plugin_versions:  # code from outside avbench: its name and version (absent otherwise)
            payload["plugins"] = dict(self.plugin_versions)
        return payload

    def result_key(self) -> str:
        """Hash of :meth:`result_payload`: names the shard folder ``_shards/<key>/``."""
        blob = json.dumps(self.result_payload(), sort_keys=True, default=str).encode()
        return hashlib.sha256(blob).hexdigest()[:16]


MAX_FILTER_TAPS = 100_000_000  # flicker filter memory tau_max / dt
SIMULATION_CHECK_SAMPLES = 1024  # samples each gyro is simulated for when the config is read


class _Ctx:
    def __init__(self, where: str):
        self.where = where

    def fail(self, key: str, msg: str):
        raise ConfigError(f"{self.where}: {key}: {msg}")


def _builtin(cls) -> bool:
    return cls.__module__.split(".")[0] == "avbench"


def _build_gyro(ctx: _Ctx, i: int, g: dict, search: Path | None = None) -> tuple[str, Gyro, float | None]:
    """The label, the :class:`Gyro` and the paper's record length (a preset's; None) of the gyro entry
    ``g`` (the values :data:`~avbench.studies.config_schema.GYRO` read, its arrays of pairs as tuples)."""
    key = f"gyros[{i}]"
    if g["preset"] is not None:
        try:
            info = presets.info(g["preset"])
        except (ValueError, KeyError) as e:
            ctx.fail(f"{key}.preset", str(e).strip("'\""))
        return g["label"] or info.name, info.gyro(), info.duration_s
    terms = []
    for j, t in enumerate(g["terms"]):
        tkey = f"{key}.terms[{j}]"
        if not isinstance(t, dict) or "type" not in t:
            ctx.fail(tkey, f"expected a table with 'type' (one of {', '.join(TERM_TYPES)}, or 'package.module:Class')")
        kind = t["type"]
        try:
            cls = term_class(kind, search)
        except ValueError as e:
            ctx.fail(f"{tkey}.type", str(e))
        kwargs = {k: (tuple(v) if isinstance(v, list) else v) for k, v in t.items() if k != "type"}
        try:
            terms.append(cls(**kwargs))
        except TypeError as e:
            ctx.fail(tkey, f"bad arguments for {kind}: {e}")
        except Exception as e:  # ValueError from the term, or anything the unit parser raises
            ctx.fail(tkey, f"{kind}: {e}")
    try:
        gyro = Gyro(dt=g["dt"], terms=terms, name=g["name"])
    except Exception as e:
        ctx.fail(key, str(e))
    return g["label"] or g["name"], gyro, None


def _tuplify(v):
    """TOML arrays of [value, "unit"] become tuples (the units module reads pairs)."""
    if isinstance(v, dict):
        return {k: _tuplify(x) for k, x in v.items()}
    if isinstance(v, list):
        if len(v) == 2 and isinstance(v[1], str) and isinstance(v[0], int | float) and not isinstance(v[0], bool):
            return (v[0], v[1])
        return [_tuplify(x) for x in v]
    return v


def parse_config(raw: dict, where: str = "<config>", path: Path | None = None) -> StudyConfig:
    """Validate a parsed TOML document and build the :class:`StudyConfig`.

    Each table is read by its declaration (:mod:`avbench.studies.config_schema`: keys, types, defaults,
    allowed values and their messages); then what joins the tables: presets, term classes and plugins,
    the record length of each gyro, labels, the paper table, and each estimator's settings per gyro
    (:func:`settings_problem`). Raises :class:`ConfigError` (naming ``where``, the key and what was
    expected) for anything invalid; nothing else escapes for any input a TOML file can hold.
    """
    ctx = _Ctx(where)
    ROOT.read(raw, "", ctx.fail)
    study = STUDY.read(raw["study"], "study", ctx.fail)
    search = path.parent if path else None
    plugin_versions = {}
    for j, m in enumerate(study["plugins"]):
        try:
            plugin_versions[m] = version_of(import_module(m, search))
        except PluginError as e:
            ctx.fail(f"study.plugins[{j}]", str(e))
    paper_table = paper = None
    if study["paper_table"] is not None:
        base = path.parent if path else Path.cwd()
        paper_table = (base / study["paper_table"]).resolve()
        paper = _read_paper_table(ctx, paper_table)

    gyros = []
    for i, entry in enumerate(raw["gyros"]):
        g = GYRO.read(entry, f"gyros[{i}]", ctx.fail)
        label, gyro, paper_duration = _build_gyro(ctx, i, _tuplify(g), search)
        for t in gyro.terms:
            if not _builtin(type(t)):
                plugin_versions[f"{type(t).__module__}:{type(t).__qualname__}"] = version_of(type(t))
        if study["n_samples"] is not None:
            n = int(study["n_samples"])
        else:
            duration = study["duration_s"] if study["duration_s"] is not None else paper_duration
            if duration is None:
                ctx.fail(f"gyros[{i}]", "an explicit gyro needs study.duration_s or study.n_samples")
            n = duration / gyro.dt
            if not n <= MAX_SAMPLES:
                ctx.fail(
                    "study.duration_s" if study["duration_s"] is not None else f"gyros[{i}]",
                    f"the record would have {n:.3g} samples at dt = {gyro.dt} s; expected at most {MAX_SAMPLES:,}",
                )
            n = int(round(n))
        if n < 16:
            ctx.fail(f"gyros[{i}]", f"the record has only {n} samples at dt = {gyro.dt} s; expected at least 16")
        for j, t in enumerate(gyro.terms):
            taps = getattr(t, "n_taps", None)
            if callable(taps) and taps(gyro.dt) > MAX_FILTER_TAPS:
                ctx.fail(
                    f"gyros[{i}].terms[{j}]",
                    f"filter memory of {taps(gyro.dt):,} samples (tau_max / dt); expected at most {MAX_FILTER_TAPS:,}",
                )
        spec = GyroSpec(label, gyro, n, entry, g["paper_gyro"])
        _check_simulation(ctx, f"gyros[{i}]", spec)
        gyros.append(spec)
    labels = [g.label for g in gyros]
    if len(set(labels)) != len(labels):
        ctx.fail("gyros", f"gyro labels must be unique, got {labels}")
    if paper is not None:
        known_gyros = sorted(set(paper["gyro"]))
        for i, g in enumerate(gyros):
            if g.paper_gyro is not None and g.paper_gyro not in known_gyros:
                ctx.fail(f"gyros[{i}].paper_gyro", f"{g.paper_gyro!r} is not a gyro of {paper_table.name}; "
                         f"expected one of {known_gyros}")
    elif any(g.paper_gyro is not None for g in gyros):
        ctx.fail("study.paper_table", "required when a gyro names its paper_gyro")
    for c, u in study["units"].items():
        try:
            from avbench.noise_models.units import from_si

            from_si(c, 1.0, u)
        except ValueError as e:
            ctx.fail(f"study.units.{c}", str(e))
    if study["figure_gyros"] is not None:
        unknown = [x for x in study["figure_gyros"] if x not in labels]
        if unknown:
            ctx.fail("study.figure_gyros", f"unknown gyro label(s) {unknown}; expected some of {labels}")
    from avbench.studies.figure_files import figure_name_problem

    problem = figure_name_problem(study["figure_gyros"] if study["figure_gyros"] is not None else labels)
    if problem:  # the file names, before any work
        ctx.fail("study.figure_gyros" if study["figure_gyros"] is not None else "gyros", problem)

    ests = []
    for i, entry in enumerate(raw["estimators"]):
        key = f"estimators[{i}]"
        e = ESTIMATOR.read(entry, key, ctx.fail)
        try:
            cls = estimators.estimator_class(e["name"], search)
        except ValueError as err:
            ctx.fail(f"{key}.name", str(err))
        if not _builtin(cls):
            plugin_versions[f"{cls.__module__}:{cls.__qualname__}"] = version_of(cls)
        if e["paper_method"] is not None:
            if paper is None:
                ctx.fail(f"{key}.paper_method", "needs study.paper_table (the paper's results to print beside ours)")
            methods = sorted(set(paper["method"]))
            if e["paper_method"] not in methods:
                ctx.fail(f"{key}.paper_method", f"{e['paper_method']!r} is not a method of {paper_table.name}; "
                         f"expected one of {methods}")
        gs = e["gyro_settings"]
        for gl in gs:
            if gl not in labels:
                ctx.fail(f"{key}.gyro_settings.{gl}", f"unknown gyro label; expected one of {labels}")
        scale = e["x0_truth_scale"]
        spec = EstimatorSpec(
            bootstrap=e["bootstrap"],
            label=e["label"] or e["name"],
            name=e["name"],
            settings=_tuplify(e["settings"]),
            gyro_settings=_tuplify(gs),
            x0_truth_scale=None if scale is None else float(scale),
            paper_method=e["paper_method"],
            cls=cls,
        )
        # check the settings for each gyro and build one estimator per gyro now, so bad settings fail
        # before any work (no trial fits)
        for g in gyros:
            where = f"{key}.gyro_settings.{g.label}" if g.label in gs else f"{key}.settings"
            try:
                est = spec.make(g)
            except Exception as err:
                ctx.fail(where, f"(gyro {g.label}) {err}")
            problem = settings_problem(est, g)
            if problem:
                ctx.fail(where, f"(gyro {g.label}) {problem}")
        ests.append(spec)
    elabels = [e.label for e in ests]
    if len(set(elabels)) != len(elabels):
        ctx.fail("estimators", f"estimator labels must be unique (set 'label'), got {elabels}")

    return StudyConfig(
        name=study["name"],
        seed=int(study["seed"]),
        replicates=int(study["replicates"]),
        gyros=tuple(gyros),
        estimators=tuple(ests),
        description=study["description"],
        block_size=int(study["block_size"]),
        backend=study["backend"],
        scheduler=study["scheduler"],
        paper_table=paper_table,
        figure_gyros=tuple(study["figure_gyros"]) if study["figure_gyros"] is not None else None,
        units=dict(study["units"]),
        path=path,
        raw=raw,
        plugins=tuple(study["plugins"]),
        plugin_versions=plugin_versions,
    )


def _read_paper_table(ctx: _Ctx, path: Path):
    from avbench.studies.papers import load_paper_table

    try:
        return load_paper_table(path)
    except FileNotFoundError:
        ctx.fail("study.paper_table", f"no such file {str(path)!r}; expected a CSV of the paper's results, "
                 "given relative to the study file (e.g. \"paper_tables/lv2015_tables_2_4_6.csv\")")
    except (OSError, UnicodeDecodeError) as e:
        ctx.fail("study.paper_table", f"cannot read {str(path)!r}: {e}")
    except Exception as e:  # a parser error or a table of the wrong shape
        ctx.fail("study.paper_table", f"{str(path)!r} is not a paper table: {str(e).splitlines()[0][:200]}")


_SIMULATION_SEED = 20240601


def _check_simulation(ctx: _Ctx, key: str, g: GyroSpec) -> None:
    """Simulate :data:`SIMULATION_CHECK_SAMPLES` samples of the gyro (or its whole record, if shorter),
    so that a gyro that cannot be simulated is a config error. Terms with a long filter memory (flicker
    ``tau_max``) are copied with the memory cut to that length: the record keeps the gyro's scale and
    dt, without the cost of a million-tap filter burn-in for a thousand samples."""
    import copy

    n = min(g.n_samples, SIMULATION_CHECK_SAMPLES)
    dt = g.gyro.dt
    terms = []
    for t in g.gyro.terms:
        if getattr(t, "tau_max", None) is not None and t.tau_max > n * dt:
            t = copy.copy(t)
            t.tau_max = float(n * dt)
        terms.append(t)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            with np.errstate(all="ignore"):
                Gyro(dt=dt, terms=terms, name=g.gyro.name).simulate(n, np.random.default_rng(_SIMULATION_SEED))
    except Exception as e:
        ctx.fail(key, f"cannot simulate this gyro: {type(e).__name__}: {e}")


def settings_problem(est, gyro: GyroSpec) -> str | None:
    """Why ``est`` (configured for ``gyro``) cannot run in the study, or None if it can; nothing is fitted.

    1. the settings against what the estimator's class declares (its settings, their constraints and
       relations: :func:`avbench.estimators.settings.validate_settings`, the check of ``get`` and ``fit``);
    2. against the study's record: a ``taus`` setting must give Allan-variance cluster sizes within
       half the record.

    What can only go wrong on data (a divergence, a record too short for the method) is recorded per
    replicate when the study runs, never a configuration error.
    """
    from avbench.estimators.allan.variance import cluster_sizes

    dt, n = gyro.gyro.dt, gyro.n_samples
    params = est.get_params()
    try:
        validate_settings(type(est), params)
    except ValueError as e:
        return str(e).splitlines()[0][:300]
    try:
        if "taus" in params and params["taus"] is not None:
            cluster_sizes(params["taus"], n, dt)
    except Exception as e:
        return f"{type(e).__name__}: {e}".splitlines()[0][:300]
    return None


def load_config(path, overrides: dict[str, Any] | None = None) -> StudyConfig:
    """Read and validate a study TOML file (``overrides`` update its [study] table)."""
    from avbench.recordings.files import check_path_kind

    path = Path(path)
    try:
        check_path_kind(path, expected="expected a study file (TOML)")
    except ValueError as e:
        raise ConfigError(str(e)) from None
    try:
        raw = tomllib.loads(path.read_text(encoding="utf-8-sig"))  # a BOM, as some editors save, is no text
    except tomllib.TOMLDecodeError as e:
        raise ConfigError(f"{path}: not valid TOML: {e}") from None
    except UnicodeDecodeError:
        raise ConfigError(f"{path}: not a text file") from None
    except RecursionError:
        raise ConfigError(f"{path}: nested too deeply to read; expected a study file (a few levels of tables)") from None
    if _depth(raw) > MAX_NESTING:
        raise ConfigError(f"{path}: nested {_depth(raw)} levels deep; expected at most {MAX_NESTING} "
                          "(tables of settings inside [[estimators]])")
    if overrides:
        raw.setdefault("study", {}).update(overrides)
    return parse_config(raw, where=str(path), path=path)


#: deepest nesting of tables/arrays a study file may have (settings of settings of ...)
MAX_NESTING = 12


def _depth(value) -> int:
    """Nesting depth of TOML tables and arrays, without recursion (a hostile file cannot overflow it)."""
    deepest, stack = 0, [(value, 0)]
    while stack:
        v, d = stack.pop()
        deepest = max(deepest, d)
        if deepest > MAX_NESTING:
            break
        if isinstance(v, dict):
            stack.extend((x, d + 1) for x in v.values())
        elif isinstance(v, list):
            stack.extend((x, d + 1) for x in v)
    return deepest
