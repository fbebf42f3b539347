"""Step 5d: the recording as a page a person opens -- one self-contained HTML file.

:func:`recording_page` renders the fits of ``avbench estimate`` (their
:class:`~avbench.estimators.results.FitResult` s, gathered in :class:`avbench.recordings.report.Estimate`)
with the sensors' Allan deviation figures and the exported stack formats into one HTML document, ``<stem>_report.html``:

* the record -- sources, format, samples, rate, jitter, gaps and the reader's notes;
* the static check's verdict (``static_check``), its reasons and its statistics per channel;
* per sensor the figure (:func:`avbench.recordings.figure.figure`), the coefficient table exactly as
  the screen shows it -- the cells are :func:`avbench.recordings.report.screen_tables`' cells, which
  are :func:`~avbench.recordings.report.shown_value`, with the same numbered footnotes -- the status
  of every coefficient that is not a plain value (its reason, its evidence), and the fit check's
  verdict of every method;
* the between-run checks of ``--combine``, the values of the filter yaml, and every exported block
  (``exports``: ``{name: (file name, text)}``) in a ``<pre>`` with a copy button.

Self-contained means the page needs no network to be read, and loads nothing from it: the figures
are ``data:image/png;base64`` URIs, the style sheet and the one script (the copy buttons) are inline,
no font is fetched (the reader's system fonts). The page states this in its own
Content-Security-Policy: nothing may be loaded but ``data:`` images, and no script may run but the
copy script, allowed by its SHA-256. Every text that comes from the data -- file names, titles,
notes, warnings, exported files -- goes through :func:`html.escape`, so a ``<script>`` in a file name
is shown, never run.

The page shell (:func:`document`), tables (:func:`html_table`), images (:func:`png_img`) and copy
blocks (:func:`copy_block`) are public: the study's page (:mod:`avbench.studies.html`) is built from
them too.
"""

from __future__ import annotations

import base64
import hashlib
import html
import io
import math

__all__ = ["recording_page", "document", "html_table", "png_img", "copy_block", "esc", "png_bytes", "avbench_version",
           "CSP", "COPY_SCRIPT"]

#: the page's one script: a click on a ``button.copy`` copies the text of the ``<pre>`` it names
#: (the clipboard API, or the selection and ``execCommand("copy")`` where that is refused); a click on
#: a ``figure.zoom`` shows it at the page's full width, a second click at its own
COPY_SCRIPT = """
document.addEventListener("click", function (ev) {
  var f = ev.target.closest ? ev.target.closest("figure.zoom") : null;
  if (f) { f.classList.toggle("zoomed"); return; }
  var b = ev.target.closest ? ev.target.closest("button.copy") : null;
  if (!b) { return; }
  var pre = document.getElementById(b.getAttribute("data-target"));
  if (!pre) { return; }
  function done(ok) {
    b.textContent = ok ? "copied" : "selected: press Ctrl+C";
    setTimeout(function () { b.textContent = "copy"; }, 2000);
  }
  function bySelection() {
    var r = document.createRange();
    r.selectNodeContents(pre);
    var s = window.getSelection();
    s.removeAllRanges();
    s.addRange(r);
    var ok = false;
    try { ok = document.execCommand("copy"); } catch (e) { ok = false; }
    done(ok);
  }
  if (navigator.clipboard && window.isSecureContext) {
    navigator.clipboard.writeText(pre.textContent).then(function () { done(true); }, bySelection);
  } else {
    bySelection();
  }
});
"""


def _script_hash(script: str) -> str:
    return "'sha256-" + base64.b64encode(hashlib.sha256(script.encode("utf-8")).digest()).decode("ascii") + "'"


#: the page's Content-Security-Policy: nothing from the network; data: images, inline style, and the
#: copy script only (by its hash)
CSP = (f"default-src 'none'; img-src data:; style-src 'unsafe-inline'; script-src {_script_hash(COPY_SCRIPT)}; "
       "base-uri 'none'; form-action 'none'")

