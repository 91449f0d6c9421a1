"""The report in a real headless browser: every page renders, every image and chart loads, every
local link resolves, no text overflows its table cell, and no chart text overlaps.

Chromium (Debian's ``chromium``; ``.ci/run`` installs it) opens a copy of each page with a small
checker script added: after the load event it lists images that did not decode
(``naturalWidth == 0``), table cells whose content is wider than the cell
(``scrollWidth > clientWidth``) and whether the page scrolls sideways, and writes that as JSON into
the page, which ``--dump-dom`` prints. Links are checked on disk by Python (the report must open
from a folder, without a network). Each page is also screenshot to PNG; set
``VOLBENCH_SCREENSHOTS=<folder>`` to keep them. It skips where Chromium is absent, unless
``VOLBENCH_REQUIRE_BROWSER`` is set (CI), where it fails. Where index.html has a ``decision-panel``,
its first image must start on the first screen (top < 900 px at 1400 px wide).

Every chart a page links (``plots/*.svg``) is inlined into one check page, where the browser lays out
its text (matplotlib writes text as ``<text>``): it fails on two texts that overlap by more than 1 px
both ways (rotated texts as rotated boxes), on text outside the SVG's own box (a cut title or label),
and on a legend (matplotlib's group ``legend_N``) whose frame covers data: a marker (``<use>``), a
vertex of a clipped data path or part of a filled one (a bar), all as drawn inside the axes' clip. The test checks the report it builds from
synthetic records (test_reports_html.synthetic_report) and, when ``VOLBENCH_REPORT`` names a
report folder (CI: ``results/smoke/report`` after the smoke pipeline), that one too.
"""

import html
import json
import os
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from test_reports_html import broken_links, synthetic_report

CHROMIUM = next((shutil.which(n) for n in ("chromium", "chromium-browser", "google-chrome") if shutil.which(n)), None)
# CI sets VOLBENCH_REQUIRE_BROWSER=1 so that a missing Chromium fails there instead of skipping.
pytestmark = [pytest.mark.integration,
              pytest.mark.skipif(CHROMIUM is None and not os.environ.get("VOLBENCH_REQUIRE_BROWSER"),
                                 reason="Chromium is not installed (apt-get install chromium)")]

FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         "--hide-scrollbars", "--allow-file-access-from-files"]
WINDOW = "--window-size=1400,3000"
CHECKER = """<script>
window.addEventListener("load", function () {
  var broken = [], overflow = [];
  document.querySelectorAll("img").forEach(function (img) {
    if (!img.complete || img.naturalWidth === 0) broken.push(img.getAttribute("src"));
  });
  document.querySelectorAll("td, th").forEach(function (cell) {
    if (cell.scrollWidth > cell.clientWidth + 1)
      overflow.push(cell.textContent.trim().slice(0, 80) + " (" + cell.scrollWidth + " > " + cell.clientWidth + " px)");
  });
  var panel = document.getElementById("decision-panel"), first = panel && panel.querySelector("img");
  var out = document.createElement("pre");
  out.id = "volbench-check";
  out.textContent = JSON.stringify({images: document.images.length, broken: broken, overflow: overflow,
    sideways: document.documentElement.scrollWidth > window.innerWidth + 1,
    panel: panel ? (first ? first.getBoundingClientRect().top + window.scrollY : "no image") : null});
  document.body.appendChild(out);
});
</script>
"""


