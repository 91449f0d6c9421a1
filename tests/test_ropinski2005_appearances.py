"""``ropinski2005-appearance`` (E6): its plan at each scale, its claims on synthetic frames and counts, its page."""

from functools import partial

import numpy as np
import pandas as pd
import pytest

from core.errors import InputError
from pipeline import experiments
from pipeline.experiments.kit import intervals
from pipeline.experiments.ropinski2005.appearances import APPEARANCES, EXPOSED, ISOVALUES, appearance_entry
from pipeline.experiments.ropinski2005.scenes import SETUPS
from reports import blocks
from reports.html import ReportContext
import test_ropinski2005_table1 as shared
from test_ropinski2005_table1 import NOISY

NAME = "ropinski2005-appearance"

planned = partial(shared.planned, name=NAME)
evaluate = partial(shared.evaluate, NAME)


TIMES = {"clip": 0.010, "transparency": 0.013, "iso": 0.012, "mip": 0.011}
REGION1 = {"clip": 0, "transparency": 3000, "iso": 2000, "mip": 3200}
REGION0 = {"clip": 9000, "iso": 7000}


def rows_of(times=TIMES, *, region1=REGION1, region0=REGION0, scenes=("seismic", "foot"), noisy=(), group=True):
    """Per scene: the lens-off row, a segments row per appearance and fused rows for the clip and iso lenses."""
    rows = []
    for scene in scenes:
        entries = [("off", "none", 0.009, {})]
        entries += [("segments", a, t, {"count_samples_region0": 10000, "count_samples_region1": region1[a],
                                        "count_samples_region2": 500}) for a, t in times.items()]
        entries += [("fused", a, times[a] * 0.9, {"count_samples_region0": region0[a],
                                                  "count_samples_region1": region1[a], "count_samples_region2": 500})
                    for a in EXPOSED if a in times]
        for config, appearance, seconds, counts in entries:
            frames = [seconds * f for f in (NOISY if (config, appearance) in noisy else [1.0] * 5)]
            rows.append({"experiment": NAME, "status": "ok", "role": "test", "scene": scene, "view": "headline",
                         "run": f"{scene}.{appearance}.{config}", "config": config, "appearance": appearance,
                         "interleave": scene if group else "", "time_total": float(np.median(frames)),
                         "frames_total": intervals.format_frames(frames), "time_total_min": min(frames),
                         "time_total_max": max(frames), "time_region1": 0.001 if appearance != "clip" else 0.0,
                         "count_samples": 10500 + counts.get("count_samples_region1", 0), "count_rays": 1000,
                         "count_lens_rays": 200 if config != "off" else np.nan, **counts})
    return rows


# ------------------------------------------------------------------------------------------------ plan
def test_plan_at_each_scale():
    smoke = planned("smoke")
    assert {r.tags["scene"] for r in smoke} == {"seismic", "skull", "foot"}
    per_scene = 1 + len(APPEARANCES) + len(EXPOSED)
    assert len(smoke) == 3 * per_scene and {r.interleave for r in smoke} == {"seismic", "skull", "foot"}
    foot = {r.id: r for r in smoke if r.tags["scene"] == "foot"}
    assert sorted(foot) == ["foot.clip.fused", "foot.clip.segments", "foot.iso.fused", "foot.iso.segments",
                            "foot.mip.segments", "foot.off", "foot.transparency.segments"]
    assert "lenses" not in foot["foot.off"].scene
    assert foot["foot.iso.fused"].options["lens_method"] == "fused"
    assert foot["foot.iso.segments"].scene["lenses"][0]["appearance"] == {"mode": "iso",
                                                                          "isovalue": ISOVALUES["foot"]}
    assert foot["foot.transparency.segments"].scene["lenses"][0]["appearance"] == {
        "mode": "dvr", "preset": "skin_bone", "opacity_scale": 0.2}
    # Only the appearance changes: the lens keeps its shape and place.
    lenses = [r.scene["lenses"][0] for r in foot.values() if "lenses" in r.scene]
    assert len({(tuple(lens["center"]), lens["radius"]) for lens in lenses}) == 1
    assert all(r.repeat >= 3 and r.backend == "gl-raycast" for r in smoke)
    assert {r.tags["scene"] for r in planned("full")} == set(SETUPS)
    assert set(ISOVALUES) == set(SETUPS)
    assert appearance_entry("engine", "clip") == {"mode": "clip"}
    assert appearance_entry("skull", "mip") == {"mode": "mip"}
    two = planned("smoke", scenes=["skull"], appearances=["clip", "mip"])
    assert sorted(r.id for r in two) == ["skull.clip.fused", "skull.clip.segments", "skull.mip.segments", "skull.off"]
    with pytest.raises(InputError, match="unknown.*highlight"):
        planned("smoke", appearances=["highlight"])


