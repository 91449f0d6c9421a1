"""kainz2009-step (E10): the swept common step and the claims on synthetic results."""

import pandas as pd

from pipeline import experiments
from pipeline.experiments import Profile
from pipeline.experiments.kainz2009.methods import TILED
from pipeline.experiments.kainz2009.step import STEPS

NAME = "kainz2009-step"


def _evaluate(claim_id, rows):
    claim = next(c for c in experiments.get(NAME).claims if c.id == claim_id)
    return claim.evaluate(pd.DataFrame(rows))


def test_step_plan_sweeps_the_step():
    profile = Profile(name="t", volume_size=16, image_size=24, warmup=0, repeat=1, experiments=[NAME])
    step = [r for r in experiments.plan(profile).values() if r.backend == TILED]
    assert sorted(r.options["step_factor"] for r in step) == sorted(STEPS)


def test_step_claims():
    rows = [{"role": "test", "step_factor": f, "time_total": t, "count_samples": n, "psnr": p}
            for f, t, n, p in ((0.25, 0.030, 4000, 48.0), (0.5, 0.017, 2000, 44.0), (1.0, 0.010, 1000, 39.0))]
    assert _evaluate("oversampling-cheap", rows).holds is True
    assert _evaluate("error-falls", rows).holds is True
    rows[0].update(time_total=0.060, psnr=43.0)
    assert _evaluate("oversampling-cheap", rows).holds is False
    assert _evaluate("error-falls", rows).holds is False
