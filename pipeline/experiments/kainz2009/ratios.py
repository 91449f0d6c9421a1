"""This paper's scopes in words.

Two scopes are compared, each like with like (:data:`~pipeline.experiments.kit.judging.TECHNIQUE`,
:data:`~pipeline.experiments.kit.judging.TOTAL`, judged by the kit):

* the technique between runs of cl-tiled: its kernels (binning, fragment count, pixel kernel), the paper's
  frame, whose host sends only the camera; not our per-frame Python and uploads;
* whole frames between cl-tiled and the peelers: OpenCL profiling events and OpenGL pass timers measure
  different scopes (a peeler's host loop, which waits on a query after every layer, is outside its passes),
  so only whole frames compare (:func:`~pipeline.experiments.kit.judging.ratios_where_both`, over the scenes
  both render, with :func:`~pipeline.experiments.kainz2009.methods.devices` in its detail).
"""

KERNELS = "cl-tiled's kernels, time_technique"
"""How the technique scope is named in a claim's ``expected`` text."""

FRAMES = "whole frames, time_total"
"""How the whole-frame scope is named in a claim's ``expected`` text."""
