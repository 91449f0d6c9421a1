"""volbench-atlas: the plan per scale, failure thresholds, heat-map cells, claims and the report on synthetic rows."""

import numpy as np
import pandas as pd
import pytest

import renderers
from core.errors import InputError
from pipeline.experiments import Profile
from pipeline.experiments.volbench import atlas as atlas_module
from pipeline.experiments.volbench.atlas import (SAMPLED_ISO, PRE_CLASSIFIED, PSNR_BREAKS, TECHNIQUES, Atlas,
                                                 atlas_rows, failure_phrases, heat_cells, left_out, technique_rows,
                                                 threshold)
from pipeline.experiments.volbench.atlas_axes import AXES, AXIS_BY_KEY, CLOUD_ISOVALUE, points
from reports import blocks
from reports.html import ReportContext
from reports.imageio import write_exr, write_png

BACKENDS = [b for b in renderers.names() if b != "reference"]


ISO_BACKENDS = {"cl-tiled", "gl-raycast", "vtk-gpu"}
"""The backends with an iso mode besides the reference."""


def _runs(scale):
    return Atlas().runs(Profile.load(f"config/{scale}.yaml"))


def _technique(run):
    """The run's technique: a TECHNIQUES label when it ran with that entry's backend and options, else its backend."""
    return next((label for label, t in TECHNIQUES.items()
                 if run.backend == t.backend and t.options.items() <= run.options.items()), run.backend)


@pytest.mark.parametrize("scale", ["smoke", "default", "full"])
def test_every_backend_is_on_six_axes_or_says_why(scale):
    runs = _runs(scale)
    reasons = left_out()
    for backend in BACKENDS:
        axes = {r.tags["axis"] for r in runs if r.backend == backend}
        assert len(axes) >= 6, (backend, axes)
        for axis in AXES:
            assert (axis.key in axes) != ((backend, axis.key) in reasons), (backend, axis.key)
            if (backend, axis.key) in reasons:
                assert reasons[(backend, axis.key)].strip()


@pytest.mark.parametrize("scale", ["smoke", "default"])
def test_each_axis_renders_one_scene_per_point_for_every_backend(scale):
    runs = _runs(scale)
    truths = {r.id: r for r in runs if r.tags["role"] == "truth"}
    for run in runs:
        if run.tags["role"] == "truth":
            continue
        truth = truths[run.reference]
        assert run.scene == truth.scene and run.views == truth.views, run.id  # the same data, camera and TF
        assert (run.warmup, run.repeat) == (0, 1)
        technique = _technique(run)
        own = TECHNIQUES[technique].slug if technique in TECHNIQUES else run.backend
        assert run.interleave == f"{run.tags['axis']}.{'truth' if own == 'reference' else own}"
    for axis in AXES:
        scenes = {r.scene["name"] for r in runs if r.tags["axis"] == axis.key}
        expected = 1 if axis.option or axis.view_key else len(axis.values[scale])
        assert len(scenes) == expected, axis.key


def test_shear_warp_runs_at_min_opacity_0_except_on_the_axis_that_sweeps_it():
    runs = [r for r in _runs("default") if r.backend in ("shearwarp", "volpack")]
    for run in runs:
        if run.tags["axis"] == "min_opacity":
            assert run.options == {"min_opacity": run.tags["value"]}  # the default 0.05 is one of its points
        else:
            assert run.options.get("min_opacity") == 0.0, run.id
    assert {r.options["min_opacity"] for r in runs if r.tags["axis"] == "min_opacity"} >= {0.0, 0.05}
    # The others keep their own options.
    assert all("min_opacity" not in r.options for r in _runs("smoke") if r.backend == "gl-raycast"
               and r.tags["axis"] != "min_opacity")


def test_run_counts_follow_the_axes():
    runs = _runs("smoke")
    reasons = left_out()
    expected = 0
    for axis in AXES:
        values = len(axis.values["smoke"])
        backends = sum((b, axis.key) not in reasons for b in BACKENDS)
        scenes = 1 if axis.option or axis.view_key else values
        expected += scenes + backends * (values if axis.option or not axis.view_key else 1)
        extra = sum(axis.key in t.axes for t in TECHNIQUES.values())
        expected += extra * scenes * (values if axis.option else 1)  # each extra technique, one run per point
    expected += len(atlas_module.CONVERGENCE_STEPS)
    assert len(runs) == expected
    pre = [r for r in runs if r.options.get("classification") == "pre"]
    assert {r.tags["axis"] for r in pre} == {"tf"} and all(r.backend == "reference" for r in pre)
    assert all(r.options["step_factor"] == atlas_module.TRUTH_STEP for r in pre)  # only the order differs
    assert [r.id for r in pre] == ["tf.0.reference-pre", "tf.1.reference-pre"]  # the ids it always had
    assert sum(r.tags["role"] == "convergence" for r in runs) == len(atlas_module.CONVERGENCE_STEPS)


