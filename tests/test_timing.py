import time

import numpy as np
import pytest

from core.errors import InputError
from pipeline import disturbance, timing
from pipeline.timing import measure, measure_together
from renderers.base import Capabilities, Renderer, RenderResult, compilation


READABLE = timing._unreadable
"""The rule conftest.py turns off for every test: this module's last test checks it."""


class Scripted(Renderer):
    """Returns preset timings frame after frame, so the harness's statistics can be checked."""

    name = "scripted"
    capabilities = Capabilities()
    technique_stages = ("stage",)

    def __init__(self, totals, *, log=None, label="a", caches=False, compiles=0):
        self.totals = list(totals)
        self.calls = 0
        self.log = log if log is not None else []
        self.label = label
        self.caches_preprocessing = caches
        self.cached = False
        self.compiles = compiles  # the first frames that compile a kernel (and preprocess 10 times slower)

    def check(self, scene):
        pass

    def drop_caches(self):
        self.cached = False

    def _render(self, scene):
        total = self.totals[min(self.calls, len(self.totals) - 1)]
        compiling = self.calls < self.compiles
        if compiling:
            compilation.record()
        self.calls += 1
        self.log.append(self.label)
        timings = {"total": total, "stage": total / 2}
        if self.caches_preprocessing and not self.cached:
            timings["classify"] = 70.0 if compiling else 7.0
            self.cached = True
        return RenderResult(np.full((2, 2, 4), self.calls, np.float32), timings=timings,
                            counters={"samples": self.calls})


def test_the_cold_frame_is_its_own_stage_and_never_timed():
    # cold 100, warm-up 3, then 3 (within 10 % of the frame before: settled, the first timed frame), 2, 10.
    renderer = Scripted([100.0, 3.0, 3.0, 2.0, 10.0])
    result = measure(renderer, scene=None, warmup=1, repeat=3)
    assert result.timings["first_frame"] > 0 and result.info["first_frame"] == result.timings["first_frame"]
    assert result.frames["total"] == [3.0, 2.0, 10.0]
    assert result.timings["total"] == 3.0 and result.timings_min["total"] == 2.0 and result.timings_max["total"] == 10.0
    assert result.info["frames"] == 3 and result.info["warmup"] == 1 and result.info["settled"]


def test_a_cold_frame_that_compiled_nothing_is_the_warm_up_where_the_next_frame_agrees_with_it():
    # A warm worker's next view: its first frame is already a warm frame, and the next one is timed.
    renderer = Scripted([3.0, 3.1, 2.0, 10.0])
    result = measure(renderer, scene=None, warmup=1, repeat=3)
    assert result.frames["total"] == [3.1, 2.0, 10.0] and renderer.calls == 1 + 3
    assert result.info["warmup"] == 0 and result.info["settled"]
    # Where it compiled, a warm-up frame of its own follows, and the settling starts from that one.
    compiled = Scripted([3.0, 3.0, 3.0, 2.0, 10.0], compiles=1)
    result = measure(compiled, scene=None, warmup=1, repeat=3)
    assert result.frames["total"] == [3.0, 2.0, 10.0] and compiled.calls == 1 + 1 + 3 and result.info["warmup"] == 1
    # A profile asking for more warm-up frames gets them, the cold frame counted among them.
    more = Scripted([3.0] * 8)
    assert measure(more, scene=None, warmup=3, repeat=3).info["warmup"] == 2 and more.calls == 1 + 2 + 3


def test_a_cold_frame_that_did_more_than_render_is_not_taken_for_a_warm_one():
    # Its wall time (uploads, preprocessing) is the reference where its reported total leaves them out.
    class Slow(Scripted):
        def _render(self, scene):
            if self.calls == 0:
                time.sleep(0.05)
            return super()._render(scene)

    renderer = Slow([0.001, 0.001, 0.001, 0.001, 0.001, 0.001])
    result = measure(renderer, scene=None, warmup=1, repeat=3)
    assert result.info["warmup"] == 1 and renderer.calls == 1 + 1 + 3


