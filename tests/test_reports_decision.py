"""Tests of the index's decision panel (reports.decision): Pareto fronts, the per-technique table, the banner."""

import re

import numpy as np
import pandas as pd
import pytest

from reports import decision, plots


def _rows(points, scene="skull-bone", kind="opaque"):
    """Overview rows from ``[(backend, setting, ms, dB)]``."""
    return pd.DataFrame([{"technique": f"{b} ({s})", "backend": b, "setting": s, "dataset": scene, "kind": kind,
                          "time_total": t / 1e3, "time_min": 0.9 * t / 1e3, "time_max": 1.2 * t / 1e3, "psnr": p,
                          "ssim": 0.9, "flip": 0.1, "record": f"runs/{b}-{s}.json", "exr": None,
                          "run": f"{scene}.{b}.{s}", "experiment": "volbench-speed-accuracy"}
                         for b, s, t, p in points])


def test_the_pareto_front_keeps_only_the_settings_nothing_beats_in_both_time_and_accuracy():
    rows = _rows([("a", "s1", 10, 30), ("a", "s2", 20, 45), ("a", "s3", 25, 40), ("a", "s4", 40, 50),
                  ("a", "s5", 40, 48), ("a", "s6", 5, np.nan)])
    front = decision.pareto_front(rows)
    assert list(front.setting) == ["s1", "s2", "s4"]  # s3 is slower and worse than s2; s5 ties s4's time, worse


def test_the_panel_picks_each_techniques_fastest_accurate_setting_and_leaves_the_reference_out():
    rows = _rows([("reference", "step_factor=1.0", 100, 45), ("gl-raycast", "step_factor=1.0", 8, 38),
                  ("gl-raycast", "step_factor=0.5", 15, 44), ("gl-raycast", "step_factor=0.25", 30, 50),
                  ("shearwarp", "default", 5, 17.6), ("shearwarp", "min_opacity=0.0", 9, 37)])
    [item] = decision.panel(rows, None, psnr_min=40, failures={"shearwarp": "min opacity ≥ 0.01 (17.6 dB)"})
    assert item["kind"] == "opaque surfaces" and "reference" not in set(item["points"].backend)
    gl, sw = item["table"]
    assert (gl["backend"], gl["setting"], gl["ms"], gl["psnr"], gl["accurate"]) == \
        ("gl-raycast", "step 0.5 voxel", "15", "44", True)
    assert gl["fails_when"] == "not in the atlas"
    # No setting gets there: its most accurate is shown, marked, after every technique that does.
    assert (sw["backend"], sw["psnr"], sw["accurate"]) == ("shearwarp", "37", False)
    assert sw["status"] == "no setting reaches 40 dB" and sw["fails_when"] == "min opacity ≥ 0.01 (17.6 dB)"
    front = item["points"][item["points"].front]
    assert set(front.setting[front.backend == "gl-raycast"]) == {"step_factor=1.0", "step_factor=0.5",
                                                                 "step_factor=0.25"}


def test_a_ratio_to_the_next_technique_is_said_only_from_its_ranking_claim_on_a_quiet_machine():
    """The index says "faster than the next" from the ranking claim's interval: a tie where it reaches ×1, no ratio
    without one (separate jobs, too few frames) or where either time was disturbed (issue 35)."""
    from reports.html import _decision_sentences

    points = [("gl-raycast", "step_factor=0.5", 10, 44), ("cl-tiled", "step_factor=0.5", 25, 45)]
    measured = "cl-tiled (step 0.5 voxel) / gl-raycast (step 0.5 voxel): ×2.5"

    def sentence(timed_with=("e/race", "e/race"), disturbed=(False, False), verdict="holds", low=2.3, high=2.7,
                 about=measured):
        rows = _rows(points).assign(timed_with=list(timed_with), disturbed=list(disturbed))
        ranking = {"skull-bone": {"verdict": verdict, "measured": about, "interval_low": low, "interval_high": high}}
        return _decision_sentences(decision.panel(rows, None, psnr_min=40), 40, ranking)[0]

    assert sentence().endswith("×2.5 faster than the next, cl-tiled (25 ms), timed together (95 % CI ×2.3–×2.7).")
    assert sentence(low=1.003).endswith("(95 % CI ×1.003–×2.7).")  # an end near ×1 does not read as ×1
    tie = sentence(verdict="inconclusive", low=0.97, high=3.1)
    assert "ties with the next, cl-tiled (25 ms)" in tie and "faster" not in tie and tie.endswith("(95 % CI ×0.97–×3.1).")
    apart = sentence(("e/gl", "e/cl"), verdict="not measured", low=np.nan, high=np.nan)
    assert "×" not in apart and apart.endswith("the next, cl-tiled (25 ms), was timed in a separate job, so no ratio "
                                               "between them is claimed.")
    assert "was timed while the machine was disturbed" in sentence(disturbed=(False, True))
    # A claim about two other techniques (an older run's) gives no ratio here; nor does no claim at all.
    assert "no ratio" in sentence(about="vtk-cpu (step 1 voxel) / shearwarp (default): ×2.5")
    rows = _rows(points).assign(timed_with="e/race", disturbed=False)
    assert "no ratio" in _decision_sentences(decision.panel(rows, None, psnr_min=40), 40)[0]


def test_technique_rows_name_the_job_that_timed_each_run_and_whether_it_was_disturbed():
    frame = pd.DataFrame({"experiment": "e", "run": ["a", "a", "b"], "view": ["v1", "v2", "v1"], "status": "ok",
                          "reference": "truth", "backend": ["gl-raycast", "gl-raycast", "cl-tiled"],
                          "time_total": [0.01, 0.012, 0.02], "psnr": 45.0, "interleave": ["g", "g", ""],
                          "info_disturbed": ["", "other work used 0.8 cores", np.nan]})
    rows = decision.technique_rows(frame).set_index("run")
    assert rows.timed_with.to_dict() == {"a": "e/g", "b": "e/b"}
    assert rows.disturbed.to_dict() == {"a": True, "b": False}


