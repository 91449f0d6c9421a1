"""Krüger & Westermann 2003 experiments: planning, the paper's table and every claim on synthetic results."""

import dataclasses
import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import renderers
from pipeline import experiments
from pipeline.experiments import Profile
from pipeline.experiments import kruger2003 as K
from reports.imageio import write_exr

ROOT = Path(__file__).resolve().parent.parent
NAMES = ("kruger2003-table1", "kruger2003-nocue", "kruger2003-passes", "kruger2003-stability", "kruger2003-occluder")


@pytest.fixture
def gl_backends(monkeypatch):
    """The registry with the GL backends, whether or not their package is importable here."""
    monkeypatch.setattr(renderers, "BACKENDS", {"gl-raycast": "renderers.gl.not_here:RayCaster",
                                                "gl-slicer": "renderers.gl.not_here:Slicer", **renderers.BACKENDS})


def _profile(**settings):
    return Profile(name="t", volume_size=16, image_size=24, warmup=0, repeat=1, experiments=list(NAMES),
                   settings=settings)


# ------------------------------------------------------------------------------------ planning
def test_experiments_are_registered_with_the_paper():
    registry = experiments.all_experiments()
    for name in NAMES:
        experiment = registry[name]
        assert experiment.paper == "kruger2003" and experiment.title and experiment.description
        assert experiment.claims, name
    table = registry["kruger2003-table1"].paper_table()
    head = table[table["data set (paper)"] == "Head"].iloc[0]
    assert head["RC-b / RC"] == pytest.approx(23.4 / 4.8, abs=0.01) and head["RC-b / SBVR"] == pytest.approx(3.3, abs=0.01)


def test_no_runs_without_the_gl_backends(monkeypatch):
    monkeypatch.setattr(renderers, "BACKENDS", {"reference": renderers.BACKENDS["reference"]})
    assert not [r for r in experiments.plan(_profile()).values() if r.experiment.startswith("kruger2003")]


def test_plan_times_methods_and_renders_truth_once(gl_backends):
    runs = [r for r in experiments.plan(_profile()).values() if r.experiment.startswith("kruger2003")]
    assert {r.experiment for r in runs} == set(NAMES)
    for run in runs:
        if run.backend == "reference":
            assert (run.warmup, run.repeat) == (0, 1), run.key
        else:
            assert run.warmup >= 1 and run.repeat >= 3, run.key
            assert "step_factor" in run.options, run.key
            # The occluder's plane hides the volume on purpose: those images have no truth.
            assert (run.reference is None) == (run.experiment == "kruger2003-occluder"), run.key
    table1 = [r for r in runs if r.experiment == "kruger2003-table1" and r.backend != "reference"]
    assert {r.tags["config"] for r in table1} == set(K.METHODS)
    assert {r.tags["scene"] for r in table1} == set(K.TABLE1)
    headline = table1[0].views[0]
    assert headline["view"] == "headline" and len(table1[0].views) == 5  # headline + 4 orbit views
    # One step for every method of a scene: the claims compare like with like.
    assert len({r.options["step_factor"] for r in table1}) == 1
    sweep = [r for r in runs if r.tags.get("part") == "m-sweep"]
    assert sorted(r.options["samples_per_pass"] for r in sweep) == list(K.M_VALUES)


def test_profiles_name_only_known_settings_and_smoke_stays_small(gl_backends):
    for profile in ("smoke", "default", "full"):
        experiments.check_settings(Profile.load(ROOT / "config" / f"{profile}.yaml"))
    smoke = dataclasses.replace(Profile.load(ROOT / "config" / "smoke.yaml"), experiments=list(NAMES))
    smoke = list(experiments.plan(smoke).values())
    assert 0 < len(smoke) <= 48
    assert all(r.scene["width"] <= 64 for r in smoke)


def test_unknown_scene_is_an_error(gl_backends):
    from core.errors import InputError

    with pytest.raises(InputError, match="unknown.*bonsai"):
        experiments.plan(_profile(**{"kruger2003-table1": {"scenes": ["bonsai"]}}))


# -------------------------------------------------------------------------------------- claims
def _claim(experiment, claim_id):
    return next(c for c in experiments.get(experiment).claims if c.id == claim_id)


def _evaluate(experiment, claim_id, rows):
    return _claim(experiment, claim_id).evaluate(pd.DataFrame(rows))


def _table1_rows(times, scenes=("head", "engine"), psnr=45.0):
    rows = []
    for scene in scenes:
        for config, seconds in times[scene].items():
            rows.append({"scene": scene, "view": "headline", "role": "test", "config": config,
                         "time_total": seconds, "psnr": psnr, "run": f"{scene}.{config}"})
    return rows


