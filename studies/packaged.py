"""The study configs shipped with avbench, by name: ``avbench run lv2015``, ``avbench studies``.

They are package data (``studies/*.toml`` with the papers' tables they reference), so they are found
from any folder after ``pip install``. A name that is also an existing file is read as the file.
"""

from __future__ import annotations

import tomllib
from importlib import resources
from pathlib import Path

__all__ = ["names", "path_of", "description", "resolve"]


def _folder() -> Path:
    return Path(str(resources.files(__package__)))


def names() -> list[str]:
    """Names of the packaged studies (the TOML files' stems), sorted."""
    return sorted(p.stem for p in _folder().glob("*.toml"))


def path_of(name: str) -> Path:
    """The packaged study config ``name``; a ValueError naming the known ones otherwise."""
    p = _folder() / f"{name}.toml"
    if name not in names() or not p.is_file():
        raise ValueError(f"unknown study {name!r}: expected a study file or one of {', '.join(names())}")
    return p


def description(name: str) -> str:
    """The ``[study] description`` of a packaged study."""
    raw = tomllib.loads(path_of(name).read_text(encoding="utf-8-sig"))
    return str(raw.get("study", {}).get("description", ""))


def resolve(arg: str) -> Path:
    """What ``avbench run ARG`` reads: the file ARG if it exists, else the packaged study ARG."""
    p = Path(arg)
    if p.is_file() or p.suffix == ".toml" or "/" in arg or "\\" in arg:
        return p  # a file (load_config says clearly if it is missing)
    return path_of(arg)
