"""The render-job time limit (pipeline.execution), retries of failed and damaged runs and the code digests
that trigger reruns (pipeline.digests)."""

import json
import os
import shutil
import subprocess
import sys
import threading
import time
from contextlib import contextmanager
from dataclasses import asdict, replace
from pathlib import Path

import numpy as np
import pytest

import renderers
from core.errors import InputError, UnsupportedFeatureError
from pipeline import digests, disturbance, execution, jobs, records, rendering
from pipeline.digests import mark_retry
from pipeline.execution import execute_limited, execute_together_limited, time_limit_reason
from pipeline.experiments import Profile, Run, plan
from pipeline.records import image_digest, run_record_path
from pipeline.scene_io import phantom_requests
from renderers.base import Capabilities, Renderer, RenderResult
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


class Raising(Renderer):
    """Fails in its kernel, as a backend bug would."""

    name = "raising"
    capabilities = Capabilities()

    def _render(self, scene):
        raise RuntimeError("kernel exploded")


class Unsupporting(Renderer):
    """Lacks a feature every scene uses: its runs are skipped before they start."""

    name = "unsupporting"
    capabilities = Capabilities()

    def check(self, scene):
        raise UnsupportedFeatureError(self.name, "volumes", "it renders none")

    def _render(self, scene):
        raise AssertionError("a skipped run rendered")


class Counting(Renderer):
    """A blank frame whose time is the number of frames rendered so far, in ms; the cold frame takes 50 ms."""

    name = "counting"
    capabilities = Capabilities()
    calls = 0

    def _render(self, scene):
        Counting.calls += 1
        if Counting.calls == 1:
            time.sleep(0.05)
        return RenderResult(np.zeros((scene.height, scene.width, 4), np.float32), timings={"total": Counting.calls / 1e3})


@pytest.fixture
def profile(tmp_path, monkeypatch):
    # The child process is spawned fresh: it gets these registry entries from its parent.
    for backend in (Hanging, Crashing, Raising, Unsupporting, Counting):
        monkeypatch.setitem(renderers.BACKENDS, backend.name, f"{__name__}:{backend.__name__}")
    return Profile(name="t", volume_size=8, results=str(tmp_path / "results"), cache=str(tmp_path / "cache"),
                   render_time_limit=120)


def _run(run_id, backend, **kw):
    return Run("volbench-phantoms", run_id, backend, SCENE, ({"view": "front"},), warmup=0, repeat=1, **kw)


@pytest.mark.parametrize("start_method", execution.START_METHODS)
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


@pytest.mark.parametrize("start_method", execution.START_METHODS)
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
    monkeypatch.setattr(rendering, "execute_together", lambda runs, **kw: calls.extend(runs) or [{"status": "ok"}])
    assert execute_limited(_run("x", "reference"), profile=replace(profile, render_time_limit=None)) == {"status": "ok"}
    assert len(calls) == 1


def _grouped(run_id, backend, views=("front", "side"), **kw):
    """A timed run of interleave group ``g`` over ``views`` (the side view turned 90°)."""
    cameras = {"front": {}, "side": {"azimuth": 90}}
    return Run("volbench-phantoms", run_id, backend, SCENE, tuple({"view": v, **cameras[v]} for v in views),
               warmup=1, repeat=3, interleave="g", **kw)


@pytest.fixture
def quiet(monkeypatch):
    """The machine reads as quiet: no view is timed twice, whatever else runs beside the test."""
    monkeypatch.setattr(disturbance, "verdict", lambda *args, **kwargs: "")


def test_the_runs_of_an_interleave_group_are_timed_together_view_by_view(profile, quiet):
    runs = [_grouped("coarse", "reference", options={"step_factor": 1.0}),
            _grouped("fine", "reference", options={"step_factor": 0.5}, views=("front",))]
    coarse, fine = rendering.execute_together(runs, profile=profile)
    assert coarse["status"] == fine["status"] == "ok"
    assert [v["view"] for v in coarse["views"]] == ["front", "side"] and [v["view"] for v in fine["views"]] == ["front"]
    front, side, fine_front = coarse["views"][0], coarse["views"][1], fine["views"][0]
    # The shared view: frame i of each run is from round i, so both have as many frames.
    assert front["interleaved"] == fine_front["interleaved"] == 2 and side["interleaved"] == 1
    assert len(front["frames"]["total"]) == len(fine_front["frames"]["total"]) >= 3
    assert front["rerun"] is None and front["timings"]["first_frame"] > 0
    for record in (coarse, fine):  # each run its own record and images, as if rendered alone
        on_disk = json.loads(run_record_path(profile.results, record["experiment"], record["run"]).read_text())
        assert on_disk["views"] == record["views"] and on_disk["interleave"] == "g"
        assert all(Path(view["exr"]).is_file() and record["run"] in view["exr"] for view in record["views"])
    assert coarse["options"]["step_factor"] == 1.0 and fine["options"]["step_factor"] == 0.5


