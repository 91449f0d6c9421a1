"""volbench-speed-accuracy: the reference's trade-off claim and the scenes a profile names."""

import numpy as np
import pandas as pd
import pytest

import renderers
from core.errors import InputError
from pipeline import experiments
from pipeline.experiments import Profile
from pipeline.experiments.kit.intervals import format_frames
from pipeline.experiments.volbench.speed_accuracy import (SCENE_KINDS, SPEED_ACCURACY_SCENES, SpeedAccuracy,
                                                      _tradeoff)


def _sweep(times, errors, *, frames=5, spread=0.02, scene="s", kind="opaque"):
    """The reference's sweep on one scene, its steps timed together (``frames`` each, ``spread`` about the median)."""
    return pd.DataFrame([{"scene": scene, "kind": kind, "backend": "reference", "role": "sweep",
                          "setting": f"step_factor={f}",
                          "time_total": t, "rmse": e, "interleave": f"{scene}.reference", "view": "headline",
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


def test_the_tradeoff_reads_the_scenes_the_reference_integrates_not_its_exact_mip_and_iso():
    """The reference's MIP and iso-surface solve each cell exactly: their time does not follow the step, and their
    error is 0 at every step. Those scenes are no evidence either way."""
    doubling = _sweep((1.0, 2.0, 4.1), (0.1, 0.05, 0.02))
    exact = _sweep((1.0, 1.0, 1.0), (0.0, 0.0, 0.0), scene="m", kind="mip")
    both = _tradeoff(pd.concat([doubling, exact, _sweep((1.0, 1.0, 1.0), (0.0, 0.0, 0.0), scene="i", kind="iso")]))
    assert both.holds and both.value == pytest.approx(_tradeoff(doubling).value)
    assert SpeedAccuracy.claims[0].evaluate(exact).holds is None  # nothing left to judge: not measured


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


def test_every_setting_the_panel_ranks_is_timed_together_per_scene_with_five_frames_at_least():
    """The contenders' settings on a scene are one interleave group (the ranking claims), the reference's steps
    another (the trade-off claim), each timed in the profile's processes; a backend that lacks the scene's mode
    has one untimed run, skipped."""
    profile = Profile.load("config/default.yaml")
    runs = [run for run in experiments.plan(Profile(**{**profile.__dict__, "experiments": ["volbench-speed-accuracy"]})
                                            ).values() if run.tags.get("role") == "sweep"]
    for run in runs:
        mode = "dvr" if SCENE_KINDS[run.tags["scene"]] not in ("mip", "iso") else SCENE_KINDS[run.tags["scene"]]
        if mode not in renderers.backend_class(run.backend).capabilities.modes:
            assert run.interleave is None and run.replicates == 1
            continue
        group = "reference" if run.backend == "reference" else "contenders"
        assert run.interleave == f"{run.tags['scene']}.{group}"
        assert run.repeat * run.replicates >= 5 and run.replicates == profile.replicates
    contenders = [run for run in runs if run.interleave == "skull-bone.contenders"]
    assert {"vtk-gpu", "gl-raycast", "cl-tiled", "shearwarp"} <= {run.backend for run in contenders}


def _ranked(points, *, groups=None, frames=6, spread=0.02):
    """Sweep rows of scene ``skull-bone`` from ``[(backend, ms, dB)]``, timed together in one process (or in the
    named ``groups``)."""
    groups = groups or ["skull-bone.contenders"] * len(points)
    rows = []
    for index, ((backend, ms, psnr), group) in enumerate(zip(points, groups)):
        times = ms / 1e3 * (1 + spread * np.sin(np.arange(frames) + 2 * index))
        rows.append({"experiment": "volbench-speed-accuracy", "run": f"skull-bone.{backend}.0", "view": "headline",
                     "scene": "skull-bone", "kind": "opaque", "backend": backend, "role": "sweep",
                     "setting": "step_factor=1.0", "status": "ok", "reference": "skull-bone.truth",
                     "time_total": float(np.median(times)), "psnr": psnr, "interleave": group,
                     "frames_total": format_frames(times)})
    return pd.DataFrame(rows)


def _ranking_claim(scene="skull-bone"):
    return next(claim for claim in SpeedAccuracy.claims if claim.id == f"ranking-{scene}")


def test_the_ranking_claim_holds_where_the_fastest_is_clearly_faster_than_the_next_and_ties_otherwise():
    claim = _ranking_claim()
    clear = claim.evaluate(_ranked([("gl-raycast", 10, 44), ("cl-tiled", 25, 45), ("shearwarp", 1, 30)]))
    assert clear.holds is True and clear.value == pytest.approx(2.5, rel=0.01) and clear.interval[0] > 1
    assert clear.measured.startswith("cl-tiled (step 1 voxel) / gl-raycast (step 1 voxel): ×2.4")
    tie = claim.evaluate(_ranked([("gl-raycast", 10, 44), ("cl-tiled", 10.05, 45)], spread=0.2))
    assert tie.holds is None and tie.inconclusive and tie.interval[0] < 1 < tie.interval[1]


def test_a_ranking_with_nothing_to_compare_is_not_measured():
    claim = _ranking_claim()
    alone = claim.evaluate(_ranked([("gl-raycast", 10, 44), ("cl-tiled", 25, 35)]))
    assert alone.holds is None and not alone.inconclusive and "1 technique(s) reach 40 dB" in alone.detail
    apart = claim.evaluate(_ranked([("gl-raycast", 10, 44), ("cl-tiled", 25, 45)], groups=["a", "b"]))
    assert apart.holds is None and "timed in separate jobs" in apart.detail
    assert _ranking_claim("foot-iso").evaluate(_ranked([("gl-raycast", 10, 44), ("cl-tiled", 25, 45)])).holds is None


def _exact_and_sampled(exact_ms, exact_db, sampled_ms, sampled_db, *, frames=6):
    rows = []
    for index, (setting, ms, psnr) in enumerate((("step_factor=1.0", exact_ms, exact_db),
                                                 ("iso_hit=sampled,step_factor=0.25", sampled_ms, sampled_db))):
        times = ms / 1e3 * (1 + 0.02 * np.sin(np.arange(frames) + 2 * index))
        rows.append({"experiment": "volbench-speed-accuracy", "run": f"foot-iso.gl-raycast.{index}", "view": "headline",
                     "scene": "foot-iso", "kind": "iso", "backend": "gl-raycast", "role": "sweep", "setting": setting,
                     "status": "ok", "time_total": float(np.median(times)), "psnr": psnr,
                     "interleave": "foot-iso.contenders", "frames_total": format_frames(times),
                     "count_samples": (350264, 737312)[index], "count_crossings": 988,
                     "count_iso_cells_solved": (17152, np.nan)[index]})
    return pd.DataFrame(rows)


def test_the_exact_iso_claim_needs_the_exact_hit_faster_and_at_least_as_accurate():
    claim = next(c for c in SpeedAccuracy.claims if c.id == "exact-iso-beats-oversampling")
    holds = claim.evaluate(_exact_and_sampled(40, 52, 140, 27))
    assert holds.holds is True
    # The counts that do not depend on the machine beside the times.
    assert "3.5e+05 cells walked, 1.72e+04 cells solved, 988 crossings" in holds.detail
    assert "7.37e+05 samples, 988 crossings" in holds.detail
    assert claim.evaluate(_exact_and_sampled(200, 52, 140, 27)).holds is False  # slower
    less = claim.evaluate(_exact_and_sampled(40, 25, 140, 27))
    assert less.holds is False and "less accurate" in less.detail
    assert claim.evaluate(_exact_and_sampled(40, 52, 140, 27).iloc[:1]).holds is None  # nothing to compare with


def test_the_iso_scene_sweeps_the_sampled_hit_and_the_others_do_not():
    profile = Profile.load("config/default.yaml")
    runs = [run for run in experiments.plan(Profile(**{**profile.__dict__, "experiments": ["volbench-speed-accuracy"]})
                                            ).values() if run.backend == "gl-raycast"]
    settings = {scene: {run.tags["setting"] for run in runs if run.tags["scene"] == scene} for scene in SCENE_KINDS}
    assert {"step_factor=1.0", "iso_hit=sampled,iso_refine=0", "iso_hit=sampled,step_factor=0.25"} <= settings["foot-iso"]
    assert not any("iso" in setting for scene in ("skull-bone", "engine-semi", "skull-mip")
                   for setting in settings[scene])
