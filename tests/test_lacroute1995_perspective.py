"""lacroute1995-perspective: perspective image quality against the field of view (§4.2.5)."""

import numpy as np
import pandas as pd
import pytest

from pipeline.experiments.lacroute1995.perspective import footprint_psnr, fov_rows
from reports.imageio import read_image
from reports.metrics import psnr
from test_lacroute1995_package import check_report, evaluate, planned, write

NAME = "lacroute1995-perspective"


def test_plan_pairs_each_field_of_view_with_its_own_truth():
    perspective = {r.id: r for r in planned(NAME, **{NAME: {"fovs": [60, 15]}})}
    assert set(perspective) == {f"{f}.{role}" for f in ("parallel", "fov15", "fov60") for role in ("truth", "shearwarp")}
    assert perspective["fov15.shearwarp"].reference == "fov15.truth"
    assert perspective["fov60.truth"].scene["camera"] == {"projection": "perspective", "fov_y": 60.0}
    assert "camera" not in perspective["parallel.truth"].scene
    assert perspective["fov60.truth"].scene == perspective["fov60.shearwarp"].scene


def _pair(tmp_path, name, radius, error):
    """A grey disc of ``radius`` pixels (of 40) and a copy off by ``error`` inside it: the truth and the test."""
    y, x = np.mgrid[:40, :40]
    disc = ((x - 20) ** 2 + (y - 20) ** 2 < radius ** 2).astype(np.float32)
    truth = np.stack([0.5 * disc, 0.5 * disc, 0.5 * disc, disc], axis=-1)
    test = truth.copy()
    test[..., 0] += error * disc
    return write(tmp_path / f"{name}-truth.exr", truth), write(tmp_path / f"{name}.exr", test)


def _fov_rows(tmp_path, errors, parallel=0.01):
    """Each field of view's disc shrinks as it widens (the eye comes closer); ``errors`` inside it by field."""
    rows = []
    for fov, error in {0.0: parallel, **errors}.items():
        truth, test = _pair(tmp_path, f"fov{fov:g}", 16 - fov / 10, error)
        rows.append({"role": "test", "dataset": "ct_skull", "fov": fov, "view": "headline", "run": f"f{fov:g}",
                     "reference": f"t{fov:g}", "exr": test, "psnr": 99.0, "info_max_ray_angle": fov / 2 + 10})
        rows.append({"role": "truth", "dataset": "ct_skull", "fov": fov, "view": "headline", "run": f"t{fov:g}",
                     "exr": truth})
    return rows


def test_footprint_psnr_counts_only_the_covered_pixels(tmp_path):
    small, big = _pair(tmp_path, "small", 5, 0.1), _pair(tmp_path, "big", 15, 0.1)
    # The same error per covered pixel: the same PSNR over the footprint, however much of the frame it covers.
    assert footprint_psnr(*small) == pytest.approx(footprint_psnr(*big)) == pytest.approx(10 * np.log10(4 / 0.01))
    with pytest.raises(ValueError, match="no pixel"):
        footprint_psnr(*_pair(tmp_path, "empty", 0, 0.1))


def test_perspective_claims(tmp_path):
    rows = _fov_rows(tmp_path, {15: 0.011, 30: 0.013, 60: 0.016, 90: 0.02})
    for claim in ("quality-falls-with-fov", "narrow-fov-like-parallel"):
        assert evaluate(NAME, claim, rows).holds is True, claim
    result = evaluate(NAME, "quality-falls-with-fov", rows)
    assert result.measured == "5.19 dB lower at 90° than at 15°" and "of the frame (whole frame 99 dB)" in result.detail
    # A 2 dB rise from 30° to 60° breaks the trend; a 15° image 3 dB off the parallel one is not "alike".
    rows = _fov_rows(tmp_path, {15: 0.015, 30: 0.02, 60: 0.015, 90: 0.03})
    for claim in ("quality-falls-with-fov", "narrow-fov-like-parallel"):
        assert evaluate(NAME, claim, rows).holds is False, claim
    assert evaluate(NAME, "quality-falls-with-fov", _fov_rows(tmp_path, {15: 0.011, 90: 0.012})).holds is False  # < 1 dB
    assert evaluate(NAME, "quality-falls-with-fov", _fov_rows(tmp_path, {15: 0.011})).holds is None
    assert evaluate(NAME, "narrow-fov-like-parallel", _fov_rows(tmp_path, {15: 0.011})[2:]).holds is None
    assert list(fov_rows(pd.DataFrame(_fov_rows(tmp_path, {60: 0.01, 15: 0.01}))).fov) == [0.0, 15.0, 60.0]


def test_a_shrinking_object_does_not_hide_the_growing_error(tmp_path):
    # The error per covered pixel grows ×1.6 while the disc covers a third of the frame it did: over the
    # whole frame the PSNR rises, over the footprint it falls.
    rows = _fov_rows(tmp_path, {15: 0.01, 90: 0.016})
    covered = fov_rows(pd.DataFrame(rows)).set_index("fov")
    assert covered.coverage[90.0] < 0.4 * covered.coverage[15.0]
    whole = {r["fov"]: psnr(read_image(r["exr"].replace(".exr", "-truth.exr")), read_image(r["exr"]))
             for r in rows if r["role"] == "test"}
    assert whole[90.0] > whole[15.0]
    assert evaluate(NAME, "quality-falls-with-fov", rows).holds is True


def test_report_writes_its_charts(tmp_path):
    rows = [{**r, "time_total": 0.1} for r in _fov_rows(tmp_path, {15: 0.011, 30: 0.013, 60: 0.016, 90: 0.02})]
    check_report(tmp_path, NAME, rows)
