"""``ropinski2005-size`` (E5): its plan at each scale, its claim on synthetic frames and counts, its page."""

from functools import partial

import numpy as np
import pandas as pd
import pytest

from core.errors import InputError
from pipeline import experiments
from pipeline.experiments.kit import intervals
from pipeline.experiments.ropinski2005.lens_size import RADII, rank_correlation, slope_decision, sweep_points
from reports import blocks
from reports.html import ReportContext
import test_ropinski2005_table1 as shared
from test_ropinski2005_table1 import NOISY

NAME = "ropinski2005-size"

planned = partial(shared.planned, name=NAME)
evaluate = partial(shared.evaluate, NAME)


def row(scene, run, seconds, *, group=True, **tags):
    frames = [seconds * f for f in tags.pop("factors", [1.0] * 5)]
    return {"experiment": NAME, "status": "ok", "role": "test", "scene": scene, "view": "headline", "run": run,
            "interleave": scene if group else "", "time_total": float(np.median(frames)),
            "frames_total": intervals.format_frames(frames), "time_total_min": min(frames),
            "time_total_max": max(frames), "count_rays": 1000, "count_samples": 10000, **tags}


def sweep(overheads, *, own=None, scenes=("skull",), noisy_first=False, group=True):
    """Rows of a sweep: ``overheads[i]`` (fraction) at radius ``RADII[i]``, coverage 10·(i + 1) %.

    ``noisy_first``: the smallest outside-appearance lens gets noisy frames.
    """
    rows = []
    for scene in scenes:
        rows.append(row(scene, f"{scene}.off", 0.01, group=group, config="off", appearance="none"))
        for appearance, values in (("outside", overheads), ("own", own or overheads)):
            for i, overhead in enumerate(values):
                noisy = {"factors": NOISY} if noisy_first and i == 0 and appearance == "outside" else {}
                rows.append(row(scene, f"{scene}.r{RADII[i]:g}.{appearance}", 0.01 * (1 + overhead), group=group,
                                **noisy, config="segments", appearance=appearance, radius=RADII[i],
                                count_lens_rays=100 * (i + 1), count_samples_region0=5000, count_samples_region1=900,
                                count_samples_region2=100))
    return rows


RISING = [0.05, 0.1, 0.15, 0.2, 0.25, 0.3]


# ------------------------------------------------------------------------------------------------ plan
def test_plan_at_each_scale():
    smoke = planned("smoke")
    assert {r.tags["scene"] for r in smoke} == {"skull", "seismic"} and {r.interleave for r in smoke} == {"skull",
                                                                                                        "seismic"}
    assert sorted(r.id for r in smoke if r.tags["scene"] == "skull") == [
        "skull.off", "skull.r0.1.outside", "skull.r0.1.own", "skull.r0.3.outside", "skull.r0.3.own",
        "skull.r0.6.outside", "skull.r0.6.own"]
    for run in smoke:
        assert run.backend == "gl-raycast" and run.repeat >= 3 and run.warmup >= 1
        if run.tags["config"] == "off":
            assert "lenses" not in run.scene
            continue
        lens = run.scene["lenses"][0]
        assert lens["radius"] == pytest.approx(run.tags["radius"] * 32)
        if run.tags["appearance"] == "outside":
            assert lens["appearance"] == {"mode": "dvr", "preset": run.tags["preset"]}
        else:
            assert lens["appearance"]["mode"] == run.tags["lens_mode"]
    default = planned("default")
    assert len(default) == 2 * (1 + 2 * len(RADII))
    assert {r.tags["scene"] for r in planned("full")} == {"skull", "seismic", "foot"}
    with pytest.raises(InputError, match="engine has a box lens"):
        planned("smoke", scenes=["engine"])
    with pytest.raises(InputError, match="three different radii"):
        planned("smoke", radii=[0.1, 0.1, 0.3])