def test_only_the_last_timed_frames_image_is_kept():
    # Every earlier frame's image is released as the next one arrives: kept alive, each new frame
    # would fault in fresh pages and the harness's cost would be timed as the backend's.
    import weakref

    class Tracked(Scripted):
        def _render(self, scene):
            alive.append(sum(ref() is not None for ref in images))  # earlier images held as this one renders
            result = super()._render(scene)
            images.append(weakref.ref(result.image))
            return result

    images, alive = [], []
    result = measure(Tracked([5.0] + [1.0] * 10), scene=None, warmup=1, repeat=8)
    assert result.image[0, 0, 0] == len(images)  # the last frame's picture
    assert result.info["frames"] == 8 and max(alive[-8:]) <= 1  # in the timed frames, at most the previous one's


def test_warm_up_lasts_until_the_frame_time_settles():
    renderer = Scripted([50.0, 9.0, 6.0, 4.0, 3.0, 2.9, 1.0])
    result = measure(renderer, scene=None, warmup=1, repeat=3)
    assert result.info["warmup"] == 4  # 9, 6, 4, 3; then 2.9, within 10 % of 3, is the first timed frame
    assert result.frames["total"] == [2.9, 1.0, 1.0]


def test_a_warm_up_that_never_settles_ends_at_its_cap():

    renderer = Scripted([50.0] + [1.0, 2.0] * 30)
    result = measure(renderer, scene=None, warmup=1, repeat=3)
    assert result.info["warmup"] == timing.MAX_WARMUP and not result.info["settled"]
    assert len(result.frames["total"]) == 3


def test_runs_timed_together_warm_up_in_rounds_until_every_one_agrees_with_its_frame_before():
    log = []
    # Cold frames of 9 (compiling nothing, they count as warm-up); a settles in round 2; b's frames fall 4, 2, 1, 1:
    # rounds 1 to 3 are warm-up for both.
    a, b = Scripted([9.0, 1.0], log=log, label="a"), Scripted([9.0, 4.0, 2.0, 1.0], log=log, label="b")
    results = measure_together([(a, None), (b, None)], warmup=1, repeat=3)
    assert [r.info["warmup"] for r in results] == [3, 3]
    assert results[0].frames["total"] == [1.0] * 3 and results[1].frames["total"] == [1.0] * 3
    # The order alternates from the first round.
    assert log[2:] == ["a", "b", "b", "a", "a", "b", "b", "a", "a", "b", "b", "a"]


def test_the_budget_adds_frames_until_min_time(monkeypatch):
    renderer = Scripted([0.001])
    result = measure(renderer, scene=None, warmup=1, repeat=3, min_time=0.05)
    assert result.info["frames"] > 3  # the wall time of the frames, not their reported times, fills it
    capped = measure(Scripted([0.001]), scene=None, warmup=1, repeat=3, min_time=60, max_frames=10)
    assert capped.info["frames"] == 10


def test_preprocessing_that_compiled_is_timed_again_in_a_frame_of_its_own():
    renderer = Scripted([1.0], caches=True, compiles=1)
    result = measure(renderer, scene=None, warmup=1, repeat=3)
    assert result.timings["classify"] == 7.0 and "classify" not in result.frames
    assert result.info["preprocessing_frame"] == "own"
    # Cold, preprocessing (compiling nothing: the first timed frame agrees with it), three timed.
    assert renderer.calls == 1 + 1 + 3 and result.info["warmup"] == 0


def test_the_cold_frame_is_the_preprocessing_frame_where_nothing_compiled():
    renderer = Scripted([1.0], caches=True)
    result = measure(renderer, scene=None, warmup=1, repeat=3)
    assert result.timings["classify"] == 7.0 and result.info["preprocessing_frame"] == "cold"
    assert renderer.calls == 1 + 3  # the cold frame compiled nothing and the next agrees with it: it is timed
    # A next view of the same renderer (its caches warm) builds its preprocessing in its cold frame too.
    again = measure(renderer, scene=None, warmup=1, repeat=3)
    assert again.timings["classify"] == 7.0 and again.info["preprocessing_frame"] == "cold"


def test_a_backend_without_cached_preprocessing_has_no_preprocessing_frame():
    result = measure(Scripted([1.0], compiles=1), scene=None, warmup=1, repeat=3)
    assert result.info["preprocessing_frame"] is None and "classify" not in result.timings


