"""Planning this paper's runs: its backends and untimed shear-warp frames checked against a ground
truth."""

from pipeline.experiments.kit.model import Run
from pipeline.experiments.kit.planning import UNTIMED, truth_run

SW, VP = "shearwarp", "volpack"
"""The paper's technique (our shear-warp) and its baseline (VolPack, the thesis's own library)."""


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
