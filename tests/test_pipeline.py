"""The pipeline's steps in-process on tiny runs, and the Snakemake DAG in a dry run."""

import hashlib
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import renderers
from pipeline.collect import collect
from pipeline.experiments import Profile, Run
from pipeline.experiments.volbench.phantoms import PhantomGallery
from pipeline import jobs
from pipeline.rendering import execute
from pipeline.records import image_digest, metrics_record_path, run_record_path
from renderers.base import Capabilities, Renderer
from reports.imageio import write_exr

ROOT = Path(__file__).resolve().parent.parent
SCENE = {"width": 12, "height": 10, "shading": {"model": "phong"},
         "volumes": [{"dataset": "sphere", "size": 12}]}
VIEWS = ({"view": "front"}, {"view": "side", "azimuth": 90.0})


class Exploding(Renderer):
    name = "exploding"
    capabilities = Capabilities(shading=frozenset({"none", "phong"}))

    def _render(self, scene):
        raise RuntimeError("kaboom")


class NoPhong(Renderer):
    name = "nophong"
    capabilities = Capabilities(reasons={"shading": "this test backend has no lighting"})

    def _render(self, scene):
        raise AssertionError("must be refused before rendering")


@pytest.fixture
def profile(tmp_path, monkeypatch):
    monkeypatch.setitem(renderers.BACKENDS, "exploding", f"{__name__}:Exploding")
    monkeypatch.setitem(renderers.BACKENDS, "nophong", f"{__name__}:NoPhong")
    return Profile(name="t", volume_size=12, results=str(tmp_path / "results"), cache=str(tmp_path / "cache"))


def _run(run_id, backend, **kw):
    return Run("volbench-phantoms", run_id, backend, SCENE, VIEWS, **kw)


def test_execute_evaluate_collect(profile, capsys):
    truth = _run("sphere.truth", "reference", options={"step_factor": 0.125})
    coarse = _run("sphere.coarse", "reference", options={"step_factor": 1.0}, reference="sphere.truth",
                  tags={"dataset": "sphere", "preset": "opaque", "kind": "phantom"},
                  statistics={"dataset": "sphere", "size": 12})
    failed = _run("sphere.failed", "exploding", reference="sphere.truth")
    skipped = _run("sphere.skipped", "nophong", reference="sphere.truth")
    records = {run.id: execute(run, profile=profile) for run in (truth, coarse, failed, skipped)}

    assert records["sphere.coarse"]["status"] == "ok"
    assert records["sphere.coarse"]["options"]["effective_step"] is not None
    assert records["sphere.coarse"]["statistics"]["size"] == 12
    assert records["sphere.failed"]["status"] == "failed" and "kaboom" in records["sphere.failed"]["reason"]
    assert records["sphere.skipped"]["status"] == "skipped"
    assert "no lighting" in records["sphere.skipped"]["reason"]
    view = records["sphere.coarse"]["views"][1]
    assert view["timings"]["total"] > 0 and view["info"]["frames"] == coarse.repeat
    assert Path(view["exr"]).exists() and Path(view["png"]).exists()
    for kind in ("exr", "png"):  # what the next workflow start checks the images against
        assert view["digests"][kind] == image_digest(view[kind])
        assert view["digests"][kind]["sha256"] == hashlib.sha256(Path(view[kind]).read_bytes()).hexdigest()

    results = profile.results
    # The evaluate job: every run of the experiment against its reference, in one process.
    pairs = [[str(run_record_path(results, run.experiment, run.id)), str(run_record_path(results, truth.experiment, truth.id)),
              str(metrics_record_path(results, run.experiment, run.id))] for run in (coarse, failed)]
    jobs.main(["evaluate", "--pairs", json.dumps(pairs)])
    assert capsys.readouterr().out == ""  # a job says what failed only: the progress line says the rest
    metrics = json.loads(metrics_record_path(results, coarse.experiment, coarse.id).read_text())
    assert metrics["status"] == "ok" and 0 < metrics["views"]["side"]["rmse"] < 0.2
    assert json.loads(metrics_record_path(results, failed.experiment, failed.id).read_text())["status"] == "skipped"

    paths = [run_record_path(results, r.experiment, r.id) for r in (truth, coarse, failed, skipped)]
    frame, claims = collect(paths, [PhantomGallery()], results_dir=results)
    assert set(frame.status) == {"ok", "failed", "skipped"}
    ok = frame[frame.run == "sphere.coarse"]
    assert sorted(ok.view) == ["front", "side"]
    assert {"time_total", "time_total_min", "time_total_max", "count_samples", "rmse", "ssim", "flip",
            "stat_nontransparent_fraction", "cpu_model", "git_commit", "pkg_numpy"} <= set(frame.columns)
    assert len(frame[frame.run == "sphere.failed"]) == 1  # recorded, not dropped
    assert (Path(results) / "runs.csv").exists() and (Path(results) / "claims.csv").exists()
    assert len(claims) == len(PhantomGallery().claims)


