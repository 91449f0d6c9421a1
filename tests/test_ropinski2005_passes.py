"""``ropinski2005-passes`` (E2): its plan, the geometry-share claim on synthetic frames, the page."""

import numpy as np
import pandas as pd
import pytest

from pipeline import experiments
from pipeline.experiments.kit import intervals
from pipeline.experiments.ropinski2005.scenes import SETUPS
from reports import blocks
from reports.html import ReportContext
from test_ropinski2005_table1 import evaluate, planned

NAME = "ropinski2005-passes"


def pass_rows(geometry, *, scenes=("seismic", "foot"), total=0.1, jitter=(1.0, 1.0, 1.0, 1.0, 1.0)):
    """One run per scene whose frames spend ``geometry`` of ``total`` seconds in the lens geometry stage."""
    rows = []
    for scene in scenes:
        stages = {"lens_geometry": geometry, "region0": 0.6 * (total - geometry), "region1": 0.1 * (total - geometry),
                  "region2": 0.3 * (total - geometry), "total": total}
        row = {"experiment": "x", "role": "test", "status": "ok", "scene": scene, "view": "headline",
               "run": f"{scene}.segments", "config": "segments", "interleave": "passes", "count_rays": 1000,
               "count_lens_rays": 200, "count_samples_region0": 6000, "count_samples_region1": 1000,
               "count_samples_region2": 3000}
        for stage, seconds in stages.items():
            frames = [seconds * (j if stage == "lens_geometry" else 1.0) for j in jitter]
            row[f"time_{stage}"] = float(np.median(frames))
            row[f"frames_{stage}"] = intervals.format_frames(frames)
        rows.append(row)
    return rows


def test_plan():
    smoke = planned("smoke", NAME)
    assert {r.tags["scene"] for r in smoke} == set(SETUPS) and {r.interleave for r in smoke} == {"passes"}
    assert all(r.options["lens_method"] == "segments" and r.repeat >= 3 and len(r.views) == 1 for r in smoke)
    assert {r.scene["height"] for r in smoke} == {48} and {r.scene["height"] for r in planned("full", NAME)} == {1024}


def test_the_geometry_share_claim():
    small = evaluate(NAME, "geometry-small", pass_rows(0.002))
    assert small.holds is True and small.measured == "lens geometry / frame 2 % (95 % CI 2 %–2 %) (seismic)"
    assert "foot: 2 % (95 % CI 2 %–2 %) (2 ms of 100 ms)" in small.detail
    assert evaluate(NAME, "geometry-small", pass_rows(0.02)).holds is False
    # Frames of the geometry stage spread across the bound: its share's interval straddles 10 %.
    spread = evaluate(NAME, "geometry-small", pass_rows(0.009, jitter=(0.5, 1.0, 1.0, 1.5, 2.0)))
    assert spread.inconclusive and spread.interval[0] < 0.1 < spread.interval[1]


def test_a_method_without_the_stage_is_not_measured():
    rows = pass_rows(0.002)
    for row in rows:
        del row["time_lens_geometry"], row["frames_lens_geometry"]
    result = evaluate(NAME, "geometry-small", rows)
    assert result.holds is None and "time_lens_geometry" in result.detail


def test_the_page(tmp_path):
    rows = pd.DataFrame(pass_rows(0.002))
    for column in ("png", "exr", "record"):
        rows[column] = ""
    report = tmp_path / "report"
    out = experiments.get(NAME).report(rows, ReportContext(report, tmp_path, NAME))
    table = next(b for b in out if isinstance(b, blocks.Table) and b.title.startswith("Passes")).frame
    seismic = table[table.scene == "seismic"].iloc[0]
    assert seismic["lens_geometry (%)"] == pytest.approx(2.0) and seismic["region0 samples"] == 6000
    assert seismic["region0 ns/sample"] == pytest.approx(1e9 * 0.6 * 0.098 / 6000)
    assert seismic["rays through the lens (%)"] == 20
    figures = [b for b in out if isinstance(b, blocks.Figure)]
    assert len(figures) == 2 and all("no data" not in (report / f.path).read_text() for f in figures)
