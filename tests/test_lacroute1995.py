"""The Lacroute 1995 experiments: run planning, views, claims and report blocks on synthetic tables."""

import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import renderers
from core.camera import Camera
from core.errors import InputError
from pipeline import experiments
from pipeline.experiments import Profile
from pipeline.experiments import common as C
from pipeline.experiments import lacroute1995 as L
from reports import blocks
from reports.html import ReportContext
from reports.imageio import write_exr

ROOT = Path(__file__).resolve().parent.parent
NAMES = ("lacroute1995-volpack", "lacroute1995-quality", "lacroute1995-matrix", "lacroute1995-angles",
         "lacroute1995-scaling", "lacroute1995-throughput", "lacroute1995-parallel", "lacroute1995-shading",
         "lacroute1995-projection", "lacroute1995-perspective")


@pytest.fixture
def all_backends(monkeypatch):
    """The registry with shearwarp and volpack, whether or not their packages are here yet."""
    monkeypatch.setattr(renderers, "BACKENDS", {"shearwarp": "renderers.shearwarp.renderer:ShearWarpRenderer",
                                                "volpack": "renderers.volpack.renderer:VolPackRenderer",
                                                **renderers.BACKENDS})


def _profile(**settings):
    return Profile(name="t", volume_size=16, image_size=24, warmup=0, repeat=1, experiments=list(NAMES),
                   settings=settings)


# ------------------------------------------------------------------------------------ planning
def test_experiments_are_registered_with_the_paper():
    registry = experiments.all_experiments()
    for name in NAMES:
        experiment = registry[name]
        assert experiment.paper == "lacroute1995" and experiment.title and experiment.description
        assert isinstance(experiment.settings, frozenset)
        assert experiment.claims, name
        table = experiment.paper_table()
        assert isinstance(table, pd.DataFrame) and not table.empty, name


def test_plan_times_comparisons_and_renders_truth_once(all_backends):
    runs = experiments.plan(_profile())
    ours = [r for r in runs.values() if r.experiment.startswith("lacroute1995")]
    assert {r.experiment for r in ours} == set(NAMES)
    for run in ours:
        if run.backend == "reference":  # ground truth: one untimed frame
            assert (run.warmup, run.repeat) == (0, 1), run.key
        elif run.warmup == 0:  # picture-only or cold (preprocessing) runs
            assert run.experiment in ("lacroute1995-quality", "lacroute1995-shading", "lacroute1995-perspective"), run.key
        else:  # timed comparisons: at least one warm-up and three timed frames, whatever the profile
            assert run.warmup >= 1 and run.repeat >= 3, run.key
        assert run.reference is None or f"{run.experiment}/{run.reference}" in runs


def test_runs_need_registered_backends(monkeypatch):
    monkeypatch.setattr(renderers, "BACKENDS", {"reference": renderers.BACKENDS["reference"]})
    runs = experiments.plan(_profile())
    assert not [r for r in runs.values() if r.experiment.startswith("lacroute1995")]
    missing = C.unregistered("shearwarp", "volpack")
    assert [what for what, _ in missing] == ["shearwarp", "volpack"]
    text = C.not_measurable(missing)[0].text
    assert "not registered" in text and "volpack" in text


def test_profile_settings_are_checked(all_backends):
    for name, settings in (("lacroute1995-volpack", {"scenes": ["head"]}),
                           ("lacroute1995-quality", {"datasets": ["nucleon"]}),
                           ("lacroute1995-matrix", {"datasets": ["nucleon"]}),
                           ("lacroute1995-angles", {"angle_step": 0}),
                           ("lacroute1995-throughput", {"brute_force": "some"}),
                           ("lacroute1995-parallel", {"schedules": ["random"]}),
                           ("lacroute1995-projection", {"datasets": ["nucleon"]}),
                           ("lacroute1995-projection", {"fov": 180}),
                           ("lacroute1995-perspective", {"fovs": [30]}),
                           ("lacroute1995-perspective", {"fovs": [30, 150]})):
        with pytest.raises(InputError, match=name):
            experiments.plan(_profile(**{name: settings}))
    with pytest.raises(InputError, match="unknown keys"):
        experiments.plan(_profile(**{"lacroute1995-angles": {"angle_steps": 10}}))
    for profile in ("smoke", "default", "full"):
        experiments.check_settings(Profile.load(ROOT / "config" / f"{profile}.yaml"))


