"""``xue2005-table1``: what it plans at each scale, every claim on synthetic results, the paper's table.

Also the helpers ``test_xue2005_variants`` shares.
"""

import numpy as np
import pandas as pd
import pytest

import renderers
from core.errors import InputError
from pipeline import experiments
from pipeline.experiments import Profile
from pipeline.experiments.kit import intervals
from pipeline.experiments.xue2005 import table1 as T
from pipeline.experiments.xue2005.tables import REAL_SCANS, TABLE1
from reports.imageio import write_exr

NAME = "xue2005-table1"

NOISY = [1.0, 1.0, 3.0, 1.0, 3.0]
"""Frames whose resampled median is 1 or 3: against steady frames, a ratio whose interval spans ×1–×3."""


def profile(scale, name=NAME, **settings):
    return Profile(name="t", scale=scale, volume_size=16, image_size=24, warmup=0, repeat=1, experiments=[name],
                   settings={name: settings} if settings else {})


def planned(scale, name=NAME, **settings):
    return [r for r in experiments.plan(profile(scale, name, **settings)).values() if r.experiment == name]


def evaluate(experiment, claim_id, rows):
    """The result of claim ``claim_id`` of ``experiment`` on ``rows`` (dicts, as the successful rows)."""
    claim = next(c for c in experiments.get(experiment).claims if c.id == claim_id)
    return claim.evaluate(pd.DataFrame(rows))


def timed(seconds, *, group, **row):
    """A successful row whose whole frames took ``seconds`` (every timed frame), in interleave ``group``."""
    return {**row, "time_total": float(np.median(seconds)), "frames_total": intervals.format_frames(seconds),
            "interleave": group, "experiment": "x", "role": "test"}


def write(path, image):
    write_exr(str(path), np.asarray(image, np.float32))
    return str(path)


# ------------------------------------------------------------------------------------------------ plan
def test_plan_at_each_scale():
    smoke = planned("smoke")
    assert {r.tags["scene"] for r in smoke} == {"head", "aneurysm"}
    assert {len(r.views) for r in smoke} == {1} and smoke[0].views[0]["view"] == "headline"
    default = planned("default")
    assert {r.tags["scene"] for r in default} == set(TABLE1)
    for run in default:
        scene = run.tags["scene"]
        if run.backend == "reference":
            assert run.id == f"{scene}.truth" and (run.warmup, run.repeat) == (0, 1)
            assert run.options == {"step_factor": 1.0}  # the slices' own step (issue 23)
        elif run.backend == "gl-slicer":
            assert run.interleave is None and len(run.views) == 1 and run.reference == f"{scene}.truth"
        elif run.tags["config"] == "basic-across":  # Basic of every stand-in of one size, in one job
            assert run.interleave == "basic128" and run.options["zinit"] == "none" and len(run.views) == 1
            assert scene not in REAL_SCANS
        elif run.backend == "vtk-gpu":  # VTK with and without its depth pass, timed with the modes
            assert run.options == {"depth_pass": run.tags["config"] == "vtk-depth", "step_factor": 1.0}
            assert run.interleave == f"{scene}.vtk" and len(run.views) == 2 and run.tags["role"] == "peer"
        elif run.backend == "gl-raycast":  # the peer, timed with the modes
            assert run.options == {"variant": "rc-b", "step_factor": 1.0} and run.interleave == scene
            assert len(run.views) == 2 and run.tags["role"] == "peer"
        else:
            assert run.backend == "gl-isbvr" and run.interleave == scene and run.reference == f"{scene}.truth"
            assert run.options["step_factor"] == 1.0 and run.warmup >= 1 and run.repeat >= 3
            assert len(run.views) == 2 and run.views[0]["view"] == "headline"
    modes = {(r.tags["scene"], r.tags["config"], r.options["zinit"]) for r in default
             if r.backend == "gl-isbvr" and r.tags["role"] == "test"}
    assert modes == {(s, c, z) for s in TABLE1
                     for c, z in (("basic", "none"), ("ess", "ess"), ("ert", "ert"), ("ess+ert", "ess+ert"))}
    grids = {r.tags["scene"]: r.tags["grid"] for r in default}
    assert grids["head"] == grids["golden_lady"] == "128³" and grids["cthead"] == "cthead as scanned"
    assert "size" not in next(r for r in default if r.tags["scene"] == "bonsai_real").scene["volumes"][0]
    assert {len(r.views) for r in planned("full")} >= {9}


