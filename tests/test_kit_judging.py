"""The kit's judging helpers (pipeline.experiments.kit.judging), the one copy every paper's claims use."""

import numpy as np
import pandas as pd
import pytest

from pipeline.experiments.kit import intervals, judging, pages
from pipeline.experiments.kit.results import MissingColumn

NOISY = [1.0, 1.0, 3.0, 1.0, 3.0]
"""Frames whose resampled median is 1 or 3: against steady frames, a ratio whose interval spans ×1–×3."""


def timed(seconds, *, group="", stage="total", **row):
    """A successful row whose ``stage`` was timed over the frames ``seconds``, in interleave ``group``."""
    return {**row, f"time_{stage}": float(np.median(seconds)), f"frames_{stage}": intervals.format_frames(seconds),
            "interleave": group, "experiment": "x"}


def test_time_ratios_decide_on_interleaved_frames():
    steady = [1.0] * 5
    rows = pd.DataFrame([timed(NOISY, group="g", config="slow", view="v"), timed(steady, group="g", config="fast",
                                                                                 view="v")])
    decision = judging.time_ratio(rows, "slow", "fast", resampler=intervals.Resampler(), at_least=2.0)
    assert decision.value == pytest.approx(1.0) and decision.interval == pytest.approx((1.0, 3.0))
    assert decision.inconclusive
    # Frames of one round are drawn together: a disturbance that slowed both cancels in their ratio.
    rows = pd.DataFrame([timed([2 * t for t in NOISY], group="g", config="slow", view="v"),
                         timed(NOISY, group="g", config="fast", view="v")])
    decision = judging.time_ratio(rows, "slow", "fast", resampler=intervals.Resampler(), at_least=1.9)
    assert decision.interval == pytest.approx((2.0, 2.0)) and decision.holds is True
    alone = rows.assign(interleave="")
    assert judging.time_ratio(alone, "slow", "fast", resampler=intervals.Resampler(), at_least=1.9).inconclusive
    with pytest.raises(ValueError, match="no successful other run"):
        judging.time_ratio(rows, "other", "fast", resampler=intervals.Resampler())


def test_time_ratio_selects_its_rows_by_matching_tags_or_a_selector():
    rows = pd.DataFrame([timed([2.0] * 3, config="slow", scene="a"), timed([1.0] * 3, config="fast", scene="a"),
                         timed([9.0] * 3, config="slow", scene="b"), timed([1.0] * 3, config="fast", scene="b")])
    assert judging.time_ratio(rows, "slow", "fast", resampler=intervals.Resampler(), scene="a").value == 2.0
    picked = []

    def select(frame, config, **match):
        picked.append((config, match))
        return judging.config_rows(frame, config, scene="b")

    assert judging.time_ratio(rows, "slow", "fast", resampler=intervals.Resampler(), select=select).value == 9.0
    assert picked == [("slow", {}), ("fast", {})]


def test_config_rows_names_what_is_missing():
    rows = pd.DataFrame([timed([1.0], config="rc", scene="head")])
    assert len(judging.config_rows(rows, "rc", scene="head")) == 1
    with pytest.raises(ValueError, match=r"no successful rc run of the sweep for \{'scene': 'foot'\}"):
        judging.config_rows(rows, "rc", what="the sweep", scene="foot")


def test_all_of_needs_every_labelled_decision_and_names_the_worst():
    holds, fails = intervals.decide(3.0, (2.5, 3.5), at_least=2.0), intervals.decide(1.5, (1.4, 1.6), at_least=2.0)
    straddles = intervals.decide(2.1, (1.9, 2.3), at_least=2.0)
    result = judging.all_of({"head": holds, "engine": fails, "foot": straddles}, notes={"head": "samples ×3"},
                            what="time ")
    assert result.holds is False and result.measured == "time ×1.5 (95 % CI ×1.4–×1.6) (engine)"
    assert result.detail.startswith("head: ×3 (95 % CI ×2.5–×3.5) (samples ×3); engine: ×1.5")
    result = judging.all_of({"head": holds, "foot": straddles}, extra="thesis ×2")
    assert result.inconclusive and result.measured.endswith("(foot)") and result.interval == (1.9, 2.3)
    assert result.detail.endswith("; thesis ×2")
    assert judging.all_of({"head": holds}).holds is True
    shares = judging.all_of({"C1": intervals.decide(0.02, (0.01, 0.03), at_most=0.1)}, show=pages.as_percent)
    assert shares.measured == "2 % (95 % CI 1 %–3 %) (C1)"


def test_all_of_nothing_is_not_a_verdict():
    with pytest.raises(ValueError, match="nothing to judge"):
        judging.all_of({}, what="time ")


