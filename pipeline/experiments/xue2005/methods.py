"""What the paper's experiments share: the depth-init modes as ``gl-isbvr`` options, Table 1's scenes and views,
their runs, the culled fraction from their counts, the table of every run and the page note for what this machine
cannot measure."""

import numpy as np
import pandas as pd

from pipeline.experiments.kit.model import Run
from pipeline.experiments.kit.pages import linked_table, not_measurable
from pipeline.experiments.kit.planning import accepts, missing_options, phantom, scene, unregistered
from pipeline.experiments.kit.results import numeric
from pipeline.experiments.xue2005.tables import TABLE1

ISBVR, SLICER, RAYCAST, VTK = "gl-isbvr", "gl-slicer", "gl-raycast", "vtk-gpu"

MODES = {
    # config: (gl-isbvr options, the paper's name)
    "basic": ({"zinit": "none"}, "Basic SBVR"),
    "ess": ({"zinit": "ess"}, "ESS (exit-based leaping, empty rays)"),
    "ert": ({"zinit": "ert"}, "ERT (pseudo early termination)"),
    "ess+ert": ({"zinit": "ess+ert"}, "ESS+ERT"),
    "front": ({"zinit": "front"}, "front-based leaping (§3.2)"),
}
"""The depth-init modes of Table 1 (and §3.2's front-based leaping) as ``gl-isbvr`` options."""

STEP = 1.0
"""Slices one voxel apart, as the paper's."""

STAGE_MS = {"init_ms": "time_init", "draw_ms": "time_draw", "time_ms": "time_total"}

OPTIONS = ("zinit", "surfaces", "phi_t_node", "phi_p_node", "depth_offset", "shader", "extra_taps", "order")


def mode_name(config):
    """The paper's name of ``config`` (a key of :data:`MODES`)."""
    return MODES[config][1]


def short_name(config):
    """``"ESS"``: a mode's name without its explanation, for legends and labels."""
    return mode_name(config).split(" (")[0]


def stand_in(scene_name, size, image):
    """``(scene, tags)``: :data:`~.tables.TABLE1`'s ``scene_name`` (a phantom at ``size``, a real scan as scanned)
    in an ``image``-pixel picture, and the tags naming its scene, data set and preset."""
    dataset, preset = TABLE1[scene_name][:2]
    tags = {"scene": scene_name, "dataset": dataset, "preset": preset}
    return scene(scene_name, image, volumes=[phantom(dataset, size, preset=preset)]), tags


def mode_runs(experiment, prefix, scene_spec, views, configs, frames, tags, *, options=None, group=None,
              reference=None):
    """Timed ``gl-isbvr`` runs of ``configs`` (keys of :data:`MODES`) on one scene, timed together.

    The runs of one call are one interleave group (``group``, default ``prefix``): frame against frame,
    so their ratios come with paired intervals. ``options`` are added to every config's; ``reference``
    is the id of the run the images are compared with.
    """
    if not accepts(ISBVR, *OPTIONS):
        return []
    return [Run(experiment, f"{prefix}.{config}", ISBVR, scene_spec, views,
                options={**MODES[config][0], "step_factor": STEP, **(options or {})}, reference=reference, **frames,
                tags={**tags, "config": config}, interleave=group or prefix)
            for config in configs]


def isbvr_not_measurable(*options, also=()):
    """The page's note of what this machine lacks for the paper (the backend or its options, :data:`OPTIONS` and
    ``options``), and ``also``: more ``(what, why)`` pairs."""
    return not_measurable(unregistered(ISBVR) + missing_options(ISBVR, *OPTIONS, *options) + list(also))


def culled_fraction(rows):
    """α' = 1 − F'_c / F (the fragments the depth test culled), the median over ``rows``' views.

    ValueError where the runs counted no fragment (``gl-isbvr``'s ``count_fragments`` off).
    """
    value = float((1.0 - numeric(rows, "count_fragments") / numeric(rows, "count_fragments_generated")).median())
    if not np.isfinite(value):
        raise ValueError(f"runs {', '.join(map(str, pd.unique(rows.run)))} counted no fragments "
                         "(gl-isbvr's count_fragments option)")
    return value


def runs_table(ok, ctx, columns):
    """The page's table of every run: ``columns`` (column: its name), stage times of :data:`STAGE_MS` in ms."""
    runs = ok.assign(**{ms: numeric(ok, stage) * 1e3 for ms, stage in STAGE_MS.items() if ms in columns})
    return linked_table("Runs", runs, list(columns), ctx, names=columns)
