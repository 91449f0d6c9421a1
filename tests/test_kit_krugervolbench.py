"""Tests of the kit helpers that kruger2003 and volbench share with other papers."""

import pandas as pd
import pytest

from pipeline.experiments.kit.pages import speed_psnr_figure
from pipeline.experiments.kit.judging import image_pairs


def test_image_pairs_compare_tags_as_text_and_say_when_none_pair(tmp_path):
    exr = tmp_path / "x.exr"
    exr.write_bytes(b"")
    rows = pd.DataFrame({"config": ["a", "b"], "scene": [1000, "1000"], "view": ["v", "v"], "exr": [str(exr)] * 2})
    assert len(image_pairs(rows, "a", "b")) == 1
    with pytest.raises(ValueError, match="no view rendered by both a and b"):
        image_pairs(rows.assign(view=["v", "w"]), "a", "b")


class _Context:
    """The one method of a report's context that a figure uses."""

    def __init__(self, folder):
        self.folder = folder

    def plot_path(self, name):
        return self.folder / f"{name}.svg", f"plots/{name}.svg"


def test_speed_psnr_figure_draws_time_against_psnr_with_the_frame_range(tmp_path, monkeypatch):
    from reports import blocks, plots

    calls = []
    monkeypatch.setattr(plots, "speed_accuracy", lambda frame, path, **options: calls.append((frame, path, options)))
    frame = pd.DataFrame({"scene": ["a"], "method": ["m"], "time_ms": [2.0], "time_ms_min": [1.0],
                          "time_ms_max": [3.0], "psnr": [41.0]})
    out = speed_psnr_figure(_Context(tmp_path), "chart", frame, heading="H", caption="C", title="T", group="scene",
                            label="method", x_label="median frame time (ms, log scale)", log_x=False)
    assert isinstance(out, blocks.Figure) and (out.title, out.path, out.caption) == ("H", "plots/chart.svg", "C")
    (drawn, path, options), = calls
    assert drawn is frame and path == tmp_path / "chart.svg"
    assert options == {"time_col": "time_ms", "error_col": "psnr", "group_col": "scene", "label_col": "method",
                       "title": "T", "log_y": False, "time_range_cols": ("time_ms_min", "time_ms_max"),
                       "better": "upper left", "log_x": False,
                       "x_label": "median frame time (ms, log scale); bars: fastest to slowest frame",
                       "y_label": "PSNR against the reference (dB)"}


def test_speed_psnr_figure_draws_a_chart_file(tmp_path):
    frame = pd.DataFrame({"scene": ["a", "a"], "method": ["m", "n"], "time_ms": [2.0, 4.0], "time_ms_min": [1.0, 3.0],
                          "time_ms_max": [3.0, 5.0], "psnr": [41.0, 45.0]})
    speed_psnr_figure(_Context(tmp_path), "chart", frame, heading="H", caption="C", title="T", group="scene",
                      label="method")
    assert (tmp_path / "chart.svg").read_text().lstrip().startswith("<?xml")
