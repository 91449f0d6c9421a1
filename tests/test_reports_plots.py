"""Tests of reports.plots: each figure is a valid, deterministic SVG naming its series."""

import re
import subprocess
import sys
import xml.etree.ElementTree as ET

import numpy as np
import pandas as pd
import pytest

from core.errors import InputError
from reports import plots


@pytest.fixture
def runs():
    """Tidy results: two backends sweeping a step size over two views."""
    rows = []
    for backend, cost, order in (("raycast", 1.0, 1), ("shearwarp", 0.3, 2)):
        for step in (1.0, 0.5, 0.25):
            for view in (0, 1):
                rows.append({
                    "backend": backend, "view": view, "step": step,
                    "time_total": cost / step * (1 + 0.1 * view),
                    "time_classify": 0.2 * cost / step, "time_composite": 0.8 * cost / step,
                    "rmse": 0.1 * step**order * (1 + 0.05 * view),
                })
    return pd.DataFrame(rows)


def svg_text(path):
    """The file's text, after checking it parses as an SVG document."""
    text = path.read_text()
    assert ET.fromstring(text.encode()).tag.endswith("svg")
    assert "<svg" in text
    return text


FIGURES = {
    "speed_accuracy": (plots.speed_accuracy, {"label_col": "step", "pareto": True},
                       ["raycast", "shearwarp", "Pareto front", "frame time (s)", "RMSE against the reference"]),
    "convergence": (plots.convergence, {"group_col": "backend"},
                    ["raycast", "shearwarp", "slope 1", "slope 2"]),
    "stage_breakdown": (plots.stage_breakdown,
                        {"stage_cols": ["time_classify", "time_composite"]},
                        ["raycast", "shearwarp", "classify time", "composite time", "median time per frame (ms)"]),
    "scaling": (plots.scaling, {"x_col": "step", "y_col": "time_total", "group_col": "backend"},
                ["raycast", "shearwarp", "frame time (s)", "step size (voxels)"]),
}


@pytest.mark.parametrize("name", FIGURES)
def test_figure_is_svg_with_series_labels_and_deterministic(tmp_path, runs, name):
    function, kwargs, labels = FIGURES[name]
    first = function(runs, tmp_path / "sub" / "a.svg", **kwargs)
    text = svg_text(first)
    for label in labels:
        assert label in text
    assert "dc:date" not in text
    second = function(runs, tmp_path / "b.svg", **kwargs)
    assert second.read_bytes() == first.read_bytes()


def test_bar_compare(tmp_path):
    table = pd.DataFrame({"dataset": ["brain", "head", "engine"],
                          "paper_fps": [10.0, np.nan, 4.0], "measured_fps": [12.5, 3.3, 4.1]})
    text = svg_text(plots.bar_compare(table, tmp_path / "a.svg", category_col="dataset",
                                      value_cols=["paper_fps", "measured_fps"]))
    for label in ("brain", "head", "engine", "paper_fps", "measured_fps", "12.5", "1 missing"):
        assert label in text
    assert ">nan<" not in text


def test_log_bars_within_one_decade_get_plain_ticks_that_do_not_overlap(tmp_path):
    # Regression: bars from 0.3 to 0.45 ms drew matplotlib's minor labels "3×10⁻¹" and "4×10⁻¹" on top of each other.
    table = pd.DataFrame({"scene": ["a", "b"], "init": [0.31, 0.44], "draw": [0.35, 0.42]})
    text = svg_text(plots.bar_compare(table, tmp_path / "a.svg", category_col="scene", value_cols=["init", "draw"],
                                      log_y=True))
    assert "×" not in text and "10^" not in text and "$" not in text
    ticks = [float(t) for t in re.findall(r">(0\.\d+)<", text)]
    assert len(set(ticks)) >= 2 and all(0.25 < t < 0.5 for t in ticks)


