"""lacroute1995-volpack: our shear-warp against VolPack, claims on synthetic tables."""

import numpy as np
import pandas as pd
import pytest

import renderers
from pipeline import experiments
from pipeline.collect import claims_table
from pipeline.experiments.kit.model import Profile
from reports import blocks
from reports.html import ReportContext
from test_lacroute1995_package import ROOT, _with_ours, evaluate, planned, timed, write

NAME = "lacroute1995-volpack"


def test_plan_times_every_configuration_of_a_scene_together():
    runs = [r for r in planned(NAME) if r.tags["role"] == "test"]
    assert {r.interleave for r in runs} == {r.tags["scene"] for r in runs} == {"brainsmall", "brain", "head"}
    assert all(r.interleave is None for r in planned(NAME) if r.tags["role"] == "truth")
    # Our octree mode is timed in every scene's group, beside VolPack's octree mode.
    octree = [r for r in runs if r.tags["config"] == "shearwarp-octree-1"]
    assert {r.interleave for r in octree} == {"brainsmall", "brain", "head"}
    assert all(r.options == {"workers": 1, "classification": "octree"} for r in octree)


def test_head_scene_is_the_ct_skull_with_volpack_classification(monkeypatch):
    head = {r.id: r for r in planned(NAME) if r.tags["scene"] == "head"}
    assert head["head.truth"].scene["volumes"] == [{"dataset": "ct_skull", "preset": "volpack", "size": 256}]
    assert head["head.truth"].scene["width"] == 512 and head["head.shearwarp-1"].reference == "head.truth"
    small = {r.id: r for r in planned(NAME, **{NAME: {"head_size": 24, "head_image_size": 32, "scenes": ["head"]}})}
    assert {r.tags["scene"] for r in small.values()} == {"head"}
    assert small["head.volpack-rle"].scene["volumes"][0]["size"] == 24 and small["head.volpack-rle"].scene["height"] == 32
    monkeypatch.setattr(renderers, "BACKENDS", _with_ours())
    smoke = [r for r in experiments.plan(Profile.load(ROOT / "config" / "smoke.yaml")).values() if r.experiment == NAME]
    assert smoke and all(r.scene["volumes"][0]["size"] == 32 and r.scene["width"] == 48 for r in smoke)


def _rows(tmp_path, base, near, ours=0.008, spread=0.0, *, octree=0.023, workers=2, frame=1.5):
    def row(config, technique, psnr, image, name, **extra):
        return {"scene": "s", "role": "test", "config": config, "psnr": psnr, "exr": write(tmp_path / f"{name}.exr", image),
                "run": name, **timed(technique, spread), **timed(technique * frame, spread, stage="total"), **extra}

    return [row("volpack-rle", 0.010, 40.0, base, "vp"), row("volpack-octree", 0.021, 39.0, base, "oct"),
            row("shearwarp-1", ours, 40.5, near, "sw", option_workers=1),
            row("shearwarp-all", 0.012, 40.5, near, "sw2", option_workers=workers),
            row("shearwarp-octree-1", octree, 39.5, near, "swo", option_workers=1, count_classified_on_the_fly=5000)]


def test_volpack_claims(tmp_path):
    base = np.zeros((8, 8, 4), np.float32)
    base[2:6, 2:6] = (0.5, 0.4, 0.3, 0.8)
    near = base.copy()
    near[3, 3, 0] += 0.004
    far = base.copy()
    far[2:6, 2:6, 0] = 0.0
    rows = _rows(tmp_path, base, near)
    assert evaluate(NAME, "speed-1-worker", rows).holds is True
    assert evaluate(NAME, "speed-all-cores", rows).holds is False
    assert evaluate(NAME, "images-agree", rows).holds is True
    assert evaluate(NAME, "accuracy-parity", rows).holds is True
    assert evaluate(NAME, "octree-vs-rle", rows).holds is True
    rows[2]["exr"] = write(tmp_path / "far.exr", far)
    assert evaluate(NAME, "images-agree", rows).holds is False
    missing = evaluate(NAME, "speed-1-worker", [r for r in rows if not r["config"].startswith("volpack")])
    assert missing.holds is None and "volpack-rle" in missing.detail
    assert evaluate(NAME, "beats-vtk-cpu", rows).holds is None  # no VTK run
    rows.append({"scene": "s", "role": "test", "config": "vtk-cpu-1", "psnr": 41.0, "run": "vtk",
                 "exr": write(tmp_path / "vtk.exr", base), **timed(0.030), **timed(0.031, stage="total")})
    beats = evaluate(NAME, "beats-vtk-cpu", rows)
    assert beats.holds is True and "VTK 30 ms" in beats.detail
    rows[-1].update(timed(0.004))
    assert evaluate(NAME, "beats-vtk-cpu", rows).holds is False


