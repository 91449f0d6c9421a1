"""``xue2005-octree``: the node sizes it plans and its claims on synthetic results."""

import pytest

from core.errors import InputError
from pipeline.experiments.xue2005.tables import PHI_P_NODES
from test_xue2005_surfaces import NOISY, evaluate, frames, picture_rows, planned, with_isbvr

NAME = "xue2005-octree"


def test_plan_times_basic_with_ert_at_every_node_size(monkeypatch):
    with_isbvr(monkeypatch)
    runs = planned(NAME)
    assert {r.interleave for r in runs} == {"head"}
    basic = next(r for r in runs if r.options["zinit"] == "none")
    ert = [r for r in runs if r is not basic]
    assert sorted(r.options["phi_p_node"] for r in ert) == list(PHI_P_NODES)
    assert {r.options["zinit"] for r in ert} == {"ert"} and {r.reference for r in ert} == {basic.id}
    volumes = {(r.scene["volumes"][0]["dataset"], r.scene["volumes"][0]["preset"]) for r in runs}
    assert volumes == {("ct_skull", "isbvr")}
    assert all(r.repeat >= 3 and r.warmup >= 1 for r in runs)
    assert {len(r.views) for r in planned(NAME, "smoke")} == {1}
    assert sorted(r.options["phi_p_node"] for r in planned(NAME, nodes=[2, 8]) if "phi_p_node" in r.options) == [2, 8]
    with pytest.raises(InputError, match="nodes: unknown"):
        planned(NAME, nodes=[3])


def _nodes(counts, times=None, views=("headline",)):
    """ERT rows per node size: ``counts[node] = (cubes, triangles, written, culled)``, optionally timed frames (ms)."""
    rows = []
    for node, (cubes, triangles, written, culled) in counts.items():
        for view in views:
            row = {"scene": "head", "view": view, "config": "ert", "run": f"head.n{node}.ert",
                   "option_phi_p_node": node, "count_cubes_p": cubes, "count_surface_triangles_p": triangles,
                   "count_init_fragments": written, "count_fragments_generated": 10_000,
                   "count_fragments": 10_000 - culled}
            if times:
                row.update(frames([ms * 1e-3 for ms in times[node]], "total", group="head"))
            rows.append(row)
    return rows


PAPER_LIKE = {1: (2e4, 9e4, 1e4, 6e3), 2: (700, 6e3, 3e3, 2e3), 4: (20, 200, 100, 50), 8: (0, 0, 0, 0)}
"""Counts shaped like Fig. 7: Φ_p shrinks with the node size and is gone at 8³."""


def test_coverage_collapses_at_the_coarsest_node_size():
    result = evaluate(NAME, "coverage-collapses", _nodes(PAPER_LIKE))
    assert result.holds is True and result.measured == "0 % of the 2³ coverage"
    assert "2e+03 and 0" in result.detail
    kept = {**PAPER_LIKE, 8: (50, 400, 600, 300)}
    assert evaluate(NAME, "coverage-collapses", _nodes(kept)).holds is False
    none = {node: (0, 0, 0, 0) for node in PHI_P_NODES}
    result = evaluate(NAME, "coverage-collapses", _nodes(none))
    assert result.holds is None and "no cube at any node size" in result.detail


def test_triangles_fall_with_the_node_size():
    result = evaluate(NAME, "triangles-fall", _nodes(PAPER_LIKE))
    assert result.holds is True and result.measured.startswith("9e+04 (1³) → 6e+03 (2³)")
    rising = {**PAPER_LIKE, 4: (20, 7e3, 100, 50)}
    assert evaluate(NAME, "triangles-fall", _nodes(rising)).holds is False
    flat = {node: (10, 100, 50, 20) for node in PHI_P_NODES}
    assert evaluate(NAME, "triangles-fall", _nodes(flat)).holds is False


def test_the_papers_node_size_must_be_fastest_with_intervals():
    best_at_two = {1: [12.0] * 5, 2: [10.0] * 5, 4: [11.0] * 5, 8: [11.5] * 5}
    result = evaluate(NAME, "paper-node-fastest", _nodes(PAPER_LIKE, best_at_two, views=("headline", "orbit000")))
    assert result.holds is True and result.measured.startswith("fastest here 2³; time / time at 2³ ×1.1 ")
    best_at_one = {**best_at_two, 1: [9.0] * 5}
    result = evaluate(NAME, "paper-node-fastest", _nodes(PAPER_LIKE, best_at_one))
    assert result.holds is False and result.measured.startswith("fastest here 1³") and result.measured.endswith("(1³)")
    tie = {**best_at_two, 4: [10.0] * 5}  # as fast as 2³ is not slower
    assert evaluate(NAME, "paper-node-fastest", _nodes(PAPER_LIKE, tie)).holds is False
    noisy = {**best_at_two, 1: [9.0 * f for f in NOISY]}
    assert evaluate(NAME, "paper-node-fastest", _nodes(PAPER_LIKE, noisy)).inconclusive


def test_ert_is_lossless_at_every_node_size(tmp_path):
    nodes = {"n1": 0.0, "n8": 0.0}
    match = {"config": "ert"}
    assert evaluate(NAME, "ert-lossless", picture_rows(tmp_path, nodes, match=match, scenes=("head",))).holds is True
    holes = picture_rows(tmp_path, {**nodes, "n2": 0.02}, match=match, scenes=("head",))
    result = evaluate(NAME, "ert-lossless", holes)
    assert result.holds is False and "2 % of pixels off" in result.measured
