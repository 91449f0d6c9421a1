"""lacroute1995-angles: time over a full turn and the principal-axis switch (Fig. 5.3)."""

import numpy as np

from pipeline.experiments.lacroute1995.angles import principal_axis
from test_lacroute1995_package import check_report, evaluate, planned


def test_plan_turns_in_equal_steps():
    angles = next(r for r in planned("lacroute1995-angles", **{"lacroute1995-angles": {"angle_step": 30}})
                  if r.id == "sphere.turn")
    assert [v["view"] for v in angles.views] == [f"deg{a}" for a in range(0, 360, 30)]


def test_principal_axis_switches_at_45_degrees():
    assert [principal_axis(a) for a in (0, 44, 45, 90, 134, 135, 224, 225, 314, 315, 359)] == \
        [0, 0, 1, 1, 1, 0, 0, 1, 1, 0, 0]


def _turn(times, dataset="sphere", axes=None):
    angles = np.arange(0, 360, 360 / len(times))
    rows = [{"dataset": dataset, "view": f"deg{a:g}", "time_total": t, "count_samples": 1e5 * t}
            for a, t in zip(angles, times)]
    if axes is not None:
        for row, axis in zip(rows, axes):
            row["info_principal_axis"] = axis
    return rows


def test_angle_claims():
    name = "lacroute1995-angles"
    angles = np.arange(0, 360, 10)
    smooth = 1.0 + 0.02 * np.cos(np.radians(4 * angles))
    head = 1.0 + 0.07 * np.cos(np.radians(2 * angles))
    rows = _turn(smooth) + _turn(head, "ct_skull")
    assert evaluate(name, "no-axis-switch-jump", rows).holds is True
    assert evaluate(name, "sphere-flat", rows).holds is True
    assert evaluate(name, "head-varies-more", rows).holds is True
    jumpy = np.where([principal_axis(a) == 1 for a in angles], 1.3, 1.0) + 0.01 * np.cos(np.radians(angles))
    assert evaluate(name, "no-axis-switch-jump", _turn(jumpy)).holds is False
    assert evaluate(name, "no-axis-switch-jump-samples", rows).holds is True
    assert evaluate(name, "no-axis-switch-jump-samples", _turn(jumpy)).holds is False
    assert evaluate(name, "sphere-flat", _turn(jumpy)).holds is False
    # the backend's own axis choice takes precedence over the 45° rule
    reported = ["x" if a < 180 else "z" for a in angles]
    result = evaluate(name, "no-axis-switch-jump", _turn(np.where(angles < 180, 1.3, 1.0), axes=reported))
    assert result.holds is False and result.measured.startswith("26.1 % at a switch")


def test_report_writes_its_charts(tmp_path):
    check_report(tmp_path, "lacroute1995-angles", _turn(1.0 + 0.02 * np.cos(np.radians(4 * np.arange(0, 360, 10)))))
