"""Kainz et al. 2009's package: its experiments, their scales, and the helpers they share (methods, scenes)."""

import dataclasses
from pathlib import Path

import pandas as pd

import renderers
from pipeline import experiments
from pipeline.experiments import Profile
from pipeline.experiments.kainz2009 import EXPERIMENTS, PAPER
from pipeline.experiments.kainz2009.methods import PEEL, TILED, device_note, devices, frames_caption, peeling_missing
from pipeline.experiments.kainz2009.scenes import volume
from pipeline.experiments.kit.model import SCALES

ROOT = Path(__file__).resolve().parent.parent
NAMES = ("kainz2009-scaling", "kainz2009-depthcap", "kainz2009-table1", "kainz2009-depth", "kainz2009-ess",
         "kainz2009-step")
ABLATIONS = ("kainz2009-sorting", "kainz2009-media", "kainz2009-coverage")


def paper_twin(experiment, ours_id):
    """``(paper, ours)``: the claim judging the paper's number and our claim ``ours_id`` beside it (their names and
    places: test_kit_judging), the twin's statement ending "(paper)" as every kainz2009 twin's does."""
    claims = {c.id: c for c in experiment.claims}
    paper, ours = claims[f"{ours_id}-paper"], claims[ours_id]
    assert paper.statement.endswith("(paper)") and (paper.target, ours.target) == ("paper", "ours")
    return paper, ours


def _runs(**settings):
    profile = Profile(name="t", volume_size=16, image_size=24, warmup=0, repeat=1, experiments=list(NAMES),
                      settings=settings)
    return [r for r in experiments.plan(profile).values() if r.experiment.startswith("kainz2009")]


def test_experiments_are_registered_with_the_paper():
    registry = experiments.all_experiments()
    assert PAPER.id == "kainz2009" and PAPER.technique == TILED and PAPER.experiments == EXPERIMENTS
    assert [cls.name for cls in EXPERIMENTS] == [*NAMES, *ABLATIONS]
    for name in (*NAMES, *ABLATIONS):
        experiment = registry[name]
        assert experiment.paper == "kainz2009" and experiment.title and experiment.description
        assert experiment.claims and experiment.paper_table() is not None, name


def test_scales_set_only_the_settings_each_experiment_reads():
    for cls in EXPERIMENTS:
        assert set(cls.scales) <= set(SCALES), cls.name
        for scale, values in cls.scales.items():
            assert set(values) <= cls.settings, (cls.name, scale, set(values) - cls.settings)


def test_no_runs_without_the_tiled_backend(monkeypatch):
    monkeypatch.setattr(renderers, "BACKENDS", {"reference": renderers.BACKENDS["reference"]})
    assert not _runs()


def test_profiles_name_only_known_settings_and_smoke_stays_small():
    for profile in ("smoke", "default", "full"):
        experiments.check_settings(Profile.load(ROOT / "config" / f"{profile}.yaml"))
    smoke = dataclasses.replace(Profile.load(ROOT / "config" / "smoke.yaml"), experiments=list(NAMES))
    smoke = [r for r in experiments.plan(smoke).values() if r.experiment.startswith("kainz2009")]
    assert 0 < len(smoke) <= 72
    assert all(r.scene["width"] <= 64 and r.scene["height"] <= 64 for r in smoke)
    assert all(v.get("size", 0) <= 32 for r in smoke for v in r.scene["volumes"])


def test_ablation_experiments_stay_tiny_in_smoke():
    smoke = dataclasses.replace(Profile.load(ROOT / "config" / "smoke.yaml"), experiments=list(ABLATIONS))
    runs = [r for r in experiments.plan(smoke).values() if r.experiment in ABLATIONS]
    for name in ABLATIONS:
        assert 0 < sum(r.experiment == name for r in runs) <= 4, name
    assert all(r.scene["width"] <= 48 and r.scene["height"] <= 48 for r in runs)
    assert all(v.get("size", 0) <= 32 for r in runs for v in r.scene["volumes"])


def test_peeling_is_planned_when_registered_and_listed_as_missing_otherwise(monkeypatch):
    monkeypatch.setattr(renderers, "BACKENDS", {"gl-peel": "renderers.gl.not_here:Peel", **renderers.BACKENDS})
    runs = _runs(**{"kainz2009-scaling": {"counts": [1, 64]}})
    peel = {r.key for r in runs if r.backend == PEEL}
    assert "kainz2009-scaling/clouds.n64.gl-peel" in peel and "kainz2009-table1/C8.gl-peel" in peel
    assert not peeling_missing()
    monkeypatch.setattr(renderers, "BACKENDS", {k: v for k, v in renderers.BACKENDS.items() if k != "gl-peel"})
    assert "not registered" in peeling_missing()[0].text
    assert not [r for r in _runs() if r.backend == PEEL]


def test_device_note_and_caption_name_only_cl_tiled_device():
    rows = pd.DataFrame([{"backend": TILED, "cl_device": "pthread-Zen", "cl_device_type": "CPU", "info_frames": 3},
                         {"backend": "vtk-gpu", "cl_device": "Some GPU", "cl_device_type": "GPU", "info_frames": 3}])
    note = device_note(rows)[0]
    assert note.startswith("cl-tiled ran on pthread-Zen: a CPU OpenCL device") and "Some GPU" not in note
    assert "only ratios" not in device_note(rows.assign(cl_device_type="GPU"))[0]
    caption = frames_caption(rows)
    assert caption.startswith("median of 3 timed frames after warm-up") and caption.endswith("cl-tiled on pthread-Zen.")
    assert device_note(rows[rows.backend != TILED]) == [] and "cl-tiled on" not in frames_caption(rows.iloc[1:])


def test_devices_name_both_apis_and_a_software_rasteriser():
    rows = pd.DataFrame([{"backend": TILED, "cl_device": "pthread-Zen", "gl_renderer": "llvmpipe (LLVM 15)",
                          "gl_software_rasterizer": True},
                         {"backend": PEEL, "cl_device": "pthread-Zen", "gl_renderer": "llvmpipe (LLVM 15)",
                          "gl_software_rasterizer": True}])
    assert devices(rows) == "OpenCL on pthread-Zen; OpenGL on llvmpipe (LLVM 15) (a software rasteriser)"
    assert devices(rows.assign(gl_renderer="NVIDIA H100", gl_software_rasterizer=False)).endswith("on NVIDIA H100")
    assert devices(rows[["backend"]]) == "devices not recorded"


def test_volume_entry_is_a_phantom_named_in_the_scene():
    entry = volume("ct_skull", 32.0, "bone", "skull", transform={"scale": 0.5})
    assert entry == {"dataset": "ct_skull", "size": 32, "preset": "bone", "name": "skull", "transform": {"scale": 0.5}}
    assert type(entry["size"]) is int  # 32.0 would be another run (spec_hash)
