"""``ropinski2005-correctness`` (E7): its plan, the accuracy and seam claims on synthetic rows, the page with images."""

import numpy as np
import pandas as pd
import pytest

from pipeline import experiments
from pipeline.experiments.kit.pages import DIFF_SCALE
from pipeline.experiments.ropinski2005 import correctness as C
from pipeline.experiments.ropinski2005.methods import METHODS
from pipeline.experiments.ropinski2005.scenes import SETUPS
from reports import blocks
from reports.html import ReportContext
from reports.imageio import write_exr
from test_ropinski2005_table1 import evaluate, planned

NAME = "ropinski2005-correctness"


def image_rows(tmp_path, *, psnr=None, seam=0.0, scene="foot"):
    """A scene's runs: reference, lens-off and, per method, the lens image and the outside-appearance image.

    ``psnr`` maps a method to its PSNR against the reference (default 50 dB); the outside-appearance images
    differ from the lens-off image by ``seam`` in one pixel.
    """
    base = np.zeros((12, 12, 4), np.float32)
    base[3:9, 3:9] = (0.5, 0.4, 0.3, 0.9)
    psnr = psnr or {}

    def exr(name, image):
        path = tmp_path / f"{scene}.{name}.exr"
        write_exr(str(path), image)
        return str(path)

    def row(run, config, role, appearance, reference, image, **metrics):
        return {"experiment": "x", "status": "ok", "scene": scene, "view": "headline", "run": run, "config": config,
                "role": role, "appearance": appearance, "reference": reference, "exr": exr(run, image), "png": "",
                "record": "", **metrics}

    seamed = base.copy()
    seamed[4, 4, 0] += seam
    rows = [row(f"{scene}.truth", "reference", "truth", "lens", "", base),
            row(f"{scene}.truth.off", "reference", "truth", "none", "", base),
            row(f"{scene}.truth.outside", "reference", "truth", "outside", f"{scene}.truth.off", base, max_error=0.0),
            row(f"{scene}.off", "off", "control", "none", f"{scene}.truth.off", base, psnr=60.0)]
    for method in ("segments", "fused"):
        rows.append(row(f"{scene}.{method}", method, "test", "lens", f"{scene}.truth", base,
                        psnr=psnr.get(method, 50.0)))
        rows.append(row(f"{scene}.{method}.outside", method, "control", "outside", f"{scene}.off", seamed,
                        max_error=seam if method == "segments" else 0.0))
    return rows


def test_plan():
    smoke = planned("smoke", NAME)
    configs = [c for c in METHODS if c != "segments-ftb"]
    assert len(smoke) == len(SETUPS) * (4 + 2 * len(configs))
    runs = {r.id: r for r in smoke if r.tags["scene"] == "skull"}
    assert {r.interleave for r in runs.values()} == {"skull"} and all(r.repeat == 1 and r.warmup == 0
                                                                      for r in runs.values())
    truth, off, outside = runs["skull.truth"], runs["skull.truth.off"], runs["skull.truth.outside"]
    assert truth.backend == off.backend == outside.backend == "reference"
    assert truth.options == {"step_factor": 0.5} and truth.tags["appearance"] == "lens" and "lenses" in truth.scene
    assert "lenses" not in off.scene and outside.reference == "skull.truth.off"
    assert runs["skull.off"].reference == "skull.truth.off" and "lenses" not in runs["skull.off"].scene
    for config in configs:
        lens, control = runs[f"skull.{config}"], runs[f"skull.{config}.outside"]
        assert lens.reference == "skull.truth" and control.reference == "skull.off"
        assert lens.options["opaque_threshold"] == control.options["opaque_threshold"] == 1.0
        assert control.scene["lenses"][0]["appearance"] == {"mode": "dvr", "preset": "bone"}
    assert {r.scene["height"] for r in planned("default", NAME)} == {256}


def test_accuracy_per_scene(tmp_path):
    rows = image_rows(tmp_path)
    result = evaluate(NAME, "accuracy-foot", rows)
    assert result.holds is True and result.measured == "50 dB (segments, headline)"
    low = evaluate(NAME, "accuracy-foot", image_rows(tmp_path, psnr={"fused": 39.0}))
    assert low.holds is False and low.measured == "39 dB (fused, headline)" and "segments: 50 dB" in low.detail
    assert evaluate(NAME, "accuracy-seismic", rows).holds is None  # no seismic run


def test_no_seams(tmp_path):
    assert evaluate(NAME, "no-seams", image_rows(tmp_path, seam=5e-6)).holds is True
    result = evaluate(NAME, "no-seams", image_rows(tmp_path, seam=2e-5))
    assert result.holds is False and result.measured == "2e-05 (segments, foot, headline)"
    assert "reference: ≤ 0" in result.detail


def test_the_page(tmp_path):
    rows = pd.DataFrame(image_rows(tmp_path, psnr={"fused": 45.0}, seam=0.05) +
                        image_rows(tmp_path, scene="engine"))
    report = tmp_path / "report"
    out = experiments.get(NAME).report(rows, ReportContext(report, tmp_path, NAME))
    table = next(b for b in out if isinstance(b, blocks.Table) and b.title.startswith("PSNR")).frame.set_index("scene")
    assert table.loc["foot", "no lens"] == 60.0 and table.loc["foot", C.method_name("fused")] == 45.0
    galleries = [b for b in out if isinstance(b, blocks.Gallery)]
    assert len(galleries) == 2 and all(g.diff_scale == DIFF_SCALE for g in galleries)
    assert len(galleries[0].items) == 4  # two methods on two scenes
    seams = {item.caption: item for item in galleries[1].items}
    assert seams["foot, " + C.method_name("segments")].note == "max difference 0.05 (headline)"
    assert all(item.difference and (report / item.difference).is_file() for item in galleries[1].items)


def test_the_claims_per_scene():
    assert [c.id for c in C.CLAIMS] == [f"accuracy-{s}" for s in SETUPS] + ["no-seams"]
    assert C.SEAM_TOLERANCE == pytest.approx(1e-5) and C.ACCURACY_PSNR == 40.0
