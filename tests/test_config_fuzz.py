"""Bad study configs are rejected before any work, with the file, the key and what was expected.

Explicit cases name the key each mistake must be reported under; a hypothesis fuzz test mutates a
valid config (drops keys, changes types, inserts junk values and unknown keys, negative and huge
numbers, unknown names) and checks that every mutant is either rejected with a ConfigError -- and
then ``avbench run`` exits with "avbench: error: ..." and creates no output folder -- or is a
valid study that runs.
"""

from __future__ import annotations

import copy
import json
import math
import tempfile
import tomllib
from pathlib import Path

import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from avbench.cli import main
from avbench.studies.config import ConfigError, load_config, parse_config
from avbench.studies.runner import run_study

BASE = """
[study]
name = "fuzz"
description = "a valid study the fuzz test mutates"
seed = 1
replicates = 2
n_samples = 2000
block_size = 1
backend = "loky"

[[gyros]]
name = "g"
label = "mygyro"
dt = 0.1
terms = [{type = "AngleRandomWalk", N = [0.5, "deg/sqrt(h)"]}, {type = "Quantization", Q = 1e-5},
         {type = "BiasInstability", B = [10.0, "deg/h"], tau_max = 600.0},
         {type = "RateRandomWalk", K = [30.0, "deg/h^1.5"]}]

[[gyros]]
preset = "SRS2000"

[[estimators]]
name = "ols"
label = "OLS"
settings = { terms = "QNB", taus = "octave", overlapping = false }
gyro_settings = { mygyro = { terms = "QNBK" } }

[[estimators]]
name = "ols_trimmed"
settings = { terms = "QNB", taus = [0.1, 0.2, 0.4, 0.8, 1.6, 3.2, 6.4], max_error_pct = 40.0 }

[[estimators]]
name = "wls"
settings = { terms = "QN", taus = "all" }
"""
RAW = tomllib.loads(BASE)


def test_base_config_is_valid():
    cfg = parse_config(copy.deepcopy(RAW))
    assert [g.label for g in cfg.gyros] == ["mygyro", "SRS2000"]


# -- explicit mistakes: each reported under its key -------------------------------------------

def _set(path, value):
    def f(raw):
        obj = raw
        for k in path[:-1]:
            obj = obj[k]
        if value is _DROP:
            del obj[path[-1]]
        else:
            obj[path[-1]] = value
    return f


_DROP = object()

