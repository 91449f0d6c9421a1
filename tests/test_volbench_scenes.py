"""The scene and ground truth volbench's convergence and speed–accuracy studies share."""

from pipeline.experiments import Profile
from pipeline.experiments.kit.model import Experiment
from pipeline.experiments.kit.planning import HEADLINE_VIEW, UNTIMED
from pipeline.experiments.volbench.scenes import scene_and_truth


class Study(Experiment):
    name = "volbench-study"
    scales = {"default": {"volume_size": 24, "image_size": 40}}


def test_the_truth_is_one_untimed_reference_frame_of_the_experiments_sized_scene():
    profile = Profile(name="t", volume_size=16, image_size=16)
    scene, truth = scene_and_truth(Study(), profile, "skull-bone", ("ct_skull", "bone", "phong"), 1 / 32,
                                   {"step_factor": 1 / 32})
    assert scene["name"] == "skull-bone" and (scene["width"], scene["height"]) == (40, 40)
    assert scene["volumes"] == [{"dataset": "ct_skull", "size": 24, "preset": "bone"}]
    assert scene["shading"] == {"model": "phong"} and scene["mode"] == "dvr"
    assert (truth.experiment, truth.id, truth.backend) == ("volbench-study", "skull-bone.truth", "reference")
    assert truth.scene == scene and truth.views == (HEADLINE_VIEW,) and truth.options == {"step_factor": 1 / 32}
    assert {"warmup": truth.warmup, "repeat": truth.repeat} == UNTIMED
    assert truth.tags == {"scene": "skull-bone", "step_factor": 1 / 32, "role": "truth"}


def test_a_scene_without_a_preset_takes_the_data_sets_default_and_the_profiles_sizes():
    profile = Profile(name="t", scale="smoke", volume_size=16, image_size=24)
    scene, truth = scene_and_truth(Study(), profile, "engine-semi", ("engine", None, "none"), 1 / 16, {})
    assert scene["volumes"] == [{"dataset": "engine", "size": 16}] and scene["width"] == 24
    assert scene["shading"] == {"model": "none"} and truth.tags == {"scene": "engine-semi", "role": "truth"}
