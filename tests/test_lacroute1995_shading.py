"""lacroute1995-shading: shading tables, union by rank and the mode switch (Table 7.1, §4.1.3, §4.4)."""

import numpy as np
import pandas as pd

from pipeline.experiments.lacroute1995.shading import mode_switch_table
from test_lacroute1995_package import evaluate, planned, timed

NAME = "lacroute1995-shading"


def test_plan_times_each_comparison_together_and_our_three_modes():
    runs = {r.id: r for r in planned(NAME)}
    modes = {i: r.options for i, r in runs.items() if i.startswith("mode.")}
    assert modes["mode.shearwarp-octree-rle"] == {"octree_rle_build": True}
    assert modes["mode.shearwarp-octree"] == {"classification": "octree"}
    assert modes["mode.shearwarp"] == {}
    assert all(r.warmup >= 1 and r.repeat >= 3 for r in runs.values())  # timed: preprocessing is timed apart
    assert {i: r.interleave for i, r in runs.items()} == {
        "baseline": "variants", "shading.procedural": "variants", "union.rank": "variants",
        "mode.shearwarp": "shearwarp-modes", "mode.shearwarp-octree-rle": "shearwarp-modes",
        "mode.shearwarp-octree": "shearwarp-modes", "mode.volpack-rle": "volpack-modes",
        "mode.volpack-octree": "volpack-modes"}


def _variant_rows(baseline=0.01, procedural=0.04, rank=0.0105, spread=0.0):
    return [{"part": "baseline", "config": "lut, path-compression", **timed(baseline, spread), "psnr": 45.0},
            {"part": "shading", "config": "procedural", **timed(procedural, spread)},
            {"part": "union", "config": "rank", **timed(rank, spread)},
            {"part": "mode", "config": "volpack-rle", **timed(0.002), "time_classify": 0.05},
            {"part": "mode", "config": "volpack-octree", **timed(0.004), "time_octree": 0.03}]


def test_variant_claims():
    rows = _variant_rows()
    for claim in ("lut-faster", "lut-accurate", "union-by-rank", "mode-switch"):
        assert evaluate(NAME, claim, rows).holds is True, claim
    rows = _variant_rows(procedural=0.012, rank=0.008)
    rows[0]["psnr"] = 30.0
    for claim in ("lut-faster", "lut-accurate", "union-by-rank"):
        assert evaluate(NAME, claim, rows).holds is False, claim
    assert evaluate(NAME, "mode-switch", rows[:3]).holds is None
    rows[4].update(timed(0.06))  # 60 ms to the octree's image against 52 ms for classify + RLE frame
    assert evaluate(NAME, "mode-switch", rows).holds is False


def test_speed_claims_read_the_technique_with_intervals():
    rows = _variant_rows(procedural=0.021, spread=0.3)
    for row in rows:
        row["time_total"] = 1.0  # the whole frame is not the claims' scope
    lut = evaluate(NAME, "lut-faster", rows)
    assert lut.holds is None and lut.inconclusive and "compiled floating point" in lut.detail
    assert evaluate(NAME, "lut-faster", _variant_rows(procedural=0.021)).holds is True
    rank = evaluate(NAME, "union-by-rank", _variant_rows(rank=0.0098, spread=0.3))
    assert rank.holds is None and rank.inconclusive


def _mode_rows(octree_rle=(0.004, 0.01), octree_frame=0.02, spread=0.0):
    """Brute force classify 20 ms + RLE 10 ms, frame 10 ms; the octree's SAT and RLE build given."""
    sat, rle_build = octree_rle
    return [{"part": "mode", "config": "shearwarp", **timed(0.01, spread), "time_classify": 0.02,
             "time_rle_build": 0.01, "count_rle_bytes": 1e5, "count_samples": 1e4},
            {"part": "mode", "config": "shearwarp-octree-rle", **timed(0.01, spread), "time_octree_build": 0.03,
             "time_sat_build": sat, "time_rle_build": rle_build},
            {"part": "mode", "config": "shearwarp-octree", **timed(octree_frame, spread), "time_octree_build": 0.03,
             "time_sat_build": 0.004, "time_octree_classify": 0.01, "count_octree_bytes": 2e4, "count_samples": 2e4,
             "count_classified_on_the_fly": 5e3}]


def test_our_mode_switch_claims():
    rows = _mode_rows()
    for claim in ("fast-classification-render", "mode-switch-ours"):
        assert evaluate(NAME, claim, rows).holds is True, claim
    # Each build stage is timed once: no interval, so however clear the times, the claim is not decided.
    result = evaluate(NAME, "octree-rle-build", rows)
    assert result.measured.startswith("×0.467: 14 ms vs 30 ms") and result.interval is None
    assert result.inconclusive and "no timed frames behind its interval" in result.detail
    assert "samples ×2 of the RLE's" in evaluate(NAME, "fast-classification-render", rows).detail
    # The octree build takes longer than classify + encode; the octree frame is 6× the RLE frame.
    rows = _mode_rows(octree_rle=(0.025, 0.01), octree_frame=0.06)
    for claim in ("fast-classification-render", "mode-switch-ours"):
        assert evaluate(NAME, claim, rows).holds is False, claim
    assert evaluate(NAME, "octree-rle-build", rows).inconclusive
    # 0.004 + 0.06 = 64 ms after an edit against 40 ms for the RLE: the switch does not pay.
    assert evaluate(NAME, "octree-rle-build", rows[:1] + rows[2:]).holds is None  # no octree-built RLE run
    # 4 + 36 ms against 40 ms, frames ±40 %: too close to call.
    close = evaluate(NAME, "mode-switch-ours", _mode_rows(octree_frame=0.036, spread=0.4))
    assert close.holds is None and close.inconclusive
    rows[0].pop("time_classify")
    assert evaluate(NAME, "mode-switch-ours", rows).holds is None  # a missing stage is not a pass
    table = mode_switch_table(pd.DataFrame(_mode_rows()))
    assert list(table["mode"]) == ["RLE, brute-force build", "RLE built from the octree", "fast classification"]
    assert np.allclose(table["after an edit (ms)"], [40.0, 24.0, 24.0])


def test_the_theses_figures_are_judged_beside_ours():
    # Table 7.1: ×4.26 (14.5 / 3.4 s). ×4.5 holds; ×4 holds only ours (≥ ×2).
    assert evaluate(NAME, "lut-faster-paper", _variant_rows(procedural=0.045)).holds is True
    assert evaluate(NAME, "lut-faster-paper", _variant_rows(procedural=0.04)).holds is False
    assert evaluate(NAME, "lut-faster", _variant_rows(procedural=0.04)).holds is True
    # §4.1.3: rank 5–15 % slower. 10 % holds; as fast as path compression alone holds only ours (≥ ×0.97).
    assert evaluate(NAME, "union-by-rank-paper", _variant_rows(rank=0.011)).holds is True
    assert evaluate(NAME, "union-by-rank-paper", _variant_rows(rank=0.01)).holds is False
    assert evaluate(NAME, "union-by-rank", _variant_rows(rank=0.01)).holds is True
    # Table 5.3: ×1.8–2.5. ×2 holds; ×3 holds only ours (×1.4–3.2).
    assert evaluate(NAME, "fast-classification-render-paper", _mode_rows(octree_frame=0.02)).holds is True
    assert evaluate(NAME, "fast-classification-render-paper", _mode_rows(octree_frame=0.03)).holds is False
    assert evaluate(NAME, "fast-classification-render", _mode_rows(octree_frame=0.03)).holds is True
