"""lacroute1995-matrix: samples and time with each coherence optimisation (Fig. 5.17)."""

from pipeline.experiments.lacroute1995.matrix import MATRIX_CONFIGS
from test_lacroute1995_package import check_report, evaluate, planned


def test_plan_has_every_configuration_and_brute_force_without_either_structure():
    matrix = planned("lacroute1995-matrix")
    assert {r.tags["config"] for r in matrix} == set(MATRIX_CONFIGS)
    brute = [r for r in matrix if r.tags["config"] == "brute-force"]
    assert all(r.options == {"rle": False, "early_termination": False} for r in brute)


def _matrix_rows(ratios, speedups, dataset="d"):
    configs = list(MATRIX_CONFIGS)
    return [{"dataset": dataset, "config": c, "count_samples": 1e6 * r, "time_total": 1.0 / s}
            for c, r, s in zip(configs, ratios, speedups)]


def test_matrix_claims():
    name = "lacroute1995-matrix"
    thesis = _matrix_rows([1, 0.78, 0.16, 0.028], [1, 1.03, 4.1, 9.9])
    for claim in ("sample-ratios", "early-termination-alone", "rle-alone", "rle-and-early-termination"):
        assert evaluate(name, claim, thesis).holds is True, claim
    weak = _matrix_rows([1, 0.3, 0.5, 0.3], [1, 3.0, 1.2, 2.0])
    for claim in ("sample-ratios", "early-termination-alone", "rle-alone", "rle-and-early-termination"):
        assert evaluate(name, claim, weak).holds is False, claim
    assert evaluate(name, "rle-alone", thesis[:3]).holds is None  # a configuration missing


def test_report_writes_its_charts(tmp_path):
    check_report(tmp_path, "lacroute1995-matrix", _matrix_rows([1, 0.78, 0.16, 0.028], [1, 1.03, 4.1, 9.9]))
