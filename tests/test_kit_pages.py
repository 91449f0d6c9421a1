"""Tests of the words pages write (pipeline.experiments.kit.pages, reports.takeaways): signs, settings,
literals, the claims' take-aways with their likely causes, and the five take-aways a page shows."""

import jinja2
import pandas as pd
import pytest

from pipeline.experiments.kit.pages import (change_words, claim_evidence, db_words, frames_note, per_gl_device,
                                            setting_words)
from pipeline.experiments.kit.verdicts import Verdict, disturbed_detail
from reports import html, takeaways
from reports.takeaways import FAILING_CLAIM, Takeaway, likely_cause, rst_inline


@pytest.mark.parametrize("ratio, words", [
    (0.9131, "8.69 % faster"), (1.0869, "8.69 % slower"), (0.0672, "×14.9 faster"), (14.9, "×14.9 slower"),
    (1.5, "×1.5 slower"), (1 / 1.5, "×1.5 faster"), (1.0, "no different"),
])
def test_change_words_say_the_sign_in_the_word_never_in_the_number(ratio, words):
    assert change_words(ratio) == words


def test_change_words_take_other_words_and_refuse_a_ratio_that_is_no_ratio():
    assert change_words(0.02, faster="fewer", slower="more") == "×50 fewer"
    assert change_words(1.2, faster="less", slower="more") == "20 % more"
    for bad in (0.0, -0.5, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="change_words: the ratio must be a positive finite number"):
            change_words(bad)


@pytest.mark.parametrize("frames, warmup, words", [
    (1, 0, "single untimed frame"), (6, 2, "median of 6 frames after 2 warm-up"),
    (6, 0, "median of 6 frames after the first frame"), (float("nan"), float("nan"), "")])
def test_frames_note_says_how_a_run_was_timed(frames, warmup, words):
    # warmup 0 with timed frames: the first frame compiled nothing and the next agreed with it (pipeline.timing).
    assert frames_note(pd.Series({"info_frames": frames, "info_warmup": warmup})) == words


def test_db_words_put_the_sign_in_the_word():
    assert db_words(-1.99) == "1.99 dB less"
    assert db_words(2.0) == "2 dB more"
    assert db_words(-0.5, more="higher", less="lower") == "0.5 dB lower"
    assert db_words(0.0, same="level with") == "level with"
    with pytest.raises(ValueError, match="db_words"):
        db_words(float("nan"))


def test_setting_words_read_key_value_settings_as_words_and_leave_other_text():
    assert setting_words("min_opacity=0.0,opaque_threshold=0.999") == "min opacity 0, opaque threshold 0.999"
    assert setting_words("step_factor=0.5") == "step 0.5 voxel"
    assert setting_words("early_termination=False,rle=False") == "early termination off, rle off"
    assert setting_words("method=segments") == "method segments"
    for text in ("default", "truth", "", "a=1,b"):
        assert setting_words(text) == text
    assert setting_words(float("nan")) == ""


def test_rst_inline_makes_literals_code_and_escapes_the_rest():
    shown = rst_inline("the ``quality_sweep`` <b>&amp; ``x<y`` end")
    assert shown == "the <code>quality_sweep</code> &lt;b&gt;&amp;amp; <code>x&lt;y</code> end"
    assert jinja2.Environment(autoescape=True).from_string("{{ t }}").render(t=shown) == shown  # not escaped twice


def test_take_away_labels_show_settings_in_words_and_speed_ups_with_the_right_word():
    frame = pd.DataFrame({"scene": "s", "technique": ["vtk-cpu (step_factor=0.5)", "ref (step_factor=0.125)"],
                          "time_total": [0.01, 0.1], "psnr": [45.0, 60.0]})
    assert takeaways.fastest_at_accuracy(frame) == [
        "At ≥ 40 dB PSNR the fastest setting on s is vtk-cpu (step 0.5 voxel) at 10 ms (45 dB), ×10 faster than the "
        "slowest that gets there."]
    assert "vtk-cpu (step 0.5 voxel) on s (30 dB)" in takeaways.accuracy_failures(frame.assign(psnr=[30.0, 60.0]))[0]