def test_a_member_whose_backend_raises_fails_alone(profile, quiet):
    good, bad, skipped = rendering.execute_together(
        [_grouped("good", "reference", options={"step_factor": 1.0}), _grouped("bad", "raising"),
         _grouped("skipped", "unsupporting")], profile=profile)
    assert (bad["status"], bad["cause"], bad["reason"]) == ("failed", "error", "RuntimeError: kernel exploded")
    assert "kernel exploded" in bad["traceback"] and bad["views"] == []
    assert skipped["status"] == "skipped" and skipped["cause"] == "unsupported"
    assert good["status"] == "ok", good["reason"]
    # Timed alone once the group's attempt failed.
    assert [(v["view"], v["interleaved"]) for v in good["views"]] == [("front", 1), ("side", 1)]
    assert json.loads(run_record_path(profile.results, "volbench-phantoms", "bad").read_text())["status"] == "failed"


BUSY = "other work used 1.00 cores while it was timed"


@pytest.mark.parametrize("reasons, loads, kept", [
    ((BUSY, ""), (1.0, 0.2), "second"),  # quiet the second time: kept
    ((BUSY, "other work used 2.00 cores while it was timed"), (1.0, 2.0), "first"),  # busier the second time
    ((BUSY, "other work used 0.50 cores while it was timed"), (1.0, 0.5), "second"),  # less busy: the quieter
    # Interrupted frames the first time, none the second; spans too short for the load in both.
    (("3 of 10 frames took over 3× the median", ""), (None, None), "second"),
])
def test_a_disturbed_view_is_timed_again_and_the_quieter_attempt_kept(profile, monkeypatch, reasons, loads, kept):
    monkeypatch.setattr(rendering, "RERUN_PAUSE", 0.0)
    monkeypatch.setattr(Counting, "calls", 0)
    said, measured, judged_after = iter(reasons), iter(loads), []

    def verdict(*args, **kwargs):
        judged_after.append(Counting.calls)  # the frames an attempt had rendered when its verdict came
        return next(said)

    monkeypatch.setattr(disturbance, "verdict", verdict)
    # The timing harness reads the load once per attempt; the render job once more over the whole job.
    monkeypatch.setattr(disturbance, "between", lambda start, end: {
        "seconds": 1.0, "foreign_cores": next(measured, None), "own_cores": None, "steal_share": None})
    record = rendering.execute(_grouped("busy", "counting", views=("front",)), profile=profile)
    assert record["status"] == "ok", record["reason"]
    view = record["views"][0]
    assert view["rerun"] == {"first": reasons[0], "second": reasons[1], "kept": kept}
    assert view["info"]["disturbed"] == reasons[kept == "second"]
    assert view["info"]["load"]["foreign_cores"] == loads[kept == "second"]
    assert (min(view["frames"]["total"]) > judged_after[0] / 1e3) == (kept == "second")
    # The cold frame is the first attempt's, whichever attempt's frames are kept.
    assert view["timings"]["first_frame"] >= 0.05 and view["info"]["first_frame"] == view["timings"]["first_frame"]


def test_a_disturbed_group_is_timed_again_together_and_says_each_reason_once(profile, monkeypatch):
    monkeypatch.setattr(rendering, "RERUN_PAUSE", 0.0)
    said = iter([BUSY, f"{BUSY}; 3 of 10 frames took over 3× the median", "", ""])  # two arms, two attempts
    monkeypatch.setattr(disturbance, "verdict", lambda *args, **kwargs: next(said))
    records = rendering.execute_together([_grouped("a", "counting", views=("front",)),
                                          _grouped("b", "counting", views=("front",))], profile=profile)
    for record in records:
        view = record["views"][0]
        assert view["interleaved"] == 2 and view["info"]["disturbed"] == ""
        assert view["rerun"] == {"first": f"{BUSY}; 3 of 10 frames took over 3× the median", "second": "", "kept": "second"}
    assert len(records[0]["views"][0]["frames"]["total"]) == len(records[1]["views"][0]["frames"]["total"])