def test_smoke_profile_stays_small(all_backends):
    runs = experiments.plan(Profile.load(ROOT / "config" / "smoke.yaml"))
    ours = [r for r in runs.values() if r.experiment.startswith("lacroute1995")]
    assert len(ours) <= 56  # about four minutes of jobs on two cores (16–32³ volumes, 48² images)
    assert all(len(r.views) <= 8 for r in ours)


def test_plan_contents(all_backends):
    runs = experiments.plan(_profile(**{
        "lacroute1995-throughput": {"cube_alphas": [0.1, 0.5, 1.0], "checker_blocks": [4, 2, 1],
                                    "checker_alphas": ["all-visible", 1.0], "brute_force": "ends", "predict": ["ct_skull"]},
        "lacroute1995-parallel": {"workers": [1, 2], "task_sizes": [1, 8, 64]},
        "lacroute1995-angles": {"angle_step": 30}}))
    matrix = [r for r in runs.values() if r.experiment == "lacroute1995-matrix"]
    assert {r.tags["config"] for r in matrix} == set(L.MATRIX_CONFIGS)
    brute = [r for r in matrix if r.tags["config"] == "brute-force"]
    assert all(r.options == {"rle": False, "early_termination": False} for r in brute)
    throughput = [r for r in runs.values() if r.experiment == "lacroute1995-throughput"]
    # ends: brute force at the first and last opacity of the cubes and block of each checker series
    assert sum(r.tags["config"] == "brute-force" for r in throughput) == 2 + 2 * 2
    assert all(r.options["min_opacity"] < 0.1 / 2 for r in throughput if "min_opacity" in r.options)
    values = {r.scene["volumes"][0]["params"]["value"] for r in throughput if r.tags.get("series", "").startswith("checker")}
    assert values == {round(L.all_visible_alpha(16) * 255), 255}
    parallel = [r for r in runs.values() if r.experiment == "lacroute1995-parallel"]
    assert {(r.options["workers"], r.options["schedule"], r.options["task_size"]) for r in parallel} >= {
        (1, "round-robin-steal", 8), (2, "contiguous", 8), (2, "round-robin-steal", 64)}
    angles = next(r for r in runs.values() if r.key == "lacroute1995-angles/sphere.turn")
    assert [v["view"] for v in angles.views] == [f"deg{a}" for a in range(0, 360, 30)]
    quality = [r for r in runs.values() if r.experiment == "lacroute1995-quality"]
    skull = next(r for r in quality if r.id == "ct_skull.binary.shearwarp")
    assert "transfer_function" in skull.scene["volumes"][0] and "preset" not in skull.scene["volumes"][0]
    cube = [r for r in quality if r.id.startswith("cube.") and r.backend == "shearwarp"]
    assert {r.options["opacity_correction"] for r in cube} == {True, False}


def test_projection_and_perspective_plans(all_backends):
    runs = experiments.plan(_profile(**{"lacroute1995-projection": {"datasets": ["brainsmall", "ct_skull"],
                                                                    "angle_step": 90, "fov": 40},
                                        "lacroute1995-perspective": {"fovs": [60, 15]}}))
    projection = [r for r in runs.values() if r.experiment == "lacroute1995-projection"]
    assert {(r.tags["dataset"], r.tags["config"]) for r in projection} == {
        (d, c) for d in ("brainsmall", "ct_skull") for c in L.PROJECTION_CONFIGS}
    for run in projection:
        assert [v["view"] for v in run.views] == ["deg0", "deg90", "deg180", "deg270"]
        assert all(v["up"] == [0.0, 0.0, 1.0] for v in run.views)  # both are z-up: turned about the body axis
        camera = run.scene.get("camera", {})
        if run.tags["config"] == "perspective":
            assert camera == {"projection": "perspective", "fov_y": 40.0} and run.options == {"workers": 1}
        else:
            assert camera == {}
        if run.tags["config"] == "fast-classification":
            assert run.options == {"classification": "octree", "workers": 1}
    assert {r.tags["thesis_dataset"] for r in projection} == {"brainsmall", "head"}
    perspective = {r.id: r for r in runs.values() if r.experiment == "lacroute1995-perspective"}
    assert set(perspective) == {f"{f}.{role}" for f in ("parallel", "fov15", "fov60") for role in ("truth", "shearwarp")}
    assert perspective["fov15.shearwarp"].reference == "fov15.truth"
    assert perspective["fov60.truth"].scene["camera"] == {"projection": "perspective", "fov_y": 60.0}
    assert "camera" not in perspective["parallel.truth"].scene
    assert perspective["fov60.truth"].scene == perspective["fov60.shearwarp"].scene
    modes = {r.id: r.options for r in runs.values() if r.experiment == "lacroute1995-shading" and r.id.startswith("mode.")}
    assert modes["mode.shearwarp-octree-rle-cold"] == {"octree_rle_build": True}
    assert modes["mode.shearwarp-octree-cold"] == {"classification": "octree"}
    assert modes["mode.shearwarp-cold"] == {}


