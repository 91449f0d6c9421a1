"""``ropinski2005``'s shared pieces: the lens methods as ``gl-raycast`` options, the paper's Table 1 and §3.4."""

import numpy as np
import pandas as pd
import pytest

import renderers
from pipeline import experiments
from pipeline.experiments.planned import planned
from pipeline.experiments.ropinski2005 import methods as M
from pipeline.experiments.ropinski2005 import tables as T
from renderers.base.options import Option


def test_every_method_is_the_single_pass_variant_with_its_lens_method():
    assert M.method_options(M.OFF) == {"variant": "single-pass", "step_factor": M.STEP}
    assert M.method_options("segments", step_factor=1.0, opaque_threshold=1.0) == {
        "variant": "single-pass", "lens_method": "segments", "step_factor": 1.0, "opaque_threshold": 1.0}
    assert M.method_options("segments-ftb")["region_order"] == "front-to-back"
    assert {M.METHODS[c][0]["lens_method"] for c in M.METHODS} == {
        "segments", "segments-stencil", "fused", "per-sample", "per-sample-mask", "frag-depth"}
    run = M.lens_run("x", "s.fused", {"volumes": []}, ({"view": "headline"},), "fused", {"warmup": 0, "repeat": 1},
                     {"scene": "s"}, group="g", reference="s.truth")
    assert run.backend == "gl-raycast" and run.interleave == "g" and run.reference == "s.truth"
    assert run.tags == {"scene": "s", "config": "fused"} and run.options["lens_method"] == "fused"


def test_a_method_the_caster_lacks_is_named_on_the_page(monkeypatch):
    cls = renderers.backend_class("gl-raycast")
    table = tuple(Option("lens_method", str, "fused", "", choices=("fused",)) if o.name == "lens_method" else o
                  for o in cls.option_table)
    monkeypatch.setattr(cls, "option_table", table)
    missing = M.unknown_methods(["fused", "segments", M.OFF, "segments"])
    assert missing == [("lens method segments", "gl-raycast's lens_method has no 'segments' here (its choices: fused), "
                                                "so its runs fail")]
    assert "lens method segments" in M.raycast_not_measurable(["segments"])[0].text
    monkeypatch.setattr(renderers, "BACKENDS", {k: v for k, v in renderers.BACKENDS.items() if k != "gl-raycast"})
    assert "gl-raycast" in M.raycast_not_measurable()[0].text and M.unknown_methods(["segments"]) == []


def test_lens_coverage():
    rows = pd.DataFrame({"count_rays": [100, 200, 100], "count_lens_rays": [10, 50, 90], "count_samples": [5, 7, 9]})
    assert M.lens_coverage(rows) == pytest.approx(0.25)  # the median of the views' shares
    assert np.isnan(M.lens_coverage(rows.drop(columns="count_lens_rays")))


def test_table1_is_the_papers():
    assert T.TABLE1 == {"seismic": (60.0, 58.3, 53.0, 49.1), "skull": (30.1, 24.0, 19.0, 14.7),
                        "foot": (29.7, 25.3, 14.8, 9.7)}
    assert T.paper_fps("foot", 1024, True) == 9.7 and T.paper_fps("skull", 512, False) == 30.1
    with pytest.raises(KeyError, match="no 256² viewport"):
        T.paper_fps("foot", 256, True)


def test_the_derived_overheads_are_the_guides():
    # note 004 §3.4, as printed: fps drop (%) at 512² and 1024², frame times (ms)
    drops = {"seismic": (2.8, 7.4), "skull": (20.3, 22.6), "foot": (14.8, 34.5)}
    for row, (small, large) in drops.items():
        assert round(100 * T.paper_drop(row, 512), 1) == small and round(100 * T.paper_drop(row, 1024), 1) == large
        assert T.paper_time_ratio(row, 1024) == pytest.approx(1 / (1 - T.paper_drop(row, 1024)))
    derived = {r["data set"]: r for r in T.derived_table()}
    assert derived["seismic"]["512² no lens (ms)"] == 16.67 and derived["foot"]["1024² lens (ms)"] == 103.09
    assert derived["skull"]["1024² Δ (ms)"] == 15.4 and derived["foot"]["512² Δ (ms)"] == 5.86


def test_the_paper_is_reproduced_by_its_experiments():
    paper = experiments.papers()["ropinski2005"]
    assert paper.technique == "gl-raycast"
    assert [cls.name for cls in paper.experiments] == [
        f"ropinski2005-{name}" for name in ("table1", "passes", "samples", "methods", "size", "appearance",
                                            "correctness", "edges", "order", "peers")]

    assert "ropinski2005" not in {row["paper"] for row in planned(renderers.names(), experiments.papers().values())}


def test_an_iso_lens_finds_its_surface_as_the_paper_does():
    lens = {"shape": "sphere", "center": [0, 0, 0], "radius": 4.0, "appearance": {"mode": "iso", "isovalue": 0.5}}
    spec = {"name": "s", "volumes": [], "lenses": [lens]}
    run = M.lens_run("e", "r", spec, ({"view": "v"},), "segments", {}, {})
    assert run.options["iso_hit"] == "sampled"  # gl-raycast's default is exact: the paper's caster samples
    dvr = M.lens_run("e", "r", {**spec, "lenses": [{**lens, "appearance": {"mode": "dvr"}}]}, ({"view": "v"},),
                     "segments", {}, {})
    assert "iso_hit" not in dvr.options