CASES = [
    (_set(("study", "colour"), "red"), r"study\.colour: unknown key; expected one of"),
    (_set(("gyros", 0, "colour"), "red"), r"gyros\[0\]\.colour: unknown key"),
    (_set(("estimators", 0, "setting"), {}), r"estimators\[0\]\.setting: unknown key"),
    (_set(("study", "seed"), _DROP), r"study\.seed: required"),
    (_set(("study", "replicates"), "30"), r"study\.replicates: expected an integer, got '30'"),
    (_set(("study", "replicates"), 0), r"study\.replicates: expected an integer >= 1, got 0"),
    (_set(("study", "replicates"), -5), r"study\.replicates: expected an integer >= 1"),
    (_set(("study", "replicates"), 10**15), r"study\.replicates: expected an integer <= 1,000,000"),
    (_set(("study", "replicates"), 2.5), r"study\.replicates: expected an integer, got 2\.5"),
    (_set(("study", "replicates"), True), r"study\.replicates: expected an integer, got True"),
    (_set(("study", "seed"), -1), r"study\.seed: expected an integer >= 0"),
    (_set(("study", "n_samples"), 8), r"study\.n_samples: expected an integer >= 16"),
    (_set(("study", "n_samples"), 10**12), r"study\.n_samples: expected an integer <= 1,000,000,000"),
    (_set(("study", "block_size"), 0), r"study\.block_size: expected an integer >= 1"),
    (_set(("study", "backend"), "spark"), r"study\.backend: expected 'loky' or 'dask'"),
    (_set(("study", "scheduler"), "tcp://h:1"), r'study\.scheduler: a scheduler address needs backend = "dask"'),
    (_set(("study", "name"), "../escape"), r"study\.name: expected a plain folder name"),
    (_set(("gyros", 0, "dt"), 0), r"gyros\[0\]: dt: expected a positive, finite sample interval"),
    (_set(("gyros", 0, "dt"), -0.1), r"gyros\[0\]: dt: expected a positive"),
    (_set(("gyros", 0, "dt"), math.nan), r"gyros\[0\]: dt: expected a positive"),
    (_set(("gyros", 0, "terms", 0, "N"), [-0.5, "deg/sqrt(h)"]), r"gyros\[0\]\.terms\[0\]: AngleRandomWalk: N: expected a finite, non-negative"),
    (_set(("gyros", 0, "terms", 0, "N"), [0.5, "deg/fortnight"]), r"gyros\[0\]\.terms\[0\]: AngleRandomWalk: unknown unit"),
    (_set(("gyros", 0, "terms", 2, "tau_max"), -600.0), r"gyros\[0\]\.terms\[2\]: BiasInstability: tau_max: expected a finite, positive"),
    (_set(("gyros", 0, "terms", 2, "tau_max"), 1e300), r"gyros\[0\]\.terms\[2\]: filter memory of .* expected at most"),
    (_set(("gyros", 0, "terms", 1, "type"), "Quantisation"), r"gyros\[0\]\.terms\[1\]\.type: unknown term type 'Quantisation'; expected one of"),
    (_set(("gyros", 0, "terms", 1, "colour"), 1), r"gyros\[0\]\.terms\[1\]: bad arguments for Quantization"),
    (_set(("gyros", 1, "preset"), "SRS3000"), r"gyros\[1\]\.preset: .*SRS3000"),
    (_set(("gyros", 1, "dt"), 0.1), r"gyros\[1\]\.dt: not allowed with 'preset'"),
    (_set(("gyros", 1, "label"), "mygyro"), r"gyros: gyro labels must be unique"),
    (_set(("estimators", 0, "name"), "olss"), r"estimators\[0\]\.name: unknown estimator 'olss': expected one of"),
    (_set(("estimators", 0, "settings", "terms"), "QNX"), r"estimators\[0\]\.settings: \(gyro SRS2000\) estimator 'ols': terms='QNX': expected a non-empty subset"),
    (_set(("estimators", 0, "settings", "taus"), "weekly"), r"estimators\[0\]\.gyro_settings\.mygyro: \(gyro mygyro\) estimator 'ols': taus='weekly': expected 'octave', 'decade', 'all'"),
    (_set(("estimators", 0, "settings", "window"), 3), r"estimators\[0\]\.gyro_settings\.mygyro: \(gyro mygyro\) estimator 'ols': unknown setting\(s\) window"),
    (_set(("estimators", 1, "settings", "taus"), [0.1, 0.2, 5000.0]), r"estimators\[1\]\.settings: \(gyro mygyro\) ValueError: taus: \[5000\.0\] s exceed half the record"),
    (_set(("estimators", 1, "settings", "max_error_pct"), -40.0), r"estimators\[1\]\.settings: \(gyro mygyro\) estimator 'ols_trimmed': max_error_pct=-40\.0: expected a finite number > 0"),
    (_set(("estimators", 0, "gyro_settings"), {"nogyro": {}}), r"estimators\[0\]\.gyro_settings\.nogyro: unknown gyro label"),
    (_set(("estimators", 0, "x0_truth_scale"), 0.5), r"estimators\[0\]\.gyro_settings\.mygyro: .*unknown setting\(s\) x0"),
    (_set(("estimators", 2, "label"), "OLS"), r"estimators: estimator labels must be unique"),
    (_set(("estimators",), []), r"estimators: expected at least one"),
]


@pytest.mark.parametrize("mutate, message", CASES, ids=[c[1][:40] for c in CASES])
def test_mistake_is_reported_under_its_key(tmp_path, mutate, message):
    raw = copy.deepcopy(RAW)
    mutate(raw)
    path = tmp_path / "bad.toml"
    path.write_text(to_toml(raw))
    with pytest.raises(ConfigError, match=message) as info:
        load_config(path)
    assert str(info.value).startswith(f"{path}: ")


def test_cli_rejects_bad_config_without_writing(tmp_path, capsys):
    raw = copy.deepcopy(RAW)
    raw["study"]["replicates"] = 0
    path = tmp_path / "bad.toml"
    path.write_text(to_toml(raw))
    out = tmp_path / "out"
    assert main(["run", str(path), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"avbench: error: {path}: study.replicates: expected an integer >= 1, got 0")
    assert not out.exists()
    # the same through --replicates, and a file that is not TOML
    path.write_text(BASE)
    assert main(["run", str(path), "--out", str(out), "--replicates", "-3"]) == 2
    assert "study.replicates: expected an integer >= 1, got -3" in capsys.readouterr().err
    path.write_text(BASE + "\n[study\n")
    assert main(["run", str(path), "--out", str(out)]) == 2
    assert "not valid TOML" in capsys.readouterr().err
    assert main(["run", str(tmp_path / "missing.toml"), "--out", str(out)]) == 2
    assert "missing.toml: no such file" in capsys.readouterr().err
    assert not out.exists()


# -- fuzz --------------------------------------------------------------------------------------

def to_toml(raw: dict) -> str:
    """A minimal TOML writer for what a config holds (tables of arrays of tables, inline values)."""

    def val(v):
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, int):
            return str(v)
        if isinstance(v, float):
            return "nan" if math.isnan(v) else ("inf" if v > 0 else "-inf") if math.isinf(v) else repr(v)
        if isinstance(v, str):
            return json.dumps(v, ensure_ascii=False)
        if isinstance(v, list):
            return "[" + ", ".join(val(x) for x in v) + "]"
        if isinstance(v, dict):
            return "{" + ", ".join(f"{json.dumps(k)} = {val(x)}" for k, x in v.items()) + "}"
        raise TypeError(type(v))

    lines = []
    for k, v in raw.items():
        if isinstance(v, dict):
            lines.append(f"[{json.dumps(k)}]")
            lines += [f"{json.dumps(kk)} = {val(vv)}" for kk, vv in v.items()]
        elif isinstance(v, list) and v and all(isinstance(x, dict) for x in v):
            for x in v:
                lines.append(f"[[{json.dumps(k)}]]")
                lines += [f"{json.dumps(kk)} = {val(vv)}" for kk, vv in x.items()]
        else:
            lines.insert(0, f"{json.dumps(k)} = {val(v)}")
    return "\n".join(lines) + "\n"