_CSS = """
:root { --fg: #1d2330; --muted: #5b6475; --line: #d9dee7; --bg: #ffffff; --band: #f5f7fa; --accent: #2456a6;
        --bad: #b3261e; --bad-bg: #fdecea; --good: #1e7d3a; --good-bg: #e8f5ec; --warn-bg: #fff6e0; }
* { box-sizing: border-box; }
body { margin: 0; color: var(--fg); background: var(--bg); line-height: 1.45;
       font: 15px/1.45 system-ui, -apple-system, "Segoe UI", Roboto, "Helvetica Neue", Arial, sans-serif; }
main { max-width: 1480px; margin: 0 auto; padding: 24px 32px 64px; }
h1 { font-size: 1.6em; margin: 0 0 4px; }
h2 { font-size: 1.3em; margin: 36px 0 8px; padding-bottom: 4px; border-bottom: 2px solid var(--line); }
h3 { font-size: 1.08em; margin: 22px 0 6px; }
h4 { font-size: 1em; margin: 16px 0 4px; }
p, li { max-width: 110ch; }
.sub { color: var(--muted); margin: 0 0 12px; }
nav { margin: 12px 0 0; padding: 8px 0; border-top: 1px solid var(--line); border-bottom: 1px solid var(--line); }
nav a { margin-right: 18px; color: var(--accent); text-decoration: none; white-space: nowrap; }
nav a:hover { text-decoration: underline; }
.scroll { overflow-x: auto; margin: 8px 0 12px; }
table { border-collapse: collapse; font-size: 0.92em; }
th, td { border: 1px solid var(--line); padding: 4px 9px; text-align: left; vertical-align: top; }
thead th { background: var(--band); font-weight: 600; white-space: nowrap; }
tbody tr:nth-child(even) td { background: #fafbfc; }
td.nowrap { white-space: nowrap; }
td.num { text-align: right; font-variant-numeric: tabular-nums; white-space: nowrap; }
td.st-not-resolved { color: var(--muted); }
td.st-non-physical, td.st-failed { color: var(--bad); }
tr.poor td { background: var(--warn-bg) !important; }
table.facts th { background: var(--band); text-align: left; white-space: nowrap; font-weight: 600; }
.badge { display: inline-block; padding: 2px 10px; border-radius: 10px; font-weight: 600; font-size: 0.92em; }
.badge.good { color: var(--good); background: var(--good-bg); }
.badge.bad { color: var(--bad); background: var(--bad-bg); }
.badge.none { color: var(--muted); background: var(--band); }
figure { margin: 10px 0 14px; }
figure img { max-width: 100%; height: auto; border: 1px solid var(--line); }
figure.zoom { cursor: zoom-in; }
figure.zoomed { cursor: zoom-out; flex-basis: 100% !important; }
figure.zoomed img { width: 100%; }
figcaption { color: var(--muted); font-size: 0.9em; }
.figs { display: flex; flex-wrap: wrap; gap: 12px; }
.figs figure { flex: 0 1 auto; max-width: 100%; }
ol.notes { font-size: 0.92em; padding-left: 28px; }
.legend { color: var(--muted); font-size: 0.9em; }
.block { margin: 12px 0 18px; border: 1px solid var(--line); border-radius: 6px; }
.block-head { display: flex; justify-content: space-between; align-items: center; padding: 6px 10px;
              background: var(--band); border-bottom: 1px solid var(--line); }
.block-head h3 { margin: 0; font-size: 1em; font-family: ui-monospace, "DejaVu Sans Mono", Menlo, Consolas, monospace; }
.fmt { margin-left: 10px; padding: 1px 8px; border-radius: 8px; background: #e3e9f4; color: var(--accent);
       font: 600 0.8em system-ui, sans-serif; }
button.copy { font: inherit; font-size: 0.88em; padding: 3px 12px; border: 1px solid var(--accent);
              color: var(--accent); background: #fff; border-radius: 4px; cursor: pointer; }
button.copy:hover { background: var(--accent); color: #fff; }
pre { margin: 0; padding: 10px 12px; overflow-x: auto; font-size: 0.86em; line-height: 1.4;
      font-family: ui-monospace, "DejaVu Sans Mono", Menlo, Consolas, monospace; }
code { font-family: ui-monospace, "DejaVu Sans Mono", Menlo, Consolas, monospace; font-size: 0.92em; }
footer { margin-top: 40px; color: var(--muted); font-size: 0.85em; }
"""


def avbench_version() -> str:
    """The installed avbench's version (from its distribution's metadata; "?" where it is not installed)."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("avbench")
    except PackageNotFoundError:
        return "?"


def esc(value) -> str:
    """``value`` as HTML text: ``str(value)`` with ``& < > " '`` escaped (:func:`html.escape`)."""
    return html.escape(str(value), quote=True)