def test_bytes_identical_across_processes(tmp_path, runs):
    runs.to_csv(tmp_path / "runs.csv", index=False)
    script = (
        "import sys, pandas as pd; from reports import plots; "
        "plots.speed_accuracy(pd.read_csv(sys.argv[1]), sys.argv[2])"
    )
    for name in ("a.svg", "b.svg"):
        subprocess.run([sys.executable, "-c", script, tmp_path / "runs.csv", tmp_path / name],
                       check=True)
    assert (tmp_path / "a.svg").read_bytes() == (tmp_path / "b.svg").read_bytes()


def test_nan_and_inf_rows_are_dropped_with_a_note(tmp_path, runs):
    runs.loc[0, "rmse"] = np.nan
    runs.loc[1, "time_total"] = np.inf
    runs.loc[2, "rmse"] = 0.0  # cannot be shown on a log axis
    text = svg_text(plots.speed_accuracy(runs, tmp_path / "a.svg"))
    assert "2 NaN/inf" in text and "1 non-positive" in text
    text = svg_text(plots.speed_accuracy(runs, tmp_path / "b.svg", log_y=False))
    assert "2 NaN/inf" in text and "non-positive" not in text
    runs.loc[3, "time_classify"] = np.inf
    text = svg_text(plots.stage_breakdown(runs, tmp_path / "c.svg",
                                          stage_cols=["time_classify", "time_composite"]))
    assert "1 infinite" in text


@pytest.mark.parametrize("name", FIGURES)
def test_empty_and_all_nan_frames_give_a_placeholder(tmp_path, runs, name):
    function, kwargs, _ = FIGURES[name]
    assert "no data" in svg_text(function(runs.iloc[:0], tmp_path / "a.svg", **kwargs))
    all_nan = runs.assign(rmse=np.nan, time_total=np.nan, time_classify=np.nan,
                          time_composite=np.nan)
    if name != "stage_breakdown":  # NaN stages mean "absent" there and plot as 0
        assert "no data" in svg_text(function(all_nan, tmp_path / "b.svg", **kwargs))
    empty_table = pd.DataFrame({"dataset": [], "fps": []})
    assert "no data" in svg_text(plots.bar_compare(empty_table, tmp_path / "c.svg",
                                                   category_col="dataset", value_cols=["fps"]))


def test_bad_input_is_named(tmp_path, runs):
    with pytest.raises(InputError, match="missing column.*'psnr'"):
        plots.speed_accuracy(runs, tmp_path / "a.svg", error_col="psnr")
    with pytest.raises(InputError, match="'backend' must be numeric"):
        plots.scaling(runs, tmp_path / "a.svg", x_col="backend", y_col="rmse")
    with pytest.raises(InputError, match=r"\.svg"):
        plots.scaling(runs, tmp_path / "a.png", x_col="step", y_col="rmse")
    with pytest.raises(InputError, match="DataFrame"):
        plots.convergence({"step": [1]}, tmp_path / "a.svg")


def test_speed_accuracy_draws_error_bars_labels_and_readable_ticks(tmp_path, runs):
    runs = runs.assign(time_ms=runs.time_total * 1e3, time_ms_min=runs.time_total * 900,
                       time_ms_max=runs.time_total * 1300)
    with_bars = svg_text(plots.speed_accuracy(runs, tmp_path / "a.svg", time_col="time_ms",
                                              time_range_cols=("time_ms_min", "time_ms_max"),
                                              x_label="median frame time (ms)", better="lower left",
                                              title="raycast reaches 1e-3 at 2 ms"))
    without = svg_text(plots.speed_accuracy(runs, tmp_path / "b.svg", time_col="time_ms"))
    for text in ("median frame time (ms)", "better: lower left", "raycast reaches 1e-3 at 2 ms", "backend"):
        assert text in with_bars
    assert with_bars.count("<path") > without.count("<path")  # the error bars
    assert "10^" not in with_bars and "10^{" not in with_bars and "$" not in with_bars  # plain-number ticks
    assert ">1000<" in with_bars or ">2000<" in with_bars or ">500<" in with_bars


