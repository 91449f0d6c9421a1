"""What several of the paper's experiments share: the methods compared, their timed runs and frame times,
the no-cue control scene, time ratios judged with their intervals, how the GL frames were timed, and what
cannot be measured without the GL backends."""

import numpy as np
import pandas as pd

from pipeline.experiments.kit import intervals
from pipeline.experiments.kit.model import ClaimResult, Run
from pipeline.experiments.kit.pages import as_ratio, frames_counted, not_measurable
from pipeline.experiments.kit.planning import accepts, missing_options, phantom, scene, unregistered
from pipeline.experiments.kit.results import rows_matching, stage_time

RAYCAST, SLICER = "gl-raycast", "gl-slicer"

METHODS = {
    # config: (backend, options, the paper's name)
    "sbvr": (SLICER, {}, "SBVR"),
    "rc": (RAYCAST, {"variant": "rc"}, "RC"),
    "rc-a": (RAYCAST, {"variant": "rc-a"}, "RC-a"),
    "rc-b": (RAYCAST, {"variant": "rc-b"}, "RC-b"),
    "single-pass": (RAYCAST, {"variant": "single-pass"}, "single pass (not in the paper)"),
    "vtk-gpu": ("vtk-gpu", {}, "VTK GPU ray caster (peer)"),
}
"""The methods of Table 1, the modern loop-with-break caster and the GPU caster users run (VTK's, with
its default early termination), as backend and options."""


def method_name(config):
    """The paper's name of ``config`` (a key of :data:`METHODS`), for tables and figures."""
    return METHODS[config][2]


def method_runs(experiment, prefix, scene_spec, views, configs, step_factor, truth, tags, frames, *, together=(),
                group=None):
    """Timed runs of ``configs`` (keys of :data:`METHODS`) on one scene, checked against ``truth``.

    The runs of the configs in ``together`` (those a claim compares) are timed in one interleave group,
    ``group`` (default ``prefix``), frame against frame. A method whose backend does not take its
    options here is left out; the page says why (:func:`gl_not_measurable`).
    """
    runs = []
    for config in configs:
        backend, options, _name = METHODS[config]
        if not accepts(backend, *options, "step_factor"):
            continue
        runs.append(Run(experiment, f"{prefix}.{config}", backend, scene_spec, views,
                        options={**options, "step_factor": step_factor}, reference=truth, **frames,
                        tags={**tags, "role": "test", "config": config},
                        interleave=(group or prefix) if config in together else None))
    return runs


FRONT_VIEW = {"view": "front", "azimuth": 0.0, "elevation": 0.0}
"""The control's view: straight at a face of the cube, orthographic, so every ray has the same length.

From an oblique view rays through the cube's corners leave it early and early termination culls them
(half of the main-pass fragments at 30° yaw, 20° pitch), which is a gain the paper's "neither
acceleration applies" (Sec. 3) excludes."""


def no_cue_control(size, image):
    """``(scene, views, tags)`` of the control: smooth, faint noise filling the cube, unshaded, :data:`FRONT_VIEW`.

    No ray reaches the termination threshold, none leaves before the last pass and no block is empty,
    so neither acceleration applies.
    """
    scene_spec = scene("no_cue", image, volumes=[phantom("fbm_control", size, preset="no_cue")], shading="none")
    return scene_spec, (FRONT_VIEW,), {"scene": "no_cue", "dataset": "fbm_control"}


def gl_not_measurable():
    """The page's note of the GL backends (or their options) this machine lacks."""
    return not_measurable(unregistered(RAYCAST, SLICER) + missing_options(RAYCAST, "variant", "samples_per_pass",
                                                                          "opaque_threshold", "block_size"))


STRICTLY_ABOVE_ONE, STRICTLY_BELOW_ONE = float(np.nextafter(1.0, 2.0)), float(np.nextafter(1.0, 0.0))
"""The bounds of "strictly slower" and "strictly faster" ratios: the intervals' bounds are inclusive, and equal
times beat nothing."""


def config_rows(frame, config, **match):
    """The rows of ``config`` in ``frame`` matching ``match``; ValueError naming them if none."""
    rows = rows_matching(frame, config, config=config, **match)
    if rows.empty:
        raise ValueError(f"no successful {config} run" + (f" for {match}" if match else ""))
    return rows


