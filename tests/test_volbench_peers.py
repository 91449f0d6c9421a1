"""volbench-peers: the plan (every backend, VTK matched and default), ratios to VTK and the claims."""

import pandas as pd
import pytest

import renderers
from core.errors import InputError
from pipeline import experiments
from pipeline.experiments import Profile
from pipeline.experiments import volbench
from pipeline.experiments.volbench import peers as P

NAME = "volbench-peers"


def _profile(**settings):
    return Profile(name="t", volume_size=16, image_size=24, warmup=0, repeat=1, experiments=[NAME],
                   settings={NAME: settings} if settings else {})


def _runs(**settings):
    return [r for r in experiments.plan(_profile(**settings)).values() if r.experiment == NAME]


def test_every_backend_renders_every_scene_and_size_against_one_truth():
    runs = _runs(scenes=["skull", "engine-mip"], image_sizes=[32, 64], matched_scenes=["sphere"])
    timed = [r for r in runs if r.tags["part"] == "timed"]
    truths = [r for r in timed if r.tags["role"] == "truth"]
    assert {(r.tags["scene"], r.tags["image_size"]) for r in truths} == {(s, i) for s in ("skull", "engine-mip")
                                                                         for i in (32, 64)}
    assert all(r.backend == "reference" and r.options["step_factor"] < 0.5 for r in truths)
    tests = [r for r in timed if r.tags["role"] == "test"]
    assert {r.backend for r in tests} == set(renderers.names())
    assert len(tests) == 4 * len(renderers.names())
    for run in tests:
        assert run.reference in {t.id for t in truths} and run.repeat >= 1
        assert run.scene["width"] == run.tags["image_size"]
        # VTK keeps its default early termination in the timed runs: what its users get.
        assert "early_termination" not in run.options
    matched = [r for r in runs if r.tags["part"] == "matched"]
    by_backend = {r.backend: r for r in matched}
    assert by_backend["vtk-gpu"].options["early_termination"] is False
    assert by_backend["vtk-gpu"].options["step_factor"] == by_backend["reference"].options["step_factor"]
    assert by_backend["vtk-gpu"].scene["shading"]["model"] == "none"


def test_unknown_scene_names_the_setting():
    with pytest.raises(InputError, match="volbench-peers.scenes"):
        _runs(scenes=["teapot"])
    with pytest.raises(InputError, match="volbench-peers.matched_scenes"):
        _runs(matched_scenes=["teapot"])


def test_no_runs_without_vtk(monkeypatch):
    monkeypatch.setattr(renderers, "BACKENDS", {"reference": renderers.BACKENDS["reference"]})
    assert not _runs()


def _row(backend, scene, time, psnr=45.0, part="timed", image=256):
    return {"run": f"{scene}.{backend}", "backend": backend, "scene": scene, "image_size": image, "part": part,
            "role": "test", "status": "ok", "time_total": time, "psnr": psnr, "technique": backend}


def test_ratios_to_vtk_are_per_scene_and_size():
    rows = pd.DataFrame([_row("vtk-gpu", "a", 0.01), _row("vtk-cpu", "a", 0.04), _row("shearwarp", "a", 0.02),
                         _row("vtk-gpu", "b", 0.02), _row("shearwarp", "b", 0.01), _row("shearwarp", "a", 0.5, image=512)])
    timed = P._timed(rows).set_index(["scene", "backend", "image_size"])
    assert timed.loc[("a", "shearwarp", 256), "over_vtk_gpu"] == pytest.approx(2.0)
    assert timed.loc[("a", "shearwarp", 256), "over_vtk_cpu"] == pytest.approx(0.5)
    assert timed.loc[("b", "shearwarp", 256), "over_vtk_gpu"] == pytest.approx(0.5)
    assert pd.isna(timed.loc[("b", "shearwarp", 256), "over_vtk_cpu"])  # no VTK CPU run on b
    assert pd.isna(timed.loc[("a", "shearwarp", 512), "over_vtk_gpu"])  # never across image sizes
    sentences = P._peer_takeaways(P._timed(rows))
    assert any(s.startswith("shearwarp takes") for s in sentences)


def test_matched_claims():
    claims = {c.id: c for c in experiments.get(NAME).claims}
    rows = pd.DataFrame([_row("vtk-gpu", "sphere", None, 70.0, "matched"), _row("vtk-gpu", "skull", None, 61.0, "matched"),
                         _row("vtk-cpu", "sphere", None, 45.0, "matched")])
    assert claims["vtk-gpu-matched"].evaluate(rows).holds is True
    assert claims["vtk-cpu-matched"].evaluate(rows).holds is True
    rows.loc[1, "psnr"] = 55.0
    rows.loc[2, "psnr"] = 35.0
    result = claims["vtk-gpu-matched"].evaluate(rows)
    assert result.holds is False and result.measured == "55 dB (skull)"   # the worst scene
    assert claims["vtk-cpu-matched"].evaluate(rows).holds is False
    assert claims["vtk-gpu-matched"].evaluate(rows[rows.backend == "vtk-cpu"]).holds is None


def test_the_smoke_scale_applies_without_profile_settings():
    smoke = P.Peers.scales["smoke"]
    runs = [r for r in experiments.plan(Profile(name="t", scale="smoke", experiments=[NAME])).values()]
    timed = [r for r in runs if r.tags["part"] == "timed"]
    assert {r.tags["scene"] for r in timed} == set(smoke["scenes"])
    assert {r.scene["width"] for r in runs} == set(smoke["image_sizes"])
    assert {r.tags["scene"] for r in runs if r.tags["part"] == "matched"} == set(smoke["matched_scenes"])


def test_peers_come_after_volbenchs_other_studies_in_its_paper():
    assert volbench.EXPERIMENTS[-1] is P.Peers and volbench.PAPER.experiments == volbench.EXPERIMENTS
    assert list(experiments.all_experiments())[:len(volbench.EXPERIMENTS)] == [cls.name for cls in volbench.EXPERIMENTS]
