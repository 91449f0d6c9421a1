"""``ropinski2005-methods`` (E4): its plan at each scale, its claims on synthetic frames and counts, its page."""

from functools import partial

import numpy as np
import pandas as pd
import pytest

from core.errors import InputError
from pipeline import experiments
from pipeline.experiments.kit import intervals
from pipeline.experiments.ropinski2005.methods_compared import CONFIGS, OCCLUDED, TABLE1_SCENES, TRANSPARENCY
from reports import blocks
from reports.html import ReportContext
import test_ropinski2005_table1 as shared
from test_ropinski2005_table1 import NOISY

NAME = "ropinski2005-methods"

planned = partial(shared.planned, name=NAME)
evaluate = partial(shared.evaluate, NAME)

"""Frame factors whose resampled median is 1 or 3: unpaired, a ratio whose interval spans ×1/3–×3."""


def rows_of(times, *, occluded=None, shaded=None, scenes=("seismic", "foot"), image=256, noisy=(), group=True):
    """Rows per scene and method: ``times[config]`` seconds (``occluded[config]`` behind the occluder).

    ``shaded[(config, occluded)]`` fragments shaded (default: 2000 for segments, 1000 for the others, half
    of it behind the occluder); 1000 rays, 500 of them occluded. Configs in ``noisy`` get noisy frames.
    """
    shaded = shaded or {}
    rows = []
    for scene in scenes:
        for flag, table in (("no", times), ("yes", occluded or {})):
            for config, seconds in table.items():
                frames = [seconds * f for f in (NOISY if config in noisy else [1.0] * 5)]
                base = 2000 if config == "segments" else 1000
                count = shaded.get((config, flag), base if flag == "no" else base / 2)
                rows.append({"experiment": NAME, "status": "ok", "role": "test", "scene": scene, "view": "headline",
                             "config": config, "occluded": flag, "image_size": float(image),
                             "run": f"{scene}.{config}" + (".occluded" if flag == "yes" else ""),
                             "interleave": scene if group else "", "reference": f"{scene}.truth",
                             "time_total": float(np.median(frames)), "frames_total": intervals.format_frames(frames),
                             "time_total_min": min(frames), "time_total_max": max(frames),
                             "count_fragments_shaded": count, "count_rays": 1000 if flag == "no" else 500,
                             "count_rays_occluded": 500 if flag == "yes" else np.nan, "count_samples": 50000,
                             "count_lens_rays": 150 if config != "per-sample" else np.nan, "psnr": 45.0})
    return rows


OPEN = {"segments": 0.010, "segments-stencil": 0.011, "fused": 0.009, "per-sample": 0.012, "per-sample-mask": 0.013,
        "frag-depth": 0.012}
BEHIND = {"segments": 0.005, "per-sample": 0.006, "frag-depth": 0.012}


# ------------------------------------------------------------------------------------------------ plan
def test_plan_at_each_scale():
    smoke = planned("smoke")
    per_scene = len(CONFIGS) + len(OCCLUDED) + 1
    assert len(smoke) == per_scene * len(TABLE1_SCENES)
    assert {r.tags["scene"] for r in smoke} == set(TABLE1_SCENES) == {"seismic", "skull", "foot", "cthead"}
    for run in smoke:
        scene = run.tags["scene"]
        if run.tags["role"] == "truth":
            assert run.id == f"{scene}.truth" and run.backend == "reference" and run.interleave is None
            continue
        assert run.interleave == scene and run.backend == "gl-raycast" and run.repeat >= 3
        assert run.scene["width"] == 48 and run.scene["volumes"][0].get("size", 32) == 32
        if run.tags["occluded"] == "yes":
            assert run.options["occluder"] == 0.5 and run.reference is None and run.tags["config"] in OCCLUDED
        else:
            assert "occluder" not in run.options and run.reference == f"{scene}.truth"
    foot = next(r for r in smoke if r.id == "foot.per-sample")
    assert foot.scene["lenses"][0]["appearance"] == {"mode": "dvr", "preset": "skin_bone",
                                                      "opacity_scale": TRANSPARENCY}
    assert next(r for r in smoke if r.id == "seismic.per-sample").scene["lenses"][0]["appearance"] == {"mode": "clip"}
    full = planned("full")
    assert {r.scene["width"] for r in full} == {1024} and {len(r.views) for r in full} == {3}
    only = planned("default", methods=["segments", "frag-depth"], scenes=["skull"], occluder=0.25)
    assert sorted(r.id for r in only) == ["skull.frag-depth", "skull.frag-depth.occluded", "skull.segments",
                                          "skull.segments.occluded", "skull.truth"]
    assert {r.options.get("occluder") for r in only if r.tags.get("occluded") == "yes"} == {0.25}
    with pytest.raises(InputError, match="unknown.*per-voxel"):
        planned("smoke", methods=["per-voxel"])


