"""Plugins without forking: an installed package (tests/plugin_pkg) registers an estimator and noise
terms through entry points; configs name them, or any class by import path; loky and Dask workers
import the same plugins and give the same tables; a missing plugin is a config error naming the
module; the result hash records each plugin's name and version."""

from __future__ import annotations

import pandas as pd
import pytest

from avbench import estimators
from conftest import STUDY_COLS
from avbench.noise_models import term_class
from avbench.cli import main
from avbench.studies.config import ConfigError, load_config, parse_config
from avbench.studies.report import read_tidy
from avbench.studies.runner import run_study

STUDY = """
[study]
name = "plugin_study"
seed = 11
replicates = 4
block_size = 1
n_samples = 4000
{extra}

[[gyros]]
name = "sine"
dt = 0.1
terms = [{{type = "AngleRandomWalk", N = 1e-3}}, {{type = "RateRandomWalk", K = 3e-5}},
         {{type = "SineRate", amplitude = 2e-4, period = 60.0}}]

[[gyros]]
name = "square"
dt = 0.1
terms = [{{type = "AngleRandomWalk", N = 1e-3}},
         {{type = "avbench_example_plugin.terms:SquareWaveRate", amplitude = 2e-4, period = 60.0}}]

[[estimators]]
name = "two_slope"

[[estimators]]
name = "avbench_example_plugin.estimators:TwoSlope"
label = "two_slope_by_path"
settings = {{ taus = "all", overlapping = false }}

[[estimators]]
name = "ols"
settings = {{ terms = "NK", taus = "octave" }}
"""


def write(tmp_path, extra="", name="s.toml"):
    p = tmp_path / name
    p.write_text(STUDY.format(extra=extra))
    return p


def test_entry_points_and_import_paths_resolve(example_plugin):
    assert "two_slope" in estimators.names()
    by_ep = estimators.estimator_class("two_slope")
    by_path = estimators.estimator_class("avbench_example_plugin.estimators:TwoSlope")
    assert by_ep is by_path and by_ep.__module__ == "avbench_example_plugin.estimators"
    assert estimators.get("two_slope", taus="decade").taus == "decade"
    assert term_class("SineRate") is term_class("avbench_example_plugin.terms:SineRate")
    with pytest.raises(ValueError, match="unknown setting"):
        estimators.get("two_slope", terms="NK")


def test_study_with_plugins_same_tables_on_loky_and_dask(example_plugin, dask_cluster, tmp_path, capsys):
    cfg_path = write(tmp_path)
    cfg = load_config(cfg_path)
    plugins = cfg.result_payload()["plugins"]
    assert plugins["avbench_example_plugin.estimators:TwoSlope"] == "avbench-example-plugin==0.2.0"
    assert plugins["avbench_example_plugin.terms:SineRate"] == "avbench-example-plugin==0.2.0"
    assert set(plugins) == {
        "avbench_example_plugin.estimators:TwoSlope",
        "avbench_example_plugin.terms:SineRate",
        "avbench_example_plugin.terms:SquareWaveRate",
    }
    rc = main(["run", str(cfg_path), "--jobs", "2", "--out", str(tmp_path / "loky"), "--no-progress"])
    assert rc == 0, capsys.readouterr().err
    rc = main(["run", str(cfg_path), "--backend", "dask", "--scheduler", dask_cluster.scheduler_address,
               "--out", str(tmp_path / "dask"), "--no-progress"])
    assert rc == 0, capsys.readouterr().err
    tables = {}
    for which in ("loky", "dask"):
        tidy = read_tidy(tmp_path / which)
        table = pd.read_csv(tmp_path / which / "table.csv")
        tables[which] = (tidy[STUDY_COLS], table)
    pd.testing.assert_frame_equal(tables["loky"][0], tables["dask"][0])
    pd.testing.assert_frame_equal(tables["loky"][1], tables["dask"][1])
    tidy = tables["loky"][0]
    assert set(tidy["estimator"]) == {"two_slope", "two_slope_by_path", "ols"}
    assert (tidy["failure"] == "").all()
    assert len(tidy) == 2 * 4 * (2 + 2 + 2)  # gyros x replicates x (N, K per estimator)
    # the gyro whose term declares no exact AV: the table says the truth curve is unavailable
    md = (tmp_path / "loky" / "table.md").read_text()
    square = md.split("## square", 1)[1]
    assert "Truth curve (exact Allan variance) unavailable: term SquareWaveRate" in square
    assert "unavailable" not in md.split("## square", 1)[0]
    assert (tmp_path / "loky" / "av_square.png").is_file() and (tmp_path / "loky" / "av_sine.png").is_file()