# ---------------------------------------------------------------------------------------------- claims
def test_a_rising_overhead_holds_a_flat_or_falling_one_fails():
    result = evaluate("overhead-grows", sweep(RISING))
    assert result.holds is True
    # 5 % of the frame more per 10 % more rays through the lens: a slope of 0.5.
    assert result.measured.startswith("slope of the overhead against the coverage (% of the frame per % of the "
                                      "rays) 0.5 (95 % CI 0.5–0.5)")
    assert "coverage 10–60 % of the rays, overhead 5 to 30 %, rank correlation 1" in result.detail
    assert evaluate("overhead-grows", sweep([0.2] * 6)).holds is False
    falling = evaluate("overhead-grows", sweep(RISING[::-1]))
    assert falling.holds is False and falling.margin < 0


def test_the_claim_reads_the_outside_appearance_only():
    assert evaluate("overhead-grows", sweep(RISING, own=RISING[::-1])).holds is True
    assert evaluate("overhead-grows", sweep(RISING[::-1], own=RISING)).holds is False


def test_every_scene_must_rise():
    rows = sweep(RISING, scenes=("skull",)) + sweep(RISING[::-1], scenes=("seismic",))
    result = evaluate("overhead-grows", rows)
    assert result.holds is False and result.measured.endswith("(seismic)")


def test_noise_makes_a_small_slope_inconclusive_unless_paired():
    shallow = [0.10, 0.101, 0.102, 0.103, 0.104, 0.105]
    unpaired = evaluate("overhead-grows", sweep(shallow, noisy_first=True, group=False))
    assert unpaired.inconclusive and unpaired.interval[0] < 0 < unpaired.interval[1]
    rows = sweep(shallow)
    for r in rows:  # one slow round slowed every run of the group
        frames = [r["time_total"] * f for f in NOISY]
        r["frames_total"] = intervals.format_frames(frames)
    paired = evaluate("overhead-grows", rows)
    assert paired.holds is True and paired.interval == pytest.approx((0.01, 0.01))


def test_the_points_and_their_statistics():
    points = sweep_points(pd.DataFrame(sweep(RISING)), "skull", "outside", resampler=intervals.Resampler())
    assert [p[0] for p in points] == list(RADII)
    assert [p[1] for p in points] == pytest.approx([10, 20, 30, 40, 50, 60])
    assert [p[2] for p in points] == pytest.approx([5, 10, 15, 20, 25, 30])
    assert rank_correlation(points) == pytest.approx(1.0)
    assert slope_decision(points).value == pytest.approx(0.5)
    with pytest.raises(ValueError, match="need three lens radii"):
        sweep_points(pd.DataFrame(sweep(RISING[:2])), "skull", "outside", resampler=intervals.Resampler())
    rows = pd.DataFrame(sweep(RISING)).drop(columns="count_lens_rays")
    assert evaluate("overhead-grows", rows).holds is None


# ------------------------------------------------------------------------------------------------ page
def test_the_page(tmp_path):
    rows = pd.DataFrame(sweep(RISING, own=[0.0, -0.02, -0.04, -0.06, -0.08, -0.1]))
    for column in ("png", "exr", "record"):
        rows[column] = ""
    report = tmp_path / "report"
    out = experiments.get(NAME).report(rows, ReportContext(report, tmp_path, NAME))
    takeaways = next(b for b in out if isinstance(b, blocks.Takeaways))
    assert any("skull (dvr) -0.2 (95 % CI -0.2–-0.2)" in s for s in takeaways.sentences)
    table = next(b for b in out if isinstance(b, blocks.Table) and b.title.startswith("Overhead and samples")).frame
    assert len(table) == 12 and set(table["lens shows"]) == {"outside", "own"}
    top = table[(table["lens shows"] == "outside") & (table["radius (edge)"] == 0.6)].iloc[0]
    assert top["overhead (%)"] == pytest.approx(30) and top["rays through the lens (%)"] == pytest.approx(60)
    figure = next(b for b in out if isinstance(b, blocks.Figure))
    assert "no data" not in (report / figure.path).read_text()