def _paths(obj, prefix=()):
    yield prefix
    if isinstance(obj, dict):
        for k, v in obj.items():
            yield from _paths(v, prefix + (k,))
    elif isinstance(obj, list):
        for i, v in enumerate(obj):
            yield from _paths(v, prefix + (i,))


def _get(obj, path):
    for k in path:
        obj = obj[k]
    return obj


_text = st.text(st.characters(blacklist_categories=("Cs",)), max_size=10)
JUNK = st.one_of(
    st.sampled_from(
        [0, -1, 1, 2**62, -(2**62), 10**12, 0.0, -0.5, 1e300, -1e300, 1e-300, math.nan, math.inf, -math.inf,
         True, False, "", "junk", "QNBKRX", "all", "deg/h", "SRS3000", "olss", "tcp://x:1", [], {}, [1, "x"],
         {"a": 1}, [0.5, "deg/h"], [[1]], {"type": "Quantization"}]
    ),
    st.integers(min_value=-(2**63), max_value=2**63 - 1),
    st.floats(allow_nan=True, allow_infinity=True),
    _text,
    st.lists(st.one_of(st.integers(-10, 10), _text), max_size=3),
)


@st.composite
def mutants(draw):
    raw = copy.deepcopy(RAW)
    for _ in range(draw(st.integers(1, 3))):
        paths = [p for p in _paths(raw) if p]
        if not paths:
            break
        path = draw(st.sampled_from(paths))
        parent, key = _get(raw, path[:-1]), path[-1]
        op = draw(st.sampled_from(["drop", "junk", "junk", "negate", "huge", "unknown_key", "rename"]))
        if op == "drop":
            del parent[key]
        elif op == "junk":
            parent[key] = draw(JUNK)
        elif op in ("negate", "huge"):
            v = parent[key]
            if isinstance(v, int | float) and not isinstance(v, bool):
                parent[key] = -v if op == "negate" else v * draw(st.sampled_from([10**6, 10**12, 1e300]))
            else:
                parent[key] = draw(JUNK)
        elif op == "unknown_key":
            target = parent if isinstance(parent, dict) else raw  # the top level is always a table
            target[draw(st.sampled_from(["colour", "replicate", "Seed", "setting", "term"]))] = draw(JUNK)
        else:  # a misspelt name
            v = parent[key]
            parent[key] = (v + "x") if isinstance(v, str) else draw(_text)
    return raw


@settings(max_examples=100, deadline=5000, derandomize=True, suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(raw=mutants())
def test_fuzzed_configs_fail_cleanly_or_run(tmp_path, raw):
    here = Path(tempfile.mkdtemp(dir=tmp_path))  # tmp_path is shared by the examples
    path = here / "mutant.toml"
    try:
        text = to_toml(raw)
        tomllib.loads(text)
    except (TypeError, tomllib.TOMLDecodeError):  # not expressible in TOML (e.g. a junk top-level value)
        event("not expressible in TOML")
        return
    path.write_text(text)
    out = here / "out"
    try:
        cfg = load_config(path)
    except ConfigError as e:
        assert str(e).startswith(f"{path}: ")
        event("rejected: " + str(e)[len(str(path)) + 2 :].split(":")[0])
        # the command line says so and writes nothing
        import contextlib
        import io

        err = io.StringIO()
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            assert main(["run", str(path), "--out", str(out), "--no-progress"]) == 2
        assert err.getvalue().startswith("avbench: error: "), err.getvalue()
        assert not out.exists()
        return
    # accepted: a valid study; run it if it is small
    event("accepted")
    if cfg.replicates * sum(g.n_samples for g in cfg.gyros) <= 20_000:
        tidy = run_study(cfg, out, progress=False, make_report=False)
        assert set(tidy["replicate"]) == set(range(cfg.replicates))
