"""What several of the paper's experiments share: the methods compared, their timed runs and frame times,
the no-cue control scene, how the GL frames were timed, and what cannot be measured without the GL backends."""

import numpy as np

from pipeline.experiments.kit.model import Run
from pipeline.experiments.kit.pages import frames_counted, not_measurable
from pipeline.experiments.kit.planning import HEADLINE_VIEW, accepts, missing_options, phantom, scene, unregistered
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


def method_runs(experiment, prefix, scene_spec, views, configs, step_factor, truth, tags, frames):
    """Timed runs of ``configs`` (keys of :data:`METHODS`) on one scene, checked against ``truth``.

    A method whose backend does not take its options here is left out; the page says why
    (:func:`gl_not_measurable`).
    """
    runs = []
    for config in configs:
        backend, options, _name = METHODS[config]
        if not accepts(backend, *options, "step_factor"):
            continue
        runs.append(Run(experiment, f"{prefix}.{config}", backend, scene_spec, views,
                        options={**options, "step_factor": step_factor}, reference=truth, **frames,
                        tags={**tags, "role": "test", "config": config}))
    return runs


def no_cue_control(size, image):
    """``(scene, views, tags)`` of the control: smooth, faint noise filling the cube, unshaded, headline view.

    No ray reaches the termination threshold and no block is empty, so neither acceleration applies.
    """
    scene_spec = scene("no_cue", image, volumes=[phantom("fbm_control", size, preset="no_cue")], shading="none")
    return scene_spec, (HEADLINE_VIEW,), {"scene": "no_cue", "dataset": "fbm_control"}


def gl_not_measurable():
    """The page's note of the GL backends (or their options) this machine lacks."""
    return not_measurable(unregistered(RAYCAST, SLICER) + missing_options(RAYCAST, "variant", "samples_per_pass",
                                                                          "opaque_threshold", "block_size"))


def time_of(frame, config, **match):
    """The median frame time of ``config`` in ``frame`` (rows matching ``match``); ValueError if none."""
    rows = rows_matching(frame, config, config=config, **match)
    if rows.empty:
        raise ValueError(f"no successful {config} run" + (f" for {match}" if match else ""))
    return float(np.median([stage_time(row) for _, row in rows.iterrows()]))


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