def document(title: str, body: str, subtitle: str | None = None, nav: list[tuple[str, str]] | None = None) -> str:
    """A whole HTML page: ``<head>`` with the charset, the viewport, :data:`CSP`, the escaped
    ``title`` and the style sheet; ``<body>`` with the title as ``<h1>``, ``subtitle``, a row of
    in-page links ``nav`` (``[(anchor, label)]``), the ``body`` (HTML, already escaped by its maker),
    and the copy script."""
    links = ""
    if nav:
        links = "<nav>" + "".join(f'<a href="#{esc(a)}">{esc(label)}</a>' for a, label in nav) + "</nav>"
    sub = f'<p class="sub">{esc(subtitle)}</p>' if subtitle else ""
    return (f'<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n'
            f'<meta name="viewport" content="width=device-width, initial-scale=1">\n'
            f'<meta http-equiv="Content-Security-Policy" content="{esc(CSP)}">\n'
            f"<title>{esc(title)}</title>\n<style>{_CSS}</style>\n</head>\n<body>\n<main>\n"
            f"<h1>{esc(title)}</h1>\n{sub}\n{links}\n{body}\n</main>\n<script>{COPY_SCRIPT}</script>\n</body>\n</html>\n")


def _cell(c) -> str:
    """One ``<td>``: a string is escaped text; a ``(text, attributes)`` pair adds attributes
    (``{"class": ..., "data-...": ...}``, values escaped)."""
    if isinstance(c, tuple):
        text, attrs = c
        a = "".join(f' {esc(k)}="{esc(v)}"' for k, v in attrs.items() if v is not None)
        return f"<td{a}>{esc(text)}</td>"
    return f"<td>{esc(c)}</td>"


def html_table(header, rows, row_classes=None, css_class: str | None = None) -> str:
    """A ``<table>`` in a horizontally scrolling box: ``header`` the column labels, ``rows`` lists of
    cells (text, or ``(text, attributes)``: :func:`_cell`), ``row_classes`` a class per row (or None)."""
    cls = f' class="{esc(css_class)}"' if css_class else ""
    head = "<thead><tr>" + "".join(f"<th>{esc(h)}</th>" for h in header) + "</tr></thead>"
    body = []
    for i, row in enumerate(rows):
        rc = (row_classes or [None] * len(rows))[i]
        body.append((f'<tr class="{esc(rc)}">' if rc else "<tr>") + "".join(_cell(c) for c in row) + "</tr>")
    return f'<div class="scroll"><table{cls}>{head}<tbody>{"".join(body)}</tbody></table></div>'


def _facts(pairs) -> str:
    """A two-column table of (label, value) -- the record's facts."""
    rows = "".join(f"<tr><th>{esc(k)}</th><td>{esc(v)}</td></tr>" for k, v in pairs)
    return f'<div class="scroll"><table class="facts"><tbody>{rows}</tbody></table></div>'


def png_bytes(fig_or_png, dpi: int = 110) -> bytes:
    """PNG bytes of a matplotlib Figure (drawn at ``dpi``, as ``avbench estimate`` saves it; the
    figure is left open) or of PNG bytes as given."""
    if isinstance(fig_or_png, (bytes, bytearray, memoryview)):
        return bytes(fig_or_png)
    buf = io.BytesIO()
    fig_or_png.savefig(buf, format="png", dpi=dpi, bbox_inches="tight")
    return buf.getvalue()


def _png_width(png: bytes) -> int:
    """The width in pixels of a PNG (its IHDR chunk)."""
    return int.from_bytes(png[16:20], "big")


def _smallest_text_px(fig, dpi: int) -> float | None:
    """The size in pixels, at ``dpi``, of the smallest visible text of a drawn matplotlib Figure."""
    from matplotlib.text import Text

    sizes = [t.get_fontsize() for t in fig.findobj(Text) if t.get_visible() and t.get_text().strip()]
    return min(sizes) * dpi / 72 if sizes else None


def png_img(fig_or_png, alt: str, caption: str | None = None, sharp: float = 1.0) -> str:
    """A ``<figure>`` holding the image inline (``data:image/png;base64``), with an escaped ``alt``
    text and caption. A matplotlib Figure is drawn at ``sharp`` x 110 dpi and shown at the size of
    110 dpi (``width``), larger on a click (``figure.zoom``); its smallest text in pixels as shown is
    ``data-text-px``."""
    attrs, cls = "", ""
    if isinstance(fig_or_png, (bytes, bytearray, memoryview)):
        png = bytes(fig_or_png)
    else:
        png = png_bytes(fig_or_png, dpi=round(110 * sharp))
        small = _smallest_text_px(fig_or_png, round(110 * sharp))
        width = round(_png_width(png) / sharp)
        attrs = f' width="{width}"' + (f' data-text-px="{small / sharp:.2f}"' if small is not None else "")
        cls = ' class="zoom"'
    data = base64.b64encode(png).decode("ascii")
    cap = f"<figcaption>{esc(caption)}</figcaption>" if caption else ""
    return f'<figure{cls}><img src="data:image/png;base64,{data}" alt="{esc(alt)}"{attrs}>{cap}</figure>'