def test_a_technique_that_made_no_frame_is_listed_with_its_reason_not_dropped():
    rows = _rows([("gl-raycast", "default", 8, 45)], scene="skull-mip", kind="mip")
    runs = pd.DataFrame([
        {"experiment": "e", "run": "skull-mip.shearwarp.0", "backend": "shearwarp", "scene": "skull-mip",
         "status": "skipped", "cause": "unsupported", "reason": "only dvr compositing is implemented", "record": "r1"},
        {"experiment": "e", "run": "skull-mip.cl-tiled.0", "backend": "cl-tiled", "scene": "skull-mip",
         "status": "failed", "cause": "unavailable", "reason": "PoCL cannot target this CPU", "record": "r2"},
        {"experiment": "e", "run": "skull-mip.reference.0", "backend": "reference", "scene": "skull-mip",
         "status": "failed", "cause": "error", "reason": "kaboom", "record": "r3"}])
    [item] = decision.panel(rows, runs)
    assert item["kind"] == "maximum intensity projection"
    statuses = {r["backend"]: r["status"] for r in item["table"]}
    assert statuses == {"gl-raycast": "",
                        "shearwarp": "lacks this kind of scene: only dvr compositing is implemented",
                        "cl-tiled": "made no frame here: PoCL cannot target this CPU"}
    # A backend whose failure the page states at its top is not told again, scene after scene.
    [item] = decision.panel(rows, runs, stated_above={"cl-tiled"})
    assert item["table"][-1]["status"] == "made no frame here: stated at the top of this page"


def _run_rows(**environment):
    backends = ["gl-raycast", "vtk-gpu", "cl-tiled", "shearwarp", "reference"]
    return pd.DataFrame([{"backend": b, "status": "ok", "cpu_model": "AMD EPYC", "usable_cpus": 2, **environment}
                         for b in backends])


def test_the_banner_says_when_gpu_techniques_ran_on_a_cpu():
    banner = decision.timing_banner(_run_rows(gl_renderer="llvmpipe (LLVM 15.0.6, 256 bits)",
                                              vtk_gl_renderer="llvmpipe (LLVM 15.0.6, 256 bits)",
                                              cl_device="pthread-AMD EPYC", cl_device_type="ALL | CPU"))
    gl, cl, cpu = banner
    assert gl["what"] == "OpenGL (gl-raycast, vtk-gpu)" and gl["software"]
    assert "not a GPU" in gl["where"] and "AMD EPYC (2 cores)" in gl["where"]
    assert cl["what"] == "OpenCL (cl-tiled)" and cl["software"] and "PoCL" in cl["where"]
    assert cpu == {"what": "CPU (shearwarp)", "where": "AMD EPYC (2 cores)", "software": False}


def test_the_banner_names_a_real_gpu_without_the_software_warning():
    banner = decision.timing_banner(_run_rows(gl_renderer="NVIDIA H100 80GB HBM3/PCIe/SSE2",
                                              vtk_gl_renderer="NVIDIA H100 80GB HBM3/PCIe/SSE2",
                                              cl_device="NVIDIA H100 80GB HBM3", cl_device_type="GPU"))
    assert [b["software"] for b in banner] == [False, False, False]
    assert banner[0]["where"] == "NVIDIA H100 80GB HBM3/PCIe/SSE2"


@pytest.mark.parametrize("frame", [pd.DataFrame(), pd.DataFrame({"x": [1]})])
def test_the_banner_is_empty_without_runs(frame):
    assert decision.timing_banner(frame) == []


def test_the_index_opens_with_the_decision_panel(tmp_path):
    from test_reports_html import page_links, synthetic_report

    index = synthetic_report(tmp_path)
    text = index.read_text()
    panel = text[text.index('<section id="decision-panel">'):text.index("</section>")]
    # Before any table of papers, phantoms or timings; one chart and one table per scene of the overview.
    assert text.index('id="decision-panel"') < text.index('id="papers"')
    charts = [link for tag, link in page_links(index).links if tag == "img" and "decision" in link]
    assert charts == [f"plots/index-decision-{s}.svg" for s in ("skull-bone", "engine-semi", "skull-mip", "foot-iso")]
    for chart in charts:
        legend = re.findall(r"<text[^>]*>\s*([^<]+?)\s*</text>", (index.parent / chart).read_text())
        assert "shearwarp" in legend and "reference" not in legend  # the ground truth is not a contender
    assert panel.count('<table class="data decision-table">') == 4
    assert "<b>reference</b>" not in panel
    # engine-semi's reference run failed (the synthetic results' one failure): the others still have a row.
    assert "Test CPU 9000" in text and "Where these times were measured" in text


def test_a_technique_keeps_its_colour_in_every_chart_of_the_panel(tmp_path):
    both = _rows([("cl-tiled", "default", 3, 45), ("gl-raycast", "default", 8, 45)])
    alone = _rows([("gl-raycast", "default", 8, 45)], scene="skull-mip", kind="mip")
    colours = []
    for rows, name in ((both, "a.svg"), (alone, "b.svg")):
        [item] = decision.panel(rows, None)
        text = plots.pareto_fronts(item["points"], tmp_path / name, title="t", psnr_min=40,
                              techniques=["cl-tiled", "gl-raycast"]).read_text()
        # The legend's gl-raycast entry: its line's stroke colour comes right before its label.
        colours.append(re.findall(r"stroke: (#[0-9a-f]{6})", text.split(">gl-raycast<")[0])[-1])
    assert colours[0] == colours[1]
