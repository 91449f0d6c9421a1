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
from dataclasses import dataclass

from pipeline.experiments.kainz2009.methods import METHOD_NAMES, TILED, devices
from pipeline.experiments.kit.judging import STRICTLY_ABOVE_ONE, STRICTLY_BELOW_ONE, ratios_where_both
from pipeline.experiments.kit.model import Claim
from pipeline.experiments.kit.words import as_ratio

KERNELS = "cl-tiled's kernels, time_technique"
"""How the technique scope is named in a claim's ``expected`` text."""

FRAMES = "whole frames, time_total"
"""How the whole-frame scope is named in a claim's ``expected`` text."""


def paper_bands(table, top, bottom, *scenes):
    """``{scene: (low, high)}``: the paper's frame time of the method with frame rates in column ``top`` of ``table``
    (:data:`~pipeline.experiments.kainz2009.tables.TABLE1` or ``TABLE2``) over that of the one in column ``bottom``,
    each a ``(slowest, fastest)`` range (fps), on each of ``scenes``.

    The paper gives each method's slowest and fastest frame rate over the same viewports, transfer functions and
    cameras, so the slowest frames are compared with each other and the fastest with each other (time is 1 / fps).
    ``high`` is ``None`` where ``top``'s range starts at 0 fps: no upper bound.
    """
    ends = {name: [b / t if t else math.inf for t, b in zip(table[name][top], table[name][bottom])] for name in scenes}
    return {name: (min(end), max(end) if math.isfinite(max(end)) else None) for name, end in ends.items()}


def bands_words(bands):
    """``"×2.78–×3.2 on C3, ≥ ×15 on C7"``: each scene's band, ``≥`` its low end where it has no upper bound."""
    return ", ".join(f"≥ {as_ratio(low)} on {name}" if high is None else f"{as_ratio(low)}–{as_ratio(high)} on {name}"
                     for name, (low, high) in bands.items())


def band_bounds(bands):
    """``{scene: {"at_least": low, "at_most": high}}`` of ``{scene: (low, high)}``: each scene's bounds for
    :func:`~pipeline.experiments.kit.judging.ratios_where_both`."""
    return {name: {"at_least": low, "at_most": high} for name, (low, high) in bands.items()}


@dataclass(frozen=True)
class PeelingRatio:
    """The whole frame of configuration ``top`` over ``bottom``'s, cl-tiled against a depth peeler either way round,
    same scene and view, on the scenes both render (:func:`~pipeline.experiments.kit.judging.ratios_where_both`).

    The paper's frame rates of the two come from its GTX 280, ours from other devices: :meth:`claims` judges the
    ratio within the paper's band on each of its scenes and, as our target beside it, its direction alone.
    """

    top: str
    bottom: str

    def _judge(self, scenes, what, **bounds):
        return lambda df: ratios_where_both(df, scenes, self.top, self.bottom, describe=devices, what=what, **bounds)

    def claims(self, id, bands, statements, *, above, paper_value, scenes=None, where=None, why="the direction only",
               note=""):
        """The claim ``<id>-paper`` that the ratio lies within each scene's band of ``bands`` (``{scene: (low,
        high)}``, :func:`paper_bands`) and ours, ``id``, that it lies above ×1 (``above``: ``top`` slower) or below it
        (:meth:`~pipeline.experiments.kit.model.Claim.with_ours`). ``statements``: the paper's claim and ours, in
        words; ``paper_value``: the paper's frame rates. Ours reads ``scenes`` (default: those of ``bands``), named
        ``where`` in its expected text (default: ``"on S2 and S3"``); ``why`` says why it judges less than the
        paper's band (that the devices differ follows); ``note`` ends what its detail says it compares.
        """
        scenes = tuple(bands) if scenes is None else scenes
        where = f"on {' and '.join(scenes)}" if where is None else where
        top, bottom = METHOD_NAMES[self.top], METHOD_NAMES[self.bottom]
        words, what = f"time({top}) / time({bottom})", f"time of {top} over {bottom}'s, same scene and view, {FRAMES}"
        peer = METHOD_NAMES[self.bottom if self.top == TILED else self.top]
        both = ", whichever both render" if len(bands) > 1 else ""
        bound = {"at_least": STRICTLY_ABOVE_ONE} if above else {"at_most": STRICTLY_BELOW_ONE}
        return Claim(f"{id}-paper", statements[0], f"{words} within {bands_words(bands)}{both} ({FRAMES})",
                     self._judge(band_bounds(bands), f"{what}; paper: {bands_words(bands)}"), paper_value=paper_value,
                     kind="timing").with_ours(
            statements[1], f"{words} {'>' if above else '<'} ×1 {where} ({FRAMES})",
            self._judge(scenes, what + note, **bound),
            why=f"{why}: {peer} and cl-tiled run here on other devices (llvmpipe, PoCL) than the paper's GTX 280")
