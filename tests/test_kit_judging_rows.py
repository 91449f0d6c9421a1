"""The kit's judging over rows of timed runs: like-scope ratios and statistics with intervals, lines, starved
parallel runs (pipeline.experiments.kit.judging; test_kit_judging.py tests the rest of the module)."""

import numpy as np
import pandas as pd
import pytest

from pipeline.experiments.kit import intervals, judging
from pipeline.experiments.kit.intervals import Resampler
from pipeline.experiments.kit.model import ClaimResult
from pipeline.experiments.kit.results import MissingColumn
from test_lacroute1995_package import frames, timed

STARVED = "2 workers had 1.0 free cores (other work used 1.00)"


def _rows(*medians, spread=0.0, run="r", **extra):
    return pd.DataFrame([{"experiment": "e", "run": f"{run}{i}", "view": "v", "interleave": "", **timed(m, spread),
                          **extra} for i, m in enumerate(medians)])


def test_ratio_takes_its_interval_from_the_frames():
    decision = judging.ratio(_rows(2.0, spread=0.1), _rows(1.0, spread=0.1, run="s"), judging.TECHNIQUE, Resampler(),
                             at_least=1.5)
    assert decision.value == pytest.approx(2.0) and decision.holds is True
    assert decision.interval[0] < 2.0 < decision.interval[1]
    close = judging.ratio(_rows(1.05, spread=0.3), _rows(1.0, spread=0.3, run="s"), judging.TECHNIQUE, Resampler(),
                          at_most=1.0)
    assert close.holds is None and close.inconclusive
    with pytest.raises(MissingColumn):
        judging.ratio(_rows(1.0), _rows(1.0), judging.COMPOSITE, Resampler())


def test_runs_timed_together_are_paired_round_by_round():
    # Both runs slowed by the same disturbances, frame for frame: their ratio is exact only when paired.
    slow = np.linspace(1, 3, 15)
    a = {"time_technique": 2.0, "frames_technique": " ".join(f"{2 * s:g}" for s in slow)}
    b = {"time_technique": 1.0, "frames_technique": " ".join(f"{s:g}" for s in slow)}

    def rows(values, group):
        return pd.DataFrame([{"experiment": "e", "run": "a" if values is a else "b", "view": "v", "interleave": group,
                              **values}])

    paired = judging.ratio(rows(a, "g"), rows(b, "g"), judging.TECHNIQUE, Resampler())
    alone = judging.ratio(rows(a, ""), rows(b, ""), judging.TECHNIQUE, Resampler())
    assert paired.interval == pytest.approx((2.0, 2.0), rel=1e-4)
    assert alone.interval[1] - alone.interval[0] > 1.0


def test_centred_draws_sit_about_the_value():
    draws = np.linspace(0.3, 0.5, 101)  # extremes of noisy medians: every draw above the value 0.1
    assert judging.decided(0.1, draws, at_most=0.12).holds is False
    centred = judging.decided(0.1, draws, at_most=0.12, centred=True)
    assert centred.interval[0] < 0.1 < centred.interval[1] and centred.inconclusive


def test_r_squared_fits_every_draw():
    x = np.array([1.0, 2.0, 3.0, 4.0])
    draws = np.vstack([2 * x + 1, [1.0, 3.0, 2.0, 4.0]])
    assert judging.r_squared(x, draws) == pytest.approx([1.0, 0.64])
    assert judging.r_squared(x, np.full((1, 4), 3.0)) == pytest.approx([1.0])  # a constant: fitted exactly
    assert judging.r_squared(x, None) is None


def test_labelled_names_each_scene_with_its_interval():
    one = judging.ratio(_rows(2.0, spread=0.1), _rows(1.0, run="s"), judging.TECHNIQUE, Resampler(), at_least=1.5)
    other = judging.decided(1.2, None, at_least=1.5)
    words = judging.labelled({"head": one, "brain": other})
    assert words.startswith("×2 (head; 95 % CI ×") and words.endswith(", ×1.2 (brain)")


