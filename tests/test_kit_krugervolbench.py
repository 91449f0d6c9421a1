"""Tests of the kit helpers that kruger2003 and volbench share with other papers."""

import pandas as pd
import pytest

from pipeline.experiments.kit.pages import speed_psnr_figure
from pipeline.experiments.kit.results import image_pairs


def test_image_pairs_match_scene_and_view_where_both_images_exist(tmp_path):
    paths = {name: tmp_path / f"{name}.exr" for name in ("a1", "a2", "b1", "b3")}
    for path in paths.values():
        path.write_bytes(b"")
    first = pd.DataFrame({"scene": ["head", "head", "foot"], "view": ["v1", "v2", "v1"],
                          "exr": [str(paths["a1"]), str(paths["a2"]), str(tmp_path / "missing.exr")]})
    second = pd.DataFrame({"scene": ["head", "foot", "head"], "view": ["v1", "v1", "v3"],
                           "exr": [str(paths["b1"]), str(paths["b3"]), str(paths["b3"])]})
    pairs = image_pairs(first, second, "a and b")
    assert [(scene, view) for scene, view, _, _ in pairs] == [("head", "v1")]  # v2: none in b; foot: a's EXR missing
    _, _, row_a, row_b = pairs[0]
    assert (row_a.exr, row_b.exr) == (str(paths["a1"]), str(paths["b1"]))


def test_image_pairs_compare_tags_as_text_and_say_when_none_pair(tmp_path):
    exr = tmp_path / "x.exr"
    exr.write_bytes(b"")
    first = pd.DataFrame({"scene": [1000], "view": ["v"], "exr": [str(exr)]})
    second = pd.DataFrame({"scene": ["1000"], "view": ["v"], "exr": [str(exr)]})
    assert len(image_pairs(first, second, "a and b")) == 1
    with pytest.raises(ValueError, match="no view rendered by both a and b"):
        image_pairs(first, second.assign(view="w"), "a and b")


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
