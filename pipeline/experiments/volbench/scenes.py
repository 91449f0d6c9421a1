"""What the convergence and speed–accuracy studies share: one phantom's scene and its ground truth."""

from pipeline.experiments.kit.planning import HEADLINE_VIEW, phantom, scene, truth_run


def scene_and_truth(experiment, profile, scene_name, scene_def, truth_factor, tags, *, mode="dvr"):
    """The scene of ``scene_def = (dataset, preset, shading)`` and its ground truth ``<scene_name>.truth``.

    Parameters
    ----------
    experiment : Experiment
        Whose ``volume_size`` and ``image_size`` settings size the phantom and the image (the
        profile's own sizes where it has none).
    profile : Profile
    scene_name : str
        The scene's name, the truth run's id prefix and its ``scene`` tag.
    scene_def : tuple
        ``(data set, preset or None for the data set's default, shading model)``.
    truth_factor : float
        The reference's step for the truth, as a fraction of a voxel.
    tags : dict
        The truth run's tags besides ``scene`` and ``role`` (``step_factor``, which
        :func:`~pipeline.experiments.kit.planning.truth_run` cannot take as a keyword).

    Returns
    -------
    scene : dict
    truth : Run
        The reference at the headline view, one untimed frame.
    """
    dataset, preset, shading = scene_def
    size = profile.setting(experiment, "volume_size", profile.volume_size)
    image_size = profile.setting(experiment, "image_size", profile.image_size)
    volume = phantom(dataset, size, **({"preset": preset} if preset else {}))
    spec = scene(scene_name, image_size, volumes=[volume], shading=shading, mode=mode)
    truth = truth_run(experiment.name, scene_name, spec, (HEADLINE_VIEW,), truth_factor, {"scene": scene_name, **tags})
    return spec, truth