def test_reasons_name_what_is_missing():
    reasons = left_out()
    assert reasons[("shearwarp", "step")].startswith("no step_factor option: ")
    assert reasons[("volpack", "fov")].startswith("projections 'perspective': VolPack")
    assert ("gl-raycast", "lens") not in reasons  # it renders lenses with its single-pass variant
    assert ("vtk-gpu", "volumes") not in reasons and ("gl-raycast", "volumes") in reasons
    assert (PRE_CLASSIFIED, "tf") not in reasons and (PRE_CLASSIFIED, "step") in reasons
    assert reasons[(SAMPLED_ISO, "step")] == TECHNIQUES[SAMPLED_ISO].elsewhere
    # A backend without iso-surfaces is left out of the iso axes for that, not for a step it lacks.
    for backend in set(BACKENDS) - ISO_BACKENDS:
        for key in ("iso-step", "thin"):
            assert reasons[(backend, key)].startswith("modes 'iso': "), (backend, key)


def test_axes_setting_is_checked():
    profile = Profile(name="t", scale="smoke", settings={"volbench-atlas": {"axes": ["angle", "teapot"]}})
    with pytest.raises(InputError, match="volbench-atlas.axes: unknown"):
        Atlas().runs(profile)
    profile = Profile(name="t", scale="smoke", settings={"volbench-atlas": {"axes": ["angle"]}})
    assert {r.tags["axis"] for r in Atlas().runs(profile)} == {"angle"}


def _row(backend, axis, value, psnr, flip=0.1, **extra):
    return {"experiment": "volbench-atlas", "status": "ok", "role": "test", "backend": backend, "axis": axis,
            "value": value, "view": "atlas", "psnr": psnr, "flip": flip, **extra}


def _synthetic():
    rows = [_row("breaks", "min_opacity", v, p) for v, p in ((0.0, 37.0), (0.01, 25.0), (0.05, 17.6))]
    rows += [_row("breaks", "angle", np.nan, p, view=f"at{a:g}") for a, p in ((0, 28.0), (45, 26.0))]
    rows += [_row("holds", "min_opacity", v, p) for v, p in ((0.0, 45.0), (0.05, 34.0))]
    rows += [_row("holds", "step", v, p) for v, p in ((0.5, 50.0), (2.0, 36.0))]
    return pd.DataFrame(rows)


def test_threshold_is_the_mildest_failing_value_in_the_axis_order():
    tests = atlas_rows(_synthetic())
    mine = tests[(tests.backend == "breaks") & (tests.axis == "min_opacity")]
    hit = threshold(mine, AXIS_BY_KEY["min_opacity"])
    assert (hit["value"], hit["psnr"], hit["everywhere"]) == (0.01, 17.6, False)
    assert hit["words"] == "min opacity ≥ 0.01"
    shell = pd.DataFrame({"value": [8.0, 4.0, 1.0], "psnr": [45.0, 29.0, 20.0]})  # thinner is harsher
    assert threshold(shell, AXIS_BY_KEY["shell"])["words"] == "shell thickness ≤ 4 voxels"
    assert threshold(shell.assign(psnr=[45.0, 31.0, 30.0]), AXIS_BY_KEY["shell"]) is None
    fov = pd.DataFrame({"value": [15.0, 30.0, 60.0], "psnr": [17.6, 23.7, 31.0]})  # fails at the milder end
    hit = threshold(fov, AXIS_BY_KEY["fov"])
    assert (hit["words"], hit["expected"]) == ("field of view ≤ 30°", False)
    middle = threshold(fov.assign(psnr=[35.0, 20.0, 31.0]), AXIS_BY_KEY["fov"])
    assert middle["words"] == "field of view at 30°"


