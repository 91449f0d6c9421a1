"""kainz2009-scaling (E2): the plan over volume counts, its scenes and its claims on synthetic results."""

import numpy as np
import pandas as pd
import pytest

from core.errors import InputError
from pipeline import experiments
from pipeline.experiments import Profile
from pipeline.experiments.kainz2009.methods import PEEL, TILED, VTK, VTK_MAX_VOLUMES
from pipeline.experiments.kainz2009.scaling import (GROUP, SERIES, TARGET_COUNT, Scaling, _one_cloud_ms,
                                                    _scaling_takeaways)
from pipeline.experiments.kainz2009.scenes import CLOUD_SPREAD
from pipeline.scene_io import build_scene

NAME = "kainz2009-scaling"


def _runs(**settings):
    profile = Profile(name="t", volume_size=16, image_size=24, warmup=0, repeat=1, experiments=[NAME],
                      settings={NAME: settings})
    return list(experiments.plan(profile).values())


def _evaluate(claim_id, rows):
    claim = next(c for c in Scaling.claims if c.id == claim_id)
    return claim.evaluate(pd.DataFrame(rows))


def _frames(seconds, *, spread=0.02, seed=0, stage="technique", n=9):
    """A stage's median and its ``n`` timed frames within ± ``spread`` of ``seconds``, as a run's columns."""
    values = seconds * (1 + spread * np.random.default_rng(seed).uniform(-1, 1, n))
    return {f"time_{stage}": float(np.median(values)), f"frames_{stage}": " ".join(f"{v:.6g}" for v in values)}


def test_scaling_plan_keeps_the_picture_and_the_clouds_across_counts():
    runs = _runs(counts=[1, 8, 50], small_size=8)
    tiled = {(r.tags["series"], r.tags["count"]): r for r in runs if r.backend == TILED}
    assert set(tiled) == {(s, n) for s in SERIES for n in (1, 8, 50)}
    one, fifty = tiled["clouds", 1].scene, tiled["clouds", 50].scene
    assert one["camera"] == fifty["camera"]  # the same pixels for every count
    assert fifty["volumes"][:1] == one["volumes"] and len(fifty["volumes"]) == 50
    assert tiled["clouds", 8].scene["volumes"] == fifty["volumes"][:8]  # cloud i is the same in every count
    assert "meshes" in tiled["clouds+mesh", 50].scene and tiled["clouds+256", 8].scene["volumes"][0]["name"] == "large"
    vtk = [r for r in runs if r.backend == VTK]
    assert vtk and all(r.tags["count"] <= VTK_MAX_VOLUMES and r.tags["series"] == "clouds" for r in vtk)
    for run in runs:
        assert (run.warmup, run.repeat) == ((0, 1) if run.backend == "reference" else (1, 5)), run.key
    # Truth runs exactly at the checked counts, and the timed runs there point at them.
    assert {r.tags["count"] for r in runs if r.backend == "reference"} == {1, 8, 50}
    with pytest.raises(InputError, match="counts"):
        _runs(counts=[1, 65])


def test_scaling_scene_builds_with_fifty_overlapping_clouds(tmp_path):
    run = next(r for r in _runs(counts=[50], small_size=8, series=["clouds"]) if r.backend == TILED)
    scene = build_scene(run.scene, cache_dir=tmp_path)
    assert len(scene.volumes) == 50 and len({v.name for v in scene.volumes}) == 50
    centres = np.array([v.world_corners().mean(axis=0) for v in scene.volumes])
    assert np.allclose(centres[0], 0) and np.abs(centres).max() <= CLOUD_SPREAD * 8 + 1e-9  # heavy overlap


def _scaling_rows(one, fifty, fifty_mesh, psnr=45.0, spread=0.02):
    rows = [{"series": "clouds", "count": 1, **_frames(one, spread=spread, seed=1), "count_samples": 1000},
            {"series": "clouds", "count": 50, **_frames(fifty, spread=spread, seed=2), "count_samples": 50000}]
    if fifty_mesh is not None:
        rows.append({"series": "clouds+mesh", "count": 50, **_frames(fifty_mesh, spread=spread, seed=3),
                     "count_samples": 50000})
    return [{**r, "config": TILED, "role": "test", "psnr": psnr, "checked": "yes",
             "scene": f"{r['series']}.n{r['count']:02d}"} for r in rows]