def test_difference_colorbar_states_its_scale(tmp_path):
    text = svg_text(plots.difference_colorbar(tmp_path / "bar.svg", 0.1))
    assert "0 → 0.1" in text and ">0.1<" in text
    with pytest.raises(InputError, match="scale"):
        plots.difference_colorbar(tmp_path / "bar.svg", 0)
    with pytest.raises(InputError, match=r"\.svg"):
        plots.difference_colorbar(tmp_path / "bar.png", 0.1)


def test_lines_draws_each_row_with_its_range_marks_and_guides(tmp_path):
    frame = pd.DataFrame({"angle": [0, 30, 60, 90, "x"], "time_ms": [2.0, 2.2, 2.1, 2.3, 1.0],
                          "low": [1.8, 2.0, 2.0, 2.1, 0.9], "high": [2.5, 2.4, 2.3, 2.6, 1.1],
                          "dataset": ["sphere"] * 5})
    common = dict(x="angle", y="time_ms", group="dataset", title="time stays flat across the 45° switch",
                  x_label="view angle (degrees)", y_label="median frame time (ms)")
    with_bars = svg_text(plots.lines(frame, tmp_path / "a.svg", y_range=("low", "high"), vlines=(45,),
                                     guides=[("thesis ±6 %", [0, 90], [2.1, 2.1])], **common))
    without = svg_text(plots.lines(frame, tmp_path / "b.svg", **common))
    for text in ("view angle (degrees)", "median frame time (ms)", "sphere", "thesis ±6 %",
                 "dropped 1 rows without a value"):
        assert text in with_bars
    assert with_bars.count("<path") > without.count("<path")  # error bars, the switch line, the guide
    with pytest.raises(InputError, match="missing column"):
        plots.lines(frame, tmp_path / "c.svg", y_range=("low", "nope"), **common)


def test_speed_accuracy_can_leave_points_unjoined(tmp_path):
    frame = pd.DataFrame({"t": [1.0, 2.0, 3.0], "e": [3.0, 1.0, 2.0], "g": ["a", "a", "a"]})
    joined = plots.speed_accuracy(frame, tmp_path / "joined.svg", time_col="t", error_col="e", group_col="g")
    loose = plots.speed_accuracy(frame, tmp_path / "loose.svg", time_col="t", error_col="e", group_col="g",
                                 join=False)
    # The joined series draws one polyline through its three points; the unjoined one none.
    assert joined.read_text().count("stroke-linecap") > loose.read_text().count("stroke-linecap")


def test_lines_can_leave_points_unjoined_and_label_them(tmp_path):
    frame = pd.DataFrame({"x": [1.0, 2.0, 3.0], "y": [3.0, 1.0, 2.0], "g": ["a"] * 3,
                          "name": ["first", "second", "third"]})
    common = dict(x="x", y="y", group="g", title="t", x_label="x", y_label="y")
    joined = plots.lines(frame, tmp_path / "joined.svg", **common).read_text()
    loose = plots.lines(frame, tmp_path / "loose.svg", join=False, label="name", **common).read_text()
    assert joined.count("stroke-linecap") > loose.count("stroke-linecap")
    assert all(name in loose and name not in joined for name in ("first", "second", "third"))
    with pytest.raises(InputError, match="missing column"):
        plots.lines(frame, tmp_path / "bad.svg", join=False, label="scene", **common)


def test_series_get_distinct_colours_and_pairs_for_many_series(tmp_path):
    styles = [plots._style(i) for i in range(200)]
    assert len({s["color"] for s in styles[:20]}) == 20  # 12 series no longer share colours
    assert len({(s["color"], s["marker"]) for s in styles}) == 200
    frame = pd.DataFrame({"t": np.arange(1.0, 13.0), "e": np.arange(1.0, 13.0), "g": [f"s{i}" for i in range(12)]})
    text = svg_text(plots.speed_accuracy(frame, tmp_path / "a.svg", time_col="t", error_col="e", group_col="g"))
    assert len({c for c in plots._PALETTE[:12] if f"stroke: {c}" in text}) == 12


def _text_lines(text):
    """The text of each <text> element in an SVG string."""
    import re

    return [line for line in re.findall(r"<text[^>]*>([^<]*)</text>", text)]