def test_a_starved_run_turns_what_it_could_decide_inconclusive():
    rows = _rows(1.0, info_starved=STARVED, info_worker_busy=0.5)
    failed = ClaimResult("×1.5", False, "slow", (1.4, 1.6), -0.5)
    result = judging.unless_starved(failed, rows, holding_survives=True)
    assert result.holds is None and result.inconclusive and STARVED in result.detail
    assert result.interval == (1.4, 1.6)
    held = ClaimResult("×0.5", True, "fast")
    assert judging.unless_starved(held, rows, holding_survives=True).holds is True
    assert judging.unless_starved(held, rows, holding_survives=False).inconclusive
    assert judging.unless_starved(failed, _rows(1.0), holding_survives=True) is failed
    assert judging.busy(rows) == "workers busy 50 % at least" and judging.busy(_rows(1.0)) == ""


def test_frames_helper_spreads_about_the_median():
    values = np.array(frames(2.0, 0.5).split(), float)
    assert np.median(values) == pytest.approx(2.0) and values.min() == pytest.approx(1.0)


def test_timed_rows_are_the_matching_rows_with_a_time_and_none_is_an_error_naming_them():
    rows = pd.concat([_rows(1.0, scene="a"), _rows(2.0, run="s", scene="b"),
                      _rows(float("nan"), run="t", scene="a")], ignore_index=True)
    assert list(judging.timed(rows, "scene a", judging.TECHNIQUE, scene="a").run) == ["r0"]
    with pytest.raises(ValueError, match="no time_technique of scene c"):
        judging.timed(rows, "scene c", judging.TECHNIQUE, scene="c")


def test_a_statistic_over_rows_has_a_draw_per_resample_and_fails_closed_without_a_value():
    value, draws = judging.statistic(_rows(1.0, 3.0, spread=0.1), judging.TECHNIQUE, Resampler(), reduce="max")
    assert value == pytest.approx(3.0) and draws.shape == (intervals.DRAWS,) and draws.min() > 2.0
    with pytest.raises(ValueError, match="no run reported time_technique"):
        judging.statistic(_rows(float("nan")), judging.TECHNIQUE, Resampler())


def test_counts_name_each_row_and_say_when_none_was_counted():
    rows = pd.DataFrame({"scene": [1.0, "head"], "count_samples": [1_050_000, 7]})
    assert judging.counts(rows, "count_samples") == "1: 1.05e+06, head: 7"
    assert judging.counts(rows, "count_fragments") == "n/a"


def test_a_line_is_judged_on_the_r_squared_of_every_draw():
    rows = _rows(1.0, 2.0, 3.0, 4.0, spread=0.01).assign(samples=[1, 2, 3, 4])
    slope, intercept, decision = judging.line(rows, "samples", judging.TECHNIQUE, Resampler(), at_least=0.95)
    assert slope == pytest.approx(1.0) and intercept == pytest.approx(0.0, abs=1e-9) and decision.holds is True
    assert judging.r2_words(decision.value) == "R² 1"


def test_a_speedup_is_a_pair_whose_ratio_to_another_is_decided_and_inconclusive_without_draws():
    rows = pd.concat([_rows(2.0, spread=0.1, config="slow"), _rows(1.0, spread=0.1, run="s", config="fast")],
                     ignore_index=True)
    value, draws = judging.speedup(rows, "slow", "fast", resampler=Resampler(), column=judging.TECHNIQUE)
    assert value == pytest.approx(2.0) and draws.shape == (intervals.DRAWS,)
    assert judging.ratio_pair((value, draws), (1.0, None)) == (value, None)
    assert judging.ratio_of_draws((value, draws), (1.0, np.ones_like(draws)), at_least=1.5).holds is True
    # No frames behind a side: no interval, and a timing without one decides nothing (issue 34: fail closed).
    assert judging.ratio_of_draws((value, None), (1.0, None), at_least=1.5).inconclusive


