"""The study config's schema: each table's keys with their type, default and allowed values, declared
once (:data:`ROOT`, :data:`STUDY`, :data:`GYRO`, :data:`ESTIMATOR`).

:meth:`Table.read` parses a table of a TOML document from its declaration: it refuses an unknown key
naming the allowed ones, a value of the wrong type, a missing required key and a value outside what
its key allows, each with the message the declaration words, and returns every declared key (the
value given, else its default). What depends on more than one table (a gyro label an estimator's
``gyro_settings`` names, a preset, a plugin's import) is checked by :func:`avbench.studies.config.parse_config`
after the tables are read. ``docs/CONFIG.md`` documents the same keys (a test holds them together).

>>> def fail(key, problem):
...     raise ValueError(f"{key}: {problem}")
>>> STUDY.read({"name": "s", "seed": 1, "replicates": 3}, "study", fail)["block_size"]
5
>>> STUDY.read({"name": "s", "seed": 1, "replicates": 0}, "study", fail)
Traceback (most recent call last):
...
ValueError: study.replicates: expected an integer >= 1, got 0
>>> GYRO.read({"preset": "SRS2000", "colour": "red"}, "gyros[0]", fail)
Traceback (most recent call last):
...
ValueError: gyros[0].colour: unknown key; expected one of dt, label, name, paper_gyro, preset, terms
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

__all__ = ["Key", "Relation", "Table", "ROOT", "STUDY", "GYRO", "ESTIMATOR", "TRUE_TERMS", "REQUIRED", "NUMBER",
           "MAX_REPLICATES", "MAX_SAMPLES"]

#: the default of a key that must be given
REQUIRED = object()
#: the type of a key that takes an integer or a float
NUMBER = (int, float)
_TYPE_NAMES = {str: "a string", int: "an integer", NUMBER: "a number", list: "an array", dict: "a table"}

#: upper limits that keep an absurd config from exhausting memory before any useful work
MAX_REPLICATES = 1_000_000
MAX_SAMPLES = 1_000_000_000  # 8 GB per record


@dataclass(frozen=True)
class Key:
    """One key of a table: its ``kind`` (a type of :data:`_TYPE_NAMES`; ``object``: any), its
    ``default`` (:data:`REQUIRED`: it must be given, ``missing`` saying so), the integers it allows
    (``minimum``, ``maximum``), the values it allows (``allowed``), a ``rule`` (value -> the problem,
    worded after the key, or None), and ``items``: the key of each element of an array or value of a
    table (reported as ``key[i]`` / ``key.name``)."""

    kind: Any
    default: Any = None
    minimum: int | None = None
    maximum: int | None = None
    allowed: tuple | None = None
    rule: Callable[[Any], str | None] | None = None
    missing: str | Callable[[], str] = "required"
    items: "Key | None" = None
    #: the type in words where it is not :data:`_TYPE_NAMES`'s
    kind_text: str | None = None

    @property
    def required(self) -> bool:
        return self.default is REQUIRED

    def type_problem(self, v) -> str | None:
        """Why ``v`` is not of this key's kind (a bool is no number), or None."""
        if self.kind is object:
            return None
        numeric = self.kind in (int, NUMBER)
        if isinstance(v, self.kind) and not (numeric and isinstance(v, bool)):
            return None
        return f"expected {self.kind_text or _TYPE_NAMES[self.kind]}, got {v!r}"

    def value_problem(self, v) -> str | None:
        """Why ``v`` (of this key's kind) is not allowed, or None."""
        if self.minimum is not None and v < self.minimum:
            return f"expected an integer >= {self.minimum}, got {v!r}"
        if self.maximum is not None and v > self.maximum:
            return f"expected an integer <= {self.maximum:,}, got {v!r}"
        if self.allowed is not None and v not in self.allowed:
            words = " or ".join(map(repr, self.allowed)) if len(self.allowed) <= 2 else \
                "one of " + ", ".join(map(repr, self.allowed))
            return f"expected {words}, got {v!r}"
        return self.rule(v) if self.rule is not None else None

    def problems(self, v, key: str):
        """``(key, problem)`` of ``v`` and, for an array or table with ``items``, of each element."""
        p = self.type_problem(v) or self.value_problem(v)
        if p:
            yield key, p
            return
        if self.items is not None:
            pairs = enumerate(v) if isinstance(v, list) else v.items()
            for name, x in pairs:
                yield from self.items.problems(x, f"{key}[{name}]" if isinstance(v, list) else f"{key}.{name}")


