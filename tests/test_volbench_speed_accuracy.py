"""volbench-speed-accuracy: the reference's trade-off claim and the scenes a profile names."""

import numpy as np
import pandas as pd
import pytest

from core.errors import InputError
from pipeline import experiments
from pipeline.experiments import Profile
from pipeline.experiments.kit.intervals import format_frames
from pipeline.experiments.volbench.speed_accuracy import SPEED_ACCURACY_SCENES, SpeedAccuracy, _tradeoff


def _sweep(times, errors, *, frames=5, spread=0.02):
    """The reference's sweep on one scene, its steps timed together (``frames`` each, ``spread`` about the median)."""
    return pd.DataFrame([{"scene": "s", "backend": "reference", "role": "sweep", "setting": f"step_factor={f}",
                          "time_total": t, "rmse": e, "interleave": "s.reference", "view": "headline",
                          "experiment": "volbench-speed-accuracy",
                          "frames_total": format_frames(t * (1 + spread * np.linspace(-1, 1, frames)))}
                         for f, t, e in zip((1.0, 0.5, 0.25), times, errors)])


def test_tradeoff_claim_needs_doubling_times():
    doubling = _tradeoff(_sweep((1.0, 2.0, 4.1), (0.1, 0.05, 0.02)))
    assert doubling.holds and doubling.interval is not None and doubling.frames == 5
    assert _tradeoff(_sweep((1.0, 1.1, 1.2), (0.1, 0.05, 0.02))).holds is False  # overhead-bound: the step barely matters
    assert _tradeoff(_sweep((1.0, 2.0, 4.0), (0.1, 0.05, 0.06))).holds is False  # error went up
    # Decided by its frames: too few, or none, leave it inconclusive.
    assert _tradeoff(_sweep((1.0, 2.0, 4.1), (0.1, 0.05, 0.02), frames=3)).inconclusive
    assert _tradeoff(_sweep((1.0, 2.0, 4.1), (0.1, 0.05, 0.02)).drop(columns="frames_total")).inconclusive


def test_claims_without_data_are_not_measured():
    empty_sweep = pd.DataFrame([{"backend": "reference", "role": "truth", "scene": "s", "setting": "truth",
                                 "time_total": 1.0, "rmse": np.nan}])
    assert SpeedAccuracy.claims[0].evaluate(empty_sweep).holds is None


def test_speed_accuracy_runs_only_the_scenes_a_profile_names():
    def planned(scenes=None, scale="default"):
        profile = Profile(name="t", scale=scale, volume_size=8, image_size=8, experiments=["volbench-speed-accuracy"],
                          settings={"volbench-speed-accuracy": {"scenes": scenes}} if scenes else {})
        return {run.tags["scene"] for run in experiments.plan(profile).values()}

    assert planned(["skull-bone"]) == {"skull-bone"}
    with pytest.raises(InputError, match="volbench-speed-accuracy.scenes"):
        planned(["teapot"])
    assert planned(scale="smoke") == set(SpeedAccuracy.scales["smoke"]["scenes"]) != set(SPEED_ACCURACY_SCENES)
    assert planned(scale="default") == set(SPEED_ACCURACY_SCENES)


def test_the_references_sweep_is_timed_together_with_five_frames_at_least():
    profile = Profile.load("config/default.yaml")
    runs = [run for run in experiments.plan(Profile(**{**profile.__dict__, "experiments": ["volbench-speed-accuracy"]})
                                            ).values() if run.tags.get("role") == "sweep"]
    sweep = [run for run in runs if run.backend == "reference"]
    assert {run.interleave for run in sweep} == {f"{scene}.reference" for scene in SPEED_ACCURACY_SCENES}
    assert all(run.repeat * run.replicates >= 5 and run.replicates == profile.replicates for run in sweep)
    assert all(not run.interleave for run in runs if run.backend != "reference")  # the others: a job each
