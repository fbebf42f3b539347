"""The README's promises about itself: its two commands, and a project that stands on its own."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _readme_commands() -> list[str]:
    block = re.search(r"```bash\n(.*?)```", (ROOT / "README.md").read_text(), re.S)
    assert block, "README.md has no bash block"
    return [line for line in block.group(1).splitlines() if line.strip()]


def test_ci_runs_the_readme_test_command():
    first, second = _readme_commands()[:2]
    assert "pytest" in second
    ci = [line.strip() for line in (ROOT / ".ci" / "run").read_text().splitlines()]
    assert second.strip() in ci, "the test command CI runs must be the README's, exactly"
    assert any("venv" in line for line in ci), ".ci/run must build its own virtual environment"


def test_readme_first_command_runs_a_committed_study():
    first = _readme_commands()[0]
    study = re.search(r"avbench run (\S+\.toml)", first).group(1)
    assert (ROOT / study).is_file()
    assert (ROOT / "results" / Path(study).stem / "meta.json").is_file()


def test_nothing_points_outside_the_project():
    """Nothing names the developers' shared folder (users have none): the optional recordings are
    found through AVBENCH_REAL_DATA or an explicit --data."""
    offenders = []
    for folder in (".", "avbench", "noise_models", "estimators", "studies", "recordings", "bench", "docs", "tests", "results"):
        for p in [ROOT / "README.md"] if folder == "." else (ROOT / folder).rglob("*"):
            if p.suffix not in {".py", ".toml", ".md", ".csv"} or "__pycache__" in p.parts:
                continue
            rel = str(p.relative_to(ROOT))
            text = p.read_text(errors="replace")
            for m in re.finditer(r"\.\./sha[r]ed|sha[r]ed/data", text):
                if rel != "tests/test_readme.py":
                    offenders.append(f"{rel}: {m.group(0)}")
    assert not offenders, offenders


def test_readme_python_blocks_run(tmp_path, monkeypatch):
    """The README's Python examples run in order in one namespace, in a folder holding the ``imu.csv``
    its recording example reads (20 minutes at 100 Hz: gyro in deg/s, accelerometer in g, no units
    in the header, as the example's options say)."""
    import numpy as np

    from avbench.noise_models import AngleRandomWalk, Gyro, RateRandomWalk

    rng = np.random.default_rng(3)
    g = Gyro(dt=0.01, terms=[AngleRandomWalk(N=1e-3), RateRandomWalk(K=1e-5)])
    n = 120_000
    cols = [np.arange(n) * 0.01] + [g.simulate(n, rng) * 180 / np.pi for _ in range(3)] + \
        [0.002 * g.simulate(n, rng) + off for off in (0.0, 0.0, 1.0)]
    np.savetxt(tmp_path / "imu.csv", np.column_stack(cols), delimiter=",", fmt="%.9g",
               header="t,gyro_x,gyro_y,gyro_z,acc_x,acc_y,acc_z", comments="")
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("MPLBACKEND", "Agg")
    code = re.findall(r"```python\n(.*?)```", (ROOT / "README.md").read_text(), re.S)
    assert len(code) >= 3
    namespace: dict = {"__name__": "__readme__"}
    for i, block in enumerate(code):
        exec(compile(block, f"README.md python block {i}", "exec"), namespace)


def test_readme_robotics_section_runs_as_written(tmp_path):
    """The robotics path of the README (simulate a record, estimate it with --format and --html) runs
    as written, and writes every file it names."""
    import os
    import subprocess
    import sys

    text = (ROOT / "README.md").read_text()
    section = text[text.index("## From a recording at rest to your filter (robotics)"):]
    block = re.search(r"```bash\n(.*?)```", section, re.S).group(1)
    env = dict(os.environ, MPLBACKEND="Agg", PATH=f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}")
    run = subprocess.run(["bash", "-euo", "pipefail", "-c", block], cwd=tmp_path, env=env, capture_output=True,
                         text=True, timeout=600)
    assert run.returncode == 0, run.stderr[-3000:]
    named = re.findall(r"`est/([^`]+)`", section.split("**What to inflate", 1)[0])
    assert {"imu_vins.yaml", "imu_kalibr.yaml", "imu_px4.params", "imu_report.html"} <= set(named)
    for name in named:
        assert (tmp_path / "est" / name).is_file(), name
    assert "## accel" in run.stdout and "## gyro" in run.stdout