def test_failures_prefer_a_threshold_inside_a_sweep_and_name_the_worst_point_otherwise():
    phrases = failure_phrases(atlas_rows(_synthetic()), ["breaks", "holds", "absent"])
    # Its threshold inside a sweep first, with the scene; then the other axes it breaks on.
    assert phrases["breaks"] == ("min opacity ≥ 0.01 on the semi-transparent engine (17.6 dB); also any view angle "
                                 "tried (0° to 45°) (26 dB)")
    assert phrases["holds"] == f"no axis below {PSNR_BREAKS:g} dB (worst 34 dB at min opacity 0.05)"
    assert "absent" not in phrases
    only_angle = _synthetic().query("axis == 'angle'")
    assert failure_phrases(atlas_rows(only_angle), ["breaks"])["breaks"].startswith(
        "any view angle tried (0° to 45°) on")
    assert Atlas().failures(_synthetic()) == {k: v for k, v in phrases.items() if k != "absent"}
    reversed_fov = [_row("breaks", "fov", np.nan, p, view=f"at{f:g}") for f, p in ((15, 10.0), (90, 45.0))]
    with_fov = pd.concat([_synthetic(), pd.DataFrame(reversed_fov)])  # lower, but on the milder side
    assert failure_phrases(atlas_rows(with_fov), ["breaks"])["breaks"] == (
        "min opacity ≥ 0.01 on the semi-transparent engine (17.6 dB); also field of view ≤ 15° (10 dB), any view "
        "angle tried (0° to 45°) (26 dB)")


def test_heat_cells_show_the_worst_point_or_the_reason():
    tests = atlas_rows(_synthetic())
    reasons = {("holds", "angle"): "no view: it cannot turn"}
    cells = heat_cells(tests, ["breaks", "holds"], reasons, unrendered={("breaks", "shell"): "no OpenCL device"},
                       difference=lambda row: f"diff-{row.value:g}.png")
    words = AXIS_BY_KEY["min_opacity"].words
    worst = cells[("breaks", words)]
    assert (worst.value, worst.text, worst.link, worst.image) == (17.6, "17.6 dB", "#atlas-min_opacity", "diff-0.05.png")
    assert worst.note == "FLIP 0.1 at min opacity 0.05"
    assert cells[("breaks", AXIS_BY_KEY["angle"].words)].value == 26.0  # the value from the view name
    lacking = cells[("holds", AXIS_BY_KEY["angle"].words)]
    assert (lacking.value, lacking.text, lacking.link) == (None, "no view: it cannot turn", None)
    unrendered = cells[("breaks", AXIS_BY_KEY["shell"].words)]
    assert (unrendered.value, unrendered.text) == (None, "no frame here: no OpenCL device")
    assert len(cells) == 2 * len(AXES)


def test_convergence_claim_needs_falling_error():
    rows = [{"role": "convergence", "backend": "reference", "value": s, "psnr": p}
            for s, p in ((1.0, 40.0), (0.5, 45.0), (0.25, 52.0))]
    claim = next(c for c in Atlas.claims if c.id == "reference-converges")
    assert claim.evaluate(pd.DataFrame(rows)).holds
    rows[2]["psnr"] = 44.0
    assert claim.evaluate(pd.DataFrame(rows)).holds is False
    assert claim.evaluate(pd.DataFrame(rows[:1])).holds is None


def test_shearwarp_claim_needs_its_worst_view_near_45():
    claim = next(c for c in Atlas.claims if c.id == "shearwarp-45")
    rows = [_row("shearwarp", "angle", np.nan, p, view=f"at{a:g}") for a, p in ((0, 40.0), (25, 38.0), (45, 30.0))]
    assert claim.evaluate(pd.DataFrame(rows)).holds
    rows[0]["psnr"] = 20.0
    assert claim.evaluate(pd.DataFrame(rows)).holds is False