def test_unknown_scene_is_an_error():
    with pytest.raises(InputError, match="unknown.*engine"):
        planned("default", scenes=["engine"])


def test_no_runs_without_isbvr(monkeypatch):
    monkeypatch.setattr(renderers, "BACKENDS", {k: v for k, v in renderers.BACKENDS.items() if k != "gl-isbvr"})
    assert planned("default") == []
    assert "gl-isbvr" in " ".join(b.text for b in T.isbvr_not_measurable())


# ---------------------------------------------------------------------------------------------- speeds
PAPER_FPS = {scene: dict(zip(("basic", "ess", "ert", "ess+ert"), TABLE1[scene][3:])) for scene in ("aneurysm", "head")}


def mode_rows(fps, *, frames=lambda seconds, view: [seconds] * 5, views=("headline", "orbit000"), shaded=None,
              group=lambda scene: scene):
    """Rows of each scene and mode at ``fps`` (frames per second), with fragment counts ``shaded[config]`` of 1000."""
    return [timed(frames(1.0 / rate, view), group=group(scene), scene=scene, view=view, config=config,
                  run=f"{scene}.{config}", grid="128³", count_fragments=(shaded or {}).get(config, 1000),
                  count_fragments_generated=1000)
            for scene, rates in fps.items() for config, rate in rates.items() for view in views]


def faster(fps, factor):
    return {s: {c: rate * (1 if c == "basic" else factor) for c, rate in rates.items()} for s, rates in fps.items()}


def test_speed_claims_hold_on_the_papers_own_numbers_and_name_the_culled_share():
    rows = mode_rows(faster(PAPER_FPS, 1.002), shaded={"basic": 1000, "ess": 300, "ert": 700, "ess+ert": 250})
    for claim in ("combined-speedup", "ert-alone", "ess-alone"):
        assert evaluate(NAME, claim, rows).holds is True, claim
    result = evaluate(NAME, "combined-speedup", rows)
    assert result.measured.startswith("Basic / ESS+ERT ×3.") and result.margin == pytest.approx(0.002, abs=1e-6)
    assert "α' 0.75 (ideal ×4)" in result.detail and "whole frames (time_total)" in result.detail


def test_speed_claims_fail_below_the_papers_ratios():
    rows = mode_rows(faster(PAPER_FPS, 0.9))
    assert evaluate(NAME, "combined-speedup", rows).holds is False  # ×3.06 < ×3.40 on the aneurysm
    slow = mode_rows({"head": {"basic": 10.0, "ess": 12.0, "ert": 10.5, "ess+ert": 13.0}})
    for claim in ("combined-speedup", "ert-alone", "ess-alone"):
        assert evaluate(NAME, claim, slow).holds is False, claim
    too_fast = mode_rows({"head": {"basic": 10.0, "ess": 40.0, "ert": 20.0, "ess+ert": 50.0}})
    assert evaluate(NAME, "ert-alone", too_fast).holds is False  # ×2 is above the band, not in it
    assert evaluate(NAME, "ess-alone", too_fast).holds is False


def test_speed_claims_rest_on_intervals_of_interleaved_frames():
    fps = {"head": {"basic": 10.0, "ess+ert": 40.0}}  # ×4 ≥ ×3.33
    disturbed = mode_rows(fps, frames=lambda seconds, view: [seconds * t for t in NOISY])
    assert evaluate(NAME, "combined-speedup", disturbed).holds is True  # one round slowed both: paired, still ×4
    alone = evaluate(NAME, "combined-speedup", mode_rows(fps, frames=lambda seconds, view: (
        [seconds * t for t in NOISY] if seconds < 0.05 else [seconds] * 5), group=lambda scene: ""))
    assert alone.inconclusive and alone.interval[0] < TABLE1["head"][6] / 7.3 < alone.interval[1]