FIRST_SCREEN = 900  # px: the decision panel's chart must start above this at a 1400-px-wide window
SVG_CHECKER = """<script>
window.addEventListener("load", function () {
  var SLACK = 1;  // px: overlaps and overhangs up to this much are font rounding
  function box(el) {  // the element's own box as 4 screen points (a rotated text gives a rotated box)
    var b = el.getBBox(), m = el.getScreenCTM();
    return [[b.x, b.y], [b.x + b.width, b.y], [b.x + b.width, b.y + b.height], [b.x, b.y + b.height]]
      .map(function (p) { var q = new DOMPoint(p[0], p[1]).matrixTransform(m); return [q.x, q.y]; });
  }
  function rect(points) {
    var xs = points.map(function (p) { return p[0]; }), ys = points.map(function (p) { return p[1]; });
    return {l: Math.min.apply(null, xs), r: Math.max.apply(null, xs), t: Math.min.apply(null, ys),
            b: Math.max.apply(null, ys)};
  }
  function depth(a, b) {  // how far two convex polygons overlap along their least-overlapping edge normal
    var least = Infinity;
    [a, b].forEach(function (poly) {
      poly.forEach(function (p, i) {
        var q = poly[(i + 1) % poly.length], nx = q[1] - p[1], ny = p[0] - q[0], n = Math.hypot(nx, ny);
        if (n === 0) return;
        var pa = a.map(function (v) { return (v[0] * nx + v[1] * ny) / n; });
        var pb = b.map(function (v) { return (v[0] * nx + v[1] * ny) / n; });
        least = Math.min(least, Math.min(Math.max.apply(null, pa), Math.max.apply(null, pb))
                                - Math.max(Math.min.apply(null, pa), Math.min.apply(null, pb)));
      });
    });
    return least;
  }
  function inside(p, r) { return p[0] > r.l + SLACK && p[0] < r.r - SLACK && p[1] > r.t + SLACK && p[1] < r.b - SLACK; }
  function clipOf(svg, el) {  // the screen rectangle an element is clipped to (its axes), or null
    var holder = el.closest("[clip-path]"), id = holder && holder.getAttribute("clip-path").match(/#([^)]+)/);
    var shape = id && svg.querySelector('[id="' + id[1] + '"] rect, [id="' + id[1] + '"] path');
    return shape ? rect(box(shape)) : null;
  }
  function covered(svg, legend) {  // data drawn under the legend's frame
    var frame = rect(box(legend.querySelector("path") || legend)), axes = legend.closest('g[id^="axes_"]'), hits = [];
    if (!axes) return hits;
    axes.querySelectorAll("[clip-path] use, path[clip-path], [clip-path] path").forEach(function (el) {
      if (el.closest('[id^="legend_"], [id^="matplotlib.axis"], defs')) return;
      var clip = clipOf(svg, el), seen = function (p) { return !clip || inside(p, {l: clip.l - 2, r: clip.r + 2, t: clip.t - 2, b: clip.b + 2}); };
      if (el.tagName === "use") {
        var r = rect(box(el)), centre = [(r.l + r.r) / 2, (r.t + r.b) / 2];
        if (seen(centre) && inside(centre, frame)) hits.push("marker at " + centre.map(Math.round));
        return;
      }
      var m = el.getScreenCTM(), numbers = (el.getAttribute("d") || "").match(/-?[0-9.]+(?:e[-+]?[0-9]+)?/gi) || [];
      var style = el.getAttribute("style") || "";
      if (/fill:\\s*(?!none)[^;\\s]/.test(style) && clip) {  // a filled shape: the part of it inside the axes
        var r = rect(box(el)), l = Math.max(r.l, clip.l, frame.l), rr = Math.min(r.r, clip.r, frame.r);
        var t = Math.max(r.t, clip.t, frame.t), b = Math.min(r.b, clip.b, frame.b);
        if (rr - l > SLACK && b - t > SLACK) hits.push("filled shape at " + [l, t].map(Math.round));
        return;
      }
      for (var i = 0; i + 1 < numbers.length; i += 2) {
        var q = new DOMPoint(+numbers[i], +numbers[i + 1]).matrixTransform(m), p = [q.x, q.y];
        if (seen(p) && inside(p, frame)) { hits.push("line vertex at " + p.map(Math.round)); return; }
      }
    });
    return hits;
  }
  var report = {};
  document.querySelectorAll("div.chart").forEach(function (holder) {
    var svg = holder.querySelector("svg"), page = svg.getBoundingClientRect(), problems = [];
    var texts = Array.prototype.filter.call(svg.querySelectorAll("text"), function (t) {
      return t.textContent.trim() !== "" && t.getBBox().width > 0;
    }).map(function (t) { return {text: t.textContent.trim(), box: box(t)}; });
    var frame = [[page.left, page.top], [page.right, page.top], [page.right, page.bottom], [page.left, page.bottom]];
    texts.forEach(function (a, i) {
      var r = rect(a.box);
      if (r.l < page.left - SLACK || r.r > page.right + SLACK || r.t < page.top - SLACK || r.b > page.bottom + SLACK)
        problems.push("text outside the chart: " + JSON.stringify(a.text));
      texts.slice(i + 1).forEach(function (b) {
        if (depth(a.box, b.box) > SLACK) problems.push("texts overlap: " + JSON.stringify(a.text) + " and " + JSON.stringify(b.text));
      });
    });
    svg.querySelectorAll('g[id^="legend_"]').forEach(function (legend) {
      var hits = covered(svg, legend);
      if (hits.length) problems.push("legend covers data: " + hits.length + " (" + hits.slice(0, 3).join("; ") + ")");
    });
    report[holder.dataset.name] = problems;
  });
  var out = document.createElement("pre");
  out.id = "volbench-charts";
  out.textContent = JSON.stringify(report);
  document.body.appendChild(out);
});
</script>
"""