def test_a_ratio_of_draws_has_an_interval_only_with_both_draws():
    top, bottom = (2.0, np.array([1.8, 2.0, 2.2] * 100)), (1.0, np.ones(300))
    decision = judging.ratio_of_draws(top, bottom, at_least=judging.STRICTLY_ABOVE_ONE)
    assert decision.value == 2.0 and decision.holds is True and decision.interval[0] > 1.0
    alone = judging.ratio_of_draws((2.0, None), bottom, at_least=1.5)
    assert alone.interval is None


def test_strict_bounds_refuse_a_tie():
    tie = intervals.decide(1.0, (1.0, 1.0), at_least=judging.STRICTLY_ABOVE_ONE)
    assert tie.holds is False
    assert intervals.decide(1.0, (1.0, 1.0), at_most=judging.STRICTLY_BELOW_ONE).holds is False


def test_a_count_leaves_out_the_views_that_did_not_count_it_and_a_missing_column_is_not_measured():
    rows = pd.DataFrame({"count_samples": [10.0, np.nan, 30.0]})
    assert judging.median_count(rows, "count_samples") == 20.0
    assert np.isnan(judging.median_count(pd.DataFrame({"count_samples": [np.nan]}), "count_samples"))
    with pytest.raises(MissingColumn):
        judging.median_count(rows, "count_fragments")


def test_judging_imports_no_page_code():
    import ast
    import inspect

    for module in (judging, __import__("pipeline.experiments.kit.checks", fromlist=["x"])):
        tree = ast.parse(inspect.getsource(module))
        imported = {node.module for node in ast.walk(tree) if isinstance(node, ast.ImportFrom)}
        imported |= {alias.name for node in ast.walk(tree) if isinstance(node, ast.Import) for alias in node.names}
        assert not any(name.endswith("kit.pages") or name.startswith("reports") for name in imported), module


def test_the_caption_says_how_the_gl_frames_were_timed():
    rows = pd.DataFrame({"info_frames": [5, 5], "option_effective_timing": ["finish", "query"]})
    caption = pages.frames_caption(rows)
    assert caption.startswith("median of 5 frames after warm-up, uploads excluded as their own stage; ")
    assert "glFinish" in caption and "GL timer queries" in caption
    assert pages.frames_caption(pd.DataFrame({"info_frames": [3]})).endswith("; timing method not recorded.")
    cl = pages.frames_caption(rows, unit="timed frames", untimed="hulls built in the warm-up frame", how="by events")
    assert cl == "median of 5 timed frames after warm-up, hulls built in the warm-up frame; by events."


def test_every_target_of_ours_stands_beside_the_papers_own_number():
    from pipeline.experiments import all_experiments

    ours = 0
    for experiment in all_experiments().values():
        for claim in experiment.claims:
            if claim.target != "ours":
                continue
            ours += 1
            assert claim.paper_value, f"{experiment.name}/{claim.id}: our target needs the paper's number it departs from"
            papers = [c for c in experiment.claims if c.target == "paper" and c.paper_value == claim.paper_value]
            assert papers, f"{experiment.name}/{claim.id}: the paper's {claim.paper_value} is not judged on its own"
            # The twin is named after ours and stands right before it, in claims.csv and on the page.
            ids = [c.id for c in experiment.claims]
            twin = f"{claim.id}-paper"
            assert twin in ids and ids.index(twin) == ids.index(claim.id) - 1, \
                f"{experiment.name}/{claim.id}: the paper's twin {twin!r} does not stand right before it"
            assert experiment.claims[ids.index(twin)] in papers, f"{experiment.name}/{twin}: not the paper's number"
    assert ours >= 10


def test_a_timing_decision_says_how_many_frames_its_thinnest_arm_holds():
    from pipeline.experiments.kit.model import ClaimResult

    rows = pd.DataFrame([timed([2.0] * 7, group="g", config="slow", view="v"),
                         timed([1.0] * 5, group="g", config="fast", view="v")])
    decision = judging.time_ratio(rows, "slow", "fast", resampler=intervals.Resampler(), at_least=1.5)
    assert decision.holds is True and decision.frames == 5
    assert ClaimResult.decided("×2", decision).frames == 5
    few = judging.time_ratio(rows.assign(**{"frames_total": [intervals.format_frames([2.0] * 7),
                                                             intervals.format_frames([1.0] * 3)]}),
                             "slow", "fast", resampler=intervals.Resampler(), at_least=1.5)
    assert few.inconclusive and few.frames == 3 and "fewer than 5" in few.why
    # "Every scene": the deciding (worst) one's frames.
    assert intervals.combine([decision, few]).frames == 3
    assert intervals.decide(2.0, None, at_least=1.5).frames is None  # a count has no frames