def test_scene_mappings_build(all_backends, tmp_path):
    """Every planned scene of a small profile is valid scene input (volumes not generated)."""
    from pipeline import scene_io

    runs = experiments.plan(_profile())
    for run in runs.values():
        if not run.experiment.startswith("lacroute1995"):
            continue
        scene_io._check_keys(run.scene, scene_io.SCENE_KEYS, where=run.key)
        for volume in run.scene["volumes"]:
            scene_io._check_keys(volume, scene_io.VOLUME_KEYS, where=run.key)
        for view in run.views:
            Camera(**{k: v for k, v in view.items() if k != "view"})


def test_principal_axis_switches_at_45_degrees():
    assert [L.principal_axis(a) for a in (0, 44, 45, 90, 134, 135, 224, 225, 314, 315, 359)] == \
        [0, 0, 1, 1, 1, 0, 0, 1, 1, 0, 0]


# ---------------------------------------------------------------------------------- helpers
def test_fits_recover_known_models():
    x = np.array([1.0, 2.0, 3.0, 5.0])
    assert L.fit_line(x, 2 * x + 1) == pytest.approx((2.0, 1.0, 1.0))
    rng = np.random.default_rng(1)
    visible, runs = rng.uniform(0, 1e6, 12), rng.uniform(0, 5e5, 12)
    seconds = visible / 2e7 + runs * 3e-9 + 1e-3
    a, b, c, r2 = L.fit_cost_model(visible, runs, seconds)
    assert (a, b, c, r2) == pytest.approx((2e7, 3e-9, 1e-3, 1.0), rel=1e-6)
    with pytest.raises(ValueError):
        L.fit_cost_model(visible[:3], runs[:3], seconds[:3])


def _write(path, image):
    write_exr(path, image.astype(np.float32))
    return str(path)


def _alpha_image(alpha):
    image = np.zeros(alpha.shape + (4,), np.float32)
    image[..., 3] = alpha
    image[..., :3] = alpha[..., None] * 0.8
    return image


def test_opacity_deficit_measures_optical_depth(tmp_path):
    tau = np.linspace(0.2, 2.5, 400).reshape(20, 20)
    reference = _write(tmp_path / "ref.exr", _alpha_image(1 - np.exp(-tau)))
    thin = _write(tmp_path / "thin.exr", _alpha_image(1 - np.exp(-tau / math.sqrt(2))))
    same = _write(tmp_path / "same.exr", _alpha_image(1 - np.exp(-tau)))
    assert L.opacity_deficit(reference, thin) == pytest.approx(1 - 1 / math.sqrt(2), abs=1e-3)
    assert L.opacity_deficit(reference, same) == pytest.approx(0.0, abs=1e-3)
    with pytest.raises(ValueError, match="missing"):
        L.opacity_deficit(reference, str(tmp_path / "nothing.exr"))


def test_worker_imbalance_reads_the_record(tmp_path):
    record = tmp_path / "run.json"
    record.write_text(json.dumps({"views": [{"view": "v", "info": {"worker_samples": [300, 100]}}]}))
    assert L.worker_imbalance(str(record), "v") == pytest.approx(0.5)
    with pytest.raises(ValueError):
        L.worker_imbalance(str(record), "other")


def test_cube_value_keeps_the_diagonal_unsaturated():
    for size in (16, 32, 128, 256):
        alpha = L.cube_value(size) / 255
        depth = -math.log(1 - alpha) * size * math.sqrt(3)
        assert 0.5 < 1 - math.exp(-depth) < 0.95


# ------------------------------------------------------------------------------------ claims
def _claim(experiment, claim_id):
    return next(c for c in experiments.get(experiment).claims if c.id == claim_id)


def _evaluate(experiment, claim_id, frame):
    return _claim(experiment, claim_id).evaluate(pd.DataFrame(frame))


