"""The pages a person opens: the recording's page (:mod:`avbench.recordings.html`) and the study's
(:mod:`avbench.studies.html`).

Read as HTML (:mod:`html.parser`): every cell of a recording's coefficient table is the screen's cell
of the fit it names, and its numbers are the fit's; every table of a study's page is its
markdown file's and the numbers of ``table.md`` are those of ``table.csv``; every text from the data is
escaped; nothing refers to the network.

Opened in a real browser (Debian's ``chromium``, headless; skipped, saying so, only where no chromium
binary is on the PATH): a copy of each page with a probe script added writes what the browser made of
it -- each image's natural size, each table cell's rendered text, the copy button's answer to a click
-- into the DOM, which ``--dump-dom`` prints. The browser's own logs say the rest:
``--enable-logging=stderr`` prints every console message of the page (an error, a blocked load, a
script exception) as a ``CONSOLE`` line, and ``--log-net-log`` records every request, the page's
own being those whose network isolation key is the page's ``file://`` site; the host resolver maps
every name to nothing, so no request leaves the machine. A control page with a console error, an
external image and a broken image shows that each of these detectors fires.
"""

from __future__ import annotations

import base64
import hashlib
import json
import math
import re
import shutil
import subprocess
import time
import warnings
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest

from avbench.noise_models.units import COEFFICIENTS

CHROMIUM = next((p for p in map(shutil.which, ("chromium", "chromium-browser", "google-chrome")) if p), None)
needs_browser = pytest.mark.skipif(CHROMIUM is None, reason="no chromium binary on the PATH (CI installs Debian's "
                                   "chromium: apt-get install -y chromium)")

NASTY_TITLE = "imu <script>document.title='pwned'</script>"
NASTY_FILE = "imu<img src=x onerror=document.title='pwned'>.csv"
NASTY_EXPORT = ("kalibr_<script>window.pwned=1</script>.yaml",
                "gyroscope_noise_density: 1.0e-3  # </pre><script>document.title='pwned'</script>\n")


# -- reading a page --------------------------------------------------------------------------------------
class Page(HTMLParser):
    """What a page holds: its elements (tag, attributes), its text, its table cells by table, the
    coefficient cells (with their ``data-*`` attributes), the scripts' texts and the footnotes."""

    def __init__(self, text: str):
        super().__init__(convert_charrefs=True)
        self.elements, self.text, self.tables, self.coef, self.scripts, self.notes = [], [], [], [], [], []
        self._cell = self._script = self._note = None
        self._in_notes = False
        self.feed(text)
        self.close()

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        self.elements.append((tag, a))
        if tag == "table":
            self.tables.append([])
        elif tag == "tr" and self.tables:
            self.tables[-1].append([])
        elif tag in ("td", "th"):
            self._cell = [a, []]
        elif tag == "script":
            self._script = []
        elif tag == "ol" and "notes" in (a.get("class") or ""):
            self._in_notes = True
        elif tag == "li" and self._in_notes:
            self._note = []

    def handle_endtag(self, tag):
        if tag in ("td", "th") and self._cell is not None:
            a, parts = self._cell
            text = "".join(parts).strip()
            self.tables[-1][-1].append(text)
            if "data-coef" in a:
                self.coef.append(((a["data-sensor"], a["data-axis"], a["data-method"], a["data-coef"]), text))
            self._cell = None
        elif tag == "script" and self._script is not None:
            self.scripts.append("".join(self._script))
            self._script = None
        elif tag == "ol":
            self._in_notes = False
        elif tag == "li" and self._note is not None:
            self.notes.append("".join(self._note).strip())
            self._note = None

    def handle_data(self, data):
        if self._script is not None:
            self._script.append(data)
            return
        self.text.append(data)
        if self._cell is not None:
            self._cell[1].append(data)
        if self._note is not None:
            self._note.append(data)

    @property
    def all_text(self) -> str:
        return "".join(self.text)