def _chromium(tmp_path, *args):
    assert CHROMIUM is not None, "VOLBENCH_REQUIRE_BROWSER is set but Chromium is not installed"
    profile = tmp_path / "chromium-profile"
    profile.mkdir(exist_ok=True)
    out = subprocess.run([CHROMIUM, *FLAGS, f"--user-data-dir={profile}", *args], capture_output=True, text=True,
                         timeout=120)
    return out


def check_page(page, tmp_path):
    """Load ``page`` (with the checker) in Chromium; return the checker's JSON and a PNG screenshot."""
    checked = page.with_name(f".check-{page.name}")
    checked.write_text(page.read_text().replace("</body>", CHECKER + "</body>"))
    try:
        out = _chromium(tmp_path, WINDOW, "--virtual-time-budget=15000", "--dump-dom", checked.resolve().as_uri())
    finally:
        checked.unlink()
    found = re.search(r'<pre id="volbench-check">(.*?)</pre>', out.stdout, re.S)
    assert found, f"the checker did not run on {page.name}: {out.stderr[-2000:]}"
    screenshot = tmp_path / f"{page.parent.parent.name}-{page.stem}.png"
    _chromium(tmp_path, WINDOW, "--virtual-time-budget=15000", f"--screenshot={screenshot}", page.resolve().as_uri())
    keep = os.environ.get("VOLBENCH_SCREENSHOTS")
    if keep and screenshot.exists():
        Path(keep).mkdir(parents=True, exist_ok=True)
        shutil.copyfile(screenshot, Path(keep) / screenshot.name)
    return json.loads(html.unescape(found.group(1))), screenshot


def linked_charts(report):
    """The chart files (``plots/*.svg``) that the report's pages link, sorted."""
    names = set()
    for page in report.glob("*.html"):
        names.update(re.findall(r'["\'](plots/[^"\'#?]+\.svg)["\']', page.read_text()))
    return sorted(report / name for name in names)


def check_charts(paths, tmp_path):
    """Lay out each SVG chart in Chromium; return {file name: [problems]} (see the module docstring)."""
    holders = []
    for path in paths:
        text = path.read_text()
        holders.append(f'<div class="chart" data-name="{html.escape(path.name)}">{text[text.index("<svg"):]}</div>')
    page = tmp_path / "charts-check.html"
    page.write_text('<!DOCTYPE html><html><head><meta charset="utf-8"></head><body>' + "".join(holders)
                    + SVG_CHECKER + "</body></html>")
    out = _chromium(tmp_path, WINDOW, "--virtual-time-budget=15000", "--dump-dom", page.resolve().as_uri())
    found = re.search(r'<pre id="volbench-charts">(.*?)</pre>', out.stdout, re.S)
    assert found, f"the chart checker did not run: {out.stderr[-2000:]}"
    return json.loads(html.unescape(found.group(1)))


def _reports(tmp_path_factory):
    reports = [synthetic_report(tmp_path_factory.mktemp("browser")).parent]
    extra = os.environ.get("VOLBENCH_REPORT")
    if extra:
        assert (Path(extra) / "index.html").is_file(), f"VOLBENCH_REPORT={extra} has no index.html"
        reports.append(Path(extra))
    return reports


def test_every_page_renders_with_its_images_links_and_cells_intact(tmp_path_factory, tmp_path):
    for report in _reports(tmp_path_factory):
        assert broken_links(report) == [], report
        pages = sorted(report.glob("*.html"))
        assert any(p.name == "index.html" for p in pages)
        for page in pages:
            result, screenshot = check_page(page, tmp_path)
            where = f"{report}/{page.name}"
            assert result["images"] > 0 or page.name in ("index.html", "appendix.html"), where  # tables only
            assert result["broken"] == [], f"{where}: images that did not load: {result['broken']}"
            assert result["overflow"] == [], f"{where}: text overflows its cell: {result['overflow']}"
            assert not result["sideways"], f"{where}: the page scrolls sideways"
            assert screenshot.is_file() and screenshot.stat().st_size > 10_000, f"{where}: no screenshot"
            if page.name == "index.html" and result["panel"] is not None:
                assert result["panel"] != "no image", f"{where}: the decision panel has no image"
                assert result["panel"] < FIRST_SCREEN, f"{where}: the decision panel's chart starts at {result['panel']} px"
        charts = linked_charts(report)
        problems = {name: found for name, found in check_charts(charts, tmp_path).items() if found}
        assert problems == {}, f"{report}: charts with overlapping, cut or covering text: {json.dumps(problems, indent=1)}"


