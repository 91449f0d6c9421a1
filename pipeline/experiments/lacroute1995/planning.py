"""What this paper's experiments share: its backends, its timing claims' stage, untimed shear-warp frames checked
against a ground truth, and the pages' note of what the shear-warp backend cannot measure here."""

from pipeline.experiments.kit.judging import TECHNIQUE
from pipeline.experiments.kit.model import Run
from pipeline.experiments.kit.pages import not_measurable
from pipeline.experiments.kit.planning import UNTIMED, missing_options, truth_run, unregistered

SW, VP = "shearwarp", "volpack"
"""The paper's technique (our shear-warp) and its baseline (VolPack, the thesis's own library)."""

TIME = TECHNIQUE
"""The timing claims' stage unless they name another: the technique (the backend's kernels and tables, or VolPack's
library calls), what the thesis timed, not the serial Python around it."""


def truth_and_shearwarp(experiment, prefix, scene, views, step_factor, tags, *, pre_classified=False):
    """``[<prefix>.truth, <prefix>.shearwarp]``: the reference and one untimed shear-warp frame checked against it.

    With ``pre_classified`` also ``<prefix>.truth-pre`` (the reference classifying voxels before
    interpolating, the thesis's comparison caster) and ``<prefix>.shearwarp-vs-pre`` checked
    against it; every run is then tagged ``truth`` = ``post`` or ``pre``.
    """
    references = [("", "post", None)]
    if pre_classified:
        references.append(("-pre", "pre", {"classification": "pre"}))
    runs = []
    for suffix, truth_kind, options in references:
        extra = {"truth": truth_kind} if pre_classified else {}
        truth = truth_run(experiment, prefix, scene, views, step_factor, tags, options=options, suffix=suffix, **extra)
        test_id = f"{prefix}.shearwarp" + (f"-vs{suffix}" if suffix else "")
        runs += [truth, Run(experiment, test_id, SW, scene, views, reference=truth.id, **UNTIMED,
                            tags={**tags, "role": "test", **extra})]
    return runs


def shearwarp_missing(*options, more=()):
    """The page's note of what cannot be measured here: the shear-warp backend, or its ``options``, where this
    machine lacks them, then the ``(what, why)`` pairs of ``more``."""
    return not_measurable(unregistered(SW) + missing_options(SW, *options) + list(more))