def test_the_claims_name_a_missing_count_or_mode():
    rows = mode_rows({"head": {"basic": 10.0, "ert": 13.0}})
    assert evaluate(NAME, "combined-speedup", rows).holds is None  # no ESS+ERT run
    for row in rows:
        del row["count_fragments_generated"]
    result = evaluate(NAME, "ert-alone", rows)
    assert result.holds is None and "count_fragments_generated" in result.detail


# ---------------------------------------------------------------------------------------------- Basic
def basic_rows(times, fragments, views=("headline", "orbit000"), across=None):
    """Basic's rows per scene (its own group), and Basic timed across the scenes in one group (headline view),
    in ``across`` seconds where given (default ``times``)."""
    across = across or times
    factors = (1.0, 1.01, 0.99, 1.0, 1.0)
    return ([timed([seconds * t for t in factors], group=scene, scene=scene, view=view, config="basic",
                   run=f"{scene}.basic", grid="128³", count_fragments=fragments[scene])
             for scene, seconds in times.items() for view in views] +
            [timed([seconds * t for t in factors], group="basic128", scene=scene, view="headline",
                   config="basic-across", run=f"{scene}.basic-across", grid="128³", count_fragments=fragments[scene])
             for scene, seconds in across.items()])


def test_basic_is_the_same_on_every_data_set():
    rows = basic_rows({"head": 0.100, "aneurysm": 0.104}, {"head": 5000, "aneurysm": 5000})
    assert evaluate(NAME, "basic-time", rows).holds is True
    assert "F head 5000 aneurysm 5000" in evaluate(NAME, "basic-time", rows).detail  # the work, beside the times
    rows = basic_rows({"head": 0.100, "aneurysm": 0.150}, {"head": 5000, "aneurysm": 5100})
    assert evaluate(NAME, "basic-time", rows).holds is False
    assert "head 100 ms aneurysm 150 ms" in evaluate(NAME, "basic-time", rows).detail
    # The times compared are those of the runs timed together, not the scenes' own jobs.
    rows = basic_rows({"head": 0.100, "aneurysm": 0.150}, {"head": 5000, "aneurysm": 5000},
                      across={"head": 0.100, "aneurysm": 0.101})
    assert evaluate(NAME, "basic-time", rows).holds is True


def test_the_papers_basic_spread_is_table1s_precision_beside_our_ten_percent():
    assert T.PAPER_BASIC_SPREAD == pytest.approx(7.35 / 7.25)
    claims = [c.id for c in experiments.get(NAME).claims]
    assert claims.index("basic-time-paper") + 1 == claims.index("basic-time")
    paper, ours = (next(c for c in experiments.get(NAME).claims if c.id == i)
                   for i in ("basic-time-paper", "basic-time"))
    assert paper.target == "paper" and ours.target == "ours" and paper.paper_value == ours.paper_value
    assert "×1.014" in paper.expected and paper.statement.endswith("(paper)")
    fragments = {"head": 5000, "aneurysm": 5000}
    within = basic_rows({"head": 0.100, "aneurysm": 0.101}, fragments)  # ×1.01: 7.3 fps on both, printed
    assert evaluate(NAME, "basic-time-paper", within).holds is True
    outside = basic_rows({"head": 0.100, "aneurysm": 0.104}, fragments)  # ×1.04: ours holds, the paper's does not
    assert evaluate(NAME, "basic-time-paper", outside).holds is False
    assert evaluate(NAME, "basic-time", outside).holds is True


def test_basic_compares_scenes_of_one_volume_size_only():
    rows = basic_rows({"head": 0.100, "cthead": 0.300}, {"head": 5000, "cthead": 9000})
    for row in rows:
        row["grid"] = "128³" if row["scene"] == "head" else "cthead as scanned"
        if row["scene"] == "cthead" and row["config"] == "basic-across":
            row["interleave"] = "cthead"  # a real scan is not timed across the stand-ins
    assert "fewer than two scenes" in evaluate(NAME, "basic-time", rows).detail
    rows += basic_rows({"aneurysm": 0.100}, {"aneurysm": 5000})
    assert evaluate(NAME, "basic-time", rows).holds is True