def _claims(**columns):
    base = {"statement": ["a", "b", "c", "d"], "expected": ["≥ 1"] * 4, "measured": ["2", "0.5", "3", "n/a"],
            "verdict": ["holds", "fails", "inconclusive", "not measured"]}
    return pd.DataFrame({**base, **columns})


def test_claims_put_failing_claims_first_each_with_its_likely_cause():
    evidence = {"interval_low": [None, 0.4, 0.9, None], "interval_high": [None, 0.6, 1.2, None],
                "disturbed_views": 0, "software_rasterizer": ["", "llvmpipe (LLVM 15)", "", ""], "stand_in": ""}
    sentences = takeaways.claims(_claims(**evidence))
    assert sentences == [
        "1 of 3 measured claims hold; 1 fail; 1 inconclusive; 1 not measured.",
        "Fails: b (measured 0.5, expected ≥ 1); likely cause: llvmpipe (GL frames timed on llvmpipe (LLVM 15), a CPU "
        "rasterizer).",
        "Inconclusive (timing noise × 1): c (measured 3, expected ≥ 1)."]
    assert [getattr(s, "importance", None) for s in sentences] == [FAILING_CLAIM, FAILING_CLAIM, None]
    # Without the claims table's evidence columns no cause is guessed; a table of holds (no verdict) still reads.
    assert "likely cause: cause not determined" in takeaways.claims(_claims())[1]
    assert takeaways.claims(pd.DataFrame({"statement": ["a"], "expected": [""], "measured": ["1"],
                                          "holds": [True]})) == ["1 of 1 measured claims hold."]


@pytest.mark.parametrize("row, cause", [
    ({"verdict": "fails", "disturbed_views": 3}, "timing noise (3 of its views timed while the machine was disturbed)"),
    ({"verdict": "inconclusive", "interval_low": 0.9, "interval_high": 1.1}, "timing noise (its 95 % interval"),
    ({"verdict": "fails", "interval_low": 0.4, "interval_high": 0.6, "software_rasterizer": "llvmpipe"}, "llvmpipe"),
    ({"verdict": "fails", "software_rasterizer": "llvmpipe"}, "a real discrepancy"),  # not a timing claim
    ({"verdict": "fails", "interval_low": 1.2, "interval_high": 1.4,
      "stand_in": "ct_skull standing in for the paper's data"}, "stand-in data (ct_skull"),
    # Two renderers of the same phantom disagreeing is not the phantom's fault.
    ({"verdict": "fails", "stand_in": "ct_skull standing in for the paper's data"}, "a real discrepancy"),
    ({"verdict": "fails"}, "a real discrepancy"),
])
def test_likely_cause_says_only_what_the_row_shows(row, cause):
    full = {"interval_low": None, "interval_high": None, "disturbed_views": 0, "software_rasterizer": "",
            "stand_in": "", **row}
    assert likely_cause(full).startswith(cause)
    assert likely_cause({"verdict": "fails"}) == "cause not determined"


def test_claim_evidence_reads_the_verdict_and_the_experiments_rows():
    rows = pd.DataFrame({"status": ["ok", "ok", "ok", "failed", "ok"],
                         "dataset": ["ct_skull", "sphere", "sphere", "engine", "sphere"],
                         "backend": ["gl-raycast", "gl-raycast", "gl-slicing", "gl-raycast", "shearwarp"],
                         "gl_software_rasterizer": [True, False, None, True, True],
                         "gl_renderer": ["llvmpipe (LLVM 15)", "NVIDIA H100", None, "softpipe", "softpipe"]})
    detail = disturbed_detail([("r", "v", "busy"), ("r", "w", "busy")]) + "; more"
    evidence = claim_evidence(Verdict("inconclusive", "×2", None, detail, disturbed_views=2), rows)
    assert evidence == {"disturbed_views": 2, "software_rasterizer": "llvmpipe (LLVM 15)",
                        "stand_in": "ct_skull standing in for the paper's data"}
    # A claim that reads a real scan too is not put down to the phantom beside it.
    with_scan = rows.assign(dataset=["ct_skull", "sphere", "cthead", "engine", "sphere"])
    assert claim_evidence(Verdict("fails", "×2", False, "x"), with_scan)["stand_in"] == ""
    # Every run records the machine's GL device; a CPU backend's claim is not timed on it.
    cpu_only = rows.assign(backend=["shearwarp", "volpack", "vtk-cpu", "shearwarp", "reference"])
    assert claim_evidence(Verdict("fails", "×2", False, "x"), cpu_only)["software_rasterizer"] == ""
    assert claim_evidence(Verdict("fails", "×2", False, "x"), rows[["status"]]) == {
        "disturbed_views": 0, "software_rasterizer": "", "stand_in": ""}