def test_speed_compares_the_technique_with_an_interval(tmp_path):
    image = np.zeros((4, 4, 4), np.float32)
    # The whole frames say ours is slower (×1.5 of 8 ms against 10 ms would not be); the kernels decide.
    rows = _rows(tmp_path, image, image, ours=0.0095)
    for row in rows:
        row["time_total"] = 0.02 if row["config"] == "shearwarp-1" else 0.01
    result = evaluate(NAME, "speed-1-worker", rows)
    assert result.holds is True and result.measured == "×0.95 (95 % CI ×0.95–×0.95) (s)"
    assert "technique ours 9.5 ms, VolPack 10 ms; whole frame ours 20 ms" in result.detail
    # Frames spread ±30 % around medians 5 % apart: the interval straddles 1.
    noisy = evaluate(NAME, "speed-1-worker", _rows(tmp_path, image, image, ours=0.0095, spread=0.3))
    assert noisy.holds is None and noisy.inconclusive and noisy.interval[0] < 1 < noisy.interval[1]
    slower = evaluate(NAME, "speed-1-worker", _rows(tmp_path, image, image, ours=0.02, spread=0.3))
    assert slower.holds is False and slower.interval[0] > 1


def test_a_starved_parallel_run_cannot_fail_the_all_cores_claim(tmp_path):
    image = np.zeros((4, 4, 4), np.float32)
    rows = _rows(tmp_path, image, image)
    starved = "2 workers had 1.0 free cores (other work used 1.00)"
    rows[3]["info_starved"] = starved
    result = evaluate(NAME, "speed-all-cores", rows)  # 12 ms against 10 ms, on one free core
    assert result.holds is None and result.inconclusive and starved in result.detail
    rows[3].update(timed(0.005))
    fast = evaluate(NAME, "speed-all-cores", rows)  # starving can only slow it: a pass stands
    assert fast.holds is True and starved in fast.detail


def _image():
    return np.zeros((4, 4, 4), np.float32)


@pytest.mark.parametrize("claim, config", [("speed-1-worker-frame", "shearwarp-1"),
                                           ("speed-all-cores-frame", "shearwarp-all")])
def test_whole_frame_claims_judge_the_whole_frames(tmp_path, claim, config):
    rows = _rows(tmp_path, _image(), _image(), ours=0.008)
    for row in rows:  # kernels: ours 8 and 12 ms against 10; whole frames: both ours 9 ms against 15
        row.update(timed(0.009 if row["config"] == config else row["time_technique"] * 1.5, stage="total"))
    result = evaluate(NAME, claim, rows)
    assert result.holds is True and result.measured == "×0.6 (95 % CI ×0.6–×0.6) (s)"
    assert "judged on the whole frame" in result.detail and "technique ours" in result.detail
    for row in rows:
        if row["config"] == config:
            row.update(timed(0.02, stage="total"))
    assert evaluate(NAME, claim, rows).holds is False
    for row in rows:  # medians 2 % under VolPack's, frames ±30 %: the interval straddles 1
        row.update(timed(0.0147 if row["config"] == config else 0.015, 0.3, stage="total")
                   if row["config"] in (config, "volpack-rle") else {})
    noisy = evaluate(NAME, claim, rows)
    assert noisy.holds is None and noisy.inconclusive and noisy.interval[0] < 1 < noisy.interval[1]


def test_octree_claim_compares_our_octree_mode_with_volpacks(tmp_path):
    held = evaluate(NAME, "octree-speed", _rows(tmp_path, _image(), _image(), octree=0.023))  # ×1.1 of 21 ms
    assert held.holds is True and held.measured.startswith("×1.1 (95 % CI") and held.measured.endswith("(s)")
    assert "VolPack 21 ms" in held.detail and "classified on the fly per frame: 5,000 (s)" in held.detail
    assert evaluate(NAME, "octree-speed", _rows(tmp_path, _image(), _image(), octree=0.030)).holds is False  # ×1.43
    noisy = evaluate(NAME, "octree-speed", _rows(tmp_path, _image(), _image(), octree=0.025, spread=0.3))
    assert noisy.holds is None and noisy.inconclusive and noisy.interval[0] < 1.2 < noisy.interval[1]
    missing = evaluate(NAME, "octree-speed", [r for r in _rows(tmp_path, _image(), _image())
                                              if r["config"] != "volpack-octree"])
    assert missing.holds is None and "volpack-octree" in missing.detail


