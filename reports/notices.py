"""Notices put on a report already written: sentences every page shows first.

:func:`reports.html.build_report` writes the notices it is given right after each page's ``<nav>``
line, as ``<p class="notice">…</p>``. A report written earlier can need one too, when it must
not pass for what it is not, e.g. when the pipeline run that should have replaced it stopped
(``volbench run``). :func:`mark_report` adds such a notice in the same place and format, with a
second class naming its kind, so that :func:`unmark_report` can take it off again without
touching the notices the report was built with.
"""

import html
import re
from pathlib import Path

from core.errors import InputError

NAV_END = "</nav>"


def _notice_line(kind):
    if not isinstance(kind, str) or not re.fullmatch(r"[a-z][a-z0-9-]*", kind):
        raise InputError(f"notice kind {kind!r}: expected a CSS class name (lower-case letters, digits, -)")
    return f'<p class="notice {kind}">'


def _pages(report_dir):
    return sorted(Path(report_dir).glob("*.html"))


def unmark_report(report_dir, *, kind):
    """Take the notices of ``kind`` off every page of the report in ``report_dir``; return the pages changed."""
    start = _notice_line(kind)
    changed = []
    for page in _pages(report_dir):
        lines = page.read_text().splitlines(keepends=True)
        kept = [line for line in lines if not line.startswith(start)]
        if len(kept) != len(lines):
            page.write_text("".join(kept))
            changed.append(page)
    return changed


def mark_report(report_dir, text, *, kind):
    """Show ``text`` first on every page of the report in ``report_dir``; return the pages marked.

    The notice goes right after the page's ``<nav>…</nav>`` line, above the notices the report
    was built with, and replaces an earlier notice of the same ``kind`` (so a report marked by
    two stopped runs says only what the last one did).

    Parameters
    ----------
    report_dir : path
        A report folder (:func:`reports.html.build_report`); a missing folder marks nothing.
    text : str
        The notice, as plain text (it is escaped).
    kind : str
        A CSS class name saying what the notice is about, e.g. ``"unfinished"``.
    """
    unmark_report(report_dir, kind=kind)
    notice = f"{_notice_line(kind)}{html.escape(' '.join(text.split()))}</p>\n"
    marked = []
    for page in _pages(report_dir):
        lines = page.read_text().splitlines(keepends=True)
        at = next((i for i, line in enumerate(lines) if line.rstrip().endswith(NAV_END)), None)
        if at is None:  # not a page of a volbench report
            continue
        lines.insert(at + 1, notice)
        page.write_text("".join(lines))
        marked.append(page)
    return marked
