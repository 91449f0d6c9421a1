"""Renders one run and compares it with its reference run: the work of a render or evaluate job.

Apart from :mod:`pipeline.records` (record paths and I/O) and :mod:`pipeline.execution` (the time
limit) because this is where the heavy imports are (the data sets, the backend registry's renderers,
OpenImageIO, the metrics): the process that only waits on a render under its time limit, and the
Snakefile, never load them.
"""

import contextlib
import json
import time
import traceback
from pathlib import Path

import datasets
import renderers
from core.errors import BackendUnavailableError, InputError, UnsupportedFeatureError
from core.transfer import Preset
from pipeline import disturbance
from pipeline.records import image_digest, new_record, run_record_path, write_json
from pipeline.scene_io import build_scene, build_volume_instance
from pipeline.timing import measure_together
from reports.imageio import read_image, write_exr, write_png


def skip_cause(exc):
    """The record's ``cause`` (:data:`core.outcomes.CAUSES`) of a run skipped because of ``exc``."""
    if isinstance(exc, datasets.DataUnavailableError):
        return "no-data"
    if isinstance(exc, BackendUnavailableError):
        return "unavailable"
    return "unsupported"


RERUN_PAUSE = 2.0
"""Seconds a render job waits before timing a disturbed view again (a passing burst of other work)."""


def execute(run, *, profile, device_environment=None, harness=None):
    """Render every view of ``run``, write its images and record; return the record."""
    return execute_together([run], profile=profile, device_environment=device_environment, harness=harness)[0]


def execute_together(runs, *, profile, device_environment=None, harness=None):
    """Render the runs of one interleave group (or one run), timed together view by view; their records.

    Each run gets its own record and images, as if rendered alone; the timed frames of the runs that
    share a view alternate round by round (:func:`pipeline.timing.measure_together`), so the ratio of
    two of them is measured under the same conditions. A view whose frames were disturbed
    (:mod:`pipeline.disturbance`) is timed once more after a pause, and the quieter attempt kept; the
    record says so (``rerun``).

    Every record's ``harness`` says what the harness itself cost: ``harness`` as given (the process
    that rendered: a job's own or a warm worker of :mod:`pipeline.workers`, and what starting it took),
    the pipeline run (:data:`pipeline.harness.PIPELINE_RUN_VARIABLE`) and ``seconds``, the wall time of
    this call for the whole group (its ``runs``, that many).
    """
    from pipeline.harness import pipeline_run

    began = time.perf_counter()
    records, arms = [], []
    job_start = disturbance.snapshot()
    for run in runs:
        record_path = run_record_path(profile.results, run.experiment, run.id)
        record = new_record(run, device_environment)
        records.append(record)
        try:
            scene = build_scene(run.scene, cache_dir=profile.cache, size=profile.volume_size, data_dir=profile.real_data)
            renderer = renderers.get(run.backend, **run.options)
            renderer.check(scene)
        except (datasets.DataUnavailableError, BackendUnavailableError, UnsupportedFeatureError) as exc:
            record.update(status="skipped", reason=str(exc), cause=skip_cause(exc))
            write_json(record_path, record)
            continue
        arms.append((run, record, record_path, scene, renderer))
    with contextlib.ExitStack() as stack:
        live = []
        for run, record, record_path, scene, renderer in arms:
            try:
                stack.enter_context(renderer)
                record["backend_environment"] = renderer.environment()
                if run.statistics:
                    measured = build_volume_instance(run.statistics, cache_dir=profile.cache,
                                                     size=profile.volume_size, data_dir=profile.real_data)
                    preset = Preset(measured.transfer_function, measured.gradient_opacity, measured.isovalue)
                    record["statistics"] = {**datasets.statistics(measured.volume, preset),
                                            "size": max(measured.volume.shape_xyz)}
                live.append((run, record, record_path, scene, renderer))
            except Exception as exc:  # recorded with its traceback: the pipeline must not lose the pair
                _failed(record, exc)
                write_json(record_path, record)
        for name in dict.fromkeys(view["view"] for run, *_ in live for view in run.views):
            members = [arm for arm in live if arm[1]["status"] == "ok" and any(v["view"] == name for v in arm[0].views)]
            try:
                _time_view(name, members)
            except Exception:  # noqa: BLE001 - timed alone, each run of the group fails or succeeds on its own
                for member in members:
                    try:
                        _time_view(name, [member])
                    except Exception as exc:  # noqa: BLE001 - recorded with its traceback
                        _failed(member[1], exc)
        _judge_short_views(live, disturbance.between(job_start, disturbance.snapshot()))
        account = {**(harness or {}), "pipeline_run": pipeline_run(), "runs": len(runs),
                   "seconds": time.perf_counter() - began}
        for run, record, record_path, scene, renderer in live:
            if record["status"] == "ok":
                # After rendering: some effective options (a step derived from the scene) exist only now.
                record["options"] = {**run.options, **renderer.options}
            record["harness"] = account
            write_json(record_path, record)
    return records


def _judge_short_views(live, job_load):
    """Judge the machine's load over the whole job for views too short to measure it themselves.

    ``/proc/stat`` counts in 10 ms ticks, so a view whose frames took under
    :data:`pipeline.disturbance.MIN_SPAN` has no load of its own; the job's (its start-up, preprocessing
    and every view) stands in for it, and a busy machine marks such views disturbed.
    """
    foreign = job_load.get("foreign_cores")
    if foreign is None:
        return
    for _, record, *_ in live:
        for view in record["views"]:
            load = view["info"].get("load") or {}
            if load.get("foreign_cores") is None:
                load["job_foreign_cores"] = foreign
                view["info"]["load"] = load
                waited = load.get("waited_share")
                reason = ""
                if foreign > disturbance.FOREIGN_LIMIT:
                    reason = f"other work used {foreign:.2f} cores during its job"
                elif foreign > disturbance.FOREIGN_NOISE and waited is not None and waited > disturbance.WAIT_LIMIT:
                    reason = (f"its threads waited {100 * waited:.0f} % of the time for a CPU while other work used "
                              f"{foreign:.2f} cores during its job")
                if reason:
                    view["info"]["disturbed"] = "; ".join(filter(None, [view["info"].get("disturbed"), reason]))