def test_parallel_speed_up_is_judged_against_the_workers(tmp_path):
    def rows(one, most, workers=2, spread=0.0):
        out = _rows(tmp_path, _image(), _image(), ours=one, workers=workers)
        out[3].update(timed(most, spread))
        out[2].update(timed(one, spread))
        return out

    held = evaluate(NAME, "parallel-speed-up", rows(0.010, 0.005))  # ×2 on 2 workers ≥ ×1.8
    assert held.holds is True and held.measured == "×2 (95 % CI ×2–×2) (s, 2 workers)" and "bound ×1.8" in held.detail
    assert evaluate(NAME, "parallel-speed-up", rows(0.010, 0.0065)).holds is False  # ×1.54
    assert evaluate(NAME, "parallel-speed-up", rows(0.010, 0.0045, workers=4)).holds is False  # ×2.2 < ×3.6
    noisy = evaluate(NAME, "parallel-speed-up", rows(0.010, 0.0056, spread=0.3))  # ×1.79, frames ±30 %
    assert noisy.holds is None and noisy.inconclusive and noisy.interval[0] < 1.8 < noisy.interval[1]
    one_core = evaluate(NAME, "parallel-speed-up", rows(0.010, 0.010, workers=1))
    assert one_core.holds is None and not one_core.inconclusive and "1-core machine" in one_core.detail


def test_a_starved_all_cores_run_leaves_the_speed_up_inconclusive(tmp_path):
    starved = "2 workers had 1.0 free cores (other work used 1.00)"
    rows = _rows(tmp_path, _image(), _image(), ours=0.010)
    rows[3].update(timed(0.008), info_starved=starved)  # ×1.25 on 2 workers: fails, but on one free core
    result = evaluate(NAME, "parallel-speed-up", rows)
    assert result.holds is None and result.inconclusive and starved in result.detail
    rows[3].update(timed(0.005))  # ×2 anyway: starving can only slow it, the pass stands
    assert evaluate(NAME, "parallel-speed-up", rows).holds is True


