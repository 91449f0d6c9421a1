"""This paper's scopes in words, and the paper's own ratios between methods from its frame-rate ranges.

Two scopes are compared, each like with like (:data:`~pipeline.experiments.kit.judging.TECHNIQUE`,
:data:`~pipeline.experiments.kit.judging.TOTAL`, judged by the kit):

* the technique between runs of cl-tiled: its kernels (binning, fragment count, pixel kernel), the paper's
  frame, whose host sends only the camera; not our per-frame Python and uploads;
* whole frames between cl-tiled and the peelers: OpenCL profiling events and OpenGL pass timers measure
  different scopes (a peeler's host loop, which waits on a query after every layer, is outside its passes),
  so only whole frames compare (:func:`~pipeline.experiments.kit.judging.ratios_where_both`, over the scenes
  both render, with :func:`~pipeline.experiments.kainz2009.methods.devices` in its detail; against the paper's
  band of each scene, :func:`band_bounds`).
"""

import math

from pipeline.experiments.kit.words import as_ratio

KERNELS = "cl-tiled's kernels, time_technique"
"""How the technique scope is named in a claim's ``expected`` text."""

FRAMES = "whole frames, time_total"
"""How the whole-frame scope is named in a claim's ``expected`` text."""


def paper_band(top_fps, bottom_fps):
    """``(low, high)``: the paper's frame time of the method with frame rates ``top_fps`` over that of the one with
    ``bottom_fps``, two ``(slowest, fastest)`` ranges of one table row (fps).

    The paper gives each method's slowest and fastest frame rate over the same viewports, transfer functions and
    cameras, so the slowest frames are compared with each other and the fastest with each other (time is 1 / fps).
    ``high`` is ``None`` where ``top``'s range starts at 0 fps: no upper bound.
    """
    ends = [bottom / top if top else math.inf for top, bottom in zip(top_fps, bottom_fps)]
    return min(ends), (max(ends) if math.isfinite(max(ends)) else None)


def band_words(band):
    """``"×0.457–×0.714"``, or ``"≥ ×15"`` without an upper bound."""
    low, high = band
    return f"≥ {as_ratio(low)}" if high is None else f"{as_ratio(low)}–{as_ratio(high)}"


def bands_words(bands):
    """``"×2.78–×3.2 on C3, ×7.67–×10 on C4"``: each scene's band (:func:`band_words`)."""
    return ", ".join(f"{band_words(band)} on {name}" for name, band in bands.items())


def band_bounds(bands):
    """``{scene: {"at_least": low, "at_most": high}}`` of ``{scene: (low, high)}``: each scene's bounds for
    :func:`~pipeline.experiments.kit.judging.ratios_where_both`."""
    return {name: {"at_least": low, "at_most": high} for name, (low, high) in bands.items()}