def test_long_titles_and_labels_are_wrapped_to_the_figure(tmp_path, runs):
    import matplotlib as mpl

    title = "a finding that goes on " * 8 + "to its end"
    text = svg_text(plots.scaling(runs, tmp_path / "a.svg", x_col="step", y_col="time_total", title=title,
                                  y_label="a y label long enough to run past the height of the axes " * 2))
    pieces = [line for line in _text_lines(text) if "finding" in line or "its end" in line]
    assert len(pieces) > 1 and " ".join(pieces).split() == title.split()
    with mpl.rc_context(plots._RC):
        assert max(plots._text_width(p, 10.8) for p in pieces) <= 432  # the figure is 432 pt wide
    assert sum("y label" in line for line in _text_lines(text)) > 1


def test_overlapping_point_labels_are_left_out_and_counted(tmp_path):
    frame = pd.DataFrame({"t": 1 + np.arange(30) * 1e-3, "e": 1 + np.arange(30) * 1e-3, "g": ["a"] * 30,
                          "name": [f"point {i}" for i in range(30)]})
    text = svg_text(plots.speed_accuracy(frame, tmp_path / "a.svg", time_col="t", error_col="e", group_col="g",
                                         label_col="name"))
    shown = [line for line in _text_lines(text) if line.startswith("point ")]
    assert 0 < len(shown) < 30
    assert f"{30 - len(shown)} point labels left out" in text


def _legend_and_axes_right_edges(text):
    """x of the legend frame's left edge and of the axes' right edge, from matplotlib's SVG groups."""
    import re

    def xs(group):
        path = re.search(rf'<g id="{group}">\s*<g id="patch_\d+">\s*<path d="([^"]*)"', text) if group == "legend_1" \
            else re.search(rf'<g id="{group}">\s*<path d="([^"]*)"', text)
        return [float(v) for v in re.findall(r"([-\d.]+) [-\d.]+", path.group(1))]

    return min(xs("legend_1")), max(xs("patch_2"))


def test_a_legend_that_would_cover_data_or_lists_many_series_goes_beside_the_axes(tmp_path):
    grid = np.linspace(1, 10, 12)
    covering = pd.DataFrame({"t": np.tile(grid, 12), "e": np.repeat(grid, 12), "g": ["a"] * 144})
    text = svg_text(plots.speed_accuracy(covering, tmp_path / "a.svg", time_col="t", error_col="e", group_col="g",
                                         log_x=False, log_y=False, join=False))
    legend_left, axes_right = _legend_and_axes_right_edges(text)
    assert legend_left > axes_right
    corner = pd.DataFrame({"t": [1.0, 2.0], "e": [1.0, 2.0], "g": ["a", "a"]})  # the upper right is free
    text = svg_text(plots.speed_accuracy(corner, tmp_path / "b.svg", time_col="t", error_col="e", group_col="g"))
    legend_left, axes_right = _legend_and_axes_right_edges(text)
    assert legend_left < axes_right
    many = pd.DataFrame({"t": [1.0, 2.0] * 8, "e": [1.0, 2.0] * 8, "g": np.repeat([f"s{i}" for i in range(8)], 2)})
    text = svg_text(plots.speed_accuracy(many, tmp_path / "c.svg", time_col="t", error_col="e", group_col="g"))
    legend_left, axes_right = _legend_and_axes_right_edges(text)
    assert legend_left > axes_right


def test_stage_breakdown_grows_with_its_bars_and_keeps_its_legend_off_them(tmp_path):
    import re

    frame = pd.DataFrame({"backend": [f"setting {i}" for i in range(36)], "time_a": 0.01, "time_b": 0.02})
    text = svg_text(plots.stage_breakdown(frame, tmp_path / "a.svg", stage_cols=["time_a", "time_b"]))
    assert float(re.search(r'height="([\d.]+)pt"', text).group(1)) > 36 * 9  # a line of 9 pt text per bar
    legend_left, axes_right = _legend_and_axes_right_edges(text)
    assert legend_left > axes_right


