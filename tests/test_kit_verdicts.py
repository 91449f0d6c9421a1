"""Tests of claim verdicts (pipeline.experiments.kit.verdicts): a claim that would read a run that did not
happen is blocked, naming it; one that does not read it keeps its verdict."""

import numpy as np
import pandas as pd
import pytest

from pipeline.experiments.kit.checks import Measure, Ratio
from pipeline.experiments.kit.intervals import format_frames
from pipeline.experiments.kit.model import Claim, ClaimResult
from pipeline.experiments.kit.results import numeric, one_row, rows_matching, stage_time
from pipeline.experiments.kit.verdicts import claim_sentences, depends_on_missing, judge


def _runs(*rows):
    """An experiment's tidy rows: ``(run, backend, scene, status, cause, time, extra)`` per run."""
    out = []
    for run, backend, scene, status, cause, time, extra in rows:
        row = {"experiment": "e", "run": run, "backend": backend, "scene": scene, "status": status, "cause": cause,
               "reason": "" if status == "ok" else f"{cause} of {run}", "view": "front" if status == "ok" else None,
               "planned_views": "" if status == "ok" else "front", **extra}
        if status == "ok":
            row["time_total"] = time
        out.append(row)
    return pd.DataFrame(out)


def _ratio(df):
    """The narrow-band kind of claim: the C8 frame over the C1 frame of the tiled caster, ≤ 4."""
    c1 = stage_time(one_row(df, "C1", scene="C1", backend="tiled"))
    c8 = stage_time(one_row(df, "C8", scene="C8", backend="tiled"))
    return ClaimResult(f"×{c8 / c1:.3g}", bool(c8 / c1 <= 4))


def _all_fast(df):
    """A claim over every tiled run that happened: each under 10 ms."""
    times = numeric(rows_matching(df, "tiled", backend="tiled"), "time_total")
    return ClaimResult(f"{times.max() * 1e3:.3g} ms", bool(times.max() < 0.01))


# Declared counts: these claims test which runs a verdict reads. Their numbers are times, and a timing decided
# on point values alone is inconclusive (test_a_timing_claim_decided_without_an_interval_is_inconclusive).
RATIO = Claim("ratio", "C8 costs at most four times C1", "≤ 4", _ratio, kind="count")
ALL_FAST = Claim("fast", "every tiled frame is fast", "< 10 ms", _all_fast, kind="count")
PEEL_ONLY = Claim("peel", "depth peeling renders C1 under 10 ms", "< 10 ms",
                  lambda df: ClaimResult("ok", stage_time(one_row(df, "peel", scene="C1", backend="peel")) < 0.01),
                  kind="count")


def test_every_run_there_gives_the_plain_verdict():
    rows = _runs(("C1.tiled", "tiled", "C1", "ok", "", 0.002, {}), ("C8.tiled", "tiled", "C8", "ok", "", 0.0145, {}))
    assert judge(RATIO, rows).verdict == "fails"  # ×7.24
    assert judge(ALL_FAST, rows).verdict == "fails"


def test_a_claim_that_reads_a_failed_run_is_blocked_naming_it():
    # With C8.tiled failed, the remaining runs alone say "holds": the claim cannot be judged.
    rows = _runs(("C1.tiled", "tiled", "C1", "ok", "", 0.002, {}), ("C3.tiled", "tiled", "C3", "ok", "", 0.004, {}),
                 ("C8.tiled", "tiled", "C8", "failed", "error", None, {}),
                 ("C1.peel", "peel", "C1", "ok", "", 0.003, {}))
    assert ALL_FAST.evaluate(rows[rows.status == "ok"]).holds is True
    for claim in (RATIO, ALL_FAST):
        verdict = judge(claim, rows)
        assert verdict.verdict == "blocked" and verdict.holds is None
        assert verdict.detail == "blocked: needs run C8.tiled, which failed"
    # A claim that never selects the failed run keeps its verdict.
    assert judge(PEEL_ONLY, rows).verdict == "holds"


def test_a_planned_limit_does_not_block():
    rows = _runs(("C1.tiled", "tiled", "C1", "ok", "", 0.002, {}), ("C3.tiled", "tiled", "C3", "ok", "", 0.004, {}),
                 ("C8.tiled", "tiled", "C8", "skipped", "unsupported", None, {}))
    assert judge(ALL_FAST, rows).verdict == "holds"
    assert depends_on_missing(_all_fast, rows) == []


@pytest.mark.parametrize("cause, words", [("unavailable", "cannot run here"), ("no-data", "has no data here"),
                                          ("time-limit", "exceeded the time limit")])