PAPER_LIKE = {"head": {"sbvr": 1 / 7.1, "rc": 1 / 4.8, "rc-a": 1 / 14.4, "rc-b": 1 / 23.4},
              "engine": {"sbvr": 1 / 10.4, "rc": 1 / 6.3, "rc-a": 1 / 6.3, "rc-b": 1 / 13.6}}


def test_table1_claims_hold_on_the_papers_own_numbers():
    rows = _table1_rows(PAPER_LIKE)
    name = "kruger2003-table1"
    for claim in ("rc-slower-than-sbvr", "ert-gain-opaque", "ert-none-semi-transparent", "ess-gain",
                  "rcb-over-rc-head", "rcb-over-sbvr-head", "accuracy"):
        assert _evaluate(name, claim, rows).holds is True, claim
    assert _evaluate(name, "rcb-over-sbvr-head", rows).measured == "×3.3 (head)"
    assert "head: RC at ×0.676 of SBVR's speed" in _evaluate(name, "rc-slower-than-sbvr", rows).detail


def test_table1_claims_fail_where_the_numbers_do():
    slow = {"head": {"sbvr": 1.0, "rc": 0.9, "rc-a": 0.8, "rc-b": 0.8},
            "engine": {"sbvr": 1.0, "rc": 1.2, "rc-a": 0.5, "rc-b": 0.5}}
    rows = _table1_rows(slow, psnr=35.0)
    name = "kruger2003-table1"
    for claim in ("rc-slower-than-sbvr", "ert-gain-opaque", "ert-none-semi-transparent", "ess-gain",
                  "rcb-over-rc-head", "rcb-over-sbvr-head", "accuracy"):
        assert _evaluate(name, claim, rows).holds is False, claim
    assert _evaluate(name, "ert-gain-opaque", _table1_rows(slow, scenes=("engine",))).holds is None


def _write(path, image):
    write_exr(str(path), image.astype(np.float32))
    return str(path)


def test_image_pair_claims(tmp_path):
    base = np.zeros((8, 8, 4), np.float32)
    base[2:6, 2:6] = (0.5, 0.4, 0.3, 0.97)
    rows = []
    for config, image in (("rc", base), ("rc-a", base - np.float32(0.02) * (base > 0)), ("rc-b", None)):
        image = rows[-1]["image"] if image is None else image
        rows.append({"scene": "head", "view": "headline", "role": "test", "config": config, "image": image,
                     "exr": _write(tmp_path / f"{config}.exr", image), "option_opaque_threshold": 0.95})
    name = "kruger2003-table1"
    assert _evaluate(name, "ess-lossless", rows).holds is True
    assert _evaluate(name, "ert-bound", rows).holds is True  # 0.02 ≤ 1 − 0.95
    rows[1]["exr"] = _write(tmp_path / "far.exr", base * 0.5)
    assert _evaluate(name, "ert-bound", rows).holds is False
    assert _evaluate(name, "ess-lossless", rows).holds is False


def test_fragment_fraction_claim_needs_the_slicer_counters():
    rows = [{"scene": "head", "view": "headline", "role": "test", "config": "sbvr",
             "count_fragments": 1000, "count_fragments_contributing": 30}]
    name = "kruger2003-table1"
    assert _evaluate(name, "fragments-contribute", rows).holds is True
    rows[0]["count_fragments_contributing"] = 300
    assert _evaluate(name, "fragments-contribute", rows).holds is False
    del rows[0]["count_fragments_contributing"]
    assert _evaluate(name, "fragments-contribute", rows).holds is None


def test_nocue_claims():
    rows = [{"config": c, "time_total": t, "count_fragments_main": f}
            for c, t, f in (("rc", 1.0, 1000), ("rc-a", 1.3, 900), ("rc-b", 1.35, 890))]
    assert _evaluate("kruger2003-nocue", "overhead", rows).holds is True
    assert _evaluate("kruger2003-nocue", "no-empty-blocks", rows).holds is True
    rows[1]["time_total"] = 0.8
    rows[2]["count_fragments_main"] = 400
    assert _evaluate("kruger2003-nocue", "overhead", rows).holds is False
    assert _evaluate("kruger2003-nocue", "no-empty-blocks", rows).holds is False


def _record(tmp_path, name, counts):
    path = tmp_path / f"{name}.json"
    path.write_text(json.dumps({"views": [{"view": "headline", "info": {"fragments_per_main_pass": counts}}]}))
    return str(path)