def test_crowded_category_ticks_are_wrapped_or_rotated(tmp_path):
    import re

    names = [f"a long category name {i}" for i in range(12)]
    table = pd.DataFrame({"category": names, "value": np.arange(1.0, 13.0)})
    text = svg_text(plots.bar_compare(table, tmp_path / "a.svg", category_col="category", value_cols=["value"]))
    angles = re.findall(r'transform="rotate\((-?[\d.]+)[^"]*"[^>]*>a long category name', text)
    assert len(angles) == 12 and all(float(a) in (-30, -45, -90) for a in angles)  # whole names, rotated
    short = pd.DataFrame({"category": ["early stop", "empty skip", "both"], "value": [1.0, 2.0, 3.0]})
    text = svg_text(plots.bar_compare(short, tmp_path / "b.svg", category_col="category", value_cols=["value"]))
    assert "early stop" in _text_lines(text) and "rotate(-30" not in text  # room enough: left as it is


def test_a_legend_kept_inside_stays_where_it_was_checked():
    """A "best" legend is placed again at every draw: once the checks keep it inside the axes, it is pinned
    there, so a later change of the axes' shape (wrapped labels, thinned ticks) cannot move it onto a label
    the checks saw free (a smoke report's chart once had its legend over the "better" note)."""
    import matplotlib as mpl
    from matplotlib.backends.backend_svg import FigureCanvasSVG
    from matplotlib.figure import Figure

    with mpl.rc_context(plots._RC):
        fig = Figure(figsize=plots.FIGSIZE, dpi=72, layout="constrained")
        FigureCanvasSVG(fig)
        ax = fig.add_subplot()
        ax.plot([1.0, 2.0, 3.0], [1.0, 1.2, 3.0], marker="o", label="a")
        ax.legend(title="g")
        plots._place_legend(fig, ax)
        legend = ax.get_legend()
        checked = legend.get_window_extent().transformed(ax.transAxes.inverted())
        ax.plot([1.0, 1.1], [2.9, 3.0], marker="o")  # data where the legend is: "best" would move it
        fig.set_figheight(fig.get_figheight() * 1.4)
        plots._layout(fig)
        drawn = legend.get_window_extent().transformed(ax.transAxes.inverted())
        np.testing.assert_allclose(drawn.p0, checked.p0, atol=1e-6)
        assert plots._legend_covers(ax, legend)  # what _tidy's second check then finds, and moves it beside


def test_a_marker_centred_on_the_legend_frame_counts_as_covered():
    """A marker centred on the legend frame's edge is half under it: a smoke report's chart kept its legend over
    an error bar's cap 0.99 px inside the frame (within the 1-px slack the check allowed), which the browser
    check, at the page's scale, found."""
    import matplotlib as mpl
    from matplotlib.backends.backend_svg import FigureCanvasSVG
    from matplotlib.figure import Figure

    with mpl.rc_context(plots._RC):
        fig = Figure(figsize=plots.FIGSIZE, dpi=72, layout="constrained")
        FigureCanvasSVG(fig)
        ax = fig.add_subplot()
        ax.plot([0.0, 1.0, 2.0], [3.0, 2.0, 0.5], marker="o", label="a series")
        ax.set(xlim=(-0.2, 2.2), ylim=(0.0, 3.2))
        legend = ax.legend(loc="lower left")
        plots._layout(fig)
        assert not plots._legend_covers(ax, legend)
        near_top = ax.transData.inverted().transform(
            (legend.get_window_extent().x0 + 20, legend.get_window_extent().y1 - 0.01))
        ax.plot([near_top[0]], [near_top[1]], marker="_")
        assert plots._legend_covers(ax, legend)
        near_top = ax.transData.inverted().transform(
            (legend.get_window_extent().x0 + 20, legend.get_window_extent().y1 + 1.5))
        ax.lines[-1].set_data([near_top[0]], [near_top[1]])  # just above the frame: a marker's half is under it
        assert plots._legend_covers(ax, legend)
        ax.lines[-1].set_data([near_top[0]], [near_top[1] + 0.3])  # clear of it
        assert not plots._legend_covers(ax, legend)
