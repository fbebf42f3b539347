"""Which figures a study's report has, without importing a plotting library.

The process that runs a study with local workers hands the drawing to them
(:func:`avbench.studies.report.write_report`); it needs the list of figures, not matplotlib.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd

__all__ = ["figure_jobs", "figure_names", "figure_name_problem", "FIGURE_KINDS"]

#: the figures of each gyro, by kind: ``<kind>_<label made safe>.png``
FIGURE_KINDS = ("av", "spread")


def figure_jobs(cfg, tidy: pd.DataFrame, out: Path) -> list[tuple[str, int, Path]]:
    """The figures of a study, as ``(kind, gyro index, path)``: an AV and a spread figure for every
    gyro in ``cfg.figure_gyros`` (default all) that has replicate 0. Imports no plotting library,
    so that a process that hands the drawing to workers does not pay for matplotlib."""
    out = Path(out)
    jobs = []
    wanted = cfg.figure_gyros or tuple(g.label for g in cfg.gyros)
    for gi, g in enumerate(cfg.gyros):
        if g.label not in wanted:
            continue
        if not ((tidy["gyro"] == g.label) & (tidy["replicate"] == 0)).any():
            continue
        jobs += [(kind, gi, out / name) for kind, name in zip(FIGURE_KINDS, figure_names(g.label))]
    return jobs


def figure_names(label: str) -> list[str]:
    """The file names of a gyro's figures: its label with every character other than a letter, a digit,
    ``-`` and ``_`` made ``_``."""
    safe = "".join(ch if ch.isalnum() or ch in "-_" else "_" for ch in label)
    return [f"{kind}_{safe}.png" for kind in FIGURE_KINDS]


def figure_name_problem(labels) -> str | None:
    """What stops the gyros ``labels`` from having a figure file each, before any work: two labels that
    give one file name (``a b`` and ``a_b``, ``x/y`` and ``x?y``), or a name too long for a file system
    (:data:`avbench.outputs.NAME_BYTES`); None when there is nothing."""
    from avbench.outputs import NAME_BYTES

    seen: dict[str, str] = {}
    for label in labels:
        for name in figure_names(label):
            if len(name.encode("utf-8", "surrogateescape")) > NAME_BYTES:
                return (f"gyro label {label[:40]!r}... gives the figure file name {name[:40]!r}... of "
                        f"{len(name.encode('utf-8', 'surrogateescape'))} bytes; expected a label giving at most "
                        f"{NAME_BYTES} (a shorter label)")
            if name in seen and seen[name] != label:
                return (f"gyro labels {seen[name]!r} and {label!r} give one figure file name {name!r}; expected labels "
                        "that differ in a letter, a digit, '-' or '_'")
            seen[name] = label
    return None