def test_a_group_killed_at_its_limit_records_every_unfinished_member_failed(profile):
    limited = replace(profile, render_time_limit=1)
    runs = [_grouped("done", "reference", options={"step_factor": 1.0}, views=("front",)),
            _grouped("stuck", "hanging", views=("front",)), _grouped("skipped", "unsupporting", views=("front",))]
    started = time.monotonic()
    # Spawned: a test before may have started Numba's OpenMP threads, which a forked child cannot use.
    done, stuck, skipped = execute_together_limited(runs, profile=limited)
    assert 3 <= time.monotonic() - started < 15  # the group's limit: the profile's times its three runs
    reason = "exceeded the profile's render_time_limit of 1 s per run (3 s for its interleave group of 3)"
    for record in (done, stuck):  # written when the group ends: the reference's too, timed or not
        assert (record["status"], record["cause"], record["reason"]) == ("failed", "time-limit", reason)
        assert json.loads(run_record_path(limited.results, "volbench-phantoms", record["run"]).read_text()) == record
    assert skipped["status"] == "skipped"  # recorded before the group was timed


def test_a_group_whose_process_dies_records_its_members_as_crashed(profile):
    records = execute_together_limited([_grouped("a", "crashing", views=("front",)),
                                        _grouped("b", "unsupporting", views=("front",))], profile=profile)
    assert [(r["status"], r["cause"]) for r in records] == [("failed", "crash"), ("skipped", "unsupported")]
    assert "exit code 9" in records[0]["reason"]


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
    monkeypatch.setattr(records, "image_digest", lambda path: pytest.fail(f"{path} was hashed again"))
    assert _retry_reason(results, record) is None


RULES = ("volume", "phantoms", "environment", "render", "evaluate", "tabulate", "collect", "report")
LOOKUPS = {"phantoms", "tabulate", "collect", "report"}
"""The rules whose code asks the registries for what they hold: every experiment, and any backend
(planning reads backend classes, the report probes every backend)."""


@pytest.fixture(scope="module")
def tree(tmp_path_factory):
    """A copy of the project's packages; a test edits a file of it with :func:`_edited`."""
    tree = tmp_path_factory.mktemp("digests") / "tree"
    for entry in ("core", "datasets", "renderers", "reports", "pipeline"):
        shutil.copytree(ROOT / entry, tree / entry, ignore=shutil.ignore_patterns("__pycache__"))
    return tree


@contextmanager
def _edited(path, edit=lambda text: text + "\n# an edit\n"):
    original = path.read_text()
    path.write_text(edit(original))
    try:
        yield
    finally:
        path.write_text(original)


def _digests(tree, backends=("reference",)):
    """``{rule: digest}``, a render's under ``render:<backend>`` for each of ``backends``."""
    found = {rule: digests.job_code_digest(rule, root=tree) for rule in RULES if rule != "render"}
    found.update({f"render:{b}": digests.job_code_digest("render", backend=b, root=tree) for b in backends})
    return found


def _changed(tree, edited, **edit):
    before = _digests(tree, renderers.names())
    with _edited(tree / edited, **edit):
        after = _digests(tree, renderers.names())
    return {key for key in before if before[key] != after[key]}


def _sources(rule, backend=None, root=ROOT):
    files, _ = digests.job_sources(rule, backend=backend, root=root)
    return {path.relative_to(root).as_posix() for path in files}


@pytest.mark.parametrize("edited, reruns", [
    ("core/errors.py", set(RULES)),
    ("datasets/loaders.py", {"volume", "render"}),  # the phantoms list reads the cache, not the loaders
    ("pipeline/scene_io.py", {"phantoms", "render"}),
    ("pipeline/timing.py", {"render"}),
    ("pipeline/execution.py", {"render"}),
    ("pipeline/rendering.py", {"render", "evaluate"}),
    ("pipeline/records.py", {"environment", "render", "evaluate", "tabulate"}),
    ("pipeline/environment.py", {"environment", "render", "tabulate", "report"}),
    ("reports/imageio.py", {"render", "evaluate", *LOOKUPS}),
    ("reports/metrics.py", {"evaluate", *LOOKUPS}),
    ("reports/html.py", {"report"}),
    ("reports/templates/base.html", {"report"}),  # read by reports/html.py only, not by its package's imageio
    ("pipeline/collect.py", {"phantoms", "tabulate", "collect"}),
    ("pipeline/experiments/volbench/phantoms.py", LOOKUPS),  # the registry's lookups import it, its Run class not
    ("pipeline/experiments/kit/model.py", {"render", *LOOKUPS}),
    ("pipeline/experiments/README.md", set()),
])
def test_editing_code_changes_the_digest_of_the_jobs_it_shapes(tree, edited, reruns):
    changed = {key.split(":")[0] for key in _changed(tree, edited)}
    assert changed == reruns


