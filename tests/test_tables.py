"""The tables a paper takes: ``avbench table`` re-renders a finished study's ``table.md`` byte for byte
(from the full-precision rows, never from the rounded ``table.csv``), and ``--latex`` is one captioned
booktabs ``table`` with the same numbers that ``pdflatex`` compiles."""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import pytest

from avbench.cli import main
from avbench.studies.report import read_summary, render_latex

ROOT = Path(__file__).resolve().parents[1]
COMMITTED = sorted(p.parent for p in (ROOT / "results").glob("*/meta.json") if (p.parent / "table.md").is_file())


@pytest.mark.parametrize("folder", COMMITTED, ids=[p.name for p in COMMITTED])
def test_table_command_equals_table_md(folder, capsys):
    assert main(["table", str(folder)]) == 0
    assert capsys.readouterr().out == (folder / "table.md").read_text()


@pytest.mark.parametrize("folder", COMMITTED, ids=[p.name for p in COMMITTED])
def test_table_csv_command_equals_table_csv(folder, capsys):
    assert main(["table", str(folder), "--csv"]) == 0
    assert capsys.readouterr().out == (folder / "table.csv").read_text()


def _cells(text: str) -> list[str]:
    """The numbers of a rendered table, in order, as printed (LaTeX's a\\times 10^{b} back to aeb)."""
    text = re.sub(r"\$(-?[\d.]+)\\times 10\^\{(-?\d+)\}\$", lambda m: f"{m[1]}e{int(m[2]):+03d}", text)
    return re.findall(r"-?\d+\.\d+(?:e[+-]\d+)?|(?<![\w.])\d+ / \d+", text)


def test_latex_is_one_captioned_booktabs_table_with_table_md_numbers():
    folder = ROOT / "results" / "lv2015"
    summary, meta = read_summary(folder)
    tex = render_latex(summary, meta)
    assert tex.count("\\begin{table}") == 1 and tex.count("\\caption{") == 1 and "\\label{tab:lv2015}" in tex
    assert tex.count("\\toprule") == tex.count("\\bottomrule") == tex.count("\\begin{tabular}") == 3
    assert "\\^{}" not in tex and "deg/h$^{1.5}$" not in tex  # lv2015 has no K; the unit test is below
    caption = tex.split("\\caption{", 1)[1].split("\\label", 1)[0]
    for words in ("30 replicates", "seed 2015", "144,000 samples", "\\Delta t = 0.1", "4~h", "Cram\\'er-Rao",
                  "Against the paper.", "the paper's is 2.48--24.8$\\times$ ours", "neither its AV grid"):
        assert words in caption
    md = (folder / "table.md").read_text()
    body = lambda t: [c for c in _cells(t) if "." in c or "/" in c]  # noqa: E731
    md_rows = [ln for ln in md.splitlines() if ln.startswith("| ") and not ln.startswith("| |")]
    tex_rows = [ln for ln in tex.splitlines() if ln.endswith("\\\\") and "&" in ln and "multicolumn" not in ln
                and not ln.startswith(" &")]
    assert len(md_rows) == len(tex_rows)
    for a, b in zip(md_rows, tex_rows):
        assert body(a.split("|", 2)[2]) == body(b.split("&", 1)[1]), (a, b)


def test_latex_units_are_superscripts(tmp_path):
    from avbench.studies.report import _tex_unit

    assert _tex_unit("deg/h^1.5") == "deg/h$^{1.5}$"
    assert _tex_unit("deg/h^2") == "deg/h$^{2}$"
    assert _tex_unit("deg/sqrt(h)") == "deg/$\\sqrt{\\mathrm{h}}$"


@pytest.mark.skipif(shutil.which("pdflatex") is None, reason="pdflatex not installed: the LaTeX is not compiled here")
@pytest.mark.parametrize("folder", COMMITTED, ids=[p.name for p in COMMITTED])
def test_latex_compiles(folder, tmp_path):
    summary, meta = read_summary(folder)
    doc = ("\\documentclass{article}\n\\usepackage{booktabs}\n"
           "\\usepackage[margin=1cm,landscape]{geometry}\n\\begin{document}\n"
           + render_latex(summary, meta) + "\\end{document}\n")
    (tmp_path / "t.tex").write_text(doc)
    done = subprocess.run(["pdflatex", "-interaction=nonstopmode", "-halt-on-error", "t.tex"], cwd=tmp_path,
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stdout[-3000:]
    assert (tmp_path / "t.pdf").stat().st_size > 0


def test_table_md_states_the_spreads_against_the_paper():
    """lv2015: the ratio of the paper's standard deviations to ours, as printed beside the numbers,
    is the range table.csv gives, and the departures the paper table explains follow it."""
    import pandas as pd

    folder = ROOT / "results" / "lv2015"
    t = pd.read_csv(folder / "table.csv")
    r = (t["paper_std"] / t["std"]).dropna()
    md = (folder / "table.md").read_text()
    assert f"paper's is {r.min():.3g}–{r.max():.3g}× ours (median {r.median():.3g}×)" in md
    assert "states neither its AV grid nor its bias-instability generator" in md


def test_tidy_csv_names_its_si_unit_and_table_csv_its_display_unit(tmp_path):
    """tidy.csv's ``unit`` column (after ``coefficient``) names the SI unit of its numbers: converting a
    row's true value from that unit to the display unit named in table.csv's ``unit`` column gives
    table.csv's true value; written again, the column is not doubled."""
    import pandas as pd

    from avbench.noise_models.units import from_si, to_si
    from avbench.studies.report import read_tidy, write_tidy

    folder = ROOT / "results" / "lv2015"
    tidy = pd.read_csv(folder / "tidy.csv")
    assert list(tidy.columns[3:6]) == ["coefficient", "unit", "true"]
    table = pd.read_csv(folder / "table.csv").drop_duplicates(["gyro", "coefficient"]).set_index(["gyro", "coefficient"])
    for (g, c, unit), d in tidy.groupby(["gyro", "coefficient", "unit"]):
        assert to_si(c, 1.0, unit) == 1.0  # an SI unit
        shown = table.loc[(g, c)]
        assert from_si(c, to_si(c, d["true"].iloc[0], unit), shown["unit"]) == pytest.approx(shown["true"], rel=1e-5)
    assert write_tidy(read_tidy(folder), tmp_path).read_text() == (folder / "tidy.csv").read_text()
