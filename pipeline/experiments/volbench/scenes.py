"""What the convergence and speed–accuracy studies share: one phantom's scene and its ground truth."""

from pipeline.experiments.kit.planning import HEADLINE_VIEW, phantom, scene, truth_run, volume_and_image_size


def scene_and_truth(experiment, profile, scene_name, scene_def, truth_factor, tags, *, mode="dvr"):
    """``(scene, truth)``: the scene ``scene_name`` of ``scene_def``, ``(data set, preset or None for its default,
    shading model)``, at ``experiment``'s sizes, and its ground truth ``<scene_name>.truth`` at ``truth_factor`` of a
    voxel in the headline view, tagged ``tags`` too (``step_factor``, which ``truth_run`` takes as no keyword)."""
    dataset, preset, shading = scene_def
    size, image_size = volume_and_image_size(profile, experiment)
    volume = phantom(dataset, size, **({"preset": preset} if preset else {}))
    spec = scene(scene_name, image_size, volumes=[volume], shading=shading, mode=mode)
    truth = truth_run(experiment.name, scene_name, spec, (HEADLINE_VIEW,), truth_factor, {"scene": scene_name, **tags})
    return spec, truth
