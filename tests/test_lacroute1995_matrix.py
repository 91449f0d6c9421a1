"""lacroute1995-matrix: samples and time with each coherence optimisation (Fig. 5.17)."""

from pipeline.experiments.lacroute1995.matrix import MATRIX_CONFIGS
from test_lacroute1995_package import check_report, evaluate, planned, timed

NAME = "lacroute1995-matrix"
TIMED = ("early-termination-alone", "rle-alone", "rle-and-early-termination")


def test_plan_has_every_configuration_and_brute_force_without_either_structure():
    matrix = planned(NAME)
    assert {r.tags["config"] for r in matrix} == set(MATRIX_CONFIGS)
    brute = [r for r in matrix if r.tags["config"] == "brute-force"]
    assert all(r.options == {"rle": False, "early_termination": False} for r in brute)
    assert {r.interleave for r in matrix} == {r.tags["dataset"] for r in matrix}  # a data set's four timed together


def _matrix_rows(ratios, speedups, dataset="d", fixed=0.0, spread=0.0):
    """Four configurations: samples relative to brute force, compositing speed-ups, ``fixed`` seconds besides."""
    configs = list(MATRIX_CONFIGS)
    return [{"dataset": dataset, "config": c, "count_samples": 1e6 * r, **timed(1e-3 / s, spread, "composite"),
             "time_total": 1e-3 / s + fixed} for c, r, s in zip(configs, ratios, speedups)]


def test_matrix_claims():
    thesis = _matrix_rows([1, 0.78, 0.16, 0.028], [1, 1.03, 4.1, 9.9])
    for claim in ("sample-ratios", *TIMED):
        assert evaluate(NAME, claim, thesis).holds is True, claim
    weak = _matrix_rows([1, 0.3, 0.5, 0.3], [1, 3.0, 1.2, 2.0])
    for claim in ("sample-ratios", *TIMED):
        assert evaluate(NAME, claim, weak).holds is False, claim
    assert evaluate(NAME, "rle-alone", thesis[:3]).holds is None  # a configuration missing


def test_speed_ups_are_of_the_compositing_loop_with_intervals():
    # 5 ms of fixed cost per frame hides a ×9.9 loop speed-up in the whole frame (×1.7): the loop decides.
    rows = _matrix_rows([1, 0.78, 0.16, 0.028], [1, 1.03, 4.1, 9.9], fixed=5e-3)
    result = evaluate(NAME, "rle-and-early-termination", rows)
    assert result.holds is True and result.measured == "×9.9 (95 % CI ×9.9–×9.9) (d)"
    assert "samples ×35.7 fewer" in result.detail and "whole frame 6 ms → 5.1 ms" in result.detail
    # ×5.5 measured with frames ±40 %: the interval straddles 5.
    noisy = evaluate(NAME, "rle-and-early-termination", _matrix_rows([1, 0.78, 0.16, 0.028], [1, 1, 4, 5.5], spread=0.4))
    assert noisy.holds is None and noisy.inconclusive and "95 % CI" in noisy.measured
    # Every data set must hold: a second one at ×3 fails the claim.
    both = rows + _matrix_rows([1, 0.78, 0.16, 0.028], [1, 1, 2.5, 3], dataset="e")
    assert evaluate(NAME, "rle-and-early-termination", both).holds is False


def test_report_writes_its_charts(tmp_path):
    check_report(tmp_path, NAME, _matrix_rows([1, 0.78, 0.16, 0.028], [1, 1.03, 4.1, 9.9]))


def test_fig_5_17s_sample_ratios_are_judged_beside_ours():
    # Inside the thesis's brainsmall–brain range (0.73–0.78, 0.16–0.22, 0.023–0.028): both hold.
    inside = _matrix_rows([1, 0.75, 0.2, 0.025], [1, 1.03, 4.1, 9.9])
    assert evaluate(NAME, "sample-ratios-paper", inside).holds is True
    # Early termination saving more, the RLE less: ours holds, the thesis's figures do not.
    outside = _matrix_rows([1, 0.6, 0.3, 0.05], [1, 1.03, 4.1, 9.9])
    assert evaluate(NAME, "sample-ratios", outside).holds is True
    assert evaluate(NAME, "sample-ratios-paper", outside).holds is False
    # The band is the counts' own, not their rounding: the brain's 0.7757 is its top.
    assert evaluate(NAME, "sample-ratios-paper", _matrix_rows([1, 0.78, 0.2, 0.025], [1, 1, 4, 9])).holds is False
