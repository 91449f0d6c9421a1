"""The report in a real headless browser: every page renders, every image and chart loads, every
local link resolves, and no text overflows its table cell.

Chromium (Debian's ``chromium``; ``.ci/run`` installs it) opens a copy of each page with a small
checker script added: after the load event it lists images that did not decode
(``naturalWidth == 0``), table cells whose content is wider than the cell
(``scrollWidth > clientWidth``) and whether the page scrolls sideways, and writes that as JSON into
the page, which ``--dump-dom`` prints. Links are checked on disk by Python (the report must open
from a folder, without a network). Each page is also screenshot to PNG; set
``VOLBENCH_SCREENSHOTS=<folder>`` to keep them. It skips where Chromium is absent, unless
``VOLBENCH_REQUIRE_BROWSER`` is set (CI), where it fails. The test checks the report it builds from
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

import pytest

from test_reports_html import broken_links, synthetic_report

CHROMIUM = next((shutil.which(n) for n in ("chromium", "chromium-browser", "google-chrome") if shutil.which(n)), None)
# CI sets VOLBENCH_REQUIRE_BROWSER=1 so that a missing Chromium fails there instead of skipping.
pytestmark = pytest.mark.skipif(CHROMIUM is None and not os.environ.get("VOLBENCH_REQUIRE_BROWSER"),
                                reason="Chromium is not installed (apt-get install chromium)")

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
  var out = document.createElement("pre");
  out.id = "volbench-check";
  out.textContent = JSON.stringify({images: document.images.length, broken: broken, overflow: overflow,
    sideways: document.documentElement.scrollWidth > window.innerWidth + 1});
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
            assert result["images"] > 0 or page.name == "index.html", where
            assert result["broken"] == [], f"{where}: images that did not load: {result['broken']}"
            assert result["overflow"] == [], f"{where}: text overflows its cell: {result['overflow']}"
            assert not result["sideways"], f"{where}: the page scrolls sideways"
            assert screenshot.is_file() and screenshot.stat().st_size > 10_000, f"{where}: no screenshot"


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
