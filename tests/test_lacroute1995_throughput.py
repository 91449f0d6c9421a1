"""lacroute1995-throughput: cubes, checkerboards and the cost model (Figs 5.19–5.21)."""

import numpy as np
import pytest

from pipeline.experiments.kit.results import fit_line
from pipeline.experiments.lacroute1995.throughput import all_visible_alpha, fit_cost_model
from test_lacroute1995_package import check_report, evaluate, planned, timed

NAME = "lacroute1995-throughput"
CLAIMS = ("linear-in-visible-voxels", "brute-force-flat", "crossover", "linear-in-runs", "one-voxel-runs", "cost-model")


def test_plan_puts_brute_force_at_the_compositing_ends_and_checkerboards_all_visible():
    throughput = planned(NAME, **{NAME: {
        "cube_alphas": [0.0, 0.1, 0.5, 1.0], "checker_blocks": [4, 2, 1], "checker_alphas": ["all-visible", 1.0],
        "brute_force": "ends", "predict": ["ct_skull"]}})
    # ends: brute force at the first and last opacity that composites (not α = 0) and block of each checker series
    brute = {r.id for r in throughput if r.tags["config"] == "brute-force"}
    assert {b for b in brute if b.startswith("cube")} == {"cube26.brute", "cube255.brute"}
    assert len(brute) == 2 + 2 * 2
    assert all(r.options["min_opacity"] < 0.1 / 2 for r in throughput if "min_opacity" in r.options)
    values = {r.scene["volumes"][0]["params"]["value"] for r in throughput if r.tags.get("series", "").startswith("checker")}
    assert values == {round(all_visible_alpha(16) * 255), 255}
    # The fit and its predictions compare every run: all timed together.
    assert {r.interleave for r in throughput} == {"cost-model"}
    every = planned(NAME, **{NAME: {"cube_alphas": [0.0, 0.1, 1.0], "brute_force": "all", "predict": []}})
    assert {r.id for r in every if r.id.startswith("cube") and r.tags["config"] == "brute-force"} == {
        "cube26.brute", "cube255.brute"}


def test_fits_recover_known_models():
    x = np.array([1.0, 2.0, 3.0, 5.0])
    assert fit_line(x, 2 * x + 1) == pytest.approx((2.0, 1.0, 1.0))
    rng = np.random.default_rng(1)
    visible, runs = rng.uniform(0, 1e6, 12), rng.uniform(0, 5e5, 12)
    seconds = visible / 2e7 + runs * 3e-9 + 1e-3
    a, b, c, r2 = fit_cost_model(visible, runs, seconds)
    assert (a, b, c, r2) == pytest.approx((2e7, 3e-9, 1e-3, 1.0), rel=1e-6)
    with pytest.raises(ValueError):
        fit_cost_model(visible[:3], runs[:3], seconds[:3])


def _row(series, config, samples, runs, seconds, spread=0.0, **tags):
    return {"series": series, "config": config, "count_samples": samples, "count_voxel_runs": runs,
            **timed(seconds, spread), "time_total": seconds + 1e-3, **tags}


def _throughput_rows(a=2e7, b=1e-7, c=1e-3, brute=0.06, n=64, spread=0.0, predicted=1.1):
    rows = []
    for alpha, visible in ((0.02, 1.0), (0.1, 0.2), (0.5, 0.03), (1.0, 0.004)):
        samples = visible * n ** 3
        rows.append(_row("cube", "optimised", samples, n * n, samples / a + n * n * b + c, spread, alpha=alpha))
    for alpha in (0.02, 1.0):
        rows.append(_row("cube", "brute-force", n ** 3, n * n, brute, spread, alpha=alpha))
    for block in (32, 8, 2, 1):
        runs = n * n * n / block
        rows.append(_row("checker α 0.05", "optimised", n ** 3 / 2, runs, n ** 3 / 2 / a + runs * b + c, spread,
                         block=block))
    for block in (32, 1):
        rows.append(_row("checker α 0.05", "brute-force", n ** 3, n * n, brute, spread, block=block))
    for dataset in ("ct_skull", "engine"):
        samples, runs = 40_000, 30_000
        rows.append(_row("predict", "optimised", samples, runs, (samples / a + runs * b + c) * predicted, spread,
                         dataset=dataset))
    return rows


