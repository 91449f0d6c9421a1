import numpy as np
import pytest

from core.errors import InputError
from pipeline.timing import measure
from renderers.base import Capabilities, Renderer, RenderResult


class Scripted(Renderer):
    """Returns preset timings frame after frame, so the harness's statistics can be checked."""

    name = "scripted"
    capabilities = Capabilities()

    def __init__(self, totals):
        self.totals = list(totals)
        self.calls = 0

    def check(self, scene):
        pass

    def _render(self, scene):
        total = self.totals[self.calls]
        self.calls += 1
        return RenderResult(np.full((2, 2, 4), self.calls, np.float32),
                            timings={"total": total, "stage": total / 2}, counters={"samples": self.calls})


def test_median_min_max_over_timed_frames_only():
    renderer = Scripted([100.0, 3.0, 1.0, 2.0, 10.0])
    result = measure(renderer, scene=None, warmup=1, repeat=4)
    assert renderer.calls == 5
    assert result.timings["total"] == pytest.approx(2.5)  # median of 3, 1, 2, 10: warm-up excluded
    assert result.timings_min["total"] == 1.0 and result.timings_max["total"] == 10.0
    assert result.timings["stage"] == pytest.approx(1.25)
    assert result.counters == {"samples": 5} and result.image[0, 0, 0] == 5
    assert result.info["frames"] == 4 and result.info["warmup"] == 1


def test_bad_repeat_counts():
    with pytest.raises(InputError, match="repeat"):
        measure(Scripted([1.0]), scene=None, warmup=0, repeat=0)
    with pytest.raises(InputError, match="warmup"):
        measure(Scripted([1.0]), scene=None, warmup=-1, repeat=1)


def test_render_result_requires_total_and_rgba_float32():
    with pytest.raises(ValueError, match="total"):
        RenderResult(np.zeros((2, 2, 4), np.float32), timings={"render": 1.0})
    with pytest.raises(ValueError, match="float32"):
        RenderResult(np.zeros((2, 2, 3), np.float32), timings={"total": 1.0})