# ---------------------------------------------------------------------------------------------- claims
def test_segments_faster_holds_and_fails():
    rows = rows_of(OPEN, occluded=BEHIND)
    result = evaluate("segments-faster", rows)
    assert result.holds is True
    # The closest baseline decides: frag-depth and per-sample at ×1.2, the first one found is named.
    assert result.measured.startswith("time(baseline) / time(segments) at 256² ×1.2 (95 % CI ×1.2–×1.2)")
    assert "foot, per-sample-mask: ×1.3" in result.detail
    assert "fragments shaded 1e+03 against 2e+03" in result.detail
    assert evaluate("segments-faster-occluded", rows).holds is True
    slow = rows_of({**OPEN, "per-sample-mask": 0.008}, occluded={**BEHIND, "frag-depth": 0.004})
    result = evaluate("segments-faster", slow)
    assert result.holds is False and "(seismic, per-sample-mask)" in result.measured
    assert evaluate("segments-faster-occluded", slow).holds is False
    # fused and the stencil sequence are not judged: slower than segments, the claim still holds.
    assert evaluate("segments-faster", rows_of({**OPEN, "fused": 0.02, "segments-stencil": 0.03})).holds is True


def test_segments_faster_is_inconclusive_across_the_bound_and_paired_when_interleaved():
    close = {**OPEN, "frag-depth": 0.0105}
    unpaired = evaluate("segments-faster", rows_of(close, noisy=("segments",), group=False))
    assert unpaired.inconclusive and unpaired.interval[0] < 1.0 < unpaired.interval[1]
    paired = evaluate("segments-faster", rows_of(close, noisy=tuple(OPEN)))  # one slow round slows every method
    assert paired.holds is True


def test_segments_faster_reads_the_largest_image_only():
    rows = rows_of(OPEN) + rows_of({**OPEN, "per-sample": 0.005}, image=128)
    assert evaluate("segments-faster", rows).holds is True
    assert evaluate("segments-faster", rows_of({**OPEN, "per-sample": 0.005}, image=512) + rows).holds is False


def test_earlyz_fragments():
    rows = rows_of(OPEN, occluded=BEHIND, shaded={("frag-depth", "yes"): 1000})
    result = evaluate("earlyz-fragments", rows)
    assert result.holds is True
    # segments: 2000 − 1000 fragments dropped for 500 covered rays (its region passes drop theirs too).
    assert result.measured == "fragments dropped per covered ray: segments ×2, frag-depth ×0 (seismic)"
    # frag-depth dropping fragments (early-z on) or segments dropping fewer than the covered rays both fail.
    assert evaluate("earlyz-fragments", rows_of(OPEN, occluded=BEHIND)).holds is False
    kept = rows_of(OPEN, occluded=BEHIND, shaded={("frag-depth", "yes"): 1000, ("segments", "yes"): 1600})
    result = evaluate("earlyz-fragments", kept)
    assert result.holds is False and "segments ×0.8" in result.measured


def test_earlyz_time():
    rows = rows_of(OPEN, occluded=BEHIND)  # frag-depth ×1 behind the occluder, segments ×0.5
    result = evaluate("earlyz-time", rows)
    assert result.holds is True and result.measured.startswith("frag-depth's saving / segments' saving ×2")
    assert "with / without the occluder: frag-depth ×1, segments ×0.5" in result.detail
    saving = rows_of(OPEN, occluded={**BEHIND, "frag-depth": 0.004})  # frag-depth ×0.333: saves more
    assert evaluate("earlyz-time", saving).holds is False


def test_claims_without_their_runs_are_not_measured():
    assert evaluate("segments-faster", rows_of({"segments": 0.01, "per-sample": 0.02})).holds is None
    result = evaluate("earlyz-time", rows_of(OPEN))
    assert result.holds is None and "no successful" in result.detail


# ------------------------------------------------------------------------------------------------ page
def test_the_page(tmp_path):
    rows = pd.DataFrame(rows_of(OPEN, occluded=BEHIND, shaded={("frag-depth", "yes"): 1000}))
    for column in ("png", "exr", "record"):
        rows[column] = ""
    report = tmp_path / "report"
    out = experiments.get(NAME).report(rows, ReportContext(report, tmp_path, NAME))
    takeaways = next(b for b in out if isinstance(b, blocks.Takeaways))
    assert any(s.startswith("Fused (one pass") and "seismic ×0.9 (95 % CI ×0.9–×0.9)" in s
               for s in takeaways.sentences)
    table = next(b for b in out if isinstance(b, blocks.Table) and b.title.startswith("Every lens method")).frame
    mask = table[(table.scene == "foot") & (table.method == "per-sample-mask")].iloc[0]
    assert mask["time / segments"] == pytest.approx(1.3) and mask["PSNR (dB)"] == 45
    behind = next(b for b in out if isinstance(b, blocks.Table) and b.title.startswith("Behind the occluder")).frame
    depth = behind[(behind.scene == "seismic") & (behind.method == "frag-depth")].iloc[0]
    assert depth["time with / without (%)"] == 100 and depth["fragments shaded with / without (%)"] == 100
    assert depth["rays covered (%)"] == 50
    figures = [b for b in out if isinstance(b, blocks.Figure)]
    assert len(figures) == 2 and all("no data" not in (report / f.path).read_text() for f in figures)
    gallery = next(b for b in out if isinstance(b, blocks.Gallery))
    assert len(gallery.items) == 2 * len(OPEN) and gallery.diff_scale == 0.1
    assert any(isinstance(b, blocks.Text) and "the foot scene's own iso lens" in b.text for b in out)
