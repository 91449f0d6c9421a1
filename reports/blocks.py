"""Building blocks an experiment returns for its part of the report; :mod:`reports.html` renders them."""

from dataclasses import dataclass, field

import pandas as pd


@dataclass
class Text:
    """A paragraph (plain text; escaped when rendered)."""

    text: str


@dataclass
class Takeaways:
    """Sentences computed from the numbers; the page shows them at its top, under the heading.

    Build them with :mod:`reports.takeaways` (or any function of the results), never by hand, so
    that they change when the numbers do.
    """

    sentences: list = field(default_factory=list)


@dataclass
class Table:
    """A table, written as HTML and, when ``csv_name`` is given, as a CSV beside the report.

    ``links`` maps a column to the text of a link: that column holds paths relative to the report
    folder (e.g. from :meth:`reports.html.ReportContext.record`) and each cell shows the text as a
    link to its path (empty cells stay empty). The CSV keeps the paths.
    """

    title: str
    frame: pd.DataFrame
    caption: str = ""
    csv_name: str | None = None
    links: dict = field(default_factory=dict)


@dataclass
class Figure:
    """An SVG chart; ``path`` is relative to the report folder.

    ``anchor`` is the figure's id on its page, so that other blocks (a heat-map cell) can link to it.
    """

    title: str
    path: str
    caption: str = ""
    anchor: str = ""


@dataclass
class GalleryItem:
    """One picture with an optional difference image, all relative to the report folder.

    ``extra`` holds more ``(label, path)`` pictures shown beside it at the same size (a real scan
    beside its phantom stand-in); ``label`` names the first picture when there are several.
    """

    caption: str
    image: str
    difference: str | None = None
    note: str = ""
    label: str = ""
    extra: tuple = ()


@dataclass
class Gallery:
    """Pictures side by side. Difference images in one gallery share one fixed scale.

    ``diff_scale`` is the absolute error shown at the top of the colour map; the report draws its
    colour bar once above the gallery and states the scale.
    """

    title: str
    items: list = field(default_factory=list)
    caption: str = ""
    diff_scale: float | None = None


@dataclass
class HeatCell:
    """One cell of a :class:`HeatMap`.

    ``value`` (dB PSNR) colours the cell; ``None`` marks a combination that was not measured, and
    ``text`` then says why (a backend lacks the feature). ``link`` is where the cell leads (e.g.
    ``"#<anchor>"`` of a chart on the page), ``image`` a picture it links beside it (the worst
    difference image), ``note`` a second, smaller line.
    """

    text: str
    value: float | None
    link: str | None = None
    image: str | None = None
    note: str = ""


@dataclass
class HeatMap:
    """A rows × columns table of cells coloured by a PSNR: red below ``thresholds[0]`` dB, amber up to
    ``thresholds[1]`` dB, green above, grey where not measured.

    ``cells`` maps ``(row, column)`` to a :class:`HeatCell`; a missing key is a cell nobody planned.
    """

    title: str
    rows: list
    columns: list
    cells: dict
    caption: str = ""
    thresholds: tuple = (30.0, 40.0)
