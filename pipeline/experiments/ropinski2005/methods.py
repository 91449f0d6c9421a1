"""What the paper's experiments share: the lens methods as ``gl-raycast`` options, their runs, the lens coverage,
the devices that timed them and what this machine cannot measure.

A lens run is ``gl-raycast``'s single-pass variant with option ``lens_method``; a lens-off run is the same
variant on the scene without its lens (``lens_method`` does nothing there), so the two differ only by the
lens. Method names come from :data:`METHODS` alone: a method the backend does not offer yet is still
planned, its runs fail with the backend's unknown-option error and the page lists it
(:func:`raycast_not_measurable`).
"""

import numpy as np
import pandas as pd

import renderers
from pipeline.experiments.kit import pages
from pipeline.experiments.kit.model import Experiment, Run, scaled
from pipeline.experiments.kit.pages import not_measurable
from pipeline.experiments.kit.planning import accepts, is_registered, missing_options, unregistered
from pipeline.experiments.kit.results import numeric, text_column

RAYCAST = "gl-raycast"

VARIANT = {"variant": "single-pass"}
"""The caster's variant for every lens run and its lens-off control (the multi-pass variants take no lens)."""

METHODS = {
    # config: (gl-raycast options beside the variant, its name in words)
    "segments": ({"lens_method": "segments"},
                 "segments (the paper: lens images, three region passes back to front)"),
    "segments-stencil": ({"lens_method": "segments-stencil"},
                         "segments, transitions by stencil and second depth test (the paper's sequence)"),
    "fused": ({"lens_method": "fused"}, "fused (one pass looping over the three segments)"),
    "per-sample": ({"lens_method": "per-sample"}, "per-sample inside test (analytic)"),
    "per-sample-mask": ({"lens_method": "per-sample-mask"}, "per-sample 3-D lens-mask fetch (Weiskopf et al.)"),
    "frag-depth": ({"lens_method": "frag-depth"}, "depth-based clipping writing gl_FragDepth"),
    "segments-ftb": ({"lens_method": "segments", "region_order": "front-to-back"},
                     "segments, regions front to back (not in the paper)"),
}
"""The lens methods as ``gl-raycast`` options (note 004 §4.1; issue 24)."""

CONFIGS = tuple(config for config in METHODS if config != "segments-ftb")
"""Every lens method, region passes back to front: the front-to-back order (E9's) composites the same samples."""

PAPER_METHOD = "segments"
"""The paper's method: the one Table 1's lens runs use."""

OFF = "off"
"""The config of a lens-off run (the scene without its lens)."""

STEP = 0.5
"""Samples half a voxel apart (the caster's default; the paper gives no step, note 004 §2.11)."""

OPTIONS = ("variant", "lens_method", "region_order", "step_factor", "opaque_threshold", "iso_hit")
"""The ``gl-raycast`` options these experiments set."""

STAGES = ("setup", "lens_geometry", "region0", "region1", "region2", "main", "readback")
"""The frame's stages a lens frame can report, in the order they run (the segments method's regions
back to front; ``main`` the single pass of the other methods and of a lens-off frame)."""

REGIONS = {"region2": "region₂ (in front of the lens)", "region1": "region₁ (inside lens ∩ box)",
           "region0": "region₀ (behind and beside the lens)"}
"""The segments method's region passes, in words (note 004 §2.2)."""

TIMES = "whole frames (time_total), median over the views of each view's median frame"
"""The scope of the timing claims: the paper's frame rates are of whole frames from views it does not give."""


def method_name(config):
    """The words for ``config`` (a key of :data:`METHODS`, or :data:`OFF`)."""
    return "no lens" if config == OFF else METHODS[config][1]


def method_options(config, *, step_factor=STEP, **extra):
    """``gl-raycast``'s options for ``config`` (a key of :data:`METHODS`, or :data:`OFF`), plus ``extra``."""
    method = {} if config == OFF else METHODS[config][0]
    return {**VARIANT, **method, "step_factor": step_factor, **extra}