def test_report_on_synthetic_rows(tmp_path):
    results_dir, report_dir = tmp_path / "results", tmp_path / "report"
    images = results_dir / "runs"
    images.mkdir(parents=True)
    truth = np.zeros((8, 8, 4), np.float32)
    rows = []
    for index, row in enumerate(_synthetic().to_dict("records")):
        exr, png = images / f"r{index}.exr", images / f"r{index}.png"
        write_exr(exr, truth + np.float32(index / 100))
        write_png(png, truth)
        rows.append({**row, "run": f"r{index}", "reference": "truth", "exr": str(exr), "png": str(png),
                     "record": ""})
    write_exr(images / "truth.exr", truth)
    views = {r["view"] for r in rows}
    rows += [{"run": "truth", "backend": "reference", "status": "ok", "role": "truth", "view": v,
              "exr": str(images / "truth.exr")} for v in views]
    ctx = ReportContext(report_dir, results_dir, "volbench-atlas")
    out = Atlas().report(pd.DataFrame(rows), ctx)
    assert isinstance(out[0], blocks.Takeaways) and 2 <= len(out[0].sentences) <= 5
    assert any("breaks once min opacity ≥ 0.01" in s for s in out[0].sentences)
    heat, iso = out[1], out[2]
    assert isinstance(heat, blocks.HeatMap) and heat.thresholds == (30.0, 40.0)
    assert heat.rows == technique_rows() and heat.columns == [axis.words for axis in AXES if axis.mode == "dvr"]
    # The iso axes in a map of their own, with the techniques that render iso-surfaces.
    assert isinstance(iso, blocks.HeatMap) and iso.columns == [axis.words for axis in AXES if axis.mode == "iso"]
    assert set(iso.rows) == ISO_BACKENDS | {SAMPLED_ISO} and "without an iso-surface mode: shearwarp" in iso.caption
    figures = [b for b in out if isinstance(b, blocks.Figure)]
    assert {f.anchor for f in figures} == {"atlas-min_opacity", "atlas-angle", "atlas-step"}
    assert all((report_dir / f.path).is_file() for f in figures)
    galleries = [b for b in out if isinstance(b, blocks.Gallery)]
    assert all(item.difference for g in galleries for item in g.items)
    assert isinstance(out[-1], blocks.Table) and len(out[-1].frame) == len(_synthetic())


def test_sphere_shell_keeps_a_layer_of_the_given_thickness():
    import datasets

    solid = datasets.load("sphere", size=24, cache_dir=False).data
    thin, thick = (datasets.load("sphere", size=24, cache_dir=False, shell=t).data for t in (1, 4))
    assert (thin > 100).sum() < (thick > 100).sum() < (solid > 100).sum()
    assert thin[12, 12, 12] == thick[12, 12, 12] == 0 < solid[12, 12, 12]  # hollow
    with pytest.raises(InputError, match="sphere shell"):
        datasets.load("sphere", size=16, cache_dir=False, shell=-1)


@pytest.mark.parametrize("scale", ["smoke", "default", "full"])
def test_iso_axes_run_the_iso_backends_and_the_sampled_hit_beside_the_exact_one(scale):
    runs = [r for r in _runs(scale) if r.tags["axis"] in ("iso-step", "thin")]
    assert all(r.scene["mode"] == "iso" for r in runs)
    for key in ("iso-step", "thin"):
        tests = [r for r in runs if r.tags["axis"] == key and r.tags["role"] == "test"]
        assert {_technique(r) for r in tests} == ISO_BACKENDS | {SAMPLED_ISO}, key
        assert all(r.options == {"iso_hit": "sampled", **({"step_factor": r.tags["value"]} if key == "iso-step" else {})}
                   for r in tests if _technique(r) == SAMPLED_ISO)
        assert all("iso_hit" not in r.options for r in tests if _technique(r) != SAMPLED_ISO)  # exact: the default
    steps = [r for r in runs if r.tags["axis"] == "iso-step" and r.tags["role"] == "test"]
    assert {r.options["step_factor"] for r in steps} == set(AXIS_BY_KEY["iso-step"].values[scale])
    thin = [r for r in runs if r.tags["axis"] == "thin" and r.tags["role"] == "truth"]
    assert [r.scene["volumes"][0]["params"]["radius"] for r in thin] == AXIS_BY_KEY["thin"].values[scale]
    assert all(r.scene["volumes"][0]["dataset"] == "tube" for r in thin)


def test_no_technique_fixes_an_option_its_axes_sweep():
    for label, technique in TECHNIQUES.items():
        assert all(AXIS_BY_KEY[key].option not in technique.options for key in technique.axes), label


def test_thin_axis_sees_the_tubes_obliquely_and_magnified():
    from core.camera import Camera
    from datasets.phantoms.tubes import TUBE_SPACING

    for value, spec, (view,) in points(AXIS_BY_KEY["thin"], [4.0, 0.25], size=48, image=64):
        camera = Camera(**{k: v for k, v in view.items() if k != "view"})
        sight = camera._offset_direction()
        assert 0.2 < abs(sight[2]) < 0.5  # neither along the tubes (z) nor square to them
        up = np.asarray(camera.up) / np.linalg.norm(camera.up)
        assert 0.9 < up[2] < 0.99  # rolled: the tubes slant across the pixel rows
        assert spec["camera"]["view_height"] == 3 * TUBE_SPACING  # the three tubes' slabs, not the whole box


