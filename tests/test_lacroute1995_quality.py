"""lacroute1995-quality: the 45° worst case, binary classification and opacity correction."""

import math

import numpy as np
import pytest

from pipeline.experiments.lacroute1995.quality import CUBE_VIEWS, cube_value, opacity_deficit
from test_lacroute1995_package import alpha_image, evaluate, planned, write


def test_plan_classifies_by_threshold_and_corrects_the_cube_both_ways():
    quality = planned("lacroute1995-quality")
    skull = next(r for r in quality if r.id == "ct_skull.binary.shearwarp")
    assert "transfer_function" in skull.scene["volumes"][0] and "preset" not in skull.scene["volumes"][0]
    cube = [r for r in quality if r.id.startswith("cube.") and r.backend == "shearwarp"]
    assert {r.options["opacity_correction"] for r in cube} == {True, False}


def test_opacity_deficit_measures_optical_depth(tmp_path):
    tau = np.linspace(0.2, 2.5, 400).reshape(20, 20)
    reference = write(tmp_path / "ref.exr", alpha_image(1 - np.exp(-tau)))
    thin = write(tmp_path / "thin.exr", alpha_image(1 - np.exp(-tau / math.sqrt(2))))
    same = write(tmp_path / "same.exr", alpha_image(1 - np.exp(-tau)))
    assert opacity_deficit(reference, thin) == pytest.approx(1 - 1 / math.sqrt(2), abs=1e-3)
    assert opacity_deficit(reference, same) == pytest.approx(0.0, abs=1e-3)
    with pytest.raises(ValueError, match="missing"):
        opacity_deficit(reference, str(tmp_path / "nothing.exr"))


def test_cube_value_keeps_the_diagonal_unsaturated():
    for size in (16, 32, 128, 256):
        alpha = cube_value(size) / 255
        depth = -math.log(1 - alpha) * size * math.sqrt(3)
        assert 0.5 < 1 - math.exp(-depth) < 0.95


def _quality_rows(psnr, truth):
    rows = []
    for tf, values in psnr.items():
        for angle, value in zip((0, 22.5, 45), values):
            rows.append({"part": "classification", "role": "test", "tf": tf, "dataset": "engine", "truth": truth,
                         "view": f"az{angle:g}", "psnr": value})
    return rows


def test_quality_claims():
    # As the engine measured: head-on both classifications are at their worst (silhouettes); from 22.5° to 45°
    # the binary one loses 1.65 dB, the smooth one 0.35 dB. Judged from 0°, the binary's "loss" would be negative.
    good = {"smooth": [36, 34.05, 33.7], "binary": [31.8, 35.4, 33.75]}
    flat = {"smooth": [34, 34, 30], "binary": [33, 33, 29.5]}
    name = "lacroute1995-quality"
    # Head-on against the ground truth (post) and against the pre-classified caster are separate claims;
    # the angle claims are judged against the pre-classified caster, the thesis's comparison.
    mixed = _quality_rows(good, "post") + _quality_rows(flat, "pre")
    assert evaluate(name, "smooth-0deg", mixed).holds is True
    assert evaluate(name, "smooth-0deg-pre", mixed).holds is False
    assert evaluate(name, "smooth-all-angles", mixed).holds is False
    assert evaluate(name, "binary-45deg-aliasing", mixed).holds is False
    mixed = _quality_rows(flat, "post") + _quality_rows(good, "pre")
    assert evaluate(name, "smooth-0deg", mixed).holds is False
    assert evaluate(name, "smooth-0deg-pre", mixed).holds is True
    assert evaluate(name, "smooth-all-angles", mixed).holds is True
    assert evaluate(name, "binary-45deg-aliasing", mixed).holds is True
    assert evaluate(name, "smooth-0deg-pre", _quality_rows(good, "post")).holds is None
    assert evaluate(name, "uncorrected-too-transparent", mixed).holds is None
    aliasing = evaluate(name, "binary-45deg-aliasing", mixed)
    assert aliasing.measured == "1.3 dB lost from 22.5° to 45° beyond the smooth one's loss (engine)"
    head_on_and_45 = [r for r in mixed if r["view"] != "az22.5"]
    assert evaluate(name, "binary-45deg-aliasing", head_on_and_45).holds is None  # no oblique baseline


def test_opacity_correction_claims(tmp_path):
    tau = np.linspace(0.2, 2.5, 400).reshape(20, 20)
    rows = []
    for view, _az, _el, spacing in CUBE_VIEWS:
        truth = write(tmp_path / f"{view}-truth.exr", alpha_image(1 - np.exp(-tau)))
        rows.append({"part": "opacity", "role": "truth", "view": view, "exr": truth, "correction": "reference"})
        rows.append({"part": "opacity", "role": "test", "view": view, "correction": "on",
                     "exr": write(tmp_path / f"{view}-on.exr", alpha_image(1 - np.exp(-tau)))})
        rows.append({"part": "opacity", "role": "test", "view": view, "correction": "off",
                     "exr": write(tmp_path / f"{view}-off.exr", alpha_image(1 - np.exp(-tau / spacing)))})
    name = "lacroute1995-quality"
    assert evaluate(name, "uncorrected-too-transparent", rows).holds is True
    assert evaluate(name, "corrected-agrees", rows).holds is True
    for row in rows:  # "corrected" images that are uncorrected
        if row["correction"] == "on":
            row["exr"] = row["exr"].replace("-on", "-off")
    assert evaluate(name, "corrected-agrees", rows).holds is False


def test_the_theses_30_percent_is_judged_beside_ours(tmp_path):
    tau = np.linspace(0.2, 2.5, 400).reshape(20, 20)
    name = "lacroute1995-quality"

    def rows(az45):
        """The cube's views uncorrected, as 1 − Δ0/Δ would have them, but at 45° ``az45`` times less deep."""
        out = []
        for view, _az, _el, spacing in CUBE_VIEWS:
            factor = az45 if view == "az45" else spacing
            out.append({"part": "opacity", "role": "truth", "view": view, "correction": "reference",
                        "exr": write(tmp_path / f"{view}-truth.exr", alpha_image(1 - np.exp(-tau)))})
            out.append({"part": "opacity", "role": "test", "view": view, "correction": "off",
                        "exr": write(tmp_path / f"{view}-{factor:g}.exr", alpha_image(1 - np.exp(-tau / factor)))})
        return out

    exact = evaluate(name, "uncorrected-too-transparent-paper", rows(math.sqrt(2)))  # 29.3 %: rounds to 30 %
    assert exact.holds is True and exact.measured == "29.3 % (az45)" and "25 %–35 % (az45)" in exact.detail
    # 35.5 % at 45°: within ours (29.3 % ± 7), more than the thesis's 30 % says.
    assert evaluate(name, "uncorrected-too-transparent", rows(1.55)).holds is True
    assert evaluate(name, "uncorrected-too-transparent-paper", rows(1.55)).holds is False
    assert evaluate(name, "uncorrected-too-transparent-paper", rows(1.25)).holds is False  # 20 %