def time_ratio(frame, slow, fast, *, resampler, at_least=None, at_most=None, column="time_total", **match):
    """``time(slow) / time(fast)``, each the median over the matching views, judged with its bootstrap interval.

    Runs timed in one interleave group are resampled round by round (:mod:`~pipeline.experiments.kit.intervals`);
    ``resampler`` is shared by every ratio of one claim.
    """
    return intervals.ratio_decision(config_rows(frame, slow, **match), config_rows(frame, fast, **match),
                                    column=column, at_least=at_least, at_most=at_most, resampler=resampler)


def median_count(rows, column="count_samples"):
    """The median of a count (samples, fragments: they do not depend on the machine) over ``rows``; NaN if uncounted."""
    return float(pd.to_numeric(rows[column], errors="coerce").median()) if column in rows else np.nan


def count_ratio(frame, slow, fast, column="count_samples", **match):
    """The ratio of a count (median over the views) of ``slow`` and ``fast``; NaN where it was not counted."""
    top, bottom = (median_count(config_rows(frame, config, **match), column) for config in (slow, fast))
    return top / bottom if bottom else np.nan


def samples_note(frame, slow, fast, **match):
    """``"samples ×2.1"``: the same ratio of the samples the shaders took (empty where not counted)."""
    ratio = count_ratio(frame, slow, fast, **match)
    return f"samples {as_ratio(ratio)}" if np.isfinite(ratio) else ""


def with_interval(text, decision, show):
    """``"0.97 (95 % CI 0.95–0.98)"``: ``text`` with the decision's interval (shown by ``show``) where it has one."""
    words = intervals.interval_words(decision, show)
    return f"{text} ({words})" if words else text


def ratio_words(decision):
    """``"×1.12 (95 % CI ×1.08–×1.17)"``: a ratio with its interval where it has one."""
    return with_interval(as_ratio(decision.value), decision, as_ratio)


def every(decisions, notes=None, *, what="", extra=""):
    """The result of labelled ratio decisions that must all hold (:func:`~pipeline.experiments.kit.intervals.combine`).

    ``measured`` names the deciding (worst) label after ``what``; the detail lists every label's ratio
    with its interval and its note (counts, which do not depend on the machine), then ``extra``.
    """
    combined = intervals.combine(decisions.values())
    worst = next(label for label, d in decisions.items()
                 if (d.value, d.interval, d.holds) == (combined.value, combined.interval, combined.holds))
    notes = notes or {}
    detail = ", ".join(f"{label}: {ratio_words(d)}" + (f", {notes[label]}" if notes.get(label) else "")
                       for label, d in decisions.items())
    return ClaimResult.decided(f"{what}{ratio_words(combined)} ({worst})", combined,
                               detail + (f"; {extra}" if extra else ""))


def time_of(frame, config, **match):
    """The median frame time of ``config`` in ``frame`` (rows matching ``match``); ValueError if none."""
    return float(np.median([stage_time(row) for _, row in config_rows(frame, config, **match).iterrows()]))


def speedup(frame, slow, fast, **match):
    """``time(slow) / time(fast)`` on the rows matching ``match``."""
    return time_of(frame, slow, **match) / time_of(frame, fast, **match)


GL_TIMING = {"query": "passes timed on the device with GL timer queries",
             "finish": "each pass timed by waiting for it (glFinish): a software rasterizer's timer queries do not "
                       "cover its deferred work"}
"""How the GL backends time their passes (their ``timing`` option, as it took effect), in words."""


def frames_caption(frame):
    """How the frames of ``frame`` were timed: frames counted, uploads excluded, the GL timing method."""
    methods = set(frame.option_effective_timing.dropna()) if "option_effective_timing" in frame else set()
    timed = ("; ".join(GL_TIMING.get(m, f"passes timed by {m!r}") for m in sorted(methods))
             or "timing method not recorded")
    return (f"{frames_counted(frame)} after warm-up, uploads (volume, gradients, min–max grid, transfer-function "
            f"tables) excluded as their own stage; {timed}.")
