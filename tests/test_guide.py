"""Every code block of the user guide (docs/GUIDE.md) and the config schema (docs/CONFIG.md) runs.

Blocks run in order in one empty folder: ``python`` blocks in one namespace (the folder first on
``sys.path``, as in an interactive session started there), ``bash`` blocks with ``bash -euo
pipefail`` and this environment's ``avbench``, ``toml`` blocks are parsed (and, with a
``<!-- file: NAME -->`` line before them, written to NAME, as are python blocks so marked).
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

DOCS = Path(__file__).resolve().parents[1] / "docs"
BLOCK = re.compile(r"(?:<!-- file: (?P<file>\S+) -->\n)?```(?P<lang>\w*)\n(?P<code>.*?)```", re.S)


def blocks(path: Path) -> list[tuple[str, str | None, str]]:
    return [(m["lang"], m["file"], m["code"]) for m in BLOCK.finditer(path.read_text())]


def run_blocks(path: Path, folder: Path, monkeypatch) -> None:
    monkeypatch.chdir(folder)
    monkeypatch.syspath_prepend(str(folder))
    env = dict(os.environ, MPLBACKEND="Agg", PATH=f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}")
    namespace: dict = {"__name__": "__guide__"}
    for i, (lang, file, code) in enumerate(blocks(path)):
        where = f"{path.name} block {i} ({lang})"
        if file:
            (folder / file).write_text(code)
        if lang == "toml":
            tomllib.loads(code)
        elif lang == "python" and not file:
            exec(compile(code, where, "exec"), namespace)
        elif lang == "bash":
            r = subprocess.run(["bash", "-euo", "pipefail", "-c", code], cwd=folder, env=env,
                               capture_output=True, text=True, timeout=600)
            assert r.returncode == 0, f"{where} failed:\n{code}\n{r.stdout[-2000:]}\n{r.stderr[-2000:]}"
        elif lang not in ("python",):
            pytest.fail(f"{where}: a block of unknown language {lang!r}; expected python, bash or toml")


def test_guide_blocks_run(tmp_path, monkeypatch):
    assert len(blocks(DOCS / "GUIDE.md")) >= 10
    run_blocks(DOCS / "GUIDE.md", tmp_path, monkeypatch)


def test_config_schema_blocks_run(tmp_path, monkeypatch):
    run_blocks(DOCS / "CONFIG.md", tmp_path, monkeypatch)


def test_config_schema_documents_every_key():
    from avbench.studies import config_schema

    text = (DOCS / "CONFIG.md").read_text()
    documented = set(re.findall(r"^\| `([a-z0-9_]+)` \|", text, re.M))
    keys = set(config_schema.STUDY.keys) | set(config_schema.GYRO.keys) | set(config_schema.ESTIMATOR.keys)
    assert keys <= documented, f"keys missing from docs/CONFIG.md: {sorted(keys - documented)}"
    assert documented - {"type"} <= keys, f"documented keys the config does not know: {sorted(documented - keys - {'type'})}"


def test_readme_links_the_guide():
    readme = (DOCS.parent / "README.md").read_text()
    assert "docs/GUIDE.md" in readme and "docs/CONFIG.md" in readme
