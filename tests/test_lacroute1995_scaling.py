"""lacroute1995-scaling: time and memory against the volume and image size (Tables 5.3, 5.4)."""

from test_lacroute1995_package import check_report, evaluate, planned


def test_plan_grows_every_data_set_and_warps_the_first_once_per_size_and_image():
    runs = planned("lacroute1995-scaling", **{"lacroute1995-scaling": {
        "datasets": ["folded_brain", "ct_skull"], "volume_sizes": [16, 32, 16], "image_sizes": [16, 32, 64],
        "image_size": 32}})
    assert [r.id for r in runs] == ["folded_brain.v16.i32", "folded_brain.v32.i32", "ct_skull.v16.i32",
                                    "ct_skull.v32.i32", "folded_brain.v16.i16", "folded_brain.v16.i64",
                                    "folded_brain.v32.i64"]
    assert [r.tags["growth"] for r in runs] == [1, 1, 1, 1, 0, 0, 0]


def _scaling_rows(growth, warp_ratio=4.0):
    rows = []
    for n, t in zip((64, 128, 256), (0.01, 0.01 * growth, 0.01 * growth ** 2)):
        rows.append({"dataset": "b", "volume_size": n, "image_size": 256, "growth": 1, "time_total": t,
                     "time_warp": 0.004, "count_rle_bytes": 0.4 * n ** 3, "count_raw_bytes": n ** 3})
    for i, w in ((64, 0.004 / warp_ratio ** 2), (128, 0.004 / warp_ratio)):
        rows.append({"dataset": "b", "volume_size": 64, "image_size": i, "growth": 0, "time_total": 0.01,
                     "time_warp": w, "count_rle_bytes": 0.4 * 64 ** 3, "count_raw_bytes": 64 ** 3})
    return rows


def test_scaling_claims():
    name = "lacroute1995-scaling"
    good = _scaling_rows(4.0)
    for claim in ("n-squared-growth", "rle-memory", "warp-per-pixel", "warp-share"):
        assert evaluate(name, claim, good).holds is True, claim
    cubic = _scaling_rows(8.0, warp_ratio=1.5)
    for row in cubic:
        row["count_rle_bytes"] = 5 * row["count_raw_bytes"]
    for claim in ("n-squared-growth", "rle-memory", "warp-per-pixel"):
        assert evaluate(name, claim, cubic).holds is False, claim


def test_report_writes_its_charts(tmp_path):
    check_report(tmp_path, "lacroute1995-scaling", _scaling_rows(4.0))