def test_volpack_claims(tmp_path):
    base = np.zeros((8, 8, 4), np.float32)
    base[2:6, 2:6] = (0.5, 0.4, 0.3, 0.8)
    near = base.copy()
    near[3, 3, 0] += 0.004
    far = base.copy()
    far[2:6, 2:6, 0] = 0.0
    rows = [
        {"scene": "s", "role": "test", "config": "volpack-rle", "time_total": 0.010, "psnr": 40.0,
         "exr": _write(tmp_path / "vp.exr", base), "run": "vp"},
        {"scene": "s", "role": "test", "config": "volpack-octree", "time_total": 0.021, "psnr": 39.0,
         "exr": _write(tmp_path / "oct.exr", base), "run": "oct"},
        {"scene": "s", "role": "test", "config": "shearwarp-1", "time_total": 0.008, "psnr": 40.5,
         "exr": _write(tmp_path / "sw.exr", near), "run": "sw"},
        {"scene": "s", "role": "test", "config": "shearwarp-all", "time_total": 0.012, "psnr": 40.5,
         "exr": _write(tmp_path / "sw2.exr", near), "run": "sw2"},
    ]
    name = "lacroute1995-volpack"
    assert _evaluate(name, "speed-1-worker", rows).holds is True
    assert _evaluate(name, "speed-all-cores", rows).holds is False
    assert _evaluate(name, "images-agree", rows).holds is True
    assert _evaluate(name, "accuracy-parity", rows).holds is True
    assert _evaluate(name, "octree-vs-rle", rows).holds is True
    rows[2]["exr"] = _write(tmp_path / "far.exr", far)
    assert _evaluate(name, "images-agree", rows).holds is False
    missing = _evaluate(name, "speed-1-worker", [r for r in rows if not r["config"].startswith("volpack")])
    assert missing.holds is None and "volpack-rle" in missing.detail
    assert _evaluate(name, "beats-vtk-cpu", rows).holds is None  # no VTK run
    rows.append({"scene": "s", "role": "test", "config": "vtk-cpu-1", "time_total": 0.030, "psnr": 41.0,
                 "exr": _write(tmp_path / "vtk.exr", base), "run": "vtk"})
    beats = _evaluate(name, "beats-vtk-cpu", rows)
    assert beats.holds is True and "VTK 30 ms" in beats.detail
    rows[-1]["time_total"] = 0.004
    assert _evaluate(name, "beats-vtk-cpu", rows).holds is False


def _quality_rows(psnr, truth):
    rows = []
    for tf, values in psnr.items():
        for angle, value in zip((0, 22.5, 45), values):
            rows.append({"part": "classification", "role": "test", "tf": tf, "dataset": "engine", "truth": truth,
                         "view": f"az{angle:g}", "psnr": value})
    return rows


def test_quality_claims():
    good = {"smooth": [38, 37.5, 37], "binary": [33, 30, 26]}
    flat = {"smooth": [34, 30, 29], "binary": [33, 33, 32.5]}
    name = "lacroute1995-quality"
    # Head-on against the ground truth (post) and against the pre-classified caster are separate claims;
    # the angle claims are judged against the pre-classified caster, the thesis's comparison.
    mixed = _quality_rows(good, "post") + _quality_rows(flat, "pre")
    assert _evaluate(name, "smooth-0deg", mixed).holds is True
    assert _evaluate(name, "smooth-0deg-pre", mixed).holds is False
    assert _evaluate(name, "smooth-all-angles", mixed).holds is False
    assert _evaluate(name, "binary-45deg-aliasing", mixed).holds is False
    mixed = _quality_rows(flat, "post") + _quality_rows(good, "pre")
    assert _evaluate(name, "smooth-0deg", mixed).holds is False
    assert _evaluate(name, "smooth-0deg-pre", mixed).holds is True
    assert _evaluate(name, "smooth-all-angles", mixed).holds is True
    assert _evaluate(name, "binary-45deg-aliasing", mixed).holds is True
    assert _evaluate(name, "smooth-0deg-pre", _quality_rows(good, "post")).holds is None
    assert _evaluate(name, "uncorrected-too-transparent", mixed).holds is None