def test_the_checker_sees_broken_images_overflowing_cells_and_broken_links(tmp_path):
    page = tmp_path / "report" / "index.html"
    page.parent.mkdir()
    page.write_text('<!DOCTYPE html><html><body><a href="nowhere.json">x</a><img src="missing.png">'
                    '<table><tr><td style="width:40px;max-width:40px;white-space:nowrap;overflow:hidden">'
                    'a-very-long-value-that-cannot-wrap-inside-forty-pixels</td></tr></table></body></html>')
    result, _ = check_page(page, tmp_path)
    assert result["broken"] == ["missing.png"]
    assert len(result["overflow"]) == 1 and "a-very-long-value" in result["overflow"][0]
    assert broken_links(page.parent) == [("index.html", "nowhere.json"), ("index.html", "missing.png")]


def _bad_chart(path, draw):
    """An SVG written by matplotlib as reports.plots writes them (text as text), after ``draw(fig, ax)``."""
    import matplotlib as mpl
    from matplotlib.figure import Figure

    with mpl.rc_context({"svg.fonttype": "none", "svg.hashsalt": "volbench"}):
        fig = Figure(figsize=(4, 3))
        ax = fig.add_subplot()
        draw(fig, ax)
        fig.savefig(path, format="svg")
    return path


def test_the_chart_checker_sees_overlapping_cut_and_covering_text(tmp_path):
    import pandas as pd

    from reports import plots

    def overlapping(fig, ax):
        ax.text(0.5, 0.5, "first label", transform=ax.transAxes)
        ax.text(0.52, 0.51, "second label", transform=ax.transAxes)

    def covering(fig, ax):
        ax.plot([0.8, 0.9, 0.95], [0.9, 0.95, 0.85], "o", label="a series with a long name")
        ax.set(xlim=(0, 1), ylim=(0, 1))
        ax.legend(loc="upper right")

    def covering_bars(fig, ax):
        ax.bar([0, 1, 2], [3, 3, 3], label="bars")
        ax.legend(loc="center")

    charts = [_bad_chart(tmp_path / "overlap.svg", overlapping),
              _bad_chart(tmp_path / "cut.svg", lambda fig, ax: fig.suptitle("a title far too long to fit " * 3)),
              _bad_chart(tmp_path / "covered.svg", covering), _bad_chart(tmp_path / "bars.svg", covering_bars)]
    frame = pd.DataFrame({"t": np.arange(1.0, 37.0), "e": np.arange(1.0, 37.0) % 7 + 1,
                          "g": [f"series {i % 12}" for i in range(36)], "n": [f"label {i}" for i in range(36)]})
    charts.append(plots.speed_accuracy(frame, tmp_path / "tidy.svg", time_col="t", error_col="e", group_col="g",
                                       label_col="n", title="a title far too long to fit " * 3))
    found = check_charts(charts, tmp_path)
    assert found["overlap.svg"] == ['texts overlap: "first label" and "second label"']
    assert found["cut.svg"] and all(p.startswith("text outside the chart") for p in found["cut.svg"])
    assert len(found["covered.svg"]) == 1 and found["covered.svg"][0].startswith("legend covers data: 2 (marker")
    assert len(found["bars.svg"]) == 1 and "filled shape" in found["bars.svg"][0]
    assert found["tidy.svg"] == []  # the same troubles, laid out by reports.plots


def test_the_checker_measures_where_the_decision_panel_starts(tmp_path):
    for margin, expected in ((100, True), (1200, False)):
        page = tmp_path / f"report{margin}" / "index.html"
        page.parent.mkdir()
        page.write_text(f'<!DOCTYPE html><html><body><div id="decision-panel" style="margin-top:{margin}px">'
                        '<img src="x.png" width="40" height="40"></div></body></html>')
        result, _ = check_page(page, tmp_path)
        assert (result["panel"] < FIRST_SCREEN) is expected, result
