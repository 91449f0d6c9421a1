"""What several of the paper's experiments share: the methods compared, their settings, runs and frame times, the
no-cue control scene, and what cannot be measured without the GL backends."""

import numpy as np

from pipeline.experiments.kit.judging import count_ratio
from pipeline.experiments.kit.model import Run, scaled
from pipeline.experiments.kit.pages import as_ratio, not_measurable
from pipeline.experiments.kit.planning import (accepts, missing_options, phantom, scene, unregistered,
                                               volume_and_image_size)
from pipeline.experiments.kit.results import speed_points

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
"""Table 1's methods, the modern loop-with-break caster and VTK's GPU caster (its default early termination)."""


UPLOADS = "uploads (volume, gradients, min–max grid, transfer-function tables) excluded as their own stage"
"""What the GL methods' timed frames leave out, for the frames captions."""


def method_name(config):
    """The paper's name of ``config`` (a key of :data:`METHODS`), for tables and figures."""
    return METHODS[config][2]


SETTINGS = frozenset({"volume_size", "image_size", "step_factor", "repeat"})
"""The settings every experiment here takes: what :func:`sizes` reads, and ``repeat`` (its timed runs' frames)."""

SIZE_SCALES = scaled(smoke={"image_size": 64})
"""What :func:`sizes` reads at each scale: the kit's sizes, with 64-pixel images at smoke scale."""


def sizes(experiment, profile):
    """``(volume size, image size, step factor)``: ``experiment``'s settings (the profile's sizes, half a voxel)."""
    return (*volume_and_image_size(profile, experiment), profile.setting(experiment, "step_factor", 0.5))


def method_runs(experiment, prefix, scene_spec, views, configs, step_factor, truth, tags, frames, *, together=(),
                group=None, extra=None):
    """Timed runs of ``configs`` (keys of :data:`METHODS`) on one scene, checked against ``truth``.

    The runs of the configs in ``together`` (those a claim compares) are timed in one interleave group, ``group``
    (default ``prefix``), frame against frame. ``extra`` options join every config's (the paper's sampled iso hit). A
    method whose backend does not take its options here is left out; the page says why (:func:`gl_not_measurable`).
    """
    planned = [(config, METHODS[config][0], {**METHODS[config][1], **(extra or {})}) for config in configs]
    return [Run(experiment, f"{prefix}.{config}", backend, scene_spec, views, reference=truth, **frames,
                options={**options, "step_factor": step_factor}, tags={**tags, "role": "test", "config": config},
                interleave=(group or prefix) if config in together else None)
            for config, backend, options in planned if accepts(backend, *options, "step_factor")]


FRONT_VIEW = {"view": "front", "azimuth": 0.0, "elevation": 0.0}
"""The control's view: straight at a face of the cube, orthographic, so every ray has the same length.

From an oblique view rays through the cube's corners leave it early and early termination culls them
(half of the main-pass fragments at 30° yaw, 20° pitch), which is a gain the paper's "neither
acceleration applies" (Sec. 3) excludes."""


def no_cue_control(size, image):
    """``(scene, views, tags)`` of the control: smooth, faint noise filling the cube, unshaded, :data:`FRONT_VIEW`:
    no ray reaches the termination threshold, none leaves before the last pass and no block is empty."""
    scene_spec = scene("no_cue", image, volumes=[phantom("fbm_control", size, preset="no_cue")], shading="none")
    return scene_spec, (FRONT_VIEW,), {"scene": "no_cue", "dataset": "fbm_control"}


def method_points(rows):
    """``rows`` with frame times in ms (:func:`~.results.speed_points`) and each method's paper name (``method``)."""
    return speed_points(rows).assign(method=lambda frame: [method_name(c) for c in frame.config])


def gl_not_measurable():
    """The page's note of the GL backends (or their options) this machine lacks."""
    return not_measurable(unregistered(RAYCAST, SLICER) + missing_options(RAYCAST, "variant", "samples_per_pass",
                                                                          "opaque_threshold", "block_size"))


def samples_note(frame, slow, fast, **match):
    """``"samples ×2.1"``: the same ratio of the samples the shaders took (empty where not counted)."""
    if "count_samples" not in frame:
        return ""
    ratio = count_ratio(frame, slow, fast, **match)
    return f"samples {as_ratio(ratio)}" if np.isfinite(ratio) else ""