def test_opacity_correction_claims(tmp_path):
    tau = np.linspace(0.2, 2.5, 400).reshape(20, 20)
    rows = []
    for view, _az, _el, spacing in L.CUBE_VIEWS:
        truth = _write(tmp_path / f"{view}-truth.exr", _alpha_image(1 - np.exp(-tau)))
        rows.append({"part": "opacity", "role": "truth", "view": view, "exr": truth, "correction": "reference"})
        rows.append({"part": "opacity", "role": "test", "view": view, "correction": "on",
                     "exr": _write(tmp_path / f"{view}-on.exr", _alpha_image(1 - np.exp(-tau)))})
        rows.append({"part": "opacity", "role": "test", "view": view, "correction": "off",
                     "exr": _write(tmp_path / f"{view}-off.exr", _alpha_image(1 - np.exp(-tau / spacing)))})
    name = "lacroute1995-quality"
    assert _evaluate(name, "uncorrected-too-transparent", rows).holds is True
    assert _evaluate(name, "corrected-agrees", rows).holds is True
    for row in rows:  # "corrected" images that are uncorrected
        if row["correction"] == "on":
            row["exr"] = row["exr"].replace("-on", "-off")
    assert _evaluate(name, "corrected-agrees", rows).holds is False


def _matrix_rows(ratios, speedups, dataset="d"):
    configs = list(L.MATRIX_CONFIGS)
    return [{"dataset": dataset, "config": c, "count_samples": 1e6 * r, "time_total": 1.0 / s}
            for c, r, s in zip(configs, ratios, speedups)]


def test_matrix_claims():
    name = "lacroute1995-matrix"
    thesis = _matrix_rows([1, 0.78, 0.16, 0.028], [1, 1.03, 4.1, 9.9])
    for claim in ("sample-ratios", "early-termination-alone", "rle-alone", "rle-and-early-termination"):
        assert _evaluate(name, claim, thesis).holds is True, claim
    weak = _matrix_rows([1, 0.3, 0.5, 0.3], [1, 3.0, 1.2, 2.0])
    for claim in ("sample-ratios", "early-termination-alone", "rle-alone", "rle-and-early-termination"):
        assert _evaluate(name, claim, weak).holds is False, claim
    assert _evaluate(name, "rle-alone", thesis[:3]).holds is None  # a configuration missing


def _turn(times, dataset="sphere", axes=None):
    angles = np.arange(0, 360, 360 / len(times))
    rows = [{"dataset": dataset, "view": f"deg{a:g}", "time_total": t, "count_samples": 1e5 * t}
            for a, t in zip(angles, times)]
    if axes is not None:
        for row, axis in zip(rows, axes):
            row["info_principal_axis"] = axis
    return rows


def test_angle_claims():
    name = "lacroute1995-angles"
    angles = np.arange(0, 360, 10)
    smooth = 1.0 + 0.02 * np.cos(np.radians(4 * angles))
    head = 1.0 + 0.07 * np.cos(np.radians(2 * angles))
    rows = _turn(smooth) + _turn(head, "ct_skull")
    assert _evaluate(name, "no-axis-switch-jump", rows).holds is True
    assert _evaluate(name, "sphere-flat", rows).holds is True
    assert _evaluate(name, "head-varies-more", rows).holds is True
    jumpy = np.where([L.principal_axis(a) == 1 for a in angles], 1.3, 1.0) + 0.01 * np.cos(np.radians(angles))
    assert _evaluate(name, "no-axis-switch-jump", _turn(jumpy)).holds is False
    assert _evaluate(name, "no-axis-switch-jump-samples", rows).holds is True
    assert _evaluate(name, "no-axis-switch-jump-samples", _turn(jumpy)).holds is False
    assert _evaluate(name, "sphere-flat", _turn(jumpy)).holds is False
    # the backend's own axis choice takes precedence over the 45° rule
    reported = ["x" if a < 180 else "z" for a in angles]
    result = _evaluate(name, "no-axis-switch-jump", _turn(np.where(angles < 180, 1.3, 1.0), axes=reported))
    assert result.holds is False and result.measured.startswith("26.1 % at a switch")


def _scaling_rows(growth, warp_ratio=4.0):
    rows = []
    for n, t in zip((64, 128, 256), (0.01, 0.01 * growth, 0.01 * growth ** 2)):
        rows.append({"dataset": "b", "volume_size": n, "image_size": 256, "growth": 1, "time_total": t,
                     "time_warp": 0.004, "count_rle_bytes": 0.4 * n ** 3, "count_raw_bytes": n ** 3})
    for i, w in ((64, 0.004 / warp_ratio ** 2), (128, 0.004 / warp_ratio)):
        rows.append({"dataset": "b", "volume_size": 64, "image_size": i, "growth": 0, "time_total": 0.01,
                     "time_warp": w, "count_rle_bytes": 0.4 * 64 ** 3, "count_raw_bytes": 64 ** 3})
    return rows


