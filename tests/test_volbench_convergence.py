"""volbench-convergence: the claims on the reference's errors as the step shrinks, and the plan at each scale."""

import numpy as np
import pandas as pd
import pytest

from pipeline.experiments import Profile
from pipeline.experiments.volbench.convergence import (CONVERGENCE_SCENES, DEFAULT_STEP, ReferenceConvergence,
                                                       _monotone, _order)


def _convergence_frame(errors_by_scene):
    rows = []
    for scene, errors in errors_by_scene.items():
        for factor, rmse in zip((2.0, 1.0, 0.5, 0.25), errors):
            rows.append({"scene": scene, "role": "sweep", "step_factor": factor, "rmse": rmse,
                         "psnr": -20 * np.log10(rmse)})
    return pd.DataFrame(rows)


def test_convergence_claims_detect_flat_and_rising_errors():
    good = _convergence_frame({"a": [0.16, 0.04, 0.01, 0.0025]})
    assert _monotone(good).holds and _order(good).holds and DEFAULT_STEP(good).holds
    assert float(_order(good).measured.split()[0]) == pytest.approx(2.0, abs=1e-6)
    flat = _convergence_frame({"a": [0.16, 0.04, 0.01, 0.0025], "b": [0.02, 0.02, 0.019, 0.03]})
    assert not _monotone(flat).holds and "b" in _monotone(flat).detail
    assert not _order(flat).holds
    assert not DEFAULT_STEP(flat).holds  # 0.03 RMSE is 30.5 dB
    assert DEFAULT_STEP(flat).measured == "30.5 dB (b)"  # the worst scene, named


def test_claims_without_data_are_not_measured():
    claim = ReferenceConvergence.claims[0]
    assert claim.evaluate(pd.DataFrame()).holds is None
    coarse_only = _convergence_frame({"a": [0.16, 0.04, 0.01]})  # no run at the default step
    assert ReferenceConvergence.claims[2].evaluate(coarse_only).holds is None


@pytest.mark.parametrize("scale", ["smoke", "full"])
def test_each_scale_applies_without_profile_settings(scale):
    own = ReferenceConvergence.scales[scale]
    runs = ReferenceConvergence().runs(Profile(name="t", scale=scale, volume_size=16, image_size=16))
    sweep = [run for run in runs if run.tags["role"] == "sweep"]
    assert sorted({run.options["step_factor"] for run in sweep}) == sorted(own["step_factors"])
    truths = [run for run in runs if run.tags["role"] == "truth"]
    assert len(truths) == len(CONVERGENCE_SCENES)
    truth_step = own.get("truth_step_factor", ReferenceConvergence.TRUTH_FACTOR)
    assert {run.options["step_factor"] for run in truths} == {truth_step}
    assert {run.scene["width"] for run in runs} == {own.get("image_size", 16)}
    assert all(run.reference in {t.id for t in truths} for run in sweep)