def _failed(record, exc):
    record.update(status="failed", reason=f"{type(exc).__name__}: {exc}", cause="error",
                  traceback=traceback.format_exc(limit=8))


def _view_scene(scene, view):
    overrides = {k: v for k, v in view.items() if k != "view"}
    return (scene.with_camera(**overrides) if overrides else scene), overrides


def _time_view(name, members):
    """Time view ``name`` of ``members`` together; write each one's images and add its view to its record."""
    frames = {key: max(getattr(member[0], key) for member in members) for key in ("warmup", "repeat", "min_time")}
    arms = []
    for member_run, _, _, scene, renderer in members:
        view = next(v for v in member_run.views if v["view"] == name)
        arms.append((renderer, _view_scene(scene, view)[0]))
    results = measure_together(arms, **frames)
    rerun = None
    disturbed = _reasons(results)
    if disturbed:
        time.sleep(RERUN_PAUSE)
        again = measure_together(arms, **frames)
        still = _reasons(again)
        quieter = not still or _foreign(again) < _foreign(results)
        rerun = {"first": disturbed, "second": still, "kept": "second" if quieter else "first"}
        # The attempt not kept was frames rendered for nothing: the harness's cost, not the run's.
        for kept, dropped in zip(again if quieter else results, results if quieter else again):
            kept.info["rerun_seconds"] = sum(dropped.info.get(key) or 0.0 for key in
                                             ("cold_seconds", "untimed_seconds", "timed_seconds"))
        if quieter:
            for kept, cold in zip(again, results):
                # The cold frame (compilation, first uploads) happened in the first attempt only.
                if "first_frame" in cold.timings:
                    kept.timings["first_frame"] = kept.info["first_frame"] = cold.timings["first_frame"]
            results = again
    for (member_run, record, record_path, _, _), result in zip(members, results):
        view = next(v for v in member_run.views if v["view"] == name)
        _, overrides = _view_scene(members[0][3], view)
        image_dir = record_path.with_suffix("")
        image_dir.mkdir(parents=True, exist_ok=True)
        exr, png = image_dir / f"{name}.exr", image_dir / f"{name}.png"
        write_exr(exr, result.image, metadata={"run": member_run.key, "view": name, "backend": member_run.backend})
        write_png(png, result.image)
        record["views"].append({
            "view": name, "camera": overrides, "exr": str(exr), "png": str(png),
            "digests": {"exr": image_digest(exr), "png": image_digest(png)},
            "timings": result.timings, "timings_min": result.timings_min,
            "timings_max": result.timings_max, "counters": result.counters, "info": result.info,
            "frames": result.frames, "interleaved": len(members), "rerun": rerun,
        })


def _reasons(results):
    """Why the arms' frames were disturbed, each reason once (the load's are every arm's), or ``""``."""
    return "; ".join(dict.fromkeys(reason for result in results
                                   for reason in (result.info.get("disturbed") or "").split("; ") if reason))


def _foreign(results):
    loads = [r.info.get("load", {}).get("foreign_cores") for r in results]
    loads = [v for v in loads if v is not None]
    return max(loads) if loads else 0.0


def evaluate(record_path, reference_path, output_path):
    """Compare each view of a run with the same view of its reference run; write the metrics.

    A view that cannot be compared (an image missing or unreadable, two sizes) makes the run's
    metrics ``failed`` with the reason, and the other views are still compared: one damaged run
    must not stop the comparisons of its experiment (the render job redoes it on the next
    ``volbench run``: :func:`pipeline.digests.mark_retry`).
    """
    # Imported here: the metrics pull in scikit-image and SciPy's statistics (over a second per
    # process), which the render and volume jobs importing this module never use.
    from reports.metrics import compare, difference_image

    record = json.loads(Path(record_path).read_text())
    truth = json.loads(Path(reference_path).read_text())
    metrics = {"experiment": record["experiment"], "run": record["run"], "reference": truth["run"],
               "status": "ok", "reason": "", "views": {}}
    if truth["status"] != "ok":
        metrics.update(status="skipped", reason=f"reference run {truth['run']} is {truth['status']}: {truth['reason']}")
    elif record["status"] != "ok":
        metrics.update(status="skipped", reason=f"run is {record['status']}")
    else:
        truth_views = {v["view"]: v for v in truth["views"]}
        diff_dir = Path(output_path).with_suffix("")
        diff_dir.mkdir(parents=True, exist_ok=True)
        failures = []
        for view in record["views"]:
            if view["view"] not in truth_views:
                continue
            try:
                test_image = read_image(view["exr"])
                truth_image = read_image(truth_views[view["view"]]["exr"])
                values = compare(truth_image, test_image)
            except InputError as exc:
                failures.append(f"view {view['view']}: {exc}")
                continue
            diff_path = diff_dir / f"{view['view']}-diff.png"
            write_png(diff_path, difference_image(truth_image, test_image))
            metrics["views"][view["view"]] = {**values, "diff_png": str(diff_path)}
        if failures:
            metrics.update(status="failed", reason="cannot compare with the reference: " + "; ".join(failures))
    write_json(output_path, metrics)
    return metrics
