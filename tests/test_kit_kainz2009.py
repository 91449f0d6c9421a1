"""Tests of the kit helpers kainz2009's experiments share (pipeline.experiments.kit)."""

import pandas as pd

from pipeline.experiments.kit.checks import Bound, Measure, worst_psnr


def test_worst_psnr_is_a_bound_on_the_lowest_psnr_of_the_matching_rows_naming_its_scene():
    check = worst_psnr("the worst image", 40.0, role="test")
    assert check == Bound(Measure("the worst image", match={"role": "test"}, column="psnr", statistic="min",
                                  unit="dB", label="scene"), at_least=40.0)
    assert check.expected == "the worst image ≥ 40 dB" and check.kind == "accuracy"
    df = pd.DataFrame({"role": ["test", "test", "truth"], "scene": ["head", "engine", "head"],
                       "psnr": [45.0, 38.5, 10.0]})
    result = check(df)
    assert result.measured == "38.5 dB (engine)" and result.holds is False
    assert worst_psnr("the worst image", 38.0, role="test")(df).holds is True