def test_an_unreadable_image_is_its_runs_metrics_failure_and_the_other_runs_are_compared(tmp_path, capsys):
    def record(run_id, views=("front", "side")):
        image_dir = tmp_path / "runs" / run_id
        image_dir.mkdir(parents=True)
        entries = []
        for name in views:
            image = np.full((6, 6, 4), 0.5 if run_id == "truth" else 0.4, np.float32)
            write_exr(image_dir / f"{name}.exr", image)
            entries.append({"view": name, "exr": str(image_dir / f"{name}.exr")})
        path = tmp_path / "runs" / f"{run_id}.json"
        path.write_text(json.dumps({"experiment": "e", "run": run_id, "status": "ok", "reason": "", "views": entries}))
        return str(path)

    truth, damaged, intact = record("truth"), record("damaged"), record("intact")
    front = tmp_path / "runs" / "damaged" / "front.exr"
    front.write_bytes(front.read_bytes()[:40])  # truncated beside its valid record
    pairs = [[damaged, truth, str(tmp_path / "metrics" / "damaged.json")],
             [intact, truth, str(tmp_path / "metrics" / "intact.json")]]
    jobs.main(["evaluate", "--pairs", json.dumps(pairs)])  # does not stop at the damaged run
    said = capsys.readouterr().out.splitlines()  # the failed comparison only, with its reason
    assert len(said) == 1 and said[0].startswith("e/damaged: metrics failed: cannot compare with the reference")
    metrics = json.loads((tmp_path / "metrics" / "damaged.json").read_text())
    assert metrics["reason"].startswith(f"cannot compare with the reference: view front: {front}: cannot read image")
    assert set(metrics["views"]) == {"side"}  # the view it could compare
    assert json.loads((tmp_path / "metrics" / "intact.json").read_text())["views"]["front"]["rmse"] == pytest.approx(0.1)


def test_missing_real_data_is_a_recorded_skip(profile, tmp_path):
    from dataclasses import replace

    run = Run("volbench-phantoms", "cthead.bone", "reference", {"volumes": [{"dataset": "cthead"}]}, ({"view": "v"},))
    record = execute(run, profile=replace(profile, real_data=str(tmp_path / "nowhere")))
    assert record["status"] == "skipped" and "nowhere" in record["reason"]


def test_report_from_collected_results(profile):
    from reports.html import build_report

    truth = _run("sphere.truth", "reference", options={"step_factor": 0.5},
                 tags={"dataset": "sphere", "preset": "opaque", "kind": "phantom"},
                 statistics={"dataset": "sphere", "size": 12})
    execute(truth, profile=profile)
    frame, claims = collect([run_record_path(profile.results, truth.experiment, truth.id)], [PhantomGallery()],
                            results_dir=profile.results)
    index = build_report(pd.read_csv(Path(profile.results) / "runs.csv"), claims, [PhantomGallery()],
                         results_dir=profile.results, environment={"cpu_model": "test cpu"})
    page = (index.parent / "volbench.html").read_text()
    assert "test cpu" in (index.parent / "appendix.html").read_text() and "volbench-phantoms" in page
    images = list((index.parent / "img").rglob("*.png"))
    assert images and all(f'src="{p.relative_to(index.parent)}"' in page for p in images)


@pytest.mark.integration
def test_snakemake_dry_run_plans_every_job(tmp_path):
    out = subprocess.run([sys.executable, "-m", "snakemake", "--dry-run", "--cores", "1", "--quiet", "rules",
                          "--configfile", "config/smoke.yaml",
                          "--config", f"results={tmp_path}/results", f"cache={tmp_path}/cache"],
                         cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr[-2000:]
    for rule in ("render", "evaluate", "collect", "report"):
        assert rule in out.stdout + out.stderr, rule