def copy_block(filename: str, text: str, ident: str, label: str | None = None) -> str:
    """One exported file ready to copy: its name as the heading (with ``label``, e.g. the format's
    name, beside it), a copy button, the text in a ``<pre>`` (``ident``: the ``<pre>``'s id, unique
    in the page)."""
    tag = f' <span class="fmt">{esc(label)}</span>' if label else ""
    return (f'<div class="block"><div class="block-head"><h3>{esc(filename)}{tag}</h3>'
            f'<button class="copy" type="button" data-target="{esc(ident)}">copy</button></div>'
            f'<pre id="{esc(ident)}">{esc(text)}</pre></div>')


def _g(v, fmt=".3g") -> str:
    return "?" if v is None or (isinstance(v, float) and not math.isfinite(v)) else format(v, fmt)


def _badge(text: str, kind: str) -> str:
    return f'<span class="badge {kind}">{esc(text)}</span>'


def _anchor(text: str) -> str:
    return "".join(ch if ch.isalnum() else "-" for ch in str(text)).strip("-").lower() or "x"


# -- the sections of the recording's page ----------------------------------------------------------------
def _record_section(data: dict) -> str:
    t = data.get("timing") or {}
    n, dt = t.get("n_samples"), t.get("sample_interval_s")
    gaps = t.get("gaps") or []
    joins = [g for g in gaps if g.get("missing_s") is None]  # --combine: a file boundary is a gap of unknown length
    missing = sum(g["missing_s"] for g in gaps if g.get("missing_s") is not None)
    pairs = [("sources", ", ".join(data.get("sources") or [])),
             ("format", data.get("format") or "?")]
    if data.get("topic"):
        pairs.append(("topic", data["topic"]))
    pairs += [("samples", f"{n}" if n is not None else "?"),
              ("rate", f"{_g(t.get('rate_hz'), '.6g')} Hz (dt = {_g(dt, '.6g')} s, from {t.get('from', '?')})"),
              ("duration", f"{_g(n * dt / 3600, '.3f')} h ({_g(n * dt, '.6g')} s)" if n and dt else "?")]
    if data.get("time_source"):
        pairs.append(("time stamps", data["time_source"]))
    if t.get("jitter_rel") is not None:
        worst = t.get("max_interval_deviation_rel")
        pairs.append(("jitter", f"{100 * t['jitter_rel']:.3g} % of dt (largest deviation "
                                f"{_g(None if worst is None else 100 * worst)} %)"))
    real = len(gaps) - len(joins)
    pairs.append(("gaps", (f"{real} ({missing:.4g} s missing)" if real else "none")
                  + (f"; {len(joins)} file boundary(ies) treated as gaps" if joins else "")))
    out = ['<section id="record"><h2>Record</h2>', _facts(pairs)]
    if gaps:
        shown = gaps[:50]
        rows = [[(str(g["before_sample"]), {"class": "num"}),
                 ("file boundary" if g.get("missing_s") is None else f"{g['missing_s']:.6g}", {"class": "num"})]
                for g in shown]
        out.append("<h3>Gaps</h3>" + html_table(["before sample", "missing (s)"], rows)
                   + (f'<p class="legend">the first 50 of {len(gaps)} gaps</p>' if len(gaps) > 50 else ""))
    notes = data.get("notes") or []
    if notes:
        out.append("<h3>Notes from the reader</h3><ul>" + "".join(f"<li>{esc(x)}</li>" for x in notes) + "</ul>")
    out.append("</section>")
    return "\n".join(out)


