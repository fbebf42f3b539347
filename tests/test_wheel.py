"""A regular (non-editable) install ships every module under one import name: the wheel built from the
tracked files holds every Python module and data file of the repository's package folders, mapped
under ``avbench/`` (setup.py), and nothing else at its top level (an explicit package list can
leave out a subpackage, which editable installs hide)."""

from __future__ import annotations

import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: repository folder -> its path inside the wheel
FOLDERS = {"avbench": "avbench", "noise_models": "avbench/noise_models", "estimators": "avbench/estimators",
           "studies": "avbench/studies", "recordings": "avbench/recordings", "bench": "avbench/bench"}


def _tracked() -> list[str]:
    out = subprocess.run(["git", "ls-files", *FOLDERS, "pyproject.toml", "setup.py", "README.md"], cwd=ROOT,
                         capture_output=True, text=True, check=True).stdout
    return out.split()


def test_the_wheel_installs_one_import_name_holding_every_module(tmp_path):
    src = tmp_path / "src"
    files = _tracked()
    for f in files:  # a copy, so the build writes nothing into the work tree
        (src / f).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(ROOT / f, src / f)
    r = subprocess.run([sys.executable, "-m", "pip", "--disable-pip-version-check", "wheel", "--no-deps",
                        "-w", str(tmp_path / "dist"), str(src)], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    assert "BuildBackendWarning" not in r.stdout + r.stderr, "the build warns: see pyproject.toml"
    (wheel,) = (tmp_path / "dist").glob("avbench-*.whl")
    shipped = set(zipfile.ZipFile(wheel).namelist())
    top = {name.split("/")[0] for name in shipped if not name.split("/")[0].endswith(".dist-info")}
    assert top == {"avbench"}, f"top-level names in the wheel: {sorted(top)}"
    wanted = set()
    for f in files:
        folder, _, rest = f.partition("/")
        if folder in FOLDERS and f.endswith((".py", ".toml", ".csv")):
            wanted.add(f"{FOLDERS[folder]}/{rest}")
    missing = sorted(wanted - shipped)
    assert not missing, f"not in the wheel: {missing}"
