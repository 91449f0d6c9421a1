"""``kruger2003-nocue``: the cost of the intermediate pass and the empty-block check on synthetic results."""

from pipeline.experiments.kruger2003 import nocue as N
from test_kruger2003_methods import NOISY, evaluate, timed

NAME = "kruger2003-nocue"


def _rows(seconds, fragments=(1000, 1000, 1000), frames=lambda t: [t] * 5, group="no_cue"):
    return [timed(frames(t), group=group, config=c, view="front", run=f"no_cue.{c}", count_fragments_main=f)
            for c, t, f in zip(("rc", "rc-a", "rc-b"), seconds, fragments)]


def test_nocue_claims():
    rows = _rows((1.0, 1.3, 1.35))
    overhead = evaluate(NAME, "overhead", rows)
    assert overhead.holds is True and overhead.measured == "time / RC's ×1.35 (95 % CI ×1.35–×1.35) (RC-b)"
    assert "main-pass fragments ×1 of RC's" in overhead.detail  # nothing culled: the cost is the passes'
    rows = _rows((1.0, 0.8, 1.35), fragments=(1000, 900, 880))
    assert evaluate(NAME, "overhead", rows).holds is False


def test_a_control_with_empty_space_measures_no_overhead():
    # RC-b culled blocks RC-a drew: the control's premise is broken, so its time says nothing of the passes.
    result = evaluate(NAME, "overhead", _rows((1.0, 1.3, 1.35), fragments=(1000, 900, 400)))
    assert result.holds is None and not result.inconclusive and "the control has empty space" in result.detail


def test_the_overhead_is_inconclusive_where_the_frames_straddle_its_bound():
    # RC-a at ×1.05 or ×3.15 of RC, frame by frame: its interval spans 10–60 %.
    rows = _rows((1.0, 1.05, 1.3), frames=lambda t: [t] * 5 if t != 1.05 else [t * f for f in NOISY])
    result = evaluate(NAME, "overhead", rows)
    assert result.inconclusive and result.interval[0] < 1.1 < result.interval[1]
    assert result.measured.endswith("(RC-a)")


def test_the_papers_about_30_percent_is_judged_beside_ours():
    claims = [c.id for c in N.NoCue.claims]
    assert claims.index("overhead-paper") + 1 == claims.index("overhead")
    paper, ours = N.NoCue.claims[:2]
    assert (paper.target, ours.target, paper.paper_value) == ("paper", "ours", ours.paper_value)
    # "A loss in performance of about 30 %": the frame rate 25–35 % below RC's, frame time ×1.33–×1.54.
    assert N.PAPER_OVERHEAD == (1 / 0.75, 1 / 0.65)
    holds = evaluate(NAME, "overhead-paper", _rows((1.0, 1.4, 1.45)))  # 29 % and 31 % fewer frames
    assert holds.holds is True and holds.measured.startswith("time / RC's ×1.4 ")
    for seconds in ((1.0, 1.3, 1.35), (1.0, 1.4, 1.55)):  # 23 % or 35.5 % fewer frames: ours holds, the paper's not
        assert evaluate(NAME, "overhead-paper", _rows(seconds)).holds is False, seconds
        assert evaluate(NAME, "overhead", _rows(seconds)).holds is True, seconds
