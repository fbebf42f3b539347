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
