"""The kit helpers from xue2005: rows by tag, group and image pair, sums and intervals of draws, views, pages."""

import numpy as np
import pandas as pd
import pytest

from pipeline.experiments.kit.intervals import Resampler, interval_of, interval_or_nan, row_draws
from pipeline.experiments.kit.judging import image_pairs, summed
from pipeline.experiments.kit.pages import by_scene, silent_without_runs, unless_missing
from pipeline.experiments.kit.planning import HEADLINE_VIEW, orbit_views
from pipeline.experiments.kit.results import MissingColumn, interleave_groups, tagged

ROWS = pd.DataFrame({"scene": ["head", "head", "bonsai", "head"], "config": ["ess", "basic", "basic", "ert"],
                     "role": ["test", "test", "peer", "test"]})


def test_tagged_matches_as_text_and_is_empty_without_the_column():
    assert tagged(ROWS, scene="head", role="test").config.tolist() == ["ess", "basic", "ert"]
    assert tagged(pd.DataFrame({"size": [64, 128]}), size="128").index.tolist() == [1]
    missing = tagged(ROWS, backend="gl-isbvr")
    assert missing.empty and list(missing.columns) == list(ROWS.columns)


def test_interval_or_nan_is_the_interval_or_nans():
    draws = np.linspace(1.0, 2.0, 101)
    assert interval_or_nan(draws) == interval_of(draws)
    assert interval_or_nan(draws, 0.5) == pytest.approx((1.25, 1.75))
    for nothing in (None, np.array([np.nan, np.inf])):
        low, high = interval_or_nan(nothing)
        assert np.isnan(low) and np.isnan(high)


def test_unless_missing_turns_a_missing_run_or_column_into_empty():
    assert unless_missing(lambda frame, column: frame[column].tolist(), ROWS, column="scene", empty=[]) == [
        "head", "head", "bonsai", "head"]
    assert unless_missing(lambda: ROWS["missing"], empty="none") == "none"

    def no_run():
        raise ValueError("no successful run")

    assert unless_missing(no_run, empty=None) is None
    with pytest.raises(ZeroDivisionError):
        unless_missing(lambda: 1 / 0, empty=None)


def test_silent_without_runs_says_nothing_where_runs_are_missing():
    @silent_without_runs
    def sentences(frame):
        """Every config, in a sentence."""
        if "config" not in frame:
            raise MissingColumn("config")
        return [", ".join(frame.config)]

    assert sentences(ROWS) == ["ess, basic, basic, ert"]
    assert sentences(ROWS.drop(columns="config")) == []
    assert sentences.__doc__ == "Every config, in a sentence."


def test_by_scene_keeps_the_scenes_first_order_and_sorts_within():
    ordered = by_scene(ROWS, "config")
    assert list(zip(ordered.scene, ordered.config)) == [("head", "basic"), ("head", "ert"), ("head", "ess"),
                                                        ("bonsai", "basic")]
    assert ordered.scene_order.tolist() == [0, 0, 0, 1]
    assert by_scene(ROWS).index.tolist() == [0, 1, 3, 2]


def test_interleave_groups_in_first_order():
    rows = ROWS.assign(interleave=["b", "a", "b", "a"])
    groups = interleave_groups(rows, role="test")
    assert list(groups) == ["b", "a"]
    assert groups["a"].config.tolist() == ["basic", "ert"] and groups["b"].config.tolist() == ["ess"]
    assert interleave_groups(rows, scene="none") == {}


def test_summed_adds_the_views_and_their_draws():
    views = pd.DataFrame({"run": ["r", "r"], "view": ["a", "b"], "time_draw": [0.002, 0.003],
                          "frames_draw": ["0.001 0.002 0.003", "0.003 0.003 0.004"]})
    value, draws = summed(views, "time_draw", Resampler(draws=50))
    assert value == pytest.approx(0.005)
    assert draws == pytest.approx(row_draws(views, "time_draw", Resampler(draws=50)).sum(axis=1))
    assert summed(views.drop(columns="frames_draw"), "time_draw", Resampler()) == (pytest.approx(0.005), None)


def test_orbit_views_start_with_the_headline_and_skip_its_azimuth():
    views = orbit_views("fbm_control", 4)
    assert views[0]["view"] == HEADLINE_VIEW["view"]
    assert [(v["view"], v["azimuth"], v["elevation"]) for v in views[1:]] == [
        ("orbit000", 0.0, 20.0), ("orbit090", 90.0, 20.0), ("orbit180", 180.0, 20.0), ("orbit270", 270.0, 20.0)]
    assert [v["view"] for v in orbit_views("fbm_control", 12)].count("orbit030") == 0
    assert [v["view"] for v in orbit_views("fbm_control", 12, repeat_headline=True)].count("orbit030") == 1
    assert len(orbit_views("fbm_control", 0)) == 1


def test_image_pairs_match_scene_and_view_where_both_images_exist(tmp_path):
    exr = {name: tmp_path / f"{name}.exr" for name in ("a1", "a2", "b1")}
    for path in exr.values():
        path.write_bytes(b"")
    rows = pd.DataFrame({"config": ["a", "a", "b", "b"], "scene": ["head"] * 4, "view": ["v1", "v2", "v1", "v2"],
                         "order": ["f", "f", "b", "b"],
                         "exr": [str(exr["a1"]), str(exr["a2"]), str(exr["b1"]), str(tmp_path / "missing.exr")]})
    pairs = image_pairs(rows, "a", "b", first_match={"order": "f"})
    found = [(scene, view, a.exr, b.exr) for scene, view, a, b in pairs]
    assert found == [("head", "v1", str(exr["a1"]), str(exr["b1"]))]
    with pytest.raises(ValueError, match="no view rendered by both a and b"):
        image_pairs(rows[rows.view == "v2"], "a", "b")
    with pytest.raises(ValueError, match="no successful b run"):
        image_pairs(rows, "a", "b", second_match={"order": "f"})