def _render(sentences):
    # As the report builds a page: ranked in Python, rendered in the report's own (strict) environment.
    return html._jinja().get_template("takeaways.html").render(takeaways=takeaways.ranked(sentences),
                                                               shown=takeaways.SHOWN)


def test_a_page_shows_five_take_aways_most_important_first_and_folds_the_rest():
    sentences = ["r1", "r2", Takeaway("accuracy", 1), "r3", Takeaway("failing", FAILING_CLAIM), "r4", "r5", "r6"]
    html = _render(sentences)
    shown, _, folded = html.partition("<details>")
    assert [s for s in ("failing", "accuracy", "r1", "r2", "r3") if f"<li>{s}</li>" in shown] == [
        "failing", "accuracy", "r1", "r2", "r3"]
    assert shown.index("failing") < shown.index("accuracy") < shown.index("r1") < shown.index("r3")
    assert "<summary>3 more take-aways</summary>" in folded and all(f"<li>{s}</li>" in folded for s in ("r4", "r5", "r6"))
    assert "<details>" not in _render(["a", "b", "c", "d", "e"]) and _render([]).strip() == ""
    assert takeaways.ranked(["a", Takeaway("f", FAILING_CLAIM), "a", "b"]) == ["f", "a", "b"]  # repeats said once


def test_a_difference_gallery_shows_each_row_with_its_difference_on_the_one_scale():
    from pipeline.experiments.kit.pages import DIFF_SCALE, difference_gallery

    class Context:  # records what the gallery asks of the report
        def __init__(self):
            self.differences = []

        def image(self, png):
            return f"img/{png}"

        def difference(self, reference, test, scale):
            self.differences.append((reference, test, scale))
            return None if reference is None else f"diff/{test}"

    results = pd.DataFrame({"run": ["a", "b", "ref"], "view": "headline", "status": "ok", "reference": ["ref", "ref", None],
                            "png": ["a.png", "b.png", "r.png"], "exr": ["a.exr", "b.exr", "r.exr"],
                            "time_total": [0.012, 0.0041, 1.0], "psnr": [41.25, float("nan"), float("nan")]})
    ctx = Context()
    gallery = difference_gallery("Each method", results.iloc[:2], ctx, against=results, caption="right |a − ref|",
                                 label=lambda row: f"run {row.run}")
    assert gallery.diff_scale == DIFF_SCALE and gallery.caption == "right |a − ref|"
    assert [(i.caption, i.image, i.difference, i.note) for i in gallery.items] == [
        ("run a", "img/a.png", "diff/a.exr", "12 ms, PSNR 41.2 dB"), ("run b", "img/b.png", "diff/b.exr", "4.1 ms")]
    assert ctx.differences == [("r.exr", "a.exr", DIFF_SCALE), ("r.exr", "b.exr", DIFF_SCALE)]
    # Against a picture of one's choosing, or none: no difference, no scale.
    only_b = difference_gallery("b against a", results.iloc[1:2], ctx, label=str, against=lambda row: "a.exr")
    assert only_b.items[0].difference == "diff/b.exr"
    plain = difference_gallery("Pictures", results.iloc[:1], ctx, label=lambda row: row.run, note=lambda row: "")
    assert plain.diff_scale is None and plain.items[0].difference is None and plain.items[0].note == ""


def test_per_gl_device_makes_one_table_per_device_with_its_name():
    rows = pd.DataFrame({"gl_renderer": ["llvmpipe", "NVIDIA H200", None], "time": [3.0, 1.0, 2.0]})
    table = per_gl_device(rows, lambda part: pd.DataFrame({"total": [part.time.sum()]}))
    assert sorted(zip(table.device, table.total)) == [("NVIDIA H200", 1.0), ("llvmpipe", 3.0), ("unknown device", 2.0)]
    assert per_gl_device(rows.iloc[:0], lambda part: part).empty