def test_technique_is_the_sum_of_the_backends_technique_stages():
    result = measure(Scripted([4.0]), scene=None, warmup=1, repeat=3)
    assert result.timings["technique"] == 2.0 and result.frames["technique"] == [2.0, 2.0, 2.0]


def test_one_untimed_frame():
    renderer = Scripted([5.0])
    result = measure(renderer, scene=None, warmup=0, repeat=1)
    assert renderer.calls == 1 and result.info["untimed"] and result.timings["total"] == 5.0


def test_arms_alternate_round_by_round_with_the_order_reversed():
    log = []
    a, b = Scripted([1.0], log=log, label="a"), Scripted([2.0], log=log, label="b")
    results = measure_together([(a, None), (b, None)], warmup=1, repeat=4)
    timed = log[-8:]
    assert timed == ["a", "b", "b", "a", "a", "b", "b", "a"]  # both settled at once: round 1 is timed
    assert [len(r.frames["total"]) for r in results] == [4, 4]
    assert results[0].timings["total"] == 1.0 and results[1].timings["total"] == 2.0


def test_disturbed_frames_are_flagged():
    renderer = Scripted([1.0, 1.0, 1.0] + [1.0, 1.0, 1.0, 50.0, 1.0, 60.0, 1.0, 1.0, 1.0, 1.0])
    result = measure(renderer, scene=None, warmup=1, repeat=10)
    assert "2 of 10 frames took over 3" in result.info["disturbed"]
    assert measure(Scripted([1.0]), scene=None, warmup=1, repeat=10).info["disturbed"] == ""


@pytest.mark.parametrize("kwargs, name", [({"repeat": 0}, "repeat"), ({"warmup": -1}, "warmup"),
                                          ({"min_time": -1}, "min_time"), ({"max_frames": 2, "repeat": 3}, "max_frames")])
def test_bad_frame_counts(kwargs, name):
    with pytest.raises(InputError, match=name):
        measure(Scripted([1.0]), scene=None, **kwargs)


def test_no_arms():
    with pytest.raises(ValueError, match="no arms"):
        measure_together([])


def test_render_result_requires_total_and_rgba_float32():
    with pytest.raises(ValueError, match="total"):
        RenderResult(np.zeros((2, 2, 4), np.float32), timings={"render": 1.0})
    with pytest.raises(ValueError, match="float32"):
        RenderResult(np.zeros((2, 2, 3), np.float32), timings={"total": 1.0})



def test_an_arm_that_settled_stays_settled_while_the_others_warm_up():
    # a settles in round 1, then jitters by 30 % frame to frame; b's frames fall 8, 4, 2, 1, 1. Waiting for
    # both to agree in one round would warm up to the cap; the round in which b settles is the first timed.
    a = Scripted([9.0, 1.0, 1.0, 1.3, 1.0, 1.3, 1.0, 1.3], label="a")
    b = Scripted([9.0, 8.0, 4.0, 2.0, 1.0, 1.0], label="b")
    results = measure_together([(a, None), (b, None)], warmup=1, repeat=3)
    assert [r.info["warmup"] for r in results] == [4, 4]  # the prepared frame and three rounds
    assert [r.info["settled"] for r in results] == [True, True]
    assert results[1].frames["total"] == [1.0] * 3


def test_a_view_is_timed_until_the_load_can_be_read(monkeypatch):
    """Frames too fast for the counters' span: timed on until it is long enough, so a disturbance shows."""
    monkeypatch.setattr(timing, "_unreadable", READABLE)
    # 20 ms: long against a scripted frame (a tenth of a millisecond), short against the 400 frames' cap.
    monkeypatch.setattr(disturbance, "MIN_SPAN", 0.02)
    result = measure(Scripted([0.001]), scene=None, warmup=1, repeat=3)
    assert 3 < result.info["frames"] < timing.MAX_FRAMES and result.info["load"]["seconds"] >= 0.02
    capped = measure(Scripted([0.001]), scene=None, warmup=1, repeat=3, max_frames=5)
    assert capped.info["frames"] == 5  # never past max_frames
