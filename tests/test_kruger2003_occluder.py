"""``kruger2003-occluder``: the coverage sweep it plans and its claims on synthetic results."""

import pytest

from pipeline import experiments
from pipeline.experiments.kit.intervals import format_frames
from pipeline.experiments.kruger2003.occluder import OCCLUDED
from test_kruger2003_methods import NOISY, evaluate, small_profile, timed, with_gl_backends

NAME = "kruger2003-occluder"


def _occluder_rows(main_ms, fractions=(0.0, 0.5, 1.0), rays=1000, passes=10):
    rows = []
    for fraction, ms in zip(fractions, main_ms):
        occluded = round(fraction * rays)
        rows.append({"role": "test", "config": "rc", "fraction": fraction, "time_total": ms * 1.2e-3,
                     "time_main": ms * 1e-3, "frames_main": format_frames([ms * 1e-3] * 5), "interleave": "sweep",
                     "view": "headline", "count_rays": rays, "count_rays_occluded": occluded,
                     "count_passes_main": passes, "count_fragments_main": passes * (rays - occluded)})
    return rows


def test_occluder_plan_sweeps_coverage_for_rc_and_rca(monkeypatch):
    with_gl_backends(monkeypatch)
    runs = [r for r in experiments.plan(small_profile()).values() if r.experiment == NAME]
    assert {(r.options["variant"], r.options["occluder"]) for r in runs} == {
        (v, f) for v in ("rc", "rc-a") for f in OCCLUDED}
    with pytest.raises(Exception, match="fractions"):
        experiments.plan(small_profile(**{NAME: {"fractions": [0, 1]}}))


def test_occluder_claims():
    rows = _occluder_rows([10.0, 5.2, 0.4])
    assert evaluate(NAME, "occluded-rays-culled", rows).holds is True
    assert evaluate(NAME, "time-proportional", rows).holds is True
    rows[1]["count_fragments_main"] += 7  # a pass drew fragments of hidden rays
    assert evaluate(NAME, "occluded-rays-culled", rows).holds is False
    assert evaluate(NAME, "time-proportional", _occluder_rows([10.0, 9.5, 9.0])).holds is False  # no fall
    assert evaluate(NAME, "time-proportional", _occluder_rows([10.0, 1.0, 0.9])).holds is False  # not linear


def _timed_rows(main_frames, group="rc", fractions=(0.0, 0.5, 1.0), rays=1000, passes=10):
    """The RC coverage sweep with every main-pass frame (milliseconds in ``main_frames``), in interleave ``group``."""
    return [timed([ms * 1e-3 for ms in frames], group=group, stage="main", role="test", config="rc", fraction=fraction,
                  view="front", run=f"no_cue.rc.f{fraction:g}", count_rays=rays,
                  count_rays_occluded=round(fraction * rays), count_passes_main=passes,
                  count_fragments_main=passes * (rays - round(fraction * rays)), time_total=1.0)
            for fraction, frames in zip(fractions, main_frames)]


def test_the_fit_and_the_time_left_get_intervals_from_the_frames():
    steady = evaluate(NAME, "time-proportional", _timed_rows([[10.0] * 5, [5.2] * 5, [0.4] * 5]))
    assert steady.holds is True
    assert steady.measured == ("R² 1 (95 % CI 1–1); 4 % (95 % CI 4 %–4 %) of the main-pass time left "
                               "at 100 % occluded")
    assert "main-pass fragments 1e+04 → 0" in steady.detail
    # Rounds disturbed alike: paired by round the line stays straight; timed apart it may not.
    disturbed = [[ms * f for f in NOISY] for ms in (10.0, 5.2, 0.4)]
    assert evaluate(NAME, "time-proportional", _timed_rows(disturbed)).holds is True
    apart = evaluate(NAME, "time-proportional", _timed_rows(disturbed, group=""))
    assert apart.inconclusive and apart.interval[0] < 0.9
    bent = evaluate(NAME, "time-proportional", _timed_rows([[10.0] * 5, [1.0] * 5, [0.9] * 5]))
    assert bent.holds is False and not bent.inconclusive
