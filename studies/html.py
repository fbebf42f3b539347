"""A finished study as one page a person opens: the tables, the leaderboard, the scores and the figures.

:func:`study_page` reads the folder ``avbench run`` wrote (:func:`avbench.studies.report.write_report`)
and returns one self-contained HTML document (``report.html`` beside the tables): the study's facts
from ``meta.json`` (seed, replicates, each gyro's record), ``table.md`` (the papers' layout, one table
per gyro), ``leaderboard.md`` (who wins where; only a study of several gyros or estimators has it),
``scores.md`` (coverage, RMSE/CRLB, the tested wins), the figures of each gyro (``av_<gyro>.png``,
``spread_<gyro>.png``: :func:`avbench.studies.figure_files.figure_jobs`) inline as
``data:image/png;base64`` URIs, and the fit times (``timings.md``, measured on the machine that
ran the study). The folder must hold a complete report (:func:`avbench.studies.report.check_report`:
every output listed in ``meta.json`` present and unchanged), else ``ValueError`` says what is wrong.

The markdown of those files is the small subset :mod:`avbench.studies.report` and
:mod:`avbench.studies.scoring` write, converted by :func:`markdown_html`: ``#`` headings, pipe
tables (a header row, a ``|---|`` row, body rows), paragraphs, and inline ``**bold**``, ``*italic*``
and ```code```. Every character of the files is escaped first (:func:`html.escape`); the inline
marks are applied to the escaped text. The page shell, its Content-Security-Policy (nothing is
loaded from the network) and its style are those of the recording's page
(:func:`avbench.recordings.html.document`).
"""

from __future__ import annotations

import re
from pathlib import Path

from avbench.recordings.html import avbench_version, document, esc, html_table, png_img

__all__ = ["study_page", "markdown_html", "pipe_cells"]

#: the markdown files of a study's report, in the order the page shows them: (file, anchor, link text, a note
#: under the heading or None)
_FILES = (("table.md", "table", "tables", None),
          ("leaderboard.md", "leaderboard", "leaderboard", None),
          ("scores.md", "scores", "scores", None),
          ("timings.md", "timings", "fit times", None))

_NUMERIC = re.compile(r"^[-+–−]?(\d|\.\d|–$)")


def _inline(text: str) -> str:
    """Escaped ``text`` with ```code```, ``**bold**`` and ``*italic*`` as HTML (not inside code)."""
    out = []
    for i, part in enumerate(re.split(r"`([^`]*)`", text)):
        if i % 2:
            out.append(f"<code>{esc(part)}</code>")
            continue
        s = esc(part)
        s = re.sub(r"\*\*(.+?)\*\*", r"<strong>\1</strong>", s)
        s = re.sub(r"(?<![\w*])\*(?!\s)(.+?)(?<!\s)\*(?![\w*])", r"<em>\1</em>", s)
        out.append(s)
    return "".join(out)


def pipe_cells(line: str) -> list[str]:
    """The cells of one pipe-table row (``| a | b |`` -> ``["a", "b"]``), stripped."""
    s = line.strip()
    if s.startswith("|"):
        s = s[1:]
    if s.endswith("|"):
        s = s[:-1]
    return [c.strip() for c in s.split("|")]


def _is_rule(line: str) -> bool:
    return bool(re.fullmatch(r"\|?\s*:?-{3,}:?\s*(\|\s*:?-{3,}:?\s*)*\|?", line.strip()))


def _table(lines: list[str]) -> str:
    """A pipe table (header, rule, body rows) as HTML; a number-like cell is right-aligned."""
    header = pipe_cells(lines[0])
    body = [pipe_cells(x) for x in lines[2:]] if len(lines) > 1 and _is_rule(lines[1]) else [pipe_cells(x) for x in lines[1:]]
    head = "<thead><tr>" + "".join(f"<th>{_inline(h)}</th>" for h in header) + "</tr></thead>"
    rows = []
    for r in body:
        cells = []
        for j, c in enumerate(r):
            cls = ' class="num"' if j > 0 and _NUMERIC.match(c) else ""
            cells.append(f"<td{cls}>{_inline(c)}</td>")
        rows.append("<tr>" + "".join(cells) + "</tr>")
    return f'<div class="scroll"><table>{head}<tbody>{"".join(rows)}</tbody></table></div>'


def markdown_html(text: str, shift: int = 0) -> str:
    """The markdown subset of a study's report files as HTML (see the module docstring): a heading
    of level k becomes ``<h{k + shift}>`` (at most ``<h6>``), consecutive lines starting with ``|`` a
    table, other runs of lines a paragraph.

    >>> print(markdown_html("## g1 <x>\\n\\n| | a |\\n|---|---|\\n| **m** | 1.5 |\\n\\nsee `t.md`", shift=1))
    <h3>g1 &lt;x&gt;</h3>
    <div class="scroll"><table><thead><tr><th></th><th>a</th></tr></thead><tbody><tr><td><strong>m</strong></td><td class="num">1.5</td></tr></tbody></table></div>
    <p>see <code>t.md</code></p>
    """
    out, para, table = [], [], []

    def flush():
        if para:
            out.append("<p>" + _inline(" ".join(para)) + "</p>")
            para.clear()
        if table:
            out.append(_table(table))
            table.clear()

    for line in text.splitlines():
        s = line.strip()
        m = re.match(r"^(#{1,6})\s+(.*)$", s)
        if s.startswith("|"):
            if para:
                flush()
            table.append(s)
            continue
        if table:
            flush()
        if not s:
            flush()
        elif m:
            flush()
            level = min(len(m.group(1)) + shift, 6)
            out.append(f"<h{level}>{_inline(m.group(2))}</h{level}>")
        else:
            para.append(s)
    flush()
    return "\n".join(out)


