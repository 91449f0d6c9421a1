"""Renders one run and compares it with its reference run: the work of a render or evaluate job.

Apart from :mod:`pipeline.records` (record paths and I/O) and :mod:`pipeline.execution` (the time
limit) because this is where the heavy imports are (the data sets, the backend registry's renderers,
OpenImageIO, the metrics): the process that only waits on a render under its time limit, and the
Snakefile, never load them.
"""

import json
import traceback
from pathlib import Path

import datasets
import renderers
from core.errors import BackendUnavailableError, InputError, UnsupportedFeatureError
from core.transfer import Preset
from pipeline.records import image_digest, new_record, run_record_path, write_json
from pipeline.scene_io import build_scene, build_volume_instance
from pipeline.timing import measure
from reports.imageio import read_image, write_exr, write_png


def skip_cause(exc):
    """The record's ``cause`` (:data:`core.outcomes.CAUSES`) of a run skipped because of ``exc``."""
    if isinstance(exc, datasets.DataUnavailableError):
        return "no-data"
    if isinstance(exc, BackendUnavailableError):
        return "unavailable"
    return "unsupported"


def execute(run, *, profile, device_environment=None):
    """Render every view of ``run``, write its images and record; return the record."""
    record_path = run_record_path(profile.results, run.experiment, run.id)
    record = new_record(run, device_environment)
    try:
        scene = build_scene(run.scene, cache_dir=profile.cache, size=profile.volume_size, data_dir=profile.real_data)
        renderer = renderers.get(run.backend, **run.options)
        renderer.check(scene)
    except (datasets.DataUnavailableError, BackendUnavailableError, UnsupportedFeatureError) as exc:
        record.update(status="skipped", reason=str(exc), cause=skip_cause(exc))
        write_json(record_path, record)
        return record
    image_dir = record_path.with_suffix("")
    image_dir.mkdir(parents=True, exist_ok=True)
    try:
        with renderer:
            record["backend_environment"] = renderer.environment()
            if run.statistics:
                measured = build_volume_instance(run.statistics, cache_dir=profile.cache, size=profile.volume_size,
                                                 data_dir=profile.real_data)
                preset = Preset(measured.transfer_function, measured.gradient_opacity, measured.isovalue)
                record["statistics"] = {**datasets.statistics(measured.volume, preset),
                                        "size": max(measured.volume.shape_xyz)}
            for view in run.views:
                overrides = {k: v for k, v in view.items() if k != "view"}
                view_scene = scene.with_camera(**overrides) if overrides else scene
                result = measure(renderer, view_scene, warmup=run.warmup, repeat=run.repeat)
                exr, png = image_dir / f"{view['view']}.exr", image_dir / f"{view['view']}.png"
                write_exr(exr, result.image, metadata={"run": run.key, "view": view["view"], "backend": run.backend})
                write_png(png, result.image)
                record["views"].append({
                    "view": view["view"], "camera": overrides, "exr": str(exr), "png": str(png),
                    "digests": {"exr": image_digest(exr), "png": image_digest(png)},
                    "timings": result.timings, "timings_min": result.timings_min,
                    "timings_max": result.timings_max, "counters": result.counters, "info": result.info,
                })
            # After rendering: some effective options (a step derived from the scene) exist only now.
            record["options"] = {**run.options, **renderer.options}
    except Exception as exc:  # recorded with its traceback: the pipeline must not lose the pair
        record.update(status="failed", reason=f"{type(exc).__name__}: {exc}", cause="error",
                      traceback=traceback.format_exc(limit=8))
    write_json(record_path, record)
    return record


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