LENS_SCALES = scaled(smoke={"orbit": 0}, default={"orbit": 0}, full={"orbit": 2})
"""What :func:`lens_settings` reads at each scale: the kit's sizes, and the headline view alone until full scale
adds two around it (:func:`~pipeline.experiments.ropinski2005.scenes.lens_views`)."""

TIMED_SCALES = scaled(base=LENS_SCALES, full={"image_size": 1024})
""":data:`LENS_SCALES` with the paper's larger viewport, 1024², at full scale."""


def lens_settings(profile, experiment, *, orbit=0):
    """``(volume size, image size, orbit, step)`` of ``experiment``'s runs in ``profile`` (``orbit`` where unset)."""
    return (profile.setting(experiment, "volume_size", profile.volume_size),
            int(profile.setting(experiment, "image_size", profile.image_size)),
            int(profile.setting(experiment, "orbit", orbit)), profile.setting(experiment, "step_factor", STEP))


def lens_run(experiment, run_id, scene_spec, views, config, frames, tags, *, step_factor=STEP, group=None,
             reference=None, options=None):
    """A ``gl-raycast`` run of ``config`` (a lens method, or :data:`OFF` on the lens-free scene), tagged with it,
    ``frames`` its warm-up, repeat and min_time, ``group`` its interleave group (a timing claim's runs are timed
    together). An iso lens finds its surface as the paper's caster does, at the samples (``iso_hit="sampled"``;
    gl-raycast's default walks every cell exactly, issue 36)."""
    iso_lens = any(lens.get("appearance", {}).get("mode") == "iso" for lens in scene_spec.get("lenses", ()))
    options = {**(options or {}), **({"iso_hit": "sampled"} if iso_lens else {})}
    return Run(experiment, run_id, RAYCAST, scene_spec, tuple(views),
               options=method_options(config, step_factor=step_factor, **options), reference=reference,
               **frames, tags={**tags, "config": config}, interleave=group)


def unknown_methods(configs):
    """``[(what, reason)]`` for each of ``configs`` whose options ``gl-raycast`` does not offer here."""
    try:
        table = {option.name: option for option in renderers.backend_class(RAYCAST).option_table}
    except Exception:  # noqa: BLE001 - not importable here: the runs are skipped with the reason
        return []
    return [(f"lens method {config}", f"{RAYCAST}'s {name} has no {value!r} here (its choices: "
                                      f"{', '.join(table[name].choices)}), so its runs fail")
            for config in dict.fromkeys(c for c in configs if c != OFF) for name, value in METHODS[config][0].items()
            if getattr(table.get(name), "choices", ()) and value not in table[name].choices]


def raycast_not_measurable(configs=()):
    """The page's note of what this machine lacks: ``gl-raycast``, its lens options, the methods ``configs`` use."""
    return not_measurable(unregistered(RAYCAST) + missing_options(RAYCAST, *OPTIONS) + unknown_methods(configs))


def scenes_of(frame):
    return list(pd.unique(text_column(frame, "scene")))


def lens_coverage(rows):
    """The share of the rays meeting lens ∩ box (``lens_rays / rays``), the median over ``rows``; NaN if uncounted."""
    if "count_lens_rays" not in rows or "count_rays" not in rows:
        return np.nan
    return float((numeric(rows, "count_lens_rays") / numeric(rows, "count_rays")).median())


def device_takeaways(tests):
    """Which GL devices timed the page, and what a CPU rasterizer's frame times mean beside the paper's."""
    return pages.device_takeaways(tests, software=(
        "its fragment shaders run on the CPU's cores, so a lens pass costs what its samples cost there, not what a "
        "GPU's fill rate makes of it; only ratios of runs timed together compare with the paper's, and the sample "
        "counts (machine-independent) say what any device has to do"))


class LensExperiment(Experiment):
    """An experiment of this paper: by default planned (:meth:`lens_runs`) only where ``gl-raycast`` is registered
    and takes :data:`OPTIONS` and :attr:`needs`."""

    paper = "ropinski2005"
    needs = ()

    def runs(self, profile):
        if not (is_registered(RAYCAST) and accepts(RAYCAST, *OPTIONS, *self.needs)):
            return []
        return self.lens_runs(profile)