def _split_title(text: str) -> tuple[str | None, str]:
    """(the text of a leading ``# `` heading, the rest)."""
    lines = text.splitlines()
    if lines and re.match(r"^#\s+", lines[0]):
        return lines[0].lstrip("#").strip(), "\n".join(lines[1:])
    return None, text


def _safe(label: str) -> str:
    """A gyro's label as it is in its figure's file name (:func:`avbench.studies.figure_files.figure_jobs`)."""
    return "".join(ch if ch.isalnum() or ch in "-_" else "_" for ch in str(label))


def _facts(meta: dict) -> str:
    rows = [[g, (str(info.get("n_samples", "?")), {"class": "num"}), (f"{info.get('dt', '?')}", {"class": "num"}),
             (f"{info['n_samples'] * info['dt'] / 3600:.3g}" if info.get("n_samples") and info.get("dt") else "?",
              {"class": "num"}), info.get("truth_curve", "exact")]
            for g, info in (meta.get("gyros") or {}).items()]
    out = [f"<p>seed {esc(meta.get('seed', '?'))}, {esc(meta.get('replicates', '?'))} replicates per gyro"
           + (f", paper table {esc(meta['paper_table'])}" if meta.get("paper_table") else "")
           + f"; result key <code>{esc(meta.get('result_key', '?'))}</code></p>"]
    if meta.get("description"):
        out.append(f"<p>{esc(str(meta['description']).strip())}</p>")
    if rows:
        out.append(html_table(["gyro", "samples", "dt (s)", "record (h)", "truth curve"], rows))
    return "\n".join(out)


def _figures(folder: Path, meta: dict) -> str:
    """Each gyro's AV and spread figures side by side; any other PNG of the report after them."""
    pngs = sorted(n for n in (meta.get("outputs") or {}) if n.endswith(".png"))
    done, out = set(), []
    for g in meta.get("gyros") or {}:
        names = [n for n in (f"av_{_safe(g)}.png", f"spread_{_safe(g)}.png") if n in pngs]
        if not names:
            continue
        done.update(names)
        what = {"av": "Allan deviation, the truth and each estimator's fit of replicate 0",
                "spread": "each estimate over its true value, over the replicates"}
        out.append(f"<h3>{esc(g)}</h3><div class=\"figs\">"
                   + "".join(png_img((folder / n).read_bytes(), f"{n}: {what[n.split('_', 1)[0]]} ({g})", n) for n in names)
                   + "</div>")
    rest = [n for n in pngs if n not in done]
    if rest:
        out.append('<div class="figs">' + "".join(png_img((folder / n).read_bytes(), n, n) for n in rest) + "</div>")
    return "\n".join(out)


def study_page(folder) -> str:
    """The self-contained HTML page of the finished study in ``folder`` (see the module docstring).

    >>> study_page("no/such/folder")
    Traceback (most recent call last):
    ...
    ValueError: no/such/folder: not a folder; expected the output folder of 'avbench run'
    """
    from avbench.studies.report import check_report

    folder = Path(folder)
    meta = check_report(folder)
    body = ['<section id="study"><h2>Study</h2>', _facts(meta), "</section>"]
    nav = [("study", "study")]
    for name, anchor, link, note in _FILES:
        path = folder / name
        if not path.is_file():
            continue
        heading, rest = _split_title(path.read_text(encoding="utf-8"))
        if name == "table.md":
            heading = "Tables"
            if meta.get("description"):  # table.md repeats the description under its title: said once, above
                rest = rest.replace(str(meta["description"]).strip(), "", 1)
        nav.append((anchor, link))
        body.append(f'<section id="{anchor}"><h2>{esc(heading or name)}</h2>'
                    + (f'<p class="legend">{esc(note)}</p>' if note else "")
                    + f'<p class="legend">from <code>{esc(name)}</code></p>'
                    + markdown_html(rest, shift=1) + "</section>")
    figs = _figures(folder, meta)
    if figs:
        nav.append(("figures", "figures"))
        body.append(f'<section id="figures"><h2>Figures</h2>{figs}</section>')
    body.append(f"<footer>avbench {esc(avbench_version())} &middot; study folder {esc(folder.name)}: every output meta.json "
                "lists is present and unchanged &middot; a self-contained page: it loads nothing from the network</footer>")
    return document(meta.get("title") or f"Study {folder.name}", "\n".join(body),
                    subtitle="a Monte Carlo study of avbench: estimators against the exact truth", nav=nav)