# --------------------------------------------------------------------------------------------- images
def image_rows(tmp_path, test_image, psnr=45.0):
    base = np.zeros((20, 20, 4), np.float32)
    base[4:16, 4:16] = (0.5, 0.4, 0.3, 0.9)
    rows = []
    for config, image in (("basic", base), ("ess+ert", test_image(base)), ("ert", base)):
        rows.append({"scene": "head", "view": "headline", "role": "test", "config": config, "psnr": psnr,
                     "exr": write(tmp_path / f"{config}.exr", image)})
    return rows


def test_lossless_needs_both_psnr_and_few_pixels_off(tmp_path):
    assert evaluate(NAME, "lossless", image_rows(tmp_path, lambda b: b)).holds is True

    def one_pixel(b):  # 1 of 400 pixels off by 0.02: PSNR 62 dB, but 0.25 % of pixels
        out = b.copy()
        out[5, 5, 0] += 0.02
        return out

    result = evaluate(NAME, "lossless", image_rows(tmp_path, one_pixel))
    assert result.holds is False and "0.25 % of pixels off" in result.measured
    assert evaluate(NAME, "lossless", image_rows(tmp_path, lambda b: b + np.float32(0.5 / 255))).holds is True
    # No pixel off by more than 1/255, but every one by 0.9/255: 49 dB.
    assert evaluate(NAME, "lossless", image_rows(tmp_path, lambda b: b + np.float32(0.9 / 255))).holds is False
    assert evaluate(NAME, "lossless", image_rows(tmp_path, lambda b: b * 0.9)).holds is False  # 26 dB


def test_accuracy_against_the_reference(tmp_path):
    rows = image_rows(tmp_path, lambda b: b)
    assert evaluate(NAME, "accuracy", rows).holds is True
    rows[1]["psnr"] = 35.0
    result = evaluate(NAME, "accuracy", rows)
    assert result.holds is False and result.measured == "35 dB (ess+ert, head, headline)"


# --------------------------------------------------------------------------------------------- counts
def test_culled_share_against_the_share_the_papers_speedup_needs():
    rows = mode_rows({"head": {"basic": 10.0, "ess+ert": 20.0}}, shaded={"ess+ert": 250})  # α' 0.75 ≥ 0.70
    assert evaluate(NAME, "culling-suffices", rows).holds is True
    rows = mode_rows({"head": {"basic": 10.0, "ess+ert": 20.0}}, shaded={"ess+ert": 400})  # α' 0.6
    result = evaluate(NAME, "culling-suffices", rows)
    assert result.holds is False and result.measured == "α' 0.6 against 0.7 needed (head)"


def test_paper_table_and_culling_table():
    table = experiments.get(NAME).paper_table()
    assert list(table["data set (paper)"]) == ["Aneurism", "Head", "Golden lady", "Bonsai"]
    bonsai = table[table["our stand-in"] == "bonsai"].iloc[0]
    assert bonsai["ESS+ERT / Basic"] == pytest.approx(3.808, abs=1e-3)
    assert bonsai["α' needed (γ → 0)"] == pytest.approx(1 - 7.3 / 27.8, abs=1e-3)
    tests = pd.DataFrame(mode_rows({"head": {"basic": 10.0, "ess": 20.0, "ert": 12.5, "ess+ert": 40.0}},
                                   shaded={"basic": 1000, "ess": 500, "ert": 800, "ess+ert": 250}))
    culling = T._culling_table(tests).set_index("mode")
    assert culling.loc["ESS+ERT", "α' ours"] == pytest.approx(0.75)
    assert culling.loc["ESS+ERT", "speed-up ours"] == pytest.approx(4.0)
    assert culling.loc["ESS+ERT", "1/(1 − α')"] == pytest.approx(4.0)
    ratios = T._ratio_table(tests).iloc[0]
    assert ratios["ERT (ours)"] == pytest.approx(1.25) and ratios["ERT (paper)"] == pytest.approx(1.59)
