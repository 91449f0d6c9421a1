"""What the paper's experiments share: the depth-init modes as ``gl-isbvr`` options, their runs, the culled
fraction from their counts, decisions in words and the page note for what this machine cannot measure."""

import numpy as np
import pandas as pd

from pipeline.experiments.kit import intervals
from pipeline.experiments.kit.model import ClaimResult, Run
from pipeline.experiments.kit.pages import as_ratio, not_measurable
from pipeline.experiments.kit.planning import accepts, missing_options, unregistered
from pipeline.experiments.kit.results import numeric

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

OPTIONS = ("zinit", "surfaces", "phi_t_node", "phi_p_node", "depth_offset", "shader", "extra_taps", "order")
"""The ``gl-isbvr`` options the experiments set."""


def mode_name(config):
    """The paper's name of ``config`` (a key of :data:`MODES`)."""
    return MODES[config][1]


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


def isbvr_not_measurable():
    """The page's note of what this machine lacks for the paper (the backend or its options)."""
    return not_measurable(unregistered(ISBVR) + missing_options(ISBVR, *OPTIONS))


def median_count(rows, column):
    """The median of a counter over ``rows`` (the views; counts do not depend on the machine)."""
    return float(numeric(rows, column).median())


def culled_fraction(rows):
    """α' = 1 − F'_c / F (the fragments the depth test culled), the median over ``rows``' views.

    ValueError where the runs counted no fragment (``gl-isbvr``'s ``count_fragments`` off).
    """
    value = float((1.0 - numeric(rows, "count_fragments") / numeric(rows, "count_fragments_generated")).median())
    if not np.isfinite(value):
        raise ValueError(f"runs {', '.join(map(str, pd.unique(rows.run)))} counted no fragments "
                         "(gl-isbvr's count_fragments option)")
    return value


def with_interval(text, decision, show=as_ratio):
    """``"×1.12 (95 % CI ×1.08–×1.17)"``: ``text`` with the decision's interval (shown by ``show``) where it has one."""
    words = intervals.interval_words(decision, show)
    return f"{text} ({words})" if words else text


def decision_words(decision, show=as_ratio):
    """A decision's value (shown by ``show``) with its interval where it has one."""
    return with_interval(show(decision.value), decision, show)


def every(decisions, *, show=as_ratio, notes=None, what="", extra=""):
    """One result of labelled decisions that must all hold (:func:`~pipeline.experiments.kit.intervals.combine`).

    ``measured`` gives the deciding (worst) label's value after ``what``; the detail lists every label's
    value with its interval and its note from ``notes`` (counts, which do not depend on the machine),
    then ``extra``.
    """
    combined = intervals.combine(decisions.values())
    worst = next(label for label, d in decisions.items()
                 if (d.value, d.interval, d.holds) == (combined.value, combined.interval, combined.holds))
    notes = notes or {}
    detail = "; ".join(f"{label}: {decision_words(d, show)}" + (f" ({notes[label]})" if notes.get(label) else "")
                       for label, d in decisions.items())
    return ClaimResult.decided(f"{what}{decision_words(combined, show)} ({worst})", combined,
                               detail + (f"; {extra}" if extra else ""))
