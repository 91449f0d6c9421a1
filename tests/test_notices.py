"""Notices put on a report already written (reports.notices), on pages that build_report wrote."""

import pandas as pd
import pytest

from core.errors import InputError
from pipeline.experiments.volbench.phantoms import PhantomGallery
from reports.html import build_report
from reports.notices import mark_report, unmark_report


@pytest.fixture
def report(tmp_path):
    """An index and a paper page, built with a notice of their own."""
    index = build_report(pd.DataFrame(columns=["experiment", "run", "status"]),
                         pd.DataFrame(columns=["experiment", "claim", "holds"]), [PhantomGallery()],
                         results_dir=tmp_path, environment={}, notices=["Built with this notice."])
    return index.parent


def _top(page):
    """The page's lines from its nav on: what a reader sees first."""
    lines = page.read_text().splitlines()
    at = next(i for i, line in enumerate(lines) if line.startswith("<nav>"))
    return lines[at:at + 3]


def test_every_page_gets_the_notice_first_and_a_second_mark_replaces_the_first(report):
    pages = sorted(report.glob("*.html"))
    assert [p.name for p in pages] == ["appendix.html", "index.html", "volbench.html"]
    originals = {page: page.read_text() for page in pages}
    assert mark_report(report, "Run <1> did not finish.", kind="unfinished") == pages
    assert mark_report(report, "Run 2 did not\nfinish.", kind="unfinished") == pages
    for page in pages:
        nav, notice, built = _top(page)
        assert nav.endswith("</nav>")
        assert notice == '<p class="notice unfinished">Run 2 did not finish.</p>'  # the last run's only
        assert built == '<p class="notice">Built with this notice.</p>'
    mark_report(report, "Run <1> did not finish.", kind="unfinished")
    assert "Run &lt;1&gt; did not finish." in (report / "index.html").read_text()  # text, not markup
    assert unmark_report(report, kind="unfinished") == pages
    assert {page: page.read_text() for page in pages} == originals  # the report as it was built
    assert unmark_report(report, kind="unfinished") == []  # nothing to take off: no page rewritten


def test_no_report_marks_nothing_and_a_kind_must_be_a_class_name(tmp_path, report):
    assert mark_report(tmp_path / "no-report", "text", kind="unfinished") == []
    with pytest.raises(InputError, match="notice kind 'not finished': expected a CSS class name"):
        mark_report(report, "text", kind="not finished")
    assert '"notice not' not in (report / "index.html").read_text()
