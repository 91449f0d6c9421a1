"""Tests of the kit's helpers for reading results into pages: view angles, stage times, titles, counts in words."""

import numpy as np
import pandas as pd
import pytest

from pipeline.experiments.kit.pages import title_or
from pipeline.experiments.kit.results import complete_groups, footprint_psnr, rows_matching, stage_points, view_angle
from pipeline.experiments.kit.words import full_count, megabytes, short_duration
from reports.imageio import write_exr


def test_view_names_give_their_angle():
    assert [view_angle(v) for v in ("az22.5", "deg090", "az-10", "az0")] == [22.5, 90.0, -10.0, 0.0]
    with pytest.raises(ValueError, match="names no angle"):
        view_angle("headline")


def test_titles_fall_back_where_the_results_cannot_say_them():
    assert title_or(lambda d: f"{len(d)} rows", [1, 2], "none") == "2 rows"
    assert title_or(lambda d: d["missing"], {}, "none") == "none"  # a KeyError: the data cannot say
    with pytest.raises(IndexError):
        title_or(lambda d: d[5], [1], "none")
    assert title_or(lambda d: d[5], [1], "none", errors=(IndexError,)) == "none"


def test_stage_points_give_a_stage_in_milliseconds_with_its_frame_range():
    frame = pd.DataFrame({"time_warp": [0.002, 0.004], "time_warp_min": [0.001, 0.003],
                          "time_warp_max": [0.003, 0.005]})
    points = stage_points(frame, "time_warp", name="warp_ms")
    assert np.allclose(points.warp_ms, [2.0, 4.0]) and np.allclose(points.warp_ms_min, [1.0, 3.0])
    assert np.allclose(points.warp_ms_max, [3.0, 5.0]) and "warp_ms" not in frame  # a copy
    bare = stage_points(frame[["time_warp"]], "time_warp", name="warp_ms")
    assert bare.warp_ms_min.isna().all() and bare.warp_ms_max.isna().all()


def test_counts_bytes_and_times_per_item_in_words():
    assert full_count(15900) == "15,900" and full_count("12") == "12" and full_count(np.nan) == ""
    assert megabytes(4_890_000) == "4.89" and megabytes(None) == ""
    assert short_duration(20.7e-9) == "20.7 ns" and short_duration(3e-6) == "3 µs"


def test_complete_groups_keep_the_values_where_every_configuration_rendered():
    frame = pd.DataFrame({"scene": ["a", "a", "b", "c", "c"], "config": ["x", "y", "x", "y", "x"], "v": range(5)})
    groups = complete_groups(frame, ("x", "y"), by="scene", missing="none has both")
    assert list(groups) == ["a", "c"] and list(groups["c"]) == ["x", "y"]
    assert groups["c"]["x"].v.tolist() == [4] and groups["a"]["y"].v.tolist() == [1]
    with pytest.raises(ValueError, match="none has both"):
        complete_groups(frame, ("x", "z"), by="scene", missing="none has both")


def test_footprint_psnr_reads_only_the_pixels_either_image_covers(tmp_path):
    truth = np.zeros((20, 20, 4), np.float32)
    truth[5:10, 5:10] = 0.5
    test = truth.copy()
    test[5:10, 5:10, 0] += 0.1
    paths = [str(tmp_path / name) for name in ("truth.exr", "test.exr", "empty.exr")]
    for path, image in zip(paths, (truth, test, np.zeros_like(truth))):
        write_exr(path, image)
    assert footprint_psnr(paths[0], paths[1]) == pytest.approx(10 * np.log10(4 / 0.01))  # 1 of 4 channels off
    with pytest.raises(ValueError, match="cover no pixel"):
        footprint_psnr(paths[2], paths[2])


def test_a_numeric_tag_matches_the_rows_of_runs_csv_that_hold_it_as_a_float():
    """runs.csv holds an integer tag as a float where another experiment leaves its column empty: a claim
    re-judged from it (scripts/compare-results) must find the same rows as from the experiment's own table."""
    table = pd.DataFrame({"task_size": [8, 64], "schedule": ["contiguous", "round-robin"], "workers": [2, 2]})
    merged = pd.concat([table, pd.DataFrame({"schedule": ["other experiment"]})], ignore_index=True)
    assert merged.task_size.dtype == float
    for frame in (table, merged):
        found = rows_matching(frame, "", task_size=8, schedule="contiguous")
        assert found.schedule.tolist() == ["contiguous"]
