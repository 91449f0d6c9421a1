"""Tests of claims' confidence intervals and the third verdict (pipeline.experiments.kit.intervals)."""

import numpy as np
import pandas as pd
import pytest

from pipeline.experiments.kit import intervals
from pipeline.experiments.kit.intervals import (combine, decide, format_frames, frame_count, frames_column, parse_frames,
                                                ratio_decision)


@pytest.mark.parametrize("column, frames", [
    ("time_total", "frames_total"), ("time_composite", "frames_composite"), ("time_technique", "frames_technique"),
    ("time_total_min", None), ("time_composite_max", None), ("count_samples", None), ("psnr", None),
])
def test_only_per_frame_times_have_frames(column, frames):
    assert frames_column(column) == frames


def test_frames_survive_their_text_to_six_significant_digits():
    values = np.array([0.00123456789, 1.5, 2.0e-7, 37.25])
    text = format_frames(values)
    assert text == "0.00123457 1.5 2e-07 37.25"
    np.testing.assert_allclose(parse_frames(text), values, rtol=5e-6)
    for empty in ("", "   ", None, float("nan")):  # a cell of a run without frames, as pandas reads it
        assert parse_frames(empty) is None


@pytest.mark.parametrize("value, interval, holds, margin", [
    (1.8, (1.6, 1.9), True, 0.2),     # wholly above the floor
    (1.2, (1.1, 1.4), False, -0.2),   # wholly below
    (1.65, (1.3, 1.7), None, 0.1),    # straddles it: the point says holds, the interval cannot tell
    (1.35, (1.3, 1.7), None, -0.1),   # and the other way round
    (1.6, (1.5, 1.7), True, 1 / 15),  # touching the bound is on it
])
def test_decide_at_least(value, interval, holds, margin):
    decision = decide(value, interval, at_least=1.5)
    assert decision.holds is holds and decision.inconclusive is (holds is None)
    assert decision.interval == interval and decision.value == value
    assert decision.margin == pytest.approx(margin)


@pytest.mark.parametrize("interval, holds", [((0.002, 0.004), True), ((0.011, 0.02), False), ((0.008, 0.012), None)])
def test_decide_at_most(interval, holds):
    value = sum(interval) / 2
    decision = decide(value, interval, at_most=0.01)
    assert decision.holds is holds
    assert decision.margin == pytest.approx((0.01 - value) / 0.01)


@pytest.mark.parametrize("interval, holds, margin", [
    ((1.2, 1.8), True, 0.5 / 2),    # value 1.5 within [1, 2]: the nearer bound, 2, is 25 % away
    ((2.1, 2.5), False, -0.3 / 2),  # above the band: the ceiling's (negative) margin
    ((0.5, 0.9), False, -0.3),      # below it: the floor's
    ((1.5, 2.5), None, 0.0),        # straddles the ceiling
    ((0.5, 2.5), None, 0.5 / 2),    # wider than the band: neither wholly in nor wholly out
])
def test_decide_two_sided(interval, holds, margin):
    value = sum(interval) / 2
    decision = decide(value, interval, at_least=1.0, at_most=2.0)
    assert decision.holds is holds
    assert decision.margin == pytest.approx(margin)


def test_without_an_interval_the_point_decides_and_a_zero_bound_has_an_absolute_margin():
    assert decide(1.2, None, at_least=1.5).holds is False
    assert decide(1.8, None, at_least=1.5) == intervals.Decision(1.8, None, True, pytest.approx(0.2), bound=1.5)
    assert decide(0.25, None, at_least=0).margin == 0.25
    assert decide(0.25, None, at_most=0).margin == -0.25


def test_combine_fails_on_any_failure_is_inconclusive_on_any_straddle_and_keeps_the_worst():
    holds = decide(2.0, (1.8, 2.2), at_least=1.5)
    close = decide(1.6, (1.55, 1.65), at_least=1.5)
    straddles = decide(1.7, (1.4, 2.0), at_least=1.5)
    fails = decide(1.2, (1.1, 1.3), at_least=1.5)
    both = combine([holds, close])
    assert both.holds is True and both == close  # the smallest margin
    assert combine([holds, straddles]).holds is None and combine([holds, straddles]).interval == straddles.interval
    # A failure outweighs an inconclusive decision, even one with a smaller margin.
    worse = decide(1.0, (0.5, 1.6), at_least=1.5)
    assert worse.holds is None and worse.margin < fails.margin
    assert combine([straddles, worse, fails, holds]) == fails
    assert combine([holds, straddles, worse]) == worse
    with pytest.raises(ValueError, match="no decisions"):
        combine([])


def _rows(*runs):
    """Tidy rows: ``(run, interleave, frames)`` each, the time the median of its frames, as collect writes them."""
    return pd.DataFrame([{"experiment": "e", "run": run, "view": "front", "interleave": group,
                          "time_total": float(np.median(frames)), "frames_total": format_frames(frames)}
                         for run, group, frames in runs])