def _static_section(data: dict) -> str:
    still = data.get("static_check")
    out = ['<section id="static"><h2>Is the record static?</h2>']
    if still is None:
        out.append("<p>" + _badge("not checked", "none") + " the payload holds no static check.</p></section>")
        return "\n".join(out)
    if still.get("static"):
        out.append("<p>" + _badge("static", "good") + " no channel moved beyond its noise: the fits' assumption "
                   "of a sensor at rest holds as far as this check sees.</p>")
    else:
        out.append("<p>" + _badge("NOT STATIC", "bad") + " the record does not look like a sensor at rest; " +
                   (esc(still["not_fitted"]) + "." if still.get("not_fitted") else
                    "the fits below assume rest, so a poor fit is expected for this reason.") + "</p>")
        out.append("<ul>" + "".join(f"<li>{esc(r)}</li>" for r in still.get("reasons") or []) + "</ul>")
    limit = still.get("spread_limit")
    rows = []
    for name, ch in (still.get("channels") or {}).items():
        moved = ", ".join(f"{a:.0f}-{b:.0f} s" for a, b in ch.get("moved_s") or []) or "-"
        rows.append([name, (_g(ch.get("spread_ratio")), {"class": "num"}), (_g(ch.get("level_z_max")), {"class": "num"}),
                     (_g(ch.get("level_threshold")), {"class": "num"}), (str(ch.get("n_windows", "?")), {"class": "num"}),
                     moved])
    if rows:
        out.append(html_table(["channel", f"spread ratio (limit {_g(limit)})", "largest level jump (sigma)",
                               "level limit (sigma)", "windows", "moved"], rows))
        out.append(f'<p class="legend">windows of {_g(still.get("window_s"))} s; a spread ratio near 1 is noise at '
                   "rest, above the limit the means wander; a level jump beyond its limit is a move (Bonferroni over "
                   f"the windows at family-wise level {_g(still.get('family_level'))}).</p>")
    out.append("</section>")
    return "\n".join(out)


def _quality_section(est) -> str:
    """The record's quality flags (``record_quality`` of the record's facts, :mod:`avbench.recordings.quality`)."""
    rq = est.extra.get("record_quality")
    if rq is None:
        return ""
    out = ['<section id="quality"><h2>Is the record what the fits assume?</h2>']
    if rq.get("ok"):
        out.append("<p>" + _badge("no flag", "good") + " no spikes, clipping, raw counts, implausible mean, dominant "
                   "rounding or moving noise level seen.</p>")
    else:
        out.append("<p>" + _badge("RECORD FLAGGED: " + ", ".join(rq.get("flagged") or []), "bad") + " the fits below "
                   "assume a record without these.</p>")
        rows = [[f["name"], f["channel"], f["finding"], f["todo"]] for f in rq.get("flags") or []]
        out.append(html_table(["flag", "channel", "what was seen", "what to do"], rows))
    out.append("</section>")
    return "\n".join(out)


def _coefficient_table(est, sensor: str, table, footnotes) -> str:
    """The screen's table of one sensor as HTML: the same cells, each with the fit it shows
    (``data-sensor``, ``data-axis``, ``data-method``, ``data-coef``) and its status as a class."""
    cols = [c for c in table.columns if c != "notes"]
    rows, classes = [], []
    for (axis, method), r in table.iterrows():
        result = est.fits[sensor][axis][method].result
        row = [axis, method]
        for col in cols:
            c = col.split(" ", 1)[0]
            flag = result.coefficients[c].status
            row.append((r[col], {"class": "num st-" + flag.replace(" ", "-"), "data-sensor": sensor, "data-axis": axis,
                                 "data-method": method, "data-coef": c}))
        row.append(r["notes"])
        rows.append(row)
        classes.append("poor" if result.fit_check.poor_fit else None)
    out = html_table(["axis", "method", *cols, "notes"], rows, classes)
    if footnotes:
        out += '<ol class="notes">' + "".join(f"<li>{esc(x)}</li>" for x in footnotes) + "</ol>"
    return out


def _status_details(est, sensor: str) -> str:
    """A table of every coefficient the record does not resolve -- the rule that decided, the fit's
    own number -- and of every term whose evidence the method tests (a non-physical or failed value is
    a footnote of the coefficient table already; a bound is in its cell); the evidence column only
    where a method tests a term."""
    from avbench.estimators.results import REASONS
    from avbench.recordings.report import in_unit

    units = est.units(sensor)
    rows = []
    for axis, per_method in est.fits[sensor].items():
        for method, fit in per_method.items():
            for c, e in fit.result.coefficients.items():
                ev = e.evidence
                if e.status != "not resolved" and ev is None:
                    continue
                own = "-"
                fitted = in_unit(c, e.fitted, units[c], sensor) if e.status == "not resolved" else None
                if fitted is not None:
                    own = f"{fitted:.3g} {units[c]}"
                evidence = "-"
                if ev is not None:
                    p = ev.p_value
                    ptext = "p = ?" if not math.isfinite(p) else ("p < 1e-6" if p < 1e-6 else f"p = {p:.2g}")
                    evidence = f"{'present' if ev.present else 'not shown'}, {ptext}"
                why = REASONS[e.reason] if e.status == "not resolved" and e.reason in REASONS else "-"
                rows.append([axis, method, c, e.status, why, (own, {"class": "num"}), evidence])
    if not rows:
        return ""
    header = ["axis", "method", "coefficient", "status", "why", "the fit's own value", "evidence (likelihood ratio test)"]
    if all(r[-1] == "-" for r in rows):  # no method tests a term's evidence: no empty column
        header, rows = header[:-1], [r[:-1] for r in rows]
    return "<h3>Not resolved, and the terms' evidence</h3>" + html_table(header, rows)


