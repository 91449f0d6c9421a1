"""Building blocks an experiment returns for its part of the report; :mod:`reports.html` renders them."""

from dataclasses import dataclass, field

import pandas as pd


@dataclass
class Text:
    """A paragraph (plain text; escaped when rendered)."""

    text: str


@dataclass
class Table:
    """A table, written as HTML and, when ``csv_name`` is given, as a CSV beside the report."""

    title: str
    frame: pd.DataFrame
    caption: str = ""
    csv_name: str | None = None


@dataclass
class Figure:
    """An SVG chart; ``path`` is relative to the report folder."""

    title: str
    path: str
    caption: str = ""


@dataclass
class GalleryItem:
    """One picture with an optional difference image, both relative to the report folder."""

    caption: str
    image: str
    difference: str | None = None
    note: str = ""


@dataclass
class Gallery:
    title: str
    items: list = field(default_factory=list)
    caption: str = ""