@dataclass(frozen=True)
class Relation:
    """A rule between the keys of one table: ``check(values)`` (every declared key, given or default)
    gives the problem or None; it is reported under ``key`` (a key of the table, or "" for the table)."""

    key: str
    check: Callable[[dict], str | None]


@dataclass(frozen=True)
class Table:
    """The keys of one table, in the order they are checked, and the relations between them."""

    keys: dict[str, Key]
    relations: tuple[Relation, ...] = ()

    def read(self, table, prefix: str, fail: Callable[[str, str], Any]) -> dict:
        """Every declared key of ``table`` (a mapping from the TOML document; the value given, else the
        key's default, None where it has none), or ``fail(key, problem)`` (which raises) for the first
        problem: not a table, an unknown key or a value of the wrong type (in the table's order), a
        required key missing, a value its key does not allow, a relation broken (in declared order)."""
        if not isinstance(table, dict):
            fail(prefix, f"expected a table, got {type(table).__name__}")

        def key(k):
            return f"{prefix}.{k}" if prefix else k

        for k, v in table.items():
            if k not in self.keys:
                fail(key(k), f"unknown key; expected one of {', '.join(sorted(self.keys))}")
            p = self.keys[k].type_problem(v)
            if p:
                fail(key(k), p)
        for k, spec in self.keys.items():
            if spec.required and k not in table:
                fail(key(k), spec.missing() if callable(spec.missing) else spec.missing)
        for k, spec in self.keys.items():
            if k in table:
                for where, p in spec.problems(table[k], key(k)):
                    fail(where, p)
        values = {k: table[k] if k in table else (None if spec.required else spec.default)
                  for k, spec in self.keys.items()}
        for r in self.relations:
            p = r.check(values)
            if p:
                fail(key(r.key) if r.key else prefix, p)
        return values


_BAD_NAME_CHARS = re.compile(r"[\x00-\x1f\x7f]")
_SCHEDULER = re.compile(r"^([a-z][a-z0-9+.-]*://[^\s/]+|[^\s:/]+:\d+)/?$")
_MODULE = re.compile(r"[A-Za-z_]\w*(\.[A-Za-z_]\w*)*")


def _label(v) -> str | None:
    if not isinstance(v, str) or not v.strip() or _BAD_NAME_CHARS.search(v) or len(v) > 200:
        return f"expected a non-empty printable name (at most 200 characters), got {v!r}"
    return None


def _folder(v) -> str | None:
    if not v or any(c in v for c in "/\\") or v.startswith(".") or _BAD_NAME_CHARS.search(v):
        return f"expected a plain folder name, got {v!r}"
    return None


def _positive(what: str):
    def rule(v) -> str | None:
        return None if math.isfinite(v) and v > 0 else f"expected a positive {what}, got {v!r}"
    return rule


def _scheduler(v) -> str | None:
    return None if _SCHEDULER.match(v) else f"expected a dask scheduler address like tcp://host:8786, got {v!r}"


def _module(v) -> str | None:
    if isinstance(v, str) and _MODULE.fullmatch(v):
        return None
    return f"expected a module name like 'my_package.my_module', got {v!r}"


def _bootstrap(v) -> str | None:
    return None if v == 0 or v >= 3 else f"expected 0 or an integer >= 3 (bootstrap draws), got {v!r}"