QUIET = 1 + 0.02 * np.random.default_rng(7).standard_normal(40)
"""Forty frames' relative noise on a quiet machine (2 %)."""


def test_a_clear_speed_up_holds_with_an_interval_that_excludes_the_bound():
    rows = _rows(("slow", "", 0.002 * QUIET), ("fast", "", 0.001 * QUIET[::-1]))
    decision = ratio_decision(rows[rows.run == "slow"], rows[rows.run == "fast"], at_least=1.5)
    assert decision.value == pytest.approx(2.0, rel=0.03)
    low, high = decision.interval
    assert 1.5 < low < decision.value < high < 2.5
    assert decision.holds is True and decision.margin > 0.25


def test_equal_distributions_straddle_the_bound_and_are_inconclusive():
    frames = 0.002 * QUIET
    rows = _rows(("a", "", frames), ("b", "", frames[::-1]))
    decision = ratio_decision(rows[rows.run == "a"], rows[rows.run == "b"], at_least=1.0)
    assert decision.value == 1.0  # the same frames: the same median
    low, high = decision.interval
    assert low < 1.0 < high
    assert decision.holds is None and decision.inconclusive


def _disturbed_rounds(group_a, group_b, seed=3):
    """A and B (A twice as slow) timed in rounds, each round slowed by its own disturbance, up to ×3."""
    rng = np.random.default_rng(seed)
    rounds = rng.uniform(1.0, 3.0, 30)
    a = 0.002 * rounds * (1 + 0.01 * rng.standard_normal(30))
    b = 0.001 * rounds * (1 + 0.01 * rng.standard_normal(30))
    return _rows(("A", group_a, a), ("B", group_b, b))


def _width(rows):
    decision = ratio_decision(rows[rows.run == "A"], rows[rows.run == "B"], at_least=1.5)
    return decision.interval[1] - decision.interval[0], decision


def test_runs_timed_together_are_resampled_by_round_so_a_shared_disturbance_cancels():
    paired, decision = _width(_disturbed_rounds("g", "g"))
    assert decision.holds is True and decision.interval[0] < 2.0 < decision.interval[1]
    unpaired, _ = _width(_disturbed_rounds("", ""))
    other_groups, _ = _width(_disturbed_rounds("g", "h"))
    assert paired < unpaired / 5 and paired < other_groups / 5
    # Another view of the group is another set of rounds: not paired with this one.
    rows = _disturbed_rounds("g", "g")
    rows.loc[rows.run == "B", "view"] = "side"
    assert _width(rows)[0] > paired * 5


def test_the_same_frames_give_the_same_interval():
    rows = _disturbed_rounds("", "")
    assert _width(rows)[1] == _width(rows.copy())[1]


def test_a_timing_without_frames_is_inconclusive_not_judged_on_its_point_value():
    rows = _rows(("slow", "", 0.002 * QUIET), ("fast", "", 0.001 * QUIET))
    for lacking in (rows.drop(columns="frames_total"), rows.assign(frames_total=["", rows.frames_total[1]])):
        decision = ratio_decision(lacking[lacking.run == "slow"], lacking[lacking.run == "fast"], at_least=1.5)
        assert decision.value == pytest.approx(2.0) and decision.interval is None and decision.inconclusive
        assert decision.why.startswith("no timed frames behind numerator")
    # A count has no frames at all: its ratio is a point.
    counts = pd.DataFrame({"run": ["a", "b"], "count_samples": [300, 100]})
    decision = ratio_decision(counts[counts.run == "a"], counts[counts.run == "b"], column="count_samples", at_most=2)
    assert (decision.value, decision.interval, decision.holds) == (3.0, None, False)


def test_two_stages_of_the_same_rows_give_a_share():
    rows = _rows(("a", "", 0.002 * QUIET)).assign(time_composite=0.0005, frames_composite=format_frames(0.0005 * QUIET))
    decision = ratio_decision(rows, rows, column="time_composite", bottom_column="time_total", at_most=0.3)
    assert decision.value == pytest.approx(0.25, rel=0.03) and decision.holds is True
    assert decision.interval[1] < 0.3


def test_a_timing_arm_with_fewer_than_five_frames_is_inconclusive():
    three = _rows(("slow", "", [0.002] * 3), ("fast", "", [0.001] * 3))
    decision = ratio_decision(three[three.run == "slow"], three[three.run == "fast"], at_least=1.5)
    assert decision.interval == pytest.approx((2.0, 2.0)) and decision.inconclusive  # a zero-width interval decides nothing
    assert decision.why == "numerator: 3 timed frames; denominator: 3 timed frames, fewer than 5"
    five = _rows(("slow", "", [0.002] * 5), ("fast", "", [0.001] * 5))
    assert ratio_decision(five[five.run == "slow"], five[five.run == "fast"], at_least=1.5).holds is True
    # Frames of several views add up: two views of three frames are six.
    views = pd.concat([_rows(("slow", "", [0.002] * 3)).assign(view=v) for v in ("a", "b")]
                      + [_rows(("fast", "", [0.001] * 3)).assign(view=v) for v in ("a", "b")], ignore_index=True)
    assert ratio_decision(views[views.run == "slow"], views[views.run == "fast"], at_least=1.5).holds is True
    assert frame_count(views[views.run == "slow"], "time_total") == 6 and frame_count(views, "count_x") == 0