def test_thin_axis_threshold_reads_in_voxels():
    rows = pd.DataFrame({"value": [4.0, 2.0, 1.0, 0.5, 0.25], "psnr": [45.0, 41.0, 36.0, 24.0, 19.0]})
    assert threshold(rows, AXIS_BY_KEY["thin"])["words"] == "tube radius ≤ 0.5 voxels"
    assert threshold(rows.assign(value=[2.0, 1.0, 0.5, 1.5, 0.375]).iloc[:2], AXIS_BY_KEY["thin"]) is None


def test_results_rows_are_named_by_technique():
    rows = [_row("gl-raycast", "thin", 0.25, 120.0), _row("gl-raycast", "thin", 0.25, 20.0, option_iso_hit="sampled"),
            _row("reference", "tf", 1.0, 35.0, option_classification="pre", option_step_factor=0.125)]
    assert atlas_rows(pd.DataFrame(rows)).backend.tolist() == ["gl-raycast", SAMPLED_ISO, PRE_CLASSIFIED]
    assert technique_rows().index(SAMPLED_ISO) == technique_rows().index("gl-raycast") + 1
    assert technique_rows()[-1] == PRE_CLASSIFIED


def test_exact_iso_hit_sees_the_thinnest_tube_that_sampling_steps_over(tmp_path):
    """The thin axis's R = 1/4 scene at 24³ and 32² (the tube covers 5 % of the pixels): measured 130 dB for the exact
    hit and 18 dB for the sampled hit at step 1, which misses most of the tube's pixels."""
    from renderers.gl import context
    from pipeline.scene_io import build_scene
    from reports.metrics import psnr

    ok, why = context.probe()
    if not ok:
        pytest.skip(f"no OpenGL 4.3 context through EGL here: {why}")
    ((_, spec, (view,)),) = points(AXIS_BY_KEY["thin"], [0.25], size=24, image=32)
    scene = build_scene(spec, cache_dir=tmp_path).with_camera(**{k: v for k, v in view.items() if k != "view"})
    truth = renderers.get("reference", step_factor=atlas_module.TRUTH_STEP).render(scene).image
    assert (truth[..., 3] > 0).mean() > 0.03  # the tubes cover a share of the picture
    exact = renderers.get("gl-raycast").render(scene).image
    sampled = renderers.get("gl-raycast", iso_hit="sampled", step_factor=1.0).render(scene).image
    assert psnr(truth, exact) >= 40.0
    assert psnr(truth, sampled) <= 25.0


def test_overlapping_iso_surfaces_run_where_several_volumes_render_iso():
    reasons = left_out()
    runs = [r for r in _runs("default") if r.tags["axis"] == "iso-volumes"]
    # vtk-gpu refuses several volumes outside dvr when it checks a scene (its capabilities cannot say so): its runs
    # are planned and recorded as skipped with that reason, which its heat-map cell shows.
    assert {_technique(r) for r in runs if r.tags["role"] == "test"} == {"cl-tiled", "vtk-gpu"}
    assert reasons[("gl-raycast", "iso-volumes")].startswith("2 volumes: ") and reasons[(SAMPLED_ISO, "iso-volumes")]
    truths = [r for r in runs if r.tags["role"] == "truth"]
    assert [len(r.scene["volumes"]) for r in truths] == [1, 2, 4]
    assert all(v["isovalue"] == CLOUD_ISOVALUE for r in truths for v in r.scene["volumes"])


def test_cl_tiled_renders_overlapping_iso_surfaces_as_the_reference(tmp_path):
    """The axis's two-cloud point at 24³ and 32²: measured (PoCL) 133 dB against the exact reference."""
    from pipeline.scene_io import build_scene
    from renderers.cl import context
    from reports.metrics import psnr

    ok, why = context.probe(context.selector_for(None))
    if not ok:
        pytest.skip(f"no OpenCL device here: {why}")
    (_, (_, spec, (view,))) = points(AXIS_BY_KEY["iso-volumes"], [1.0, 2.0], size=24, image=32)
    scene = build_scene(spec, cache_dir=tmp_path).with_camera(**{k: v for k, v in view.items() if k != "view"})
    truth = renderers.get("reference", step_factor=atlas_module.TRUTH_STEP).render(scene).image
    assert (truth[..., 3] > 0).mean() > 0.1
    assert psnr(truth, renderers.get("cl-tiled").render(scene).image) >= 45.0
