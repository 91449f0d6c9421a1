"""volbench-speed-accuracy: the reference's trade-off claim and the scenes a profile names."""

import numpy as np
import pandas as pd
import pytest

from core.errors import InputError
from pipeline import experiments
from pipeline.experiments import Profile
from pipeline.experiments.volbench.speed_accuracy import SPEED_ACCURACY_SCENES, SpeedAccuracy, _tradeoff


def test_tradeoff_claim_needs_doubling_times():
    rows = [{"scene": "s", "backend": "reference", "role": "sweep", "setting": f"step_factor={f}",
             "time_total": t, "rmse": e} for f, t, e in ((1.0, 1.0, 0.1), (0.5, 2.0, 0.05), (0.25, 4.1, 0.02))]
    assert _tradeoff(pd.DataFrame(rows)).holds
    rows[1]["time_total"], rows[2]["time_total"] = 1.1, 1.2  # overhead-bound: the step barely matters
    assert not _tradeoff(pd.DataFrame(rows)).holds
    rows[1]["time_total"], rows[2]["time_total"], rows[2]["rmse"] = 2.0, 4.0, 0.06  # error went up
    assert not _tradeoff(pd.DataFrame(rows)).holds


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