def test_scaling_claims():
    name = "lacroute1995-scaling"
    good = _scaling_rows(4.0)
    for claim in ("n-squared-growth", "rle-memory", "warp-per-pixel", "warp-share"):
        assert _evaluate(name, claim, good).holds is True, claim
    cubic = _scaling_rows(8.0, warp_ratio=1.5)
    for row in cubic:
        row["count_rle_bytes"] = 5 * row["count_raw_bytes"]
    for claim in ("n-squared-growth", "rle-memory", "warp-per-pixel"):
        assert _evaluate(name, claim, cubic).holds is False, claim


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
        assert _evaluate(name, claim, rows).holds is True, claim
    slow = _throughput_rows(brute=0.002)  # brute force faster than everything: the RLE never pays
    assert _evaluate(name, "crossover", slow).holds is False
    assert _evaluate(name, "one-voxel-runs", slow).holds is False
    for row in rows:
        if row["series"] == "predict":
            row["time_total"] *= 2
    assert _evaluate(name, "cost-model", rows).holds is False


def _parallel_rows(t1=0.02, speedup=1.8, schedules=None, tasks=None, record=None):
    rows = [{"volume_size": 128, "workers": 1, "schedule": "round-robin-steal", "task_size": 8, "time_total": t1},
            {"volume_size": 128, "workers": 2, "schedule": "round-robin-steal", "task_size": 8,
             "time_total": t1 / speedup, "record": record, "view": "headline"}]
    for schedule, time in (schedules or {}).items():
        rows.append({"volume_size": 128, "workers": 2, "schedule": schedule, "task_size": 8, "time_total": time,
                     "record": record, "view": "headline"})
    for task, time in (tasks or {}).items():
        rows.append({"volume_size": 128, "workers": 2, "schedule": "round-robin-steal", "task_size": task,
                     "time_total": time})
    return rows


def test_parallel_claims(tmp_path):
    name = "lacroute1995-parallel"
    assert _evaluate(name, "speed-up", _parallel_rows()).holds is True
    assert _evaluate(name, "speed-up", _parallel_rows(speedup=1.1)).holds is False
    ordered = {"round-robin": 0.0115, "contiguous-steal": 0.012, "contiguous": 0.02}
    assert _evaluate(name, "schedule-order", _parallel_rows(schedules=ordered)).holds is True
    assert _evaluate(name, "schedule-order", _parallel_rows(schedules={**ordered, "contiguous": 0.009})).holds is False
    assert _evaluate(name, "schedule-order", _parallel_rows()).holds is None
    assert _evaluate(name, "task-size-u", _parallel_rows(tasks={1: 0.02, 64: 0.015})).holds is True
    assert _evaluate(name, "task-size-u", _parallel_rows(tasks={1: 0.005, 64: 0.015})).holds is False
    record = tmp_path / "r.json"
    record.write_text(json.dumps({"views": [{"view": "headline", "info": {"worker_samples": [105, 95]}}]}))
    rows = _parallel_rows(schedules={"contiguous": 0.02}, record=str(record))
    assert _evaluate(name, "load-imbalance", rows).holds is True
    assert _evaluate(name, "imbalance-order", rows).holds is False  # both 5 %: contiguous not worse


def test_variant_claims():
    name = "lacroute1995-shading"
    rows = [{"part": "baseline", "config": "lut, path-compression", "time_total": 0.01, "psnr": 45.0},
            {"part": "shading", "config": "procedural", "time_total": 0.04},
            {"part": "union", "config": "rank", "time_total": 0.0105},
            {"part": "mode", "config": "volpack-rle", "time_total": 0.01, "time_classify": 0.05, "time_render": 0.002},
            {"part": "mode", "config": "volpack-octree", "time_total": 0.01, "time_octree": 0.03, "time_render": 0.004}]
    for claim in ("lut-faster", "lut-accurate", "union-by-rank", "mode-switch"):
        assert _evaluate(name, claim, rows).holds is True, claim
    rows[1]["time_total"], rows[0]["psnr"], rows[2]["time_total"] = 0.012, 30.0, 0.008
    for claim in ("lut-faster", "lut-accurate", "union-by-rank"):
        assert _evaluate(name, claim, rows).holds is False, claim
    assert _evaluate(name, "mode-switch", rows[:3]).holds is None


