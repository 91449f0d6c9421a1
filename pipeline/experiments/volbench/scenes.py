"""What the convergence and speed–accuracy studies share: one phantom's scene and its ground truth."""

from pipeline.experiments.kit.planning import HEADLINE_VIEW, phantom, scene, truth_run, volume_and_image_size


def scene_and_truth(experiment, profile, scene_name, scene_def, truth_factor, tags, *, mode="dvr"):
    """``(scene, truth)``: the scene ``scene_name`` of ``scene_def``, ``(data set, preset or None for its default,
    shading model)``, at ``experiment``'s sizes, and its ground truth ``<scene_name>.truth``: the reference at
    ``truth_factor`` of a voxel in the headline view, one untimed frame.

    ``tags`` are the truth's besides ``scene`` and ``role`` (``step_factor``, which
    :func:`~pipeline.experiments.kit.planning.truth_run` cannot take as a keyword).
    """
    dataset, preset, shading = scene_def
    size, image_size = volume_and_image_size(profile, experiment)
    volume = phantom(dataset, size, **({"preset": preset} if preset else {}))
    spec = scene(scene_name, image_size, volumes=[volume], shading=shading, mode=mode)
    truth = truth_run(experiment.name, scene_name, spec, (HEADLINE_VIEW,), truth_factor, {"scene": scene_name, **tags})
    return spec, truth