def test_points_of_a_configuration_fail_closed_and_counts_ratio_to_nan_where_uncounted():
    rows = pd.DataFrame([{"run": "a", "config": "slow", "view": "v", "time_total": 2.0, "count_samples": 40},
                         {"run": "b", "config": "fast", "view": "v", "time_total": 0.5, "count_samples": 10},
                         {"run": "c", "config": "broken", "view": "v", "time_total": float("nan")}])
    assert judging.median_time(rows, "slow") == 2.0 and judging.point_speedup(rows, "slow", "fast") == 4.0
    with pytest.raises(ValueError, match="run c reported no 'total' time"):
        judging.point_speedup(rows, "broken", "fast")
    assert judging.count_ratio(rows, "slow", "fast") == 4.0
    assert np.isnan(judging.count_ratio(rows, "broken", "fast"))


def test_a_count_a_claim_rests_on_fails_closed_where_no_view_counted_it():
    rows = pd.DataFrame({"count_samples": [4.0, 2.0, np.nan]})
    assert judging.counted(rows, "count_samples", "brain") == 3.0
    with pytest.raises(ValueError, match="brain counted no samples"):
        judging.counted(pd.DataFrame({"count_samples": [np.nan]}), "count_samples", "brain")


def test_the_worst_row_decides_and_each_group_keeps_its_own_extreme():
    rows = pd.DataFrame({"case": ["a", "a", "b"], "psnr": [40.0, 31.0, 35.0], "holes": [0, 2, 5]})
    worst, per_case = judging.worst_of(rows, "psnr", "case", lowest=True)
    assert worst.psnr == 31.0 and per_case.to_dict() == {"a": 31.0, "b": 35.0}
    worst, per_case = judging.worst_of(rows, "holes", "case")
    assert worst.case == "b" and per_case.to_dict() == {"a": 2, "b": 5}


def test_a_ratio_of_two_stages_taken_once_per_view_resamples_the_views_and_fails_closed():
    rows = pd.DataFrame({"time_phi_p": [0.20, 0.22, 0.18, 0.21, 0.19], "time_phi_t": [0.01, 0.011, 0.009, 0.01, 0.01]})
    value, draws, views = judging.view_ratio(rows, "time_phi_p", "time_phi_t", Resampler(), key="head")
    assert value == pytest.approx(20.0) and views == 5 and draws.shape == (intervals.DRAWS,)
    assert draws.min() < value < draws.max()
    with pytest.raises(ValueError, match="head: a view without"):
        judging.view_ratio(rows.assign(time_phi_t=[0.01, np.nan, 0.01, 0.01, 0.01]), "time_phi_p", "time_phi_t",
                           Resampler(), key="head")


def test_a_ratio_of_two_stages_timed_once_per_process_resamples_each_views_processes_too():
    """Two processes per view: their spread widens the interval that the views' spread alone would give."""
    rows = pd.DataFrame({"time_phi_p": [0.20, 0.22, 0.18, 0.21, 0.19], "time_phi_t": [0.01] * 5})
    alone = intervals.interval_of(judging.view_ratio(rows, "time_phi_p", "time_phi_t", Resampler(), key="h")[1])
    apart = rows.assign(once_phi_p=[f"{p - 0.04:.2f} | {p + 0.04:.2f}" for p in rows.time_phi_p],
                        once_phi_t=["0.01 | 0.01"] * 5)
    value, draws, views = judging.view_ratio(apart, "time_phi_p", "time_phi_t", Resampler(), key="h")
    low, high = intervals.interval_of(draws)
    assert value == pytest.approx(20.0) and views == 5 and low < alone[0] and high > alone[1]
    # A process's two stages are drawn together: a process slow in both leaves the ratio where it was.
    together = rows.assign(once_phi_p=[f"{p:.2f} | {2 * p:.2f}" for p in rows.time_phi_p],
                           once_phi_t=["0.01 | 0.02"] * 5)
    assert intervals.interval_of(judging.view_ratio(together, "time_phi_p", "time_phi_t", Resampler(),
                                                    key="h")[1]) == pytest.approx(alone)