def _mode_rows(octree_rle=(0.004, 0.01), octree_frame=0.02):
    """Cold mode runs: brute force classify 20 ms + RLE 10 ms, frame 10 ms; the octree's SAT and RLE build given."""
    sat, rle_build = octree_rle
    return [{"part": "mode", "config": "shearwarp", "time_total": 0.01, "time_classify": 0.02, "time_rle_build": 0.01,
             "count_rle_bytes": 1e5},
            {"part": "mode", "config": "shearwarp-octree-rle", "time_total": 0.01, "time_octree_build": 0.03,
             "time_sat_build": sat, "time_rle_build": rle_build},
            {"part": "mode", "config": "shearwarp-octree", "time_total": octree_frame, "time_octree_build": 0.03,
             "time_sat_build": 0.004, "time_octree_classify": 0.01, "count_octree_bytes": 2e4}]


def test_our_mode_switch_claims():
    name = "lacroute1995-shading"
    rows = _mode_rows()
    for claim in ("octree-rle-build", "fast-classification-render", "mode-switch-ours"):
        assert _evaluate(name, claim, rows).holds is True, claim
    result = _evaluate(name, "octree-rle-build", rows)
    assert result.measured.startswith("14 ms vs 30 ms")
    # The octree build takes longer than classify + encode; the octree frame is 6× the RLE frame.
    rows = _mode_rows(octree_rle=(0.025, 0.01), octree_frame=0.06)
    for claim in ("octree-rle-build", "fast-classification-render", "mode-switch-ours"):
        assert _evaluate(name, claim, rows).holds is False, claim
    # 0.004 + 0.06 = 64 ms after an edit against 40 ms for the RLE: the switch does not pay.
    assert _evaluate(name, "octree-rle-build", rows[:1] + rows[2:]).holds is None  # no octree-built RLE run
    rows[0].pop("time_classify")
    assert _evaluate(name, "mode-switch-ours", rows).holds is None  # a missing stage is not a pass
    table = L.mode_switch_table(pd.DataFrame(_mode_rows()))
    assert list(table["mode"]) == ["RLE, brute-force build", "RLE built from the octree", "fast classification"]
    assert np.allclose(table["after an edit (ms)"], [40.0, 24.0, 24.0])


def _projection_rows(perspective=2.3, octree=2.0, octree_bytes=2e5, datasets=(("brainsmall", "brainsmall"),
                                                                               ("ct_skull", "head"))):
    rows = []
    for dataset, thesis in datasets:
        for config, factor in (("parallel", 1.0), ("perspective", perspective), ("fast-classification", octree)):
            for index, angle in enumerate((0, 90, 180, 270)):
                rows.append({"dataset": dataset, "thesis_dataset": thesis, "config": config, "view": f"deg{angle}",
                             "time_total": 0.01 * factor * (1 + 0.1 * index), "count_raw_bytes": 1e6,
                             "count_rle_bytes": 3e5 if config != "fast-classification" else 1e5,
                             **({"count_octree_bytes": octree_bytes} if config == "fast-classification" else {})})
    return rows


def test_projection_claims():
    name = "lacroute1995-projection"
    rows = _projection_rows()
    summary = L.projection_summary(pd.DataFrame(rows))
    assert list(summary.config[:3]) == list(L.PROJECTION_CONFIGS) and set(summary.views) == {4}
    parallel = summary[(summary.dataset == "brainsmall") & (summary.config == "parallel")].iloc[0]
    assert math.isclose(parallel["mean"], 0.0115) and math.isclose(parallel.fastest, 0.01)
    assert math.isclose(parallel.slowest, 0.013)
    head = summary[(summary.dataset == "ct_skull") & (summary.config == "perspective")].iloc[0]
    assert math.isclose(head["time / parallel"], 2.3) and math.isclose(head["thesis time / parallel"], 2.35 / 0.87)
    for claim in ("perspective-cost", "fast-classification-cost", "fast-classification-memory"):
        assert _evaluate(name, claim, rows).holds is True, claim
    assert _evaluate(name, "perspective-cost", rows).measured == "×2.3 (brainsmall), ×2.3 (ct_skull)"
    # What the backend engineer measured on small volumes: octree mode 4–7× the RLE.
    rows = _projection_rows(perspective=1.2, octree=5.5, octree_bytes=4e6)
    for claim in ("perspective-cost", "fast-classification-cost", "fast-classification-memory"):
        assert _evaluate(name, claim, rows).holds is False, claim
    only_parallel = [r for r in rows if r["config"] == "parallel"]
    assert _evaluate(name, "perspective-cost", only_parallel).holds is None
    assert _evaluate(name, "fast-classification-memory", only_parallel).holds is None


