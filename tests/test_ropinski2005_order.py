"""``ropinski2005-order`` (E9): its plan at each scale, its claims on synthetic frames and counts, its page."""

from functools import partial

import numpy as np
import pandas as pd
import pytest

from core.errors import InputError
from pipeline import experiments
from pipeline.experiments.kit import intervals
from pipeline.experiments.ropinski2005.order import FRONT_TO_BACK, OPAQUE_SCALE, SCENES, THRESHOLD
from reports import blocks
from reports.html import ReportContext
from reports.imageio import write_exr
import test_ropinski2005_table1 as shared
from test_ropinski2005_table1 import NOISY

NAME = "ropinski2005-order"

planned = partial(shared.planned, name=NAME)
evaluate = partial(shared.evaluate, NAME)


def rows_of(back=0.012, front=0.010, *, region0=(8000, 5000), difference=(0.03, 1e-7), scenes=("foot", "seismic"),
            noisy=False, group=True):
    """Both orders with early termination on and off per scene: times, region₀ samples (back, front) and
    max |front − back| (on, off)."""
    rows = []
    for scene in scenes:
        for termination, max_error in zip(("on", "off"), difference):
            suffix = "" if termination == "on" else ".all"
            for config, seconds, samples in (("segments", back, region0[0]), (FRONT_TO_BACK, front, region0[1])):
                factors = NOISY if noisy and config == FRONT_TO_BACK else [1.0] * 5
                frames = [seconds * f for f in factors]
                name = "back" if config == "segments" else "front"
                rows.append({"experiment": NAME, "status": "ok", "role": "test", "scene": scene, "view": "headline",
                             "run": f"{scene}.{name}{suffix}", "config": config, "termination": termination,
                             "interleave": scene if group else "", "time_total": float(np.median(frames)),
                             "frames_total": intervals.format_frames(frames), "time_total_min": min(frames),
                             "time_total_max": max(frames), "count_samples": samples + 3000,
                             "count_samples_region0": samples if termination == "on" else 8000,
                             "count_samples_region1": 1000, "count_samples_region2": 2000,
                             "reference": f"{scene}.back{suffix}" if config == FRONT_TO_BACK else np.nan,
                             "max_error": max_error if config == FRONT_TO_BACK else np.nan})
    return rows


# ------------------------------------------------------------------------------------------------ plan
def test_plan_at_each_scale():
    smoke = planned("smoke")
    assert len(smoke) == 4 * len(SCENES) and {r.interleave for r in smoke} == set(SCENES)
    runs = {r.id: r for r in smoke}
    for scene in SCENES:
        back, front = runs[f"{scene}.back"], runs[f"{scene}.front"]
        assert back.options["lens_method"] == front.options["lens_method"] == "segments"
        assert "region_order" not in back.options and front.options["region_order"] == "front-to-back"
        assert back.options["opaque_threshold"] == THRESHOLD and front.reference == back.id
        everything = runs[f"{scene}.front.all"]
        assert everything.options["opaque_threshold"] == 1.0 and everything.reference == f"{scene}.back.all"
        assert back.scene == front.scene == everything.scene and back.repeat >= 3
    foot = runs["foot.back"].scene["lenses"][0]["appearance"]
    assert foot["mode"] == "iso" and foot["transfer_function"]["points"][0][4] == 1.0
    assert runs["skull.back"].scene["lenses"][0]["appearance"] == {"mode": "dvr", "preset": "bone",
                                                                   "opacity_scale": OPAQUE_SCALE}
    assert runs["seismic.back"].scene["lenses"][0]["center"] == [0.0, 0.0, 0.0]
    assert {r.scene["width"] for r in planned("full")} == {1024}
    assert sorted(r.id for r in planned("smoke", scenes=["foot"])) == ["foot.back", "foot.back.all", "foot.front",
                                                                       "foot.front.all"]
    with pytest.raises(InputError, match="unknown.*engine"):
        planned("smoke", scenes=["engine"])


# ---------------------------------------------------------------------------------------------- claims
def test_front_to_back_faster():
    result = evaluate("front-to-back-faster", rows_of())
    assert result.holds is True
    assert result.measured == "time(back to front) / time(front to back) ×1.2 (95 % CI ×1.2–×1.2) (foot)"
    assert "region₀ samples 8e+03 back to front, 5e+03 front to back" in result.detail
    assert evaluate("front-to-back-faster", rows_of(front=0.013)).holds is False
    noisy = evaluate("front-to-back-faster", rows_of(front=0.0115, noisy=True, group=False))
    assert noisy.inconclusive and noisy.interval[0] < 1 < noisy.interval[1]


def test_front_to_back_samples():
    result = evaluate("front-to-back-samples", rows_of())
    assert result.holds is True and result.measured == "front to back takes 62.5 % of the region₀ samples (seismic)"
    assert evaluate("front-to-back-samples", rows_of(region0=(8000, 8000))).holds is False


def test_same_image_and_drops_only_terminated():
    rows = rows_of()
    assert evaluate("same-image", rows).holds is True
    result = evaluate("drops-only-terminated", rows)
    assert result.holds is True and result.measured == "0.03 (foot)"
    assert evaluate("same-image", rows_of(difference=(0.03, 1e-3))).holds is False
    assert evaluate("drops-only-terminated", rows_of(difference=(1 - THRESHOLD + 1e-3, 0.0))).holds is False
    unmeasured = pd.DataFrame(rows_of()).drop(columns="max_error")
    assert evaluate("same-image", unmeasured).holds is None


# ------------------------------------------------------------------------------------------------ page
def test_the_page(tmp_path):
    rows = pd.DataFrame(rows_of())
    for column in ("png", "record"):
        rows[column] = ""
    rows["exr"] = [str(tmp_path / f"{run}.exr") for run in rows.run]
    for path in rows.exr:
        write_exr(path, np.full((8, 8, 4), 0.5, np.float32))
    report = tmp_path / "report"
    out = experiments.get(NAME).report(rows, ReportContext(report, tmp_path, NAME))
    table = next(b for b in out if isinstance(b, blocks.Table) and b.title.startswith("Both orders")).frame
    assert len(table) == 4
    on = table[(table.scene == "foot") & (table["early termination"] == "on")].iloc[0]
    assert on["back / front"] == pytest.approx(1.2) and on["region0 samples, front"] == 5000
    assert on["max |front − back|"] == pytest.approx(0.03)
    gallery = next(b for b in out if isinstance(b, blocks.Gallery))
    assert len(gallery.items) == 4 and gallery.diff_scale == 0.1 and all(item.difference for item in gallery.items)
