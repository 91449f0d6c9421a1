"""The render-job time limit, retries of failed runs and the code digests that trigger reruns."""

import json
import os
import shutil
import subprocess
import sys
import time
from dataclasses import asdict, replace
from pathlib import Path

import numpy as np
import pytest

import renderers
from core.errors import InputError
from pipeline import rendering, runner
from pipeline.experiments import Profile, Run
from pipeline.runner import execute_limited, image_digest, mark_retry, run_record_path, time_limit_reason
from renderers.base import Capabilities, Renderer
from reports.imageio import write_exr, write_png

ROOT = Path(__file__).resolve().parent.parent
SCENE = {"width": 8, "height": 8, "volumes": [{"dataset": "sphere", "size": 8}]}


class Hanging(Renderer):
    """Spins like a kernel on NaN rays: never returns, ignores signals' Python handlers."""

    name = "hanging"
    capabilities = Capabilities()

    def _render(self, scene):
        while True:
            time.sleep(0.05)


class Crashing(Renderer):
    name = "crashing"
    capabilities = Capabilities()

    def _render(self, scene):
        os._exit(9)  # dies like a segfault in native code: no record, no exception


@pytest.fixture
def profile(tmp_path, monkeypatch):
    # The child process is spawned fresh: it gets these registry entries from its parent.
    monkeypatch.setitem(renderers.BACKENDS, "hanging", f"{__name__}:Hanging")
    monkeypatch.setitem(renderers.BACKENDS, "crashing", f"{__name__}:Crashing")
    return Profile(name="t", volume_size=8, results=str(tmp_path / "results"), cache=str(tmp_path / "cache"),
                   render_time_limit=120)


def _run(run_id, backend, **kw):
    return Run("volbench-phantoms", run_id, backend, SCENE, ({"view": "front"},), warmup=0, repeat=1, **kw)


@pytest.mark.parametrize("start_method", runner.START_METHODS)
def test_a_hanging_job_is_killed_at_the_limit_and_recorded_as_failed(profile, start_method):
    limited = replace(profile, render_time_limit=3)
    started = time.monotonic()
    record = execute_limited(_run("stuck", "hanging"), profile=limited, start_method=start_method)
    elapsed = time.monotonic() - started
    assert record["status"] == "failed"
    assert record["reason"] == "exceeded the profile's render_time_limit of 3 s" == time_limit_reason(3)
    assert 3 <= elapsed < 15
    on_disk = json.loads(run_record_path(limited.results, "volbench-phantoms", "stuck").read_text())
    assert on_disk["status"] == "failed" and on_disk["reason"] == record["reason"]
    # The rest of the pipeline goes on: the next run in the same process renders normally.
    ok = execute_limited(_run("fine", "reference", options={"step_factor": 1.0}), profile=profile)
    assert ok["status"] == "ok", ok["reason"]
    assert Path(ok["views"][0]["exr"]).is_file()


@pytest.mark.parametrize("start_method", runner.START_METHODS)
def test_a_crashed_render_process_is_recorded_as_failed(profile, start_method):
    record = execute_limited(_run("crash", "crashing"), profile=profile, start_method=start_method)
    assert record["status"] == "failed" and "exit code 9" in record["reason"]