def test_throughput_claims():
    rows = _throughput_rows()
    for claim in CLAIMS:
        assert evaluate(NAME, claim, rows).holds is True, claim
    slow = _throughput_rows(brute=0.002)  # brute force faster than everything: the RLE never pays
    assert evaluate(NAME, "crossover", slow).holds is False
    assert evaluate(NAME, "one-voxel-runs", slow).holds is False
    assert evaluate(NAME, "cost-model", _throughput_rows(predicted=2.0)).holds is False
    result = evaluate(NAME, "cost-model", _throughput_rows(predicted=1 / 0.9))
    assert result.measured == "-10 % (95 % CI -10 %–-10 %) (ct_skull)"


def test_brute_force_is_judged_where_it_composites():
    rows = _throughput_rows()
    # At α = 0 brute force only resamples: a third of the time, and no part of the claim.
    rows.append(_row("cube", "brute-force", 64 ** 3, 64 * 64, 0.02, alpha=0.0))
    assert evaluate(NAME, "brute-force-flat", rows).holds is True
    rows[-1]["alpha"] = 0.2
    flat = evaluate(NAME, "brute-force-flat", rows)
    assert flat.holds is False and flat.measured.startswith("66.7 %")


def test_timing_claims_are_inconclusive_when_the_frames_cannot_tell():
    # Frames ±60 % about medians that hold: the intervals of the ratios and fits reach across the bounds.
    noisy = _throughput_rows(spread=0.6, predicted=1.2)
    for claim in ("brute-force-flat", "cost-model"):
        result = evaluate(NAME, claim, noisy)
        assert result.holds is None and result.inconclusive, claim
    assert evaluate(NAME, "one-voxel-runs", _throughput_rows(brute=0.027, spread=0.6)).inconclusive


def test_report_writes_its_charts(tmp_path):
    check_report(tmp_path, NAME, _throughput_rows())


def test_the_theses_figures_are_judged_beside_ours():
    rows = _throughput_rows()
    for claim in ("crossover-paper", "one-voxel-runs-paper", "cost-model-paper"):
        assert evaluate(NAME, claim, rows).holds is True, claim
    # A cube 70 % visible slower than brute force: ours (≤ 50 % visible) holds, the thesis's 80 % crossover not.
    late = rows + [_row("cube", "optimised", 0.7 * 64 ** 3, 64 * 64, 0.07, alpha=0.05)]
    assert evaluate(NAME, "crossover", late).holds is True
    assert evaluate(NAME, "crossover-paper", late).holds is False
    # All visible 40 % slower than brute force: more than the thesis's worst case, 25 %.
    slow_full = [dict(r, **timed(0.084)) if r["series"] == "cube" and r["config"] == "optimised"
                 and r["alpha"] == 0.02 else r for r in rows]
    result = evaluate(NAME, "crossover-paper", slow_full)
    assert result.holds is False and "above it at most ×1.4" in result.measured
    assert evaluate(NAME, "crossover", slow_full).holds is True
    # 1-voxel runs 25 % slower than brute force: within our 30 %, not the thesis's 15 %.
    assert evaluate(NAME, "one-voxel-runs", _throughput_rows(brute=0.027)).holds is True
    assert evaluate(NAME, "one-voxel-runs-paper", _throughput_rows(brute=0.027)).holds is False
    # Predicted 30 % under the measured: the thesis's own head prediction was 31 % under (ours: 25 %).
    under = _throughput_rows(predicted=1 / 0.7)
    assert evaluate(NAME, "cost-model-paper", under).holds is True
    assert evaluate(NAME, "cost-model", under).holds is False
    assert evaluate(NAME, "cost-model-paper", _throughput_rows(predicted=1.6)).holds is False