def _fit_check_table(est, sensor: str) -> str:
    """The fit check's verdict of every method on every axis, with its statistic and where it was fitted."""
    from avbench.recordings.report import fitted_on

    n = {a: int(x.size) for a, x in est.record(sensor).axes.items()}
    rows, classes = [], []
    for axis, per_method in est.fits[sensor].items():
        for method, fit in per_method.items():
            r = fit.result
            check = r.fit_check
            pf = check.poor_fit
            verdict = "failed" if r.failure else {True: "POOR FIT", False: "fits", None: "no check"}[pf]
            stat = check.reading or (f"{_g(check.stat)} against {check.reference}"
                                     if pf is not None and math.isfinite(check.stat) else "-")
            p = check.pvalue if pf is not None else math.nan
            ptext = "-" if not math.isfinite(p) else ("< 1e-6" if p < 1e-6 else f"{p:.3g}")
            rows.append([axis, method, (verdict, {"class": "nowrap"}), stat, (ptext, {"class": "num"}),
                         fitted_on(fit, n[axis]), (f"{fit.seconds:.3g}", {"class": "num"}), r.failure or ""])
            classes.append("poor" if pf or r.failure else None)
    return "<h3>Fit check</h3>" + html_table(["axis", "method", "verdict", "statistic", "p-value", "fitted on",
                                                "time (s)", "failure"], rows, classes) + \
        '<p class="legend">POOR FIT: the model misses the Allan variance beyond its intervals (the chi-square type ' \
        'check of each method, p &lt; its level); "no check": the method makes none.</p>'


def _sensor_section(est, sensor: str, table, footnotes, fig) -> str:
    from avbench.noise_models.units import TERM_NAMES
    from avbench.recordings.report import level_text

    s = est.record(sensor)
    terms = ", ".join(f"{c} = {n}" for c, n in TERM_NAMES[sensor].items())
    level = level_text(est)
    out = [f'<section id="sensor-{esc(_anchor(sensor))}"><h2>{esc(sensor)}</h2>',
           f'<p class="sub">samples in {esc(s.unit_in)} (SI: {esc(s.si_unit)}); {esc(terms)}</p>']
    caption = ("Allan deviation (points, 68 % chi-square bars) with each method's model (dashed, over the scales "
               "it fitted) and the first method's terms (dotted); under it the fit check's standardised residuals "
               "z per tau with the +-2 band. Click a figure to enlarge it.")
    if isinstance(fig, dict):  # one figure per axis
        out.append('<div class="figs">' + "".join(
            png_img(f, f"Allan deviation of {sensor} {axis} with each method's model curve, and the fit check's "
                       f"residuals under it", f"{sensor} {axis}", sharp=1.5) for axis, f in fig.items()) + "</div>")
        out.append(f'<p class="legend">{esc(caption)}</p>')
    elif fig is not None:
        out.append(png_img(fig, f"Allan deviation of each {sensor} axis with each method's model curve, and the fit "
                                "check's residuals under it", caption))
    out.append("<h3>Coefficients</h3>")
    out.append(f'<p class="legend">value [{level} % interval]; "&lt; x": not resolved by this record, x its upper '
               f'{level} % bound (its interval reaches zero, or the record does not show the term); "(+- s)": a '
               'standard error only; "(no interval)": an estimate not tested against zero; "-": not in the '
               'method\'s model; notes: the '
               "footnotes under the table.</p>")
    out.append(_coefficient_table(est, sensor, table, footnotes))
    out.append(_status_details(est, sensor))
    out.append(_fit_check_table(est, sensor))
    out.append("</section>")
    return "\n".join(out)