# ---------------------------------------------------------------------------------------------- claims
def test_clip_cheapest():
    result = evaluate("clip-cheapest", rows_of())
    assert result.holds is True
    assert result.measured.startswith("time(appearance) / time(clip) ×1.1 (95 % CI ×1.1–×1.1) (seismic, mip)")
    assert "foot, transparency: ×1.3" in result.detail and "region₁ samples 3e+03 against 0" in result.detail
    result = evaluate("clip-cheapest", rows_of({**TIMES, "iso": 0.008}))
    assert result.holds is False and "(seismic, iso)" in result.measured
    assert evaluate("clip-cheapest", rows_of({**TIMES, "mip": 0.0095})).holds is False  # ×0.95: just below ×1
    noisy = evaluate("clip-cheapest", rows_of({**TIMES, "mip": 0.0101}, noisy=(("segments", "clip"),), group=False))
    assert noisy.inconclusive


def test_iso_stops():
    result = evaluate("iso-stops", rows_of())
    assert result.holds is True and result.measured == "66.7 % (seismic)"
    assert "foot: iso 2e+03, transparency 3e+03 region₁ samples" in result.detail
    assert evaluate("iso-stops", rows_of(region1={**REGION1, "iso": 3000})).holds is False


def test_clip_exposes():
    result = evaluate("clip-exposes", rows_of())
    assert result.holds is True and result.measured == "×1.29 (foot)"
    assert "the fused method" in result.detail
    assert evaluate("clip-exposes", rows_of(region0={"clip": 7000, "iso": 7000})).holds is False


def test_claims_need_their_appearances():
    rows = rows_of({"clip": 0.01, "mip": 0.011})
    assert evaluate("iso-stops", rows).holds is None
    assert evaluate("clip-exposes", rows).holds is None
    assert evaluate("clip-cheapest", rows).holds is True  # the appearances that were rendered


# ------------------------------------------------------------------------------------------------ page
def test_the_page(tmp_path):
    rows = pd.DataFrame(rows_of())
    for column in ("png", "exr", "record"):
        rows[column] = ""
    report = tmp_path / "report"
    out = experiments.get(NAME).report(rows, ReportContext(report, tmp_path, NAME))
    takeaways = next(b for b in out if isinstance(b, blocks.Takeaways))
    assert any(s.startswith("Overhead of each lens appearance on the foot (segments): clip 11.1 % (95 % CI "
                            "11.1–11.1 %)") for s in takeaways.sentences)
    table = next(b for b in out if isinstance(b, blocks.Table) and b.title.startswith("Each appearance")).frame
    assert len(table) == 2 * (len(APPEARANCES) + len(EXPOSED))
    iso = table[(table.scene == "seismic") & (table.appearance == "iso") & (table.method == "segments")].iloc[0]
    assert iso["overhead (%)"] == pytest.approx(100 * (0.012 / 0.009 - 1), abs=1e-3)
    assert iso["region1 samples"] == 2000 and iso["rays through the lens (%)"] == 20
    figures = [b for b in out if isinstance(b, blocks.Figure)]
    assert len(figures) == 2 and all("no data" not in (report / f.path).read_text() for f in figures)
    gallery = next(b for b in out if isinstance(b, blocks.Gallery))
    assert len(gallery.items) == 2 * (1 + len(APPEARANCES))
