"""kainz2009-media (E9): the apple and its rods, analytic against sampled media, and the claims."""

import pandas as pd

from pipeline import experiments
from pipeline.experiments import Profile
from pipeline.experiments.kainz2009.media import ROD_COUNT
from pipeline.experiments.kainz2009.methods import TILED
from pipeline.scene_io import build_scene

NAME = "kainz2009-media"


def _evaluate(claim_id, rows):
    claim = next(c for c in experiments.get(NAME).claims if c.id == claim_id)
    return claim.evaluate(pd.DataFrame(rows))


def test_media_plan_checks_both_variants_against_one_truth(tmp_path):
    profile = Profile(name="t", volume_size=16, image_size=24, warmup=0, repeat=1, experiments=[NAME],
                      settings={NAME: {"volume_size": 16}})
    tests = {r.options["media"]: r for r in experiments.plan(profile).values() if r.backend == TILED}
    assert set(tests) == {"analytic", "sampled"} and {r.reference for r in tests.values()} == {"apple.truth"}
    scene = build_scene(tests["analytic"].scene, cache_dir=tmp_path)
    assert len(scene.meshes) == ROD_COUNT and all(m.medium is not None for m in scene.meshes)
    assert all(m.mesh.triangle_count == 76 for m in scene.meshes) and len(scene.volumes) == 1


def _rows(analytic, sampled, *, psnr=(50.0, 50.0), steps=(10, 400)):
    return [{"scene": "apple", "role": "test", "config": c, "time_total": 2 * t, "time_pixel": t, "psnr": p,
             "count_medium_steps": n} for c, t, p, n in zip(("analytic", "sampled"), (analytic, sampled), psnr, steps)]


def test_media_claims():
    rows = _rows(0.010, 0.011)
    assert _evaluate("shortcut-gain", rows).measured == "×1.1 (10 % gain)"
    for claim in ("shortcut-gain", "shortcut-exact", "fewer-steps"):
        assert _evaluate(claim, rows).holds is True, claim
    rows = _rows(0.010, 0.009, psnr=(50.0, 45.0), steps=(10, 10))
    for claim in ("shortcut-gain", "shortcut-exact", "fewer-steps"):
        assert _evaluate(claim, rows).holds is False, claim
    assert _evaluate("shortcut-gain", rows[:1]).holds is None