def _combine_section(data: dict, units) -> str:
    """The agreement test of ``--combine`` and the between-run spread, each coefficient in ``units(sensor)``
    (the unit of the sensor's coefficient table)."""
    from avbench.noise_models.units import from_si

    if "combine" not in data and "between_runs" not in data:
        return ""
    out = ['<section id="runs"><h2>Several recordings</h2>']
    rows = []
    for sensor, per_axis in (data.get("combine") or {}).items():
        for axis, a in per_axis.items():
            verdict = "agree" if a.get("agree") else ("DISAGREE" if a.get("agree") is not None else "not testable")
            rows.append([sensor, axis, verdict, ("-" if a.get("p_value") is None else f"{a['p_value']:.3g}", {"class": "num"}),
                         a.get("note") or ""])
    if rows:
        out.append("<h3>Do the recordings agree?</h3>" + html_table(["sensor", "axis", "verdict", "p-value", "test"], rows))
    br = data.get("between_runs")
    if br:
        rows = []
        for sensor, per_axis in br.get("sensors", {}).items():
            for axis, per_coef in per_axis.items():
                for c, r in per_coef.items():
                    if r.get("tau") is None:
                        continue
                    unit = units(sensor)[c]

                    def d(v, c=c, unit=unit, sensor=sensor):
                        return "?" if v is None else f"{from_si(c, v, unit, sensor):.4g}"

                    lo, hi = r.get("tau_ci") or (None, None)
                    pred = r.get("prediction")
                    rows.append([sensor, axis, c, unit, (f"{d(r['mean'])} +- {d(r.get('mean_se'))}", {"class": "num"}),
                                 (str(r.get("k")), {"class": "num"}), (d(r["tau"]), {"class": "num"}),
                                 (f"{d(lo)} to {d(hi)}", {"class": "num"}),
                                 (f"{d(pred[0])} to {d(pred[1])}" if pred else "-", {"class": "num"})])
        out.append(f"<h3>Between-run spread ({esc(br.get('method', '?'))} on each recording alone; random effects, "
                   "DerSimonian &amp; Laird 1986)</h3>")
        out.append(html_table(["sensor", "axis", "coefficient", "unit", "mean", "runs", "between-run SD",
                               "SD 95 % interval", "a new run (95 %)"], rows))
        if "inflate" in br:
            out.append("<p>--inflate auto: " + esc(", ".join(f"{k} x {v:.3g}" for k, v in br["inflate"].items())) + "</p>")
    out.append("</section>")
    return "\n".join(out)


#: the formats whose file holds Kalibr's four keys (:data:`avbench.recordings.filter_yaml.KEYS`)
KALIBR_KEY_FORMATS = ("kalibr", "allan_variance_ros", "openvins")


def _values_section(tables: dict, exports: dict | None) -> str:
    """Each written format's own keys, values and units (``tables``: ``{name: [Entry]}``,
    :func:`avbench.recordings.exports.tables`), one table per format under its file's name."""
    out = ['<section id="filter"><h2>Filter values</h2>',
           '<p class="legend">each format\'s keys, values and units as its file writes them (the files '
           "themselves under Exports).</p>"]
    for name, entries in tables.items():
        filename = (exports or {}).get(name, (name,))[0]
        rows = [[e.key, (f"{e.value:.6g}", {"class": "num"}), e.unit, e.axis, e.bound or ""] for e in entries]
        header = ["key", "value", "unit", "axis", "a bound, not an estimate"]
        if not any(r[-1] for r in rows):
            header, rows = header[:-1], [r[:-1] for r in rows]
        out.append(f"<h3>{esc(filename)} <span class=\"fmt\">{esc(name)}</span></h3>" + html_table(header, rows))
    out.append("</section>")
    return "\n".join(out)


def _filter_section(data: dict, exports: dict | None) -> str:
    """Kalibr's keys as the files that hold them write them (each value with its unit, inflated as
    written), where such a file was written; every other format's keys are its own, in its block
    under Exports."""
    from avbench.recordings.exports.base import factor
    from avbench.recordings.filter_yaml import KEYS, UNITS

    fy = data.get("filter_yaml")
    if not fy:
        return ""
    text = fy if isinstance(fy, str) else fy.get("text")
    kalibr_files = [n for n in (exports or {}) if n in KALIBR_KEY_FORMATS]
    if not text and not kalibr_files:
        return ""
    shown_texts = {t for _, t in (exports or {}).values()}
    out = ['<section id="filter"><h2>Kalibr keys</h2>']
    if isinstance(fy, dict):
        inflate = fy.get("inflate")
        pair = tuple(inflate) if isinstance(inflate, list) else inflate
        where = ", ".join(kalibr_files) if kalibr_files else "imu.yaml"
        out.append(f"<p>as written in {esc(where)}: values from <code>{esc(fy.get('method', '?'))}</code>, the "
                   "largest over the axes" + ("; not inflated" if pair in (None, (1.0, 1.0)) else "; inflated as the "
                                              "file says") + "</p>")
        sensor_coef = {k: sc for sc, k in KEYS.items()}
        bounds = fy.get("bounds") or {}
        rows = []
        for k, v in (fy.get("values_si") or {}).items():
            f = factor(pair if pair is not None else (1.0, 1.0), *sensor_coef[k])
            rows.append([k, (f"{v * f:.6g}" if v is not None else "?", {"class": "num"}), UNITS[k], bounds.get(k, "")])
        if rows:
            header = ["key", "value", "unit", "a bound, not a resolved value"]
            if not any(r[-1] for r in rows):
                header, rows = header[:-1], [r[:-1] for r in rows]
            out.append(html_table(header, rows))
    if text and text not in shown_texts:
        out.append(copy_block("imu.yaml", text, "filter-yaml", label="kalibr"))
    out.append("</section>")
    return "\n".join(out)