def test_study_plugins_modules_are_imported_by_workers(example_plugin, tmp_path):
    body = STUDY.format(extra='plugins = ["avbench_example_plugin.estimators"]').split("[[estimators]]")[0]
    p = tmp_path / "s.toml"
    p.write_text(body + '[[estimators]]\nname = "example_white"\n')
    cfg = load_config(p)
    assert cfg.plugins == ("avbench_example_plugin.estimators",)
    assert cfg.result_payload()["plugins"]["avbench_example_plugin.estimators"] == "avbench-example-plugin==0.2.0"
    one = run_study(cfg, tmp_path / "one", n_jobs=1, progress=False, make_report=False)
    two = run_study(cfg, tmp_path / "two", n_jobs=2, progress=False, make_report=False)
    pd.testing.assert_frame_equal(one[STUDY_COLS], two[STUDY_COLS])
    assert set(one["coefficient"]) == {"N"} and (one["failure"] == "").all()


def test_hash_covers_plugin_versions(example_plugin, tmp_path, monkeypatch):
    import avbench.studies.config as config
    cfg_path = write(tmp_path)
    key = load_config(cfg_path).result_key()
    monkeypatch.setattr(config, "version_of", lambda obj: "avbench-example-plugin==0.3.0")
    assert load_config(cfg_path).result_key() != key


def test_configs_without_plugins_keep_their_hash(tmp_path):
    from conftest import study_toml

    p = tmp_path / "t.toml"
    p.write_text(study_toml())
    cfg = load_config(p)
    assert "plugins" not in cfg.result_payload() and cfg.plugin_versions == {}


@pytest.mark.parametrize(
    "extra, estimator, message",
    [
        ('plugins = ["no_such_pkg.mod"]', "ols", r"study\.plugins\[0\]: cannot import plugin module 'no_such_pkg\.mod'"),
        ("", "no_such_pkg.mod:Est", r"estimators\[0\]\.name: cannot import plugin module 'no_such_pkg\.mod'"),
        ("", "avbench.estimators.curve_fits.least_squares:Nope", r"estimators\[0\]\.name: plugin module 'avbench\.estimators\.curve_fits\.least_squares' has no attribute 'Nope'"),
        ("", "numpy:ndarray", r"estimators\[0\]\.name: .*expected a subclass of avbench\.estimators\.Estimator"),
        ('plugins = ["not a module"]', "ols", r"study\.plugins\[0\]: expected a module name"),
    ],
)
def test_missing_plugin_is_a_config_error_naming_it(tmp_path, extra, estimator, message):
    raw = {
        "study": {"name": "x", "seed": 1, "replicates": 1, "n_samples": 1000},
        "gyros": [{"name": "g", "dt": 0.1, "terms": [{"type": "AngleRandomWalk", "N": 1e-3}]}],
        "estimators": [{"name": estimator}],
    }
    if extra:
        raw["study"]["plugins"] = [extra.split('"')[1]]
    with pytest.raises(ConfigError, match=message):
        parse_config(raw, where="cfg.toml")


def test_missing_term_plugin_is_a_config_error(tmp_path):
    raw = {
        "study": {"name": "x", "seed": 1, "replicates": 1, "n_samples": 1000},
        "gyros": [{"name": "g", "dt": 0.1, "terms": [{"type": "gone_pkg:Drift", "a": 1.0}]}],
        "estimators": [{"name": "ols"}],
    }
    with pytest.raises(ConfigError, match=r"gyros\[0\]\.terms\[0\]\.type: cannot import plugin module 'gone_pkg'"):
        parse_config(raw, where="cfg.toml")


def test_estimator_in_a_file_beside_the_config(tmp_path, monkeypatch):
    """A module next to the study file is found (its folder is searched), and the hash records a
    hash of its source, so editing the file starts a new shard folder."""
    monkeypatch.setattr("sys.path", list(__import__("sys").path))  # undo the folder insertion afterwards
    (tmp_path / "beside_est.py").write_text(
        "from avbench.estimators.curve_fits.least_squares import OLS\n\nclass MyOLS(OLS):\n    '''OLS under another name.'''\n"
    )
    p = tmp_path / "s.toml"
    p.write_text(
        '[study]\nname = "b"\nseed = 1\nreplicates = 1\nn_samples = 2000\n'
        '[[gyros]]\nname = "g"\ndt = 0.1\nterms = [{type = "AngleRandomWalk", N = 1e-3}]\n'
        '[[estimators]]\nname = "beside_est:MyOLS"\nsettings = { terms = "N" }\n'
    )
    cfg = load_config(p)
    assert cfg.result_payload()["plugins"]["beside_est:MyOLS"].startswith("source sha256:")
