"""Packaged studies by name: ``avbench studies`` lists them and ``avbench run NAME`` finds them from
any folder, writing ./results/NAME unless --out is given; the paper tables they cite ship with them."""

from __future__ import annotations

import os
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from avbench.studies import packaged
from avbench.cli import main


def test_studies_are_listed_from_any_folder(tmp_path):
    avbench = Path(sys.executable).parent / "avbench"
    r = subprocess.run([str(avbench), "studies"], cwd=tmp_path, capture_output=True, text=True, timeout=300,
                       env=dict(os.environ, MPLBACKEND="Agg"))
    assert r.returncode == 0, r.stderr
    listed = [line.split()[0] for line in r.stdout.splitlines()]
    assert listed == packaged.names() and "lv2015" in listed
    assert "Lv et al. 2015" in r.stdout


def test_run_by_name_writes_to_results_name_in_the_current_folder(tmp_path, monkeypatch, capsys):
    import avbench.studies.runner
    seen = {}

    def fake_run_study(cfg, out, **kw):  # the study itself is long: check what would run, where
        import pandas as pd

        seen.update(name=cfg.name, out=Path(out), path=cfg.path)
        Path(out).mkdir(parents=True, exist_ok=True)
        tidy = pd.DataFrame()
        tidy.attrs["table.md"] = "table\n"  # the run's own table, which the command prints
        return tidy

    monkeypatch.setattr(avbench.studies.runner, "run_study", fake_run_study)
    monkeypatch.chdir(tmp_path)
    assert main(["run", "lv2015", "--replicates", "1"]) == 0
    assert seen["name"] == "lv2015" and seen["out"] == Path("results") / "lv2015"
    assert seen["path"] == packaged.path_of("lv2015")
    assert main(["run", "lv2015", "--out", "elsewhere"]) == 0 and seen["out"] == Path("elsewhere")
    assert main(["run", "no_such_study"]) == 2
    assert "unknown study 'no_such_study': expected a study file or one of" in capsys.readouterr().err


@pytest.mark.parametrize("name", packaged.names())
def test_packaged_paper_tables_ship_with_the_study(name):
    path = packaged.path_of(name)
    study = tomllib.loads(path.read_text())["study"]
    if "paper_table" not in study:
        pytest.skip(f"{name} cites no paper table")
    table = (path.parent / study["paper_table"]).resolve()
    assert table.is_file(), f"{name}: paper_table {study['paper_table']} is not beside the config"
    assert table.is_relative_to(path.parent.resolve()), f"{name}: paper_table outside the package"