def _exports_section(exports: dict | None) -> str:
    if not exports:
        return ""
    out = ['<section id="exports"><h2>Exports</h2>',
           '<p class="legend">each block is a file of the named format, ready to copy into the stack that reads it.</p>']
    for i, (name, (filename, text)) in enumerate(exports.items()):
        out.append(copy_block(filename, text, f"export-{i}", label=name))
    out.append("</section>")
    return "\n".join(out)


def recording_page(est, figures: dict, exports: dict | None = None, title: str | None = None,
                   tables: dict | None = None) -> str:
    """The self-contained HTML page of one recording (see the module docstring).

    ``est``: the fits and the record's facts (:class:`avbench.recordings.report.Estimate`);
    ``figures``: ``{sensor: matplotlib Figure or PNG bytes}``, or ``{sensor: {axis: Figure}}`` (one figure
    per axis, each readable from a narrow window up; a sensor without one has no figure);
    ``exports``: ``{name: (file name, text)}`` of the stack formats, each shown in a block with a copy
    button; ``title``: the page's heading (default: the sources); ``tables``: ``{name: [Entry]}``, the
    numbers each format writes under its own keys (:func:`avbench.recordings.exports.tables`), one
    table each. Returns the page as a string.

    >>> import numpy as np
    >>> from avbench.noise_models import AngleRandomWalk, Gyro
    >>> from avbench.recordings import report
    >>> from avbench.recordings.fit import fit_axis
    >>> from avbench.recordings.sensors import SensorRecord
    >>> from avbench.recordings.timing import Timing
    >>> x = Gyro(dt=0.01, terms=[AngleRandomWalk(N=1e-3)]).simulate(4096, np.random.default_rng(0))
    >>> s = SensorRecord("gyro", "rad/s", {"x": x}, {})
    >>> fits = {"gyro": {"x": fit_axis(x, 0.01, np.zeros(0, dtype=np.int64), ["wls"])}}
    >>> est = report.Estimate(["sim <1>"], Timing(0.01, "--fs", 4096), [s], fits)
    >>> page = recording_page(est, {}, {"kalibr": ("imu.yaml", "a: 1 # <b>")})
    >>> page.startswith("<!DOCTYPE html>"), "sim &lt;1&gt;" in page, "# &lt;b&gt;" in page
    (True, True, True)
    """
    from avbench.estimators.results import jsonable
    from avbench.recordings.report import SCHEMA, screen_tables

    figures = figures or {}
    coefficient_tables = screen_tables(est)
    data = {"sources": [str(x) for x in est.sources], "timing": jsonable(est.timing.to_dict()),
            **jsonable(est.extra), "notes": est.notes}  # the record's facts
    nav = [("record", "record"), ("static", "static check")]
    body = [_record_section(data), _static_section(data)]
    quality = _quality_section(est)
    if quality:
        nav.append(("quality", "record checks"))
        body.append(quality)
    for sensor, (table, footnotes) in coefficient_tables.items():
        nav.append((f"sensor-{_anchor(sensor)}", sensor))
        body.append(_sensor_section(est, sensor, table, footnotes, figures.get(sensor)))
    combine = _combine_section(data, est.units)
    if combine:
        nav.append(("runs", "several recordings"))
        body.append(combine)
    filt = _values_section(tables, exports) if tables else _filter_section(data, exports)
    if filt:
        nav.append(("filter", "filter values"))
        body.append(filt)
    ex = _exports_section(exports)
    if ex:
        nav.append(("exports", "exports"))
        body.append(ex)
    body.append(f'<footer>avbench {esc(avbench_version())} &middot; payload schema {esc(SCHEMA)} &middot; '
                "a self-contained page: it loads nothing from the network.</footer>")
    sources = ", ".join(data.get("sources") or [])
    return document(title or f"avbench estimate: {sources}", "\n".join(body),
                    subtitle="noise coefficients of a static IMU recording, every axis, every method", nav=nav)