def _fov_rows(psnrs, parallel=40.0):
    rows = [{"role": "test", "dataset": "ct_skull", "fov": 0.0, "psnr": parallel, "ssim": 0.99, "view": "headline"}]
    for fov, psnr in psnrs.items():
        rows.append({"role": "test", "dataset": "ct_skull", "fov": fov, "psnr": psnr, "ssim": 0.98, "view": "headline",
                     "info_max_ray_angle": fov / 2 + 10})
        rows.append({"role": "truth", "dataset": "ct_skull", "fov": fov, "view": "headline"})
    return rows


def test_perspective_claims():
    name = "lacroute1995-perspective"
    rows = _fov_rows({15: 39.5, 30: 38.0, 60: 36.0, 90: 33.0})
    for claim in ("quality-falls-with-fov", "narrow-fov-like-parallel"):
        assert _evaluate(name, claim, rows).holds is True, claim
    assert _evaluate(name, "quality-falls-with-fov", rows).measured == "6.5 dB lower at 90° than at 15°"
    # A 2 dB rise from 30° to 60° breaks the trend; a 15° image 3 dB off the parallel one is not "alike".
    rows = _fov_rows({15: 37.0, 30: 35.0, 60: 37.0, 90: 33.0})
    for claim in ("quality-falls-with-fov", "narrow-fov-like-parallel"):
        assert _evaluate(name, claim, rows).holds is False, claim
    assert _evaluate(name, "quality-falls-with-fov", _fov_rows({15: 39.5, 90: 39.0})).holds is False  # < 1 dB
    assert _evaluate(name, "quality-falls-with-fov", _fov_rows({15: 39.5})).holds is None
    assert _evaluate(name, "narrow-fov-like-parallel", _fov_rows({15: 39.5})[1:]).holds is None
    assert list(L.fov_rows(pd.DataFrame(_fov_rows({60: 36.0, 15: 39.5}))).fov) == [0.0, 15.0, 60.0]


# ------------------------------------------------------------------------------------ reports
def _context(tmp_path, name):
    report = tmp_path / "report"
    (report / "csv").mkdir(parents=True)
    return ReportContext(report, tmp_path, name)


def _finish(rows, name):
    frame = pd.DataFrame(rows)
    frame["experiment"], frame["status"] = name, "ok"
    frame["run"] = [f"r{i}" for i in range(len(frame))]
    for column in ("time_total_min", "time_total_max"):
        frame[column] = frame.time_total * (0.9 if column.endswith("min") else 1.1)
    return frame


@pytest.mark.parametrize("name,rows", [
    ("lacroute1995-matrix", _matrix_rows([1, 0.78, 0.16, 0.028], [1, 1.03, 4.1, 9.9])),
    ("lacroute1995-angles", _turn(1.0 + 0.02 * np.cos(np.radians(4 * np.arange(0, 360, 10))))),
    ("lacroute1995-scaling", _scaling_rows(4.0)),
    ("lacroute1995-throughput", _throughput_rows()),
    ("lacroute1995-parallel", _parallel_rows(schedules={"round-robin": 0.0115, "contiguous-steal": 0.012,
                                                        "contiguous": 0.02}, tasks={1: 0.02, 64: 0.015})),
    ("lacroute1995-projection", _projection_rows()),
    ("lacroute1995-perspective", [{**r, "time_total": 0.1, "reference": "none"} for r in _fov_rows({15: 39.5, 30: 38.0, 60: 36.0, 90: 33.0})]),
])
def test_reports_write_their_charts(tmp_path, name, rows):
    frame = _finish(rows, name)
    for column, value in (("view", "headline"), ("png", ""), ("exr", ""), ("record", "")):
        if column not in frame:
            frame[column] = value
    if name == "lacroute1995-parallel":
        frame["study"] = "workers"
    out = experiments.get(name).report(frame, _context(tmp_path, name))
    kinds = {type(b) for b in out}
    assert blocks.Takeaways in kinds and blocks.Figure in kinds, name
    takeaways = next(b for b in out if isinstance(b, blocks.Takeaways))
    assert takeaways.sentences, name
    for figure in (b for b in out if isinstance(b, blocks.Figure)):
        svg = (tmp_path / "report" / figure.path).read_text()
        assert "no data" not in svg, (name, figure.path)
