"""``ropinski2005-samples`` (E3): its plan and its three count claims on synthetic rows, the page."""

import pandas as pd

from pipeline import experiments
from pipeline.experiments.ropinski2005.methods import METHODS
from pipeline.experiments.ropinski2005.scenes import SETUPS
from reports import blocks
from reports.html import ReportContext
from test_ropinski2005_table1 import evaluate, planned

NAME = "ropinski2005-samples"

REGIONS = (6000, 1000, 3000)
"""Samples of region₀, region₁, region₂ with the outside appearance: together the lens-off 10000."""


def count_rows(*, outside=REGIONS, lens=(6000, 0, 3000), total=None, methods=("segments", "per-sample"),
               scenes=("seismic",)):
    """The lens-off run, then per method the outside-appearance and lens-appearance runs, counted.

    A method other than the segments and fused methods counts no regions (as the caster); ``total`` is the
    outside-appearance run's sample total (default: the sum of ``outside``).
    """
    rows = []
    for scene in scenes:
        base = {"experiment": "x", "role": "test", "status": "ok", "scene": scene, "view": "headline"}
        rows.append({**base, "run": f"{scene}.off", "config": "off", "appearance": "none", "count_samples": 10000})
        for method in methods:
            counts = {"outside": outside, "lens": lens}
            for appearance, regions in counts.items():
                row = {**base, "run": f"{scene}.{method}.{appearance}", "config": method, "appearance": appearance,
                       "count_samples": (total if appearance == "outside" and total is not None else sum(regions))}
                if method in ("segments", "fused"):
                    row |= {f"count_samples_region{i}": n for i, n in enumerate(regions)}
                rows.append(row)
    return rows


def test_plan():
    smoke = planned("smoke", NAME)
    configs = [c for c in METHODS if c != "segments-ftb"]
    assert len(smoke) == len(SETUPS) * (1 + 2 * len(configs))
    assert all(r.options["opaque_threshold"] == 1.0 and (r.warmup, r.repeat) == (0, 1) for r in smoke)
    assert all(r.interleave == r.tags["scene"] for r in smoke)  # one job per scene
    foot = {r.id: r for r in smoke if r.tags["scene"] == "foot"}
    assert "lenses" not in foot["foot.off"].scene and foot["foot.off"].tags["appearance"] == "none"
    assert foot["foot.fused.outside"].scene["lenses"][0]["appearance"] == {"mode": "dvr", "preset": "skin_bone"}
    assert foot["foot.fused.lens"].scene["lenses"][0]["appearance"]["mode"] == "iso"
    assert {r.id for r in planned("smoke", NAME, methods=["fused"], scenes=["foot"])} == {
        "foot.off", "foot.fused.outside", "foot.fused.lens"}


def test_the_outside_appearance_takes_the_lens_off_samples():
    assert evaluate(NAME, "invariant", count_rows()).holds is True
    result = evaluate(NAME, "invariant", count_rows(total=10001, methods=("per-sample",)))
    assert result.holds is False and result.measured == "1 samples (per-sample, seismic, headline)"
    fewer = evaluate(NAME, "invariant", count_rows(total=9990))
    assert fewer.holds is False and fewer.measured == "-10 samples (segments, seismic, headline)"


def test_the_regions_partition_the_samples():
    result = evaluate(NAME, "regions-partition", count_rows())
    assert result.holds is True and "segments" in result.detail and "per-sample" not in result.detail
    twice = evaluate(NAME, "regions-partition", count_rows(outside=(6000, 1010, 3000), total=10000))
    assert twice.holds is False and twice.measured.startswith("regions − no lens = 10 samples (segments")
    assert evaluate(NAME, "regions-partition", count_rows(methods=("per-sample",))).holds is None


def test_the_lens_changes_only_region1():
    result = evaluate(NAME, "outside-unchanged", count_rows())
    assert result.holds is True and "seismic segments region₁ 0 of 1000" in result.detail
    moved = evaluate(NAME, "outside-unchanged", count_rows(lens=(6000, 0, 2000)))
    assert moved.holds is False and moved.measured == "region2 differs by 1000 samples (segments, seismic, headline)"


def test_the_page(tmp_path):
    rows = pd.DataFrame(count_rows(scenes=("seismic", "foot")))
    for column in ("png", "exr", "record"):
        rows[column] = ""
    report = tmp_path / "report"
    out = experiments.get(NAME).report(rows, ReportContext(report, tmp_path, NAME))
    table = next(b for b in out if isinstance(b, blocks.Table) and b.title.startswith("Samples per frame")).frame
    segments = table[(table.scene == "foot") & table.method.str.startswith("segments")].iloc[0]
    assert segments["no lens"] == 10000 and segments["lens with its own appearance"] == 9000
    assert segments["region₁, outside"] == 1000 and segments["region₁, lens"] == 0
    figure = next(b for b in out if isinstance(b, blocks.Figure))
    assert "no data" not in (report / figure.path).read_text()