def test_editing_one_job_entry_function_changes_that_job_digest_alone(tree):
    def edit(text):
        assert "def render(args):\n" in text
        return text.replace("def render(args):\n", "def render(args):\n    \"\"\"Edited.\"\"\"\n")

    assert _changed(tree, "pipeline/jobs.py", edit=edit) == {f"render:{b}" for b in renderers.names()}


@pytest.mark.parametrize("edited, package", [("renderers/shearwarp/octree.py", "renderers.shearwarp"),
                                             ("renderers/gl/glsl.py", "renderers.gl"),
                                             ("renderers/cl/tiled.py", "renderers.cl"),
                                             ("renderers/cl/kernels/pixel.cl", "renderers.cl"),
                                             ("renderers/reference/raycast.py", "renderers.reference")])
def test_editing_a_backend_changes_its_renders_and_no_other_backends(tree, edited, package):
    # Of the other rules, only those that look backends up by name; not the phantoms' generation,
    # the device probe (it takes renderers.cl.context, not the backend its package gathers) or
    # the comparisons.
    ours = {f"render:{b}" for b in renderers.names() if renderers.backend_module(b).startswith(package)}
    assert _changed(tree, edited) == ours | LOOKUPS


FORMER_JOB_SOURCES = {
    "volume": ("core", "datasets"),
    "environment": ("core", "pipeline/environment.py", "renderers/gl/context.py", "renderers/cl/context.py"),
    "render": ("core", "datasets", "renderers/__init__.py", "renderers/base", "pipeline/records.py",
               "pipeline/execution.py", "pipeline/rendering.py", "pipeline/scene_io.py", "pipeline/timing.py",
               "pipeline/environment.py", "pipeline/experiments/kit/model.py", "reports/imageio.py"),
    "evaluate": ("core", "pipeline/records.py", "pipeline/rendering.py", "reports/metrics.py", "reports/imageio.py"),
    "phantoms": ("core", "datasets", "pipeline/collect.py", "pipeline/scene_io.py", "pipeline/experiments"),
    "tabulate": ("core", "pipeline/records.py", "pipeline/collect.py", "pipeline/environment.py",
                 "pipeline/experiments", "reports/metrics.py"),
    "collect": ("pipeline/collect.py",),
    "report": ("core", "pipeline/experiments", "reports"),
}
"""The hand-kept list the digests were made of before they were derived from the imports, with
``pipeline/runner.py`` replaced by the modules its parts moved to (records; execution for a render)
and ``pipeline/experiments/base.py`` by the module of the ``Run`` it held (``kit/model.py``). Its
folders stood for what the job uses in them: which modules that is,
:func:`test_every_file_a_job_runs_is_in_its_sources` checks on the jobs themselves."""


@pytest.mark.parametrize("rule", RULES)
def test_derived_sources_include_the_former_list(rule):
    backends = renderers.names() if rule == "render" else [None]
    for backend in backends:
        sources = _sources(rule, backend)
        files = [entry for entry in FORMER_JOB_SOURCES[rule] if (ROOT / entry).is_file()]
        assert set(files) <= sources, (backend, sorted(set(files) - sources))
        # Registries import whole packages: every paper's modules, the render's backend's files.
        packages = [entry for entry in FORMER_JOB_SOURCES[rule] if entry == "pipeline/experiments"]
        if backend is not None:
            packages.append(Path(*renderers.backend_module(backend).split(".")[:2]).as_posix())
        for package in packages:
            files = {path.relative_to(ROOT).as_posix() for path in (ROOT / package).rglob("*")
                     if path.is_file() and "__pycache__" not in path.parts and path.suffix not in digests.LEFT_OUT_SUFFIXES}
            assert files <= sources, (backend, package, sorted(files - sources))
        if backend == "reference":
            for module in ("core/scene.py", "core/transfer.py", "datasets/cache.py", "datasets/phantoms/heads.py",
                           "renderers/base/interface.py", "renderers/reference/raycast.py"):
                assert module in sources, module


