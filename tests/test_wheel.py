"""A regular (non-editable) install ships every module: the wheel built from the tracked files holds
every Python module and data file of the four packages (an explicit package list once left out the
subpackage ``studies.recordings``, which editable installs hide)."""

from __future__ import annotations

import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("noise_models", "estimators", "studies", "bench")


def _tracked() -> list[str]:
    out = subprocess.run(["git", "ls-files", *PACKAGES, "pyproject.toml", "README.md"], cwd=ROOT,
                         capture_output=True, text=True, check=True).stdout
    return out.split()


def test_the_wheel_holds_every_module_and_data_file(tmp_path):
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
    wanted = {f for f in files if f.split("/")[0] in PACKAGES and f.endswith((".py", ".toml", ".csv"))}
    missing = sorted(wanted - shipped)
    assert not missing, f"not in the wheel: {missing}"