def test_passes_claims(tmp_path):
    rows = [{"part": "passes", "role": "test", "config": "rc", "time_total": 2.0,
             "record": _record(tmp_path, "rc", [100, 100, 100, 100])},
            {"part": "passes", "role": "test", "config": "rc-a", "time_total": 1.0,
             "record": _record(tmp_path, "rca", [100, 80, 40, 10])},
            {"part": "iso", "role": "test", "config": "rc-a", "time_total": 0.5}]
    rows += [{"part": "m-sweep", "role": "test", "config": "rc-b", "m": m, "time_total": t}
             for m, t in ((1, 3.0), (8, 1.0), (64, 2.0))]
    name = "kruger2003-passes"
    for claim in ("rc-flat", "rca-falls", "iso-faster", "m-u-shape"):
        assert _evaluate(name, claim, rows).holds is True, claim
    assert _evaluate(name, "m-u-shape", rows).measured == "fastest at M = 8"
    rows[0]["record"] = _record(tmp_path, "rc2", [100, 90, 50, 20])
    rows[1]["record"] = _record(tmp_path, "rca2", [100, 100, 100, 90])
    rows[2]["time_total"] = 1.5
    rows[-1]["time_total"] = 0.5
    for claim in ("rc-flat", "rca-falls", "iso-faster", "m-u-shape"):
        assert _evaluate(name, claim, rows).holds is False, claim


def test_stability_claims():
    rows = [{"scene": "head", "sweep": "threshold", "value": t, "time_total": s, "psnr": p, "role": "test"}
            for t, s, p in ((0.8, 1.0, 35.0), (0.95, 1.2, 42.0), (1.0, 1.5, 50.0))]
    rows += [{"scene": "head", "sweep": "block", "value": b, "time_total": 1.0, "psnr": 44.0 + d, "role": "test"}
             for b, d in ((4, 0.0), (8, 0.05), (16, 0.0))]
    name = "kruger2003-stability"
    assert _evaluate(name, "threshold-trades-error", rows).holds is True
    assert _evaluate(name, "blocks-lossless", rows).holds is True
    rows[-1]["psnr"] = 40.0  # a block size that skips something visible
    assert _evaluate(name, "blocks-lossless", rows).holds is False
    rows[0]["psnr"] = 51.0
    assert _evaluate(name, "threshold-trades-error", rows).holds is False


def _occluder_rows(main_ms, fractions=(0.0, 0.5, 1.0), rays=1000, passes=10):
    rows = []
    for fraction, ms in zip(fractions, main_ms):
        occluded = round(fraction * rays)
        rows.append({"role": "test", "config": "rc", "fraction": fraction, "time_total": ms * 1.2e-3,
                     "time_main": ms * 1e-3, "count_rays": rays, "count_rays_occluded": occluded,
                     "count_passes_main": passes, "count_fragments_main": passes * (rays - occluded)})
    return rows


def test_occluder_plan_sweeps_coverage_for_rc_and_rca(gl_backends):
    runs = [r for r in experiments.plan(_profile()).values() if r.experiment == "kruger2003-occluder"]
    assert {(r.options["variant"], r.options["occluder"]) for r in runs} == {
        (v, f) for v in ("rc", "rc-a") for f in K.OCCLUDED}
    with pytest.raises(Exception, match="fractions"):
        experiments.plan(_profile(**{"kruger2003-occluder": {"fractions": [0, 1]}}))


def test_occluder_claims():
    name = "kruger2003-occluder"
    rows = _occluder_rows([10.0, 5.2, 0.4])
    assert _evaluate(name, "occluded-rays-culled", rows).holds is True
    assert _evaluate(name, "time-proportional", rows).holds is True
    rows[1]["count_fragments_main"] += 7  # a pass drew fragments of hidden rays
    assert _evaluate(name, "occluded-rays-culled", rows).holds is False
    assert _evaluate(name, "time-proportional", _occluder_rows([10.0, 9.5, 9.0])).holds is False  # no fall
    assert _evaluate(name, "time-proportional", _occluder_rows([10.0, 1.0, 0.9])).holds is False  # not linear


def test_device_sentence_and_ratios_per_device():
    rows = pd.DataFrame([{"config": c, "scene": "head", "view": "headline", "time_total": t, "gl_renderer": device,
                          "gl_software_rasterizer": device.startswith("llvmpipe")}
                         for device, scale in (("llvmpipe (LLVM 15)", 1.0), ("NVIDIA H100", 0.01))
                         for c, t in (("sbvr", 3.0 * scale), ("rc", 5.0 * scale), ("rc-a", 2.0 * scale),
                                      ("rc-b", 1.0 * scale))])
    software = K._device_takeaways(rows[rows.gl_renderer.str.startswith("llvmpipe")])
    assert "CPU rasterizer" in software[0] and "no GPU run" in software[0]
    both = K._device_takeaways(rows)
    assert "per device" in both[0] and "NVIDIA H100" in both[0]
    groups = dict(list(rows.groupby(K._devices(rows))))
    assert set(groups) == {"llvmpipe (LLVM 15)", "NVIDIA H100"}
    ratio = K._ratio_table(groups["NVIDIA H100"])
    assert ratio["RC-b / RC (ours)"].iloc[0] == pytest.approx(5.0)
