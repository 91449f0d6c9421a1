"""kainz2009-step (E10): the swept common step and the claims on synthetic results."""

import numpy as np
import pandas as pd

from pipeline import experiments
from pipeline.experiments import Profile
from pipeline.experiments.kainz2009.methods import TILED
from pipeline.experiments.kainz2009.step import STEPS, Step

NAME = "kainz2009-step"


def _evaluate(claim_id, rows):
    claim = next(c for c in Step.claims if c.id == claim_id)
    return claim.evaluate(pd.DataFrame(rows))


def _frames(seconds, *, spread=0.02, seed=0, stage="technique", n=9):
    """A stage's median and its ``n`` timed frames within ± ``spread`` of ``seconds``, as a run's columns."""
    values = seconds * (1 + spread * np.random.default_rng(seed).uniform(-1, 1, n))
    return {f"time_{stage}": float(np.median(values)), f"frames_{stage}": " ".join(f"{v:.6g}" for v in values)}


def test_step_plan_sweeps_the_step_and_times_every_step_together():
    profile = Profile(name="t", volume_size=16, image_size=24, warmup=0, repeat=1, experiments=[NAME])
    step = [r for r in experiments.plan(profile).values() if r.backend == TILED]
    assert sorted(r.options["step_factor"] for r in step) == sorted(STEPS)
    assert {r.interleave for r in step} == {"mixed"}


def _rows(seconds, samples=(1000, 2000, 4000, 8000), psnr=(39.0, 44.0, 48.0, 52.0), spread=0.02):
    """Steps 1 … 0.125 (coarse to fine) with their kernel seconds, samples and PSNR."""
    return [{"role": "test", "step_factor": f, "count_samples": n, "psnr": p, "time_total": 1.2 * t,
             **_frames(t, spread=spread, seed=i)}
            for i, (f, t, n, p) in enumerate(zip((1.0, 0.5, 0.25, 0.125), seconds, samples, psnr))]


def test_step_claims():
    # A fixed 6 ms and 4 µs per sample, 2 µs for the samples the finest steps add (cache hits).
    rows = _rows((0.010, 0.014, 0.020, 0.028))
    result = _evaluate("oversampling-cheap", rows)
    assert result.holds is True and result.measured.startswith("×0.511 (95 % CI ×")
    assert result.measured.endswith("2.03e+03 ns per added sample from 0.25 to 0.125, 3.96e+03 ns from 1 to 0.5")
    assert _evaluate("error-falls", rows).holds is True
    # The per-sample cost of the whole frame would fall here too (the fixed 6 ms spread over more
    # samples), yet each added sample costs more at the finest steps: the claim fails.
    rows = _rows((0.010, 0.012, 0.016, 0.040), psnr=(39.0, 44.0, 43.0, 52.0))
    assert rows[-1]["time_technique"] / 8000 < rows[0]["time_technique"] / 1000
    assert _evaluate("oversampling-cheap", rows).holds is False
    assert _evaluate("error-falls", rows).holds is False
    assert _evaluate("oversampling-cheap", _rows((0.010, 0.014, 0.020, 0.036), spread=0.3)).inconclusive
    assert _evaluate("oversampling-cheap", rows[:2]).holds is None  # one pair of steps: nothing to compare
