"""lacroute1995-perspective: perspective image quality against the field of view (§4.2.5)."""

import pandas as pd

from pipeline.experiments.lacroute1995.perspective import fov_rows
from test_lacroute1995_package import check_report, evaluate, planned


def test_plan_pairs_each_field_of_view_with_its_own_truth():
    perspective = {r.id: r for r in planned("lacroute1995-perspective", **{"lacroute1995-perspective": {"fovs": [60, 15]}})}
    assert set(perspective) == {f"{f}.{role}" for f in ("parallel", "fov15", "fov60") for role in ("truth", "shearwarp")}
    assert perspective["fov15.shearwarp"].reference == "fov15.truth"
    assert perspective["fov60.truth"].scene["camera"] == {"projection": "perspective", "fov_y": 60.0}
    assert "camera" not in perspective["parallel.truth"].scene
    assert perspective["fov60.truth"].scene == perspective["fov60.shearwarp"].scene


def _fov_rows(psnrs, parallel=40.0):
    rows = [{"role": "test", "dataset": "ct_skull", "fov": 0.0, "psnr": parallel, "ssim": 0.99, "view": "headline"}]
    for fov, psnr in psnrs.items():
        rows.append({"role": "test", "dataset": "ct_skull", "fov": fov, "psnr": psnr, "ssim": 0.98, "view": "headline",
                     "info_max_ray_angle": fov / 2 + 10})
        rows.append({"role": "truth", "dataset": "ct_skull", "fov": fov, "view": "headline"})
    return rows


def test_perspective_claims():
    name = "lacroute1995-perspective"
    rows = _fov_rows({15: 39.5, 30: 38.0, 60: 36.0, 90: 33.0})
    for claim in ("quality-falls-with-fov", "narrow-fov-like-parallel"):
        assert evaluate(name, claim, rows).holds is True, claim
    assert evaluate(name, "quality-falls-with-fov", rows).measured == "6.5 dB lower at 90° than at 15°"
    # A 2 dB rise from 30° to 60° breaks the trend; a 15° image 3 dB off the parallel one is not "alike".
    rows = _fov_rows({15: 37.0, 30: 35.0, 60: 37.0, 90: 33.0})
    for claim in ("quality-falls-with-fov", "narrow-fov-like-parallel"):
        assert evaluate(name, claim, rows).holds is False, claim
    assert evaluate(name, "quality-falls-with-fov", _fov_rows({15: 39.5, 90: 39.0})).holds is False  # < 1 dB
    assert evaluate(name, "quality-falls-with-fov", _fov_rows({15: 39.5})).holds is None
    assert evaluate(name, "narrow-fov-like-parallel", _fov_rows({15: 39.5})[1:]).holds is None
    assert list(fov_rows(pd.DataFrame(_fov_rows({60: 36.0, 15: 39.5}))).fov) == [0.0, 15.0, 60.0]


def test_report_writes_its_charts(tmp_path):
    rows = [{**r, "time_total": 0.1, "reference": "none"} for r in _fov_rows({15: 39.5, 30: 38.0, 60: 36.0, 90: 33.0})]
    check_report(tmp_path, "lacroute1995-perspective", rows)