def test_a_missing_value_is_not_a_verdict():
    for value in (np.nan, float("nan")):
        with pytest.raises(ValueError, match="missing"):
            decide(value, None, at_most=1.0)  # it compared False with the bound: "fails"


# ------------------------------------------------------------------------------------- processes
def _process_rows(*runs):
    """Tidy rows ``(run, interleave, [frames of each process])``, timed as collect writes a replicated run."""
    return pd.DataFrame([{"experiment": "e", "run": run, "view": "front", "interleave": group,
                          "time_total": intervals.process_time(processes),
                          "frames_total": intervals.format_processes(processes)}
                         for run, group, processes in runs])


def test_processes_survive_their_text_and_a_run_time_is_the_mean_of_their_medians():
    processes = [np.array([0.001, 0.002, 0.003]), np.array([0.004, 0.005, 0.009])]
    text = intervals.format_processes(processes)
    assert text == "0.001 0.002 0.003 | 0.004 0.005 0.009"
    assert [list(p) for p in intervals.parse_processes(text)] == [list(p) for p in processes]
    assert list(parse_frames(text)) == [0.001, 0.002, 0.003, 0.004, 0.005, 0.009]
    assert intervals.process_time(processes) == pytest.approx((0.002 + 0.005) / 2)
    rows = _process_rows(("a", "", processes), ("b", "", [processes[0]]))
    assert frame_count(rows, "time_total") == 9


def test_the_interval_covers_the_spread_between_processes_not_only_their_frames():
    """Two processes of one run whose frames agree within themselves but not with each other (as the bonsai's
    ESS+ERT ratio did: ×2.23 in one run, ×1.96 in the next): the interval must span both."""
    first, second = 0.0020 * QUIET[:10], 0.0024 * QUIET[10:20]
    other = 0.001 * QUIET[20:30]
    one = _process_rows(("slow", "", [first]), ("fast", "", [other]))
    both = _process_rows(("slow", "", [first, second]), ("fast", "", [other, other[::-1]]))
    narrow = ratio_decision(one[one.run == "slow"], one[one.run == "fast"], at_least=1.0)
    wide = ratio_decision(both[both.run == "slow"], both[both.run == "fast"], at_least=1.0)
    assert wide.value == pytest.approx(2.2, rel=0.03)
    assert wide.interval[0] < 2.05 and wide.interval[1] > 2.35  # about each process's own ratio
    assert (wide.interval[1] - wide.interval[0]) > 3 * (narrow.interval[1] - narrow.interval[0])


def test_runs_timed_together_share_their_processes_so_a_slow_process_cancels():
    """A and B timed together in two processes, the second twice as slow for both: paired by process (and by
    round within one), their ratio stays narrow; timed apart, the process's slowness widens it."""
    a, b = 0.002 * QUIET[:10], 0.001 * QUIET[10:20]
    together = _process_rows(("A", "g", [a, 2 * a[::-1]]), ("B", "g", [b, 2 * b[::-1]]))
    apart = together.assign(interleave=["", ""])
    paired, _ = _width(together)
    unpaired, _ = _width(apart)
    assert _width(together)[1].value == pytest.approx(2.0, rel=0.03)
    assert paired < unpaired / 5


def test_runs_of_one_group_timed_in_different_processes_are_drawn_apart():
    """A group of two OpenGL stacks is timed in a process per stack (pipeline.experiments.stack_parts): rows of one
    group whose processes differ are not paired, as runs of separate jobs are not; rows of the same processes are."""
    a, b = 0.002 * QUIET[:10], 0.001 * QUIET[10:20]
    together = _process_rows(("A", "g", [a, 2 * a[::-1]]), ("B", "g", [b, 2 * b[::-1]]))
    same = together.assign(harness_pids=["[11, 12]", "[11, 12]"])
    parts = together.assign(harness_pids=["[11, 12]", "[13, 14]"])
    assert _width(same)[0] == pytest.approx(_width(together)[0])
    assert _width(parts)[0] == pytest.approx(_width(together.assign(interleave=["", ""]))[0])
    one_process = together.assign(harness_pid=[11, 13], harness_pids=[np.nan, np.nan])
    assert _width(one_process)[0] == pytest.approx(_width(parts)[0])