def _assert_self_contained(page: Page, raw: str):
    """Nothing in the page refers to the network: every src a data: PNG, every href an anchor in the
    page, no <link>, <iframe>, <object> or <embed>, no url( or @import in a style, no http(s) in any
    attribute; one script, the copy script, allowed by the CSP through its hash; no event handler."""
    from avbench.recordings.html import COPY_SCRIPT, CSP

    tags = [t for t, _ in page.elements]
    assert not {"link", "iframe", "object", "embed", "base", "form"} & set(tags)
    for tag, a in page.elements:
        for k, v in a.items():
            assert not k.startswith("on"), (tag, k)
            assert "http://" not in (v or "") and "https://" not in (v or ""), (tag, k, v)
        if "src" in a:
            assert a["src"].startswith("data:image/png;base64,"), (tag, a["src"][:60])
        if "href" in a:
            assert a["href"].startswith("#"), (tag, a["href"])
    style = raw[raw.index("<style>"):raw.index("</style>")]
    assert "url(" not in style and "@import" not in style
    assert page.scripts == [COPY_SCRIPT]
    csp = [a["content"] for t, a in page.elements if t == "meta" and a.get("http-equiv") == "Content-Security-Policy"]
    assert csp == [CSP] and "default-src 'none'" in CSP
    digest = base64.b64encode(hashlib.sha256(COPY_SCRIPT.encode()).digest()).decode()
    assert f"'sha256-{digest}'" in CSP


