"""The kit helpers lacroute1995's experiments added (:func:`pipeline.experiments.kit.results.nonempty_or`,
:func:`pipeline.experiments.kit.pages.time_lines_figure`)."""

from types import SimpleNamespace

import pandas as pd
import pytest

from pipeline.experiments.kit.pages import time_lines_figure
from pipeline.experiments.kit.results import nonempty_or


@pytest.mark.parametrize("found", [pd.DataFrame({"a": [1]}), [0], {"brain": 1.0}])
def test_nonempty_or_returns_what_it_found(found):
    assert nonempty_or(found, "unused") is found


@pytest.mark.parametrize("found", [pd.DataFrame({"a": []}), [], {}, pd.Series(dtype=float)])
def test_nonempty_or_raises_its_message_where_nothing_was_found(found):
    with pytest.raises(ValueError, match="^fewer than three task sizes swept$"):
        nonempty_or(found, "fewer than three task sizes swept")


def _context(folder):
    """A report's context with the one method a figure uses."""
    return SimpleNamespace(plot_path=lambda name: (folder / f"{name}.svg", f"plots/{name}.svg"))


def test_time_lines_figure_draws_the_median_frame_with_its_range(tmp_path, monkeypatch):
    from reports import blocks, plots

    calls = []
    monkeypatch.setattr(plots, "lines", lambda frame, path, **options: calls.append((frame, path, options)))
    frame = pd.DataFrame({"size": [64, 128], "data": ["a", "a"], "time_ms": [2.0, 8.0], "time_ms_min": [1.0, 7.0],
                          "time_ms_max": [3.0, 9.0]})
    out = time_lines_figure(_context(tmp_path), "growth", frame, heading="H", caption="C", title="T", x="size",
                            group="data", x_label="size", log_x=True)
    assert isinstance(out, blocks.Figure) and (out.title, out.path, out.caption) == ("H", "plots/growth.svg", "C")
    (drawn, path, options), = calls
    assert drawn is frame and path == tmp_path / "growth.svg"
    assert options == {"x": "size", "y": "time_ms", "group": "data", "y_range": ("time_ms_min", "time_ms_max"),
                       "title": "T", "x_label": "size", "y_label": "median frame time (ms)", "log_x": True}


def test_time_lines_figure_draws_a_chart_file(tmp_path):
    frame = pd.DataFrame({"size": [64, 128], "data": ["a", "a"], "time_ms": [2.0, 8.0], "time_ms_min": [1.0, 7.0],
                          "time_ms_max": [3.0, 9.0]})
    time_lines_figure(_context(tmp_path), "growth", frame, heading="H", caption="C", title="T", x="size", group="data",
                      x_label="size", y_label="median technique time (ms)")
    assert (tmp_path / "growth.svg").read_text().lstrip().startswith("<?xml")
