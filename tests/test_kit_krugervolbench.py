"""Tests of the kit helpers that kruger2003 and volbench share with other papers."""

import pandas as pd
import pytest

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