def _entries(section: str):
    def rule(v) -> str | None:
        return None if v else f"expected at least one [[{section}]] entry"
    return rule


def _one_length(values) -> str | None:
    if values["duration_s"] is not None and values["n_samples"] is not None:
        return "give duration_s or n_samples, not both"
    return None


def _scheduler_backend(values) -> str | None:
    if values["scheduler"] is not None and values["backend"] != "dask":
        return 'a scheduler address needs backend = "dask"'
    return None


def _estimator_names() -> str:
    from avbench import estimators

    return f"required; expected one of {', '.join(estimators.names())}"


#: the document: its three sections
ROOT = Table({
    "study": Key(dict, REQUIRED, missing="required section is missing"),
    "gyros": Key(list, REQUIRED, missing="required section is missing", rule=_entries("gyros")),
    "estimators": Key(list, REQUIRED, missing="required section is missing", rule=_entries("estimators")),
})

#: ``[study]``
STUDY = Table({
    "name": Key(str, REQUIRED, rule=_folder),
    "description": Key(str, ""),
    "seed": Key(int, REQUIRED, minimum=0),
    "replicates": Key(int, REQUIRED, minimum=1, maximum=MAX_REPLICATES),
    "duration_s": Key(NUMBER, rule=_positive("number of seconds")),
    "n_samples": Key(int, minimum=16, maximum=MAX_SAMPLES),
    "block_size": Key(int, 5, minimum=1),
    "backend": Key(str, "loky", allowed=("loky", "dask")),
    "scheduler": Key(str, rule=_scheduler),
    "paper_table": Key(str),
    "figure_gyros": Key(list),
    "units": Key(dict, {}),
    "plugins": Key(list, [], items=Key(object, rule=_module)),
}, relations=(Relation("duration_s", _one_length), Relation("scheduler", _scheduler_backend)))


def _preset_or_terms(values) -> str | None:
    if (values["preset"] is None) == (values["terms"] is None):
        return "expected either 'preset' or an explicit gyro ('name', 'dt', 'terms'), not both or neither"
    return None


def _not_with_preset(key: str):
    def check(values) -> str | None:
        if values["preset"] is not None and values[key] is not None:
            return "not allowed with 'preset' (a preset has its own sample rate and terms)"
        return None
    return Relation(key, check)


def _explicit_needs(key: str):
    def check(values) -> str | None:
        return "required for an explicit gyro" if values["preset"] is None and values[key] is None else None
    return Relation(key, check)


#: each ``[[gyros]]`` entry: a preset, or an explicit gyro (its terms are read by their classes)
GYRO = Table({
    "preset": Key(str),
    "name": Key(str, rule=_label),
    "label": Key(str, rule=_label),
    "dt": Key(NUMBER),
    "terms": Key(list),
    "paper_gyro": Key(str, rule=_label),
}, relations=(Relation("", _preset_or_terms), *(_not_with_preset(k) for k in ("dt", "terms", "name")),
              *(_explicit_needs(k) for k in ("name", "dt"))))

#: the ``terms`` setting that fits each gyro with its own term set (:attr:`avbench.noise_models.Gyro.term_set`),
#: resolved per gyro before the settings are checked: the estimator told the true model
TRUE_TERMS = "true"

#: each ``[[estimators]]`` entry (its settings are checked by the estimator's declarations)
ESTIMATOR = Table({
    "name": Key(str, REQUIRED, missing=_estimator_names),
    "label": Key(str, rule=_label),
    "settings": Key(dict, {}),
    "gyro_settings": Key(dict, {}, items=Key(dict, kind_text="a table of settings")),
    "x0_truth_scale": Key(NUMBER, rule=_positive("factor")),
    "bootstrap": Key(int, 0, rule=_bootstrap),
    "paper_method": Key(str, rule=_label),
})
