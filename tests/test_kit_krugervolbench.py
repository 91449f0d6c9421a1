"""Tests of the kit helpers that kruger2003 and volbench share with other papers."""

import pandas as pd
import pytest

from pipeline.experiments.kit.pages import TIMED_CAPTION, speed_psnr_figure, timed_metrics_table
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


class _Links:
    """The one method of a report's context that a linked table uses: every path linked as it is."""

    def run_links(self, frame):
        return frame.copy()


def test_timed_metrics_table_shows_times_in_ms_and_metrics_sorted_and_linked():
    frame = pd.DataFrame({"scene": ["b", "a", "a"], "step": [1.0, 2.0, 1.0], "time_total": [0.004, 0.002, 0.003],
                          "time_total_min": [0.003, 0.001, 0.002], "time_total_max": [0.005, 0.003, 0.004],
                          "psnr": [40.0, 30.0, 35.0], "record": ["r0", "r1", "r2"], "exr": ["e0", "e1", "e2"]},
                         index=[7, 8, 9])
    table = timed_metrics_table("T", frame, ["scene", "step"], _Links(), by=["scene", "time (ms)"], csv_name="t.csv")
    assert (table.title, table.caption, table.csv_name) == ("T", TIMED_CAPTION, "t.csv")
    assert list(table.frame.columns) == ["scene", "step", "time (ms)", "fastest (ms)", "slowest (ms)", "PSNR (dB)",
                                         "record", "EXR"]
    assert table.frame["time (ms)"].tolist() == pytest.approx([2.0, 3.0, 4.0])
    assert table.frame.step.tolist() == [2.0, 1.0, 1.0] and table.frame.record.tolist() == ["r1", "r2", "r0"]
    assert timed_metrics_table("T", frame, ["scene"], _Links(), by=["scene"], caption="C").caption == "C"
