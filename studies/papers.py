"""The papers' published result tables, kept in the project (``studies/paper_tables/*.csv``).

Each CSV starts with ``#`` comment lines naming its source (authors, year, journal, table) and the
units of its numbers; a study names one with ``paper_table = "paper_tables/<file>.csv"`` (relative
to the study file), and its tables then print the paper's figures beside ours. A study whose
paper table cannot be read, or whose ``paper_gyro`` / ``paper_method`` names are not in it, is a
configuration error (:mod:`avbench.studies.config`), never a silent omission.
"""

from __future__ import annotations

import math
from pathlib import Path

import pandas as pd

__all__ = ["load_paper_table", "add_paper", "paper_notes"]


def load_paper_table(path: Path) -> pd.DataFrame:
    """A paper's result table as long format: gyro, method, coefficient, mean, error_pct, std.

    Long tables (Lv et al. 2015) are read as they are. Wide tables (Miao et al. 2014, 2015: one row
    per gyro and coefficient, a column per method) are melted: a column ``<method>_mean``,
    ``<method>_indicator_pct`` or ``<method>_std`` gives that statistic of ``<method>``; any other
    numeric column (``allan_variance``, ``online``) is the mean of the method it names. The gyro
    is the ``gyro`` column, else ``fog`` (FOG number).
    """
    df = pd.read_csv(path, comment="#")
    if "method" in df.columns:
        need = {"gyro", "method", "coefficient", "mean"}
        if not need <= set(df.columns):
            raise ValueError(f"{path}: expected columns {sorted(need)} (long format), got {list(df.columns)}")
        return df.assign(gyro=df["gyro"].astype(str))
    gcol = next((c for c in ("gyro", "fog") if c in df.columns), None)
    if gcol is None or "coefficient" not in df.columns:
        raise ValueError(f"{path}: expected a 'gyro' (or 'fog') and a 'coefficient' column, got {list(df.columns)}")
    stats = {"_mean": "mean", "_indicator_pct": "error_pct", "_std": "std"}
    rows = []
    for _, r in df.iterrows():
        entries: dict = {}
        for col in df.columns:
            if col in (gcol, "coefficient") or not pd.api.types.is_numeric_dtype(df[col]) or col == "rate_hz":
                continue
            suffix = next((sfx for sfx in stats if col.endswith(sfx)), None)
            method, stat = (col[: -len(suffix)], stats[suffix]) if suffix else (col, "mean")
            entries.setdefault(method, {})[stat] = r[col]
        for method, vals in entries.items():
            rows.append({"gyro": str(r[gcol]), "method": method, "coefficient": r["coefficient"], **vals})
    return pd.DataFrame(rows)


def paper_notes(path: Path) -> list[str]:
    """The known departures from the paper a table file explains in ``# Departure: ...`` lines,
    printed beside the numbers in ``table.md``."""
    lines = Path(path).read_text(encoding="utf-8").splitlines()
    return [ln[1:].strip() for ln in lines if ln.startswith("#") and ln[1:].strip().startswith("Departure:")]


def add_paper(summary: pd.DataFrame, paper: pd.DataFrame, gyro_map: dict, method_map: dict) -> pd.DataFrame:
    """The summary with the paper's mean, error % and std of each (gyro, method, coefficient) beside ours."""
    s = summary.copy()
    for col in ("paper_mean", "paper_error_pct", "paper_std"):
        s[col] = math.nan
    for i, r in s.iterrows():
        pg, pm = gyro_map.get(r["gyro"], r["gyro"]), method_map.get(r["estimator"])
        if pm is None:
            continue
        hit = paper[(paper["gyro"] == pg) & (paper["method"] == pm) & (paper["coefficient"] == r["coefficient"])]
        if len(hit):
            h = hit.iloc[0]
            s.at[i, "paper_mean"] = h["mean"]
            s.at[i, "paper_error_pct"] = h.get("error_pct", math.nan)
            s.at[i, "paper_std"] = h.get("std", math.nan)
    return s