def test_a_backend_that_made_no_frame_blocks_as_one(cause, words):
    rows = _runs(*[(f"{scene}.tiled", "tiled", scene, "skipped" if cause != "time-limit" else "failed", cause, None, {})
                   for scene in ("C1", "C2", "C3", "C4", "C5", "C6", "C7", "C8", "C9", "C10")],
                 ("C1.peel", "peel", "C1", "ok", "", 0.003, {}))
    verdict = judge(RATIO, rows)
    assert verdict.verdict == "blocked"
    assert verdict.detail == f"blocked: needs tiled, which {words} (all 10 of its runs)"
    assert judge(PEEL_ONLY, rows).verdict == "holds"


def test_a_column_only_the_missing_runs_report_blocks_rather_than_goes_unmeasured():
    def fragments(df):
        return ClaimResult("n", bool(numeric(rows_matching(df, "tiled", backend="tiled"), "count_fragments").max() < 64))

    claim = Claim("frag", "fragments stay under the cap", "< 64", fragments, kind="count")
    rows = _runs(("C1.tiled", "tiled", "C1", "failed", "error", None, {}), ("C1.peel", "peel", "C1", "ok", "", 0.003, {}))
    assert claim.evaluate(rows[rows.status == "ok"]).holds is None  # "not measurable" on what is left
    assert judge(claim, rows).verdict == "blocked"
    ok_only = rows[rows.status == "ok"]
    verdict = judge(claim, ok_only)
    assert verdict.verdict == "not measured" and verdict.detail == "column 'count_fragments' (no run reported it)"


def test_take_away_sentences_leave_blocked_claims_to_the_claims_table():
    rows = _runs(("C1.tiled", "tiled", "C1", "ok", "", 0.002, {}), ("C8.tiled", "tiled", "C8", "failed", "error", None, {}),
                 ("C1.peel", "peel", "C1", "ok", "", 0.003, {}))
    assert claim_sentences(_judged((RATIO, PEEL_ONLY), rows)) == [
        "depth peeling renders C1 under 10 ms: ok, holds ()."]


def _judged(claims, rows):
    """The claims as claims.csv holds them once judged: what a page's take-aways read."""
    verdicts = [judge(claim, rows) for claim in claims]
    return pd.DataFrame([{"claim": c.id, "statement": c.statement, "verdict": v.verdict, "measured": v.measured,
                          "detail": v.detail} for c, v in zip(claims, verdicts)])


NOISE = 1 + 0.02 * np.random.default_rng(11).standard_normal(30)
"""Thirty frames' relative noise (2 %)."""


def _timed(run, seconds, **extra):
    """An ``ok`` row of ``run`` with thirty timed frames around ``seconds`` (as collect writes them)."""
    frames = seconds * NOISE
    return (run, "tiled", run.split(".")[0], "ok", "", float(np.median(frames)),
            {"frames_total": format_frames(frames), **extra})


SPEED_UP = Claim("speed-up", "C1 is at least twice as fast as C8", "≥ ×2",
                 Ratio(Measure("C8", match={"scene": "C8"}), Measure("C1", match={"scene": "C1"}), at_least=2.0))


def test_a_timing_claim_whose_interval_straddles_its_bound_is_inconclusive():
    rows = _runs(_timed("C1.tiled", 0.002), _timed("C8.tiled", 0.004))
    verdict = judge(SPEED_UP, rows)
    assert verdict.verdict == "inconclusive" and verdict.holds is None
    low, high = verdict.interval
    assert low < 2.0 < high and verdict.margin == pytest.approx(0.0)
    assert verdict.measured.startswith("×2 (95 % CI")
    assert claim_sentences(_judged((SPEED_UP,), rows)) == [
        f"C1 is at least twice as fast as C8: {verdict.measured}, inconclusive ({verdict.detail})."]
    clear = judge(SPEED_UP, _runs(_timed("C1.tiled", 0.002), _timed("C8.tiled", 0.005)))
    assert clear.verdict == "holds" and clear.interval[0] > 2.0 and clear.margin == pytest.approx(0.25)
    assert clear.disturbed_views == verdict.disturbed_views == 0
    short = judge(SPEED_UP, _runs(_timed("C1.tiled", 0.002), _timed("C8.tiled", 0.003)))
    assert short.verdict == "fails" and short.interval[1] < 2.0 and short.margin == pytest.approx(-0.25)


