"""``ropinski2005-edges`` (E8): where each case puts its lens, the claims on synthetic images, the page."""

from functools import partial

import numpy as np
import pandas as pd
import pytest

from core.errors import InputError
from pipeline import experiments
from pipeline.experiments.ropinski2005.edges import (CASES, CONFIGS, GRAZING_VIEW_HEIGHT, case_scene, coverage_holes,
                                                     grazing_size, toward_camera)
from reports import blocks
from reports.html import ReportContext
from reports.imageio import write_exr
import test_ropinski2005_table1 as shared

NAME = "ropinski2005-edges"

planned = partial(shared.planned, name=NAME)
evaluate = partial(shared.evaluate, NAME)
SIZE = 32


def cube(alpha=0.9, size=16):
    """A premultiplied image of the filled cube: grey at ``alpha`` over a square, empty around it."""
    image = np.zeros((size, size, 4), np.float32)
    image[4:12, 4:12] = (0.5 * alpha, 0.4 * alpha, 0.3 * alpha, alpha)
    return image


def rows_of(tmp_path, *, images=None, cases=("behind", "grazing"), hole_rays=None, psnr=45.0):
    """A truth row per case and a row per method; ``images[(case, method)]`` replaces the method's cube image."""
    images = images or {}
    hole_rays = {"behind": 120, **(hole_rays or {})}
    rows = []
    for case in cases:
        truth = tmp_path / f"{case}.truth.exr"
        write_exr(truth, cube())
        rows.append({"experiment": NAME, "status": "ok", "role": "truth", "case": case, "run": f"{case}.truth",
                     "view": "headline", "exr": str(truth), "png": "", "record": ""})
        for method in CONFIGS:
            path = tmp_path / f"{case}.{method}.exr"
            write_exr(path, images.get((case, method), cube()))
            rows.append({"experiment": NAME, "status": "ok", "role": "test", "case": case, "config": method,
                         "run": f"{case}.{method}", "view": "headline", "reference": f"{case}.truth",
                         "exr": str(path), "png": "", "record": "", "psnr": psnr, "max_error": 0.001,
                         "count_lens_rays": 0.0 if method not in ("per-sample", "per-sample-mask") else np.nan,
                         "count_rays": 64.0,
                         "count_hole_rays": hole_rays.get(case, 0) if method == "segments-stencil" else np.nan})
    return rows


# ------------------------------------------------------------------------------------------------ cases
@pytest.mark.parametrize("image", [48, 256])
def test_each_case_puts_its_lens_where_it_says(image):
    box = SIZE / 2  # the cube's half edge: the box is [-16, 16]³ in world units
    for case in CASES:
        spec, view = case_scene(case, image, size=SIZE)
        lens = spec["lenses"][0]
        assert spec["volumes"][0]["dataset"] == "seismic" and lens["appearance"]["opacity_scale"] == 0.2
        if case == "grazing":
            assert view["view"] == "axis" and lens["shape"] == "box"
            assert lens["center"] == [0.0, 0.0, pytest.approx(0.3 * SIZE)]  # from the top face, seen from above
            assert np.allclose(toward_camera(view), (0, 0, 1))
            assert spec["camera"] == {"view_height": pytest.approx(GRAZING_VIEW_HEIGHT * SIZE)}
            # The side faces lie on pixel centres: (k + ½) pixels from the picture's middle.
            pitch = GRAZING_VIEW_HEIGHT * SIZE / image
            half = lens["size"][0] / 2
            assert (half / pitch - 0.5) == pytest.approx(round(half / pitch - 0.5), abs=1e-4)
            assert lens["size"][0] == lens["size"][1] and lens["size"][2] == pytest.approx(0.6 * SIZE)
            continue
        center, radius = np.array(lens["center"]), lens["radius"]
        toward = toward_camera(view)
        along = center @ toward
        nearest = np.clip(center, -box, box)  # the box point nearest the sphere's centre
        meets = np.linalg.norm(center - nearest) < radius
        encloses = np.linalg.norm(np.abs(center) + box) < radius  # the farthest corner inside
        assert {"partly-front": meets and not encloses and along > 0,
                "partly-behind": meets and not encloses and along < 0,
                "in-front": not meets and along > radius,
                "behind": not meets and along < -radius,
                "enclosing-volume": encloses,
                "enclosing-camera": meets and not encloses}[case], case
        if case == "enclosing-camera":
            eye = spec["camera"]["distance"] * toward
            assert spec["camera"]["projection"] == "perspective" and np.linalg.norm(eye - center) < radius
        else:
            assert "camera" not in spec