class _Calls:
    """The project files whose functions run while it is active (this thread and threads it starts),
    leaving out what runs on import: a module's code, and the class bodies and calls it makes."""

    def __init__(self):
        self.files, self.importing = set(), 0

    def _call(self, frame, event, arg):
        if frame.f_code.co_name == "<module>":
            self.importing += 1
            return self._in_module
        if not self.importing:
            self.files.add(frame.f_code.co_filename)
        return None

    def _in_module(self, frame, event, arg):
        if event == "return":
            self.importing -= 1
            return None
        return self._in_module

    def __enter__(self):
        sys.settrace(self._call)
        threading.settrace(self._call)
        return self

    def __exit__(self, *exc):
        sys.settrace(None)
        threading.settrace(None)

    def project_files(self):
        packages = ("core", "datasets", "renderers", "reports", "pipeline")
        paths = (Path(name) for name in self.files)
        return {path.relative_to(ROOT).as_posix() for path in paths
                if path.is_relative_to(ROOT) and path.relative_to(ROOT).parts[0] in packages}


@pytest.mark.slow
def test_every_file_a_job_runs_is_in_its_sources(tmp_path):
    """Each job of a small experiment, run in this process: no function of a file outside its digest's sources runs."""
    from test_reports_html import SIZE, synthetic_results

    experiment, settings = "volbench-convergence", {"volbench-convergence": {"step_factors": [1.0], "truth_step_factor": 0.5}}
    synthetic_results(tmp_path, experiments=[experiment], settings=settings)  # records, metrics, tables, phantoms
    profile = Profile(name="t", volume_size=8, image_size=SIZE, results=str(tmp_path / "results"),
                      cache=str(tmp_path / "cache"), experiments=[experiment], settings=settings, render_time_limit=None)
    runs = plan(profile)
    run = next(run for run in runs.values() if run.reference is None)
    pairs = [[str(run_record_path(profile.results, r.experiment, name)) for name in (r.id, r.reference)]
             + [str(records.metrics_record_path(profile.results, r.experiment, r.id))]
             for r in runs.values() if r.reference is not None]
    as_json = json.dumps(asdict(profile))
    # Rendered apart, so the synthetic records stay as the other jobs expect them.
    rendered = json.dumps(asdict(replace(profile, results=str(tmp_path / "rendered"))))
    request = next(iter(phantom_requests(run.volume_entries, size=profile.volume_size).values()))
    arguments = {
        "volume": ["--request", json.dumps(request), "--cache", profile.cache],
        "environment": ["--output", str(tmp_path / "environment.json")],
        "render": ["--run", json.dumps(run.as_dict()), "--profile", rendered],  # no time limit: in this process
        "evaluate": ["--pairs", json.dumps(pairs)],
        "phantoms": ["--profile", as_json, "--output", str(tmp_path / "results" / "volumes.csv")],
        "tabulate": ["--profile", as_json, "--experiment", experiment],
        "collect": ["--profile", as_json],
        "report": ["--profile", as_json],
    }
    for rule in RULES:
        with _Calls() as calls:
            jobs.main([rule, *arguments[rule]])
        ran = calls.project_files() - {"pipeline/jobs.py"}  # its entry functions' code is in the digest
        sources = _sources(rule, run.backend if rule == "render" else None)
        assert ran and ran <= sources, (rule, sorted(ran - sources))


def test_a_computed_import_the_digests_cannot_follow_is_an_error(tree):
    # Code a render runs (pipeline.timing's measure) imports by a computed name.
    def edit(text):
        return text.replace("import statistics\n", "import importlib\nimport statistics\n") + \
            "\n\ndef _plugin(name):\n    return importlib.import_module(name)\n"

    with _edited(tree / "pipeline" / "timing.py", edit=edit):
        digests.job_code_digest("render", backend="reference", root=tree)  # not run by the job: no error
    with _edited(tree / "pipeline" / "timing.py", edit=lambda text: edit(text) + "\n\n_plugin('json')\n"):  # on import
        with pytest.raises(RuntimeError, match="^pipeline.timing imports modules by a name computed at run time"):
            digests.job_code_digest("render", backend="reference", root=tree)
    for module in digests.NAMED_IMPORTS:  # each one does
        path = ROOT.joinpath(*module.split(".")) / "__init__.py"
        assert "importlib.import_module(" in path.read_text(), module


def test_an_unknown_rule_is_refused_naming_the_jobs():
    with pytest.raises(InputError, match="^rule 'rendr': pipeline.jobs has no function of that name; it has .*render"):
        digests.job_code_digest("rendr")