def test_page_shows_each_mode_against_volpacks_and_where_the_time_goes(tmp_path):
    rows = _rows(tmp_path, _image(), _image())
    stages = {"opacity_table": 0.0005, "shade_table": 0.0005, "composite": 0.005, "warp": 0.002}
    for row in rows:
        row.update(status="ok", backend="volpack" if row["config"].startswith("volpack") else "shearwarp",
                   dataset="d", image_size=48, view="headline", png="", record="", time_total_min=0.01,
                   time_total_max=0.02)
        if row["backend"] == "volpack":
            row.update(time_shade=0.001, time_render=row["time_technique"] - 0.001, time_readback=0.002,
                       info_stage_timing="wall clock around the library calls", count_rle_bytes=1000)
        else:
            row.update({f"time_{k}": v for k, v in stages.items()}, count_samples=900)
    rows[-1].update(time_octree_runs=0.001, time_octree_classify=0.014, count_candidate_voxels=40000)
    rows[2].update(timed(0.009, stage="total"))  # ours, 1 worker: the whole frame ×0.6 of VolPack's, kernels ×0.8
    report = tmp_path / "report"
    claims = claims_table(pd.DataFrame(rows).assign(experiment=NAME), [experiments.get(NAME)])  # as tabulate judges
    out = experiments.get(NAME).report(pd.DataFrame(rows), ReportContext(report, tmp_path, NAME, claims=claims))
    tables = {b.title: b.frame for b in out if isinstance(b, blocks.Table)}
    modes = tables["Each mode of ours against VolPack's"].iloc[0]
    assert modes["VolPack RLE"] == "10 / 15 ms" and modes["ours, 1 worker"] == "8 / 9 ms (×0.8 / ×0.6)"
    assert modes["ours, octree"] == "23 / 34.5 ms (×1.1 / ×1.1)"  # against VolPack's octree mode, 21 ms
    stage = tables["s (d → 48²): where the time goes"].set_index("technique")
    ours = stage.loc["our shear-warp, 1 worker"]
    assert list(stage.columns) == ["octree runs", "octree classify", "opacity table", "shade table", "composite",
                                   "warp", "render call's work", "8-bit → float", "around the kernels", "whole frame",
                                   "record", "EXR"]  # the backend's technique stages, then VolPack's
    assert ours["composite"] == "5 (55.6 %)" and ours["render call's work"] == "7.5 (83.3 %)"
    assert ours["around the kernels"] == "1 (11.1 %)" and ours["octree classify"] == ""
    octree = stage.loc["our shear-warp, fast classification (octree), 1 worker"]
    assert octree["render call's work"] == "22.5 (65.2 %)"  # with the octree's runs and classification, as VolPack's
    vp = stage.loc["VolPack, classified RLE"]
    assert vp["render call's work"] == "9 (60 %)" and vp["shade table"] == "1 (6.67 %)"
    assert vp["8-bit → float"] == "2 (13.3 %)"
    assert vp["around the kernels"] == "3 (20 %)" and vp["composite"] == ""
    rle_only = experiments.get(NAME).report(pd.DataFrame([r for r in rows if "octree" not in r["config"]]),
                                            ReportContext(report, tmp_path, NAME))
    stage = next(b.frame for b in rle_only if isinstance(b, blocks.Table) and b.title.endswith("where the time goes"))
    assert "octree runs" not in stage and "opacity table" in stage  # no run of the scene has octree stages
    texts = " ".join(b.text for b in out if isinstance(b, blocks.Text))
    assert "without USE_TIMER" in texts
    counts = tables["The counts behind the times"]
    assert list(counts["samples composited"]) == ["900", "", "900", ""]  # VolPack counts no samples
    assert list(counts["RLE (MB)"]) == ["", "0.001", "", "0.001"]
    takeaways = next(b for b in out if isinstance(b, blocks.Takeaways)).sentences
    assert takeaways[0].startswith("Speed against VolPack (bound ×1 unless said): one worker, technique, against "
                                   "VolPack RLE: ×0.8 (95 % CI ×0.8–×0.8) (s), holds; one worker, whole frame: "
                                   "×0.6 (95 % CI ×0.6–×0.6) (s), holds; all cores, technique: ×1.2")
    assert "our octree mode against VolPack's, technique (bound ×1.2): ×1.1" in takeaways[0]
    assert "parallel speed-up, 1 worker / all cores (bound 0.9 × the workers): ×0.667 (95 % CI ×0.667–×0.667) (s, 2 workers)" in takeaways[0]
    octree_words = next(t for t in takeaways if "octree mode classifies 5,000 voxels" in t)
    assert "of the 40,000 its octree cannot rule out, and composites ×1 the samples of our RLE mode" in octree_words
    assert "its kernels take 15 ms more than our RLE mode's, 3 µs per voxel classified" in octree_words
    assert "VolPack's octree mode takes 11 ms more than its RLE mode" in octree_words


def test_the_theses_figures_are_judged_beside_ours(tmp_path):
    def rows(one, most, workers=2):
        out = _rows(tmp_path, _image(), _image(), ours=one, workers=workers)
        out[3].update(timed(most))
        out[2].update(timed(one))
        return out

    # Table 6.2 on 2 processors: ×2.0–2.12 over its two data sets.
    held = evaluate(NAME, "parallel-speed-up-paper", rows(0.010, 0.0049))  # ×2.04
    assert held.holds is True and "bound ×2–×2.12" in held.detail
    assert evaluate(NAME, "parallel-speed-up-paper", rows(0.010, 0.0055)).holds is False  # ×1.82: ours holds
    assert evaluate(NAME, "parallel-speed-up", rows(0.010, 0.0055)).holds is True
    missing = evaluate(NAME, "parallel-speed-up-paper", rows(0.010, 0.0035, workers=3))
    assert missing.holds is None and "no column for 3 processors" in missing.detail
    # Table 5.3: octree ×1.8–2.5 the RLE. VolPack's 21 ms against 10 ms holds; 30 ms holds only ours (×1.4–3.2).
    assert evaluate(NAME, "octree-vs-rle-paper", rows(0.008, 0.012)).holds is True
    slow = rows(0.008, 0.012)
    slow[1].update(timed(0.030))
    assert evaluate(NAME, "octree-vs-rle-paper", slow).holds is False
    assert evaluate(NAME, "octree-vs-rle", slow).holds is True