def test_grazing_size_puts_the_faces_on_pixel_centres():
    for image in (48, 100, 256, 1024):
        pitch = GRAZING_VIEW_HEIGHT / image
        half = grazing_size(image) / 2
        assert half / pitch - 0.5 == pytest.approx(round(half / pitch - 0.5))
        assert abs(half - 0.25) <= pitch


def test_plan_at_each_scale():
    smoke = planned("smoke")
    assert len(smoke) == len(CASES) * (1 + len(CONFIGS))
    for run in smoke:
        case = run.tags["case"]
        if run.backend == "reference":
            assert run.id == f"{case}.truth" and run.interleave is None
            continue
        assert run.interleave == case and run.reference == f"{case}.truth" and run.repeat == 1 and run.warmup == 0
        assert run.options["opaque_threshold"] == 1.0 and len(run.views) == 1
        assert run.scene["width"] == 48
    assert {r.scene["width"] for r in planned("full")} == {512}
    two = planned("smoke", cases=["behind"], methods=["segments-stencil"])
    assert sorted(r.id for r in two) == ["behind.segments-stencil", "behind.truth"]
    with pytest.raises(InputError, match="unknown.*sideways"):
        planned("smoke", cases=["sideways"])


# ---------------------------------------------------------------------------------------------- claims
def test_coverage_holes():
    reference = cube()
    assert coverage_holes(reference, reference) == (0, 64)
    faint = cube(alpha=0.05)
    assert coverage_holes(reference, faint) == (64, 64)  # 0.05 < 10 % of 0.9
    assert coverage_holes(reference, cube(alpha=0.2)) == (0, 64)  # lighter, not a hole
    torn = reference.copy()
    torn[4:6, 4:12] = 0.0
    assert coverage_holes(reference, torn) == (16, 64)
    assert coverage_holes(cube(alpha=0.05), np.zeros_like(reference)) == (0, 0)  # nothing covered to lose


def test_no_holes_holds_and_fails(tmp_path):
    result = evaluate("no-holes", rows_of(tmp_path))
    assert result.holds is True and result.measured.startswith("0 hole pixels of 64 covered")
    torn = cube()
    torn[4:8, 4:12] = 0.0
    result = evaluate("no-holes", rows_of(tmp_path, images={("behind", "segments-stencil"): torn}))
    assert result.holds is False
    assert result.measured == "32 hole pixels of 64 covered (segments-stencil, behind)"
    assert "behind: 32, grazing: 0" in result.detail


def test_accuracy(tmp_path):
    assert evaluate("edges-accurate", rows_of(tmp_path)).holds is True
    rows = rows_of(tmp_path)
    rows[-1]["psnr"] = 38.0
    result = evaluate("edges-accurate", rows)
    assert result.holds is False and result.measured == "38 dB (frag-depth, grazing)"


def test_hole_closed(tmp_path):
    result = evaluate("hole-closed", rows_of(tmp_path))
    assert result.holds is True and result.measured == "120 rays without a region, 0 hole pixels"
    assert "behind: 120, grazing: 0" in result.detail
    assert evaluate("hole-closed", rows_of(tmp_path, hole_rays={"behind": 0})).holds is False
    torn = np.zeros((16, 16, 4), np.float32)
    assert evaluate("hole-closed", rows_of(tmp_path, images={("behind", "segments-stencil"): torn})).holds is False
    assert evaluate("hole-closed", rows_of(tmp_path, cases=("grazing",))).holds is None


# ------------------------------------------------------------------------------------------------ page
def test_the_page(tmp_path):
    torn = cube()
    torn[4:8, 4:12] = 0.0
    rows = pd.DataFrame(rows_of(tmp_path, images={("grazing", "fused"): torn}))
    report = tmp_path / "report"
    out = experiments.get(NAME).report(rows, ReportContext(report, tmp_path, NAME))
    table = next(b for b in out if isinstance(b, blocks.Table) and b.title.startswith("Each case")).frame
    assert len(table) == 2 * len(CONFIGS)
    fused = table[(table.case == "grazing") & (table.method == "fused")].iloc[0]
    assert fused["hole pixels"] == 32 and fused["covered pixels"] == 64
    stencil = table[(table.case == "behind") & (table.method == "segments-stencil")].iloc[0]
    assert stencil["hole rays (stencil)"] == 120 and stencil["hole pixels"] == 0
    galleries = [b for b in out if isinstance(b, blocks.Gallery)]
    assert [len(g.items) for g in galleries] == [2, 2 * len(CONFIGS)] and galleries[1].diff_scale == 0.1
    assert all(item.difference for item in galleries[1].items)