def _scene_run(scene, config, median, spread):
    """A test run of ``config`` on ``scene`` with whole frames about ``median`` seconds (± ``spread``)."""
    return {"experiment": "e", "run": f"{config}-{scene}", "view": "v", "interleave": "", "role": "test",
            "scene": scene, "config": config, **timed(median, spread, stage="total")}


def test_ratios_compare_only_the_scenes_both_configurations_rendered_and_none_is_not_measured():
    frame = pd.DataFrame([_scene_run(s, c, m, 0.05) for s, c, m in
                          (("s1", "peel", 3.0), ("s1", "tiled", 1.0), ("s2", "peel", 2.0), ("s3", "tiled", 1.0))])
    result = judging.ratios_where_both(frame, ["s1", "s2", "s3"], "peel", "tiled", what="peel / tiled",
                                       describe=lambda rows: f"{len(rows)} rows", at_least=2.0)
    assert result.holds is True and "(s1)" in result.measured and "s2" not in result.detail
    assert result.detail.endswith("; peel / tiled; 2 rows")
    with pytest.raises(ValueError, match="no scene of s2, s3 rendered by both peel and tiled"):
        judging.ratios_where_both(frame, ["s2", "s3"], "peel", "tiled", what="")


def test_each_scene_may_be_judged_against_a_band_of_its_own():
    frame = pd.DataFrame([_scene_run(s, c, m, 0.01) for s, c, m in
                          (("s1", "peel", 3.0), ("s1", "tiled", 1.0), ("s2", "peel", 2.0), ("s2", "tiled", 1.0))])
    bands = {"s1": {"at_least": 2.5, "at_most": 3.5}, "s2": {"at_least": 2.5, "at_most": None}}
    result = judging.ratios_where_both(frame, bands, "peel", "tiled", what="peel / tiled")
    assert result.holds is False and "(s2)" in result.measured
    assert judging.ratios_where_both(frame, {"s1": bands["s1"]}, "peel", "tiled", what="").holds is True


def _psnr_rows(values):
    """Test rows of two methods on two views, and a reference row that is never judged."""
    rows = [{"role": "test", "config": config, "scene": "head", "view": view, "run": f"head.{config}", "psnr": psnr}
            for (config, view), psnr in values.items()]
    return pd.DataFrame(rows + [{"role": "reference", "config": "truth", "scene": "head", "view": "a",
                                 "run": "head.truth", "psnr": 0.0}])


def test_worst_test_psnr_names_the_worst_view_and_lists_methods_in_the_given_order():
    rows = _psnr_rows({("rc", "a"): 52.0, ("rc", "b"): 41.5, ("sbvr", "a"): 47.0, ("sbvr", "b"): 60.0})
    result = judging.worst_test_psnr(rows, ("sbvr", "rc"), at_least=40.0)
    assert result.holds
    assert result.measured == "41.5 dB (rc, head, b)"
    assert result.detail == "sbvr: ≥ 47 dB, rc: ≥ 41.5 dB"
    assert not judging.worst_test_psnr(rows, ("sbvr", "rc"), at_least=45.0).holds
    assert judging.worst_test_psnr(rows, ("sbvr",), at_least=45.0).holds  # rc's 41.5 dB is not judged


def test_worst_test_psnr_refuses_a_view_without_its_comparison():
    rows = _psnr_rows({("rc", "a"): 52.0, ("rc", "b"): float("nan")})
    with pytest.raises(ValueError, match=r"head\.rc \(b\)"):
        judging.worst_test_psnr(rows, ("rc",), at_least=40.0)
    with pytest.raises(ValueError, match="no PSNR"):
        judging.worst_test_psnr(_psnr_rows({("rc", "a"): float("nan")}), ("rc",), at_least=40.0)
