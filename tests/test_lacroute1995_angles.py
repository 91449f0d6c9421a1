"""lacroute1995-angles: time over a full turn and the principal-axis switch (Fig. 5.3)."""

import numpy as np

from pipeline.experiments.lacroute1995.angles import principal_axis
from test_lacroute1995_package import check_report, evaluate, planned, timed

NAME = "lacroute1995-angles"
ANGLES = np.arange(0, 360, 10)


def test_plan_turns_in_equal_steps_timed_together():
    runs = planned(NAME, **{NAME: {"angle_step": 30}})
    angles = next(r for r in runs if r.id == "sphere.turn")
    assert [v["view"] for v in angles.views] == [f"deg{a}" for a in range(0, 360, 30)]
    assert {r.interleave for r in runs} == {"turns"}


def test_principal_axis_switches_at_45_degrees():
    assert [principal_axis(a) for a in (0, 44, 45, 90, 134, 135, 224, 225, 314, 315, 359)] == \
        [0, 0, 1, 1, 1, 0, 0, 1, 1, 0, 0]


def _turn(times, dataset="sphere", axes=None, spread=0.0):
    angles = np.arange(0, 360, 360 / len(times))
    rows = [{"dataset": dataset, "view": f"deg{a:g}", **timed(t, spread), "time_total": 2 * t, "count_samples": 1e5 * t}
            for a, t in zip(angles, times)]
    if axes is not None:
        for row, axis in zip(rows, axes):
            row["info_principal_axis"] = axis
    return rows


def test_angle_claims():
    smooth = 1.0 + 0.02 * np.cos(np.radians(4 * ANGLES))
    head = 1.0 + 0.07 * np.cos(np.radians(2 * ANGLES))
    rows = _turn(smooth) + _turn(head, "ct_skull")
    assert evaluate(NAME, "no-axis-switch-jump", rows).holds is True
    assert evaluate(NAME, "sphere-flat", rows).holds is True
    assert evaluate(NAME, "head-varies-more", rows).holds is True
    jumpy = np.where([principal_axis(a) == 1 for a in ANGLES], 1.3, 1.0) + 0.01 * np.cos(np.radians(ANGLES))
    assert evaluate(NAME, "no-axis-switch-jump", _turn(jumpy)).holds is False
    assert evaluate(NAME, "no-axis-switch-jump-samples", rows).holds is True
    assert evaluate(NAME, "no-axis-switch-jump-samples", _turn(jumpy)).holds is False
    assert evaluate(NAME, "sphere-flat", _turn(jumpy)).holds is False
    assert evaluate(NAME, "head-varies-more", _turn(head) + _turn(smooth, "ct_skull")).holds is False
    # the backend's own axis choice takes precedence over the 45° rule
    reported = ["x" if a < 180 else "z" for a in ANGLES]
    ripple = 1 + 0.002 * np.cos(np.radians(8 * ANGLES))  # some change away from the switch: a finite ratio
    result = evaluate(NAME, "no-axis-switch-jump", _turn(np.where(ANGLES < 180, 1.3, 1.0) * ripple, axes=reported))
    assert result.holds is False and "26.3 % at a switch" in result.detail
    # Nothing changes away from it: an infinite ratio in every draw has no interval, so it is not decided.
    flat = evaluate(NAME, "no-axis-switch-jump", _turn(np.where(ANGLES < 180, 1.3, 1.0), axes=reported))
    assert flat.inconclusive and flat.measured.startswith("×∞") and "no finite interval" in flat.detail


def test_the_technique_decides_with_intervals():
    flat = 1.0 + 0.02 * np.cos(np.radians(4 * ANGLES))
    rows = _turn(flat)
    for row in rows[:3]:
        row["time_total"] = 5.0  # Python around the kernels: not the claim's scope
    result = evaluate(NAME, "sphere-flat", rows)
    assert result.holds is True and result.measured == "3.88 % (95 % CI 3.88 %–3.88 %)"
    # 10 % over the turn, every view's frames ±30 %: the interval reaches across 12 %.
    noisy = evaluate(NAME, "sphere-flat", _turn(1.0 + 0.05 * np.cos(np.radians(ANGLES)), spread=0.3))
    assert noisy.holds is None and noisy.inconclusive and noisy.interval[0] < 0.12 < noisy.interval[1]


def test_report_writes_its_charts(tmp_path):
    check_report(tmp_path, NAME, _turn(1.0 + 0.02 * np.cos(np.radians(4 * ANGLES))))


def test_the_theses_head_over_sphere_figure_is_judged_beside_ours():
    sphere = 1.0 + 0.02 * np.cos(np.radians(4 * ANGLES))  # varies 4 %
    steep = evaluate(NAME, "head-varies-more-paper", _turn(sphere) + _turn(1.0 + 0.05 * np.cos(np.radians(2 * ANGLES)),
                                                                           "ct_skull"))
    assert steep.holds is True and steep.measured.startswith("×2.5")  # 10 % against 4 %: at least 13 / 6
    # 6 % against 4 %: more than the sphere (ours holds), short of the thesis's ×2.17.
    mild = _turn(sphere) + _turn(1.0 + 0.03 * np.cos(np.radians(2 * ANGLES)), "ct_skull")
    assert evaluate(NAME, "head-varies-more-paper", mild).holds is False
    assert evaluate(NAME, "head-varies-more", mild).holds is True
