"""The study config is read by its declared schema (:mod:`avbench.studies.config_schema`): for every key
of every table, ``parse_config`` refuses what the declaration refuses with the declaration's words, and
fills what the file leaves out with the declared default; every committed study parses."""

from __future__ import annotations

import copy
import re
import tomllib
from pathlib import Path

import pytest

from avbench.studies.config import ConfigError, load_config, parse_config
from avbench.studies.config_schema import ESTIMATOR, GYRO, NUMBER, REQUIRED, ROOT, STUDY

from test_config_fuzz import BASE

ROOT_DIR = Path(__file__).resolve().parents[1]
RAW = tomllib.loads(BASE)
#: each table of the base config: (its schema, the path to it in the document, the key prefix in messages)
TABLES = [(ROOT, (), ""), (STUDY, ("study",), "study"), (GYRO, ("gyros", 0), "gyros[0]"),
          (ESTIMATOR, ("estimators", 0), "estimators[0]")]
#: a value of each kind, and one of another kind
OF_KIND = {str: "x", int: 3, NUMBER: 2.5, list: [], dict: {}}
OTHER = {str: 7, int: "7", NUMBER: "7", list: "7", dict: "7"}


def _table(raw, path):
    for p in path:
        raw = raw[p]
    return raw


def _refusal(raw) -> str:
    with pytest.raises(ConfigError) as info:
        parse_config(raw, where="cfg")
    return str(info.value)


def _key(prefix, k):
    return f"{prefix}.{k}" if prefix else k


@pytest.mark.parametrize("schema, path, prefix", TABLES)
def test_an_unknown_key_is_refused_naming_every_key_the_table_declares(schema, path, prefix):
    raw = copy.deepcopy(RAW)
    _table(raw, path)["colour"] = "red"
    assert _refusal(raw) == f"cfg: {_key(prefix, 'colour')}: unknown key; expected one of {', '.join(sorted(schema.keys))}"


@pytest.mark.parametrize("schema, path, prefix", TABLES)
def test_a_value_of_another_type_is_refused_naming_the_declared_type(schema, path, prefix):
    for k, spec in schema.keys.items():
        if spec.kind is object:
            continue
        raw = copy.deepcopy(RAW)
        _table(raw, path)[k] = OTHER[spec.kind]
        assert _refusal(raw) == f"cfg: {_key(prefix, k)}: {spec.type_problem(OTHER[spec.kind])}", k
        if spec.kind in (int, NUMBER):  # a bool is no number
            _table(raw, path)[k] = True
            assert re.search(rf"{re.escape(_key(prefix, k))}: expected an? (integer|number), got True", _refusal(raw)), k


@pytest.mark.parametrize("schema, path, prefix", TABLES)
def test_a_required_key_left_out_is_named(schema, path, prefix):
    for k, spec in schema.keys.items():
        if spec.required:
            raw = copy.deepcopy(RAW)
            del _table(raw, path)[k]
            message = spec.missing() if callable(spec.missing) else spec.missing
            assert _refusal(raw) == f"cfg: {_key(prefix, k)}: {message}", k


@pytest.mark.parametrize("schema, path, prefix", TABLES)
def test_a_value_beyond_its_declared_limits_or_choices_is_refused(schema, path, prefix):
    cases = 0
    for k, spec in schema.keys.items():
        bad = [v for v in (None if spec.minimum is None else spec.minimum - 1,
                           None if spec.maximum is None else spec.maximum + 1) if v is not None]
        if spec.allowed is not None:
            bad.append("".join(spec.allowed) + "?")
        for v in bad:
            raw = copy.deepcopy(RAW)
            if k == "duration_s":
                raw["study"].pop("n_samples", None)
            _table(raw, path)[k] = v
            assert _refusal(raw) == f"cfg: {_key(prefix, k)}: {spec.value_problem(v)}", (k, v)
            cases += 1
    assert cases or not any(s.minimum is not None or s.allowed for s in schema.keys.values())


def test_what_a_file_leaves_out_takes_the_declared_default():
    """The base config with each optional key of [study] and of an estimator left out: the resolved
    config holds the key's declared default; given, the value given."""
    fields = {"description": "description", "block_size": "block_size", "backend": "backend", "units": "units"}
    for k, field in fields.items():
        raw = copy.deepcopy(RAW)
        raw["study"].pop(k, None)
        assert getattr(parse_config(raw), field) == STUDY.keys[k].default, k
        raw["study"][k] = OF_KIND[STUDY.keys[k].kind] if k != "backend" else "dask"
        assert getattr(parse_config(raw), field) == raw["study"][k], k
    raw = copy.deepcopy(RAW)
    est = parse_config(raw).estimators[1]  # ols_trimmed: no label, bootstrap or gyro_settings given
    assert est.label == est.name and est.bootstrap == ESTIMATOR.keys["bootstrap"].default
    assert est.gyro_settings == ESTIMATOR.keys["gyro_settings"].default


def test_every_key_has_a_kind_and_a_default_of_that_kind():
    for schema in (ROOT, STUDY, GYRO, ESTIMATOR):
        for k, spec in schema.keys.items():
            assert spec.kind is object or spec.kind in OF_KIND, k
            if spec.default is not None and spec.default is not REQUIRED:
                assert spec.type_problem(spec.default) is None and spec.value_problem(spec.default) is None, k


@pytest.mark.parametrize("path", sorted((ROOT_DIR / "studies").glob("*.toml")), ids=lambda p: p.name)
def test_every_committed_study_parses_with_what_its_file_gives(path):
    """Each committed study: its [study] values as the file gives them, the declared default otherwise."""
    cfg = load_config(path)
    study = tomllib.loads(path.read_text())["study"]
    for k, field in (("name", "name"), ("seed", "seed"), ("replicates", "replicates"), ("block_size", "block_size"),
                     ("backend", "backend"), ("description", "description"), ("units", "units")):
        assert getattr(cfg, field) == study.get(k, STUDY.keys[k].default), k
    assert cfg.plugins == tuple(study.get("plugins", STUDY.keys["plugins"].default))
    assert len(cfg.gyros) == len(cfg.raw["gyros"]) and len(cfg.estimators) == len(cfg.raw["estimators"])
