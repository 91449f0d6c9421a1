"""This paper's scopes in words, and the whole-frame ratios its claims against the peelers share.

Two scopes are compared, each like with like (:data:`~pipeline.experiments.kit.judging.TECHNIQUE`,
:data:`~pipeline.experiments.kit.judging.TOTAL`, judged by the kit):

* the technique between runs of cl-tiled: its kernels (binning, fragment count, pixel kernel), the paper's
  frame, whose host sends only the camera; not our per-frame Python and uploads;
* whole frames between cl-tiled and the peelers: OpenCL profiling events and OpenGL pass timers measure
  different scopes (a peeler's host loop, which waits on a query after every layer, is outside its passes),
  so only whole frames compare. :func:`frame_ratios` is the kit's all-of over the scenes both render, with the
  devices the two ran on in its detail (which the kit cannot know).
"""

import pandas as pd

from pipeline.experiments.kainz2009.methods import METHOD_NAMES, TILED, devices
from pipeline.experiments.kit import intervals
from pipeline.experiments.kit.judging import TOTAL, all_of, measured, ratio
from pipeline.experiments.kit.results import rows_matching

KERNELS = "cl-tiled's kernels, time_technique"
"""How the technique scope is named in a claim's ``expected`` text."""

FRAMES = "whole frames, time_total"
"""How the whole-frame scope is named in a claim's ``expected`` text."""


def frame_ratios(df, scenes, top, bottom, *, what, **bounds):
    """``top``'s whole frame over ``bottom``'s (two configs, one of them cl-tiled) on every one of ``scenes`` both
    render, each judged against ``bounds`` with its interval; ``what`` says the ratio in the detail, before the
    devices the two ran on."""
    resampler = intervals.Resampler()
    decisions, compared = {}, []
    for name in scenes:
        pair = [rows_matching(df, name, scene=name, role="test", config=config) for config in (top, bottom)]
        pair = [measured(part, TOTAL) for part in pair]
        if not any(part.empty for part in pair):
            decisions[name] = ratio(*pair, TOTAL, resampler, **bounds)
            compared += pair
    if not decisions:
        peer = METHOD_NAMES[bottom if top == TILED else top]
        raise ValueError(f"no scene of {', '.join(scenes)} rendered by both {peer} and cl-tiled")
    return all_of(decisions, extra=f"{what}; {devices(pd.concat(compared))}")