def test_scaling_claims():
    rows = _scaling_rows(0.010, 0.030, 0.039)
    for claim in ("flat-with-mesh", "flat-volumes", "accuracy"):
        assert _evaluate(claim, rows).holds is True, claim
    result = _evaluate("flat-with-mesh", rows)
    assert result.measured.startswith("×3.89 (95 % CI ×") and result.interval[1] <= 4
    assert "volume samples 50000 and 1000 (×50), so the time per sample ×0.0778" in result.detail
    rows[1]["psnr"] = 39.0  # one count below the floor is enough
    assert _evaluate("accuracy", rows).holds is False
    # A checked count whose comparison is missing is not left out of the worst PSNR: nothing is measured.
    rows[1]["psnr"] = float("nan")
    missing = _evaluate("accuracy", rows)
    assert missing.holds is None and "psnr missing in" in missing.detail
    # A count without a reference (not checked) has no PSNR by design.
    rows[1]["checked"] = "no"
    assert _evaluate("accuracy", rows).holds is True
    rows = _scaling_rows(0.010, 0.06, 0.2, psnr=38.0)
    for claim in ("flat-with-mesh", "flat-volumes", "accuracy"):
        assert _evaluate(claim, rows).holds is False, claim
    # Around the bound with frames this scattered, the interval cannot tell.
    result = _evaluate("flat-volumes", _scaling_rows(0.010, 0.040, None, spread=0.3))
    assert result.holds is None and result.inconclusive and result.interval[0] < 4 < result.interval[1]
    # Meshes refused (skipped): the headline target is not measured rather than failed.
    result = _evaluate("flat-with-mesh", _scaling_rows(0.01, 0.02, None))
    assert result.holds is None and not result.inconclusive


def test_scaling_times_the_compared_runs_together():
    runs = {r.id: r for r in Scaling().runs(Profile(name="t", settings={NAME: {
        "counts": [1, 8, TARGET_COUNT], "small_size": 8}}))}
    grouped = {key for key, run in runs.items() if run.interleave == GROUP}
    assert grouped == {f"clouds.n{n:02d}.{b}" for n in (1, 8, TARGET_COUNT) for b in ("tiled", PEEL)} | {
        f"clouds+mesh.n{TARGET_COUNT}.tiled"}
    assert all(runs[key].interleave is None for key in runs.keys() - grouped)  # VTK, the other series, truths


def test_scaling_growth_table_and_fit():
    rows = pd.DataFrame([{"series": "clouds", "config": c, "count": n, "time_ms": t * n + 1}
                         for c, t in ((TILED, 0.5), (VTK, 2.0)) for n in (1, 4, 8)])
    base = _one_cloud_ms(rows)
    assert list(base[rows.config == VTK]) == [3.0] * 3 and list(base[rows.config == TILED]) == [1.5] * 3
    tests = rows.assign(time_total=rows.time_ms / 1e3)
    sentence = _scaling_takeaways(tests)[0]
    assert "1 ms + 0.5 ms per added volume" in sentence and "R² 1" in sentence


def _growth(tiled, peel, spread=0.02):
    return [{"series": "clouds", "count": n, "config": c, "role": "test", **_frames(t, spread=spread, seed=n + 7 * i,
                                                                                      stage="total")}
            for i, (c, times) in enumerate(((TILED, tiled), (PEEL, peel))) for n, t in times.items()]


def test_peeling_grows_faster_claim():
    growth = _growth({1: 1.0, 8: 2.0, 32: 4.0}, {1: 0.5, 8: 3.0})
    result = _evaluate("peeling-grows-faster", growth)
    assert result.holds is True
    assert result.measured.startswith("peeling ×6.02, cl-tiled ×1.99 at N = 8: ×3.02 (95 % CI ×")
    assert _evaluate("peeling-grows-faster", _growth({1: 1.0, 8: 2.0}, {1: 0.5, 8: 0.8})).holds is False
    result = _evaluate("peeling-grows-faster", _growth({1: 1.0, 8: 2.0}, {1: 0.5, 8: 1.05}, spread=0.3))
    assert result.inconclusive and result.interval[0] < 1 < result.interval[1]
