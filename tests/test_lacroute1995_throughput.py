"""lacroute1995-throughput: cubes, checkerboards and the cost model (Figs 5.19–5.21)."""

import numpy as np
import pytest

from pipeline.experiments.kit.results import fit_line
from pipeline.experiments.lacroute1995.throughput import all_visible_alpha, fit_cost_model
from test_lacroute1995_package import check_report, evaluate, planned


def test_plan_puts_brute_force_at_the_ends_and_checkerboards_all_visible():
    throughput = planned("lacroute1995-throughput", **{"lacroute1995-throughput": {
        "cube_alphas": [0.1, 0.5, 1.0], "checker_blocks": [4, 2, 1], "checker_alphas": ["all-visible", 1.0],
        "brute_force": "ends", "predict": ["ct_skull"]}})
    # ends: brute force at the first and last opacity of the cubes and block of each checker series
    assert sum(r.tags["config"] == "brute-force" for r in throughput) == 2 + 2 * 2
    assert all(r.options["min_opacity"] < 0.1 / 2 for r in throughput if "min_opacity" in r.options)
    values = {r.scene["volumes"][0]["params"]["value"] for r in throughput if r.tags.get("series", "").startswith("checker")}
    assert values == {round(all_visible_alpha(16) * 255), 255}


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


def _throughput_rows(a=2e7, b=1e-7, c=1e-3, brute=0.06, n=64):
    rows = []
    for alpha, visible in ((0.02, 1.0), (0.1, 0.2), (0.5, 0.03), (1.0, 0.004)):
        samples = visible * n ** 3
        rows.append({"series": "cube", "config": "optimised", "alpha": alpha, "count_samples": samples,
                     "count_voxel_runs": n * n, "time_total": samples / a + n * n * b + c})
    for alpha in (0.02, 1.0):
        rows.append({"series": "cube", "config": "brute-force", "alpha": alpha, "count_samples": n ** 3,
                     "count_voxel_runs": n * n, "time_total": brute})
    for block in (32, 8, 2, 1):
        runs = n * n * n / block
        samples = n ** 3 / 2
        rows.append({"series": "checker α 0.05", "config": "optimised", "block": block, "count_samples": samples,
                     "count_voxel_runs": runs, "time_total": samples / a + runs * b + c})
    for block in (32, 1):
        rows.append({"series": "checker α 0.05", "config": "brute-force", "block": block, "count_samples": n ** 3,
                     "count_voxel_runs": n * n, "time_total": brute})
    for dataset in ("ct_skull", "engine"):
        samples, runs = 40_000, 30_000
        rows.append({"series": "predict", "dataset": dataset, "config": "optimised", "count_samples": samples,
                     "count_voxel_runs": runs, "time_total": (samples / a + runs * b + c) * 1.1})
    return rows


def test_throughput_claims():
    name = "lacroute1995-throughput"
    rows = _throughput_rows()
    for claim in ("linear-in-visible-voxels", "brute-force-flat", "crossover", "linear-in-runs", "one-voxel-runs",
                  "cost-model"):
        assert evaluate(name, claim, rows).holds is True, claim
    slow = _throughput_rows(brute=0.002)  # brute force faster than everything: the RLE never pays
    assert evaluate(name, "crossover", slow).holds is False
    assert evaluate(name, "one-voxel-runs", slow).holds is False
    for row in rows:
        if row["series"] == "predict":
            row["time_total"] *= 2
    assert evaluate(name, "cost-model", rows).holds is False


def test_report_writes_its_charts(tmp_path):
    check_report(tmp_path, "lacroute1995-throughput", _throughput_rows())