def test_a_verdict_that_rests_on_a_disturbed_view_is_inconclusive():
    disturbed = {"info_disturbed": "other work used 1.00 cores while it was timed"}
    # C8 disturbed: ten times faster it would not be twice as slow as C1.
    rows = _runs(_timed("C1.tiled", 0.002, info_disturbed=""), _timed("C8.tiled", 0.005, **disturbed))
    verdict = judge(SPEED_UP, rows)
    assert verdict.verdict == "inconclusive" and verdict.holds is None and verdict.disturbed_views == 1
    assert verdict.detail.startswith("inconclusive: its verdict rests on 1 view timed while the machine was disturbed "
                                     "(C8.tiled/front: other work used 1.00 cores while it was timed)")
    assert judge(SPEED_UP, rows.drop(columns="frames_total")).verdict == "inconclusive"  # on its times alone
    # Both disturbed: a disturbance slows two runs by different amounts (under a CPU hog the matrix's
    # brute force and early termination did: ×1.71 quiet, ×3.0 loaded), so their ratio cannot decide.
    both = _runs(_timed("C1.tiled", 0.002, **disturbed), _timed("C8.tiled", 0.005, **disturbed))
    assert judge(SPEED_UP, both).verdict == "inconclusive"
    # Far from its bound too: a random slow-down rarely restores what a disturbance broke, so a verdict
    # that reads disturbed times is not trusted however far it is from its bound.
    far = _runs(_timed("C1.tiled", 0.002, **disturbed), _timed("C8.tiled", 2.0, **disturbed))
    assert judge(SPEED_UP, far).verdict == "inconclusive"
    # A claim that reads no disturbed view keeps its verdict.
    other = _runs(_timed("C1.tiled", 0.002, info_disturbed=""), _timed("C8.tiled", 0.005, info_disturbed=""),
                  _timed("C9.tiled", 0.001, **disturbed))
    assert judge(SPEED_UP, other).verdict == "holds"


def test_a_timing_claim_decided_without_an_interval_is_inconclusive():
    rows = _runs(("C1.tiled", "tiled", "C1", "ok", "", 0.002, {}), ("C8.tiled", "tiled", "C8", "ok", "", 0.0145, {}))
    timing = Claim("ratio", "C8 costs at most four times C1", "≤ 4", _ratio, kind="timing")
    verdict = judge(timing, rows)
    assert verdict.verdict == "inconclusive" and verdict.measured == "×7.25"
    assert verdict.detail.endswith("inconclusive: a timing decided without an interval (no bootstrap over timed "
                                   "frames behind it)")
    assert judge(RATIO, rows).verdict == "fails"  # a count needs no interval
    decided = Claim("speed-up", "C1 is faster", "≥ ×2", Ratio(Measure("C8", match={"scene": "C8"}),
                                                            Measure("C1", match={"scene": "C1"}), at_least=2.0))
    timed = rows.assign(frames_total=[format_frames([0.002] * 5), format_frames([0.0145] * 5)], interleave="g")
    assert judge(decided, timed).verdict == "holds"  # with its interval


def test_an_inconclusive_timing_says_about_how_many_processes_would_decide_it():
    """As pyperf says how many runs a benchmark needs: the half-width towards the bound shrinks as 1/√processes."""
    from pipeline.experiments.kit.intervals import decide, processes_to_decide

    def straddling(value, interval):
        return Claim("c", "A beats B", "≥ ×2", lambda df: ClaimResult.decided(
            f"×{value}", decide(value, interval, at_least=2.0)), kind="timing")

    rows = _runs(_timed("C1.tiled", 0.002, processes=2), _timed("C8.tiled", 0.004, processes=2))
    verdict = judge(straddling(2.1, (1.9, 2.3)), rows)
    # (0.2 / 0.1)² × 2 processes = 8
    assert verdict.verdict == "inconclusive" and verdict.processes == 2
    assert verdict.detail == ("its interval straddles the bound: about 8 processes per arm (here 2) would decide it "
                              "at the spread measured")
    assert "too near it" in judge(straddling(2.001, (1.9, 2.1)), rows).detail
    assert processes_to_decide(2.0, (1.9, 2.1), 2.0, 3) is None  # on the bound: nothing decides it
    assert processes_to_decide(1.95, (1.9, 2.05), 2.0, 3) == 12  # below the bound: the upper half-width counts
    assert processes_to_decide(2.1, None, 2.0, 3) is None


def test_a_timing_claim_on_one_process_per_run_is_inconclusive():
    """Frames of one process cannot show the spread between two (issue 23: ×2.23 and ×1.96 in two runs, each
    ±2 %): a run of one process per arm does not decide a timing claim, however clear its interval."""
    one = judge(SPEED_UP, _runs(_timed("C1.tiled", 0.002, processes=1), _timed("C8.tiled", 0.005, processes=1)))
    assert one.verdict == "inconclusive" and one.holds is None and one.processes == 1
    assert one.interval[0] > 2.0  # clear of the bound, as far as one process's frames go
    assert one.detail.endswith("inconclusive: its interval rests on one process per run (the profile's replicates "
                               "is 1), whose frames cannot show the spread between two processes; replicates ≥ 2 "
                               "would decide it")
    two = judge(SPEED_UP, _runs(_timed("C1.tiled", 0.002, processes=2), _timed("C8.tiled", 0.005, processes=2)))
    assert two.verdict == "holds" and two.processes == 2
    # A count rests on no frames: one process decides it.
    rows = _runs(("C1.tiled", "tiled", "C1", "ok", "", 0.002, {"processes": 1}),
                 ("C8.tiled", "tiled", "C8", "ok", "", 0.0145, {"processes": 1}))
    assert judge(RATIO, rows).verdict == "fails"
