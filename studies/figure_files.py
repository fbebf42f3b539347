"""Which figures a study's report has, without importing a plotting library.

The process that runs a study with local workers hands the drawing to them
(:func:`avbench.studies.report.write_report`); it needs the list of figures, not matplotlib.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd

__all__ = ["figure_jobs"]


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
        safe = "".join(ch if ch.isalnum() or ch in "-_" else "_" for ch in g.label)
        jobs += [("av", gi, out / f"av_{safe}.png"), ("spread", gi, out / f"spread_{safe}.png")]
    return jobs