# -- the inputs: a simulated 6-axis recording, a tiny finished study --------------------------------------
@pytest.fixture(scope="module")
def recording():
    """(payload, the gyro's figure as PNG bytes, exports) of a 2-minute 6-axis record at 100 Hz with one gap of
    0.5 s, from a source whose name holds markup, fitted by three methods (a value without an
    interval, with one, with the terms' evidence) as ``avbench estimate`` fits it."""
    import matplotlib

    matplotlib.use("Agg")

    from avbench.noise_models import AngleRandomWalk, BiasInstability, Gyro, RateRandomWalk
    from avbench.recordings import figure, report
    from avbench.recordings.estimate import fit_sensors
    from avbench.recordings.fit import scaled_allan
    from avbench.recordings.sensors import SensorRecord
    from avbench.recordings.static import static_check
    from avbench.recordings.timing import Timing

    rng = np.random.default_rng(3)
    n, dt = 12_000, 0.01
    g = Gyro(dt=dt, terms=[AngleRandomWalk(N=2e-3), BiasInstability(B=5e-5, tau_max=n * dt), RateRandomWalk(K=2e-5)])
    a = Gyro(dt=dt, terms=[AngleRandomWalk(N=1e-3), RateRandomWalk(K=1e-5)])
    sensors = [SensorRecord("gyro", "rad/s", {ax: g.simulate(n, rng) for ax in "xyz"}, {ax: f"g{ax}" for ax in "xyz"}),
               SensorRecord("accel", "m/s^2", {ax: a.simulate(n, rng) + (9.81 if ax == "z" else 0.0) for ax in "xyz"},
                            {ax: f"a{ax}" for ax in "xyz"})]
    timing = Timing(dt, "time stamps", n, starts=np.array([n // 2]), gap_seconds=np.array([0.5]), jitter=1e-4,
                    max_deviation=3e-4)
    avs = {s.sensor: {ax: scaled_allan(x, dt, timing.starts) for ax, x in s.axes.items()} for s in sensors}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with np.errstate(all="ignore"):
            fits = fit_sensors(sensors, timing, ["wls", "gmwm", "whittle_debiased"])
    extra = {"format": "text", "topic": None, "time_source": "column 't' (s)", "notes": ["a note <b>with markup</b>"],
             "static_check": static_check(sensors, dt, avs)}
    est = report.Estimate([NASTY_FILE], timing, sensors, fits, extra)
    gyro = sensors[0]  # the gyro's figure only (drawing is the slow part); the accelerometer has none
    flags = {ax: {m: f.result.fit_check.poor_fit for m, f in fits["gyro"][ax].items()} for ax in gyro.axes}
    figures = {"gyro": {ax: figure.figure(gyro, fits["gyro"], avs["gyro"], dt, NASTY_FILE, flags, axes=[ax])
                        for ax in gyro.axes}}  # one figure per axis, as avbench estimate --html draws them
    exports = {"kalibr": NASTY_EXPORT, "openvins": ("kalibr_imu_chain.yaml", "imu0:\n  update_rate: 100.0\n")}
    return est, figures, exports


@pytest.fixture(scope="module")
def recording_html(recording):
    from avbench.recordings.html import recording_page

    data, figures, exports = recording
    import matplotlib.pyplot as plt

    page = recording_page(data, figures, exports, title=NASTY_TITLE)
    for f in figures["gyro"].values():
        plt.close(f)
    return page


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    """The folder of a finished two-gyro, two-estimator study of 3 replicates of 3000 samples."""
    from conftest import study_toml

    from avbench.studies.config import load_config
    from avbench.studies.runner import run_study

    root = tmp_path_factory.mktemp("study")
    (root / "study.toml").write_text(study_toml(replicates=3, block_size=3, n_samples=3000))
    run_study(load_config(root / "study.toml"), root / "out", n_jobs=1, progress=False)
    return root / "out"


# -- the recording's page ----------------------------------------------------------------------------------
def _first_numbers(text: str) -> list[float]:
    return [float(x) for x in re.findall(r"[-+]?\d+(?:\.\d+)?(?:e[-+]?\d+)?", text)]


def test_every_coefficient_cell_is_the_fits(recording, recording_html):
    from avbench.noise_models.units import from_si
    from avbench.recordings.report import screen_tables, shown_value

    est = recording[0]
    page = Page(recording_html)
    cells = dict(page.coef)
    assert len(cells) == len(page.coef)  # one cell per (sensor, axis, method, coefficient)
    expected = {}
    for sensor, axes in est.fits.items():
        modelled = [c for c in COEFFICIENTS if any(f.result.coefficients[c].status != "not modelled"
                                                   for per in axes.values() for f in per.values())]
        for axis, per in axes.items():
            for method, fit in per.items():
                for c in modelled:
                    expected[(sensor, axis, method, c)] = fit.result.coefficients[c]
    assert set(cells) == set(expected)
    n_values = 0
    for key, e in expected.items():
        sensor, _, _, c = key
        unit = est.units(sensor)[c]
        assert cells[key] == shown_value(e, unit, sensor), key
        # and the numbers themselves, read back from the cell, are the fit's at the digits shown
        if e.status == "ok":
            nums = _first_numbers(cells[key])
            assert math.isclose(nums[0], float(f"{from_si(c, e.value, unit, sensor):.3g}"), rel_tol=1e-12), key
            if e.interval is not None:
                iv = [from_si(c, v, unit, sensor) for v in e.interval]
                assert np.allclose(nums[1:3], [float(f"{v:.3g}") for v in iv], rtol=1e-12, atol=0), key
            n_values += 1
        elif e.status == "not resolved" and e.interval is not None:
            bound = from_si(c, e.interval[1], unit, sensor)
            assert math.isclose(_first_numbers(cells[key])[0], float(f"{bound:.3g}"), rel_tol=1e-12), key
    assert n_values > 10
    # the footnotes are the screen's, in its order
    assert page.notes == [n for _, (_, notes) in screen_tables(est).items() for n in notes]


def test_the_page_shows_the_record_the_static_check_and_the_figures(recording, recording_html):
    est, figures, _ = recording
    page = Page(recording_html)
    text = page.all_text
    assert f"{est.timing.n_samples}" in text and "1 (0.5 s missing)" in text
    assert "static" in text and "gyro x" in text and "accel magnitude" in text
    assert "Fit check" in text and ("POOR FIT" in text or "fits" in text)
    assert "a note <b>with markup</b>" in text  # the reader's notes, as text
    tables = page.tables
    evidence = [t for t in tables if t and t[0][-1] == "evidence (likelihood ratio test)"]
    assert evidence and any(r[3] == "not resolved" for t in evidence for r in t[1:])
    assert any(r[-1].startswith("present, p") for t in evidence for r in t[1:])  # whittle_debiased tests each term
    imgs = [a for t, a in page.elements if t == "img"]
    assert len(imgs) == len(figures["gyro"])  # one per axis, each a PNG shown at its 110 dpi width
    for a in imgs:
        png = base64.b64decode(a["src"].split(",", 1)[1])
        assert png[:8] == b"\x89PNG\r\n\x1a\n" and int.from_bytes(png[16:20], "big") > int(a["width"]) > 500
    for name, (filename, body) in recording[2].items():
        assert filename in text and body in text  # each export under its file name, verbatim


def test_every_text_is_escaped(recording_html):
    page = Page(recording_html)
    text = page.all_text
    assert NASTY_TITLE in text and NASTY_FILE in text and NASTY_EXPORT[0] in text and NASTY_EXPORT[1] in text
    assert [t for t, _ in page.elements].count("script") == 1  # the copy script, nothing injected
    assert not any(t == "img" and "onerror" in a for t, a in page.elements)
    assert "<script>document" not in recording_html and "<script>window" not in recording_html


def test_nothing_refers_to_the_network(recording_html, study):
    from avbench.studies.html import study_page

    _assert_self_contained(Page(recording_html), recording_html)
    raw = study_page(study)
    _assert_self_contained(Page(raw), raw)


def test_a_rule_catches_an_external_resource(recording_html):
    bad = recording_html.replace("</main>", '<img src="https://cdn.example.org/x.png"></main>')
    with pytest.raises(AssertionError):
        _assert_self_contained(Page(bad), bad)


def test_the_stack_exports_show_as_copy_blocks(recording):
    """The files of :func:`avbench.recordings.exports.render` as the page's blocks, each verbatim under its name."""
    exports = pytest.importorskip("avbench.recordings.exports")
    from avbench.recordings.html import recording_page

    est, figures, _ = recording
    rendered = exports.render(est.results(), "kalibr,vins", "gmwm", est.timing.fs)
    files = {name: ("imu" + suffix, text) for name, (suffix, text) in rendered.items()}
    page = Page(recording_page(est, figures, files))
    pres = {a["id"]: a for t, a in page.elements if t == "pre"}
    buttons = [a["data-target"] for t, a in page.elements if t == "button"]
    assert sorted(buttons) == sorted(pres) and len(buttons) == 2
    for filename, text in files.values():
        assert filename in page.all_text and text in page.all_text


def test_several_recordings_and_the_filter_yaml(recording):
    """The parts of ``--combine`` and ``--kalibr``: the agreement test, the between-run spread in
    display units, the yaml's values and its text (shown once when an export holds the same text)."""
    from avbench.recordings.html import recording_page

    import dataclasses

    extra = dict(recording[0].extra)
    extra["combine"] = {"gyro": {"x": {"p_value": 0.31, "agree": True, "n_taus": 6, "worst_tau_s": 2.0, "note": "chi^2"},
                                "y": {"p_value": None, "agree": None, "n_taus": 0, "worst_tau_s": None, "note": "few"}}}
    n_si = np.deg2rad(0.1) / 60  # 0.1 deg/sqrt(h) in rad/sqrt(s)
    extra["between_runs"] = {"method": "gmwm", "inflate": {"gyroscope_noise_density": 1.25}, "sensors": {"gyro": {"x": {
        "N": {"k": 3, "mean": n_si, "mean_se": 0.01 * n_si, "tau": 0.05 * n_si, "tau_ci": [0.0, 0.2 * n_si],
              "cv": 0.05, "prediction": [0.8 * n_si, 1.2 * n_si]}}}}}
    yaml = "gyroscope_noise_density: 2.9e-05  # <unit>\n"
    extra["filter_yaml"] = {"method": "gmwm", "inflate": [1.0, 1.0], "values_si": {"gyroscope_noise_density": 2.9e-5},
                           "bounds": {}, "text": yaml}
    data = dataclasses.replace(recording[0], extra=extra)
    page = Page(recording_page(data, {}))
    text = page.all_text
    assert "agree" in text and "not testable" in text and "gyroscope_noise_density x 1.25" in text
    spread = next(t for t in page.tables if t[0][:3] == ["sensor", "axis", "coefficient"])
    assert spread[1][3:5] == ["deg/sqrt(h)", "0.1 +- 0.001"] and spread[1][-1] == "0.08 to 0.12"
    assert text.count(yaml) == 1
    assert Page(recording_page(data, {}, {"kalibr": ("imu.yaml", yaml)})).all_text.count(yaml) == 1


def test_a_minimal_payload_renders():
    """A payload without the optional parts (no static check, no notes, no exports, no figure)."""
    from avbench.recordings import report
    from avbench.recordings.fit import fit_axis
    from avbench.recordings.html import recording_page
    from avbench.recordings.sensors import SensorRecord
    from avbench.recordings.timing import Timing

    x = np.random.default_rng(0).normal(0, 1e-3, 4096)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fits = {"gyro": {"x": fit_axis(x, 0.01, np.zeros(0, dtype=np.int64), ["wls"])}}
    est = report.Estimate(["sim"], Timing(0.01, "--fs", 4096), [SensorRecord("gyro", "rad/s", {"x": x}, {})], fits)
    page = Page(recording_page(est, {}))
    assert "not checked" in page.all_text and len(page.coef) >= 3
    assert not any(t == "img" for t, _ in page.elements)


# -- the study's page --------------------------------------------------------------------------------------
def _plain(md_cell: str) -> str:
    return md_cell.replace("**", "").replace("`", "").replace("*", "")


def _md_tables(text: str) -> list[list[list[str]]]:
    """The pipe tables of a markdown file, each as rows of cells (the rule row dropped)."""
    tables, current = [], None
    for line in text.splitlines():
        if line.startswith("|"):
            if current is None:
                current = []
                tables.append(current)
            if not re.fullmatch(r"\|(-+\|)+", line.strip()):
                current.append([_plain(c.strip()) for c in line.strip().strip("|").split("|")])
        else:
            current = None
    return tables


def test_the_study_page_holds_every_table_and_figure(study):
    from avbench.studies.html import study_page
    from avbench.studies.report import paper_layout, read_summary

    raw = study_page(study)
    page = Page(raw)
    md = [t for name in ("table.md", "leaderboard.md", "scores.md", "timings.md") if (study / name).is_file()
          for t in _md_tables((study / name).read_text())]
    assert page.tables[1:] == md  # the first table: the study's gyros (meta.json)
    # the numbers of table.md are those of table.csv, in the papers' layout
    summary, meta = read_summary(study)
    for (_, _, cols, rows), table in zip(paper_layout(summary, meta), page.tables[1:]):
        assert table[0] == ["", *cols]
        assert [[_plain(label), *cells] for _, label, cells in rows] == table[1:]
    pngs = sorted(n for n in meta["outputs"] if n.endswith(".png"))
    srcs = [base64.b64decode(a["src"].split(",", 1)[1]) for t, a in page.elements if t == "img"]
    assert len(pngs) == 4 and sorted(srcs) == sorted((study / n).read_bytes() for n in pngs)
    assert "Study tiny" in page.all_text and "Who wins where" in page.all_text


def test_the_study_page_refuses_an_incomplete_report(study, tmp_path):
    from avbench.studies.html import study_page

    copy = tmp_path / "copy"
    shutil.copytree(study, copy, ignore=shutil.ignore_patterns("_shards"))
    (copy / "table.md").write_text((copy / "table.md").read_text() + "\n| edited | 1 |\n")
    with pytest.raises(ValueError, match="table.md does not belong"):
        study_page(copy)


def test_markdown_is_escaped():
    from avbench.studies.html import markdown_html

    out = markdown_html("# t <script>x()</script>\n\n| a <b> | **b** & *c* |\n|---|---|\n| `<i>` | 1 |\n\ntext <img src=x>")
    page = Page(out)
    assert [t for t, _ in page.elements if t in ("script", "img", "b", "i")] == []
    assert page.tables == [[["a <b>", "b & c"], ["<i>", "1"]]]
    assert "t <script>x()</script>" in page.all_text and "text <img src=x>" in page.all_text


# -- in a real browser --------------------------------------------------------------------------------------
PROBE = """
window.addEventListener("load", function () {
  var out = {images: [], coef: [], tables: [], scripts: document.scripts.length, title: document.title, copy: null};
  out.width = window.innerWidth;
  out.scroll = document.documentElement.scrollWidth;
  out.body_px = parseFloat(getComputedStyle(document.body).fontSize);
  document.querySelectorAll("img").forEach(function (im) {
    out.images.push([im.naturalWidth, im.naturalHeight, im.getBoundingClientRect().width,
                     parseFloat(im.getAttribute("width")), parseFloat(im.dataset.textPx)]);
  });
  document.querySelectorAll("td[data-coef]").forEach(function (td) {
    out.coef.push([td.dataset.sensor, td.dataset.axis, td.dataset.method, td.dataset.coef, td.innerText]);
  });
  document.querySelectorAll("table").forEach(function (t) {
    var rows = [];
    t.querySelectorAll("tr").forEach(function (tr) {
      var r = [];
      tr.querySelectorAll("th, td").forEach(function (c) { r.push(c.innerText.trim()); });
      rows.push(r);
    });
    out.tables.push(rows);
  });
  function finish() {
    var p = document.createElement("pre");
    p.id = "avbench-probe";
    p.textContent = JSON.stringify(out);
    document.body.appendChild(p);
  }
  var b = document.querySelector("button.copy");
  if (b) { b.click(); setTimeout(function () { out.copy = b.textContent; finish(); }, 200); } else { finish(); }
});
"""

_FLAGS = ["--headless=new", "--disable-gpu", "--no-sandbox", "--enable-logging=stderr", "--v=0",
          "--host-resolver-rules=MAP * ~NOTFOUND", "--disable-background-networking", "--disable-component-update",
          "--disable-sync", "--no-first-run", "--no-default-browser-check", "--disable-extensions",
          "--disable-default-apps", "--virtual-time-budget=3000"]


def _with_probe(raw: str) -> str:
    """The page with :data:`PROBE` before ``</body>``, and the probe's hash added to the page's CSP."""
    digest = base64.b64encode(hashlib.sha256(PROBE.encode()).digest()).decode()
    out = raw.replace("script-src ", f"script-src &#x27;sha256-{digest}&#x27; ", 1)
    return out.replace("</body>", f"<script>{PROBE}</script>\n</body>", 1)


def _browse(raw: str, folder: Path, width: int = 1400) -> dict:
    """Open the page (with the probe) in headless chromium: the probe's findings, the page's console
    messages and the requests the page made (netlog events whose isolation key is the page's file:// site)."""
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "page.html"
    path.write_text(_with_probe(raw), encoding="utf-8")
    net = folder / "net.json"
    run = subprocess.run([CHROMIUM, *_FLAGS, f"--window-size={width},1000", f"--user-data-dir={folder / 'profile'}", f"--log-net-log={net}",
                          "--dump-dom", path.as_uri()], capture_output=True, text=True, timeout=60)
    console = [line for line in run.stderr.splitlines() if ":CONSOLE" in line and "source: file://" in line]
    events = json.loads(net.read_text())
    kinds = {v: k for k, v in events["constants"]["logEventTypes"].items()}
    requests = [e["params"]["url"] for e in events["events"] if kinds.get(e["type"]) == "URL_REQUEST_START_JOB"
                and "file://" in e["params"].get("network_isolation_key", "")]
    dom = Page(run.stdout)
    probe = [a for t, a in dom.elements if t == "pre" and a.get("id") == "avbench-probe"]
    assert probe, f"the probe wrote nothing (exit {run.returncode}): {run.stderr[-2000:]}"
    text = dom.all_text
    found = json.loads(text[text.rindex("{\"images\""):].strip())
    return {"probe": found, "console": console, "requests": requests}


@pytest.fixture(scope="module")
def browser_times():
    times = []
    yield times
    assert sum(times) < 30, f"the browser runs took {sum(times):.1f} s"


@needs_browser
def test_browser_detects_console_errors_external_requests_and_broken_images(tmp_path, browser_times):
    """The control: each detector fires on a page that has what it detects."""
    t0 = time.perf_counter()
    bad = ('<!DOCTYPE html><html><head><title>bad</title></head><body><img src="http://example.invalid/a.png">'
           '<img src="data:image/png;base64,AAAA"><script>console.error("boom")</script></body></html>')
    r = _browse(bad, tmp_path / "bad")
    assert any('"boom"' in line for line in r["console"])
    assert r["requests"] == ["http://example.invalid/a.png"]
    assert [im[0] for im in r["probe"]["images"]] == [0, 0]
    # the pages' own policy turns an external load into a console message, blocked before any request
    from avbench.recordings.html import document

    r = _browse(document("t", '<img src="https://cdn.example.org/x.png">'), tmp_path / "csp")
    assert r["requests"] == [] and any("Content Security Policy" in line for line in r["console"])
    browser_times.append(time.perf_counter() - t0)


@needs_browser
@pytest.mark.parametrize("width", [800, 1400])
def test_browser_recording_page(recording, recording_html, tmp_path, browser_times, width):
    """At a window 800 and 1400 px wide: nothing wider than the window, every figure's smallest text
    at least the body's size as shown, and every cell the fit's."""
    from avbench.recordings.report import shown_value

    t0 = time.perf_counter()
    r = _browse(recording_html, tmp_path, width)
    browser_times.append(time.perf_counter() - t0)
    assert r["console"] == [] and r["requests"] == []
    p = r["probe"]
    assert abs(p["width"] - width) < 40 and p["scroll"] <= p["width"], (p["scroll"], p["width"])
    assert len(p["images"]) == len(recording[1]["gyro"])
    for natural, height, shown, attr_width, text_px in p["images"]:
        assert natural > 500 and height > 200 and shown > 300
        assert text_px * shown / attr_width >= p["body_px"], (text_px, shown, attr_width, p["body_px"])
    assert p["scripts"] == 2 and p["title"] == NASTY_TITLE  # the copy script and the probe; the title as text
    assert p["copy"] != "copy"  # the copy script answered the click
    est = recording[0]
    assert len(p["coef"]) == len(Page(recording_html).coef) > 0
    for sensor, axis, method, c, text in p["coef"]:
        e = est.fits[sensor][axis][method].result.coefficients[c]
        assert text == shown_value(e, est.units(sensor)[c], sensor)


@needs_browser
def test_browser_study_page(study, tmp_path, browser_times):
    from avbench.studies.html import study_page

    raw = study_page(study)
    t0 = time.perf_counter()
    r = _browse(raw, tmp_path)
    browser_times.append(time.perf_counter() - t0)
    assert r["console"] == [] and r["requests"] == []
    p = r["probe"]
    assert len(p["images"]) == 4 and all(w > 300 and h > 200 and shown > 200 for w, h, shown, _, _ in p["images"])
    assert p["tables"] == Page(raw).tables  # the browser shows the cells the HTML holds
    md = _md_tables((study / "table.md").read_text())
    assert p["tables"][1:1 + len(md)] == md


# -- the filter values: each format's own keys, values and units --------------------------------------------
def _written_numbers(name: str, text: str) -> dict:
    """key -> number as the file writes it, read as its stack reads it (PyYAML for the YAML files, the
    parameter rows for PX4, the assignments of GTSAM's snippet)."""
    import yaml

    if name == "px4":
        return {k: float(v) for k, v in re.findall(r"^1\t1\t(\w+)\t(\S+)\t9$", text, re.M)}
    if name == "gtsam":
        return {k: float(v) for k, v in re.findall(r"^([A-Z_]+) = ([-+.\deE]+)", text, re.M)}
    if name == "matlab":  # gyro = gyroparams( 'NoiseDensity', [x y z], ...: one number per axis
        out = {}
        for var, body in re.findall(r"^(\w+) = \w+\( \.\.\.\n(.*?)\);", text, re.M | re.S):
            for prop, vector in re.findall(r"'(\w+)', \[([^\]]*)\]", body):
                out.update({f"{var}.{prop}({i + 1})": float(v) for i, v in enumerate(vector.split())})
        return out
    d = json.loads(text)["value0"] if name == "basalt" else \
        yaml.safe_load(text.split("\n", 1)[1] if text.startswith("%YAML") else text)
    d = d["imu0"] if name == "openvins" else d
    out = {}
    for k, v in d.items():  # a list: one number per element, key[i]
        out.update({f"{k}[{i}]": x for i, x in enumerate(v) if isinstance(x, float) and x} if isinstance(v, list) else {k: v})
    return out


#: the numbers a file writes that are not noise values avbench measured (rates, placeholders, constants)
_NOT_NOISE = {"update_rate", "imu_update_rate", "IMU.Frequency", "GRAVITY", "INTEGRATION_COVARIANCE", "time_offset"}


def _values_tables(tables) -> dict:
    """key -> [value, unit] of the page's filter-value tables (header row starting "key", "value", "unit")."""
    return {row[0]: row[1:3] for t in tables if t and t[0][:3] == ["key", "value", "unit"] for row in t[1:]}


def _values_page(recording, names):
    from avbench.recordings import exports
    from avbench.recordings.html import recording_page

    est = recording[0]
    rendered = exports.render(est.results(), names, "gmwm", est.timing.fs)
    files = {name: ("imu" + suffix, text) for name, (suffix, text) in rendered.items()}
    values = exports.tables(est.results(), names, "gmwm", est.timing.fs)
    return recording_page(est, {}, files, tables=values), files


@pytest.mark.parametrize("names", [["px4", "gtsam"], ["kalibr", "vins", "orbslam3", "openvins"],
                                   ["basalt", "matlab", "ros_imu_covariance"]])
def test_the_filter_values_are_each_files_own_keys_and_numbers(recording, names):
    page, files = _values_page(recording, names)
    shown = _values_tables(Page(page).tables)
    written = {k: v for name, (_, text) in files.items() for k, v in _written_numbers(name, text).items()
               if isinstance(v, float) and k not in _NOT_NOISE}
    assert set(shown) == set(written), (sorted(shown), sorted(written))  # no key of a format not asked for
    for key, (value, unit) in shown.items():
        assert math.isclose(float(value), written[key], rel_tol=5e-6), key  # at the 6 digits shown
        name = next(n for n in names if key in _written_numbers(n, files[n][1]))
        assert unit and (unit in files[name][1] or name == "basalt")  # basalt's JSON states no unit
    assert "value (SI)" not in page


@needs_browser
def test_browser_filter_values_at_800_px(recording, tmp_path, browser_times):
    page, files = _values_page(recording, ["px4", "gtsam"])
    t0 = time.perf_counter()
    r = _browse(page, tmp_path, 800)
    browser_times.append(time.perf_counter() - t0)
    p = r["probe"]
    assert p["scroll"] <= p["width"]
    shown = _values_tables(p["tables"])
    written = {**_written_numbers("px4", files["px4"][1]), **_written_numbers("gtsam", files["gtsam"][1])}
    written = {k: v for k, v in written.items() if k not in _NOT_NOISE}
    assert set(shown) == set(written)
    assert all(math.isclose(float(v), written[k], rel_tol=5e-6) for k, (v, _) in shown.items())
