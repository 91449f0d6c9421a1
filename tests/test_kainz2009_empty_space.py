"""kainz2009-ess (E8): boxes against brick hulls, the build runs and the claims on synthetic results."""

import pandas as pd

from pipeline import experiments
from pipeline.experiments import Profile
from pipeline.experiments.kainz2009.empty_space import BRICKS

NAME = "kainz2009-ess"


def _evaluate(claim_id, rows):
    claim = next(c for c in experiments.get(NAME).claims if c.id == claim_id)
    return claim.evaluate(pd.DataFrame(rows))


def test_ess_plan_times_each_hull_build_in_a_single_untimed_frame():
    profile = Profile(name="t", volume_size=16, image_size=24, warmup=0, repeat=1, experiments=[NAME])
    builds = [r for r in experiments.plan(profile).values() if r.tags["role"] == "build"]
    assert {r.options["brick_size"] for r in builds} == set(BRICKS)
    assert all((r.warmup, r.repeat) == (0, 1) and r.reference is None for r in builds)


def _ess_rows(box, hulls, psnr_box=45.0, psnr_hull=44.5, build_ms=2.0):
    rows = [{"scene": "torso", "role": "test", "config": "box", "brick": 0, "time_total": box, "psnr": psnr_box}]
    rows += [{"scene": "torso", "role": "test", "config": "hull", "brick": b, "time_total": t, "psnr": psnr_hull}
             for b, t in hulls.items()]
    rows += [{"scene": "torso", "role": "build", "config": "hull", "brick": b, "time_bricks": build_ms * 4e-4,
              "time_hull": build_ms * 6e-4} for b in hulls]
    return rows


def test_ess_claims():
    rows = _ess_rows(0.010, {4: 0.0095, 8: 0.0088, 16: 0.0092})
    for claim in ("hull-faster", "best-brick-8", "hull-accurate", "build-cheap"):
        assert _evaluate(claim, rows).holds is True, claim
    rows = _ess_rows(0.010, {4: 0.012, 8: 0.011, 16: 0.0105}, psnr_hull=40.0, build_ms=20.0)
    for claim in ("hull-faster", "best-brick-8", "hull-accurate", "build-cheap"):
        assert _evaluate(claim, rows).holds is False, claim