def test_a_render_job_forks_its_limited_run(profile):
    # The Snakefile's render job: a fresh process that forks the run (Numba compiled in the child).
    run = _run("job", "reference", options={"step_factor": 1.0})
    job = subprocess.run([sys.executable, "-m", "pipeline.jobs", "render", "--run", json.dumps(run.as_dict()),
                          "--profile", json.dumps(asdict(profile))], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert job.returncode == 0, job.stderr
    record = json.loads(run_record_path(profile.results, run.experiment, run.id).read_text())
    assert record["status"] == "ok", record["reason"]
    assert Path(record["views"][0]["exr"]).is_file()


def test_start_method_is_checked(profile):
    with pytest.raises(InputError, match="start_method 'forkserver': use one of spawn, fork"):
        execute_limited(_run("x", "reference"), profile=profile, start_method="forkserver")


def test_an_error_in_the_child_is_recorded_with_its_message(profile):
    bad = Run("volbench-phantoms", "bad", "reference", {"volumes": [{"dataset": "sphere", "size": 8}],
                                                         "camera": {"up": [0, 0, 0]}}, ({"view": "v"},))
    record = execute_limited(bad, profile=profile)
    assert record["status"] == "failed" and "camera up: must be a non-zero vector" in record["reason"]


def test_no_limit_runs_in_process(profile, monkeypatch):
    calls = []
    monkeypatch.setattr(rendering, "execute", lambda run, **kw: calls.append(run) or {"status": "ok"})
    assert execute_limited(_run("x", "reference"), profile=replace(profile, render_time_limit=None)) == {"status": "ok"}
    assert len(calls) == 1


@pytest.mark.parametrize("value", [0, -5, "soon", float("inf")])
def test_render_time_limit_must_be_a_positive_number(value):
    mapping = {"name": "p", "scale": "smoke", "volume_size": 8, "image_size": 8, "warmup": 0, "repeat": 1, "results": "r"}
    with pytest.raises(InputError, match="^profile 'p' render_time_limit"):
        Profile.from_mapping({**mapping, "render_time_limit": value})


def test_every_shipped_profile_sets_a_render_time_limit():
    for name in ("smoke", "default", "full"):
        profile = Profile.load(ROOT / "config" / f"{name}.yaml")
        assert profile.render_time_limit is not None and profile.render_time_limit > 0, name


def test_retry_marker_is_new_only_for_failed_records(tmp_path):
    results = tmp_path / "r"
    marker = mark_retry(results, "e", "run1")  # no record yet: never a trigger
    assert marker.is_file() and marker.stat().st_mtime == 0
    record = run_record_path(results, "e", "run1")
    record.parent.mkdir(parents=True)
    for status, retried in (("ok", False), ("skipped", False), ("failed", True)):
        record.write_text(json.dumps({"status": status}))
        assert (mark_retry(results, "e", "run1").stat().st_mtime > record.stat().st_mtime) == retried, status
    record.write_text("{half a reco")
    assert mark_retry(results, "e", "run1").stat().st_mtime > record.stat().st_mtime
    record.write_text(json.dumps({"status": "ok"}))  # the retry succeeded: the marker goes back to 1970
    assert mark_retry(results, "e", "run1").stat().st_mtime == 0


def _record_with_images(results):
    """An ``ok`` record of run ``e/run1`` naming one view's EXR and PNG with their digests, as execute writes it."""
    record = run_record_path(results, "e", "run1")
    record.with_suffix("").mkdir(parents=True)
    image = np.zeros((4, 4, 4), np.float32)
    image[1:3, 1:3] = 0.5
    exr, png = record.with_suffix("") / "front.exr", record.with_suffix("") / "front.png"
    write_exr(exr, image)
    write_png(png, image)
    view = {"view": "front", "exr": str(exr), "png": str(png), "digests": {"exr": image_digest(exr), "png": image_digest(png)}}
    record.write_text(json.dumps({"status": "ok", "views": [view]}))
    return record, exr, png


def _retry_reason(results, record):
    """What the retry marker says after the workflow's start-up, or ``None`` when the run is not retried."""
    marker = mark_retry(results, "e", "run1")
    return marker.read_text() if marker.stat().st_mtime > record.stat().st_mtime else None


def test_a_run_whose_images_are_missing_or_damaged_is_retried(tmp_path):
    results = tmp_path / "r"
    record, exr, png = _record_with_images(results)
    assert _retry_reason(results, record) is None
    intact = exr.read_bytes()
    exr.write_bytes(intact[:len(intact) // 2])  # truncated, as by a full disk or a copy cut short
    assert f"names a damaged image (view 'front': its EXR {exr} has {len(intact) // 2} bytes, not {len(intact)})" \
        in _retry_reason(results, record)
    exr.write_bytes(intact)  # the same bytes again, with a new modification time: the digest decides
    assert _retry_reason(results, record) is None
    damaged = bytearray(intact)
    damaged[-1] ^= 0xFF  # same size, one byte changed
    exr.write_bytes(damaged)
    os.utime(exr, ns=(exr.stat().st_atime_ns, json.loads(record.read_text())["views"][0]["digests"]["exr"]["mtime_ns"] + 1))
    assert f"its EXR {exr} does not match its SHA-256" in _retry_reason(results, record)
    exr.write_bytes(intact)
    png.unlink()
    assert f"its PNG {png} is missing" in _retry_reason(results, record)
    view = {"view": "front", "exr": str(exr), "png": str(png)}
    record.write_text(json.dumps({"status": "ok", "views": [view]}))  # written before records had digests
    assert "carries no image digests" in _retry_reason(results, record)


def test_images_whose_size_and_time_are_as_recorded_are_not_read_again(tmp_path, monkeypatch):
    results = tmp_path / "r"
    record, _, _ = _record_with_images(results)
    monkeypatch.setattr(runner, "image_digest", lambda path: pytest.fail(f"{path} was hashed again"))
    assert _retry_reason(results, record) is None


def _copy_tree(tmp_path):
    tree = tmp_path / "tree"
    for entry in ("core", "datasets", "renderers", "reports", "pipeline"):
        shutil.copytree(ROOT / entry, tree / entry, ignore=shutil.ignore_patterns("__pycache__"))
    return tree


@pytest.mark.parametrize("edited, reruns", [
    ("core/camera.py", {"volume", "phantoms", "render", "evaluate", "tabulate", "report", "environment"}),
    ("core/transfer.py", {"volume", "phantoms", "render", "evaluate", "tabulate", "report", "environment"}),
    ("datasets/loaders.py", {"volume", "phantoms", "render"}),
    ("renderers/base/interface.py", {"render"}),
    ("renderers/reference/raycast.py", {"render"}),
    ("pipeline/scene_io.py", {"phantoms", "render"}),
    ("pipeline/timing.py", {"render"}),
    ("pipeline/runner.py", {"render", "evaluate", "tabulate"}),
    ("reports/imageio.py", {"render", "evaluate", "report"}),
    ("reports/metrics.py", {"evaluate", "tabulate", "report"}),
    ("pipeline/collect.py", {"phantoms", "tabulate", "collect"}),
    ("pipeline/experiments/volbench.py", {"phantoms", "tabulate", "report"}),
    ("reports/html.py", {"report"}),
    ("pipeline/environment.py", {"environment", "render", "tabulate"}),
])
def test_editing_shared_code_changes_the_digest_of_the_jobs_it_shapes(tmp_path, edited, reruns):
    tree = _copy_tree(tmp_path)
    rules = ("volume", "phantoms", "environment", "render", "evaluate", "tabulate", "collect", "report")

    def digests():
        return {rule: runner.job_code_digest(rule, backend="reference" if rule == "render" else None, root=tree)
                for rule in rules}

    before = digests()
    with open(tree / edited, "a") as f:
        f.write("\n# an edit\n")
    after = digests()
    assert {rule for rule in rules if before[rule] != after[rule]} == reruns


@pytest.mark.parametrize("backend, edited", [("gl-raycast", "renderers/gl/glsl.py"),
                                             ("cl-tiled", "renderers/cl/kernels/pixel.cl"),
                                             ("reference", "renderers/reference/raycast.py")])
def test_a_backend_job_reruns_when_any_file_of_its_package_changes(tmp_path, backend, edited):
    tree = _copy_tree(tmp_path)
    before = runner.job_code_digest("render", backend=backend, root=tree)
    other = runner.job_code_digest("render", backend="shearwarp", root=tree)
    with open(tree / edited, "a") as f:
        f.write("\n// an edit\n")
    assert runner.job_code_digest("render", backend=backend, root=tree) != before
    assert runner.job_code_digest("render", backend="shearwarp", root=tree) == other


def test_job_sources_exist_and_cover_what_a_render_job_imports():
    for rule, entries in runner.JOB_SOURCES.items():
        assert runner.source_files(entries), rule
    files = {p.relative_to(ROOT).as_posix() for p in runner.source_files(runner.JOB_SOURCES["render"])}
    for module in ("core/scene.py", "core/transfer.py", "datasets/cache.py", "datasets/phantoms/heads.py",
                   "renderers/base/interface.py", "pipeline/runner.py", "pipeline/scene_io.py", "pipeline/timing.py",
                   "reports/imageio.py"):
        assert module in files, module
    with pytest.raises(FileNotFoundError):
        runner.source_files(["no/such/file.py"])
